/* server/uploads.h - the table of uploads and their life (private to the server).
 *
 * Owns: struct sts_upload and its states; finding, adopting (RESUME), keeping, sweeping and
 * dropping uploads, on srv->uploads (a handle table, handles.h: ids, owner, the live count).
 * Does not own: the handlers that fill an upload (h_upload.c), the data dir, the generic
 * table (handles.c).
 *
 * Locking: srv->uploads.mu guards the list, the states and the live count (the records that
 * are not DONE count against max-uploads). A HELD upload is used without the lock by the one connection that holds it (its
 * requests run one at a time); a COMMITTING one by the worker running its COMMIT; KEPT and
 * DONE records are touched only under the lock, since the sweep may drop them at any time.
 * Exception: `received` of a HELD upload is read by other threads (the disk check at
 * UPLOAD_BEGIN sums what is still promised), so it is stored and read atomically.
 *
 * Ownership: records are allocated by the UPLOAD_BEGIN handler and owned by the table once
 * inserted; sts_upload_free closes the temp file and removes it.
 */
#ifndef STS_UPLOADS_H
#define STS_UPLOADS_H

#include "server.h"
#include "handles.h"

typedef struct sts_upload sts_upload;

/* An upload's life: HELD by a connection -> (COMMIT) COMMITTING -> DONE, or -> KEPT when its
 * connection closes (upload-keep > 0) -> HELD again by the connection that resumes it, or
 * dropped after upload-keep. DONE keeps the commit's summary for upload-keep seconds so that
 * a client whose connection broke while COMMIT ran learns that it succeeded (RESUME, then
 * COMMIT again, answers the same summary) instead of uploading again. */
enum { STS_UP_HELD, STS_UP_COMMITTING, STS_UP_KEPT, STS_UP_DONE };
#define MAX_DONE 16   /* DONE records kept at most (the oldest goes first) */

struct sts_upload {
    sts_handle  hd;          /* first: id, owner connection (conn id; 0 once DONE), live */
    char        name[ST_NAME_MAX + 1];
    char        hint[STP_MAX_HINT + 1];      /* as the client sent it (matched on RESUME) */
    char        fmt[STP_MAX_HINT + 1];       /* the format the file is imported as */
    char        options[STP_MAX_OPTIONS + 1];
    uint64_t    total;
    uint64_t    received;    /* written by the holder with __atomic_store_n: the disk check of
                              * another BEGIN reads it under the table's lock (uploads.c) */
    uint32_t    crc_want, crc;
    uint32_t    flags;
    int         state;
    uint64_t    native;      /* COMMITTING: bytes of free disk promised to the set's native
                              * file (sts_uploads_promise_native; set and read under the lock) */
    int64_t     since_ms;    /* KEPT: when its connection closed; DONE: when committed */
    uint64_t    gen;         /* DONE: registry generation of the set it made */
    stp_upload_done done;    /* DONE: the COMMIT reply */
    int         fd;
    char        path[4096];
};

/* Closes the temp file, removes it (path non-empty) and frees the record. */
void sts_upload_free(sts_upload *u);
/* Frees every record (server teardown, no other thread left) and the table's mutex. */
void sts_uploads_free(sts_server *srv);

/* A closing connection's unfinished uploads are kept for upload-keep seconds (resume), or
 * dropped when it is 0. Called by its I/O thread. */
void sts_upload_drop_conn(sts_server *srv, uint64_t conn_id);
/* Drops kept and DONE uploads older than upload-keep (the I/O threads call it once a second). */
void sts_uploads_sweep(sts_server *srv, int64_t now_ms);

/* The disk check of UPLOAD_BEGIN (upl35): what sts_uploads_insert saw. */
typedef struct sts_upload_room {
    uint64_t avail;      /* free bytes of the temp files' file system (f_bavail * f_frsize) */
    uint64_t promised;   /* bytes the uploads in the table still expect (total - received),
                          * and the native files of the ones committing */
    uint64_t headroom;   /* kept free: 1/64 of the file system's size, at most 64 MiB */
} sts_upload_room;

/* Adds a new HELD record and gives it an id. When the table is full the oldest KEPT upload
 * is dropped to make room; returns -1 (nothing added) when it is full of live uploads.
 * Before that, under the table's lock (so two BEGINs cannot both take the same free bytes):
 * u->total + the bytes promised to the HELD, KEPT and COMMITTING uploads (and the native
 * files of the COMMITTING ones, sts_uploads_promise_native) + the headroom
 * must fit in the free space of the file system of u->fd (its temp file), else -2, nothing
 * added, *room says why. A record's promise ends when it leaves the table or becomes DONE.
 * When fstatvfs fails the check is skipped (the old behaviour: a full disk shows at CHUNK). */
int sts_uploads_insert(sts_server *srv, sts_upload *u, sts_upload_room *room);

/* UPLOAD_COMMIT with a data dir and native files, once the set is imported (res36): the
 * native file's `bytes` + the bytes promised to the other unfinished uploads (bodies still to
 * come, native files being written) + the headroom must fit in the free space of the file
 * system of dir (u's file, in the data dir's tmp/). Then u->native = bytes, a promise that
 * ends with u's record as the others do, and 0; else -1, *room says why. When statvfs fails
 * the check is skipped (0). */
int sts_uploads_promise_native(sts_server *srv, sts_upload *u, const char *dir, uint64_t bytes,
                               sts_upload_room *room);

/* UPLOAD_BEGIN with RESUME: finds the record of the same name, size, CRC32C, hint and options
 * and gives it to conn_id: a KEPT upload becomes HELD again; a DONE one is lent so that COMMIT
 * can repeat its reply (only while its set is still the one it made). Copies what the reply
 * needs into *id / *received; returns 1 when found, 0 when none matches, -1 when a match is
 * HELD by another live connection or still COMMITTING (the caller answers BUSY). */
int sts_uploads_adopt(sts_server *srv, const stp_upload_begin *rq, uint64_t conn_id,
                      uint64_t *id, uint64_t *received);

/* Finds the caller's HELD upload. take 0: leaves it; take 1: removes it from the table
 * (ABORT); take 2: marks it COMMITTING (COMMIT; sts_uploads_finish_commit ends that). */
sts_upload *sts_uploads_find(sts_server *srv, uint64_t id, uint64_t conn_id, int take);

/* COMMIT of a DONE record the caller took over with RESUME: copies its original reply into
 * *out under the lock (the sweep may drop the record right after); 1 when there is one. */
int sts_uploads_done_reply(sts_server *srv, uint64_t id, uint64_t conn_id, stp_upload_done *out);

/* Ends a COMMITTING upload: dropped when it failed (done NULL); DONE with its reply when it
 * made a set and upload-keep > 0. */
void sts_uploads_finish_commit(sts_server *srv, sts_upload *u, const stp_upload_done *done);

/* UPLOAD_STATUS: the progress of the caller's own upload or of a KEPT one; 1 when found. */
int sts_uploads_progress(sts_server *srv, uint64_t id, uint64_t conn_id, stp_upload_progress *p);

#endif
