/* client/seamtex_cluster.h - libseamtex's cluster client: one handle over every node of a
 * seamtex cluster (docs/cluster.md).
 *
 * Owns: the client's view of the membership (from seed nodes answering CLUSTER), routing of
 * each call to the set's owners by rendezvous hashing (protocol/stp_cluster.h: the same
 * ranking the nodes compute), failover to the next node in the ranking on a connection error
 * or timeout, following MOVED and refreshing the view, one connection per node (opened when
 * first needed); blocking routed calls (libcluster.c) and pipelined ones, several requests in
 * flight on several nodes at once (libcluster_pipe.c). Opening from an etcd URL is in
 * seamtex_etcd.h (libseamtex_etcd). Does not own: the wire protocol, single-node calls
 * (seamtex.h).
 *
 * THREADING: an stc_cluster is used by one thread at a time (it owns its connections).
 * OWNERSHIP: stc_cluster_open returns a handle freed with stc_cluster_close (NULL accepted).
 * Results of a routed call (sample values, info faces, messages) are owned by the connection
 * that answered and valid until the next call on this handle.
 * ERRORS: as seamtex.h; a call fails with a connection error only when every node tried
 * failed (STC_EINTERRUPTED, the caller's interrupt hook, is returned at once: stc_cluster_open); stc_cluster_errmsg says why (a node's refusal as "node ID: its message"; "" after a
 * routed call that succeeded). Every function that takes a handle accepts NULL:
 * STC_EINVAL from those that return a code (stc_cluster_conn: NULL with *err STC_EINVAL),
 * "" from stc_cluster_errmsg, 0 (and *nodes NULL) from the counts, zeros from
 * stc_cluster_get_counters.
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
 * 5000 ms (failover needs one). opts->interrupt (with interrupt_user, interrupt_every_ms) is
 * the hook of every connection the handle opens (seamtex.h stc_set_interrupt): when it stops
 * a routed call's wait (connect, HELLO, CLUSTER, the reply), the call returns
 * STC_EINTERRUPTED at once - not a connection error: no other node is tried, the node is not
 * marked down, no failover counted; a pipelined append whose connect it stops returns
 * that code (a request moved from a failed node is handed out with it). The handle stays usable (the abandoned reply is dropped, as on one connection).
 * NULL on failure with *err and errmsg set (err, errmsg may be NULL / 0). */
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
/* The connection to node i (opened now if needed); NULL with *err on failure (STC_EINVAL
 * for i past the nodes). Owned by cl. */
stc_conn *stc_cluster_conn(stc_cluster *cl, size_t i, int *err);

/* Runs fn(conn, arg) on the set's first owner, then on the next node in the ranking while fn
 * fails with a connection error or a timeout, following MOVED replies; NOT_FOUND from an owner
 * sends it on to the owners not asked yet (and, when an owner could not be reached, to the
 * rest of the ranking): NOT_FOUND is returned only when no node asked holds the set. A call
 * that fails on what may be a stale view refreshes it and routes once more; otherwise the
 * view is refreshed at the start of the next call, so results stay valid until then.
 * *used (may be NULL) gets the connection that answered (NULL when none did). Returns fn's
 * last result; STC_EINVAL for a NULL set or fn. */
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

/* ---- pipelined routed calls (client/libcluster_pipe.c) --------------------------------------
 * The cluster form of seamtex.h's append / get_reply API, for the calls that name a set:
 * SAMPLE, SAMPLE_DIR and INFO. Each append is routed at once (first owner, nodes marked down
 * last, as stc_cluster_call) and queued on that node's one connection; requests for sets owned
 * by different nodes go out concurrently, and any number may be in flight per node (the
 * caller keeps its window, e.g. -P of seamtex-bench). The arguments are copied (the caller's
 * buffers are free again when the append returns), so that a request can be sent again:
 *   - a connection error on a node, or no reply to its oldest request within the request
 *     timeout, closes that node's connection and sends every request in flight on it to the
 *     next node of its set's ranking (stc_cluster_counters.failovers counts them);
 *   - a MOVED reply sends the request to the address it names (up to 4 hops).
 *   - NOT_FOUND follows stc_cluster_call's rule: the next owner not asked, and the rest of
 *     the ranking when a node failed on the way; only then is NOT_FOUND handed out.
 * The membership is refreshed (when a failure or MOVED asked for it) only while nothing is in
 * flight; stc_cluster_refresh and the blocking stc_cluster_* calls return STC_ESTATE while
 * pipelined requests are outstanding.
 * ORDER: replies are handed out as they are read: one node's in the order it answers, across
 * nodes whichever is read first (busy nodes are looked at round robin, so none is starved);
 * not in the order of the appends. Match them by reqid. A request that was sent again answers
 * when its new node does; a request that no node could take comes back as a reply with conn
 * NULL and status the last connection error (every request appended gets exactly one reply).
 * ERRORS: an append returns an error with nothing appended (a bad argument, or no node
 * reachable); stc_cluster_get_reply returns STC_ESTATE with nothing outstanding, STC_ETIMEDOUT
 * when no reply came within timeout_ms (as stc_get_reply: 0 = only what has arrived, < 0 = the
 * request timeout); requests stay outstanding. */
int stc_cluster_append_sample(stc_cluster *cl, const char *set, const stc_sample_opts *o,
                              const stc_query *q, size_t n, uint32_t *reqid);
int stc_cluster_append_sample_dir(stc_cluster *cl, const char *set, const stc_sample_opts *o,
                                  const stc_dir_query *q, size_t n, uint32_t *reqid);
int stc_cluster_append_info(stc_cluster *cl, const char *set, uint32_t *reqid);
/* Sends what is queued on every node (per-request timeout; a node that fails has its requests
 * sent elsewhere). 0, or STC_ESTATE with nothing outstanding. */
int stc_cluster_flush(stc_cluster *cl);

typedef struct stc_cluster_reply {
    uint32_t       reqid;     /* as the append returned it */
    unsigned       opcode;
    int            status;    /* 0, a server status, or (conn NULL) the last connection error */
    const char    *errmsg;    /* "" when status == 0 */
    const char    *set;       /* the set the request named */
    size_t         node;      /* index of the node that answered (stc_cluster_nodes); SIZE_MAX
                                 when none did */
    stc_conn      *conn;      /* that node's connection, NULL when none answered */
    stc_reply      reply;     /* the reply as stc_get_reply gave it on conn */
} stc_cluster_reply;
/* The next reply (flushing first). Everything r points to is owned by cl and valid until the
 * next call on cl. */
int stc_cluster_get_reply(stc_cluster *cl, int timeout_ms, stc_cluster_reply *r);
/* Decoders for a reply of stc_cluster_get_reply (results owned by r->conn, valid as r is);
 * they return r->status when it is not 0. */
int stc_cluster_reply_sample(const stc_cluster_reply *r, stc_sample_result *res);
int stc_cluster_reply_info(const stc_cluster_reply *r, stc_info *out);
/* Requests appended and not yet handed out. */
size_t stc_cluster_pending(const stc_cluster *cl);
/* Gives up on every outstanding pipelined request (late replies are dropped); returns how
 * many. */
size_t stc_cluster_discard_pending(stc_cluster *cl);

typedef struct stc_cluster_counters {
    uint64_t calls, failovers, moved, refreshes;
} stc_cluster_counters;
void stc_cluster_get_counters(const stc_cluster *cl, stc_cluster_counters *out);

#ifdef __cplusplus
}
#endif
#endif
