/* server/uploads.c - the table of uploads and their life (uploads.h).
 *
 * Owns: keeping, adopting, sweeping and dropping upload records. Does not own: what the
 * handlers write into a HELD upload (h_upload.c).
 */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "uploads.h"

void sts_upload_free(sts_upload *u)
{
    if (u->fd >= 0)
        close(u->fd);
    if (u->path[0])
        unlink(u->path);
    free(u);
}

void sts_uploads_free(sts_server *srv)
{
    sts_upload *u = srv->uploads.list;
    while (u) {
        sts_upload *n = u->next;
        sts_upload_free(u);
        u = n;
    }
    srv->uploads.list = NULL;
    srv->uploads.n = 0;
}

/* Unlinks the records `doomed` picks (called under the lock, in list order, newest first);
 * the caller frees them outside the lock. uploads.n counts the records that are not DONE. */
static sts_upload *unlink_uploads(sts_server *srv, int (*doomed)(sts_upload *, void *), void *arg)
{
    sts_upload *drop = NULL;
    pthread_mutex_lock(&srv->uploads.mu);
    for (sts_upload **pp = &srv->uploads.list; *pp;) {
        sts_upload *u = *pp;
        if (doomed(u, arg)) {
            *pp = u->next;
            if (u->state != STS_UP_DONE)
                srv->uploads.n--;
            u->next = drop;
            drop = u;
        } else {
            pp = &u->next;
        }
    }
    pthread_mutex_unlock(&srv->uploads.mu);
    return drop;
}

static void free_uploads(sts_upload *u)
{
    while (u) {
        sts_upload *n = u->next;
        sts_upload_free(u);
        u = n;
    }
}

typedef struct sweep_arg {
    uint64_t conn_id;
    int64_t  now, keep_ms;
    int      ndone;
} sweep_arg;

/* A closing connection's held uploads become KEPT, or are dropped when upload-keep is 0. An
 * upload in COMMITTING finishes on its worker whatever happens to the connection. */
static int held_by_conn(sts_upload *u, void *arg)
{
    sweep_arg *a = arg;
    if (u->conn_id != a->conn_id || u->state != STS_UP_HELD)
        return 0;
    if (a->keep_ms <= 0)
        return 1;
    u->state = STS_UP_KEPT;
    u->since_ms = a->now;
    return 0;
}

static int expired(sts_upload *u, void *arg)
{
    sweep_arg *a = arg;
    if (u->state == STS_UP_DONE && ++a->ndone > MAX_DONE)
        return 1;
    return (u->state == STS_UP_KEPT || u->state == STS_UP_DONE) &&
           (a->keep_ms <= 0 || a->now - u->since_ms >= a->keep_ms);
}

void sts_upload_drop_conn(sts_server *srv, uint64_t conn_id)
{
    sweep_arg a = {conn_id, sts_now_ms(), (int64_t)STS_LIVE(srv, upload_keep) * 1000, 0};
    free_uploads(unlink_uploads(srv, held_by_conn, &a));
}

void sts_uploads_sweep(sts_server *srv, int64_t now_ms)
{
    sweep_arg a = {0, now_ms, (int64_t)STS_LIVE(srv, upload_keep) * 1000, 0};
    sts_upload *gone = unlink_uploads(srv, expired, &a);
    for (sts_upload *u = gone; u; u = u->next) {
        if (u->state != STS_UP_KEPT)
            continue;
        STS_STAT_ADD(srv, uploads_expired, 1);
        sts_logf(&srv->log, STS_INFO, "unfinished upload of '%s' (%llu of %llu bytes) dropped "
                 "after upload-keep", u->name, (unsigned long long)u->received,
                 (unsigned long long)u->total);
    }
    free_uploads(gone);
}

/* RESUME: match on name, size, CRC32C, hint and options (uploads.h). */
int sts_uploads_adopt(sts_server *srv, const stp_upload_begin *rq, uint64_t conn_id,
                      uint64_t *id, uint64_t *received)
{
    int found = 0;
    pthread_mutex_lock(&srv->uploads.mu);
    for (sts_upload *u = srv->uploads.list; u; u = u->next) {
        if (strcmp(u->name, rq->name) || u->total != rq->total_size || u->crc_want != rq->crc32c ||
            strcmp(u->hint, rq->hint) || strcmp(u->options, rq->options))
            continue;
        if (u->state == STS_UP_HELD || u->state == STS_UP_COMMITTING) {
            found = -1;
            continue;
        }
        if (u->state == STS_UP_DONE) {  /* only while its set is still the one it made */
            st_setref *ref = NULL;
            uint64_t gen = st_registry_get(srv->reg, u->name, &ref, NULL) == 0 ? ref->gen : 0;
            st_setref_release(ref);
            if (gen != u->gen)
                continue;
        }
        if (u->state == STS_UP_KEPT) {
            u->state = STS_UP_HELD;
            u->flags = rq->flags & ~(uint32_t)STP_UF_RESUME;
        }
        u->conn_id = conn_id;
        *id = u->id;
        *received = u->received;
        found = 1;
        break;
    }
    pthread_mutex_unlock(&srv->uploads.mu);
    return found;
}

sts_upload *sts_uploads_find(sts_server *srv, uint64_t id, uint64_t conn_id, int take)
{
    pthread_mutex_lock(&srv->uploads.mu);
    sts_upload *found = NULL;
    for (sts_upload **pp = &srv->uploads.list; *pp; pp = &(*pp)->next) {
        sts_upload *u = *pp;
        if (u->id != id || u->conn_id != conn_id)
            continue;
        if (u->state == STS_UP_HELD) {
            found = u;
            if (take == 1) {
                *pp = u->next;
                srv->uploads.n--;
            } else if (take == 2) {
                u->state = STS_UP_COMMITTING;
            }
        }
        break;
    }
    pthread_mutex_unlock(&srv->uploads.mu);
    return found;
}

/* Ends a COMMITTING upload: dropped when it failed; DONE with its reply when it made a set. */
void sts_uploads_finish_commit(sts_server *srv, sts_upload *u, const stp_upload_done *done)
{
    pthread_mutex_lock(&srv->uploads.mu);
    int keep = done && STS_LIVE(srv, upload_keep) > 0;
    if (keep) {
        st_setref *ref = NULL;
        if (st_registry_get(srv->reg, u->name, &ref, NULL) == 0) {
            u->gen = ref->gen;
            st_setref_release(ref);
        }
        u->done = *done;
        u->state = STS_UP_DONE;
        u->since_ms = sts_now_ms();
        u->conn_id = 0;
        srv->uploads.n--;
        if (u->path[0])
            unlink(u->path);  /* without a data dir the file is not needed once imported */
        u->path[0] = 0;
    } else {
        for (sts_upload **pp = &srv->uploads.list; *pp; pp = &(*pp)->next)
            if (*pp == u) {
                *pp = u->next;
                srv->uploads.n--;
                break;
            }
    }
    pthread_mutex_unlock(&srv->uploads.mu);
    if (!keep)
        sts_upload_free(u);
}


int sts_uploads_done_reply(sts_server *srv, uint64_t id, uint64_t conn_id, stp_upload_done *out)
{
    int found = 0;
    pthread_mutex_lock(&srv->uploads.mu);
    for (sts_upload *u = srv->uploads.list; u; u = u->next)
        if (u->id == id && u->conn_id == conn_id && u->state == STS_UP_DONE) {
            *out = u->done;
            found = 1;
            break;
        }
    pthread_mutex_unlock(&srv->uploads.mu);
    return found;
}

int sts_uploads_insert(sts_server *srv, sts_upload *u)
{
    pthread_mutex_lock(&srv->uploads.mu);
    sts_upload *evicted = NULL;
    if (srv->uploads.n >= STS_LIVE(srv, max_uploads)) {
        /* full: a live upload goes before the oldest one kept for resume */
        sts_upload **oldest = NULL;
        for (sts_upload **pp = &srv->uploads.list; *pp; pp = &(*pp)->next)
            if ((*pp)->state == STS_UP_KEPT && (!oldest || (*pp)->since_ms < (*oldest)->since_ms))
                oldest = pp;
        if (oldest) {
            evicted = *oldest;
            *oldest = evicted->next;
            srv->uploads.n--;
        }
    }
    int full = srv->uploads.n >= STS_LIVE(srv, max_uploads);
    if (!full) {
        u->id = ++srv->uploads.next_id;
        u->next = srv->uploads.list;
        srv->uploads.list = u;
        srv->uploads.n++;
    }
    pthread_mutex_unlock(&srv->uploads.mu);
    if (evicted) {
        STS_STAT_ADD(srv, uploads_expired, 1);
        sts_logf(&srv->log, STS_INFO, "kept upload of '%s' dropped for a new one (max-uploads)",
                 evicted->name);
        sts_upload_free(evicted);
    }
    return full ? -1 : 0;
}

int sts_uploads_progress(sts_server *srv, uint64_t id, uint64_t conn_id, stp_upload_progress *p)
{
    int found = 0;
    pthread_mutex_lock(&srv->uploads.mu);
    for (sts_upload *u = srv->uploads.list; u; u = u->next)
        if (u->id == id &&
            (u->state == STS_UP_KEPT || (u->state != STS_UP_DONE && u->conn_id == conn_id))) {
            p->received = u->received;
            p->total = u->total;
            found = 1;
            break;
        }
    pthread_mutex_unlock(&srv->uploads.mu);
    return found;
}
