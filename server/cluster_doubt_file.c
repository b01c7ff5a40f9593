/* server/cluster_doubt_file.c - a write in doubt kept in the data dir, so that it is settled
 * also when the process that refused it dies first (docs/cluster.md "Writes in doubt").
 *
 * A write whose etcd transaction got no answer is answered UNAVAILABLE only after what settling
 * it needs is on disk: `<data-dir>/cluster-doubt`, written whole (temp file, fsync, rename,
 * folder fsync), removed once the write is settled. A node that starts with the file (same node
 * id and prefix) holds the doubt as if it had refused the write itself: the fence compares the
 * revision saved with it, and a write that applied meanwhile is undone. When the fence shows
 * that the write applied, the file is written again with that fact (and the write's revision)
 * before the undo is sent: a fence that moved the op key cannot be asked again.
 *
 * Text, one `key value` per line (the value runs to the end of the line; no value may hold a
 * newline): `seamtex-doubt 1`, `node`, `prefix`, `kind`, `applied`, `applied_rev`, `op_rev`,
 * `name`, `tag`, for a claim, finalize or take-back `claim_name`, `claim_rec`, `claim_rev`,
 * `claim_repeat` and `claim_prev` (a REPLACE's record before), then `acked` per copies/ key a finalize put, `rec` (the record's value as it
 * was, when kept), `copy_key` + `copy_val` per copies/ key as it was, and `end`.
 *
 * Owns: the file. Does not own: the doubt (cluster_fence.c), the data dir's sets (datadir.c).
 */
#include <errno.h>
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cluster_node.h"
#include "fdio.h"
#include "fileio.h"
#include "server.h"

#define DOUBT_FILE "cluster-doubt"
#define DOUBT_CAP  (1u << 20)

static int doubt_path(const sts_cluster *cl, char *out, size_t cap)
{
    if (!cl->srv->dd)
        return -1;
    int n = snprintf(out, cap, "%s/" DOUBT_FILE, st_datadir_path(cl->srv->dd));
    return n > 0 && (size_t)n < cap ? 0 : -1;
}

typedef struct wbuf { char *p; size_t n, cap; int bad; } wbuf;

static void put(wbuf *b, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static void put(wbuf *b, const char *key, const char *fmt, ...)
{
    char val[4096];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(val, sizeof val, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= sizeof val || strchr(val, '\n')) {
        b->bad = 1;
        return;
    }
    size_t need = strlen(key) + 1 + (size_t)n + 1;
    if (b->n + need + 1 > b->cap) {
        size_t cap = (b->cap ? b->cap * 2 : 4096) + need;
        char *p = cap <= DOUBT_CAP ? realloc(b->p, cap) : NULL;
        if (!p) {
            b->bad = 1;
            return;
        }
        b->p = p;
        b->cap = cap;
    }
    b->n += (size_t)sprintf(b->p + b->n, "%s %s\n", key, val);
}

int sts_cluster_doubt_save(sts_cluster *cl, const sts_cl_doubt *d)
{
    char path[4096];
    if (doubt_path(cl, path, sizeof path) != 0)
        return -1;
    if (!d) {
        if (unlink(path) != 0)
            return errno == ENOENT ? 0 : -1;
        return stu_fsync_parent(path);
    }
    wbuf b = {0};
    int claim = d->kind == STS_DOUBT_CLAIM || d->kind == STS_DOUBT_FINALIZE ||
                d->kind == STS_DOUBT_UNCLAIM;
    char rec[2048], prev[2048];
    if (claim && (scl_setrec_format(rec, sizeof rec, &d->claim.rec) != 0 ||
                  (d->claim.had_prev && scl_setrec_format(prev, sizeof prev, &d->claim.prev))))
        b.bad = 1;
    put(&b, "seamtex-doubt", "1");
    put(&b, "node", "%s", cl->self);
    put(&b, "prefix", "%s", cl->prefix);
    put(&b, "kind", "%d", d->kind);
    put(&b, "applied", "%d", d->applied);
    put(&b, "applied_rev", "%" PRId64, d->applied_rev);
    put(&b, "op_rev", "%" PRId64, cl->op_rev);
    put(&b, "name", "%s", d->name);
    put(&b, "tag", "%s", d->tag);
    if (claim) {
        put(&b, "claim_name", "%s", d->claim.name);
        put(&b, "claim_rec", "%s", rec);
        put(&b, "claim_rev", "%" PRId64, d->claim.mod_rev);
        put(&b, "claim_repeat", "%d", d->claim.repeat);
        if (d->claim.had_prev)
            put(&b, "claim_prev", "%s", prev);
    }
    for (int i = 0; i < d->nacked && i <= STS_CL_MAX_HOLDERS; i++)
        put(&b, "acked", "%s", d->acked[i]);
    if (d->rec)
        put(&b, "rec", "%s", d->rec);
    for (size_t i = 0; i < d->copies.n; i++) {
        put(&b, "copy_key", "%s", d->copies.v[i].key);
        put(&b, "copy_val", "%s", d->copies.v[i].val);
    }
    put(&b, "end", "%s", "");
    int rc = -1;
    st_error e;
    if (!b.bad && st_file_write_atomic(path, b.p, b.n, &e) == 0)
        rc = 0;
    else
        sts_logf(&cl->srv->log, STS_ERROR, "cluster: could not keep the %s of '%s' in doubt in "
                 "the data dir (%s): a restart before etcd answers again cannot settle it",
                 d->kind == STS_DOUBT_DELETE ? "delete" : "write", d->name,
                 b.bad ? "a value does not fit" : e.msg);
    free(b.p);
    return rc;
}

/* parsing: every key at most once except the repeated ones */
static int get_i64(const char *v, int64_t lo, int64_t hi, int64_t *out)
{
    char *end;
    errno = 0;
    long long x = strtoll(v, &end, 10);
    if (errno || end == v || *end || x < lo || x > hi)
        return -1;
    *out = x;
    return 0;
}

static int copy_str(char *dst, size_t cap, const char *v)
{
    size_t n = strlen(v);
    if (n >= cap)
        return -1;
    memcpy(dst, v, n + 1);
    return 0;
}

static int add_copy(scl_kvs *k, const char *key, const char *val)
{
    scl_kv *v = realloc(k->v, (k->n + 1) * sizeof *v);
    if (!v)
        return -1;
    k->v = v;
    memset(&v[k->n], 0, sizeof v[k->n]);
    v[k->n].key = strdup(key);
    v[k->n].val = strdup(val);
    v[k->n].key_len = strlen(key);
    v[k->n].val_len = strlen(val);
    k->n++;
    return v[k->n - 1].key && v[k->n - 1].val ? 0 : -1;
}

/* d from the file's text (NUL-terminated); why (cap bytes) on failure */
static int parse(sts_cluster *cl, char *text, sts_cl_doubt *d, int64_t *op_rev, char *why,
                 size_t cap)
{
    int seen_end = 0, first = 1;
    char pending_key[SCL_KEY_MAX] = "";
    int have_key = 0;
    for (char *line = text, *next; line && *line && !seen_end; line = next) {
        next = strchr(line, '\n');
        if (!next) {
            snprintf(why, cap, "a line without its end");
            return -1;
        }
        *next++ = 0;
        char *v = strchr(line, ' ');
        if (!v) {
            snprintf(why, cap, "a line without a value");
            return -1;
        }
        *v++ = 0;
        int64_t x = 0;
        int bad = 0;
        if (first) {
            bad = strcmp(line, "seamtex-doubt") || strcmp(v, "1");
            first = 0;
        } else if (!strcmp(line, "node")) {
            if (strcmp(v, cl->self)) {
                snprintf(why, cap, "another node id's");
                return -1;
            }
        } else if (!strcmp(line, "prefix")) {
            if (strcmp(v, cl->prefix)) {
                snprintf(why, cap, "another cluster prefix's");
                return -1;
            }
        } else if (!strcmp(line, "kind")) {
            bad = get_i64(v, STS_DOUBT_CLAIM, STS_DOUBT_RESTORE, &x);
            d->kind = (int)x;
        } else if (!strcmp(line, "applied")) {
            bad = get_i64(v, 0, 1, &x);
            d->applied = (int)x;
        } else if (!strcmp(line, "applied_rev")) {
            bad = get_i64(v, 0, INT64_MAX, &d->applied_rev);
        } else if (!strcmp(line, "op_rev")) {
            bad = get_i64(v, 0, INT64_MAX, op_rev);
        } else if (!strcmp(line, "name")) {
            bad = copy_str(d->name, sizeof d->name, v);
        } else if (!strcmp(line, "tag")) {
            bad = copy_str(d->tag, sizeof d->tag, v);
        } else if (!strcmp(line, "claim_name")) {
            bad = copy_str(d->claim.name, sizeof d->claim.name, v);
        } else if (!strcmp(line, "claim_rec")) {
            bad = scl_setrec_parse(v, &d->claim.rec);
        } else if (!strcmp(line, "claim_rev")) {
            bad = get_i64(v, 0, INT64_MAX, &d->claim.mod_rev);
        } else if (!strcmp(line, "claim_prev")) {
            bad = scl_setrec_parse(v, &d->claim.prev);
            d->claim.had_prev = !bad;
        } else if (!strcmp(line, "claim_repeat")) {
            bad = get_i64(v, 0, 1, &x);
            d->claim.repeat = (int)x;
        } else if (!strcmp(line, "acked")) {
            bad = d->nacked > STS_CL_MAX_HOLDERS ||
                  copy_str(d->acked[d->nacked], sizeof d->acked[0], v);
            d->nacked += !bad;
        } else if (!strcmp(line, "rec")) {
            bad = d->rec != NULL || !(d->rec = strdup(v));
        } else if (!strcmp(line, "copy_key")) {
            bad = have_key || copy_str(pending_key, sizeof pending_key, v);
            have_key = !bad;
        } else if (!strcmp(line, "copy_val")) {
            bad = !have_key || add_copy(&d->copies, pending_key, v);
            have_key = 0;
        } else if (!strcmp(line, "end")) {
            seen_end = 1;
        } else {
            bad = 1;
        }
        if (bad) {
            snprintf(why, cap, "a bad line '%.40s'", line);
            return -1;
        }
    }
    if (!seen_end || have_key || !d->name[0] || !d->tag[0]) {
        snprintf(why, cap, "cut short");
        return -1;
    }
    return 0;
}

void sts_cluster_doubt_load(sts_cluster *cl)
{
    char path[4096];
    if (doubt_path(cl, path, sizeof path) != 0)
        return;
    void *buf = NULL;
    size_t len = 0;
    st_error e;
    int rc = st_file_read(path, DOUBT_CAP, &buf, &len, &e);
    if (rc == ST_ENOTFOUND)
        return;
    sts_cl_doubt *d = calloc(1, sizeof *d);
    int64_t op_rev = 0;
    char why[sizeof e.msg];
    snprintf(why, sizeof why, "%s", rc ? e.msg : !d ? "out of memory" : "a zero byte");
    if (rc == 0 && d && memchr(buf, 0, len) == NULL &&
        parse(cl, buf, d, &op_rev, why, sizeof why) == 0) {
        sts_logf(&cl->srv->log, STS_WARN, "cluster: a write of '%s' was left in doubt by an "
                 "earlier process of this node: settled when etcd answers", d->name);
        /* the fence compares the revision the write compared; a write known to have applied
         * is undone without one, and the op key is read again before the next write */
        cl->op_rev = op_rev;
        cl->op_known = !d->applied;
        sts_cluster_doubt_set(cl, d, 0);
        STS_CL_ADD(cl, writes_in_doubt, 1);
        free(buf);
        return;
    }
    sts_cluster_doubt_free_one(d);
    free(buf);
    sts_logf(&cl->srv->log, STS_ERROR, "cluster: %s: not a write in doubt of this node (%s): "
             "ignored and removed", path, why);
    if (unlink(path) == 0)
        stu_fsync_parent(path);
}
