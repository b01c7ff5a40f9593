/* server/h_upload.c - the upload handlers, DELETE, and loading the data dir at start.
 *
 * Owns: the UPLOAD_* and DELETE handlers, import of a source file by format
 * (sts_import_path), publishing a committed set, the data-dir load callback. Does not own:
 * the table of uploads and their life (uploads.c), the on-disk commit protocol
 * (store/datadir.c), the registry (store/registry.c), the file readers (store/import.c).
 *
 * Chunks must come in order. COMMIT checks size and CRC32C, imports the file (the set is
 * validated before anything is published), commits it to the data dir (fsync + rename, see
 * datadir.h) and only then publishes it in the registry and replies OK. Without a data dir
 * the set lives in memory only. UPLOAD_BEGIN with RESUME takes over a kept upload (uploads.h).
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "server.h"
#include "uploads.h"
#include "import.h"
#include "native.h"
#include "ptex.h"

/* ---- importing --------------------------------------------------------------------------- */

/* The extension a source of this content gets on disk (importers key on it when the content
 * has no magic, e.g. OBJ). */
static const char *sniff_ext(const uint8_t *p, size_t n)
{
    if (n >= 4 && !memcmp(p, "Ptex", 4)) return "ptx";
    if (n >= 4 && p[0] == 0x76 && p[1] == 0x2f && p[2] == 0x31 && p[3] == 0x01) return "exr";
    if (n >= 4 && !memcmp(p, "\x89PNG", 4)) return "png";
    if (n >= 3 && p[0] == 0xFF && p[1] == 0xD8 && p[2] == 0xFF) return "jpg";
    if (n >= 4 && (!memcmp(p, "II*\0", 4) || !memcmp(p, "MM\0*", 4))) return "tif";
    if (n >= 2 && !memcmp(p, "#?", 2)) return "hdr";
    if (n >= 5 && !memcmp(p, "DRACO", 5)) return "drc";
    if (n >= 4 && !memcmp(p, "DDS ", 4)) return "dds";
    return "obj";  /* text without magic: the only text format the importer reads */
}

int sts_import_path(sts_server *srv, const char *path, const char *fmt, const char *options,
                    st_set **out, st_error *e)
{
    size_t max_bytes = (size_t)STS_LIVE(srv, max_set_bytes);
    *out = NULL;
    (void)fmt; /* the importer goes by the content's magic (the extension came from it) */
    st_import_opts o;
    st_import_opts_init(&o);
    o.max_bytes = max_bytes;
    st_setref *tex = NULL;
    char opts[STP_MAX_OPTIONS + 1];
    snprintf(opts, sizeof opts, "%s", options ? options : "");
    for (char *save = NULL, *tok = strtok_r(opts, " ", &save); tok; tok = strtok_r(NULL, " ", &save)) {
        char *eq = strchr(tok, '=');
        if (!eq) {
            st_setref_release(tex);
            return st_fail(e, ST_EINVAL, "option '%s' is not key=value", tok);
        }
        *eq = 0;
        const char *k = tok, *v = eq + 1;
        if (!strcmp(k, "texture")) {
            st_setref_release(tex);
            tex = NULL;
            if (st_registry_get(srv->reg, v, &tex, NULL) != 0)
                return st_fail(e, ST_EBUSY, "texture set '%.64s' is not loaded (upload it first)", v);
            o.texture = tex->set;
        } else if (!strcmp(k, "cube")) {
            char kind[32];
            unsigned size = 0;
            snprintf(kind, sizeof kind, "%s", v);
            char *colon = strchr(kind, ':');
            if (colon) {
                *colon = 0;
                size = (unsigned)strtoul(colon + 1, NULL, 10);
            }
            static const struct { const char *n; int v; } kinds[] = {
                {"none", ST_IMPORT_CUBE_NONE}, {"auto", ST_IMPORT_CUBE_AUTO},
                {"strip_v", ST_IMPORT_CUBE_STRIP_V}, {"strip_h", ST_IMPORT_CUBE_STRIP_H},
                {"cross_h", ST_IMPORT_CUBE_CROSS_H}, {"cross_v", ST_IMPORT_CUBE_CROSS_V},
                {"latlong", ST_IMPORT_CUBE_LATLONG}, {"ptex", ST_IMPORT_CUBE_PTEX}};
            int found = -1;
            for (size_t i = 0; i < sizeof kinds / sizeof kinds[0]; i++)
                if (!strcmp(kinds[i].n, kind))
                    found = kinds[i].v;
            if (found < 0) {
                st_setref_release(tex);
                return st_fail(e, ST_EINVAL, "cube=%s: not one of none auto strip_v strip_h "
                               "cross_h cross_v latlong ptex", kind);
            }
            o.cube = (uint8_t)found;
            o.face_size = size;
        } else if (!strcmp(k, "colorspace")) {
            o.colorspace = !strcmp(v, "srgb") ? ST_IMPORT_CS_SRGB
                         : !strcmp(v, "linear") ? ST_IMPORT_CS_LINEAR : ST_IMPORT_CS_AUTO;
        } else {
            st_setref_release(tex);
            return st_fail(e, ST_EINVAL, "unknown option '%s' (texture, cube, colorspace)", k);
        }
    }
    int rc = st_import_file(path, &o, out, e);
    st_setref_release(tex);
    return rc;
}

/* ---- publishing ---------------------------------------------------------------------------- */

typedef struct publish_arg {
    sts_server *srv;
    st_set     *set;        /* ownership passes to the registry */
    int         replaced;
    st_error   *e;
} publish_arg;

static int publish_cb(void *arg, const st_manifest *m, const char *source_path)
{
    (void)source_path;
    publish_arg *pa = arg;
    st_set_source src = {m->bytes, m->crc, m->format};
    st_set *s = pa->set;
    pa->set = NULL;
    return st_registry_put(pa->srv->reg, m->name, s, &src, STS_LIVE(pa->srv, max_sets),
                           &pa->replaced, pa->e);
}

typedef struct load_arg {
    sts_server *srv;
    int         failed;
} load_arg;

static int import_cb(void *arg, const st_manifest *m, const char *source_path, st_set **out,
                     st_error *e)
{
    load_arg *la = arg;
    int rc = sts_import_path(la->srv, source_path, m->format, m->options, out, e);
    if (rc && rc != ST_EBUSY)
        sts_logf(&la->srv->log, STS_ERROR, "data dir: set '%s' (%s) does not import: %s",
                 m->name, source_path, e->msg);
    return rc;
}

static int load_publish_cb(void *arg, const st_manifest *m, st_set *set, st_error *e)
{
    load_arg *la = arg;
    st_set_source src = {m->bytes, m->crc, m->format};
    int mapped = set && set->map;
    int rc = st_registry_put(la->srv->reg, m->name, set, &src, 0, NULL, e);
    if (rc)
        sts_logf(&la->srv->log, STS_ERROR, "data dir: set '%s': %s", m->name, e->msg);
    else
        sts_logf(&la->srv->log, STS_DEBUG, "data dir: loaded '%s' (%s, %llu bytes, %s)", m->name,
                 m->format, (unsigned long long)m->bytes, mapped ? "native file" : "in memory");
    return rc;
}

static void report_cb(void *arg, const char *name, const char *why)
{
    load_arg *la = arg;
    la->failed++;
    sts_logf(&la->srv->log, STS_WARN, "data dir: set '%s': %s", name, why);
}

static void note_cb(void *arg, const char *name, const char *what)
{
    load_arg *la = arg;
    if (name[0])
        sts_logf(&la->srv->log, STS_INFO, "data dir: set '%s': %s", name, what);
    else
        sts_logf(&la->srv->log, STS_INFO, "data dir: %s", what);
}

int sts_load_datadir(sts_server *srv)
{
    if (!srv->dd)
        return 0;
    load_arg la = {srv, 0};
    st_error e;
    st_error_clear(&e);
    int built = 0;
    int64_t t0 = sts_now_ms();
    st_datadir_loader L = {.arg = &la, .import = import_cb, .publish = load_publish_cb,
                           .report = report_cb, .note = note_cb,
                           .native_flags = srv->cfg.verify_native ? ST_NATIVE_VERIFY : 0,
                           .no_native = !srv->cfg.native, .built = &built};
    int n = st_datadir_load_sets(srv->dd, &L, &e);
    if (n < 0) {
        sts_logf(&srv->log, STS_ERROR, "data dir %s: %s", st_datadir_path(srv->dd), e.msg);
        return n;
    }
    if (srv->cfg.native)
        sts_logf(&srv->log, STS_INFO, "data dir %s: %d sets loaded (%d mapped from native files, "
                 "%d native files built), %d set aside or cleaned, %lld ms",
                 st_datadir_path(srv->dd), n, n - built, built, la.failed,
                 (long long)(sts_now_ms() - t0));
    else
        sts_logf(&srv->log, STS_INFO, "data dir %s: %d sets imported (--native no), %d set aside "
                 "or cleaned, %lld ms", st_datadir_path(srv->dd), n, la.failed,
                 (long long)(sts_now_ms() - t0));
    return n;
}

/* ---- handlers -------------------------------------------------------------------------------- */

int sts_h_upload_begin(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    stp_upload_begin rq;
    const char *why = NULL;
    int st = stp_dec_upload_begin(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    st_error e;   /* rq.name follows the name rule: stp_dec_upload_begin checked it */
    st_error_clear(&e);
    if (rq.hint[0] && st_format_check(rq.hint, &e) != 0) {
        sts_reply_st(out, h, ST_EINVAL, e.msg);
        return 0;
    }
    for (const char *p = rq.options; *p; p++)
        if ((unsigned char)*p < 0x20 || (unsigned char)*p > 0x7e)
            return sts_reply_bad(out, h, STP_S_INVALID, "options must be printable ASCII");
    uint64_t max_up = STS_LIVE(srv, max_upload);
    if (rq.total_size > max_up) {
        char msg[128];
        snprintf(msg, sizeof msg, "upload of %llu bytes is over max-upload %llu",
                 (unsigned long long)rq.total_size, (unsigned long long)max_up);
        sts_reply_error(out, h, STP_S_TOO_LARGE, msg);
        return 0;
    }
    if (rq.flags & STP_UF_RESUME) {
        uint64_t id = 0, received = 0;
        int found = sts_uploads_adopt(srv, &rq, c->conn->id, &id, &received);
        if (found > 0) {
            STS_STAT_ADD(srv, uploads_resumed, 1);
            sts_logf(&srv->log, STS_INFO, "upload of '%s' resumed at %llu of %llu bytes%s", rq.name,
                     (unsigned long long)received, (unsigned long long)rq.total_size,
                     received == rq.total_size ? " (complete: COMMIT repeats or finishes it)" : "");
            stp_upload_begin_reply r = {id, received, STP_DEFAULT_MAX_CHUNK};
            stp_enc_upload_begin_reply(out, h->reqid, &r);
            return 0;
        }
        if (found < 0) {
            sts_reply_error(out, h, STP_S_BUSY, "that upload is held by another connection or "
                            "being committed (retry shortly)");
            return 0;
        }
        /* nothing to resume: a fresh upload, received 0 */
    }
    if (!(rq.flags & STP_UF_REPLACE)) {
        st_setref *ref = NULL;
        if (st_registry_get(srv->reg, rq.name, &ref, NULL) == 0) {
            st_setref_release(ref);
            sts_reply_error(out, h, STP_S_EXISTS, "a set of that name exists (use REPLACE)");
            return 0;
        }
    }
    sts_upload *u = calloc(1, sizeof *u);
    if (!u) {
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    u->fd = -1;
    snprintf(u->name, sizeof u->name, "%s", rq.name);
    snprintf(u->hint, sizeof u->hint, "%s", rq.hint);
    snprintf(u->fmt, sizeof u->fmt, "%s", rq.hint);
    snprintf(u->options, sizeof u->options, "%s", rq.options);
    u->total = rq.total_size;
    u->crc_want = rq.crc32c;
    u->flags = rq.flags & ~(uint32_t)STP_UF_RESUME;
    u->conn_id = c->conn->id;
    int rc;
    if (srv->dd) {
        rc = st_datadir_tmpfile(srv->dd, u->path, sizeof u->path, &u->fd, &e);
    } else {
        const char *tmp = getenv("TMPDIR");
        snprintf(u->path, sizeof u->path, "%s/seamtexd-upload-XXXXXX", tmp && *tmp ? tmp : "/tmp");
        u->fd = mkostemp(u->path, O_CLOEXEC);
        rc = u->fd < 0 ? st_fail(&e, ST_EIO, "temp file: %s", strerror(errno)) : 0;
        if (rc)
            u->path[0] = 0;
    }
    if (rc) {
        u->path[0] = 0;
        sts_upload_free(u);
        sts_reply_st(out, h, rc, e.msg);
        return 0;
    }
    if (sts_uploads_insert(srv, u) != 0) {
        sts_upload_free(u);
        sts_reply_error(out, h, STP_S_BUSY, "too many uploads in progress (max-uploads)");
        return 0;
    }
    STS_STAT_ADD(srv, uploads_begun, 1);
    stp_upload_begin_reply r = {u->id, 0, STP_DEFAULT_MAX_CHUNK};
    stp_enc_upload_begin_reply(out, h->reqid, &r);
    return 0;
}

int sts_h_upload_chunk(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_upload_chunk rq;
    const char *why = NULL;
    int st = stp_dec_upload_chunk(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    /* only this connection uses the upload, and its requests run one at a time */
    sts_upload *u = sts_uploads_find(c->srv, rq.upload_id, c->conn->id, 0);
    if (!u) {
        sts_reply_error(out, h, STP_S_NOT_FOUND, "no such upload on this connection");
        return 0;
    }
    if (rq.offset != u->received) {
        char msg[128];
        snprintf(msg, sizeof msg, "chunk offset %llu, the server has %llu bytes",
                 (unsigned long long)rq.offset, (unsigned long long)u->received);
        sts_reply_error(out, h, STP_S_INVALID, msg);
        return 0;
    }
    if (rq.len > STP_DEFAULT_MAX_CHUNK || rq.len > u->total - u->received) {
        sts_reply_error(out, h, STP_S_INVALID, "chunk passes the announced size or max_chunk");
        return 0;
    }
    size_t done = 0;
    while (done < rq.len) {
        ssize_t w = pwrite(u->fd, rq.data + done, rq.len - done, (off_t)(u->received + done));
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0) {
            char msg[128];
            snprintf(msg, sizeof msg, "write: %s", strerror(errno));
            sts_reply_error(out, h, STP_S_IO, msg);
            return 0;
        }
        done += (size_t)w;
    }
    u->crc = stp_crc32c(u->crc, rq.data, rq.len);
    u->received += rq.len;
    STS_STAT_ADD(c->srv, upload_bytes, rq.len);
    stp_upload_progress p = {u->received, u->total};
    stp_enc_upload_progress(out, h->opcode, h->reqid, &p);
    return 0;
}

int sts_h_upload_commit(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    uint64_t id;
    const char *why = NULL;
    int st = stp_dec_id_req(body, h->body_len, &id, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    stp_upload_done again;
    if (sts_uploads_done_reply(srv, id, c->conn->id, &again)) {
        /* committed before and its reply lost (taken over with RESUME): the same reply */
        stp_enc_upload_done(out, h->reqid, &again);
        return 0;
    }
    sts_upload *u = sts_uploads_find(srv, id, c->conn->id, 2);
    if (!u) {
        sts_reply_error(out, h, STP_S_NOT_FOUND, "no such upload on this connection");
        return 0;
    }
    st_error e;
    st_error_clear(&e);
    char msg[400];
    if (u->received != u->total) {
        snprintf(msg, sizeof msg, "upload has %llu of %llu bytes", (unsigned long long)u->received,
                 (unsigned long long)u->total);
        sts_reply_error(out, h, STP_S_INVALID, msg);
        goto fail;
    }
    if (u->crc != u->crc_want) {
        snprintf(msg, sizeof msg, "CRC32C of the upload is %08x, %08x was announced", u->crc,
                 u->crc_want);
        sts_reply_error(out, h, STP_S_CORRUPT, msg);
        goto fail;
    }
    close(u->fd);
    u->fd = -1;
    /* the file gets the extension of its format, so importers that key on it find it */
    if (!u->fmt[0]) {
        uint8_t head[16] = {0};
        int fd = open(u->path, O_RDONLY | O_CLOEXEC);
        ssize_t n = fd >= 0 ? read(fd, head, sizeof head) : -1;
        if (fd >= 0)
            close(fd);
        snprintf(u->fmt, sizeof u->fmt, "%s", sniff_ext(head, n > 0 ? (size_t)n : 0));
    }
    {
        char named[sizeof u->path];
        size_t pl = strlen(u->path), fl = strlen(u->fmt);
        if (pl + 1 + fl < sizeof named) {
            memcpy(named, u->path, pl);
            named[pl] = '.';
            memcpy(named + pl + 1, u->fmt, fl + 1);
            if (rename(u->path, named) == 0)
                memcpy(u->path, named, pl + fl + 2);
        }
    }
    st_set *set = NULL;
    int rc = sts_import_path(srv, u->path, u->fmt, u->options, &set, &e);
    if (rc) {
        if (rc == ST_EBUSY)
            rc = ST_ENOTFOUND;  /* a texture= set that is not there */
        sts_reply_st(out, h, rc, e.msg);
        goto fail;
    }
    /* two uploads of one new name must not both succeed: check and commit under one lock */
    pthread_mutex_lock(&srv->commit_mu);
    {
        st_setref *ref = NULL;
        int exists = st_registry_get(srv->reg, u->name, &ref, NULL) == 0;
        st_setref_release(ref);
        if (exists && !(u->flags & STP_UF_REPLACE)) {
            pthread_mutex_unlock(&srv->commit_mu);
            st_set_free(set);
            sts_reply_error(out, h, STP_S_EXISTS, "a set of that name exists (use REPLACE)");
            goto fail;
        }
        /* refuse before the disk commit, so a set is never on disk but not served */
        if (!exists && st_registry_count(srv->reg) >= STS_LIVE(srv, max_sets)) {
            pthread_mutex_unlock(&srv->commit_mu);
            st_set_free(set);
            sts_reply_error(out, h, STP_S_BUSY, "the server holds max-sets sets");
            goto fail;
        }
    }
    stp_upload_done done;
    memset(&done, 0, sizeof done);
    snprintf(done.name, sizeof done.name, "%s", u->name);
    done.kind = set->info.kind;
    done.nchan = set->info.nchan;
    done.dtype = set->info.dtype;
    done.nfaces = set->info.nfaces;
    done.memory = st_set_memory(set);
    publish_arg pa = {srv, set, 0, &e};
    if (srv->dd) {
        /* writes the native file too; pa.set becomes the mapped set before publish_cb */
        rc = st_datadir_commit_set(srv->dd, u->name, u->path, u->fmt, u->options, u->total,
                                   srv->cfg.native ? &pa.set : NULL, publish_cb, &pa, &e);
        u->path[0] = 0;  /* the data dir owns (or removed) the file now */
        st_set_free(pa.set);  /* not published when the commit failed early */
    } else {
        st_manifest m;
        memset(&m, 0, sizeof m);
        snprintf(m.name, sizeof m.name, "%s", u->name);
        snprintf(m.format, sizeof m.format, "%s", u->fmt);
        m.bytes = u->total;
        rc = publish_cb(&pa, &m, u->path);
    }
    pthread_mutex_unlock(&srv->commit_mu);
    if (rc) {
        sts_reply_st(out, h, rc, e.msg);
        goto fail;
    }
    STS_STAT_ADD(srv, uploads_committed, 1);
    sts_logf(&srv->log, STS_INFO, "set '%s' %s from a %llu-byte .%s upload (%u faces, %llu bytes "
             "in memory)", done.name, pa.replaced ? "replaced" : "created",
             (unsigned long long)u->total, u->fmt, done.nfaces, (unsigned long long)done.memory);
    sts_uploads_finish_commit(srv, u, &done);
    stp_enc_upload_done(out, h->reqid, &done);
    return 0;
fail:
    STS_STAT_ADD(srv, uploads_failed, 1);
    sts_uploads_finish_commit(srv, u, NULL);
    return 0;
}

int sts_h_upload_abort(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    uint64_t id;
    const char *why = NULL;
    int st = stp_dec_id_req(body, h->body_len, &id, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    sts_upload *u = sts_uploads_find(c->srv, id, c->conn->id, 1);
    if (!u) {
        sts_reply_error(out, h, STP_S_NOT_FOUND, "no such upload on this connection");
        return 0;
    }
    sts_upload_free(u);
    stp_enc_empty(out, h->opcode, STP_F_REPLY, h->reqid, 0);
    return 0;
}

int sts_h_upload_status(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    uint64_t id;
    const char *why = NULL;
    int st = stp_dec_id_req(body, h->body_len, &id, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    /* the caller's own upload, or one kept for resume (copied under the table's lock: the
     * sweep may drop a kept upload at any time) */
    stp_upload_progress p = {0, 0};
    int found = sts_uploads_progress(c->srv, id, c->conn->id, &p);
    if (!found) {
        sts_reply_error(out, h, STP_S_NOT_FOUND, "no such upload on this connection or kept for resume");
        return 0;
    }
    stp_enc_upload_progress(out, h->opcode, h->reqid, &p);
    return 0;
}

static int unpublish_cb(void *arg, const char *name)
{
    sts_server *srv = arg;
    st_registry_remove(srv->reg, name, NULL);
    return 0;
}

int sts_h_delete(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    char name[STP_MAX_NAME + 1];
    const char *why = NULL;
    int st = stp_dec_name_req(body, h->body_len, name, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    st_error e;   /* name follows the name rule: stp_dec_name_req checked it */
    st_error_clear(&e);
    int rc = ST_ENOTFOUND;
    if (srv->dd)
        rc = st_datadir_delete(srv->dd, name, unpublish_cb, srv, &e);
    if (rc == ST_ENOTFOUND)  /* not on disk (in-memory set, or the built-in one) */
        rc = st_registry_remove(srv->reg, name, &e);
    if (rc) {
        sts_reply_st(out, h, rc, e.msg);
        return 0;
    }
    STS_STAT_ADD(srv, deletes, 1);
    sts_logf(&srv->log, STS_INFO, "set '%s' deleted", name);
    stp_enc_empty(out, h->opcode, STP_F_REPLY, h->reqid, 0);
    return 0;
}
