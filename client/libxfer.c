/* client/libxfer.c - libseamtex's file transfers: UPLOAD (begin, windowed chunks, commit,
 * abort on any failure) and FETCH (open, windowed reads, CRC32C check, atomic rename).
 *
 * Owns: the client side of PROTOCOL.md 4.8 and 4.10. Does not own: sockets and pending
 * requests (libconn.c). Chunks are pipelined (a window of requests in flight) so that an
 * upload is not one round trip per chunk; the window never exceeds the server's max_inflight.
 */
#include "libseamtex_int.h"
#include "fdio.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#define XFER_WINDOW        8
#define XFER_DEFAULT_CHUNK (1u << 20)
/* After a timeout the clean-up request (UPLOAD_ABORT, FETCH_CLOSE) is waited for at most this
 * long (or the request timeout when shorter), so that a transfer with timeout T returns within
 * about T + this allowance from a server that stopped answering, not 2 T (libseamtex(3)). */
#define XFER_CLEANUP_AFTER_TIMEOUT_MS 1000

static int start_req(stc_conn *c, uint8_t op, uint32_t *id)
{
    *id = stc__next_reqid(c);
    return stc__pend_add(c, *id, op, 0);
}

static int xfer_encoded(stc_conn *c, int st)
{
    if (st == 0)
        return 0;
    stc__pend_drop_last(c);
    return stc__enc_error(c, st);
}

/* One request/reply on the blocking path, waiting up to timeout_ms (0 = none); 0 with an OK
 * reply in *f. */
static int roundtrip_within(stc_conn *c, uint32_t id, int timeout_ms, stc_frame *f)
{
    int64_t dl = stc__deadline(timeout_ms);
    int rc = stc__flush(c, dl);
    if (stc__gave_up(rc))
        stc__pend_abandon(c, id);
    if (rc)
        return rc;
    if ((rc = stc__wait(c, id, 0, dl, f)) != 0)
        return rc;
    return f->h.status ? stc__status_error(c, f) : 0;
}

static int roundtrip(stc_conn *c, uint32_t id, stc_frame *f)
{
    return roundtrip_within(c, id, c->timeout_ms, f);
}

static int window_size(const stc_conn *c)
{
    uint32_t w = c->server.max_inflight ? c->server.max_inflight : 1;
    return w < XFER_WINDOW ? (int)w : XFER_WINDOW;
}

/* Sends id-only request op for `xid` and waits, keeping the caller's error message: used to
 * clean up (UPLOAD_ABORT, FETCH_CLOSE) after a failure. `after` is the failure's code: after a
 * timeout the wait is XFER_CLEANUP_AFTER_TIMEOUT_MS at most (the request is sent all the same;
 * a late reply is dropped); after an interrupt (or once the interrupt hook said stop), and
 * after the caller's own stop (STC_ECANCELED: its progress callback, e.g. on Ctrl-C) on a
 * connection with an interrupt hook, it is not waited for at all: queued, sent as far as the
 * socket takes it now (the rest goes out with the connection's next call), its reply
 * dropped. (A caller who stopped the transfer wants out now; with no timeout the wait on a
 * hung server never ended, and a hook that reports signals - Python's - had nothing left to
 * report: the callback had taken the Ctrl-C.) Returns STC_EINTERRUPTED when the hook has
 * said stop during this call (the caller's call returns that, libseamtex(3)), else 0. */
static int cleanup_call(stc_conn *c, uint8_t op, uint64_t xid, int after)
{
    char keep[sizeof c->msg];
    stc_frame f;
    uint32_t id;
    int wait_ms = c->timeout_ms;
    if (c->sticky)
        return c->intr.said ? STC_EINTERRUPTED : 0;
    if (after == STC_ETIMEDOUT && (wait_ms <= 0 || wait_ms > XFER_CLEANUP_AFTER_TIMEOUT_MS))
        wait_ms = XFER_CLEANUP_AFTER_TIMEOUT_MS;
    memcpy(keep, c->msg, sizeof keep);
    if (c->hold) {
        stp_buf_consume(&c->in, c->hold);
        c->hold = 0;
    }
    if (start_req(c, op, &id) == 0 &&
        xfer_encoded(c, stp_enc_id_req(&c->out, op, id, (uint32_t)wait_ms, xid)) == 0) {
        if (c->intr.said || (after == STC_ECANCELED && c->intr.fn)) {
            (void)stc__flush(c, stc__now_ms());
            stc__pend_abandon(c, id);
        } else {
            (void)roundtrip_within(c, id, wait_ms, &f);
        }
    }
    if (c->hold) {
        stp_buf_consume(&c->in, c->hold);
        c->hold = 0;
    }
    memcpy(c->msg, keep, sizeof keep);
    return c->intr.said ? STC_EINTERRUPTED : 0;
}

/* The code a failed transfer returns after its clean-up: its own, or STC_EINTERRUPTED when
 * the hook said stop during the clean-up (the caller's message kept, so it tells the first
 * failure). */
static int after_cleanup(stc_conn *c, int rc, int cleanup_rc)
{
    if (cleanup_rc && rc != cleanup_rc) {
        size_t n = strlen(c->msg);
        snprintf(c->msg + n, sizeof c->msg - n, "%s(then interrupted while cleaning up)",
                 n ? " " : "");
        return cleanup_rc;
    }
    return rc;
}

static void abandon_all(stc_conn *c, const uint32_t *ids, int n)
{
    for (int i = 0; i < n; i++)
        stc__pend_abandon(c, ids[i]);
}

/* ---- upload ---------------------------------------------------------------------------------- */

static int upload_mem(stc_conn *c, const uint8_t *data, size_t len, const char *set,
                      const char *hint, const stc_upload_opts *o, stc_upload_result *out)
{
    stp_upload_begin bg;
    stp_upload_begin_reply br;
    stc_frame f;
    const char *why = NULL;
    uint32_t id, ids[XFER_WINDOW], crc, chunk;
    int rc, inflight = 0, win = window_size(c);
    uint64_t sent, acked;

    if ((rc = stc__check_name(c, set)) != 0)
        return rc;
    if (o && o->options && strlen(o->options) > STP_MAX_OPTIONS)
        return stc__fail(c, STC_EINVAL, "options longer than %d bytes", STP_MAX_OPTIONS);
    /* a path's long extension is no hint (ext_hint gives ""); a long hint the caller named
     * is refused, as an unknown short one is by the server (it used to be dropped silently,
     * and the file imported by its magic) */
    if (hint && strlen(hint) > STP_MAX_HINT)
        return stc__fail(c, STC_EINVAL, "hint '%.40s' is longer than %d bytes", hint,
                         STP_MAX_HINT);
    if (o && (o->flags & ~(unsigned)(STC_UPLOAD_REPLACE | STC_UPLOAD_RESUME | STC_UPLOAD_REPLICA |
                                     STC_UPLOAD_STAGE)))
        return stc__fail(c, STC_EINVAL, "unknown upload flags 0x%x", o->flags);
    crc = stp_crc32c(0, data, len);

    memset(&bg, 0, sizeof bg);
    snprintf(bg.name, sizeof bg.name, "%s", set);
    snprintf(bg.hint, sizeof bg.hint, "%s", hint ? hint : "");
    snprintf(bg.options, sizeof bg.options, "%s", o && o->options ? o->options : "");
    bg.total_size = len;
    bg.crc32c = crc;
    bg.flags = (o && (o->flags & STC_UPLOAD_REPLACE) ? STP_UF_REPLACE : 0) |
               (o && (o->flags & STC_UPLOAD_RESUME) ? STP_UF_RESUME : 0) |
               (o && (o->flags & STC_UPLOAD_REPLICA) ? STP_UF_REPLICA : 0) |
               (o && (o->flags & STC_UPLOAD_STAGE) ? STP_UF_STAGE : 0);
    if ((rc = start_req(c, STP_OP_UPLOAD_BEGIN, &id)) != 0 ||
        (rc = xfer_encoded(c, stp_enc_upload_begin(&c->out, id, (uint32_t)c->timeout_ms, &bg))) != 0 ||
        (rc = roundtrip(c, id, &f)) != 0)
        return rc;
    if (stp_dec_upload_begin_reply(f.body, f.h.body_len, &br, &why) != 0)
        return stc__break(c, STC_EPROTO, "malformed UPLOAD_BEGIN reply: %s", why);
    if (br.received > len) {
        (void)cleanup_call(c, STP_OP_UPLOAD_ABORT, br.upload_id, 0);   /* then sticky EPROTO */
        return stc__break(c, STC_EPROTO, "the server holds more bytes than the file has");
    }

    chunk = o && o->chunk ? o->chunk : XFER_DEFAULT_CHUNK;
    if (br.max_chunk && chunk > br.max_chunk)
        chunk = br.max_chunk;
    if (c->server.max_body > 64 && chunk > c->server.max_body - 64)
        chunk = c->server.max_body - 64;
    if (chunk == 0)
        chunk = 1;

    sent = acked = br.received;
    while (acked < len) {
        while (inflight < win && sent < len) {
            stp_upload_chunk ch;
            uint64_t left = len - sent;
            ch.upload_id = br.upload_id;
            ch.offset = sent;
            ch.len = left < chunk ? (uint32_t)left : chunk;
            ch.data = data + sent;
            if ((rc = start_req(c, STP_OP_UPLOAD_CHUNK, &id)) != 0 ||
                (rc = xfer_encoded(c, stp_enc_upload_chunk(&c->out, id, (uint32_t)c->timeout_ms,
                                                      &ch))) != 0)
                goto fail;
            ids[inflight++] = id;
            sent += ch.len;
        }
        int64_t dl = stc__deadline(c->timeout_ms);
        if ((rc = stc__flush(c, dl)) != 0)
            goto fail;
        if ((rc = stc__wait(c, 0, 1, dl, &f)) != 0)
            goto fail;
        /* The window is a FIFO of our ids; with an out-of-order server, find the one. */
        int k;
        for (k = 0; k < inflight && ids[k] != f.h.reqid; k++)
            ;
        if (k == inflight) {
            rc = stc__break(c, STC_EPROTO, "reply to request %u during an upload",
                            (unsigned)f.h.reqid);
            goto fail;
        }
        memmove(ids + k, ids + k + 1, (size_t)(inflight - k - 1) * sizeof *ids);
        inflight--;
        if (f.h.status) {
            rc = stc__status_error(c, &f);
            goto fail;
        }
        stp_upload_progress pg;
        if (stp_dec_upload_progress(f.body, f.h.body_len, &pg, &why) != 0) {
            rc = stc__break(c, STC_EPROTO, "malformed UPLOAD_CHUNK reply: %s", why);
            goto fail;
        }
        if (pg.received > acked)
            acked = pg.received;
        if (c->hold) {
            stp_buf_consume(&c->in, c->hold);
            c->hold = 0;
        }
        if (o && o->progress && o->progress(o->user, acked, len) != 0) {
            rc = stc__fail(c, STC_ECANCELED, "upload cancelled by the progress callback");
            goto fail;
        }
    }

    if ((rc = start_req(c, STP_OP_UPLOAD_COMMIT, &id)) != 0 ||
        (rc = xfer_encoded(c, stp_enc_id_req(&c->out, STP_OP_UPLOAD_COMMIT, id,
                                        (uint32_t)c->timeout_ms, br.upload_id))) != 0)
        goto fail;
    if ((rc = roundtrip(c, id, &f)) != 0) {
        /* A failed commit has dropped the upload on the server already; a timed-out one
         * may still finish, so abort it explicitly. */
        if (stc__gave_up(rc))
            rc = after_cleanup(c, rc, cleanup_call(c, STP_OP_UPLOAD_ABORT, br.upload_id, rc));
        return rc;
    }
    if (out) {
        stp_upload_done dn;
        if (stp_dec_upload_done(f.body, f.h.body_len, &dn, &why) != 0)
            return stc__break(c, STC_EPROTO, "malformed UPLOAD_COMMIT reply: %s", why);
        memset(out, 0, sizeof *out);
        snprintf(out->name, sizeof out->name, "%s", dn.name);
        out->kind = dn.kind;
        out->nchan = dn.nchan;
        out->dtype = dn.dtype;
        out->nfaces = dn.nfaces;
        out->memory = dn.memory;
        out->crc32c = crc;
        out->resumed_from = br.received;
    }
    return 0;

fail:
    abandon_all(c, ids, inflight);
    rc = after_cleanup(c, rc, cleanup_call(c, STP_OP_UPLOAD_ABORT, br.upload_id, rc));
    return rc;
}

static const char *ext_hint(const char *path)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash) || strlen(dot + 1) > STP_MAX_HINT)
        return "";
    return dot + 1;
}

int stc_upload_buffer(stc_conn *c, const void *data, size_t len, const char *set,
                      const stc_upload_opts *o, stc_upload_result *out)
{
    int rc = stc__begin_blocking(c);
    if (rc)
        return rc;
    if (len && !data)
        return stc__fail(c, STC_EINVAL, "data is NULL");
    return upload_mem(c, (const uint8_t *)data, len, set, o && o->hint ? o->hint : "", o, out);
}

int stc_upload_file(stc_conn *c, const char *path, const char *set, const stc_upload_opts *o,
                    stc_upload_result *out)
{
    struct stat st;
    void *map = NULL;
    int fd, rc = stc__begin_blocking(c);
    if (rc)
        return rc;
    if (!path)
        return stc__fail(c, STC_EINVAL, "path is NULL");
    fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return stc__fail(c, STC_EFILE, "%s: %s", path, strerror(errno));
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        close(fd);
        return stc__fail(c, STC_EFILE, "%s: not a regular file", path);
    }
    if (st.st_size > 0) {
        map = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
        if (map == MAP_FAILED) {
            rc = errno;
            close(fd);
            return stc__fail(c, STC_EFILE, "%s: mmap: %s", path, strerror(rc));
        }
    }
    close(fd);
    rc = upload_mem(c, (const uint8_t *)map, (size_t)st.st_size, set,
                    o && o->hint ? o->hint : ext_hint(path), o, out);
    if (map)
        munmap(map, (size_t)st.st_size);
    return rc;
}

/* ---- fetch -------------------------------------------------------------------------------------- */

int stc_fetch_format_for_path(const char *path)
{
    const char *dot = path ? strrchr(path, '.') : NULL, *slash = path ? strrchr(path, '/') : NULL;
    if (!dot || (slash && dot < slash))
        return -1;
    return stp_fetch_format_parse(dot + 1);
}

int stc_fetch_file(stc_conn *c, const char *set, unsigned format, const char *path,
                   stc_progress_fn progress, void *user)
{
    stp_fetch_open fo;
    stp_fetch_open_reply fr;
    stc_frame f;
    const char *why = NULL;
    char part[4096];
    uint32_t id, ids[XFER_WINDOW], chunk, crc = 0;
    uint64_t asked = 0, got = 0;
    int rc, fd = -1, inflight = 0;
    int win = (c && (c->server.caps & STP_CAP_OUT_OF_ORDER)) ? 1 : 0;

    if ((rc = stc__begin_blocking(c)) != 0)
        return rc;
    if (!win)
        win = window_size(c);
    if (path && format == STC_FETCH_AUTO) {
        int f = stc_fetch_format_for_path(path);
        format = f < 0 ? STC_FETCH_PTX : (unsigned)f;   /* no known extension: Ptex */
    }
    if ((rc = stc__check_name(c, set)) != 0)
        return rc;
    if (!path)
        return stc__fail(c, STC_EINVAL, "path is NULL");
    if (!stp_fetch_format_name(format))
        return stc__fail(c, STC_EINVAL, "fetch format %u is not one libseamtex knows", format);
    if ((size_t)snprintf(part, sizeof part, "%s.part", path) >= sizeof part)
        return stc__fail(c, STC_EINVAL, "path too long");

    memset(&fo, 0, sizeof fo);
    snprintf(fo.name, sizeof fo.name, "%s", set);
    fo.format = (uint8_t)format;
    if ((rc = start_req(c, STP_OP_FETCH_OPEN, &id)) != 0 ||
        (rc = xfer_encoded(c, stp_enc_fetch_open(&c->out, id, (uint32_t)c->timeout_ms, &fo))) != 0 ||
        (rc = roundtrip(c, id, &f)) != 0)
        return rc;
    if (stp_dec_fetch_open_reply(f.body, f.h.body_len, &fr, &why) != 0)
        return stc__break(c, STC_EPROTO, "malformed FETCH_OPEN reply: %s", why);
    chunk = fr.max_chunk ? fr.max_chunk : STP_DEFAULT_MAX_CHUNK;
    if (chunk > XFER_DEFAULT_CHUNK)
        chunk = XFER_DEFAULT_CHUNK;

    fd = open(part, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
        rc = stc__fail(c, STC_EFILE, "%s: %s", part, strerror(errno));
        goto fail;
    }
    while (got < fr.total_size) {
        while (inflight < win && asked < fr.total_size) {
            stp_fetch_read rd = { fr.fetch_id, asked, chunk };
            if ((rc = start_req(c, STP_OP_FETCH_READ, &id)) != 0 ||
                (rc = xfer_encoded(c, stp_enc_fetch_read(&c->out, id, (uint32_t)c->timeout_ms,
                                                    &rd))) != 0)
                goto fail;
            ids[inflight++] = id;
            asked += fr.total_size - asked < chunk ? fr.total_size - asked : chunk;
        }
        int64_t dl = stc__deadline(c->timeout_ms);
        if ((rc = stc__flush(c, dl)) != 0 || (rc = stc__wait(c, ids[0], 0, dl, &f)) != 0)
            goto fail;
        memmove(ids, ids + 1, (size_t)(inflight - 1) * sizeof *ids);
        inflight--;
        if (f.h.status) {
            rc = stc__status_error(c, &f);
            goto fail;
        }
        stp_fetch_data fd_;
        if (stp_dec_fetch_data(f.body, f.h.body_len, &fd_, &why) != 0) {
            rc = stc__break(c, STC_EPROTO, "malformed FETCH_READ reply: %s", why);
            goto fail;
        }
        if (fd_.offset != got || fd_.len == 0 || fd_.len > fr.total_size - got) {
            rc = stc__break(c, STC_EPROTO, "FETCH_READ returned offset %llu len %u, expected "
                            "offset %llu", (unsigned long long)fd_.offset, (unsigned)fd_.len,
                            (unsigned long long)got);
            goto fail;
        }
        if (stu_write_all(fd, fd_.data, fd_.len) != 0) {
            rc = stc__fail(c, STC_EFILE, "%s: write: %s", part, strerror(errno));
            goto fail;
        }
        crc = stp_crc32c(crc, fd_.data, fd_.len);
        got += fd_.len;
        if (c->hold) {
            stp_buf_consume(&c->in, c->hold);
            c->hold = 0;
        }
        if (progress && progress(user, got, fr.total_size) != 0) {
            rc = stc__fail(c, STC_ECANCELED, "fetch cancelled by the progress callback");
            goto fail;
        }
    }
    if (crc != fr.crc32c) {
        rc = stc__fail(c, STC_ECHECKSUM, "CRC32C of the download is %08x, the server said %08x",
                       crc, fr.crc32c);
        goto fail;
    }
    if (fsync(fd) != 0 || close(fd) != 0) {
        fd = -1;
        rc = stc__fail(c, STC_EFILE, "%s: %s", part, strerror(errno));
        goto fail;
    }
    fd = -1;
    if (rename(part, path) != 0) {
        rc = stc__fail(c, STC_EFILE, "rename %s: %s", path, strerror(errno));
        goto fail;
    }
    /* the file is complete; an interrupt while closing still says so (the hook's rule) */
    if ((rc = cleanup_call(c, STP_OP_FETCH_CLOSE, fr.fetch_id, 0)) != 0)
        return stc__fail(c, rc, "interrupted closing the fetch (%s is complete)", path);
    return 0;

fail:
    abandon_all(c, ids, inflight);
    rc = after_cleanup(c, rc, cleanup_call(c, STP_OP_FETCH_CLOSE, fr.fetch_id, rc));
    if (fd >= 0)
        close(fd);
    unlink(part);
    return rc;
}
