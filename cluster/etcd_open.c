/* cluster/etcd_open.c - stc_cluster_open_etcd and stc_cluster_open_url (seamtex_etcd.h): the
 * membership read from etcd (PREFIX/nodes/, catalog.h) as the seeds of stc_cluster_open.
 * Built into libseamtex_etcd.a (with etcd.c and catalog.c) for clients, and into
 * libseamtex_cluster.a with the rest of cluster/.
 */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "catalog.h"
#include "etcd.h"
#include "seamtex_etcd.h"

static pthread_once_t curl_once = PTHREAD_ONCE_INIT;

/* "a,b,c" of the nodes' addresses into seeds (cap bytes); how many, or -1 with *err, msg */
static int read_members(const char *url, int timeout_ms, char *seeds, size_t cap, int *err,
                        char *msg, size_t ml)
{
    char prefix[256], why[256] = "";
    if (scl_etcd_url_check(url, prefix, sizeof prefix, why, sizeof why) != 0) {
        *err = STC_EINVAL;
        snprintf(msg, ml, "%s", why);
        return -1;
    }
    pthread_once(&curl_once, scl_etcd_global_init);
    scl_etcd *e = scl_etcd_open(url, timeout_ms, why, sizeof why);
    if (!e) {
        *err = STC_ENOMEM;
        snprintf(msg, ml, "%s", why[0] ? why : "out of memory");
        return -1;
    }
    char key[SCL_KEY_MAX];
    scl_key_node(key, prefix, "");
    scl_kvs kvs;
    memset(&kvs, 0, sizeof kvs);
    int rc = scl_etcd_range(e, key, 1, &kvs), n = 0;
    if (rc != SCL_OK) {
        *err = rc == SCL_EUNREACHABLE ? STC_ECONNECT : rc == SCL_ENOMEM ? STC_ENOMEM : STC_EPROTO;
        snprintf(msg, ml, "etcd: %s", scl_etcd_errmsg(e));
        scl_etcd_close(e);
        return -1;
    }
    size_t len = 0;
    seeds[0] = 0;
    for (size_t i = 0; i < kvs.n; i++) {
        char addr[STP_MAX_NODE_ADDR + 1];
        uint64_t inc;
        if (scl_node_parse(kvs.v[i].val, addr, sizeof addr, &inc) != 0)
            continue;                     /* not a node record: not a seed */
        size_t al = strlen(addr);
        if (len + al + 2 > cap)
            break;                        /* enough seeds: any one gives the membership */
        if (len)
            seeds[len++] = ',';
        memcpy(seeds + len, addr, al + 1);
        len += al;
        n++;
    }
    scl_kvs_free(&kvs);
    scl_etcd_close(e);
    if (!n) {
        *err = STC_ECONNECT;
        snprintf(msg, ml, "no seamtexd is registered under %s in etcd", key);
        return -1;
    }
    return n;
}

stc_cluster *stc_cluster_open_etcd(const char *url, const stc_opts *opts, int *err,
                                   char *errmsg, size_t errmsg_len)
{
    int dummy;
    char scratch[8];
    if (!err)
        err = &dummy;
    if (!errmsg || !errmsg_len) {
        errmsg = scratch;
        errmsg_len = sizeof scratch;
    }
    if (!url) {
        *err = STC_EINVAL;
        snprintf(errmsg, errmsg_len, "etcd URL is NULL");
        return NULL;
    }
    int tmo = opts && opts->connect_timeout_ms > 0 ? opts->connect_timeout_ms : 2000;
    char seeds[4096];
    if (read_members(url, tmo, seeds, sizeof seeds, err, errmsg, errmsg_len) < 0)
        return NULL;
    return stc_cluster_open(seeds, opts, err, errmsg, errmsg_len);
}

stc_cluster *stc_cluster_open_url(const char *where, const stc_opts *opts, int *err,
                                  char *errmsg, size_t errmsg_len)
{
    if (where && !strncmp(where, "etcd://", 7))
        return stc_cluster_open_etcd(where, opts, err, errmsg, errmsg_len);
    return stc_cluster_open(where, opts, err, errmsg, errmsg_len);
}
