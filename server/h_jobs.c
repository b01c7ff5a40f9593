/* server/h_jobs.c - COMPRESS jobs (BC1 re-encoding on the job thread) and FETCH handles.
 *
 * Owns: the jobs (queued, running and recently finished) in their handle table, the job
 * thread, progress and cancel plumbing into st_bc1_compress_set, persisting a finished BC1
 * set as a DDS file in the data dir; the per-connection fetch handles in srv->fetches (a set
 * serialised once to .ptx or .dds in memory, read in chunks). Does not own: the handle table
 * itself (handles.c: ids, owner, capacity, lock), the BC1 encoder, the writers (store/).
 *
 * Jobs run one at a time on their own thread (the encoder may use threads of its own), so a
 * long compression never occupies the workers that answer requests. Finished jobs stay
 * visible to JOB_STATUS until 256 newer ones have finished.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bc1.h"
#include "bc1_measure.h"
#include "export.h"
#include "dispatch.h"
#include "cluster_node.h"
#include "h_jobs.h"
#include "h_upload.h"
#include "handles.h"
#include "io.h"
#include "ptex.h"
#include "server.h"

#define KEEP_FINISHED 256
#define MAX_FETCHES   256

/* Jobs are in jobs->table with owner 0 (any connection may ask about or cancel a job) and
 * count against max-jobs while queued or running. */
typedef struct sts_jobs {
    sts_handles    table;      /* its mutex guards the jobs' states and `stop` */
    pthread_cond_t cv;         /* the job thread waits here for queued jobs */
    int            stop;
    pthread_t      thread;
    int            started;
} sts_jobs;

typedef struct sts_job {
    sts_handle  hd;            /* first: id, owner 0, live while queued or running */
    int         state;         /* stp_job_state, under jobs->table.mu */
    uint32_t    progress_bits; /* float bits, atomic */
    uint16_t    result;
    char        msg[STP_MAX_MSG + 1];
    volatile int cancel;
    st_setref  *src;
    char        target[ST_NAME_MAX + 1];
    uint8_t     level, flags;
} sts_job;

/* Fetches are in srv->fetches, owned by the connection that opened them. */
typedef struct sts_fetch {
    sts_handle hd;             /* first: id, owner connection */
    uint8_t   *data;
    size_t     len;
} sts_fetch;

#define JOB(h)   ((sts_job *)(h))     /* sts_handle is the first member of both */
#define FETCH(h) ((sts_fetch *)(h))

static int every(sts_handle *h, void *arg)
{
    (void)h;
    (void)arg;
    return 1;
}

/* ---- the job thread ---------------------------------------------------------------------- */

static void progress_cb(void *arg, double f)
{
    sts_job *j = arg;
    float x = (float)f;
    uint32_t bits;
    memcpy(&bits, &x, 4);
    __atomic_store_n(&j->progress_bits, bits, __ATOMIC_RELAXED);
}

typedef struct pub_arg {
    sts_server *srv;
    st_set     *set;
    st_error   *e;
} pub_arg;

static int pub_cb(void *arg, const st_manifest *m, const char *source_path)
{
    (void)source_path;
    pub_arg *pa = arg;
    st_set_source src = {m->bytes, m->crc, m->format};
    st_set *s = pa->set;
    pa->set = NULL;
    return st_registry_put(pa->srv->reg, m->name, s, &src, STS_LIVE(pa->srv, max_sets), NULL,
                           pa->e);
}

/* Publishes the BC1 set as `target`, durable as a .dds when there is a data dir. */
static int store_result_locked(sts_server *srv, sts_job *j, st_set *bc1, st_error *e);

static int store_result(sts_server *srv, sts_job *j, st_set *bc1, st_error *e)
{
    pthread_mutex_lock(&srv->commit_mu);
    int rc = store_result_locked(srv, j, bc1, e);
    pthread_mutex_unlock(&srv->commit_mu);
    return rc;
}

/* Writes bc1 as a DDS file into a data dir temp file (path, *len); ST_EUNSUPPORTED when the
 * set has no DDS form. bc1 stays the caller's. */
static int dds_tmp(sts_server *srv, const st_set *bc1, char *path, size_t cap, size_t *len,
                   st_error *e)
{
    uint8_t *buf = NULL;
    int rc = st_dds_write_mem(bc1, &buf, len, e);
    if (rc)
        return rc;
    int fd = -1;
    rc = st_datadir_tmpfile(srv->dd, path, cap, &fd, e);
    if (rc) {
        free(buf);
        return rc;
    }
    size_t done = 0;
    int werr = 0;
    while (done < *len) {
        ssize_t w = write(fd, buf + done, *len - done);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0) {
            werr = w < 0 ? errno : EIO;
            break;
        }
        done += (size_t)w;
    }
    close(fd);
    free(buf);
    if (done != *len) {
        st_datadir_discard(path);
        return st_fail(e, ST_EIO, "writing the DDS file failed: %s", strerror(werr));
    }
    return 0;
}

static int store_result_locked(sts_server *srv, sts_job *j, st_set *bc1, st_error *e)
{
    if (!(j->flags & STP_CF_REPLACE)) {
        st_setref *ref = NULL;
        if (st_registry_get(srv->reg, j->target, &ref, NULL) == 0) {
            st_setref_release(ref);
            st_set_free(bc1);
            return st_fail(e, ST_EEXIST, "set '%s' exists (use the replace flag)", j->target);
        }
    }
    if (srv->dd) {
        char path[4096];
        size_t len = 0;
        int rc = dds_tmp(srv, bc1, path, sizeof path, &len, e);
        if (rc == 0) {
            pub_arg pa = {srv, bc1, e};
            rc = st_datadir_commit_set(srv->dd, j->target, path, "dds", "", len,
                                       srv->cfg.native ? &pa.set : NULL, pub_cb, &pa, e);
            st_set_free(pa.set);
            return rc;
        }
        if (rc != ST_EUNSUPPORTED) {
            st_set_free(bc1);
            return rc;
        }
        sts_logf(&srv->log, STS_WARN, "job %llu: '%s' has no DDS form (%s); kept in memory only",
                 (unsigned long long)j->hd.id, j->target, e->msg);
    }
    return st_registry_put(srv->reg, j->target, bc1, NULL, STS_LIVE(srv, max_sets), NULL, e);
}

/* In a cluster: the result is claimed, staged, copied to its owners and published like an
 * upload (sts_cluster_record_file); a wire status, msg set. */
static int record_result(sts_server *srv, sts_job *j, st_set *bc1, char *msg, size_t cap)
{
    char path[4096];
    size_t len = 0;
    st_error e;
    st_error_clear(&e);
    int rc = dds_tmp(srv, bc1, path, sizeof path, &len, &e);
    if (rc) {
        st_set_free(bc1);
        if (rc == ST_EUNSUPPORTED)
            snprintf(msg, cap, "'%.64s' has no DDS form: the cluster cannot copy it", j->target);
        else
            sts_scrub_paths(e.msg, msg, cap);
        return rc == ST_EUNSUPPORTED ? STP_S_UNSUPPORTED : sts_status_from_st(rc);
    }
    return sts_cluster_record_file(srv->cluster, j->target, (j->flags & STP_CF_REPLACE) != 0,
                                   STP_KIND_BC1, path, "dds", len, bc1, msg, cap);
}

static void run_job(sts_server *srv, sts_job *j)
{
    st_error e;
    st_error_clear(&e);
    int rc;
    st_bc1_opts o;
    st_bc1_opts_default(&o);
    /* wire levels 0..9: 0-4 FAST, 5-7 HQ (the CLI's default 5), 8-9 BEST (PROTOCOL.md 4.9) */
    o.level = j->level >= 8 ? ST_BC1_BEST : j->level >= 5 ? ST_BC1_HQ : ST_BC1_FAST;
    o.seam_mode = (j->flags & STP_CF_SEAM_AWARE) ? ST_BC1_SEAM_AWARE : ST_BC1_SEAM_NONE;
    o.threads = (int)(STS_LIVE(srv, job_threads) > 64 ? 64 : STS_LIVE(srv, job_threads));
    st_set *bc1 = NULL;
    rc = st_bc1_compress_set(j->src->set, &o, progress_cb, j, &j->cancel, &bc1, &e);
    /* the job's report: quality against the source, measured as the seam report does */
    st_bc1_quality q;
    st_error me;
    st_error_clear(&me);
    int measured = rc == 0 && st_bc1_measure(j->src->set, bc1, o.step, &q, &me) == 0;
    if (rc == 0 && !measured)
        sts_logf(&srv->log, STS_WARN, "job %llu: no quality report: %s", (unsigned long long)j->hd.id,
                 me.msg);
    /* in a cluster the result is claimed and copied to its owners like an upload */
    int wst = 0;
    char cmsg[sizeof e.msg] = "";
    if (rc == 0 && srv->cluster)
        wst = record_result(srv, j, bc1, cmsg, sizeof cmsg);
    else if (rc == 0)
        rc = store_result(srv, j, bc1, &e);
    if (wst) {
        rc = ST_EIO;   /* for the counters below; the job's result is the wire status */
        snprintf(e.msg, sizeof e.msg, "%s", cmsg);
    }
    sts_handles_lock(&srv->jobs->table);
    j->result = (uint16_t)(wst ? wst : sts_status_from_st(rc));
    j->state = rc == 0 ? STP_JOB_DONE : rc == ST_ECANCELED ? STP_JOB_CANCELED : STP_JOB_FAILED;
    if (rc == 0 && measured && q.nseams)
        snprintf(j->msg, sizeof j->msg, "created set '%s': PSNR %.2f dB inside charts; seam RMS "
                 "%.2f -> %.2f (per channel, 0..255, %u seams)", j->target, q.psnr,
                 q.seam_rms_src, q.seam_rms_bc1, q.nseams);
    else if (rc == 0 && measured)
        snprintf(j->msg, sizeof j->msg, "created set '%s': PSNR %.2f dB (no seams)", j->target,
                 q.psnr);
    else if (rc == 0)
        snprintf(j->msg, sizeof j->msg, "created set '%s'", j->target);
    else
        sts_scrub_paths(e.msg[0] ? e.msg : st_strerror(rc), j->msg, sizeof j->msg);
    sts_handles_retire_locked(&srv->jobs->table, &j->hd);
    sts_handles_unlock(&srv->jobs->table);
    if (rc == 0)
        STS_STAT_ADD(srv, jobs_done, 1);
    else if (rc == ST_ECANCELED)
        STS_STAT_ADD(srv, jobs_canceled, 1);
    else
        STS_STAT_ADD(srv, jobs_failed, 1);
    sts_logf(&srv->log, rc ? STS_WARN : STS_INFO, "job %llu (compress '%s' -> '%s'): %s",
             (unsigned long long)j->hd.id, j->src->name, j->target, j->msg);
    st_setref_release(j->src);
    j->src = NULL;
}

static void *job_main(void *arg)
{
    sts_server *srv = arg;
    sts_jobs *J = srv->jobs;
    sts_handles_lock(&J->table);
    for (;;) {
        sts_job *next = NULL;
        for (sts_handle *h = J->table.list; h; h = h->next)  /* newest first: the oldest queued */
            if (JOB(h)->state == STP_JOB_QUEUED)
                next = JOB(h);
        if (!next) {
            if (J->stop)
                break;
            pthread_cond_wait(&J->cv, &J->table.mu);
            continue;
        }
        if (next->cancel) {
            next->state = STP_JOB_CANCELED;
            next->result = STP_S_CANCELED;
            snprintf(next->msg, sizeof next->msg, "canceled before it started");
            sts_handles_retire_locked(&J->table, &next->hd);
            st_setref_release(next->src);
            next->src = NULL;
            STS_STAT_ADD(srv, jobs_canceled, 1);
            continue;
        }
        next->state = STP_JOB_RUNNING;
        sts_handles_unlock(&J->table);
        run_job(srv, next);
        sts_handles_lock(&J->table);
        /* prune finished jobs past KEEP_FINISHED */
        unsigned finished = 0;
        for (sts_handle *h = J->table.list, *n; h; h = n) {
            n = h->next;
            if (JOB(h)->state >= STP_JOB_DONE && ++finished > KEEP_FINISHED) {
                sts_handles_unlink_locked(&J->table, h);
                free(h);
            }
        }
    }
    sts_handles_unlock(&J->table);
    return NULL;
}

int sts_jobs_start(sts_server *srv)
{
    sts_jobs *J = calloc(1, sizeof *J);
    if (!J)
        return -1;
    sts_handles_init(&J->table);
    pthread_cond_init(&J->cv, NULL);
    srv->jobs = J;
    if (pthread_create(&J->thread, NULL, job_main, srv) != 0)
        return -1;
    J->started = 1;
    return 0;
}

void sts_jobs_stop(sts_server *srv)
{
    sts_jobs *J = srv->jobs;
    if (J) {
        sts_handles_lock(&J->table);
        J->stop = 1;
        for (sts_handle *h = J->table.list; h; h = h->next)
            /* a stopping server does not wait for long compressions; atomic: the encoder
             * threads read it without the lock */
            __atomic_store_n(&JOB(h)->cancel, 1, __ATOMIC_RELAXED);
        pthread_cond_broadcast(&J->cv);
        sts_handles_unlock(&J->table);
        if (J->started)
            pthread_join(J->thread, NULL);
        for (sts_handle *h = sts_handles_unlink_if(&J->table, every, NULL), *n; h; h = n) {
            n = h->next;
            st_setref_release(JOB(h)->src);
            free(h);
        }
        sts_handles_destroy(&J->table);
        pthread_cond_destroy(&J->cv);
        free(J);
        srv->jobs = NULL;
    }
    for (sts_handle *h = sts_handles_unlink_if(&srv->fetches, every, NULL), *n; h; h = n) {
        n = h->next;
        free(FETCH(h)->data);
        free(h);
    }
}

/* ---- COMPRESS / JOB_STATUS / JOB_CANCEL ------------------------------------------------------- */

int sts_h_compress(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    stp_compress_req rq;
    const char *why = NULL;
    int st = stp_dec_compress_req(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    st_error e;   /* both names follow the name rule: stp_dec_compress_req checked them */
    st_error_clear(&e);
    if (rq.level > 9)
        return sts_reply_bad(out, h, STP_S_INVALID, "level must be 0..9");
    if (srv->cluster && !sts_cluster_etcd_ok(srv->cluster)) {
        STS_CL_ADD(srv->cluster, refused_unavailable, 1);
        sts_reply_error(out, h, STP_S_UNAVAILABLE, "cluster coordinator (etcd) unreachable: "
                        "compress refused, retry later");
        return 0;
    }
    st_setref *src = NULL;
    if (sts_get_served(srv, rq.name, &src, &e) != 0) {
        sts_reply_not_here(srv, out, h, rq.name, e.msg);
        return 0;
    }
    if (src->set->info.meshtype == ST_MESH_TRIANGLE) { /* refused up front, not as a job */
        st_setref_release(src);
        sts_reply_st(out, h, ST_EUNSUPPORTED, ST_BC1_TRIANGLE_REFUSAL);
        return 0;
    }
    if (!(rq.flags & STP_CF_REPLACE)) {
        st_setref *t = NULL;
        if (st_registry_get(srv->reg, rq.target, &t, NULL) == 0) {
            st_setref_release(t);
            st_setref_release(src);
            sts_reply_error(out, h, STP_S_EXISTS, "target set exists (use the replace flag)");
            return 0;
        }
    }
    sts_job *j = calloc(1, sizeof *j);
    if (!j) {
        st_setref_release(src);
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    j->src = src;
    snprintf(j->target, sizeof j->target, "%s", rq.target);
    j->level = rq.level;
    j->flags = rq.flags;
    j->state = STP_JOB_QUEUED;
    sts_jobs *J = srv->jobs;
    sts_handles_lock(&J->table);
    int full = sts_handles_add_locked(&J->table, &j->hd, STS_LIVE(srv, max_jobs)) != 0;
    uint64_t id = j->hd.id;   /* the job thread may finish and prune it once unlocked */
    if (!full)
        pthread_cond_signal(&J->cv);
    sts_handles_unlock(&J->table);
    if (full) {
        st_setref_release(src);
        free(j);
        sts_reply_error(out, h, STP_S_BUSY, "too many compress jobs (max-jobs)");
        return 0;
    }
    STS_STAT_ADD(srv, jobs_started, 1);
    stp_enc_id_reply(out, h->opcode, h->reqid, id);
    return 0;
}

static int job_reply(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out,
                     int cancel)
{
    sts_server *srv = c->srv;
    uint64_t id;
    const char *why = NULL;
    int st = stp_dec_id_req(body, h->body_len, &id, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    stp_job_status r;
    memset(&r, 0, sizeof r);
    sts_handles_lock(&srv->jobs->table);
    sts_job *j = JOB(sts_handles_find_locked(&srv->jobs->table, id, STS_ANY_OWNER));
    int found = j != NULL;
    if (j) {
        if (cancel && j->state <= STP_JOB_RUNNING)
            __atomic_store_n(&j->cancel, 1, __ATOMIC_RELAXED);  /* read by the encoder */
        r.job_id = j->hd.id;
        r.state = (uint8_t)j->state;
        uint32_t bits = __atomic_load_n(&j->progress_bits, __ATOMIC_RELAXED);
        memcpy(&r.progress, &bits, 4);
        if (j->state == STP_JOB_DONE)
            r.progress = 1.0f;
        r.result = j->result;
        snprintf(r.message, sizeof r.message, "%s",
                 j->state == STP_JOB_QUEUED ? (j->cancel ? "cancel requested" : "queued")
                 : j->state == STP_JOB_RUNNING ? (j->cancel ? "cancel requested" : "running")
                 : j->msg);
    }
    sts_handles_unlock(&srv->jobs->table);
    if (!found) {
        sts_reply_error(out, h, STP_S_NOT_FOUND, "no such job");
        return 0;
    }
    stp_enc_job_status(out, h->opcode, h->reqid, &r);
    return 0;
}

int sts_h_job_status(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    return job_reply(c, h, body, out, 0);
}

int sts_h_job_cancel(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    return job_reply(c, h, body, out, 1);
}

/* ---- FETCH ------------------------------------------------------------------------------------ */

/* The FETCH formats are the store's export formats, number for number (proto_lists.h). */
#define SAME_FETCH(NAME, str, v) \
    _Static_assert((int)STP_FETCH_##NAME == (int)ST_EXPORT_##NAME, "fetch format " str);
STP_FETCH_FORMATS(SAME_FETCH)
#undef SAME_FETCH

/* Open fetches hold their serialised file in memory: it counts against max-memory together
 * with the connection buffers (srv->mem_used + srv->fetch_mem) and, per connection, against
 * conn-fetch-cap. Reserves n bytes; 0, or -1 when they do not fit. */
static int fetch_mem_take(sts_server *srv, uint64_t n)
{
    uint64_t max = STS_LIVE(srv, max_memory);
    uint64_t cur = __atomic_load_n(&srv->fetch_mem, __ATOMIC_RELAXED);
    do {
        uint64_t bufs = __atomic_load_n(&srv->mem_used, __ATOMIC_RELAXED);
        if (bufs + cur + n > max)
            return -1;
    } while (!__atomic_compare_exchange_n(&srv->fetch_mem, &cur, cur + n, 1, __ATOMIC_RELAXED,
                                          __ATOMIC_RELAXED));
    return 0;
}

static void fetch_mem_give(sts_server *srv, uint64_t n)
{
    __atomic_sub_fetch(&srv->fetch_mem, n, __ATOMIC_RELAXED);
}

static void fetch_free(sts_server *srv, sts_fetch *f)
{
    fetch_mem_give(srv, f->len);
    free(f->data);
    free(f);
}

static int owned_by(sts_handle *h, void *arg)
{
    return h->owner == *(const uint64_t *)arg;
}

void sts_fetch_drop_conn(sts_server *srv, uint64_t conn_id)
{
    for (sts_handle *h = sts_handles_unlink_if(&srv->fetches, owned_by, &conn_id), *n; h; h = n) {
        n = h->next;
        fetch_free(srv, FETCH(h));
    }
}

static sts_fetch *find_fetch(sts_server *srv, uint64_t id, uint64_t conn_id, int take)
{
    sts_handles_lock(&srv->fetches);
    sts_handle *f = sts_handles_find_locked(&srv->fetches, id, conn_id);
    if (f && take)
        sts_handles_unlink_locked(&srv->fetches, f);
    sts_handles_unlock(&srv->fetches);
    return FETCH(f);
}

/* Bytes of the fetches this connection holds open. Only the connection itself opens or
 * closes its fetches and it runs one request at a time, so the sum cannot change under a
 * FETCH_OPEN of the same connection. */
static uint64_t conn_fetch_bytes(sts_server *srv, uint64_t conn_id)
{
    uint64_t sum = 0;
    sts_handles_lock(&srv->fetches);
    for (sts_handle *h = srv->fetches.list; h; h = h->next)
        if (h->owner == conn_id)
            sum += FETCH(h)->len;
    sts_handles_unlock(&srv->fetches);
    return sum;
}

/* Refuses a FETCH_OPEN for memory: TOO_LARGE when the file alone can never fit (over
 * conn-fetch-cap or max-memory), BUSY when it would fit once other fetches are closed. */
static void fetch_refuse_mem(sts_ctx *c, const stp_header *h, stp_buf *out, const char *name,
                             uint64_t bytes, uint64_t held, int estimate)
{
    const char *what = estimate ? "needs up to" : "serialised is";
    sts_server *srv = c->srv;
    uint64_t cap = STS_LIVE(srv, conn_fetch_cap), max = STS_LIVE(srv, max_memory);
    char msg[400];
    int status;
    if (bytes > cap || bytes > max) {
        status = STP_S_TOO_LARGE;
        snprintf(msg, sizeof msg, "set '%s' %s %llu bytes, over %s %llu", name, what,
                 (unsigned long long)bytes, bytes > cap ? "conn-fetch-cap" : "max-memory",
                 (unsigned long long)(bytes > cap ? cap : max));
    } else if (held + bytes > cap) {
        status = STP_S_BUSY;
        snprintf(msg, sizeof msg, "set '%s' (%llu bytes) with this connection's open fetches "
                 "(%llu bytes) passes conn-fetch-cap %llu: close a fetch first", name,
                 (unsigned long long)bytes, (unsigned long long)held, (unsigned long long)cap);
    } else {
        status = STP_S_BUSY;
        snprintf(msg, sizeof msg, "set '%s' (%llu bytes): server memory is at max-memory; "
                 "retry", name, (unsigned long long)bytes);
    }
    STS_STAT_ADD(srv, fetches_refused, 1);
    sts_reply_error(out, h, status, msg);
}

int sts_h_fetch_open(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    stp_fetch_open rq;
    const char *why = NULL;
    int st = stp_dec_fetch_open(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    st_error e;
    st_error_clear(&e);
    st_setref *ref = NULL;
    if (sts_get_served(srv, rq.name, &ref, &e)) {   /* the decoder checked the name */
        sts_reply_not_here(srv, out, h, rq.name, e.msg);
        return 0;
    }
    /* room first, for an estimate (the set's memory: a file holds no more than its set,
     * except meshes as text, settled below), so that serialising itself stays in the caps */
    uint64_t cap = STS_LIVE(srv, conn_fetch_cap);
    uint64_t held = conn_fetch_bytes(srv, c->conn->id);
    uint64_t reserved = st_set_memory(ref->set);
    if (held + reserved > cap || fetch_mem_take(srv, reserved) != 0) {
        fetch_refuse_mem(c, h, out, rq.name, reserved, held, 1);
        st_setref_release(ref);
        return 0;
    }
    void *data = NULL;
    size_t len = 0;
    int rc = st_export_mem(ref->set, rq.format, srv->tmpdir, &data, &len, &e);
    st_setref_release(ref);
    if (rc) {
        fetch_mem_give(srv, reserved);
        free(data);
        char msg[sizeof e.msg + STP_MAX_NAME + 16];
        snprintf(msg, sizeof msg, "set '%s': %s", rq.name, e.msg[0] ? e.msg : st_strerror(rc));
        sts_reply_st(out, h, rc, msg);
        return 0;
    }
    /* hold exactly the file's size from now on */
    if (len > reserved && (held + len > cap || fetch_mem_take(srv, len - reserved) != 0)) {
        fetch_mem_give(srv, reserved);
        free(data);
        fetch_refuse_mem(c, h, out, rq.name, len, held, 0);
        return 0;
    }
    if (len < reserved)
        fetch_mem_give(srv, reserved - len);
    sts_fetch *f = calloc(1, sizeof *f);
    if (!f) {
        fetch_mem_give(srv, len);
        free(data);
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    f->data = data;
    f->len = len;
    f->hd.owner = c->conn->id;
    sts_handles_lock(&srv->fetches);
    int full = sts_handles_add_locked(&srv->fetches, &f->hd, MAX_FETCHES) != 0;
    sts_handles_unlock(&srv->fetches);
    if (full) {
        fetch_free(srv, f);
        STS_STAT_ADD(srv, fetches_refused, 1);
        sts_reply_error(out, h, STP_S_BUSY, "too many open fetches (256 on the server)");
        return 0;
    }
    STS_STAT_ADD(srv, fetches, 1);
    stp_fetch_open_reply r = {f->hd.id, len, stp_crc32c(0, data, len), STP_DEFAULT_MAX_CHUNK};
    stp_enc_fetch_open_reply(out, h->reqid, &r);
    return 0;
}

int sts_h_fetch_read(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_fetch_read rq;
    const char *why = NULL;
    int st = stp_dec_fetch_read(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    /* only this connection can close the handle, and not while this request runs */
    sts_fetch *f = find_fetch(c->srv, rq.fetch_id, c->conn->id, 0);
    if (!f) {
        sts_reply_error(out, h, STP_S_NOT_FOUND, "no such fetch on this connection");
        return 0;
    }
    if (rq.offset > f->len) {
        sts_reply_error(out, h, STP_S_INVALID, "offset is past the end of the file");
        return 0;
    }
    /* max_len 0 = as much as one reply holds (max_chunk), as LIST's max 0: so a reply with
     * len 0 always means the end of the file (PROTOCOL.md 4.10) */
    size_t n = f->len - rq.offset;
    if (rq.max_len && n > rq.max_len)
        n = rq.max_len;
    if (n > STP_DEFAULT_MAX_CHUNK)
        n = STP_DEFAULT_MAX_CHUNK;
    stp_fetch_data d = {rq.offset, (uint32_t)n, f->data + rq.offset};
    stp_enc_fetch_data(out, h->reqid, &d);
    return 0;
}

int sts_h_fetch_close(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    uint64_t id;
    const char *why = NULL;
    int st = stp_dec_id_req(body, h->body_len, &id, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    sts_fetch *f = find_fetch(c->srv, id, c->conn->id, 1);
    if (!f) {
        sts_reply_error(out, h, STP_S_NOT_FOUND, "no such fetch on this connection");
        return 0;
    }
    fetch_free(c->srv, f);
    stp_enc_empty(out, h->opcode, STP_F_REPLY, h->reqid, 0);
    return 0;
}
