/* server/shm.h - shared-memory sampling for clients on a Unix connection (shm.c; PROTOCOL.md
 * 4.12, docs/daemon.md "Shared-memory sampling").
 *
 * Owns: the descriptors a Unix connection receives (SCM_RIGHTS), the connection's mapped
 * region (struct sts_shm_conn), the SHM_ATTACH handler, the shared-memory form of SAMPLE /
 * SAMPLE_DIR (queries copied once out of the region into thread-private memory, the reply
 * written into it), the per-thread private buffers (struct sts_shm_scratch) and the shm_*
 * STATS keys. Does not own: sampling (h_basic.c: sts_sample_run), reading frames (io.c calls
 * sts_shm_recv on Unix connections), the connection's life (io.c calls sts_shm_conn_free).
 *
 * Safety: the region is shared with a client that may rewrite or (were it not sealed)
 * truncate it at any moment. The daemon maps only a memfd sealed against shrinking and
 * growing whose size is the one announced, reads each request's queries exactly once (one
 * memcpy into private memory, before anything looks at them), never reads back what it wrote
 * there, and checks every offset and length against the mapping with overflow-free arithmetic.
 *
 * Threads: sts_shm_recv, the attach and sts_shm_conn_free run on the connection's I/O thread;
 * sts_shm_sample on whichever thread runs the request (I/O or worker), which only reads
 * conn->shm: it is set by an earlier request of the same connection, and a connection has one
 * request out at a time, handed over through the pool's lock.
 */
#ifndef STS_SHM_H
#define STS_SHM_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "dispatch.h"

#define STS_SHM_MAX_FDS 4     /* descriptors held per connection before SHM_ATTACH takes them */

typedef struct sts_shm_conn {
    int      fds[STS_SHM_MAX_FDS];   /* received and not yet taken, oldest first */
    unsigned nfds;
    uint8_t *map;                    /* the attached region, NULL = none */
    uint64_t size;
} sts_shm_conn;

/* Private memory of one thread for shared-memory requests: the copied queries and the reply
 * before it goes into the region. Grows, never shrinks. */
typedef struct sts_shm_scratch {
    uint8_t *q;
    size_t   qcap;
    stp_buf  reply;
} sts_shm_scratch;
void sts_shm_scratch_free(sts_shm_scratch *s);   /* NULL accepted; frees s too */

/* recv() for a Unix connection: the same result, and descriptors that come with the bytes
 * are kept for SHM_ATTACH (STS_SHM_MAX_FDS at most; more are closed at once, shm_fds_dropped). */
ssize_t sts_shm_recv(sts_server *srv, sts_conn *c, void *buf, size_t len);
/* Unmaps the region and closes held descriptors; the connection is closing. */
void sts_shm_conn_free(sts_server *srv, sts_conn *c);

STS_HANDLER(sts_h_shm_attach);
/* A decoded SAMPLE / SAMPLE_DIR request with STP_SF_SHM: checks the offsets, copies the
 * queries, samples (sts_sample_run), writes the reply into the region and appends one frame to
 * out (the stp_shm_reply, or an error). Returns 0. */
int sts_shm_sample(sts_ctx *c, const stp_header *h, stp_sample_req *rq, stp_buf *out);

/* The shm_* STATS entries (PROTOCOL.md 4.7); fills at most cap, returns how many. */
size_t sts_shm_stats(sts_server *srv, stp_stat *s, size_t cap);
#define STS_SHM_STAT_KEYS 7

#endif
