/* client/libcluster_int.h - private to libseamtex's cluster client: the stc_cluster handle
 * shared by libcluster.c (membership, ranking, blocking routed calls) and libcluster_pipe.c
 * (pipelined routed calls). Not installed.
 *
 * Node indices (nodes[i]) are stable while pipelined requests are outstanding: the view is
 * replaced (stc_cluster_refresh) only when none is, and a MOVED address not in the view is
 * appended at the end.
 */
#ifndef STC_CLUSTER_INT_H
#define STC_CLUSTER_INT_H

#include <stdint.h>

#include "seamtex_cluster.h"
#include "stp_cluster.h"

#define MAX_NODES 256
#define DOWN_MS   1000   /* a node that failed is tried last for this long */

typedef struct cl_node {
    char      id[STP_MAX_NODE_ID + 1];
    char      addr[STP_MAX_NODE_ADDR + 1];
    stc_conn *conn;
    int64_t   down_until;
} cl_node;

typedef struct stc__cl_pipe stc__cl_pipe;   /* libcluster_pipe.c; NULL until first used */

struct stc_cluster {
    stc_opts  opts;
    char      token[STP_MAX_TOKEN + 1];
    char      name[64];
    cl_node   nodes[MAX_NODES];
    size_t    n;
    unsigned  replicas;
    stc_cluster_node pub[MAX_NODES];
    const char *ids[MAX_NODES];
    int64_t   last_refresh;
    int       refresh_due;   /* a call saw a failover or MOVED: refresh at the start of the next */
    stc_cluster_counters cnt;
    char      msg[1024];
    stc__cl_pipe *pipe;
};

/* libcluster.c: 1 when rc means "try the next node" (connection error, timeout, shutdown). */
int stc__cluster_conn_error(int rc);
/* libcluster.c: adds a node by address (id may be the address); its index, or -1 when full. */
int stc__cluster_add_node(stc_cluster *cl, const char *id, const char *addr);

/* libcluster.c: the NOT_FOUND rule of every routed call (docs/cluster.md): after NOT_FOUND, the
 * position in tries[] (nt nodes, in the order they are tried) of the next node to ask: the
 * owners (owner[i] != 0) not tried yet (tried[i] != 0), then, when a node could not be reached
 * (unreached), any node not tried yet; nt when none is left. */
size_t stc__cluster_next_after_not_found(const size_t *tries, size_t nt, const char *tried,
                                         const char *owner, int unreached);

/* libcluster_pipe.c: pipelined requests outstanding (0 when the pipe was never used). */
size_t stc__cluster_pipe_pending(const stc_cluster *cl);
/* libcluster_pipe.c: frees the pipe (NULL accepted); the connections are cl's. */
void stc__cluster_pipe_free(stc__cl_pipe *p);

#endif
