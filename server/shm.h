/* server/shm.h - shared-memory sampling for clients on a Unix connection (shm.c; PROTOCOL.md
 * 4.12, docs/daemon.md "Shared-memory sampling").
 *
 * Owns: the descriptors a Unix connection receives (SCM_RIGHTS), the connection's mapped
 * region (struct sts_shm_conn), the SHM_ATTACH handler, the shared-memory form of SAMPLE /
 * SAMPLE_DIR (shm_sample.c: queries copied out of the region in small chunks, each byte read
 * once, replies written straight into it), the per-thread private buffers (struct
 * sts_shm_scratch) and the shm_* STATS keys. Does not own: the sampling steps every SAMPLE
 * shares (h_basic.c), reading frames (io.c calls sts_shm_recv on Unix connections), the
 * connection's life (io.c calls sts_shm_conn_free).
 *
 * Safety: the region is shared with a client that may rewrite or (were it not sealed)
 * truncate it at any moment. The daemon maps only a memfd sealed against shrinking and
 * growing whose size is the one announced, reads each query byte exactly once (a memcpy of a
 * chunk into private memory, before anything looks at it), never reads back what it wrote
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

/* Private memory of one thread for shared-memory requests whose query and reply rooms
 * overlap: their queries, copied whole before the first reply byte is written. Grows, never
 * shrinks. */
typedef struct sts_shm_scratch {
    uint8_t *q;
    size_t   qcap;
} sts_shm_scratch;
void sts_shm_scratch_free(sts_shm_scratch *s);   /* NULL accepted; frees s too */

/* readv() for a Unix connection (niov buffers filled in turn: io.c's split reads): the same
 * result, and descriptors that come with the bytes are kept for SHM_ATTACH (STS_SHM_MAX_FDS
 * at most; more are closed at once, shm_fds_dropped). */
struct iovec;
ssize_t sts_shm_recv(sts_server *srv, sts_conn *c, struct iovec *iov, int niov);
/* Unmaps the region and closes held descriptors; the connection is closing. */
void sts_shm_conn_free(sts_server *srv, sts_conn *c);

STS_HANDLER(sts_h_shm_attach);
/* shm_sample.c: a decoded SAMPLE / SAMPLE_DIR request with STP_SF_SHM: checks the offsets,
 * samples the queries in place, writes the reply into the region and appends one frame to
 * out (the stp_shm_reply, or an error). Returns 0. */
int sts_shm_sample(sts_ctx *c, const stp_header *h, stp_sample_req *rq, stp_buf *out);

/* The shm_* STATS entries (PROTOCOL.md 4.7); fills at most cap, returns how many. */
size_t sts_shm_stats(sts_server *srv, stp_stat *s, size_t cap);
#define STS_SHM_STAT_KEYS 8

#endif
