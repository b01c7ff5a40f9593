/* client/bench_cluster.c - seamtex-bench --cluster: the nodes a load goes to.
 *
 * Owns: asking a cluster for its membership (libseamtex's stc_cluster, the nodes' own ranking)
 * and turning the owners of the sampled set (SAMPLE) or every node (PING) into the list of
 * HOST:PORT the connections are spread over, round robin. Does not own: the connections or
 * the load (bench_loop.c, bench_wire.c).
 */
#include <stdio.h>
#include <string.h>

#include "bench.h"
#include "seamtex_cluster.h"
#include "stp_cluster.h"

int bench_cluster_targets(const bench_cfg *cfg, const char *seeds, bench_target *out,
                          unsigned max, char *msg, size_t ml)
{
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.token = cfg->token;
    o.client_name = "seamtex-bench";
    int err = 0;
    stc_cluster *cl = stc_cluster_open(seeds, &o, &err, msg, ml);
    if (!cl)
        return -1;
    size_t order[256];
    size_t n = stc_cluster_rank(cl, cfg->set, order, 256);
    if (bench_op_samples(cfg->op) && n > stc_cluster_replicas(cl))
        n = stc_cluster_replicas(cl);   /* only the owners hold the set */
    const stc_cluster_node *nodes;
    stc_cluster_nodes(cl, &nodes);
    unsigned got = 0;
    for (size_t r = 0; r < n && got < max; r++) {
        unsigned port;
        if (stp_split_addr(nodes[order[r]].addr, out[got].host, sizeof out[got].host, &port) != 0)
            continue;
        snprintf(out[got].port, sizeof out[got].port, "%u", port);
        got++;
    }
    stc_cluster_close(cl);
    if (!got) {
        snprintf(msg, ml, "the cluster has no node for set '%s'", cfg->set);
        return -1;
    }
    return (int)got;
}
