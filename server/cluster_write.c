/* server/cluster_write.c - the cluster's write path (docs/cluster.md "Writes"): the claim in
 * etcd, pushes of the staged copy to the other owners, the finalizing transaction, taking
 * a claim back, a COMPRESS result's write (staged and published as an upload's), DELETE, and
 * the one-record catalogue read REPLICA_PUBLISH asks before hiding a copy (sts_cluster_records). Runs on the thread of the request (a worker for COMMIT and DELETE),
 * never on an I/O thread; etcd calls go through cl->etcd_w under cl->etcd_mu, and every
 * transaction through sts_cluster_wtxn (cluster_fence.c: a write etcd did not answer is
 * settled so that it matches its UNAVAILABLE reply).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cluster_node.h"
#include "h_upload.h"
#include "peer.h"
#include "server.h"

#define PUSH_TIMEOUT_MS 30000
#define PUBLISH_TIMEOUT_MS 30000   /* the receiver imports the staged copy again */
#define TELL_TIMEOUT_MS 5000       /* a holder of stale contents only hides them */

/* The manifest of this node's copy of name and the path of its stored source; 0 or -1. */
static int local_source(sts_server *srv, const char *name, st_manifest *m, char *spath,
                        size_t cap, st_error *e)
{
    char mpath[4096];
    snprintf(mpath, sizeof mpath, "%s/sets/%s/manifest", st_datadir_path(srv->dd), name);
    st_error_clear(e);
    if (st_manifest_read(mpath, m, e) != 0)
        return -1;
    snprintf(spath, cap, "%s/sets/%s/%s", st_datadir_path(srv->dd), name, m->source);
    return 0;
}

/* The CRC-32C of the file at path (the wire checksum an upload of it carries); 0 or -1. */
static int file_crc32c(const char *path, uint32_t *out)
{
    uint32_t c = 0;
    FILE *f = fopen(path, "rbe");
    if (!f)
        return -1;
    uint8_t buf[65536];
    size_t k;
    while ((k = fread(buf, 1, sizeof buf, f)) > 0)
        c = stp_crc32c(c, buf, k);
    int bad = ferror(f);
    fclose(f);
    *out = c;
    return bad ? -1 : 0;
}

int sts_cluster_rerecord(sts_cluster *cl, const char *name, int kind)
{
    char spath[4096], key[SCL_KEY_MAX], ckey[SCL_KEY_MAX], val[2048], cval[9];
    st_manifest m;
    st_error e;
    scl_setrec r;
    memset(&r, 0, sizeof r);
    if (local_source(cl->srv, name, &m, spath, sizeof spath, &e) != 0 ||
        file_crc32c(spath, &r.crc32c) != 0) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: '%s' not recorded again: its source cannot "
                 "be read", name);
        return -1;
    }
    r.crc32 = m.crc;
    r.size = m.bytes;
    snprintf(r.fmt, sizeof r.fmt, "%s", m.format);
    snprintf(r.options, sizeof r.options, "%s", m.options);
    r.version = 1;
    r.state = SCL_SET_OK;
    snprintf(r.origin, sizeof r.origin, "%s", cl->self);
    r.inc = cl->inc;
    r.kind = kind;
    if (scl_setrec_format(val, sizeof val, &r) != 0)
        return -1;
    scl_key_set(key, cl->prefix, name);
    scl_key_copies(ckey, cl->prefix, name, cl->self);
    scl_copy_format(cval, m.crc);
    /* only a free name: a name another node recorded first keeps that node's contents */
    scl_cmp cmp = {key, SCL_CMP_CREATE, 0};
    scl_op ops[2] = {{SCL_OP_PUT, key, val, 0}, {SCL_OP_PUT, ckey, cval, 0}};
    int ok = 0;
    int rc = scl_etcd_txn(cl->etcd_r, &cmp, 1, ops, 2, &ok, NULL);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return -1;
    if (ok) {
        STS_CL_ADD(cl, sets_rerecorded, 1);
        sts_logf(&cl->srv->log, STS_WARN, "cluster: '%s' recorded again from this node's copy "
                 "(crc32 %08x): the catalogue had lost it", name, (unsigned)m.crc);
    }
    return 0;
}

/* The token this node sends to the others (they share it). */
static void node_token(sts_server *srv, char out[STS_TOKEN_MAX + 1])
{
    pthread_mutex_lock(&srv->cfg_mu);
    snprintf(out, STS_TOKEN_MAX + 1, "%s", srv->cfg.token);
    pthread_mutex_unlock(&srv->cfg_mu);
}

/* Pushes the source file spath (manifest m) to the node at addr as the copy of name; a
 * failure is counted, and logged unless quiet (the caller logs it). */
static int push_source(sts_cluster *cl, const char *name, const st_manifest *m,
                       const char *spath, int stage, const char *addr, int quiet, char *msg,
                       size_t cap)
{
    sts_server *srv = cl->srv;
    char token[STS_TOKEN_MAX + 1];
    node_token(srv, token);
    uint32_t crc = 0;
    int rc = scl_peer_push(addr, token, spath, name, m->format, m->options, stage,
                           PUSH_TIMEOUT_MS, &crc, msg, cap);
    if (rc == 0) {
        STS_CL_ADD(cl, copies_pushed, 1);
        STS_CL_ADD(cl, push_bytes, m->bytes);
        sts_logf(&srv->log, STS_INFO, "cluster: copy of '%s' (%llu bytes) pushed to %s", name,
                 (unsigned long long)m->bytes, addr);
    } else {
        STS_CL_ADD(cl, push_failures, 1);
        if (!quiet)
            sts_logf(&srv->log, STS_WARN, "cluster: %s", msg);
    }
    return rc;
}

int sts_cluster_push(sts_cluster *cl, const char *name, const char *addr, char *msg, size_t cap)
{
    char spath[4096];
    st_manifest m;
    st_error e;
    if (local_source(cl->srv, name, &m, spath, sizeof spath, &e) != 0) {
        snprintf(msg, cap, "no local copy of '%s' to push: %s", name, e.msg);
        return -1;
    }
    return push_source(cl, name, &m, spath, 0, addr, 1, msg, cap);
}

/* reads sets/<name>; 1 found (rec, mod), 0 absent, < 0 an etcd error (noted); with raw, a
 * copy of the value as it is in etcd (the caller frees it) */
static int read_rec(sts_cluster *cl, const char *key, scl_setrec *rec, int64_t *mod, char **raw)
{
    scl_kvs kvs;
    int rc = scl_etcd_range(cl->etcd_w, key, 0, &kvs);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return rc;
    int found = 0;
    if (kvs.n == 1 && scl_setrec_parse(kvs.v[0].val, rec) == 0) {
        *mod = kvs.v[0].mod_rev;
        found = 1;
    } else if (kvs.n == 1) {
        *mod = kvs.v[0].mod_rev;
        found = 2;   /* a record that is not ours: treated as taken */
    }
    if (raw && found) {
        *raw = strdup(kvs.v[0].val);
        if (!*raw)
            found = SCL_ENOMEM;
    }
    scl_kvs_free(&kvs);
    return found;
}

static int unavailable(sts_cluster *cl, char *msg, size_t cap, const char *what)
{
    STS_CL_ADD(cl, refused_unavailable, 1);
    snprintf(msg, cap, "cluster coordinator (etcd) unreachable: %s refused, retry later", what);
    return STP_S_UNAVAILABLE;
}

int sts_cluster_claim(sts_cluster *cl, const char *name, uint32_t crc32c, uint32_t crc32,
                      uint64_t size, const char *fmt, const char *options, int replace,
                      sts_cl_claim *c, char *msg, size_t cap)
{
    memset(c, 0, sizeof *c);
    snprintf(c->name, sizeof c->name, "%s", name);
    scl_setrec *r = &c->rec;
    r->crc32c = crc32c;
    r->crc32 = crc32;
    r->size = size;
    snprintf(r->fmt, sizeof r->fmt, "%s", fmt);
    snprintf(r->options, sizeof r->options, "%s", options);
    r->version = 1;
    r->state = SCL_SET_PENDING;
    snprintf(r->origin, sizeof r->origin, "%s", cl->self);
    r->inc = cl->inc;
    r->kind = -1;
    char key[SCL_KEY_MAX], val[2048];
    scl_key_set(key, cl->prefix, name);
    int status = 0;
    pthread_mutex_lock(&cl->etcd_mu);
    for (int attempt = 0; attempt < 2; attempt++) {
        scl_setrec cur;
        int64_t mod = 0;
        int found = cl->doubt && sts_cluster_resolve(cl, cl->etcd_w) != SCL_OK
                        ? SCL_EUNREACHABLE
                        : read_rec(cl, key, &cur, &mod, NULL);
        if (found < 0) {
            status = unavailable(cl, msg, cap, "upload");
            break;
        }
        scl_cmp cmp = {key, SCL_CMP_CREATE, 0};
        if (found) {
            int same = found == 1 && cur.crc32c == crc32c && cur.size == size;
            if (same && cur.state == SCL_SET_OK) {
                /* the same contents are recorded: a repeat (a retried upload); make sure the
                 * owners hold it and answer OK */
                c->rec = cur;
                c->mod_rev = mod;
                c->repeat = 1;
                status = 0;
                break;
            }
            if (same || !replace) {
                STS_CL_ADD(cl, claims_lost, 1);
                snprintf(msg, cap, same ? "set '%s' is being uploaded through another node (retry)"
                                        : "set '%s' exists in the cluster with other contents "
                                          "(use REPLACE)", name);
                status = same ? STP_S_BUSY : STP_S_EXISTS;
                break;
            }
            c->had_prev = found == 1;
            if (found == 1)
                c->prev = cur;
            r->version = found == 1 ? cur.version + 1 : 1;
            cmp.target = SCL_CMP_MOD;
            cmp.rev = mod;
        }
        scl_setrec_format(val, sizeof val, r);
        /* a REPLACE of acknowledged contents keeps their record beside the claim (prev/, in
         * the same transaction): abandoning the claim records them again (cluster_repair.c) */
        char pkey[SCL_KEY_MAX], pval[2048];
        scl_key_prev(pkey, cl->prefix, name);
        scl_op ops[2] = {{SCL_OP_PUT, key, val, 0}, {SCL_OP_PUT, pkey, pval, 0}};
        size_t nops = c->had_prev && c->prev.state == SCL_SET_OK &&
                      scl_setrec_format(pval, sizeof pval, &c->prev) == 0 ? 2 : 1;
        int ok = 0;
        int64_t rev = 0;
        sts_cl_doubt d;
        memset(&d, 0, sizeof d);
        d.kind = STS_DOUBT_CLAIM;
        snprintf(d.name, sizeof d.name, "%s", name);
        d.claim = *c;
        int rc = sts_cluster_wtxn(cl, cl->etcd_w, &cmp, 1, ops, nops, &ok, &rev, &d);
        if (rc != SCL_OK) {
            status = rc == SCL_EUNREACHABLE ? unavailable(cl, msg, cap, "upload") : STP_S_INTERNAL;
            if (rc != SCL_EUNREACHABLE)
                snprintf(msg, cap, "cluster: %s", scl_etcd_errmsg(cl->etcd_w));
            break;
        }
        if (ok) {
            c->mod_rev = rev;
            STS_CL_ADD(cl, claims, 1);
            status = 0;
            break;
        }
        /* another claim came between the read and the transaction: read again */
        status = STP_S_EXISTS;
        snprintf(msg, cap, "set '%s' was claimed by another upload meanwhile", name);
    }
    pthread_mutex_unlock(&cl->etcd_mu);
    return status;
}

int sts_cluster_records(sts_cluster *cl, const char *name, uint32_t crc32)
{
    char key[SCL_KEY_MAX];
    scl_key_set(key, cl->prefix, name);
    scl_setrec rec;
    int64_t mod = 0;
    pthread_mutex_lock(&cl->etcd_mu);
    int found = read_rec(cl, key, &rec, &mod, NULL);
    pthread_mutex_unlock(&cl->etcd_mu);
    if (found < 0)
        return found;
    return found == 1 && rec.state == SCL_SET_OK && rec.crc32 == crc32;
}

void sts_cluster_unclaim(sts_cluster *cl, const sts_cl_claim *c)
{
    if (c->repeat)
        return;
    pthread_mutex_lock(&cl->etcd_mu);
    int rc = sts_cluster_take_back(cl, cl->etcd_w, c, c->mod_rev, 0, NULL);
    pthread_mutex_unlock(&cl->etcd_mu);
    if (rc != SCL_OK)
        sts_logf(&cl->srv->log, STS_WARN, "cluster: claim of '%s' not taken back yet (etcd: "
                 "%s); settled when etcd answers again", c->name, scl_etcd_errmsg(cl->etcd_w));
}

/* A REPLACE just recorded: every member that holds a copy of other contents (a copies/ key
 * with another CRC) but got no push - not an owner in this node's view: a node joining, or an
 * extra copy repair has not dropped yet - is sent the same REPLICA_PUBLISH, on which it hides
 * its stale copy from reads (h_upload.c; before, it served the replaced contents until its next
 * repair pass: cl27's defect 5). Best effort: one it misses drops its copy at that pass. */
static void tell_stale_holders(sts_cluster *cl, const sts_cl_claim *c,
                               const char (*acked)[STP_MAX_NODE_ID + 1], int nack)
{
    char ckey[SCL_KEY_MAX];
    scl_key_copies(ckey, cl->prefix, c->name, "");
    scl_kvs copies;
    memset(&copies, 0, sizeof copies);
    pthread_mutex_lock(&cl->etcd_mu);
    int rc = scl_etcd_range(cl->etcd_w, ckey, 1, &copies);
    pthread_mutex_unlock(&cl->etcd_mu);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return;
    sts_cl_member *m = NULL;
    size_t n = sts_cluster_members(cl, &m, NULL);
    size_t plen = strlen(ckey);
    for (size_t i = 0; i < copies.n; i++) {
        const char *id = copies.v[i].key + plen;
        uint32_t crc = 0;
        int told = copies.v[i].key_len <= plen ||
                   scl_copy_parse(copies.v[i].val, &crc) != 0 || crc == c->rec.crc32;
        for (int k = 0; !told && k < nack; k++)
            told = !strcmp(acked[k], id);
        for (size_t j = 0; !told && j < n; j++)
            if (!strcmp(m[j].id, id)) {
                char pm[512], token[STS_TOKEN_MAX + 1];
                node_token(cl->srv, token);
                int prc = scl_peer_publish(m[j].addr, token, c->name, c->rec.crc32,
                                           TELL_TIMEOUT_MS, pm, sizeof pm);
                if (prc && prc != SCL_PEER_NOT_FOUND)   /* it hid its stale copy */
                    sts_logf(&cl->srv->log, STS_WARN, "cluster: %s", pm);
                else
                    sts_logf(&cl->srv->log, STS_INFO, "cluster: %s told that '%s' was replaced",
                             m[j].id, c->name);
                told = 1;
            }
    }
    free(m);
    scl_kvs_free(&copies);
}

int sts_cluster_replicate(sts_cluster *cl, sts_cl_claim *c, int kind, const char *stage,
                          char *msg, size_t cap)
{
    char spath[4096];   /* the copy pushed: the staged one, or the published one */
    st_manifest sm;
    st_error se;
    int have_src = stage ? st_datadir_staged_read(cl->srv->dd, stage, &sm, spath, sizeof spath,
                                                  &se) == 0
                         : local_source(cl->srv, c->name, &sm, spath, sizeof spath, &se) == 0;
    sts_cl_member *m = NULL;
    size_t n = sts_cluster_members(cl, &m, NULL);
    size_t order[16];
    size_t R = sts_cluster_rank(m, n, c->name, order, cl->replicas < 16 ? cl->replicas : 16);
    char acked[STS_CL_MAX_HOLDERS + 1][STP_MAX_NODE_ID + 1];   /* the owners and this node */
    char addrs[STS_CL_MAX_HOLDERS + 1][STP_MAX_NODE_ADDR + 1];  /* acked[i]'s, "" for this node */
    int nack = 0, self_owner = 0;
    char why[512] = "";
    for (size_t i = 0; i < R; i++) {
        const sts_cl_member *o = &m[order[i]];
        if (!strcmp(o->id, cl->self)) {
            self_owner = 1;
            addrs[nack][0] = 0;
            snprintf(acked[nack++], sizeof acked[0], "%s", o->id);
            continue;
        }
        char pm[512];
        if (!have_src)
            snprintf(pm, sizeof pm, "no local copy to push: %.200s", se.msg);
        if (have_src && push_source(cl, c->name, &sm, spath, stage != NULL, o->addr, 0, pm,
                                    sizeof pm) == 0) {
            snprintf(addrs[nack], sizeof addrs[0], "%s", o->addr);
            snprintf(acked[nack++], sizeof acked[0], "%s", o->id);
        } else {
            snprintf(why, sizeof why, "%s", pm);
        }
    }
    free(m);
    size_t need = cl->quorum < R ? cl->quorum : R;
    if ((size_t)nack < need || R == 0) {
        sts_cluster_unclaim(cl, c);
        snprintf(msg, cap, "write quorum not reached: %d of %zu owners hold '%s'%s%s", nack, need,
                 c->name, why[0] ? ": " : "", why);
        return STP_S_UNAVAILABLE;
    }
    /* finalize: the record "ok" with its kind, and a copies/ key per holder (this node's own
     * copy too when it is not an owner: repair drops it once the owners confirmed theirs) */
    if (!self_owner) {
        addrs[nack][0] = 0;
        snprintf(acked[nack++], sizeof acked[0], "%s", cl->self);
    }
    char key[SCL_KEY_MAX], val[2048], ckeys[17][SCL_KEY_MAX], cval[9];
    scl_key_set(key, cl->prefix, c->name);
    c->rec.state = SCL_SET_OK;
    c->rec.kind = kind;
    scl_setrec_format(val, sizeof val, &c->rec);
    scl_copy_format(cval, c->rec.crc32);
    scl_op ops[19];
    size_t nops = 0;
    ops[nops++] = (scl_op){SCL_OP_PUT, key, val, 0};
    for (int i = 0; i < nack; i++) {
        scl_key_copies(ckeys[i], cl->prefix, c->name, acked[i]);
        ops[nops++] = (scl_op){SCL_OP_PUT, ckeys[i], cval, 0};
    }
    char pkey[SCL_KEY_MAX];   /* the replaced record kept for an abandon: no longer needed */
    scl_key_prev(pkey, cl->prefix, c->name);
    if (c->had_prev)
        ops[nops++] = (scl_op){SCL_OP_DEL, pkey, NULL, 0};
    scl_cmp cmp = {key, SCL_CMP_MOD, c->mod_rev};
    int ok = 0;
    sts_cl_doubt *d = calloc(1, sizeof *d);
    if (!d) {
        sts_cluster_unclaim(cl, c);
        snprintf(msg, cap, "out of memory while recording '%s'", c->name);
        return STP_S_INTERNAL;
    }
    d->kind = STS_DOUBT_FINALIZE;
    snprintf(d->name, sizeof d->name, "%s", c->name);
    d->claim = *c;
    d->nacked = nack;
    memcpy(d->acked, acked, (size_t)nack * sizeof acked[0]);
    pthread_mutex_lock(&cl->etcd_mu);
    int rc = sts_cluster_wtxn(cl, cl->etcd_w, &cmp, 1, ops, nops, &ok, NULL, d);
    pthread_mutex_unlock(&cl->etcd_mu);
    free(d);
    if (rc != SCL_OK)
        return unavailable(cl, msg, cap, "upload");   /* taken back when etcd answers */
    if (!ok) {
        snprintf(msg, cap, "set '%s' was replaced or deleted while this upload was copied", c->name);
        return STP_S_EXISTS;
    }
    sts_cluster_note_set(cl, c->name, c->rec.crc32, (const char (*)[STP_MAX_NODE_ID + 1])acked, nack);
    /* recorded: the receivers publish the copies they staged (one that misses this does it
     * at its next repair pass, which finds the write recorded) */
    for (int i = 0; stage && i < nack; i++) {
        if (!addrs[i][0])
            continue;
        char pm[512], token[STS_TOKEN_MAX + 1];
        node_token(cl->srv, token);
        if (scl_peer_publish(addrs[i], token, c->name, c->rec.crc32, PUBLISH_TIMEOUT_MS, pm,
                             sizeof pm) != 0)
            sts_logf(&cl->srv->log, STS_WARN, "cluster: %s (its repair pass publishes it)", pm);
    }
    if (c->had_prev)
        tell_stale_holders(cl, c, (const char (*)[STP_MAX_NODE_ID + 1])acked, nack);
    return 0;
}

int sts_cluster_record_file(sts_cluster *cl, const char *name, int replace, int kind,
                            const char *path, const char *fmt, uint64_t bytes, st_set *set,
                            char *msg, size_t cap)
{
    sts_server *srv = cl->srv;
    uint32_t c32c = 0, c32 = 0;
    uint64_t got = 0;
    st_error e;
    st_error_clear(&e);
    if (file_crc32c(path, &c32c) != 0 || st_file_crc(path, &got, &c32, &e) != 0 || got != bytes) {
        st_datadir_discard(path);
        st_set_free(set);
        snprintf(msg, cap, "cannot read the result written for '%s'", name);
        return STP_S_IO;
    }
    sts_cl_claim c;
    int st = sts_cluster_claim(cl, name, c32c, c32, bytes, fmt, "", replace, &c, msg, cap);
    if (st) {
        st_datadir_discard(path);
        st_set_free(set);
        return st;
    }
    /* staged, not published, until the write is recorded (as an upload: h_upload.c) */
    char sid[64];
    int rc = st_datadir_stage(srv->dd, name, path, fmt, "", bytes, sid, sizeof sid, &e);
    if (rc) {
        sts_cluster_unclaim(cl, &c);
        st_set_free(set);
        snprintf(msg, cap, "staging the result for '%s' failed", name);
        return sts_status_from_st(rc);
    }
    STS_CL_ADD(cl, copies_staged, 1);
    st = sts_cluster_replicate(cl, &c, kind, sid, msg, cap);
    if (st && !c.repeat) {
        st_set_free(set);
        sts_drop_staged(srv, sid, "the write was refused");
        return st;
    }
    st_error pe;
    st_error_clear(&pe);
    rc = sts_publish_staged(srv, sid, set, NULL, &pe);
    if (rc && rc != ST_ENOTFOUND)
        sts_logf(&srv->log, STS_WARN, "cluster: the recorded copy of '%s' is staged but could "
                 "not be published here yet (%s): the repair pass tries again", name, pe.msg);
    return st;
}

int sts_cluster_delete(sts_cluster *cl, const char *name,
                       int (*local_delete)(sts_server *srv, const char *name), char *msg,
                       size_t cap)
{
    char key[SCL_KEY_MAX], ckey[SCL_KEY_MAX];
    scl_key_set(key, cl->prefix, name);
    scl_key_copies(ckey, cl->prefix, name, "");
    scl_setrec rec;
    int64_t mod = 0;
    char *raw = NULL;
    scl_kvs copies;
    memset(&copies, 0, sizeof copies);
    pthread_mutex_lock(&cl->etcd_mu);
    int found = cl->doubt && sts_cluster_resolve(cl, cl->etcd_w) != SCL_OK
                    ? SCL_EUNREACHABLE
                    : read_rec(cl, key, &rec, &mod, &raw);
    int rc = found < 0 ? found : SCL_OK;
    if (found > 0) {
        rc = scl_etcd_range(cl->etcd_w, ckey, 1, &copies);
        sts_cluster_note_etcd(cl, rc);
        if (rc == SCL_OK) {
            /* recorded first: the record and every copies/ key in one transaction; what it
             * removes is kept in case etcd applies it after this request was refused */
            scl_cmp cmp = {key, SCL_CMP_MOD, mod};
            scl_op ops[2] = {{SCL_OP_DEL, key, NULL, 0}, {SCL_OP_DEL_PREFIX, ckey, NULL, 0}};
            sts_cl_doubt d;
            memset(&d, 0, sizeof d);
            d.kind = STS_DOUBT_DELETE;
            snprintf(d.name, sizeof d.name, "%s", name);
            d.rec = raw;
            d.copies = copies;
            int ok = 0;
            rc = sts_cluster_wtxn(cl, cl->etcd_w, &cmp, 1, ops, 2, &ok, NULL, &d);
            if (rc == SCL_OK && !ok) {
                pthread_mutex_unlock(&cl->etcd_mu);
                scl_kvs_free(&copies);
                free(raw);
                snprintf(msg, cap, "set '%s' changed while being deleted (retry)", name);
                return STP_S_BUSY;
            }
        }
    }
    pthread_mutex_unlock(&cl->etcd_mu);
    free(raw);
    if (rc != SCL_OK) {
        scl_kvs_free(&copies);
        return unavailable(cl, msg, cap, "delete");
    }
    sts_cluster_note_set(cl, name, 0, NULL, 0);
    int lrc = local_delete(cl->srv, name);
    if (found > 0) {
        /* forward to the other holders (best effort: repair drops what is left) */
        sts_cl_member *m = NULL;
        size_t n = sts_cluster_members(cl, &m, NULL);
        size_t plen = strlen(ckey);
        for (size_t i = 0; i < copies.n; i++) {
            const char *id = copies.v[i].key + plen;
            if (copies.v[i].key_len <= plen || !strcmp(id, cl->self))
                continue;
            for (size_t j = 0; j < n; j++)
                if (!strcmp(m[j].id, id)) {
                    char pm[512], token[STS_TOKEN_MAX + 1];
                    node_token(cl->srv, token);
                    if (scl_peer_delete(m[j].addr, token, name, 5000, pm, sizeof pm) != 0)
                        sts_logf(&cl->srv->log, STS_WARN, "cluster: %s", pm);
                }
        }
        free(m);
        scl_kvs_free(&copies);
        return 0;
    }
    scl_kvs_free(&copies);
    if (lrc == ST_ENOTFOUND) {
        snprintf(msg, cap, "no set %s", name);
        return STP_S_NOT_FOUND;
    }
    if (lrc) {
        snprintf(msg, cap, "delete of '%s' failed on this node", name);
        return sts_status_from_st(lrc);
    }
    return 0;
}
