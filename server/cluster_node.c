/* server/cluster_node.c - the node's place in the cluster: start / stop, the membership
 * thread, the view shared with handlers, CLUSTER, MOVED and the STATS keys
 * (cluster_node.h; design: docs/cluster.md).
 *
 * Owns: the lease (granted, kept alive every TTL/3, re-granted when etcd forgot it), the
 * node's key, the membership view (polled every min(TTL/3, 500 ms)), the etcd-reachable
 * flag. Does not own: repair (cluster_repair.c), the write path (cluster_write.c), the HTTP
 * (cluster/etcd.c).
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cluster_node.h"
#include "dispatch.h"
#include "peer.h"
#include "server.h"

int sts_cluster_etcd_ok(sts_cluster *cl)
{
    return __atomic_load_n(&cl->etcd_ok, __ATOMIC_RELAXED);
}

void sts_cluster_note_etcd(sts_cluster *cl, int rc)
{
    if (rc == SCL_ECANCELED)
        return;   /* not asked (stopping): says nothing about etcd */
    int ok = rc != SCL_EUNREACHABLE;
    int was = __atomic_exchange_n(&cl->etcd_ok, ok, __ATOMIC_RELAXED);
    if (!ok)
        STS_CL_ADD(cl, etcd_errors, 1);
    if (ok && __atomic_load_n(&cl->recheck, __ATOMIC_RELAXED) &&
        __atomic_exchange_n(&cl->recheck, 0, __ATOMIC_RELAXED))
        sts_cluster_kick(cl);   /* a publish left unchecked: the catalogue decides now */
    if (was != ok)
        sts_logf(&cl->srv->log, ok ? STS_INFO : STS_WARN, "cluster: etcd %s", ok
                 ? "reachable again: uploads, deletes and compress jobs accepted"
                 : "unreachable: serving with the last membership; uploads, deletes and "
                   "compress jobs refused (UNAVAILABLE)");
}

size_t sts_cluster_rank(const sts_cl_member *m, size_t n, const char *name, size_t *order, size_t k)
{
    const char *ids[256];
    if (n > 256)
        n = 256;
    for (size_t i = 0; i < n; i++)
        ids[i] = m[i].id;
    return stp_hrw_rank(ids, n, name, order, k);
}

size_t sts_cluster_members(sts_cluster *cl, sts_cl_member **members, uint64_t *epoch)
{
    pthread_mutex_lock(&cl->mu);
    size_t n = cl->nmembers;
    *members = malloc((n ? n : 1) * sizeof **members);
    if (*members && n)
        memcpy(*members, cl->members, n * sizeof **members);
    if (!*members)
        n = 0;
    if (epoch)
        *epoch = cl->epoch;
    pthread_mutex_unlock(&cl->mu);
    return n;
}

void sts_cluster_set_catalogue(sts_cluster *cl, sts_cl_entry *cat, size_t n)
{
    pthread_mutex_lock(&cl->mu);
    sts_cl_entry *old = cl->cat;
    cl->cat = cat;
    cl->ncat = n;
    pthread_mutex_unlock(&cl->mu);
    free(old);
}

void sts_cluster_set_served(sts_cluster *cl, struct sts_cl_served *sv, size_t n, uint64_t gen)
{
    pthread_mutex_lock(&cl->mu);
    struct sts_cl_served *old = cl->served;
    cl->served = sv;
    cl->nserved = sv ? n : 0;
    cl->serve_gen = gen;
    pthread_mutex_unlock(&cl->mu);
    free(old);
}

static int cmp_served(const void *a, const void *b)
{
    return strcmp(((const struct sts_cl_served *)a)->name, ((const struct sts_cl_served *)b)->name);
}

uint64_t sts_cluster_served_gen(const sts_cluster *cl, const char *name)
{
    struct sts_cl_served key;
    snprintf(key.name, sizeof key.name, "%s", name);
    const struct sts_cl_served *s =
        cl->nserved ? bsearch(&key, cl->served, cl->nserved, sizeof *s, cmp_served) : NULL;
    return s ? s->gen : 0;
}

/* under mu */
static int is_hidden(const sts_cluster *cl, const char *name, uint64_t gen)
{
    for (size_t i = 0; i < cl->nhidden; i++)
        if (cl->hidden[i].gen == gen && !strcmp(cl->hidden[i].name, name))
            return 1;
    return 0;
}

int sts_cluster_serves(sts_cluster *cl, const st_setref *ref)
{
    if (!ref->source_bytes)
        return 1;   /* not from the data dir (the built-in set): not the cluster's */
    pthread_mutex_lock(&cl->mu);
    int ok = (ref->gen >= cl->serve_gen || sts_cluster_served_gen(cl, ref->name) == ref->gen) &&
             !(cl->nhidden && is_hidden(cl, ref->name, ref->gen));
    pthread_mutex_unlock(&cl->mu);
    return ok;
}

uint64_t sts_cluster_hide(sts_cluster *cl, const char *name)
{
    st_setref *ref = NULL;
    if (st_registry_get(cl->srv->reg, name, &ref, NULL) != 0)
        return 0;
    uint64_t gen = ref->source_bytes ? ref->gen : 0;
    st_setref_release(ref);
    if (!gen)
        return 0;
    pthread_mutex_lock(&cl->mu);
    if (cl->nhidden == cl->hidden_cap) {
        size_t cap = cl->hidden_cap ? 2 * cl->hidden_cap : 8;
        struct sts_cl_hidden *h = realloc(cl->hidden, cap * sizeof *h);
        if (!h) {
            pthread_mutex_unlock(&cl->mu);
            return 0;
        }
        cl->hidden = h;
        cl->hidden_cap = cap;
    }
    struct sts_cl_hidden *h = &cl->hidden[cl->nhidden++];
    snprintf(h->name, sizeof h->name, "%s", name);
    h->gen = gen;
    h->seq = ++cl->hide_seq;
    pthread_mutex_unlock(&cl->mu);
    STS_CL_ADD(cl, copies_hidden, 1);
    return gen;
}

void sts_cluster_unhide(sts_cluster *cl, const char *name, uint64_t gen, uint64_t seq_max)
{
    pthread_mutex_lock(&cl->mu);
    for (size_t i = 0; i < cl->nhidden;)
        if (cl->hidden[i].gen == gen && cl->hidden[i].seq <= seq_max &&
            !strcmp(cl->hidden[i].name, name))
            cl->hidden[i] = cl->hidden[--cl->nhidden];
        else
            i++;
    pthread_mutex_unlock(&cl->mu);
}

uint64_t sts_cluster_hide_seq(sts_cluster *cl)
{
    pthread_mutex_lock(&cl->mu);
    uint64_t s = cl->hide_seq;
    pthread_mutex_unlock(&cl->mu);
    return s;
}

void sts_cluster_hidden_prune(sts_cluster *cl, uint64_t seq_max)
{
    /* a copy of the list, so that the registry is not asked under mu */
    pthread_mutex_lock(&cl->mu);
    size_t n = cl->nhidden;
    struct sts_cl_hidden *h = n ? malloc(n * sizeof *h) : NULL;
    if (h)
        memcpy(h, cl->hidden, n * sizeof *h);
    pthread_mutex_unlock(&cl->mu);
    for (size_t i = 0; h && i < n; i++) {
        st_setref *ref = NULL;
        int held = st_registry_get(cl->srv->reg, h[i].name, &ref, NULL) == 0 &&
                   ref->gen == h[i].gen;
        st_setref_release(ref);
        if (!held && h[i].seq <= seq_max)
            sts_cluster_unhide(cl, h[i].name, h[i].gen, seq_max);
    }
    free(h);
}

int sts_get_served(sts_server *srv, const char *name, st_setref **ref, st_error *e)
{
    int rc = st_registry_get(srv->reg, name, ref, e);
    if (rc || !srv->cluster || sts_cluster_serves(srv->cluster, *ref))
        return rc;
    st_setref_release(*ref);
    *ref = NULL;
    STS_CL_ADD(srv->cluster, reads_unconfirmed, 1);
    return st_fail(e, ST_ENOTFOUND, "this node's copy of '%s' is not confirmed current by the "
                   "cluster catalogue", name);
}

static int cmp_entry(const void *a, const void *b)
{
    return strcmp(((const sts_cl_entry *)a)->name, ((const sts_cl_entry *)b)->name);
}

void sts_cluster_note_set(sts_cluster *cl, const char *name, uint32_t crc32,
                          const char (*holders)[STP_MAX_NODE_ID + 1], int nholders)
{
    pthread_mutex_lock(&cl->mu);
    size_t i = 0;
    while (i < cl->ncat && strcmp(cl->cat[i].name, name) < 0)
        i++;
    int found = i < cl->ncat && !strcmp(cl->cat[i].name, name);
    if (!holders) {
        if (found) {
            memmove(cl->cat + i, cl->cat + i + 1, (cl->ncat - i - 1) * sizeof *cl->cat);
            cl->ncat--;
        }
    } else {
        if (!found) {
            sts_cl_entry *g = realloc(cl->cat, (cl->ncat + 1) * sizeof *g);
            if (!g) {
                pthread_mutex_unlock(&cl->mu);
                return;   /* the next repair pass reads it from etcd */
            }
            cl->cat = g;
            memmove(cl->cat + i + 1, cl->cat + i, (cl->ncat - i) * sizeof *cl->cat);
            cl->ncat++;
        }
        sts_cl_entry *e = &cl->cat[i];
        memset(e, 0, sizeof *e);
        snprintf(e->name, sizeof e->name, "%s", name);
        e->crc32 = crc32;
        e->state = SCL_SET_OK;
        for (int h = 0; h < nholders && h < STS_CL_MAX_HOLDERS; h++)
            snprintf(e->holders[e->nholders++], sizeof e->holders[0], "%s", holders[h]);
    }
    pthread_mutex_unlock(&cl->mu);
}

int sts_cluster_moved(sts_cluster *cl, const char *name, char *addr, size_t cap)
{
    int moved = 0;
    pthread_mutex_lock(&cl->mu);
    size_t order[16];
    size_t no = sts_cluster_rank(cl->members, cl->nmembers, name, order, cl->nmembers < 16 ? cl->nmembers : 16);
    sts_cl_entry key;
    snprintf(key.name, sizeof key.name, "%s", name);
    const sts_cl_entry *e = cl->cat ? bsearch(&key, cl->cat, cl->ncat, sizeof *cl->cat, cmp_entry) : NULL;
    int recorded = e && e->state == SCL_SET_OK;
    if (recorded) {
        /* a live node with a current copy, in ranking order (owners first) */
        for (size_t r = 0; r < no && !moved; r++) {
            const sts_cl_member *m = &cl->members[order[r]];
            if (!strcmp(m->id, cl->self))
                continue;
            for (int h = 0; h < e->nholders; h++)
                if (!strcmp(e->holders[h], m->id)) {
                    snprintf(addr, cap, "%s", m->addr);
                    moved = 1;
                    break;
                }
        }
    }
    if (!moved) {
        /* not known here (or no live holder seen yet): an owner answers NOT_FOUND, any other
         * node sends the client to the first owner, so redirects never loop */
        size_t R = cl->replicas < no ? cl->replicas : no;
        int self_owner = 0;
        for (size_t r = 0; r < R; r++)
            self_owner |= !strcmp(cl->members[order[r]].id, cl->self);
        if (!self_owner && R > 0) {
            snprintf(addr, cap, "%s", cl->members[order[0]].addr);
            moved = 1;
        } else if (recorded) {
            /* the catalogue records the set (ok) but no live member holds a current copy and
             * this node serves none: it exists, nobody can serve it now - not NOT_FOUND */
            snprintf(addr, cap, "set '%s' exists but no live node holds a copy", name);
            moved = -1;
        }
    }
    pthread_mutex_unlock(&cl->mu);
    if (moved > 0)
        STS_CL_ADD(cl, moved, 1);
    return moved;
}

void sts_reply_not_here(sts_server *srv, stp_buf *out, const stp_header *h, const char *name,
                        const char *msg)
{
    char addr[STP_MAX_NAME + 64 > STP_MAX_NODE_ADDR + 1 ? STP_MAX_NAME + 64 : STP_MAX_NODE_ADDR + 1];
    int m = srv->cluster ? sts_cluster_moved(srv->cluster, name, addr, sizeof addr) : 0;
    if (m > 0)
        sts_reply_error(out, h, STP_S_MOVED, addr);
    else if (m < 0)
        sts_reply_error(out, h, STP_S_UNAVAILABLE, addr);
    else
        sts_reply_st(out, h, ST_ENOTFOUND, msg);
}

void sts_cluster_recheck(sts_cluster *cl)
{
    __atomic_store_n(&cl->recheck, 1, __ATOMIC_RELAXED);
    if (sts_cluster_etcd_ok(cl) && __atomic_exchange_n(&cl->recheck, 0, __ATOMIC_RELAXED))
        sts_cluster_kick(cl);
}

void sts_cluster_kick(sts_cluster *cl)
{
    pthread_mutex_lock(&cl->wake_mu);
    cl->kick = 1;
    pthread_cond_broadcast(&cl->wake);
    pthread_mutex_unlock(&cl->wake_mu);
}

/* ---- membership thread -------------------------------------------------------------------- */

/* Whether nodes/<id> names another process of this id that is still there: another
 * incarnation at another address that answers PING (a restart on the same address, or a
 * process that does not answer within a second, is this node's earlier self, gone). */
static int id_in_use(sts_cluster *cl, const char *key, char *addr, size_t cap)
{
    scl_kvs kv;
    uint64_t inc = 0;
    int rc = scl_etcd_range(cl->etcd_m, key, 0, &kv);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return 0;
    int other = kv.n == 1 && scl_node_parse(kv.v[0].val, addr, cap, &inc) == 0 &&
                inc != cl->inc && strcmp(addr, cl->addr) != 0;
    scl_kvs_free(&kv);
    return other && scl_peer_ping(addr, 1000) == 0;
}

/* Grants a lease and puts nodes/<id>. At start (first), a node id that another live process
 * has registered is refused: -2 (two processes of one id would each act as that node). */
static int register_node(sts_cluster *cl, int first)
{
    char key[SCL_KEY_MAX], val[512], other[STP_MAX_NODE_ADDR + 1];
    int64_t lease = 0, rev = 0;
    scl_key_node(key, cl->prefix, cl->self);
    if (first && id_in_use(cl, key, other, sizeof other)) {
        sts_logf(&cl->srv->log, STS_ERROR, "cluster: node id '%s' is in use: a live process "
                 "registered it at %s (two nodes started with the same --node-id?)", cl->self,
                 other);
        return -2;
    }
    int rc = scl_etcd_grant(cl->etcd_m, cl->srv->cfg.lease_ttl, &lease);
    if (rc == SCL_OK) {
        scl_node_format(val, sizeof val, cl->addr, cl->inc);
        scl_op op = {SCL_OP_PUT, key, val, lease};
        int ok = 0;
        rc = scl_etcd_txn(cl->etcd_m, NULL, 0, &op, 1, &ok, &rev);
    }
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: cannot register node '%s': %s", cl->self,
                 scl_etcd_errmsg(cl->etcd_m));
        return -1;
    }
    cl->lease = lease;
    __atomic_store_n(&cl->node_rev, rev, __ATOMIC_RELAXED);
    STS_CL_ADD(cl, lease_grants, 1);
    sts_logf(&cl->srv->log, STS_INFO, "cluster: node '%s' registered at %s (lease %llds)",
             cl->self, cl->addr, (long long)cl->srv->cfg.lease_ttl);
    return 0;
}

static int cmp_member(const void *a, const void *b)
{
    return strcmp(((const sts_cl_member *)a)->id, ((const sts_cl_member *)b)->id);
}

/* reads nodes/ into the view; kicks repair when the membership changed */
static void poll_members(sts_cluster *cl)
{
    char key[SCL_KEY_MAX];
    scl_key_node(key, cl->prefix, "");
    scl_kvs kvs;
    int rc = scl_etcd_range(cl->etcd_m, key, 1, &kvs);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return;
    size_t plen = strlen(key);
    sts_cl_member *m = calloc(kvs.n ? kvs.n : 1, sizeof *m);
    size_t n = 0;
    for (size_t i = 0; m && i < kvs.n; i++) {
        const char *id = kvs.v[i].key + plen;
        if (kvs.v[i].key_len <= plen || stp_node_id_check(id, strlen(id)) != 0 ||
            scl_node_parse(kvs.v[i].val, m[n].addr, sizeof m[n].addr, &m[n].inc) != 0)
            continue;
        snprintf(m[n].id, sizeof m[n].id, "%s", id);
        m[n].key_rev = kvs.v[i].create_rev;
        n++;
    }
    scl_kvs_free(&kvs);
    if (!m)
        return;
    qsort(m, n, sizeof *m, cmp_member);
    /* this node's own key: gone while its lease runs (another process of this id deleted it
     * when it left), or another process's */
    const sts_cl_member *me = NULL;
    for (size_t i = 0; i < n && !me; i++)
        if (!strcmp(m[i].id, cl->self))
            me = &m[i];
    if (cl->lease && !me) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: the key of node '%s' is gone while its lease "
                 "runs (another process of this id left?): registering again", cl->self);
        cl->lease = 0;   /* the membership thread registers again at once */
    } else if (me && me->inc && me->inc != cl->inc && me->inc != cl->other_inc) {
        sts_logf(&cl->srv->log, STS_ERROR, "cluster: node id '%s' is registered by another "
                 "process at %s: two nodes run with the same --node-id; this one (%s) is not "
                 "a member while that one runs", cl->self, me->addr, cl->addr);
        cl->other_inc = me->inc;
    }
    pthread_mutex_lock(&cl->mu);
    int changed = n != cl->nmembers || (n && memcmp(m, cl->members, n * sizeof *m) != 0);
    if (changed) {
        free(cl->members);
        cl->members = m;
        cl->nmembers = n;
        cl->epoch++;
        m = NULL;
    }
    pthread_mutex_unlock(&cl->mu);
    free(m);
    if (changed) {
        __atomic_store_n(&cl->changed_ms, sts_now_ms(), __ATOMIC_RELAXED);
        STS_CL_ADD(cl, membership_changes, 1);
        char list[1024];
        size_t at = 0;
        list[0] = 0;
        pthread_mutex_lock(&cl->mu);
        for (size_t i = 0; i < cl->nmembers && at + 80 < sizeof list; i++)
            at += (size_t)snprintf(list + at, sizeof list - at, "%s%s", i ? " " : "", cl->members[i].id);
        pthread_mutex_unlock(&cl->mu);
        sts_logf(&cl->srv->log, STS_INFO, "cluster: membership now %zu node(s): %s", n, list);
        sts_cluster_kick(cl);
    }
}

/* sleeps ms or until stop; returns 1 when stopping */
static int nap(sts_cluster *cl, int ms, int want_kick)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_sec += ms / 1000;
    ts.tv_nsec += (long)(ms % 1000) * 1000000L;
    if (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    pthread_mutex_lock(&cl->wake_mu);
    while (!cl->stop && !(want_kick && cl->kick))
        if (pthread_cond_timedwait(&cl->wake, &cl->wake_mu, &ts) == ETIMEDOUT)
            break;
    int stop = cl->stop;
    if (want_kick)
        cl->kick = 0;
    pthread_mutex_unlock(&cl->wake_mu);
    return stop;
}

int sts_cluster_nap(sts_cluster *cl, int ms) { return nap(cl, ms, 1); }

static void *member_main(void *arg)
{
    sts_cluster *cl = arg;
    int ttl_ms = (int)cl->srv->cfg.lease_ttl * 1000;
    int poll_ms = ttl_ms / 3 < 500 ? ttl_ms / 3 : 500;
    int64_t next_keep = sts_now_ms() + ttl_ms / 3;
    do {
        if (!cl->lease) {
            register_node(cl, 0);
            next_keep = sts_now_ms() + ttl_ms / 3;
        } else if (sts_now_ms() >= next_keep) {
            int64_t ttl = 0;
            int rc = scl_etcd_keepalive(cl->etcd_m, cl->lease, &ttl);
            sts_cluster_note_etcd(cl, rc);
            if (rc == SCL_OK && ttl > 0) {
                STS_CL_ADD(cl, lease_renewals, 1);
                next_keep = sts_now_ms() + ttl_ms / 3;
            } else if (rc == SCL_OK) {
                sts_logf(&cl->srv->log, STS_WARN, "cluster: lease of node '%s' expired; "
                         "registering again", cl->self);
                cl->lease = 0;
                continue;
            }
        }
        poll_members(cl);
        /* a write in doubt is settled as soon as etcd answers, not only at the next write
         * (repair keeps what it may put back meanwhile); never waits for the write path */
        if (__atomic_load_n(&cl->in_doubt, __ATOMIC_RELAXED) && sts_cluster_etcd_ok(cl) &&
            pthread_mutex_trylock(&cl->etcd_mu) == 0) {
            sts_cluster_resolve(cl, cl->etcd_m);
            pthread_mutex_unlock(&cl->etcd_mu);
        }
    } while (!nap(cl, poll_ms, 0));
    return NULL;
}

/* ---- life --------------------------------------------------------------------------------- */

/* A random 64-bit id (never 0): this process's incarnation - the claims it makes carry it, so
 * that the other nodes can tell a claim of a process that is gone when the node restarted
 * meanwhile (docs/cluster.md "Repair") - and a new catalogue's mark (cluster_mark.c). */
uint64_t sts_cluster_random_id(void)
{
    uint64_t v = 0;
    FILE *f = fopen("/dev/urandom", "rbe");
    if (!f || fread(&v, sizeof v, 1, f) != 1) {
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        v = ((uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec) ^
            ((uint64_t)getpid() << 40);
    }
    if (f)
        fclose(f);
    return v ? v : 1;
}

int sts_cluster_config_check(const struct sts_config *c, char *prefix, size_t prefix_cap,
                             char *err, size_t errcap)
{
    char pfx[256], e[256], host[256];
    unsigned port;
    if (!c->cluster[0])
        return 0;
    if (scl_etcd_url_check(c->cluster, prefix ? prefix : pfx, prefix ? prefix_cap : sizeof pfx,
                           e, sizeof e) != 0) {
        snprintf(err, errcap, "cluster: %s", e);
        return -1;
    }
    if (stp_node_id_check(c->node_id, strlen(c->node_id)) != 0) {
        snprintf(err, errcap, "node-id: '%s' is not 1..64 bytes of [A-Za-z0-9._-]", c->node_id);
        return -1;
    }
    /* port 0: the port this server binds (sts_cluster_start; tests listen on port 0) */
    size_t n = strlen(c->advertise);
    if (stp_split_addr(c->advertise, host, sizeof host, &port) != 0 &&
        (n < 3 || strcmp(c->advertise + n - 2, ":0") != 0)) {
        snprintf(err, errcap, "advertise: '%s' is not HOST:PORT", c->advertise);
        return -1;
    }
    return 0;
}

int sts_cluster_init(sts_server *srv)
{
    sts_cluster *cl = calloc(1, sizeof *cl);
    if (!cl)
        return -1;
    cl->srv = srv;
    cl->etcd_ok = 1;   /* until a call says otherwise */
    char err[512];
    if (sts_cluster_config_check(&srv->cfg, cl->prefix, sizeof cl->prefix, err, sizeof err)) {
        sts_logf(&srv->log, STS_ERROR, "%s", err);
        free(cl);
        return -1;
    }
    snprintf(cl->self, sizeof cl->self, "%s", srv->cfg.node_id);
    cl->inc = sts_cluster_random_id();
    /* the data dir is loaded: its copies wait for the catalogue (sts_cluster_serves) */
    cl->serve_gen = st_registry_next_gen(srv->reg);
    cl->replicas = srv->cfg.replicas;
    cl->quorum = srv->cfg.write_quorum ? srv->cfg.write_quorum : srv->cfg.replicas;
    cl->adv_state = -1;   /* the advertised address not checked yet */
    pthread_mutex_init(&cl->mu, NULL);
    pthread_mutex_init(&cl->etcd_mu, NULL);
    pthread_mutex_init(&cl->wake_mu, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_cond_init(&cl->wake, &ca);
    pthread_condattr_destroy(&ca);
    scl_etcd_global_init();
    cl->etcd_w = scl_etcd_open(srv->cfg.cluster, 2000, err, sizeof err);
    cl->etcd_m = scl_etcd_open(srv->cfg.cluster, 2000, err, sizeof err);
    cl->etcd_r = scl_etcd_open(srv->cfg.cluster, 2000, err, sizeof err);
    srv->cluster = cl;
    if (!cl->etcd_w || !cl->etcd_m || !cl->etcd_r) {
        sts_logf(&srv->log, STS_ERROR, "cluster: %s", err);
        return -1;
    }
    /* the membership and repair threads' calls end at stop; the write path's (etcd_w, on
     * workers) are let finish: an acknowledged write has all of them behind it */
    scl_etcd_set_abort(cl->etcd_m, &cl->stop);
    scl_etcd_set_abort(cl->etcd_r, &cl->stop);
    sts_cluster_mark_load(cl);   /* before any etcd call: the revision watch */
    sts_cluster_doubt_load(cl);
    return 0;
}

int sts_cluster_start(sts_server *srv)
{
    sts_cluster *cl = srv->cluster;
    char host[256];
    unsigned port;
    if (stp_split_addr(srv->cfg.advertise, host, sizeof host, &port) != 0) {
        /* port 0: the port this server bound (tests listen on port 0) */
        size_t n = strlen(srv->cfg.advertise);
        if (n < 3 || strcmp(srv->cfg.advertise + n - 2, ":0") != 0) {
            sts_logf(&srv->log, STS_ERROR, "cluster: --advertise '%s' is not HOST:PORT",
                     srv->cfg.advertise);
            return -1;
        }
        snprintf(cl->addr, sizeof cl->addr, "%.*s:%d", (int)(n - 2), srv->cfg.advertise, srv->port);
    } else {
        snprintf(cl->addr, sizeof cl->addr, "%s", srv->cfg.advertise);
    }
    if (sts_cluster_settings_check(cl) != 0)
        return -1;   /* other replicas / write quorum than the cluster's */
    int reg = register_node(cl, 1);
    if (reg == -2)
        return -1;   /* the id is another live process's */
    if (reg == 0)
        poll_members(cl);
    if (pthread_create(&cl->member_thread, NULL, member_main, cl) != 0)
        return -1;
    cl->threads = 1;
    if (pthread_create(&cl->repair_thread, NULL, sts_cluster_repair_main, cl) != 0)
        return -1;
    cl->threads = 2;
    sts_logf(&srv->log, STS_INFO, "cluster: prefix %s, node '%s' at %s, replicas %u, write "
             "quorum %u, lease %us, repair every %us", cl->prefix, cl->self, cl->addr,
             cl->replicas, cl->quorum, srv->cfg.lease_ttl, srv->cfg.repair_interval);
    return 0;
}

/* an advertised address that reaches the node is checked again this often */
#define ADVERTISE_RECHECK_MS 60000

void sts_cluster_advertise_check(sts_cluster *cl)
{
    int64_t now = sts_now_ms();
    if ((cl->adv_state == 1 && now < cl->adv_next_ms) ||
        __atomic_load_n(&cl->stop, __ATOMIC_RELAXED))
        return;   /* (stopping: no new connection that could hold the stop) */
    char id[STP_MAX_NODE_ID + 1] = "", msg[512] = "";
    int rc = scl_peer_self_id(cl->addr, 1000, id, sizeof id, msg, sizeof msg);
    if (rc == 0 && strcmp(id, cl->self) != 0) {
        snprintf(msg, sizeof msg, "node '%s' answers there", id);
        rc = -1;
    }
    int ok = rc == 0;
    __atomic_store_n(&cl->advertise_ok, ok, __ATOMIC_RELAXED);
    if (ok && cl->adv_state == 0)
        sts_logf(&cl->srv->log, STS_INFO, "cluster: the advertised address %s reaches this "
                 "node again", cl->addr);
    else if (!ok && cl->adv_state != 0)
        sts_logf(&cl->srv->log, STS_WARN, "cluster: the advertised address %s does not reach "
                 "this node (%s): other nodes and clients cannot reach it there (check "
                 "--advertise); checked again every repair pass (STATS cluster_advertise_ok 0)",
                 cl->addr, msg);
    cl->adv_state = ok;
    cl->adv_next_ms = now + ADVERTISE_RECHECK_MS;
}

void sts_cluster_stop(sts_server *srv)
{
    sts_cluster *cl = srv->cluster;
    if (!cl)
        return;
    /* also ends the etcd calls the membership and repair threads are inside (an etcd that
     * stopped answering would hold each for its deadline on every endpoint) */
    pthread_mutex_lock(&cl->wake_mu);
    __atomic_store_n(&cl->stop, 1, __ATOMIC_RELAXED);
    pthread_cond_broadcast(&cl->wake);
    pthread_mutex_unlock(&cl->wake_mu);
    if (cl->threads >= 1)
        pthread_join(cl->member_thread, NULL);
    if (cl->threads >= 2)
        pthread_join(cl->repair_thread, NULL);
    cl->threads = 0;
    if (cl->lease && sts_cluster_etcd_ok(cl)) {
        /* a graceful leave: the others need not wait for the lease. Only this process's key:
         * one another process of this id put since is not this node's to delete */
        char key[SCL_KEY_MAX];
        scl_key_node(key, cl->prefix, cl->self);
        scl_etcd_set_abort(cl->etcd_m, NULL);
        scl_cmp cmp = {key, SCL_CMP_MOD, __atomic_load_n(&cl->node_rev, __ATOMIC_RELAXED)};
        scl_op op = {SCL_OP_DEL, key, NULL, 0};
        int ok = 0;
        int rc = scl_etcd_txn(cl->etcd_m, &cmp, 1, &op, 1, &ok, NULL);
        sts_logf(&srv->log, rc ? STS_WARN : STS_INFO, "cluster: node '%s' %s", cl->self,
                 rc ? "could not leave: etcd did not answer; its lease ends it"
                 : ok ? "left" : "left (its key was another process's: kept)");
    } else if (cl->lease) {
        sts_logf(&srv->log, STS_INFO, "cluster: etcd unreachable: node '%s' leaves when its "
                 "lease expires (%u s)", cl->self, srv->cfg.lease_ttl);
    }
}

void sts_cluster_free(sts_server *srv)
{
    sts_cluster *cl = srv->cluster;
    if (!cl)
        return;
    scl_etcd_close(cl->etcd_w);
    scl_etcd_close(cl->etcd_m);
    scl_etcd_close(cl->etcd_r);
    free(cl->members);
    free(cl->cat);
    free(cl->served);
    free(cl->hidden);
    free(cl->orphans);
    free(cl->gone);
    free(cl->backoff);
    sts_cluster_doubt_free(cl);
    pthread_mutex_destroy(&cl->mu);
    pthread_mutex_destroy(&cl->etcd_mu);
    pthread_mutex_destroy(&cl->wake_mu);
    pthread_cond_destroy(&cl->wake);
    free(cl);
    srv->cluster = NULL;
}

/* ---- CLUSTER and STATS --------------------------------------------------------------------- */

int sts_h_cluster(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    const char *why = NULL;
    if (h->body_len && stp_dec_empty(body, h->body_len, &why))
        return sts_reply_bad(out, h, STP_S_BAD_REQUEST, why);
    sts_cluster *cl = c->srv->cluster;
    if (!cl) {
        sts_reply_error(out, h, STP_S_UNSUPPORTED, "this server is not in a cluster");
        return 0;
    }
    sts_cl_member *m = NULL;
    uint64_t epoch = 0;
    size_t n = sts_cluster_members(cl, &m, &epoch);
    stp_cluster_node *nodes = calloc(n ? n : 1, sizeof *nodes);
    if (!nodes) {
        free(m);
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    for (size_t i = 0; i < n; i++) {
        nodes[i].id = m[i].id;
        nodes[i].id_len = (uint16_t)strlen(m[i].id);
        nodes[i].addr = m[i].addr;
        nodes[i].addr_len = (uint16_t)strlen(m[i].addr);
    }
    stp_cluster_reply r;
    memset(&r, 0, sizeof r);
    r.epoch = epoch;
    r.replicas = (uint8_t)cl->replicas;
    r.write_quorum = (uint8_t)cl->quorum;
    r.flags = sts_cluster_etcd_ok(cl) ? STP_CLF_ETCD_OK : 0;
    snprintf(r.self_id, sizeof r.self_id, "%s", cl->self);
    r.count = (uint32_t)n;
    r.nodes = nodes;
    stp_enc_cluster_reply(out, h->reqid, &r);
    free(nodes);
    free(m);
    return 0;
}

size_t sts_cluster_stats(sts_cluster *cl, stp_stat *s, size_t cap)
{
    size_t n = 0;
#define K(k, val) do { if (n < cap) { snprintf(s[n].key, sizeof s[n].key, "cluster_%s", k); \
    s[n].type = STP_STAT_U64; s[n].v.u = (val); n++; } } while (0)
#define C(f) __atomic_load_n(&cl->n.f, __ATOMIC_RELAXED)
    pthread_mutex_lock(&cl->mu);
    uint64_t members = cl->nmembers, epoch = cl->epoch, cat = cl->ncat;
    pthread_mutex_unlock(&cl->mu);
    K("members", members);
    K("epoch", epoch);
    K("catalogue_sets", cat);
    K("etcd_ok", (uint64_t)sts_cluster_etcd_ok(cl));
    K("etcd_errors", C(etcd_errors));
    K("lease_grants", C(lease_grants));
    K("lease_renewals", C(lease_renewals));
    K("membership_changes", C(membership_changes));
    K("repair_passes", C(repair_passes));
    K("copies_pushed", C(copies_pushed));
    K("copies_received", C(copies_received));
    K("copies_dropped", C(copies_dropped));
    K("push_failures", C(push_failures));
    K("push_bytes", C(push_bytes));
    K("moved", C(moved));
    K("refused_unavailable", C(refused_unavailable));
    K("under_replicated", C(under_replicated));
    K("claims", C(claims));
    K("claims_lost", C(claims_lost));
    K("in_doubt", (uint64_t)__atomic_load_n(&cl->in_doubt, __ATOMIC_RELAXED));
    K("writes_in_doubt", C(writes_in_doubt));
    K("doubts_undone", C(doubts_undone));
    K("reads_unconfirmed", C(reads_unconfirmed));
    K("copies_staged", C(copies_staged));
    K("staged_published", C(staged_published));
    K("staged_dropped", C(staged_dropped));
    K("copies_hidden", C(copies_hidden));
    K("sets_rerecorded", C(sets_rerecorded));
    K("pushes_backed_off", C(pushes_backed_off));
    K("etcd_went_back", C(etcd_went_back));
    K("advertise_ok", (uint64_t)__atomic_load_n(&cl->advertise_ok, __ATOMIC_RELAXED));
#undef K
#undef C
    return n;
}
