/* tests/common/cluster_fixture.h - the pieces of a loopback seamtex cluster shared by the
 * cluster tests (tests/integration/test_cluster*.c).
 *
 * Owns: starting node i of a cluster (seamtexd --cluster <etcd> --node-id n<i>, 2 s leases, a
 * repair pass every second, no default set) with a chosen R and W; .ptx files of distinct
 * contents ("tints": face 0 repainted) to upload; reading the red channel at the middle of
 * face 0, which tells a tint apart; a cluster client seeded with the nodes. Does not own:
 * etcd (etcd_fixture.h), the daemon process (daemon_fixture.h), what a test checks.
 */
#ifndef ST_CLUSTER_FIXTURE_H
#define ST_CLUSTER_FIXTURE_H

#include <stdint.h>

#include "daemon_fixture.h"
#include "seamtex_cluster.h"

/* Starts d as node "n<idx>" of the cluster at etcd_url with replicas R and write quorum W
 * (0: W = R). 0 or -1. Call again after a kill to restart it with the same data dir and id. */
int st_cluster_node_start(st_daemon *d, const char *etcd_url, int idx, unsigned R, unsigned W);

/* 1 when each of the n nodes counts `members` members and reaches etcd (STATS
 * cluster_members, cluster_etcd_ok). */
int st_cluster_all_see(const st_daemon *nodes, int n, uint64_t members);

/* A cluster client with the n nodes as seeds (127.0.0.1:port each), or NULL. */
stc_cluster *st_cluster_open_nodes(const st_daemon *nodes, int n);

/* Writes n tint files <dir>/tint<t>.ptx (tint t * step) and their paths into files[t]
 * (each cap bytes). 0 or -1. */
int st_cluster_tint_files(const char *dir, int n, int step, char (*files)[300]);

/* Uploads each tint file through cl under the name "probe", reads its red value into red[t]
 * and deletes it again. 0, or the first failing call's status. */
int st_cluster_tint_reds(stc_cluster *cl, int n, char (*files)[300], float *red);

/* The SAMPLE the red helpers send: one bilinear query at the middle of face 0. */
void st_red_query(stc_sample_opts *o, stc_query *q);
/* The red channel at the middle of face 0 of set through c into *red; 0 or the status. */
int st_red_at(stc_conn *c, const char *set, float *red);
/* The same through the cluster client. */
int st_cluster_red_at(stc_cluster *cl, const char *set, float *red);
/* Reads each of the n sets names[] through cl every 50 ms for ms milliseconds and compares
 * its red value with want[]; prints the first 5 misses and the totals; returns the number of
 * reads that failed or gave other contents. */
int st_cluster_read_all_for(stc_cluster *cl, const char *const *names, int n, const float *want,
                            int ms);
/* The red channel of set read from node d alone (a connection of its own), or -1 when d does
 * not serve it. */
float st_red_on(const st_daemon *d, const char *set);

/* Runs `$SEAMTEX_BUILD/seamtex --cluster where args...` (posix_spawn: no fork in a process
 * linking OIIO; args NULL-terminated, at most 12), its stdout into out (cap bytes, through a
 * file in dir); returns the exit status (128 when killed), or -1 when it could not start. */
int st_cluster_cli(const char *dir, const char *where, const char *const *args, char *out,
                   size_t cap);

#endif
