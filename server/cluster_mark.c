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
 * The cluster's settings live beside the mark: `PREFIX/config` = {"replicas":R,
 * "write_quorum":W}, put by the first node that finds none. Nodes that disagree on R place
 * sets differently (one pushes a copy the others drop as extra, over and over), so a node
 * started with other --replicas / --write-quorum than the key's refuses to start.
 *
 * Owns: the mark key's reading and creation, the cluster-id file, the config key's check at
 * start. Does not own: recording the sets again (cluster_write.c, sts_cluster_rerecord), the
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

/* the mark the data dir keeps for this prefix; 0 when none (no file, or another prefix's) */
static uint64_t file_mark(sts_cluster *cl)
{
    char path[4096];
    void *buf = NULL;
    size_t len = 0;
    st_error e;
    if (mark_path(cl, path, sizeof path) != 0 || st_file_read(path, 4096, &buf, &len, &e) != 0)
        return 0;
    const char *s = buf, *nl = memchr(s, '\n', len);
    size_t plen = strlen(cl->prefix);
    uint64_t id = 0;
    if (nl && nl - s == 17 + (ptrdiff_t)plen && s[16] == ' ' && !memcmp(s + 17, cl->prefix, plen))
        id = parse_id(s, 16);
    free(buf);
    return id;
}

static int file_keep(sts_cluster *cl, uint64_t id)
{
    char path[4096], line[300];
    st_error e;
    int n = snprintf(line, sizeof line, "%016" PRIx64 " %s\n", id, cl->prefix);
    if (mark_path(cl, path, sizeof path) != 0 || n <= 0 || (size_t)n >= sizeof line ||
        st_file_write_atomic(path, line, (size_t)n, &e) != 0) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: the catalogue's mark not kept in the data "
                 "dir (%s)", MARK_FILE);
        return -1;
    }
    return 0;
}

int sts_cluster_mark_adopt(sts_cluster *cl)
{
    return cl->mark_seen ? file_keep(cl, cl->mark_seen) : -1;
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
    uint64_t known = file_mark(cl);
    cl->mark_seen = seen;
    if (seen && seen == known)
        return 0;
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
                file_keep(cl, id);
            return 0;
        }
    }
    if (!known && seen) {
        file_keep(cl, seen);   /* the first catalogue this data dir joins */
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
