/* server/uploads.c - the table of uploads and their life (uploads.h).
 *
 * Owns: keeping, adopting, sweeping and dropping upload records, on the generic handle table
 * srv->uploads (handles.c: ids, owner connection, live count, lock). Does not own: what the
 * handlers write into a HELD upload (h_upload.c).
 */
#include <stdlib.h>
#include <string.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "uploads.h"

#define UP(h) ((sts_upload *)(h))   /* sts_handle is an upload's first member */

void sts_upload_free(sts_upload *u)
{
    if (u->fd >= 0)
        close(u->fd);
    if (u->path[0])
        unlink(u->path);
    free(u);
}

static void free_uploads(sts_handle *h)
{
    while (h) {
        sts_handle *n = h->next;
        sts_upload_free(UP(h));
        h = n;
    }
}

static int every(sts_handle *h, void *arg)
{
    (void)h;
    (void)arg;
    return 1;
}

void sts_uploads_free(sts_server *srv)
{
    free_uploads(sts_handles_unlink_if(&srv->uploads, every, NULL));
    sts_handles_destroy(&srv->uploads);
}

typedef struct sweep_arg {
    uint64_t conn_id;
    int64_t  now, keep_ms;
    int      ndone;
} sweep_arg;

/* A closing connection's held uploads become KEPT, or are dropped when upload-keep is 0. An
 * upload in COMMITTING finishes on its worker whatever happens to the connection. */
static int held_by_conn(sts_handle *h, void *arg)
{
    sts_upload *u = UP(h);
    sweep_arg *a = arg;
    if (u->hd.owner != a->conn_id || u->state != STS_UP_HELD)
        return 0;
    if (a->keep_ms <= 0)
        return 1;
    u->state = STS_UP_KEPT;
    u->since_ms = a->now;
    return 0;
}

static int expired(sts_handle *h, void *arg)
{
    sts_upload *u = UP(h);
    sweep_arg *a = arg;
    if (u->state == STS_UP_DONE && ++a->ndone > MAX_DONE)
        return 1;
    return (u->state == STS_UP_KEPT || u->state == STS_UP_DONE) &&
           (a->keep_ms <= 0 || a->now - u->since_ms >= a->keep_ms);
}

void sts_upload_drop_conn(sts_server *srv, uint64_t conn_id)
{
    sweep_arg a = {conn_id, sts_now_ms(), (int64_t)STS_LIVE(srv, upload_keep) * 1000, 0};
    free_uploads(sts_handles_unlink_if(&srv->uploads, held_by_conn, &a));
}

void sts_uploads_sweep(sts_server *srv, int64_t now_ms)
{
    sweep_arg a = {0, now_ms, (int64_t)STS_LIVE(srv, upload_keep) * 1000, 0};
    sts_handle *gone = sts_handles_unlink_if(&srv->uploads, expired, &a);
    for (sts_handle *h = gone; h; h = h->next) {
        sts_upload *u = UP(h);
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
    sts_handles_lock(&srv->uploads);
    for (sts_handle *h = srv->uploads.list; h; h = h->next) {
        sts_upload *u = UP(h);
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
        u->hd.owner = conn_id;
        *id = u->hd.id;
        *received = u->received;
        found = 1;
        break;
    }
    sts_handles_unlock(&srv->uploads);
    return found;
}

sts_upload *sts_uploads_find(sts_server *srv, uint64_t id, uint64_t conn_id, int take)
{
    sts_handles_lock(&srv->uploads);
    sts_upload *u = UP(sts_handles_find_locked(&srv->uploads, id, conn_id));
    if (u && u->state != STS_UP_HELD)
        u = NULL;
    if (u && take == 1)
        sts_handles_unlink_locked(&srv->uploads, &u->hd);
    else if (u && take == 2)
        u->state = STS_UP_COMMITTING;
    sts_handles_unlock(&srv->uploads);
    return u;
}

/* Ends a COMMITTING upload: dropped when it failed; DONE with its reply when it made a set. */
void sts_uploads_finish_commit(sts_server *srv, sts_upload *u, const stp_upload_done *done)
{
    sts_handles_lock(&srv->uploads);
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
        u->hd.owner = 0;
        sts_handles_retire_locked(&srv->uploads, &u->hd);
        if (u->path[0])
            unlink(u->path);  /* without a data dir the file is not needed once imported */
        u->path[0] = 0;
    } else {
        sts_handles_unlink_locked(&srv->uploads, &u->hd);
    }
    sts_handles_unlock(&srv->uploads);
    if (!keep)
        sts_upload_free(u);
}

int sts_uploads_done_reply(sts_server *srv, uint64_t id, uint64_t conn_id, stp_upload_done *out)
{
    sts_handles_lock(&srv->uploads);
    sts_upload *u = UP(sts_handles_find_locked(&srv->uploads, id, conn_id));
    int found = u && u->state == STS_UP_DONE;
    if (found)
        *out = u->done;
    sts_handles_unlock(&srv->uploads);
    return found;
}

#define HEADROOM_MAX (64ull << 20)

static uint64_t add_sat(uint64_t a, uint64_t b)
{
    return a > UINT64_MAX - b ? UINT64_MAX : a + b;
}

/* The disk check (uploads.h), under the table's lock: `need` more bytes on the file system of
 * fd (or of path when fd < 0); `skip` is a KEPT record about to be dropped for this one (its
 * promise goes with it). The promises are the body bytes the unfinished uploads still expect
 * (total - received) and the native files their COMMITs are writing (res36). They are summed
 * before the free space is read: a chunk's bytes are written before its `received` grows and
 * a native file's before its record leaves the table, so bytes landing in between are
 * counted twice (refuses early) but never missed. 1 when need fits. */
static int room_locked(sts_server *srv, uint64_t need, int fd, const char *path,
                       const sts_upload *skip, sts_upload_room *room)
{
    uint64_t promised = 0;
    for (sts_handle *h = srv->uploads.list; h; h = h->next) {
        const sts_upload *o = UP(h);
        if (o == skip || o->state == STS_UP_DONE)
            continue;
        uint64_t got = __atomic_load_n(&o->received, __ATOMIC_ACQUIRE);
        promised = add_sat(promised, got < o->total ? o->total - got : 0);
        promised = add_sat(promised, o->native);
    }
    struct statvfs v;
    if (fd >= 0 ? fstatvfs(fd, &v) != 0 : !path || !path[0] || statvfs(path, &v) != 0)
        return 1;
    uint64_t size = (uint64_t)v.f_blocks * v.f_frsize;
    room->avail = (uint64_t)v.f_bavail * v.f_frsize;
    room->promised = promised;
    room->headroom = size / 64 < HEADROOM_MAX ? size / 64 : HEADROOM_MAX;
    return add_sat(add_sat(need, promised), room->headroom) <= room->avail;
}

int sts_uploads_promise_native(sts_server *srv, sts_upload *u, const char *dir, uint64_t bytes,
                               sts_upload_room *room)
{
    sts_handles_lock(&srv->uploads);
    int fits = room_locked(srv, bytes, -1, dir, NULL, room);
    if (fits)
        u->native = bytes;
    sts_handles_unlock(&srv->uploads);
    return fits ? 0 : -1;
}

int sts_uploads_insert(sts_server *srv, sts_upload *u, sts_upload_room *room)
{
    uint64_t cap = STS_LIVE(srv, max_uploads);
    sts_handles_lock(&srv->uploads);
    sts_upload *oldest = NULL;
    if (srv->uploads.live >= cap) {
        /* full: a live upload goes before the oldest one kept for resume */
        for (sts_handle *h = srv->uploads.list; h; h = h->next)
            if (UP(h)->state == STS_UP_KEPT && (!oldest || UP(h)->since_ms < oldest->since_ms))
                oldest = UP(h);
        if (!oldest) {   /* max-uploads says so before the disk does (BUSY) */
            sts_handles_unlock(&srv->uploads);
            return -1;
        }
    }
    if (!room_locked(srv, u->total, u->fd, NULL, oldest, room)) {
        sts_handles_unlock(&srv->uploads);
        return -2;
    }
    sts_upload *evicted = oldest;
    if (oldest)
        sts_handles_unlink_locked(&srv->uploads, &oldest->hd);
    int full = sts_handles_add_locked(&srv->uploads, &u->hd, cap) != 0;
    sts_handles_unlock(&srv->uploads);
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
    sts_handles_lock(&srv->uploads);
    sts_upload *u = UP(sts_handles_find_locked(&srv->uploads, id, STS_ANY_OWNER));
    int found = u && (u->state == STS_UP_KEPT ||
                      (u->state != STS_UP_DONE && u->hd.owner == conn_id));
    if (found) {
        p->received = u->received;
        p->total = u->total;
    }
    sts_handles_unlock(&srv->uploads);
    return found;
}
