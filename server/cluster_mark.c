/* server/cluster_mark.c - the catalogue's identity (docs/cluster.md "Catalogue lost").
 *
 * etcd holds the only record of which sets exist; repair drops a local copy the catalogue
 * does not record (a DELETE). An etcd that lost its data (restarted with its data dir wiped,
 * or restored from an old backup) records nothing, and every node would drop every set two
 * lease TTLs later. So the catalogue carries a mark, `PREFIX/cluster` (16 hex digits, drawn
 * by the node that finds the prefix without one), and each node keeps the mark it has
 * worked with in `<data-dir>/cluster-id` (`<16 hex digits> <prefix>`, written whole). A pass
 * whose catalogue carries another mark, or none, while the data dir knows one is not judged
 * against that catalogue: the node drops nothing, records its sets again (only names still
 * free) and then keeps the new mark; the next pass is an ordinary one.
 *
 * An etcd restored from an older snapshot or backup keeps the mark, but goes back to the
 * backup's revision: the revision watch of the node's etcd handles (cluster/etcd.h) sees a
 * reply below a revision seen before, and the pass is not judged either (one WARN, STATS
 * cluster_etcd_went_back), then the catalogue's revision is adopted. cluster-id keeps the
 * highest revision seen as a second line, `rev N`, so that a node restarted on a restored etcd
 * catches it too: written before a pass drops anything, when a pass confirms a local copy
 * recorded after the kept revision, and every 10th pass while the revision moves.
 *
 * The cluster's settings live beside the mark: `PREFIX/config` = {"replicas":R,
 * "write_quorum":W}, put by the first node that finds none. Nodes that disagree on R place
 * sets differently (one pushes a copy the others drop as extra, over and over), so a node
 * started with other --replicas / --write-quorum than the key's refuses to start.
 *
 * Owns: the mark key's reading and creation, the cluster-id file (mark and kept revision), the
 * judgement of the revision watch, the config key's check at start. Does not own: recording the sets again (cluster_write.c, sts_cluster_rerecord), the
 * pass (cluster_repair.c).
 */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cluster_node.h"
#include "fileio.h"
#include "server.h"

#define MARK_FILE "cluster-id"
/* the highest revision seen is kept at least every this many passes while it moves
 * (docs/cluster.md "Catalogue lost"): what a node restarted after etcd was restored compares
 * with */
#define KEEP_EVERY_PASSES 10

static int mark_path(const sts_cluster *cl, char *out, size_t cap)
{
    if (!cl->srv->dd)
        return -1;
    int n = snprintf(out, cap, "%s/" MARK_FILE, st_datadir_path(cl->srv->dd));
    return n > 0 && (size_t)n < cap ? 0 : -1;
}

/* "0123456789abcdef" -> the id; 0 when it is not 16 hex digits or is 0 */
static uint64_t parse_id(const char *s, size_t len)
{
    if (len != 16)
        return 0;
    uint64_t v = 0;
    for (size_t i = 0; i < 16; i++) {
        int c = s[i], d = c >= '0' && c <= '9' ? c - '0'
                        : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
        if (d < 0)
            return 0;
        v = v << 4 | (uint64_t)d;
    }
    return v;
}

/* the mark the data dir keeps for this prefix, 0 when none (no file, or another prefix's);
 * *rev: the revision kept with it (the second line, "rev N"), 0 when none (a file of a version
 * before the revision watch) */
static uint64_t file_mark(sts_cluster *cl, int64_t *rev)
{
    char path[4096];
    void *buf = NULL;
    size_t len = 0;
    st_error e;
    if (rev)
        *rev = 0;
    if (mark_path(cl, path, sizeof path) != 0 || st_file_read(path, 4096, &buf, &len, &e) != 0)
        return 0;
    const char *s = buf, *nl = memchr(s, '\n', len);
    size_t plen = strlen(cl->prefix);
    uint64_t id = 0;
    if (nl && nl - s == 17 + (ptrdiff_t)plen && s[16] == ' ' && !memcmp(s + 17, cl->prefix, plen))
        id = parse_id(s, 16);
    const char *r = nl ? nl + 1 : NULL, *end = s + len;
    if (rev && id && r && end - r > 4 && !memcmp(r, "rev ", 4)) {
        int64_t v = 0;
        const char *q = r + 4;
        while (q < end && *q >= '0' && *q <= '9' && v < INT64_MAX / 10 - 9)
            v = v * 10 + (*q++ - '0');
        if (q < end && *q == '\n' && q > r + 4)
            *rev = v;
    }
    free(buf);
    return id;
}

/* writes the file whole: the mark id, and the revision rev (0: none) */
static int file_keep(sts_cluster *cl, uint64_t id, int64_t rev)
{
    char path[4096], line[340];
    st_error e;
    int n = rev > 0 ? snprintf(line, sizeof line, "%016" PRIx64 " %s\nrev %" PRId64 "\n", id,
                               cl->prefix, rev)
                    : snprintf(line, sizeof line, "%016" PRIx64 " %s\n", id, cl->prefix);
    if (mark_path(cl, path, sizeof path) != 0 || n <= 0 || (size_t)n >= sizeof line ||
        st_file_write_atomic(path, line, (size_t)n, &e) != 0) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: the catalogue's mark not kept in the data "
                 "dir (%s)", MARK_FILE);
        return -1;
    }
    cl->rev_kept = rev;
    cl->checks_unkept = 0;
    return 0;
}

void sts_cluster_mark_load(sts_cluster *cl)
{
    int64_t rev = 0;
    if (file_mark(cl, &rev))
        cl->rev_kept = rev;
    scl_revwatch_seed(&cl->revw, cl->rev_kept);
    scl_etcd_set_revwatch(cl->etcd_w, &cl->revw);
    scl_etcd_set_revwatch(cl->etcd_m, &cl->revw);
    scl_etcd_set_revwatch(cl->etcd_r, &cl->revw);
}

int sts_cluster_mark_adopt(sts_cluster *cl)
{
    if (!cl->mark_seen || file_keep(cl, cl->mark_seen, cl->pass_rev) != 0)
        return -1;
    scl_revwatch_reset(&cl->revw, cl->pass_rev);
    if (cl->back_from)
        sts_logf(&cl->srv->log, STS_INFO, "cluster: the catalogue at revision %" PRId64 " "
                 "adopted (every local set it lacked recorded again)", cl->pass_rev);
    cl->back_from = 0;
    return 0;
}

void sts_cluster_rev_keep(sts_cluster *cl, int64_t rec_rev)
{
    int64_t rev = cl->keep_top;
    if (!cl->mark_seen || cl->back_from || rev <= cl->rev_kept ||
        (rec_rev && rec_rev <= cl->rev_kept))
        return;
    if (file_keep(cl, cl->mark_seen, rev) != 0) {
        cl->rev_kept = rev;   /* (logged) not tried again before the revision moves on */
        cl->checks_unkept = 0;
    }
}

int sts_cluster_mark_check(sts_cluster *cl, int64_t rev)
{
    char key[SCL_KEY_MAX];
    scl_key_mark(key, cl->prefix);
    scl_kvs kv;
    int rc = scl_etcd_range_at(cl->etcd_r, key, 0, rev, &kv);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK)
        return rc;
    uint64_t seen = kv.n == 1 ? parse_id(kv.v[0].val, kv.v[0].val_len) : 0;
    int other = kv.n == 1 && !seen;   /* a value that is not a mark: left alone */
    scl_kvs_free(&kv);
    uint64_t known = file_mark(cl, NULL);   /* (its revision: cl->rev_kept, from init on) */
    cl->mark_seen = seen;
    cl->pass_rev = rev;
    if (seen && seen == known) {
        /* the mark known: the revision watch says whether etcd went back (the pass's own
         * read is among the replies it judged) */
        int64_t from, to;
        if (!scl_revwatch_back(&cl->revw, &from, &to) && !cl->back_from) {
            /* the highest revision seen, kept by this pass if something is at stake, and at
             * least every KEEP_EVERY_PASSES passes while the revision moves */
            cl->keep_top = scl_revwatch_top(&cl->revw);
            if (++cl->checks_unkept >= KEEP_EVERY_PASSES)
                sts_cluster_rev_keep(cl, 0);
            return 0;
        }
        if (!cl->back_from) {
            cl->back_from = from;
            STS_CL_ADD(cl, etcd_went_back, 1);
            sts_logf(&cl->srv->log, STS_WARN, "cluster: etcd went back in time (revision %"
                     PRId64 " -> %" PRId64 "): restored from an older snapshot or backup; the "
                     "catalogue under %s is not judged: nothing is dropped, this node's sets "
                     "are recorded again, then its revision is adopted", from, to, cl->prefix);
        }
        return 1;
    }
    if (!seen && !other) {
        /* no mark: a new catalogue (or one of a version before marks): this node marks it */
        char val[17];
        uint64_t id = sts_cluster_random_id();
        snprintf(val, sizeof val, "%016" PRIx64, id);
        scl_cmp cmp = {key, SCL_CMP_CREATE, 0};
        scl_op op = {SCL_OP_PUT, key, val, 0};
        int ok = 0;
        rc = scl_etcd_txn(cl->etcd_r, &cmp, 1, &op, 1, &ok, NULL);
        sts_cluster_note_etcd(cl, rc);
        if (rc != SCL_OK)
            return rc;
        if (ok) {
            sts_logf(&cl->srv->log, known ? STS_WARN : STS_INFO, "cluster: catalogue under %s "
                     "had no mark: marked %s", cl->prefix, val);
            cl->mark_seen = id;
        }
        if (!known) {
            /* the catalogue the pass read is the one just marked (or marked by another node
             * meanwhile: kept at the next pass) */
            if (ok)
                file_keep(cl, id, rev);
            return 0;
        }
    }
    if (!known && seen) {
        file_keep(cl, seen, rev);   /* the first catalogue this data dir joins */
        return 0;
    }
    if (!known)
        return 0;   /* a foreign value under the key: judged as before marks */
    sts_logf(&cl->srv->log, STS_ERROR, "cluster: the catalogue under %s is not the one this "
             "node's data dir knows (mark %016" PRIx64 " kept, %s in etcd): etcd lost its data "
             "or was restored from an older backup; nothing is dropped, this node's sets are "
             "recorded again", cl->prefix, known, seen ? "another" : "none");
    return 1;
}

int sts_cluster_settings_check(sts_cluster *cl)
{
    char key[SCL_KEY_MAX], val[64];
    scl_key_config(key, cl->prefix);
    if (scl_config_format(val, sizeof val, cl->replicas, cl->quorum) != 0)
        return -1;
    scl_cmp cmp = {key, SCL_CMP_CREATE, 0};
    scl_op op = {SCL_OP_PUT, key, val, 0};
    int ok = 0;
    int rc = scl_etcd_txn(cl->etcd_m, &cmp, 1, &op, 1, &ok, NULL);
    scl_kvs kv = {0};
    if (rc == SCL_OK && !ok)
        rc = scl_etcd_range(cl->etcd_m, key, 0, &kv);
    sts_cluster_note_etcd(cl, rc);
    if (rc != SCL_OK) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: the cluster's settings (%s) not checked: "
                 "etcd did not answer", key);
        return 0;
    }
    if (ok) {
        sts_logf(&cl->srv->log, STS_INFO, "cluster: settings recorded: %s", val);
        return 0;
    }
    unsigned r = 0, w = 0;
    int parsed = kv.n == 1 && scl_config_parse(kv.v[0].val, &r, &w) == 0;
    scl_kvs_free(&kv);
    if (!parsed) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: %s holds no settings record: not checked", key);
        return 0;
    }
    if (r == cl->replicas && w == cl->quorum)
        return 0;
    sts_logf(&cl->srv->log, STS_ERROR, "cluster: this cluster has replicas %u, write quorum %u "
             "(%s); this node was started with --replicas %u --write-quorum %u: refused (to "
             "change them, docs/cluster.md \"Flags\")", r, w, key, cl->replicas, cl->quorum);
    return -1;
}
