/* server/h_jobs.c - COMPRESS jobs (BC1 re-encoding on the job thread) and FETCH handles.
 *
 * Owns: the job table (queued, running and recently finished jobs), the job thread, progress
 * and cancel plumbing into st_bc1_compress_set, persisting a finished BC1 set as a DDS file in
 * the data dir; the per-connection fetch handles (a set serialised once to .ptx or .dds in
 * memory, read in chunks). Does not own: the BC1 encoder, the writers (store/).
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

#include "ptex.h"
#include "server.h"
#include "bc1.h"
#include "bc1_measure.h"

#define KEEP_FINISHED 256
#define MAX_FETCHES   256

struct sts_job {
    uint64_t    id;
    int         state;         /* stp_job_state, under jobs.mu */
    uint32_t    progress_bits; /* float bits, atomic */
    uint16_t    result;
    char        msg[STP_MAX_MSG + 1];
    volatile int cancel;
    st_setref  *src;
    char        target[ST_NAME_MAX + 1];
    uint8_t     level, flags;
    sts_job    *next;
};

struct sts_fetch {
    uint64_t   id, conn_id;
    uint8_t   *data;
    size_t     len;
    sts_fetch *next;
};

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
        uint8_t *buf = NULL;
        size_t len = 0;
        int rc = st_dds_write_mem(bc1, &buf, &len, e);
        if (rc == 0) {
            char path[4096];
            int fd = -1;
            rc = st_datadir_tmpfile(srv->dd, path, sizeof path, &fd, e);
            if (rc == 0) {
                size_t done = 0;
                while (done < len) {
                    ssize_t w = write(fd, buf + done, len - done);
                    if (w < 0 && errno == EINTR)
                        continue;
                    if (w <= 0)
                        break;
                    done += (size_t)w;
                }
                close(fd);
                free(buf);
                if (done != len) {
                    st_datadir_discard(path);
                    st_set_free(bc1);
                    return st_fail(e, ST_EIO, "writing the DDS file failed");
                }
                pub_arg pa = {srv, bc1, e};
                rc = st_datadir_commit_set(srv->dd, j->target, path, "dds", "", len,
                                           srv->cfg.native ? &pa.set : NULL, pub_cb, &pa, e);
                st_set_free(pa.set);
                return rc;
            }
            free(buf);
        }
        if (rc != ST_EUNSUPPORTED) {
            st_set_free(bc1);
            return rc;
        }
        sts_logf(&srv->log, STS_WARN, "job %llu: '%s' has no DDS form (%s); kept in memory only",
                 (unsigned long long)j->id, j->target, e->msg);
    }
    return st_registry_put(srv->reg, j->target, bc1, NULL, STS_LIVE(srv, max_sets), NULL, e);
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
        sts_logf(&srv->log, STS_WARN, "job %llu: no quality report: %s", (unsigned long long)j->id,
                 me.msg);
    if (rc == 0)
        rc = store_result(srv, j, bc1, &e);
    pthread_mutex_lock(&srv->jobs.mu);
    j->result = (uint16_t)sts_status_from_st(rc);
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
        snprintf(j->msg, sizeof j->msg, "%s", e.msg[0] ? e.msg : st_strerror(rc));
    srv->jobs.active--;
    pthread_mutex_unlock(&srv->jobs.mu);
    if (rc == 0)
        STS_STAT_ADD(srv, jobs_done, 1);
    else if (rc == ST_ECANCELED)
        STS_STAT_ADD(srv, jobs_canceled, 1);
    else
        STS_STAT_ADD(srv, jobs_failed, 1);
    sts_logf(&srv->log, rc ? STS_WARN : STS_INFO, "job %llu (compress '%s' -> '%s'): %s",
             (unsigned long long)j->id, j->src->name, j->target, j->msg);
    st_setref_release(j->src);
    j->src = NULL;
}

static void *job_main(void *arg)
{
    sts_server *srv = arg;
    sts_jobs *J = &srv->jobs;
    pthread_mutex_lock(&J->mu);
    for (;;) {
        sts_job *next = NULL;
        for (sts_job *j = J->list; j; j = j->next)  /* newest first: take the oldest queued */
            if (j->state == STP_JOB_QUEUED)
                next = j;
        if (!next) {
            if (J->stop)
                break;
            pthread_cond_wait(&J->cv, &J->mu);
            continue;
        }
        if (next->cancel) {
            next->state = STP_JOB_CANCELED;
            next->result = STP_S_CANCELED;
            snprintf(next->msg, sizeof next->msg, "canceled before it started");
            J->active--;
            st_setref_release(next->src);
            next->src = NULL;
            STS_STAT_ADD(srv, jobs_canceled, 1);
            continue;
        }
        next->state = STP_JOB_RUNNING;
        pthread_mutex_unlock(&J->mu);
        run_job(srv, next);
        pthread_mutex_lock(&J->mu);
        /* prune finished jobs past KEEP_FINISHED */
        unsigned finished = 0;
        for (sts_job **pp = &J->list; *pp;) {
            sts_job *j = *pp;
            if (j->state >= STP_JOB_DONE && ++finished > KEEP_FINISHED) {
                *pp = j->next;
                free(j);
            } else {
                pp = &j->next;
            }
        }
    }
    pthread_mutex_unlock(&J->mu);
    return NULL;
}

int sts_jobs_start(sts_server *srv)
{
    sts_jobs *J = &srv->jobs;
    if (pthread_create(&J->thread, NULL, job_main, srv) != 0)
        return -1;
    J->started = 1;
    return 0;
}

void sts_jobs_stop(sts_server *srv)
{
    sts_jobs *J = &srv->jobs;
    pthread_mutex_lock(&J->mu);
    J->stop = 1;
    for (sts_job *j = J->list; j; j = j->next)
        j->cancel = 1;  /* a stopping server does not wait for long compressions */
    pthread_cond_broadcast(&J->cv);
    pthread_mutex_unlock(&J->mu);
    if (J->started)
        pthread_join(J->thread, NULL);
    J->started = 0;
    while (J->list) {
        sts_job *j = J->list;
        J->list = j->next;
        st_setref_release(j->src);
        free(j);
    }
    while (J->fetches) {
        sts_fetch *f = J->fetches;
        J->fetches = f->next;
        free(f->data);
        free(f);
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
    st_setref *src = NULL;
    if (st_registry_get(srv->reg, rq.name, &src, &e) != 0) {
        sts_reply_st(out, h, ST_ENOTFOUND, e.msg);
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
    pthread_mutex_lock(&srv->jobs.mu);
    if (srv->jobs.active >= STS_LIVE(srv, max_jobs)) {
        pthread_mutex_unlock(&srv->jobs.mu);
        st_setref_release(src);
        free(j);
        sts_reply_error(out, h, STP_S_BUSY, "too many compress jobs (max-jobs)");
        return 0;
    }
    j->id = ++srv->jobs.next_id;
    j->next = srv->jobs.list;
    srv->jobs.list = j;
    srv->jobs.active++;
    pthread_cond_signal(&srv->jobs.cv);
    pthread_mutex_unlock(&srv->jobs.mu);
    STS_STAT_ADD(srv, jobs_started, 1);
    stp_enc_id_reply(out, h->opcode, h->reqid, j->id);
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
    int found = 0;
    pthread_mutex_lock(&srv->jobs.mu);
    for (sts_job *j = srv->jobs.list; j; j = j->next) {
        if (j->id != id)
            continue;
        found = 1;
        if (cancel && j->state <= STP_JOB_RUNNING)
            j->cancel = 1;
        r.job_id = j->id;
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
        break;
    }
    pthread_mutex_unlock(&srv->jobs.mu);
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

void sts_fetch_drop_conn(sts_server *srv, uint64_t conn_id)
{
    sts_fetch *drop = NULL;
    pthread_mutex_lock(&srv->jobs.mu);
    for (sts_fetch **pp = &srv->jobs.fetches; *pp;) {
        sts_fetch *f = *pp;
        if (f->conn_id == conn_id) {
            *pp = f->next;
            f->next = drop;
            drop = f;
            srv->jobs.nfetches--;
        } else {
            pp = &f->next;
        }
    }
    pthread_mutex_unlock(&srv->jobs.mu);
    while (drop) {
        sts_fetch *n = drop->next;
        free(drop->data);
        free(drop);
        drop = n;
    }
}

static sts_fetch *find_fetch(sts_server *srv, uint64_t id, uint64_t conn_id, int take)
{
    sts_fetch *found = NULL;
    pthread_mutex_lock(&srv->jobs.mu);
    for (sts_fetch **pp = &srv->jobs.fetches; *pp; pp = &(*pp)->next) {
        if ((*pp)->id == id && (*pp)->conn_id == conn_id) {
            found = *pp;
            if (take) {
                *pp = found->next;
                srv->jobs.nfetches--;
            }
            break;
        }
    }
    pthread_mutex_unlock(&srv->jobs.mu);
    return found;
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
    if (st_registry_get(srv->reg, rq.name, &ref, &e)) {   /* the decoder checked the name */
        sts_reply_st(out, h, e.code ? e.code : ST_ENOTFOUND, e.msg);
        return 0;
    }
    uint8_t *data = NULL;
    size_t len = 0;
    int rc;
    if (rq.format == STP_FETCH_PTX) {
        void *buf = NULL;
        rc = ref->set->info.kind == ST_KIND_PERFACE
                 ? st_ptex_write_mem(ref->set, &buf, &len, &e)
                 : st_fail(&e, ST_EUNSUPPORTED, "only per-face sets are fetched as .ptx (try dds)");
        data = buf;
    } else if (rq.format == STP_FETCH_DDS) {
        rc = ref->set->info.kind == ST_KIND_BC1
                 ? st_dds_write_mem(ref->set, &data, &len, &e)
                 : st_fail(&e, ST_EUNSUPPORTED, "only BC1 sets are fetched as .dds (COMPRESS first)");
    } else {
        rc = st_fail(&e, ST_EINVAL, "format must be 0 (ptx) or 1 (dds)");
    }
    st_setref_release(ref);
    if (rc) {
        free(data);
        sts_reply_st(out, h, rc, e.msg);
        return 0;
    }
    sts_fetch *f = calloc(1, sizeof *f);
    if (!f) {
        free(data);
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    f->data = data;
    f->len = len;
    f->conn_id = c->conn->id;
    pthread_mutex_lock(&srv->jobs.mu);
    if (srv->jobs.nfetches >= MAX_FETCHES) {
        pthread_mutex_unlock(&srv->jobs.mu);
        free(data);
        free(f);
        sts_reply_error(out, h, STP_S_BUSY, "too many open fetches");
        return 0;
    }
    f->id = ++srv->jobs.next_fetch;
    f->next = srv->jobs.fetches;
    srv->jobs.fetches = f;
    srv->jobs.nfetches++;
    pthread_mutex_unlock(&srv->jobs.mu);
    STS_STAT_ADD(srv, fetches, 1);
    stp_fetch_open_reply r = {f->id, len, stp_crc32c(0, data, len), STP_DEFAULT_MAX_CHUNK};
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
    size_t n = f->len - rq.offset;
    if (n > rq.max_len)
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
    free(f->data);
    free(f);
    stp_enc_empty(out, h->opcode, STP_F_REPLY, h->reqid, 0);
    return 0;
}
