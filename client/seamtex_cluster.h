/* client/seamtex_cluster.h - libseamtex's cluster client: one handle over every node of a
 * seamtex cluster (docs/cluster.md).
 *
 * Owns: the client's view of the membership (from seed nodes answering CLUSTER), routing of
 * each call to the set's owners by rendezvous hashing (protocol/stp_cluster.h: the same
 * ranking the nodes compute), failover to the next node in the ranking on a connection error
 * or timeout, following MOVED and refreshing the view, one connection per node (opened when
 * first needed). Does not own: the wire protocol, single-node calls (seamtex.h).
 *
 * THREADING: an stc_cluster is used by one thread at a time (it owns its connections).
 * OWNERSHIP: stc_cluster_open returns a handle freed with stc_cluster_close (NULL accepted).
 * Results of a routed call (sample values, info faces, messages) are owned by the connection
 * that answered and valid until the next call on this handle.
 * ERRORS: as seamtex.h; a call fails with a connection error only when every node tried
 * failed; stc_cluster_errmsg says why.
 */
#ifndef SEAMTEX_CLUSTER_H
#define SEAMTEX_CLUSTER_H

#include "seamtex.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct stc_cluster stc_cluster;

typedef struct stc_cluster_node {
    const char *id;        /* node id (a MOVED address not yet in the view: the address) */
    const char *addr;      /* "host:port" */
} stc_cluster_node;

/* Opens from seeds "HOST:PORT[,HOST:PORT...]": the first seed that answers CLUSTER gives the
 * membership. opts (may be NULL) applies to every connection; a request timeout of 0 becomes
 * 5000 ms (failover needs one). NULL on failure with *err and errmsg set. */
stc_cluster *stc_cluster_open(const char *seeds, const stc_opts *opts, int *err, char *errmsg,
                              size_t errmsg_len);
void stc_cluster_close(stc_cluster *cl);
const char *stc_cluster_errmsg(const stc_cluster *cl);

/* Asks the nodes for the membership again (each in turn until one answers). */
int stc_cluster_refresh(stc_cluster *cl);
/* The membership as last seen (owned by cl, valid until the next call on cl). */
size_t stc_cluster_nodes(stc_cluster *cl, const stc_cluster_node **nodes);
unsigned stc_cluster_replicas(const stc_cluster *cl);
/* The ranking of the nodes for set (owners first: the first stc_cluster_replicas); writes up
 * to max node indices into idx; returns how many. */
size_t stc_cluster_rank(stc_cluster *cl, const char *set, size_t *idx, size_t max);
/* The connection to node i (opened now if needed); NULL with *err on failure. Owned by cl. */
stc_conn *stc_cluster_conn(stc_cluster *cl, size_t i, int *err);

/* Runs fn(conn, arg) on the set's first owner, then on the next node in the ranking while fn
 * fails with a connection error or a timeout, following MOVED replies; NOT_FOUND from an owner
 * sends it on to the owners not asked yet (and, when an owner could not be reached, to the
 * rest of the ranking): NOT_FOUND is returned only when no node asked holds the set. A call
 * that fails on what may be a stale view refreshes it and routes once more; otherwise the
 * view is refreshed at the start of the next call, so results stay valid until then.
 * *used (may be NULL) gets the connection that answered. Returns fn's last result. */
typedef int (*stc_cluster_fn)(stc_conn *c, void *arg);
int stc_cluster_call(stc_cluster *cl, const char *set, stc_cluster_fn fn, void *arg,
                     stc_conn **used);

/* Routed forms of the calls of seamtex.h (same arguments and results). */
int stc_cluster_sample(stc_cluster *cl, const char *set, const stc_sample_opts *o,
                       const stc_query *q, size_t n, stc_sample_result *res);
int stc_cluster_info(stc_cluster *cl, const char *set, uint32_t face_first, uint32_t face_count,
                     stc_info *out);
int stc_cluster_upload_file(stc_cluster *cl, const char *path, const char *set,
                            const stc_upload_opts *o, stc_upload_result *out);
int stc_cluster_delete(stc_cluster *cl, const char *set);

typedef struct stc_cluster_counters {
    uint64_t calls, failovers, moved, refreshes;
} stc_cluster_counters;
void stc_cluster_get_counters(const stc_cluster *cl, stc_cluster_counters *out);

#ifdef __cplusplus
}
#endif
#endif
