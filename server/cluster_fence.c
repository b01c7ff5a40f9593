/* server/cluster_fence.c - the write path's transactions and writes in doubt (docs/cluster.md
 * "Writes in doubt").
 *
 * An etcd request that got no answer may still be applied: etcd may have it in a socket
 * buffer (a paused or overloaded etcd) or have applied it before the reply was lost. The
 * request was answered UNAVAILABLE ("refused"), so such a write must not take effect later.
 * Every transaction of the write path therefore also compares this node's op key
 * (PREFIX/ops/<id>) with the mod_revision the node last saw and puts a new value (the op's
 * tag: incarnation, sequence number, what, which set). After an etcd error the write is in
 * doubt; before anything else is written, the node puts a fence on the op key (compare the
 * same revision, put): when the fence applies, the write never can (its compare now fails);
 * when it does not, the key's value says whether the write applied, and the node undoes it
 * (a claim taken back, a deleted record and its copies/ keys put back) or, for a take-back
 * that did not apply, sends it again. Undoing is a write like any other, so it may itself end
 * in doubt and be settled the same way.
 *
 * Owns: the op key's state in sts_cluster (op_rev, op_seq, doubt, in_doubt, doubt_set), under
 * cl->etcd_mu (doubt_set under cl->mu). Does not own: what the writes are
 * (cluster_write.c), when a resolution is tried (the next write; the membership thread while
 * etcd answers, cluster_node.c).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cluster_node.h"
#include "server.h"

static const char *const kind_name[] = {"claim", "finalize", "unclaim", "delete", "restore"};

static void kvs_drop(scl_kvs *k)
{
    scl_kvs_free(k);
    memset(k, 0, sizeof *k);
}

/* a deep copy of src's keys and values into dst (empty on failure: -1) */
static int kvs_copy(scl_kvs *dst, const scl_kvs *src)
{
    memset(dst, 0, sizeof *dst);
    if (!src->n)
        return 0;
    dst->v = calloc(src->n, sizeof *dst->v);
    if (!dst->v)
        return -1;
    for (size_t i = 0; i < src->n; i++) {
        dst->v[i] = src->v[i];
        dst->v[i].key = strdup(src->v[i].key);
        dst->v[i].val = strdup(src->v[i].val);
        dst->n = i + 1;
        if (!dst->v[i].key || !dst->v[i].val) {
            kvs_drop(dst);
            return -1;
        }
    }
    dst->revision = src->revision;
    return 0;
}

void sts_cluster_doubt_free_one(sts_cl_doubt *d)
{
    if (!d)
        return;
    free(d->rec);
    scl_kvs_free(&d->copies);
    free(d);
}

/* a claim, finalize or delete that etcd applied after its refusal is undone */
static int undone_when_applied(int kind)
{
    return kind == STS_DOUBT_CLAIM || kind == STS_DOUBT_FINALIZE || kind == STS_DOUBT_DELETE;
}

void sts_cluster_doubt_set(sts_cluster *cl, sts_cl_doubt *d, int keep)
{
    /* on disk first: the write is answered UNAVAILABLE after this returns */
    if (keep)
        sts_cluster_doubt_save(cl, d);
    sts_cluster_doubt_free_one(cl->doubt);
    cl->doubt = d;
    __atomic_store_n(&cl->in_doubt, d != NULL, __ATOMIC_RELAXED);
    pthread_mutex_lock(&cl->mu);
    snprintf(cl->doubt_set, sizeof cl->doubt_set, "%s", d ? d->name : "");
    pthread_mutex_unlock(&cl->mu);
}

int sts_cluster_doubts(sts_cluster *cl, const char *name)
{
    if (!__atomic_load_n(&cl->in_doubt, __ATOMIC_RELAXED))
        return 0;
    pthread_mutex_lock(&cl->mu);
    int r = !strcmp(cl->doubt_set, name);
    pthread_mutex_unlock(&cl->mu);
    return r;
}

void sts_cluster_doubt_free(sts_cluster *cl)
{
    sts_cluster_doubt_free_one(cl->doubt);
    cl->doubt = NULL;
}

/* reads the op key: its mod_revision (0 when absent) and, when val is given, its value */
static int read_op(sts_cluster *cl, scl_etcd *h, int64_t *mod, char *val, size_t cap)
{
    char key[SCL_KEY_MAX];
    scl_key_op(key, cl->prefix, cl->self);
    scl_kvs kvs;
    int rc = scl_etcd_range(h, key, 0, &kvs);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return rc;
    *mod = kvs.n == 1 ? kvs.v[0].mod_rev : 0;
    if (val)
        snprintf(val, cap, "%s", kvs.n == 1 ? kvs.v[0].val : "");
    scl_kvs_free(&kvs);
    return SCL_OK;
}

int sts_cluster_wtxn(sts_cluster *cl, scl_etcd *h, const scl_cmp *cmp, size_t ncmp,
                     const scl_op *ops, size_t nops, int *ok, int64_t *rev,
                     const sts_cl_doubt *d)
{
    *ok = 0;
    if (cl->doubt) {
        int rc = sts_cluster_resolve(cl, h);
        if (rc != SCL_OK)
            return rc;
    }
    if (!cl->op_known) {
        int rc = read_op(cl, h, &cl->op_rev, NULL, 0);
        if (rc != SCL_OK)
            return rc;
        cl->op_known = 1;
    }
    scl_cmp *c = malloc((ncmp + 1) * sizeof *c);
    scl_op *o = malloc((nops + 1) * sizeof *o);
    sts_cl_doubt *nd = malloc(sizeof *nd);
    if (!c || !o || !nd) {
        free(c);
        free(o);
        free(nd);
        return SCL_ENOMEM;
    }
    char key[SCL_KEY_MAX];
    scl_key_op(key, cl->prefix, cl->self);
    memcpy(c, cmp, ncmp * sizeof *c);
    memcpy(o, ops, nops * sizeof *o);
    *nd = *d;
    nd->applied = 0;
    nd->applied_rev = 0;
    nd->rec = NULL;
    memset(&nd->copies, 0, sizeof nd->copies);
    int rc = SCL_OK;
    for (int attempt = 0; attempt < 2; attempt++) {
        cl->op_seq++;
        if (scl_op_format(nd->tag, sizeof nd->tag, cl->inc, cl->op_seq, kind_name[d->kind],
                          d->name) != 0) {
            rc = SCL_ENOMEM;
            break;
        }
        c[ncmp] = (scl_cmp){key, SCL_CMP_MOD, cl->op_rev};
        o[nops] = (scl_op){SCL_OP_PUT, key, nd->tag, 0};
        int64_t r = 0;
        rc = scl_etcd_txn(h, c, ncmp + 1, o, nops + 1, ok, &r);
        sts_cluster_note_etcd(cl, rc);
        if (rc != SCL_OK) {
            /* sent, perhaps applied, perhaps still to be: in doubt until resolved */
            if ((d->rec && !(nd->rec = strdup(d->rec))) || kvs_copy(&nd->copies, &d->copies)) {
                /* cannot keep what undoing needs: keep the rest (logged when resolved) */
                free(nd->rec);
                nd->rec = NULL;
            }
            sts_logf(&cl->srv->log, STS_WARN, "cluster: %s of '%s' in doubt (etcd did not "
                     "answer); settled when etcd answers again", kind_name[d->kind], d->name);
            sts_cluster_doubt_set(cl, nd, 1);
            STS_CL_ADD(cl, writes_in_doubt, 1);
            nd = NULL;
            break;
        }
        if (*ok) {
            cl->op_rev = r;
            if (rev)
                *rev = r;
            break;
        }
        /* a compare failed: the caller's, or the op key's. The key moved either to this very
         * tag (etcd applied the request on an endpoint that timed out, and the try on the
         * next endpoint then failed its compare: the write is done) or to a write of an
         * earlier process of this node that etcd applied late: read it, go again once */
        int64_t mod = 0;
        char now[sizeof nd->tag];
        rc = read_op(cl, h, &mod, now, sizeof now);
        if (rc != SCL_OK || mod == cl->op_rev)
            break;
        if (!strcmp(now, nd->tag)) {
            *ok = 1;
            cl->op_rev = mod;
            if (rev)
                *rev = mod;
            break;
        }
        sts_logf(&cl->srv->log, STS_WARN, "cluster: op key of '%s' moved (rev %lld -> %lld): "
                 "a late write of an earlier process", cl->self, (long long)cl->op_rev,
                 (long long)mod);
        cl->op_rev = mod;
    }
    free(c);
    free(o);
    free(nd);
    return rc;
}

int sts_cluster_take_back(sts_cluster *cl, scl_etcd *h, const sts_cl_claim *c, int64_t rev,
                          int nacked, const char (*acked)[STP_MAX_NODE_ID + 1])
{
    char key[SCL_KEY_MAX], val[2048], ckeys[STS_CL_MAX_HOLDERS + 1][SCL_KEY_MAX];
    scl_key_set(key, cl->prefix, c->name);
    scl_cmp cmp = {key, SCL_CMP_MOD, rev};
    scl_op ops[STS_CL_MAX_HOLDERS + 2];
    size_t n = 0;
    ops[n++] = (scl_op){SCL_OP_DEL, key, NULL, 0};
    if (c->had_prev) {
        scl_setrec_format(val, sizeof val, &c->prev);
        ops[0] = (scl_op){SCL_OP_PUT, key, val, 0};
    }
    for (int i = 0; i < nacked && i <= STS_CL_MAX_HOLDERS; i++) {
        scl_key_copies(ckeys[i], cl->prefix, c->name, acked[i]);
        ops[n++] = (scl_op){SCL_OP_DEL, ckeys[i], NULL, 0};
    }
    sts_cl_doubt d;
    memset(&d, 0, sizeof d);
    d.kind = STS_DOUBT_UNCLAIM;
    snprintf(d.name, sizeof d.name, "%s", c->name);
    d.claim = *c;
    d.claim.mod_rev = rev;
    d.nacked = nacked;
    if (nacked > 0) /* acked may be NULL when none acknowledged (memcpy's NULL is UB even for 0) */
        memcpy(d.acked, acked, (size_t)nacked * sizeof d.acked[0]);
    int ok = 0;
    int rc = sts_cluster_wtxn(cl, h, &cmp, 1, ops, n, &ok, NULL, &d);
    if (rc == SCL_OK)
        sts_logf(&cl->srv->log, ok ? STS_INFO : STS_WARN, "cluster: claim of '%s' taken back%s",
                 c->name, ok ? "" : " (not possible: the record changed meanwhile)");
    return rc;
}

/* Puts back a record and its copies/ keys removed by a DELETE that etcd applied after the
 * request had been answered UNAVAILABLE; only while the name is still free. */
static int restore(sts_cluster *cl, scl_etcd *h, sts_cl_doubt *was)
{
    if (!was->rec) {
        sts_logf(&cl->srv->log, STS_ERROR, "cluster: delete of '%s' was applied late and cannot "
                 "be undone (out of memory when it was sent)", was->name);
        return SCL_OK;
    }
    char key[SCL_KEY_MAX];
    scl_key_set(key, cl->prefix, was->name);
    scl_cmp cmp = {key, SCL_CMP_CREATE, 0};
    scl_op *ops = malloc((was->copies.n + 1) * sizeof *ops);
    if (!ops)
        return SCL_ENOMEM;
    ops[0] = (scl_op){SCL_OP_PUT, key, was->rec, 0};
    for (size_t i = 0; i < was->copies.n; i++)
        ops[i + 1] = (scl_op){SCL_OP_PUT, was->copies.v[i].key, was->copies.v[i].val, 0};
    sts_cl_doubt d = *was;
    d.kind = STS_DOUBT_RESTORE;
    int ok = 0;
    int rc = sts_cluster_wtxn(cl, h, &cmp, 1, ops, was->copies.n + 1, &ok, NULL, &d);
    free(ops);
    if (rc == SCL_OK) {
        sts_logf(&cl->srv->log, ok ? STS_INFO : STS_WARN, "cluster: '%s' put back (its delete "
                 "was refused but etcd applied it late)%s", was->name,
                 ok ? "" : ": not possible, the name was taken again meanwhile");
        if (ok)
            sts_cluster_kick(cl);
    }
    return rc;
}

int sts_cluster_resolve(sts_cluster *cl, scl_etcd *h)
{
    for (int round = 0; cl->doubt && round < 8; round++) {
        sts_cl_doubt *d = cl->doubt;
        int rc = SCL_OK, applied = d->applied;   /* 1: known already (kept by a process that
                                                    died before undoing it): no fence */
        if (!applied) {
            char key[SCL_KEY_MAX], fence[256], now[1024];
            scl_key_op(key, cl->prefix, cl->self);
            cl->op_seq++;
            scl_op_format(fence, sizeof fence, cl->inc, cl->op_seq, "fence", d->name);
            scl_cmp cmp = {key, SCL_CMP_MOD, cl->op_rev};
            scl_op op = {SCL_OP_PUT, key, fence, 0};
            int ok = 0;
            int64_t rev = 0;
            rc = scl_etcd_txn(h, &cmp, 1, &op, 1, &ok, &rev);
            sts_cluster_note_etcd(cl, rc);
            if (rc != SCL_OK)
                return rc;   /* still in doubt (a fence that applied unseen is handled next
                                time) */
            if (ok) {
                cl->op_rev = rev;
            } else {
                /* the key moved: to the write's tag when it applied, else to a fence sent in
                 * an earlier try (or a late write of an earlier process); in every case the
                 * write can no longer apply, its compare names a revision that is gone */
                rc = read_op(cl, h, &cl->op_rev, now, sizeof now);
                if (rc != SCL_OK)
                    return rc;
                applied = !strcmp(now, d->tag);
            }
            if (applied) {
                /* the op key now says so for good only until this node's next write: kept
                 * before undoing, so that a restart undoes it without asking again */
                d->applied = 1;
                d->applied_rev = cl->op_rev;
                if (undone_when_applied(d->kind))
                    sts_cluster_doubt_save(cl, d);
            }
        }
        cl->doubt = NULL;   /* owned here now; undoing may leave a new one */
        __atomic_store_n(&cl->in_doubt, 0, __ATOMIC_RELAXED);
        sts_logf(&cl->srv->log, STS_INFO, "cluster: %s of '%s' %s", kind_name[d->kind], d->name,
                 applied ? "was applied late: undoing it" : "did not apply (fenced)");
        /* a claim, finalize or delete that applied is undone; a take-back or put-back that
         * did not apply is sent again */
        if (applied && undone_when_applied(d->kind))
            STS_CL_ADD(cl, doubts_undone, 1);
        switch (d->kind) {
        case STS_DOUBT_CLAIM:
            /* the claim's revision is the op key's: one transaction */
            if (applied)
                rc = sts_cluster_take_back(cl, h, &d->claim, d->applied_rev, 0, NULL);
            break;
        case STS_DOUBT_FINALIZE:
            /* applied: the record "ok" and the copies/ keys, at the op key's revision */
            rc = applied ? sts_cluster_take_back(cl, h, &d->claim, d->applied_rev, d->nacked,
                                                 (const char (*)[STP_MAX_NODE_ID + 1])d->acked)
                         : sts_cluster_take_back(cl, h, &d->claim, d->claim.mod_rev, 0, NULL);
            break;
        case STS_DOUBT_UNCLAIM:
            if (!applied)
                rc = sts_cluster_take_back(cl, h, &d->claim, d->claim.mod_rev, d->nacked,
                                           (const char (*)[STP_MAX_NODE_ID + 1])d->acked);
            break;
        case STS_DOUBT_DELETE:
            if (applied)
                rc = restore(cl, h, d);
            break;
        case STS_DOUBT_RESTORE:
            if (!applied)
                rc = restore(cl, h, d);
            break;
        }
        if (rc != SCL_OK && !cl->doubt) {
            /* the undo or resend was not sent (etcd unreadable, no memory): still owed */
            sts_cluster_doubt_set(cl, d, 0);
            return rc;
        }
        if (!cl->doubt)
            sts_cluster_doubt_set(cl, NULL, 1);   /* clears doubt_set and the file */
        sts_cluster_doubt_free_one(d);
        if (rc != SCL_OK)
            return rc;
    }
    return cl->doubt ? SCL_EUNREACHABLE : SCL_OK;
}
