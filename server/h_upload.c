/* server/h_upload.c - the upload handlers and DELETE.
 *
 * Owns: the UPLOAD_*, REPLICA_PUBLISH and DELETE handlers, import of a source file by format and options
 * (sts_import_path, also used by the start-up load), publishing a committed set, publishing
 * or dropping a cluster write's staged copy (sts_publish_staged, sts_drop_staged). Does not
 * own: the table of uploads and their life (uploads.c), loading the data dir at start
 * (startup.c), the on-disk commit protocol (store/datadir.c), the registry
 * (store/registry.c), the file readers (store/import.c).
 *
 * Chunks must come in order. COMMIT checks size and CRC32C, imports the file (the set is
 * validated before anything is published), commits it to the data dir (fsync + rename, see
 * datadir.h) and only then publishes it in the registry and replies OK. Without a data dir
 * the set lives in memory only. UPLOAD_BEGIN with RESUME takes over a kept upload (uploads.h).
 * In a cluster (not a REPLICA push) the file is claimed, then staged (datadir.h "Staged
 * copies"), pushed and recorded (cluster_write.c), and published (sts_publish_staged) only
 * once recorded: a refused write drops its staged copy and leaves this node's copy as it was.
 * A REPLICA push with STAGE is staged likewise, and published by REPLICA_PUBLISH (or by the
 * repair pass, cluster_repair.c).
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cluster_node.h"
#include "dispatch.h"
#include "h_upload.h"
#include "import.h"
#include "io.h"
#include "native.h"
#include "ptex.h"
#include "server.h"
#include "stp_name.h"
#include "uploads.h"

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

/* The upload options through the store's one grammar (st_import_opts_parse, import.h), the
 * texture name held to the set-name rule (protocol/stp_name.h). Used at UPLOAD_BEGIN (so a bad
 * option is refused before any chunk is sent), at COMMIT and at start-up: one grammar.
 * ST_EINVAL with the parser's message. */
static int parse_options(const char *options, st_import_opts *o, char *texture, size_t cap,
                         st_error *e)
{
    int rc = st_import_opts_parse(options, o, texture, cap, e);
    if (rc == 0 && texture[0]) {
        int pr = stp_name_check(texture, strlen(texture), NULL);
        if (pr != STP_NAME_OK)
            rc = st_fail(e, ST_EINVAL, "texture=%.64s: %s", texture, stp_name_problem_text(pr));
    }
    return rc;
}

/* A format hint must be a source format the data dir can record (st_format_check) that the
 * importer knows by its extension (st_import_detect: the store's one list). */
static int hint_check(const char *hint, st_error *e)
{
    st_error ignore;
    char probe[STP_MAX_HINT + 3];
    snprintf(probe, sizeof probe, "x.%s", hint);
    if (st_format_check(hint, &ignore) != 0 || st_import_detect("", 0, probe) == ST_FMT_AUTO)
        return st_fail(e, ST_EINVAL, "format hint '%.15s' is not a format the server imports "
                       "(ptx penv exr png jpg jpeg tif tiff hdr tga bmp obj drc dds ...; empty: "
                       "detect)", hint);
    return 0;
}

int sts_import_path(sts_server *srv, const char *path, const char *fmt, const char *options,
                    int recorded, st_set **out, st_error *e)
{
    *out = NULL;
    (void)fmt; /* the importer goes by the content's magic (the extension came from it) */
    st_import_opts o;
    st_import_opts_init(&o);
    o.max_bytes = (size_t)STS_LIVE(srv, max_set_bytes);
    o.no_side_files = 1; /* the uploads folder holds other clients' uploads: never read them */
    o.cube_lenient = (uint8_t)(recorded != 0);
    char texture[STP_MAX_NAME + 1];
    int rc = parse_options(options, &o, texture, sizeof texture, e);
    if (rc)
        return rc;
    st_setref *tex = NULL;
    if (texture[0]) {
        if (st_registry_get(srv->reg, texture, &tex, NULL) != 0)
            return st_fail(e, ST_EBUSY, "texture set '%.64s' is not loaded (upload it first)",
                           texture);
        o.texture = tex->set;
    }
    rc = st_import_file(path, &o, out, e);
    st_setref_release(tex);
    /* a .ptx's levels past level 0 are made now, so that a corrupt one is refused here */
    if (rc == ST_OK && (rc = st_set_levels(*out, e)) != ST_OK) {
        st_set_free(*out);
        *out = NULL;
    }
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

int sts_publish_staged(sts_server *srv, const char *id, st_set *set, int *replaced, st_error *e)
{
    if (!set) {
        st_manifest m;
        char src[4096];
        int rc = st_datadir_staged_read(srv->dd, id, &m, src, sizeof src, e);
        if (!rc)
            rc = sts_import_path(srv, src, m.format, m.options, 1, &set, e);
        if (rc)
            return rc;
    }
    publish_arg pa = {srv, set, 0, e};
    pthread_mutex_lock(&srv->commit_mu);
    int rc = st_datadir_publish_staged(srv->dd, id, srv->cfg.native ? &pa.set : NULL,
                                       publish_cb, &pa, e);
    pthread_mutex_unlock(&srv->commit_mu);
    st_set_free(pa.set);  /* not published when the commit failed early */
    if (replaced)
        *replaced = pa.replaced;
    if (!rc && srv->cluster)
        STS_CL_ADD(srv->cluster, staged_published, 1);
    return rc;
}

void sts_drop_staged(sts_server *srv, const char *id, const char *why)
{
    st_error e;
    st_error_clear(&e);
    st_manifest m;
    int known = st_datadir_staged_read(srv->dd, id, &m, NULL, 0, &e) == 0;
    pthread_mutex_lock(&srv->commit_mu);
    int rc = st_datadir_drop_staged(srv->dd, id, &e);
    pthread_mutex_unlock(&srv->commit_mu);
    if (rc == ST_ENOTFOUND)
        return;   /* published or dropped by another thread meanwhile */
    if (rc == 0 && srv->cluster)
        STS_CL_ADD(srv->cluster, staged_dropped, 1);
    sts_logf(&srv->log, rc ? STS_WARN : STS_INFO, "cluster: staged copy %s of '%s' %s (%s)%s%s",
             id, known ? m.name : "?", rc ? "could not be dropped" : "dropped", why,
             rc ? ": " : "", rc ? e.msg : "");
}

/* ---- handlers -------------------------------------------------------------------------------- */

/* Refuses an upload request: the reply (its text through sts_reply_error, which keeps server
 * paths out) and a log line at WARN, the default level shows it, with the peer, the stage and
 * the reason (the log may name server paths: `logwhy`, NULL = the reply's text). */
static void refuse(sts_ctx *c, const stp_header *h, stp_buf *out, const char *name, int status,
                   const char *why, const char *logwhy)
{
    const char *op = stp_opcode_name(h->opcode);
    const char *sname = stp_status_name(status);
    sts_reply_error(out, h, status, why);
    sts_logkv(&c->srv->log, STS_WARN,
              STS_FIELDS(STS_FS("event", "upload_refused"), STS_FS("set", name),
                         STS_FS("peer", c->conn->peer), STS_FS("stage", op),
                         STS_FS("status", sname), STS_FS("reason", logwhy ? logwhy : why)),
              "upload%s%.255s%s from %s refused at %s (%s): %s",
              name && *name ? " of '" : "", name ? name : "", name && *name ? "'" : "",
              c->conn->peer, op ? op : "?", sname ? sname : "?", logwhy ? logwhy : why);
}

/* The same with a decoder's reason, as sts_reply_bad words it ("<OPCODE>: <why>"). */
static int refuse_bad(sts_ctx *c, const stp_header *h, stp_buf *out, int status, const char *why)
{
    const char *op = stp_opcode_name(h->opcode);
    char msg[200];
    snprintf(msg, sizeof msg, "%s: %s", op ? op : "request", why ? why : "malformed body");
    refuse(c, h, out, NULL, status, msg, NULL);
    return 0;
}

int sts_h_upload_begin(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    stp_upload_begin rq;
    const char *why = NULL;
    int st = stp_dec_upload_begin(body, h->body_len, &rq, &why);
    if (st)
        return refuse_bad(c, h, out, st, why);
    st_error e;   /* rq.name follows the name rule: stp_dec_upload_begin checked it */
    st_error_clear(&e);
    if (rq.hint[0] && hint_check(rq.hint, &e) != 0) {
        refuse(c, h, out, rq.name, STP_S_INVALID, e.msg, NULL);
        return 0;
    }
    for (const char *p = rq.options; *p; p++)
        if ((unsigned char)*p < 0x20 || (unsigned char)*p > 0x7e) {
            refuse(c, h, out, rq.name, STP_S_INVALID, "options must be printable ASCII", NULL);
            return 0;
        }
    {
        /* the options are checked now, with the grammar COMMIT uses, before any chunk */
        st_import_opts o;
        char texture[STP_MAX_NAME + 1];
        st_import_opts_init(&o);
        if (parse_options(rq.options, &o, texture, sizeof texture, &e) != 0) {
            refuse(c, h, out, rq.name, STP_S_INVALID, e.msg, NULL);
            return 0;
        }
    }
    if ((rq.flags & STP_UF_REPLICA) && !srv->cluster) {
        refuse(c, h, out, rq.name, STP_S_INVALID, "REPLICA uploads are for cluster nodes; this "
               "server is not in a cluster", NULL);
        return 0;
    }
    if (srv->cluster && !(rq.flags & STP_UF_REPLICA) && !sts_cluster_etcd_ok(srv->cluster)) {
        STS_CL_ADD(srv->cluster, refused_unavailable, 1);
        refuse(c, h, out, rq.name, STP_S_UNAVAILABLE, "cluster coordinator (etcd) unreachable: "
               "upload refused, retry later", NULL);
        return 0;
    }
    if (rq.flags & STP_UF_REPLICA)
        rq.flags |= STP_UF_REPLACE;   /* a copy replaces whatever this node holds */
    uint64_t max_up = STS_LIVE(srv, max_upload);
    if (rq.total_size > max_up) {
        char msg[128];
        snprintf(msg, sizeof msg, "upload of %llu bytes is over max-upload %llu",
                 (unsigned long long)rq.total_size, (unsigned long long)max_up);
        refuse(c, h, out, rq.name, STP_S_TOO_LARGE, msg, NULL);
        return 0;
    }
    if (rq.flags & STP_UF_RESUME) {
        uint64_t id = 0, received = 0;
        int found = sts_uploads_adopt(srv, &rq, c->conn->id, &id, &received);
        if (found > 0) {
            STS_STAT_ADD(srv, uploads_resumed, 1);
            sts_logkv(&srv->log, STS_INFO,
                      STS_FIELDS(STS_FS("event", "upload_resumed"), STS_FS("set", rq.name),
                                 STS_FS("peer", c->conn->peer), STS_FI("received", received),
                                 STS_FI("total", rq.total_size)),
                      "upload of '%s' resumed at %llu of %llu bytes%s", rq.name,
                      (unsigned long long)received, (unsigned long long)rq.total_size,
                      received == rq.total_size ? " (complete: COMMIT repeats or finishes it)"
                                                : "");
            stp_upload_begin_reply r = {id, received, STP_DEFAULT_MAX_CHUNK};
            stp_enc_upload_begin_reply(out, h->reqid, &r);
            return 0;
        }
        if (found < 0) {
            refuse(c, h, out, rq.name, STP_S_BUSY, "that upload is held by another connection "
                   "or being committed (retry shortly)", NULL);
            return 0;
        }
        /* nothing to resume: a fresh upload, received 0 */
    }
    if (!(rq.flags & STP_UF_REPLACE) && !srv->cluster) {
        /* (in a cluster the catalogue decides at COMMIT: this node may hold no copy) */
        st_setref *ref = NULL;
        if (st_registry_get(srv->reg, rq.name, &ref, NULL) == 0) {
            st_setref_release(ref);
            refuse(c, h, out, rq.name, STP_S_EXISTS, "a set of that name exists (use REPLACE)",
                   NULL);
            return 0;
        }
    }
    sts_upload *u = calloc(1, sizeof *u);
    if (!u) {
        refuse(c, h, out, rq.name, STP_S_NOMEM, "out of memory", NULL);
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
    u->hd.owner = c->conn->id;
    int rc;
    if (srv->dd) {
        rc = st_datadir_tmpfile(srv->dd, u->path, sizeof u->path, &u->fd, &e);
    } else {
        snprintf(u->path, sizeof u->path, "%s/seamtexd-upload-XXXXXX", srv->tmpdir);
        u->fd = mkostemp(u->path, O_CLOEXEC);
        rc = u->fd < 0 ? st_fail(&e, ST_EIO, "temp file %s: %s", u->path, strerror(errno)) : 0;
    }
    if (rc) {
        u->path[0] = 0;
        sts_upload_free(u);
        refuse(c, h, out, rq.name, sts_status_from_st(rc), e.msg, NULL);
        return 0;
    }
    sts_upload_room room = {0, 0, 0};
    int ins = sts_uploads_insert(srv, u, &room);
    if (ins == -2) {
        /* refused now rather than at a CHUNK once much of the file is sent (upl35); the
         * message ends with the errno text of a full disk, as the other refusals of one do */
        char msg[320];
        snprintf(msg, sizeof msg, "upload of %llu bytes does not fit: %llu bytes free on the "
                 "upload disk, %llu promised to uploads in progress, %llu kept free: %s",
                 (unsigned long long)rq.total_size, (unsigned long long)room.avail,
                 (unsigned long long)room.promised, (unsigned long long)room.headroom,
                 strerror(ENOSPC));
        sts_upload_free(u);
        refuse(c, h, out, rq.name, STP_S_IO, msg, NULL);
        return 0;
    }
    if (ins != 0) {
        sts_upload_free(u);
        refuse(c, h, out, rq.name, STP_S_BUSY, "too many uploads in progress (max-uploads)",
               NULL);
        return 0;
    }
    STS_STAT_ADD(srv, uploads_begun, 1);
    stp_upload_begin_reply r = {u->hd.id, 0, STP_DEFAULT_MAX_CHUNK};
    stp_enc_upload_begin_reply(out, h->reqid, &r);
    return 0;
}

int sts_h_upload_chunk(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_upload_chunk rq;
    const char *why = NULL;
    int st = stp_dec_upload_chunk(body, h->body_len, &rq, &why);
    if (st)
        return refuse_bad(c, h, out, st, why);
    /* only this connection uses the upload, and its requests run one at a time */
    sts_upload *u = sts_uploads_find(c->srv, rq.upload_id, c->conn->id, 0);
    if (!u) {
        refuse(c, h, out, NULL, STP_S_NOT_FOUND, "no such upload on this connection", NULL);
        return 0;
    }
    if (rq.offset != u->received) {
        char msg[128];
        snprintf(msg, sizeof msg, "chunk offset %llu, the server has %llu bytes",
                 (unsigned long long)rq.offset, (unsigned long long)u->received);
        refuse(c, h, out, u->name, STP_S_INVALID, msg, NULL);
        return 0;
    }
    if (rq.len > STP_DEFAULT_MAX_CHUNK) {
        /* not reached through io.c (the body cap is max_chunk + 20): the same status */
        refuse(c, h, out, u->name, STP_S_TOO_LARGE, "chunk is over max_chunk", NULL);
        return 0;
    }
    if (rq.len > u->total - u->received) {
        refuse(c, h, out, u->name, STP_S_INVALID, "chunk passes the announced total_size", NULL);
        return 0;
    }
    size_t done = 0;
    while (done < rq.len) {
        ssize_t w = pwrite(u->fd, rq.data + done, rq.len - done, (off_t)(u->received + done));
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0) {
            char msg[128], logmsg[sizeof u->path + 128];
            snprintf(msg, sizeof msg, "write: %s", strerror(errno));
            snprintf(logmsg, sizeof logmsg, "write %s: %s", u->path, strerror(errno));
            refuse(c, h, out, u->name, STP_S_IO, msg, logmsg);
            return 0;
        }
        done += (size_t)w;
    }
    u->crc = stp_crc32c(u->crc, rq.data, rq.len);
    /* after the bytes are on disk: the disk check of another BEGIN reads it (uploads.h) */
    __atomic_store_n(&u->received, u->received + rq.len, __ATOMIC_RELEASE);
    STS_STAT_ADD(c->srv, upload_bytes, rq.len);
    stp_upload_progress p = {u->received, u->total};
    stp_enc_upload_progress(out, h->opcode, h->reqid, &p);
    return 0;
}

/* A store message about the upload's temp file, for the reply: every mention of the file
 * becomes "upload '<name>'", and a message that does not mention it starts with that, so the
 * reply names the set and the reason (sts_reply_error then hides any other server path). */
static void name_for_path(const char *msg, const char *path, const char *name, char *out,
                          size_t cap)
{
    size_t n = 0, pl = strlen(path);
    char who[ST_NAME_MAX + 16];
    snprintf(who, sizeof who, "upload '%s'", name);
    if (!pl || !strstr(msg, path))
        n = (size_t)snprintf(out, cap, "%s: ", who);
    for (const char *p = msg; *p && n + 1 < cap;) {
        if (pl && !strncmp(p, path, pl)) {
            for (const char *q = who; *q && n + 1 < cap; q++)
                out[n++] = *q;
            p += pl;
            while (*p && *p != ':' && *p != ' ' && *p != '\'')
                p++;   /* the extension the commit gave the file */
        } else {
            out[n++] = *p++;
        }
    }
    out[n] = 0;
}

int sts_h_upload_commit(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    uint64_t id;
    const char *why = NULL;
    int st = stp_dec_id_req(body, h->body_len, &id, &why);
    if (st)
        return refuse_bad(c, h, out, st, why);
    stp_upload_done again;
    if (sts_uploads_done_reply(srv, id, c->conn->id, &again)) {
        /* committed before and its reply lost (taken over with RESUME): the same reply */
        stp_enc_upload_done(out, h->reqid, &again);
        return 0;
    }
    sts_upload *u = sts_uploads_find(srv, id, c->conn->id, 2);
    if (!u) {
        refuse(c, h, out, NULL, STP_S_NOT_FOUND, "no such upload on this connection", NULL);
        return 0;
    }
    st_error e;
    st_error_clear(&e);
    char msg[sizeof e.msg + ST_NAME_MAX + 64];
    if (u->received != u->total) {
        snprintf(msg, sizeof msg, "upload has %llu of %llu bytes", (unsigned long long)u->received,
                 (unsigned long long)u->total);
        refuse(c, h, out, u->name, STP_S_INVALID, msg, NULL);
        goto fail;
    }
    if (u->crc != u->crc_want) {
        snprintf(msg, sizeof msg, "CRC32C of the upload is %08x, %08x was announced", u->crc,
                 u->crc_want);
        refuse(c, h, out, u->name, STP_S_CORRUPT, msg, NULL);
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
    char tmp_path[sizeof u->path];   /* the name the store's messages use for the file */
    snprintf(tmp_path, sizeof tmp_path, "%s", u->path);
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
    /* a replica is a copy of a set a node accepted, perhaps one before session 32: recorded */
    int rc = sts_import_path(srv, u->path, u->fmt, u->options, (u->flags & STP_UF_REPLICA) != 0,
                             &set, &e);
    if (rc) {
        if (rc == ST_EBUSY)
            rc = ST_ENOTFOUND;  /* a texture= set that is not there */
        name_for_path(e.msg, tmp_path, u->name, msg, sizeof msg);
        refuse(c, h, out, u->name, sts_status_from_st(rc), msg, e.msg);
        goto fail;
    }
    /* in a cluster: claim the name in the catalogue first (docs/cluster.md "Writes") */
    sts_cl_claim claim;
    int clustered = srv->cluster && !(u->flags & STP_UF_REPLICA);
    /* the native file this commit writes, promised against the free disk beside the bodies
     * and native files promised to the other uploads (res36), or refused before it is written */
    if (srv->dd && srv->cfg.native && !clustered && !(srv->cluster && (u->flags & STP_UF_STAGE))) {
        uint64_t nbytes = 0;
        sts_upload_room room = {0, 0, 0};
        rc = st_native_size(set, &nbytes, &e);
        if (!rc && sts_uploads_promise_native(srv, u, u->path, nbytes, &room) != 0) {
            st_set_free(set);
            snprintf(msg, sizeof msg, "the set's native file of %llu bytes does not fit: %llu "
                     "bytes free on the data disk, %llu promised to uploads in progress, %llu "
                     "kept free: %s", (unsigned long long)nbytes, (unsigned long long)room.avail,
                     (unsigned long long)room.promised, (unsigned long long)room.headroom,
                     strerror(ENOSPC));
            refuse(c, h, out, u->name, STP_S_IO, msg, NULL);
            goto fail;
        }
        if (rc) {
            st_set_free(set);
            name_for_path(e.msg, tmp_path, u->name, msg, sizeof msg);
            refuse(c, h, out, u->name, sts_status_from_st(rc), msg, e.msg);
            goto fail;
        }
    }
    if (clustered) {
        uint64_t fbytes = 0;
        uint32_t fcrc = 0;
        int cst = st_file_crc(u->path, &fbytes, &fcrc, &e) == 0
                      ? sts_cluster_claim(srv->cluster, u->name, u->crc, fcrc, u->total, u->fmt,
                                          u->options, (u->flags & STP_UF_REPLACE) != 0, &claim,
                                          msg, sizeof msg)
                      : STP_S_IO;
        if (cst) {
            st_set_free(set);
            refuse(c, h, out, u->name, cst, cst == STP_S_IO ? "cannot read the upload" : msg, NULL);
            goto fail;
        }
    }
    /* two uploads of one new name must not both succeed: check and commit under one lock */
    pthread_mutex_lock(&srv->commit_mu);
    {
        st_setref *ref = NULL;
        int exists = st_registry_get(srv->reg, u->name, &ref, NULL) == 0;
        st_setref_release(ref);
        if (exists && !(u->flags & STP_UF_REPLACE) && !clustered) {
            pthread_mutex_unlock(&srv->commit_mu);
            st_set_free(set);
            refuse(c, h, out, u->name, STP_S_EXISTS, "a set of that name exists (use REPLACE)",
                   NULL);
            goto fail;
        }
        /* refuse before the disk commit, so a set is never on disk but not served */
        if (!exists && st_registry_count(srv->reg) >= STS_LIVE(srv, max_sets)) {
            pthread_mutex_unlock(&srv->commit_mu);
            if (clustered)
                sts_cluster_unclaim(srv->cluster, &claim);
            st_set_free(set);
            refuse(c, h, out, u->name, STP_S_BUSY, "the server holds max-sets sets", NULL);
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
    if (clustered) {
        /* staged, not published: the copy this node holds (and serves) stays the acknowledged
         * one until the write is recorded (docs/cluster.md "Writes": staged copies) */
        pthread_mutex_unlock(&srv->commit_mu);
        char sid[64];
        rc = st_datadir_stage(srv->dd, u->name, u->path, u->fmt, u->options, u->total, sid,
                              sizeof sid, &e);
        u->path[0] = 0;  /* the data dir owns (or removed) the file now */
        if (rc) {
            sts_cluster_unclaim(srv->cluster, &claim);
            st_set_free(set);
            name_for_path(e.msg, tmp_path, u->name, msg, sizeof msg);
            refuse(c, h, out, u->name, sts_status_from_st(rc), msg, e.msg);
            goto fail;
        }
        STS_CL_ADD(srv->cluster, copies_staged, 1);
        /* acknowledged only once W owners hold it durably and the catalogue says so */
        int cst = sts_cluster_replicate(srv->cluster, &claim, done.kind, sid, msg, sizeof msg);
        if (cst && !claim.repeat) {
            /* the write did not take effect: its copy goes, the old one stays served */
            st_set_free(set);
            sts_drop_staged(srv, sid, "the write was refused");
            refuse(c, h, out, u->name, cst, msg, NULL);
            goto fail;
        }
        /* recorded (or a repeat of the recorded contents): published here now */
        st_error pe;
        st_error_clear(&pe);
        int prc = sts_publish_staged(srv, sid, set, &pa.replaced, &pe);
        if (prc && prc != ST_ENOTFOUND)
            sts_logf(&srv->log, STS_WARN, "cluster: the recorded copy of '%s' is staged but "
                     "could not be published here yet (%s): the repair pass tries again",
                     u->name, pe.msg);
        if (cst) {
            refuse(c, h, out, u->name, cst, msg, NULL);
            goto fail;
        }
    } else if (srv->cluster && (u->flags & STP_UF_STAGE)) {
        /* a push of a write not recorded yet: staged until the writer's REPLICA_PUBLISH (or
         * this node's repair pass finds the write recorded); what this node serves stays */
        pthread_mutex_unlock(&srv->commit_mu);
        char sid[64];
        rc = st_datadir_stage(srv->dd, u->name, u->path, u->fmt, u->options, u->total, sid,
                              sizeof sid, &e);
        u->path[0] = 0;
        st_set_free(set);   /* imported again from the staged source when published */
        if (rc) {
            name_for_path(e.msg, tmp_path, u->name, msg, sizeof msg);
            refuse(c, h, out, u->name, sts_status_from_st(rc), msg, e.msg);
            goto fail;
        }
        STS_CL_ADD(srv->cluster, copies_received, 1);
        STS_CL_ADD(srv->cluster, copies_staged, 1);
    } else {
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
            name_for_path(e.msg, tmp_path, u->name, msg, sizeof msg);
            refuse(c, h, out, u->name, sts_status_from_st(rc), msg, e.msg);
            goto fail;
        }
        if (srv->cluster)
            STS_CL_ADD(srv->cluster, copies_received, 1);
    }
    STS_STAT_ADD(srv, uploads_committed, 1);
    sts_logkv(&srv->log, STS_INFO,
              STS_FIELDS(STS_FS("event", pa.replaced ? "set_replaced" : "set_created"),
                         STS_FS("set", done.name), STS_FS("peer", c->conn->peer),
                         STS_FS("format", u->fmt), STS_FI("bytes", u->total),
                         STS_FI("faces", done.nfaces), STS_FI("memory", done.memory)),
              "set '%s' %s from a %llu-byte .%s upload (%u faces, %llu bytes in memory)",
              done.name, pa.replaced ? "replaced" : "created", (unsigned long long)u->total,
              u->fmt, done.nfaces, (unsigned long long)done.memory);
    sts_uploads_finish_commit(srv, u, &done);
    stp_enc_upload_done(out, h->reqid, &done);
    return 0;
fail:
    STS_STAT_ADD(srv, uploads_failed, 1);
    sts_uploads_finish_commit(srv, u, NULL);
    return 0;
}

int sts_h_replica_publish(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    char name[STP_MAX_NAME + 1];
    uint32_t crc = 0;
    const char *why = NULL;
    int st = stp_dec_replica_publish(body, h->body_len, name, &crc, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    if (!srv->cluster || !srv->dd) {
        sts_reply_error(out, h, STP_S_UNSUPPORTED, "REPLICA_PUBLISH is for cluster nodes; this "
                        "server is not in a cluster");
        return 0;
    }
    st_error e;
    st_error_clear(&e);
    st_datadir_staged *s = NULL;
    size_t n = 0;
    int rc = st_datadir_staged_list(srv->dd, &s, &n, NULL, NULL, &e);
    if (rc) {
        sts_reply_st(out, h, rc, e.msg);
        return 0;
    }
    rc = ST_ENOTFOUND;
    for (size_t i = 0; rc == ST_ENOTFOUND && i < n; i++)
        if (!strcmp(s[i].m.name, name) && s[i].m.crc == crc) {
            st_error_clear(&e);
            rc = sts_publish_staged(srv, s[i].id, NULL, NULL, &e);
        }
    free(s);
    if (rc == ST_ENOTFOUND) {
        /* published already (this node's repair pass found the write recorded first)? */
        st_setref *ref = NULL;
        int got = st_registry_get(srv->reg, name, &ref, NULL) == 0;
        int have = got && ref->source_crc == crc;
        int stale = got && !have && ref->source_bytes;
        uint32_t mine = got ? ref->source_crc : 0;
        st_setref_release(ref);
        if (!have) {
            /* the write of other contents is recorded: a copy of other contents here is stale
             * (a holder that got no push: cluster_write.c), hidden until the repair pass that
             * drops it. Unless the catalogue, asked now, records this copy's contents: then
             * the message names contents nobody recorded (a client's mistake, pc32), and the
             * current copy stays served. With etcd unreachable the message cannot be checked
             * and is not believed: the copy stays served, as every copy is while etcd is away,
             * and the repair pass run as soon as etcd answers again decides (one unverifiable
             * message takes no set off the air; left33). */
            int rec = stale ? sts_cluster_records(srv->cluster, name, mine) : 0;
            if (rec == 1) {
                sts_reply_error(out, h, STP_S_NOT_FOUND, "no staged copy of that set and crc32; "
                                "the catalogue records this node's copy, which stays served");
            } else if (rec < 0) {
                sts_cluster_recheck(srv->cluster);
                sts_logf(&srv->log, STS_WARN, "cluster: REPLICA_PUBLISH names other contents of "
                         "'%s' than this node's copy and etcd cannot be asked: the copy stays "
                         "served until a repair pass reads the catalogue", name);
                sts_reply_error(out, h, STP_S_UNAVAILABLE, "cluster coordinator (etcd) "
                                "unreachable: the publish cannot be checked against the "
                                "catalogue; this node's copy of other contents stays served "
                                "until its repair pass reads the catalogue");
            } else if (stale && sts_cluster_hide(srv->cluster, name)) {
                sts_logf(&srv->log, STS_INFO, "cluster: '%s' replaced elsewhere: this node's "
                         "copy of other contents is hidden from reads", name);
                sts_reply_error(out, h, STP_S_NOT_FOUND, "no staged copy of that set and crc32; "
                                "this node's copy of other contents is hidden (stale)");
            } else {
                sts_reply_error(out, h, STP_S_NOT_FOUND, "no staged copy of that set and crc32");
            }
            return 0;
        }
        rc = 0;
    }
    if (rc) {
        sts_reply_st(out, h, rc, e.msg);
        return 0;
    }
    sts_logf(&srv->log, STS_INFO, "cluster: staged copy of '%s' published (the write is recorded)",
             name);
    stp_enc_empty(out, h->opcode, STP_F_REPLY, h->reqid, 0);
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

static int delete_local(sts_server *srv, const char *name, st_error *e)
{
    int rc = ST_ENOTFOUND;
    if (srv->dd)
        rc = st_datadir_delete(srv->dd, name, unpublish_cb, srv, e);
    if (rc == ST_ENOTFOUND)  /* not on disk (in-memory set, or the built-in one) */
        rc = st_registry_remove(srv->reg, name, e);
    return rc;
}

int sts_delete_local(sts_server *srv, const char *name)
{
    st_error e;
    st_error_clear(&e);
    return delete_local(srv, name, &e);
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
    if (srv->cluster) {
        /* recorded in the catalogue before any copy is removed (cluster_write.c). This
         * node's copy is hidden from reads first: a DELETE it cannot record (etcd out of
         * reach) may be one forwarded by the node that deleted the set and answered OK, so
         * the copy stays hidden until a repair pass finds the set recorded (docs/cluster.md
         * "Reads and MOVED"); a refusal for another reason shows it again at once */
        char msg[512];
        uint64_t hid = sts_cluster_hide(srv->cluster, name);
        int cst = sts_cluster_delete(srv->cluster, name, sts_delete_local, msg, sizeof msg);
        if (hid && cst && cst != STP_S_UNAVAILABLE)
            sts_cluster_unhide(srv->cluster, name, hid, UINT64_MAX);
        if (cst) {
            sts_reply_error(out, h, cst, msg);
            return 0;
        }
        STS_STAT_ADD(srv, deletes, 1);
        sts_logf(&srv->log, STS_INFO, "set '%s' deleted from the cluster", name);
        stp_enc_empty(out, h->opcode, STP_F_REPLY, h->reqid, 0);
        return 0;
    }
    int rc = delete_local(srv, name, &e);
    if (rc) {
        sts_reply_st(out, h, rc, e.msg);
        return 0;
    }
    STS_STAT_ADD(srv, deletes, 1);
    sts_logkv(&srv->log, STS_INFO,
              STS_FIELDS(STS_FS("event", "set_deleted"), STS_FS("set", name),
                         STS_FS("peer", c->conn->peer)),
              "set '%s' deleted", name);
    stp_enc_empty(out, h->opcode, STP_F_REPLY, h->reqid, 0);
    return 0;
}
