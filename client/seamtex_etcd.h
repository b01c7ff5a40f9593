/* client/seamtex_etcd.h - opening an stc_cluster from the cluster's etcd (libseamtex_etcd).
 *
 * Owns: reading the membership a cluster of seamtexd keeps in etcd (PREFIX/nodes/<id>,
 * docs/cluster.md "Keys") and opening stc_cluster with those nodes as seeds. Lives in its own
 * library so that libseamtex.a stays free of libcurl and json-c: link with
 *     -lseamtex_etcd -lseamtex $(pkg-config --libs libcurl json-c)
 * (pkg-config seamtex-etcd gives the same). Does not own: the cluster client
 * (seamtex_cluster.h), the etcd gateway client (cluster/etcd.c).
 *
 * THREADING: may be called from any thread; libcurl's global set-up runs once (pthread_once).
 * OWNERSHIP and ERRORS: as stc_cluster_open.
 */
#ifndef SEAMTEX_ETCD_H
#define SEAMTEX_ETCD_H

#include "seamtex_cluster.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Opens from url "etcd://HOST:PORT[,HOST:PORT...]/PREFIX" (seamtexd --cluster's URL): the
 * nodes registered under PREFIX/nodes/ become the seeds of stc_cluster_open, whose first
 * answering node gives the membership and R. opts->connect_timeout_ms (0 = 2000) also bounds
 * each etcd request. NULL on failure with *err (STC_EINVAL: not such a URL; STC_ECONNECT: no
 * etcd endpoint answered, or no node is registered; STC_EPROTO: etcd's reply was not
 * understood; or stc_cluster_open's code) and a message in errmsg. */
stc_cluster *stc_cluster_open_etcd(const char *url, const stc_opts *opts, int *err,
                                   char *errmsg, size_t errmsg_len);
/* stc_cluster_open_etcd for a string that starts with "etcd://", else stc_cluster_open
 * (seeds "HOST:PORT[,...]"): what a --cluster option takes. */
stc_cluster *stc_cluster_open_url(const char *where, const stc_opts *opts, int *err,
                                  char *errmsg, size_t errmsg_len);

#ifdef __cplusplus
}
#endif
#endif
