/* cluster/etcd.h - a small client of etcd's v3 JSON gateway (libcurl + json-c).
 *
 * Owns: the etcd URL grammar (etcd://HOST:PORT[,HOST:PORT...]/PREFIX), HTTP POSTs to the
 * gateway (/v3/kv/range, /v3/kv/put, /v3/kv/txn, /v3/kv/deleterange, /v3/lease/grant,
 * /v3/lease/keepalive), the base64 of keys and values, the JSON shapes of etcd 3.4 (int64s
 * come as JSON strings), failing over between endpoints. Does not own: what the keys mean
 * (catalog.h), threads (the caller's).
 *
 * Errors: every call returns 0, or SCL_EUNREACHABLE (no endpoint answered within the deadline)
 * or SCL_EBADREPLY (an answer that is not what etcd sends), or SCL_ECANCELED (the handle's
 * abort flag was set), with a message in e->msg.
 * Threading: one scl_etcd is used by one thread at a time (it owns one curl handle); open one
 * per thread, or lock around it. curl_global_init must have run (scl_etcd_global_init) before
 * the first open, on a thread of its own while no other thread uses curl.
 * Ownership: scl_kvs results are the caller's, freed with scl_kvs_free.
 */
#ifndef SCL_ETCD_H
#define SCL_ETCD_H

#include <stddef.h>
#include <stdint.h>

enum { SCL_OK = 0, SCL_EUNREACHABLE = -1, SCL_EBADREPLY = -2, SCL_ENOMEM = -3,
       SCL_ECANCELED = -4   /* the abort flag (scl_etcd_set_abort) was set */ };

#define SCL_MAX_ENDPOINTS 8

typedef struct scl_etcd scl_etcd;

/* Parses url into endpoints and prefix without connecting (prefix: "/seamtex"; may not be
 * empty or end in '/'). 0, or -1 with a message in err. */
int scl_etcd_url_check(const char *url, char *prefix, size_t prefix_cap, char *err, size_t cap);
void scl_etcd_global_init(void);
/* NULL on a bad url (message in err) or out of memory. timeout_ms bounds every call. */
scl_etcd *scl_etcd_open(const char *url, int timeout_ms, char *err, size_t cap);
void scl_etcd_close(scl_etcd *e);
/* flag (NULL: none; not owned, read atomically, must outlive the handle's calls): while it is
 * nonzero a call fails at once with SCL_ECANCELED, and a call in progress gives up within
 * about a second (libcurl's progress callback) instead of waiting out its deadline on every
 * endpoint: what lets a stopping server leave an etcd that stopped answering. */
void scl_etcd_set_abort(scl_etcd *e, const int *flag);
/* The revision watch (docs/cluster.md "Catalogue lost"): etcd's revision only grows, and an
 * etcd restored from a snapshot or backup answers with a lower one than its clients have seen.
 * A watch, shared by the handles of one client (set with scl_etcd_set_revwatch; not owned,
 * must outlive their calls), holds the highest header.revision of their /v3/kv/ replies
 * (range, put, deleterange, txn: linearizable, so a reply to a request sent after revision r
 * was seen carries r or more from a store that did not go back; lease replies are not
 * watched: a follower fills their header from its own store). A kv reply whose revision is
 * below the highest the watch held when its request was sent marks the watch "went back"
 * (from: that highest, to: the reply's) until scl_revwatch_reset. Fields: atomics, use the
 * functions. */
typedef struct scl_revwatch {
    int64_t  top;                       /* the highest revision seen (or seeded) */
    int64_t  back_from, back_to;        /* 0: not gone back since the last reset */
    uint64_t gen;                       /* resets: a reply to a request sent before one is
                                           not judged against the new top */
} scl_revwatch;
void scl_etcd_set_revwatch(scl_etcd *e, scl_revwatch *w);
/* top = max(top, rev): a revision remembered from an earlier process */
void scl_revwatch_seed(scl_revwatch *w, int64_t rev);
int64_t scl_revwatch_top(scl_revwatch *w);
/* 1 with *from, *to when a reply went back since the last reset, else 0 */
int scl_revwatch_back(scl_revwatch *w, int64_t *from, int64_t *to);
/* Forgets the highest revision and any going back: top = rev (the catalogue adopted). */
void scl_revwatch_reset(scl_revwatch *w, int64_t rev);
const char *scl_etcd_prefix(const scl_etcd *e);
const char *scl_etcd_errmsg(const scl_etcd *e);

typedef struct scl_kv {
    char    *key;   size_t key_len;     /* NUL-terminated copies */
    char    *val;   size_t val_len;
    int64_t  create_rev, mod_rev, version, lease;
} scl_kv;
typedef struct scl_kvs {
    scl_kv  *v;
    size_t   n;
    int64_t  revision;                  /* of the store when read */
} scl_kvs;
void scl_kvs_free(scl_kvs *k);

/* Reads key (prefix 0) or every key starting with key (prefix 1), sorted by key. */
int scl_etcd_range(scl_etcd *e, const char *key, int prefix, scl_kvs *out);
/* The same as the store was at revision rev (> 0; 0: now), so that two reads see one state
 * (a revision etcd has compacted away is an error reply: SCL_EBADREPLY). */
int scl_etcd_range_at(scl_etcd *e, const char *key, int prefix, int64_t rev, scl_kvs *out);
int scl_etcd_put(scl_etcd *e, const char *key, const char *val, int64_t lease);
/* Deletes key, or every key under it with prefix 1. */
int scl_etcd_delete(scl_etcd *e, const char *key, int prefix);
int scl_etcd_grant(scl_etcd *e, int64_t ttl_s, int64_t *lease);
/* Renews a lease; *ttl 0 when etcd no longer knows it (expired). */
int scl_etcd_keepalive(scl_etcd *e, int64_t lease, int64_t *ttl);

/* A transaction: if every compare holds, the ops run (*succeeded 1), else none (*succeeded 0).
 * Compares: the key's create_revision or mod_revision EQUAL rev (create 0 = "absent"). */
enum { SCL_CMP_CREATE, SCL_CMP_MOD };
typedef struct scl_cmp { const char *key; int target; int64_t rev; } scl_cmp;
enum { SCL_OP_PUT, SCL_OP_DEL, SCL_OP_DEL_PREFIX };
typedef struct scl_op { int type; const char *key; const char *val; int64_t lease; } scl_op;
int scl_etcd_txn(scl_etcd *e, const scl_cmp *cmp, size_t ncmp, const scl_op *ops, size_t nops,
                 int *succeeded, int64_t *revision);

#endif
