/* server/cluster_repair.c - the repair thread (docs/cluster.md "Repair and rebalance").
 *
 * Owns: one pass over the catalogue, run at start, on every membership change and every
 * --repair-interval seconds: the copies/ keys of this node's copies kept true, stale and
 * forgotten copies dropped (a set the catalogue lacks, after two lease TTLs), copies pushed
 * to owners that lack one (by the first live holder in the ranking only, so one node pushes
 * each set; a push that failed backs off, per set and target process), extra copies dropped once every owner has confirmed its own, abandoned claims
 * removed (a REPLACE's: the record it replaced put back, from prev/), the staged copies of
 * this node's writes published or dropped by the catalogue, the local copies reads
 * may use confirmed (sts_cluster_set_served; a copy a DELETE hid is shown again once the
 * catalogue records its contents); then the catalogue snapshot the handlers use
 * (MOVED) is replaced. A catalogue without the mark this node's data dir keeps (etcd lost its
 * data: cluster_mark.c), or read from an etcd that went back to a revision below one this node
 * has seen (restored from an older snapshot), is not judged: the node's sets are recorded
 * again first. Before a pass drops anything it keeps its revision in the data dir. Does not
 * own: the membership (cluster_node.c), the write path.
 * Nothing happens while etcd is unreachable.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cluster_node.h"
#include "h_upload.h"
#include "server.h"
#include "stp_name.h"

static int64_t wall_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

typedef struct rec_row {
    scl_setrec rec;
    int64_t    mod_rev;
    int        valid;
} rec_row;

static sts_cl_entry *find_entry(sts_cl_entry *cat, size_t n, const char *name)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        int c = strcmp(cat[mid].name, name);
        if (!c)
            return &cat[mid];
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return NULL;
}

static int holds(const sts_cl_entry *e, const char *id)
{
    for (int h = 0; h < e->nholders; h++)
        if (!strcmp(e->holders[h], id))
            return 1;
    return 0;
}

static void add_holder(sts_cl_entry *e, const char *id)
{
    if (!holds(e, id) && e->nholders < STS_CL_MAX_HOLDERS)
        snprintf(e->holders[e->nholders++], sizeof e->holders[0], "%s", id);
}

static void remove_holder(sts_cl_entry *e, const char *id)
{
    for (int h = 0; h < e->nholders; h++)
        if (!strcmp(e->holders[h], id)) {
            memmove(e->holders[h], e->holders[h + 1], (size_t)(e->nholders - h - 1) * sizeof e->holders[0]);
            e->nholders--;
            return;
        }
}

static int is_member(const sts_cl_member *m, size_t n, const char *id)
{
    for (size_t i = 0; i < n; i++)
        if (!strcmp(m[i].id, id))
            return 1;
    return 0;
}

/* 1 when the process that made a claim (origin id, incarnation inc) is still the live member
 * of that id; a claim or member without an incarnation (0) is judged by the id alone */
static int origin_live(const sts_cl_member *m, size_t n, const char *id, uint64_t inc)
{
    for (size_t i = 0; i < n; i++)
        if (!strcmp(m[i].id, id))
            return !inc || !m[i].inc || m[i].inc == inc;
    return 0;
}

/* Puts copies/<name>/<id> only while the record is the one this pass read (its
 * mod_revision rec_rev): a delete or replace since then (the pass reads sets/ and copies/ one
 * after the other) must not get a copies/ key of the old contents back. */
static void put_copy_key(sts_cluster *cl, const char *name, const char *id, uint32_t crc,
                         int64_t rec_rev)
{
    char key[SCL_KEY_MAX], skey[SCL_KEY_MAX], val[9];
    scl_key_copies(key, cl->prefix, name, id);
    scl_key_set(skey, cl->prefix, name);
    scl_copy_format(val, crc);
    scl_cmp cmp = {skey, SCL_CMP_MOD, rec_rev};
    scl_op op = {SCL_OP_PUT, key, val, 0};
    int ok = 0;
    sts_cluster_note_etcd(cl, scl_etcd_txn(cl->etcd_r, &cmp, 1, &op, 1, &ok, NULL));
}

static void drop_copy_key(sts_cluster *cl, const char *name)
{
    char key[SCL_KEY_MAX];
    scl_key_copies(key, cl->prefix, name, cl->self);
    sts_cluster_note_etcd(cl, scl_etcd_delete(cl->etcd_r, key, 0));
}

static void drop_local(sts_cluster *cl, const char *name, const char *why)
{
    sts_cluster_rev_keep(cl, 0);   /* a drop: the revision judged is kept first */
    int rc = sts_delete_local(cl->srv, name);
    if (rc == 0 || rc == ST_ENOTFOUND) {
        STS_CL_ADD(cl, copies_dropped, 1);
        sts_logf(&cl->srv->log, STS_INFO, "cluster: copy of '%s' dropped (%s)", name, why);
    } else {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: copy of '%s' could not be dropped", name);
    }
}

/* 1 when (name, mod_rev) has been in the list was[] (seen by earlier passes) for longer than
 * twice the lease TTL; records it in next[] with the time it was first seen. The lists: the
 * pending claims seen without their origin node (a node re-registering after an etcd outage
 * is not gone), and the local sets seen missing from the catalogue (mod_rev 0: a delete that
 * etcd applied after the request was answered UNAVAILABLE is put back by its node meanwhile,
 * cluster_fence.c). */
static int seen_long_enough(sts_cluster *cl, const struct sts_cl_orphan *was, size_t nwas,
                            const char *name, int64_t mod_rev, struct sts_cl_orphan *next,
                            size_t *nnext)
{
    int64_t now = sts_now_ms(), since = now;
    for (size_t i = 0; i < nwas; i++)
        if (!strcmp(was[i].name, name) && was[i].mod_rev == mod_rev)
            since = was[i].since_ms;
    if (next) {
        snprintf(next[*nnext].name, sizeof next[0].name, "%s", name);
        next[*nnext].mod_rev = mod_rev;
        next[*nnext].since_ms = since;
        (*nnext)++;
    }
    return now - since > 2000 * (int64_t)cl->srv->cfg.lease_ttl;
}

/* Whether reads may use local copy r (published before this pass began) by catalogue entry e
 * (NULL: the catalogue does not record the name): the copy of the contents recorded (ok, or
 * pending: the contents being written) yes; other contents recorded ok (replaced while this
 * node was away) no; other contents pending (a replace in flight) or no record (deleted, or a
 * delete in doubt about to be put back) only when the last pass served this very copy - a
 * node that was down over a delete or replace never serves the old copy after it returns.
 * For a replace in flight, a copy published since the last pass began (gen >= prev_gen, the
 * serve_gen that pass set) was served too: a recorded write's or a repair push's, so the
 * contents the pending claim has not replaced (without this, a copy written a moment before
 * a REPLACE that then fails went unserved until the pass after the claim was taken back). */
static int confirm(const sts_cluster *cl, const st_setref *r, const sts_cl_entry *e,
                   uint64_t prev_gen)
{
    if (e && e->crc32 == r->source_crc)
        return 1;
    if (e && e->state == SCL_SET_OK)
        return 0;
    if (e && r->gen >= prev_gen)
        return 1;
    return sts_cluster_served_gen(cl, r->name) == r->gen;   /* the last pass's list */
}

static void staged_broken(void *arg, const char *id, const char *why)
{
    sts_cluster *cl = arg;
    sts_logf(&cl->srv->log, STS_WARN, "cluster: staged copy %s unreadable (%s): moved to broken/",
             id, why);
}

/* The staged copies of writes (this node's uploads and COMPRESS results, and pushes of other
 * nodes' writes; datadir.h "Staged copies") against the
 * catalogue just read: the contents recorded "ok" are published here (the write was recorded
 * but its node did not get to publish them: killed, or a publish that failed); recorded
 * "pending" they wait (the write is in flight, or its claim is abandoned later); other
 * contents or no record: the write was refused, taken back or abandoned, and the staged copy
 * goes - once it is older than the catalogue read by a margin (a copy staged after the read
 * may belong to a claim the read did not see), and never while this node has a write on the
 * set in doubt (its outcome decides). Runs before the pass looks at the registry, so a copy
 * published here is judged as published since the pass began. */
static void resolve_staged(sts_cluster *cl, const sts_cl_entry *cat, size_t nc, int64_t t0)
{
    sts_server *srv = cl->srv;
    st_datadir_staged *s = NULL;
    size_t n = 0;
    st_error e;
    st_error_clear(&e);
    if (st_datadir_staged_list(srv->dd, &s, &n, staged_broken, cl, &e) != 0) {
        sts_logf(&srv->log, STS_WARN, "cluster: staged copies not listed: %s", e.msg);
        return;
    }
    for (size_t i = 0; i < n; i++) {
        const char *name = s[i].m.name;
        if (sts_cluster_doubts(cl, name))
            continue;
        const sts_cl_entry *en = find_entry((sts_cl_entry *)cat, nc, name);
        if (en && en->crc32 == s[i].m.crc) {
            if (en->state != SCL_SET_OK)
                continue;   /* the write is in flight */
            st_setref *ref = NULL;   /* published already (a crash after its commit, or a
                                        plain push of the same contents): not again */
            int have = st_registry_get(srv->reg, name, &ref, NULL) == 0 &&
                       ref->source_crc == s[i].m.crc;
            st_setref_release(ref);
            if (have) {
                sts_drop_staged(srv, s[i].id, "this node holds these contents already");
                continue;
            }
            st_error_clear(&e);
            st_manifest still;
            int rc = sts_publish_staged(srv, s[i].id, NULL, NULL, &e);
            if (rc == 0)
                sts_logf(&srv->log, STS_INFO, "cluster: staged copy %s of '%s' published: the "
                         "cluster records these contents", s[i].id, name);
            else if (rc != ST_ENOTFOUND &&
                     st_datadir_staged_read(srv->dd, s[i].id, &still, NULL, 0, NULL) == 0)
                sts_logf(&srv->log, STS_WARN, "cluster: staged copy %s of '%s' could not be "
                         "published: %s", s[i].id, name, e.msg);   /* (not: gone meanwhile) */
        } else if (s[i].mtime_ms < t0 - 2000) {
            sts_cluster_rev_keep(cl, 0);   /* a drop: the revision judged is kept first */
            sts_drop_staged(srv, s[i].id, en ? "the cluster records other contents"
                                             : "the cluster does not record the set");
        }
    }
    free(s);
}

/* A catalogue that is not the one the data dir knows (sts_cluster_mark_check: etcd lost its
 * data, or went back in time): nothing is judged against it; every local set it does not record is recorded again
 * (the name still free), and once all are, the data dir keeps the catalogue's mark and the
 * next pass, run at once, is an ordinary one. Reads meanwhile use what the last pass
 * confirmed. */
static void record_again(sts_cluster *cl, const sts_cl_entry *cat, size_t nc)
{
    sts_server *srv = cl->srv;
    size_t cap = st_registry_count(srv->reg) + 16;
    st_setref **refs = calloc(cap, sizeof *refs);
    size_t nr = refs ? st_registry_snapshot(srv->reg, refs, cap) : 0;
    int all = refs != NULL;
    for (size_t i = 0; i < nr; i++) {
        st_setref *r = refs[i];
        if (r->source_bytes && !find_entry((sts_cl_entry *)cat, nc, r->name) &&
            sts_cluster_rerecord(cl, r->name, r->set->info.kind) != 0)
            all = 0;
        st_setref_release(r);
    }
    free(refs);
    if (all && sts_cluster_mark_adopt(cl) == 0)   /* the mark, and the pass's revision */
        sts_cluster_kick(cl);
}

/* ---- the backoff of repair pushes that fail (docs/cluster.md "Repair and rebalance") ----
 * Per (set contents, target process): a node that cannot take one copy (a set over its
 * limits) may take the others, and each (set, node) is judged by its own pushes. The first
 * failure waits one --repair-interval, each further one twice the last, up to
 * BACKOFF_CAP_MS (or the interval, if longer). Other contents (a replace), another process
 * of the node (a restart) or a new registration of it (a new lease: another create_revision
 * of its key) are another key: they start afresh. An entry that no pass wants any more (the
 * push succeeded, the node or the set is gone, another node pushes now) is dropped at the
 * end of the pass. */
#define BACKOFF_CAP_MS 60000

static struct sts_cl_backoff *backoff_find(sts_cluster *cl, const sts_cl_entry *e,
                                           const sts_cl_member *o)
{
    for (size_t i = 0; i < cl->nbackoff; i++) {
        struct sts_cl_backoff *b = &cl->backoff[i];
        if (b->crc == e->crc32 && b->inc == o->inc && b->key_rev == o->key_rev &&
            !strcmp(b->name, e->name) && !strcmp(b->node, o->id))
            return b;
    }
    return NULL;
}

/* the wait after `fails` consecutive failures, in ms */
static int64_t backoff_delay(const sts_cluster *cl, unsigned fails)
{
    int64_t base = 1000 * (int64_t)cl->srv->cfg.repair_interval, cap = BACKOFF_CAP_MS;
    if (base < 1)
        base = 1;
    if (cap < base)
        cap = base;
    int64_t d = base;
    for (unsigned k = 1; k < fails && d < cap; k++)
        d *= 2;
    return d < cap ? d : cap;
}

/* a failed push of e to o, with the push's message: a new entry (logged) or one more
 * failure of an entry b (logged at debug level only) */
static void backoff_failed(sts_cluster *cl, struct sts_cl_backoff *b, const sts_cl_entry *e,
                           const sts_cl_member *o, const char *msg)
{
    sts_server *srv = cl->srv;
    if (!b) {
        if (cl->nbackoff == cl->backoff_cap) {
            size_t cap = cl->backoff_cap ? 2 * cl->backoff_cap : 16;
            struct sts_cl_backoff *nb = realloc(cl->backoff, cap * sizeof *nb);
            if (!nb) {   /* no memory: not backed off, logged as before */
                sts_logf(&srv->log, STS_WARN, "cluster: %s", msg);
                return;
            }
            cl->backoff = nb;
            cl->backoff_cap = cap;
        }
        b = &cl->backoff[cl->nbackoff++];
        memset(b, 0, sizeof *b);
        snprintf(b->name, sizeof b->name, "%s", e->name);
        snprintf(b->node, sizeof b->node, "%s", o->id);
        b->crc = e->crc32;
        b->inc = o->inc;
        b->key_rev = o->key_rev;
    }
    b->fails++;
    b->seen = 1;
    int64_t d = backoff_delay(cl, b->fails);
    b->next_ms = sts_now_ms() + d;
    if (b->fails == 1)
        sts_logf(&srv->log, STS_WARN, "cluster: %s; the push of '%s' to node '%s' backs off: "
                 "tried again in %lld s at the earliest, the wait doubling with each failure "
                 "up to %lld s (not logged again until it succeeds)", msg, e->name, o->id,
                 (long long)(d / 1000), (long long)(backoff_delay(cl, 64) / 1000));
    else
        sts_logf(&srv->log, STS_DEBUG, "cluster: %s (failure %u in a row; next try in %lld s)",
                 msg, b->fails, (long long)(d / 1000));
}

/* drops the entries the pass did not want and clears the mark of the others */
static void backoff_prune(sts_cluster *cl)
{
    size_t k = 0;
    for (size_t i = 0; i < cl->nbackoff; i++)
        if (cl->backoff[i].seen) {
            cl->backoff[k] = cl->backoff[i];
            cl->backoff[k++].seen = 0;
        }
    cl->nbackoff = k;
}

static void pass(sts_cluster *cl)
{
    sts_server *srv = cl->srv;
    pthread_mutex_lock(&cl->mu);
    uint64_t prev_gen = cl->serve_gen;   /* copies published since the last pass began */
    uint64_t hseq = cl->hide_seq;        /* copies hidden before the catalogue is read */
    pthread_mutex_unlock(&cl->mu);
    uint64_t g0 = st_registry_next_gen(srv->reg);   /* copies published from now on: not judged */
    int64_t t0 = wall_ms();
    char skey[SCL_KEY_MAX], ckey[SCL_KEY_MAX];
    scl_key_set(skey, cl->prefix, "");
    scl_key_all_copies(ckey, cl->prefix);
    scl_kvs sets, copies;
    int rc = scl_etcd_range(cl->etcd_r, skey, 1, &sets);
    if (rc == SCL_OK) {
        /* the copies/ keys as they were when sets/ was read: read later, a write between the
         * two (a late DELETE: the record read, its copies/ keys gone) made every holder look
         * like it lacked its copy, and the set was pushed again to nodes that held it - a
         * copy whose record then came back (put back) went unserved until their next pass */
        rc = scl_etcd_range_at(cl->etcd_r, ckey, 1, sets.revision, &copies);
        if (rc != SCL_OK)
            scl_kvs_free(&sets);
    }
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return;
    /* the catalogue read is the one this node's data dir knows, or etcd has lost its data */
    int lost = sts_cluster_mark_check(cl, sets.revision);
    if (lost < 0) {
        scl_kvs_free(&sets);
        scl_kvs_free(&copies);
        return;
    }
    STS_CL_ADD(cl, repair_passes, 1);
    sts_cl_member *m = NULL;
    size_t nm = sts_cluster_members(cl, &m, NULL);
    size_t splen = strlen(skey), cplen = strlen(ckey);

    /* the catalogue: sets/ comes sorted by key, i.e. by name */
    sts_cl_entry *cat = calloc(sets.n ? sets.n : 1, sizeof *cat);
    rec_row *rows = calloc(sets.n ? sets.n : 1, sizeof *rows);
    size_t nc = 0;
    for (size_t i = 0; cat && rows && i < sets.n; i++) {
        const char *name = sets.v[i].key + splen;
        /* a name etcd hands back is outside input too: only a valid set name is a set */
        if (sets.v[i].key_len <= splen || !stp_name_valid(name, sets.v[i].key_len - splen) ||
            scl_setrec_parse(sets.v[i].val, &rows[nc].rec) != 0)
            continue;
        snprintf(cat[nc].name, sizeof cat[nc].name, "%s", name);
        cat[nc].crc32 = rows[nc].rec.crc32;
        cat[nc].state = rows[nc].rec.state;
        rows[nc].mod_rev = sets.v[i].mod_rev;
        rows[nc].valid = 1;
        nc++;
    }
    /* copies/<name>/<id>: live holders with the current CRC; own keys remembered */
    for (size_t i = 0; cat && i < copies.n; i++) {
        char *k = copies.v[i].key + cplen, *slash = strrchr(k, '/');
        uint32_t crc;
        if (copies.v[i].key_len <= cplen || !slash || scl_copy_parse(copies.v[i].val, &crc) != 0)
            continue;
        *slash = 0;
        sts_cl_entry *e = find_entry(cat, nc, k);
        if (e && e->crc32 == crc && is_member(m, nm, slash + 1))
            add_holder(e, slash + 1);
    }
    scl_kvs_free(&sets);
    scl_kvs_free(&copies);
    if (!cat || !rows || lost) {
        if (cat && rows)
            record_again(cl, cat, nc);
        free(cat);
        free(rows);
        free(m);
        return;
    }

    /* a node that has just started has no snapshot yet: it gets this one now, before the
     * pushes of its first pass, so that it answers MOVED for the sets it lacks (not NOT_FOUND) */
    int first = __atomic_load_n(&cl->n.repair_passes, __ATOMIC_RELAXED) == 1;   /* this one */
    sts_cl_entry *early = first ? malloc((nc ? nc : 1) * sizeof *early) : NULL;
    if (early) {
        memcpy(early, cat, nc * sizeof *early);
        sts_cluster_set_catalogue(cl, early, nc);
    }

    resolve_staged(cl, cat, nc, t0);

    /* this node's copies */
    size_t cap = st_registry_count(srv->reg) + 16;
    st_setref **refs = calloc(cap, sizeof *refs);
    size_t nr = refs ? st_registry_snapshot(srv->reg, refs, cap) : 0;
    char *mine = calloc(nc ? nc : 1, 1);   /* 1: a current local copy */
    struct sts_cl_orphan *gone = calloc(nr ? nr : 1, sizeof *gone);
    struct sts_cl_served *served = calloc(nr ? nr : 1, sizeof *served);
    size_t ngone = 0, nserved = 0;
    for (size_t i = 0; mine && i < nr; i++) {
        st_setref *r = refs[i];
        if (!r->source_bytes)
            continue;   /* not from the data dir (the built-in set): not the cluster's */
        sts_cl_entry *e = find_entry(cat, nc, r->name);
        if (served && r->gen < g0 && confirm(cl, r, e, prev_gen)) {   /* refs[] is sorted by name */
            snprintf(served[nserved].name, sizeof served[0].name, "%s", r->name);
            served[nserved++].gen = r->gen;
        }
        if (e && e->state == SCL_SET_OK && r->source_crc == e->crc32)
            sts_cluster_unhide(cl, r->name, r->gen, hseq);   /* recorded: the delete was not */
        int settled = r->created_ms < t0 - 2000;   /* published before the catalogue was read */
        if (!e) {
            /* deleted, unless this node's delete of it is in doubt or was applied late by
             * another node's etcd and is about to be put back: kept for two lease TTLs */
            if (settled && !sts_cluster_doubts(cl, r->name) &&
                seen_long_enough(cl, cl->gone, cl->ngone, r->name, 0, gone, &ngone))
                drop_local(cl, r->name, "the cluster does not record it: deleted");
        } else if (e->state != SCL_SET_OK) {
            continue;
        } else if (r->source_crc != e->crc32) {
            if (settled) {
                drop_local(cl, r->name, "stale: the cluster records other contents");
                drop_copy_key(cl, r->name);
                remove_holder(e, cl->self);
            }
        } else {
            mine[e - cat] = 1;
            /* a copy recorded after the revision the data dir keeps: kept now, so that an
             * etcd restored to before its record is caught after a restart too */
            sts_cluster_rev_keep(cl, rows[e - cat].mod_rev);
            if (!holds(e, cl->self)) {
                put_copy_key(cl, r->name, cl->self, e->crc32, rows[e - cat].mod_rev);
                add_holder(e, cl->self);
            }
        }
    }
    for (size_t i = 0; i < nr; i++)
        st_setref_release(refs[i]);
    free(refs);
    sts_cluster_hidden_prune(cl, hseq);
    /* reads use what this pass confirmed from now on (with no list, for want of memory, the
     * copies published since the last pass began still are) */
    if (served && mine)
        sts_cluster_set_served(cl, served, nserved, g0);
    else
        free(served);
    free(cl->gone);
    cl->gone = gone;
    cl->ngone = gone ? ngone : 0;
    /* a copies/ key of this node without a current local copy (lost, or dropped while a
     * record was away) is not a copy: removed, so that repair makes one where it is owed */
    for (size_t i = 0; mine && i < nc; i++)
        if (cat[i].state == SCL_SET_OK && !mine[i] && holds(&cat[i], cl->self)) {
            drop_copy_key(cl, cat[i].name);
            remove_holder(&cat[i], cl->self);
        }

    /* placement; copies are dropped only once the membership has been stable for a lease TTL
     * (after an etcd outage every node re-registers, and a partial view must not move sets) */
    int64_t stable_ms = sts_now_ms() - __atomic_load_n(&cl->changed_ms, __ATOMIC_RELAXED);
    int may_drop = stable_ms >= 1000 * (int64_t)srv->cfg.lease_ttl;
    struct sts_cl_orphan *next = calloc(nc ? nc : 1, sizeof *next);
    size_t nnext = 0;
    size_t *order = calloc(nm ? nm : 1, sizeof *order);
    uint64_t under = 0;
    for (size_t i = 0; order && mine && i < nc; i++) {
        if (__atomic_load_n(&cl->stop, __ATOMIC_RELAXED))
            break;   /* stopping: no further push (a peer that hangs would hold the stop) */
        sts_cl_entry *e = &cat[i];
        if (e->state != SCL_SET_OK) {
            if (!origin_live(m, nm, rows[i].rec.origin, rows[i].rec.inc) &&
                seen_long_enough(cl, cl->orphans, cl->norphans, e->name, rows[i].mod_rev, next,
                                 &nnext)) {
                /* a claim whose node is gone, or was restarted since (its write path died
                 * with the process that claimed): abandoned. A REPLACE's claim gives the
                 * name back to the contents it replaced (their record, kept under prev/ by
                 * the claim's own transaction: the same mod_revision), else the name is
                 * freed. */
                char key[SCL_KEY_MAX], pkey[SCL_KEY_MAX];
                scl_key_set(key, cl->prefix, e->name);
                scl_key_prev(pkey, cl->prefix, e->name);
                scl_kvs pv = {0};
                scl_setrec prev;
                int restore = scl_etcd_range(cl->etcd_r, pkey, 0, &pv) == SCL_OK && pv.n == 1 &&
                              pv.v[0].mod_rev == rows[i].mod_rev &&
                              scl_setrec_parse(pv.v[0].val, &prev) == 0 &&
                              prev.state == SCL_SET_OK;
                scl_cmp cmp = {key, SCL_CMP_MOD, rows[i].mod_rev};
                scl_op ops[2] = {{SCL_OP_DEL, key, NULL, 0}, {SCL_OP_DEL, pkey, NULL, 0}};
                if (restore)
                    ops[0] = (scl_op){SCL_OP_PUT, key, pv.v[0].val, 0};
                int ok = 0;
                sts_cluster_note_etcd(cl, scl_etcd_txn(cl->etcd_r, &cmp, 1, ops, 2, &ok, NULL));
                if (ok)
                    sts_logf(&srv->log, STS_INFO, "cluster: abandoned claim of '%s' by '%s' %s",
                             e->name, rows[i].rec.origin, restore
                             ? "undone: the contents it replaced are recorded again"
                             : "removed");
                scl_kvs_free(&pv);
            }
            continue;
        }
        size_t nrank = sts_cluster_rank(m, nm, e->name, order, nm);
        size_t R = cl->replicas < nrank ? cl->replicas : nrank;
        if (mine[i]) {
            const char *pusher = NULL;
            for (size_t r = 0; r < nrank && !pusher; r++)
                if (holds(e, m[order[r]].id))
                    pusher = m[order[r]].id;
            if (pusher && !strcmp(pusher, cl->self)) {
                for (size_t r = 0; r < R; r++) {
                    const sts_cl_member *o = &m[order[r]];
                    if (holds(e, o->id))
                        continue;
                    struct sts_cl_backoff *b = backoff_find(cl, e, o);
                    if (b && sts_now_ms() < b->next_ms) {
                        b->seen = 1;   /* failed lately: not yet */
                        STS_CL_ADD(cl, pushes_backed_off, 1);
                        continue;
                    }
                    char msg[512];
                    if (sts_cluster_push(cl, e->name, o->addr, msg, sizeof msg) == 0) {
                        put_copy_key(cl, e->name, o->id, e->crc32, rows[i].mod_rev);
                        add_holder(e, o->id);
                        if (b)   /* not marked seen: dropped at the end of the pass */
                            sts_logf(&srv->log, STS_INFO, "cluster: the push of '%s' to node "
                                     "'%s' succeeded after %u failed tries: backoff ended",
                                     e->name, o->id, b->fails);
                    } else {
                        backoff_failed(cl, b, e, o, msg);
                    }
                }
            }
            int owner = 0, confirmed = 1;
            for (size_t r = 0; r < R; r++) {
                owner |= !strcmp(m[order[r]].id, cl->self);
                confirmed &= holds(e, m[order[r]].id);
            }
            if (!owner && confirmed && R > 0 && may_drop) {
                /* every owner is live and has confirmed a current copy: this one is extra */
                drop_copy_key(cl, e->name);
                drop_local(cl, e->name, "extra: every owner holds a current copy");
                remove_holder(e, cl->self);
            }
        }
        if ((size_t)e->nholders < R)
            under++;
    }
    __atomic_store_n(&cl->n.under_replicated, under, __ATOMIC_RELAXED);
    if (order && mine)
        backoff_prune(cl);   /* the pushes this pass did not want: succeeded, or not owed */
    free(cl->orphans);
    cl->orphans = next;
    cl->norphans = next ? nnext : 0;
    free(order);
    free(mine);
    free(rows);
    free(m);
    sts_cluster_set_catalogue(cl, cat, nc);
}

void *sts_cluster_repair_main(void *arg)
{
    sts_cluster *cl = arg;
    int ms = (int)cl->srv->cfg.repair_interval * 1000;
    do {   /* a pass at once: the copies from the data dir are served once one confirms them */
        if (sts_cluster_etcd_ok(cl))
            pass(cl);
        sts_cluster_advertise_check(cl);   /* after the pass: never delays it */
    } while (!sts_cluster_nap(cl, ms));
    return NULL;
}
