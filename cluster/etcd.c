/* cluster/etcd.c - etcd v3 JSON gateway client (etcd.h).
 *
 * Owns: the HTTP exchange (one curl easy handle per scl_etcd, reused: keep-alive), building
 * request JSON, the revision watch (etcd.h). Does not own: key meanings, decoding the replies and base64 (etcd_reply.c).
 */
#include <curl/curl.h>
#include <json.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "etcd.h"
#include "etcd_reply.h"

struct scl_etcd {
    CURL *curl;
    char  endpoints[SCL_MAX_ENDPOINTS][128];
    int   nend, cur;            /* cur: the endpoint that answered last */
    int   timeout_ms;
    const int *abort;           /* scl_etcd_set_abort; NULL = none */
    scl_revwatch *revw;         /* scl_etcd_set_revwatch; NULL = none */
    char  prefix[256];
    char  msg[256];
    char *resp; size_t resp_len, resp_cap;
};

/* ---- URL --------------------------------------------------------------------------------- */

static int parse_url(const char *url, char ends[][128], int *nend, char *prefix, size_t pcap,
                     char *err, size_t cap)
{
    const char *p = url;
    if (strncmp(p, "etcd://", 7) != 0) {
        snprintf(err, cap, "cluster URL must start with etcd:// (etcd://HOST:PORT[,HOST:PORT]/PREFIX)");
        return -1;
    }
    p += 7;
    const char *slash = strchr(p, '/');
    if (!slash || slash == p) {
        snprintf(err, cap, "cluster URL needs HOST:PORT and a /PREFIX");
        return -1;
    }
    int n = 0;
    while (p < slash) {
        const char *comma = memchr(p, ',', (size_t)(slash - p));
        const char *end = comma ? comma : slash;
        size_t len = (size_t)(end - p);
        if (len == 0 || len >= 128 || !memchr(p, ':', len) || n == SCL_MAX_ENDPOINTS) {
            snprintf(err, cap, "cluster URL: bad endpoint list (at most %d HOST:PORT, comma-separated)",
                     SCL_MAX_ENDPOINTS);
            return -1;
        }
        if (ends) {
            memcpy(ends[n], p, len);
            ends[n][len] = 0;
        }
        n++;
        p = comma ? comma + 1 : end;
    }
    size_t pl = strlen(slash);
    if (pl < 2 || pl >= pcap || slash[pl - 1] == '/') {
        snprintf(err, cap, "cluster URL: the /PREFIX must be 1..%zu bytes and not end in '/'", pcap - 2);
        return -1;
    }
    for (const char *q = slash; *q; q++)
        if ((unsigned char)*q <= 0x20 || (unsigned char)*q >= 0x7f) {
            snprintf(err, cap, "cluster URL: the prefix must be printable ASCII without spaces");
            return -1;
        }
    memcpy(prefix, slash, pl + 1);
    if (nend)
        *nend = n;
    return 0;
}

int scl_etcd_url_check(const char *url, char *prefix, size_t prefix_cap, char *err, size_t cap)
{
    return parse_url(url, NULL, NULL, prefix, prefix_cap, err, cap);
}

void scl_etcd_global_init(void) { curl_global_init(CURL_GLOBAL_DEFAULT); }

static size_t on_data(char *p, size_t sz, size_t n, void *arg)
{
    scl_etcd *e = arg;
    size_t len = sz * n;
    if (e->resp_len + len + 1 > e->resp_cap) {
        size_t cap = (e->resp_len + len + 1) * 2;
        if (cap > (256u << 20))
            return 0;   /* refuse a reply over 256 MiB: the transfer fails */
        char *q = realloc(e->resp, cap);
        if (!q)
            return 0;
        e->resp = q;
        e->resp_cap = cap;
    }
    memcpy(e->resp + e->resp_len, p, len);
    e->resp_len += len;
    e->resp[e->resp_len] = 0;
    return len;
}

scl_etcd *scl_etcd_open(const char *url, int timeout_ms, char *err, size_t cap)
{
    scl_etcd *e = calloc(1, sizeof *e);
    if (!e) {
        snprintf(err, cap, "out of memory");
        return NULL;
    }
    if (parse_url(url, e->endpoints, &e->nend, e->prefix, sizeof e->prefix, err, cap) != 0) {
        free(e);
        return NULL;
    }
    e->timeout_ms = timeout_ms > 0 ? timeout_ms : 2000;
    e->curl = curl_easy_init();
    if (!e->curl) {
        snprintf(err, cap, "curl_easy_init failed");
        free(e);
        return NULL;
    }
    return e;
}

void scl_etcd_close(scl_etcd *e)
{
    if (!e)
        return;
    curl_easy_cleanup(e->curl);
    free(e->resp);
    free(e);
}

void scl_etcd_set_abort(scl_etcd *e, const int *flag) { e->abort = flag; }

void scl_etcd_set_revwatch(scl_etcd *e, scl_revwatch *w) { e->revw = w; }

void scl_revwatch_seed(scl_revwatch *w, int64_t rev)
{
    int64_t t = __atomic_load_n(&w->top, __ATOMIC_ACQUIRE);
    while (rev > t && !__atomic_compare_exchange_n(&w->top, &t, rev, 0, __ATOMIC_ACQ_REL,
                                                   __ATOMIC_ACQUIRE))
        ;
}

int64_t scl_revwatch_top(scl_revwatch *w) { return __atomic_load_n(&w->top, __ATOMIC_ACQUIRE); }

int scl_revwatch_back(scl_revwatch *w, int64_t *from, int64_t *to)
{
    *from = __atomic_load_n(&w->back_from, __ATOMIC_ACQUIRE);
    *to = __atomic_load_n(&w->back_to, __ATOMIC_ACQUIRE);
    return *from != 0;
}

void scl_revwatch_reset(scl_revwatch *w, int64_t rev)
{
    __atomic_add_fetch(&w->gen, 1, __ATOMIC_ACQ_REL);
    __atomic_store_n(&w->top, rev, __ATOMIC_RELEASE);
    __atomic_store_n(&w->back_from, 0, __ATOMIC_RELEASE);
    __atomic_store_n(&w->back_to, 0, __ATOMIC_RELEASE);
}

/* a kv reply at revision rev to a request sent when the watch held top0 (generation gen0) */
static void revwatch_note(scl_revwatch *w, int64_t top0, uint64_t gen0, int64_t rev)
{
    if (rev <= 0)
        return;
    if (rev < top0 && __atomic_load_n(&w->gen, __ATOMIC_ACQUIRE) == gen0) {
        int64_t f = __atomic_load_n(&w->back_from, __ATOMIC_ACQUIRE);
        while (top0 > f && !__atomic_compare_exchange_n(&w->back_from, &f, top0, 0,
                                                        __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE))
            ;
        __atomic_store_n(&w->back_to, rev, __ATOMIC_RELEASE);
        return;   /* the top stays: later replies below it went back too */
    }
    scl_revwatch_seed(w, rev);
}

static int aborted(const scl_etcd *e)
{
    return e->abort && __atomic_load_n(e->abort, __ATOMIC_RELAXED);
}

/* libcurl's progress callback: nonzero ends the transfer (CURLE_ABORTED_BY_CALLBACK) */
static int on_progress(void *arg, curl_off_t dltotal, curl_off_t dlnow, curl_off_t ultotal,
                       curl_off_t ulnow)
{
    (void)dltotal, (void)dlnow, (void)ultotal, (void)ulnow;
    return aborted(arg);
}

const char *scl_etcd_prefix(const scl_etcd *e) { return e->prefix; }
const char *scl_etcd_errmsg(const scl_etcd *e) { return e->msg; }

/* ---- HTTP ------------------------------------------------------------------------------------ */

/* POSTs body to path on the current endpoint, then the others; parses the reply into *out. */
static int post(scl_etcd *e, const char *path, json_object *body, json_object **out)
{
    *out = NULL;
    const char *js = json_object_to_json_string_ext(body, JSON_C_TO_STRING_PLAIN);
    struct curl_slist *hdr = curl_slist_append(NULL, "Content-Type: application/json");
    int rc = SCL_EUNREACHABLE;
    /* the revision watch: kv calls only (etcd.h); gen before top, so that a reset between
     * the two reads is seen as one */
    scl_revwatch *w = e->revw && !strncmp(path, "/v3/kv/", 7) ? e->revw : NULL;
    uint64_t gen0 = w ? __atomic_load_n(&w->gen, __ATOMIC_ACQUIRE) : 0;
    int64_t top0 = w ? scl_revwatch_top(w) : 0;
    for (int t = 0; t < e->nend; t++) {
        int k = (e->cur + t) % e->nend;
        if (aborted(e)) {
            snprintf(e->msg, sizeof e->msg, "etcd %s%s: not asked: stopping", e->endpoints[k], path);
            rc = SCL_ECANCELED;
            break;
        }
        char url[256];
        snprintf(url, sizeof url, "http://%s%s", e->endpoints[k], path);
        e->resp_len = 0;
        if (e->resp)
            e->resp[0] = 0;
        curl_easy_reset(e->curl);
        curl_easy_setopt(e->curl, CURLOPT_URL, url);
        curl_easy_setopt(e->curl, CURLOPT_POSTFIELDS, js);
        curl_easy_setopt(e->curl, CURLOPT_HTTPHEADER, hdr);
        curl_easy_setopt(e->curl, CURLOPT_WRITEFUNCTION, on_data);
        curl_easy_setopt(e->curl, CURLOPT_WRITEDATA, e);
        curl_easy_setopt(e->curl, CURLOPT_TIMEOUT_MS, (long)e->timeout_ms);
        curl_easy_setopt(e->curl, CURLOPT_CONNECTTIMEOUT_MS, (long)e->timeout_ms);
        curl_easy_setopt(e->curl, CURLOPT_NOSIGNAL, 1L);
        if (e->abort) {
            curl_easy_setopt(e->curl, CURLOPT_XFERINFOFUNCTION, on_progress);
            curl_easy_setopt(e->curl, CURLOPT_XFERINFODATA, e);
            curl_easy_setopt(e->curl, CURLOPT_NOPROGRESS, 0L);
        }
        CURLcode cc = curl_easy_perform(e->curl);
        if (cc != CURLE_OK) {
            snprintf(e->msg, sizeof e->msg, "etcd %s: %s", e->endpoints[k], curl_easy_strerror(cc));
            if (cc == CURLE_ABORTED_BY_CALLBACK) {
                rc = SCL_ECANCELED;
                break;
            }
            continue;
        }
        long code = 0;
        curl_easy_getinfo(e->curl, CURLINFO_RESPONSE_CODE, &code);
        json_object *j = e->resp ? json_tokener_parse(e->resp) : NULL;
        if (code == 200 && j && !json_object_is_type(j, json_type_object)) {
            snprintf(e->msg, sizeof e->msg, "etcd %s%s: the reply is not a JSON object: %.120s",
                     e->endpoints[k], path, e->resp);
            json_object_put(j);
            rc = SCL_EBADREPLY;
            break;
        }
        if (code != 200 || !j) {
            snprintf(e->msg, sizeof e->msg, "etcd %s%s: HTTP %ld: %.120s", e->endpoints[k], path,
                     code, e->resp ? e->resp : "");
            json_object_put(j);
            /* a 5xx (no leader) is as good as unreachable: try the next endpoint */
            if (code >= 500 || code == 0)
                continue;
            rc = SCL_EBADREPLY;
            break;
        }
        e->cur = k;
        *out = j;
        if (w)
            revwatch_note(w, top0, gen0, scl_reply_header_revision(j));
        rc = SCL_OK;
        break;
    }
    curl_slist_free_all(hdr);
    return rc;
}

static void add_b64(json_object *o, const char *field, const char *s, size_t n)
{
    char *b = scl_b64_enc(s, n);
    json_object_object_add(o, field, json_object_new_string(b ? b : ""));
    free(b);
}

/* the end of the range of keys starting with key: key with its last byte + 1 */
static void add_prefix_end(json_object *o, const char *key)
{
    size_t n = strlen(key);
    char *end = malloc(n + 1);
    if (!end)
        return;
    memcpy(end, key, n + 1);
    if (n)
        end[n - 1] = (char)(end[n - 1] + 1);
    add_b64(o, "range_end", end, n);
    free(end);
}

int scl_etcd_range(scl_etcd *e, const char *key, int prefix, scl_kvs *out)
{
    return scl_etcd_range_at(e, key, prefix, 0, out);
}

int scl_etcd_range_at(scl_etcd *e, const char *key, int prefix, int64_t rev, scl_kvs *out)
{
    memset(out, 0, sizeof *out);
    json_object *rq = json_object_new_object(), *r = NULL;
    add_b64(rq, "key", key, strlen(key));
    if (prefix)
        add_prefix_end(rq, key);
    if (rev > 0)
        json_object_object_add(rq, "revision", json_object_new_int64(rev));
    int rc = post(e, "/v3/kv/range", rq, &r);
    json_object_put(rq);
    if (rc == SCL_OK)
        rc = scl_reply_range(r, out, e->msg, sizeof e->msg);
    json_object_put(r);
    return rc;
}

static json_object *put_req(const char *key, const char *val, int64_t lease)
{
    json_object *rq = json_object_new_object();
    add_b64(rq, "key", key, strlen(key));
    add_b64(rq, "value", val, strlen(val));
    if (lease)
        json_object_object_add(rq, "lease", json_object_new_int64(lease));
    return rq;
}

static json_object *del_req(const char *key, int prefix)
{
    json_object *rq = json_object_new_object();
    add_b64(rq, "key", key, strlen(key));
    if (prefix)
        add_prefix_end(rq, key);
    return rq;
}

int scl_etcd_put(scl_etcd *e, const char *key, const char *val, int64_t lease)
{
    json_object *rq = put_req(key, val, lease), *r = NULL;
    int rc = post(e, "/v3/kv/put", rq, &r);
    json_object_put(rq);
    json_object_put(r);
    return rc;
}

int scl_etcd_delete(scl_etcd *e, const char *key, int prefix)
{
    json_object *rq = del_req(key, prefix), *r = NULL;
    int rc = post(e, "/v3/kv/deleterange", rq, &r);
    json_object_put(rq);
    json_object_put(r);
    return rc;
}

int scl_etcd_grant(scl_etcd *e, int64_t ttl_s, int64_t *lease)
{
    json_object *rq = json_object_new_object(), *r = NULL;
    json_object_object_add(rq, "TTL", json_object_new_int64(ttl_s));
    int rc = post(e, "/v3/lease/grant", rq, &r);
    json_object_put(rq);
    if (rc == SCL_OK)
        rc = scl_reply_grant(r, lease, e->msg, sizeof e->msg);
    json_object_put(r);
    return rc;
}

int scl_etcd_keepalive(scl_etcd *e, int64_t lease, int64_t *ttl)
{
    json_object *rq = json_object_new_object(), *r = NULL;
    json_object_object_add(rq, "ID", json_object_new_int64(lease));
    int rc = post(e, "/v3/lease/keepalive", rq, &r);
    json_object_put(rq);
    *ttl = 0;
    if (rc == SCL_OK)
        rc = scl_reply_keepalive(r, ttl, e->msg, sizeof e->msg);
    json_object_put(r);
    return rc;
}

int scl_etcd_txn(scl_etcd *e, const scl_cmp *cmp, size_t ncmp, const scl_op *ops, size_t nops,
                 int *succeeded, int64_t *revision)
{
    json_object *rq = json_object_new_object(), *r = NULL;
    json_object *ca = json_object_new_array(), *sa = json_object_new_array();
    for (size_t i = 0; i < ncmp; i++) {
        json_object *c = json_object_new_object();
        add_b64(c, "key", cmp[i].key, strlen(cmp[i].key));
        json_object_object_add(c, "result", json_object_new_string("EQUAL"));
        int create = cmp[i].target == SCL_CMP_CREATE;
        json_object_object_add(c, "target", json_object_new_string(create ? "CREATE" : "MOD"));
        json_object_object_add(c, create ? "create_revision" : "mod_revision",
                               json_object_new_int64(cmp[i].rev));
        json_object_array_add(ca, c);
    }
    for (size_t i = 0; i < nops; i++) {
        json_object *o = json_object_new_object();
        if (ops[i].type == SCL_OP_PUT)
            json_object_object_add(o, "request_put", put_req(ops[i].key, ops[i].val, ops[i].lease));
        else
            json_object_object_add(o, "request_delete_range",
                                   del_req(ops[i].key, ops[i].type == SCL_OP_DEL_PREFIX));
        json_object_array_add(sa, o);
    }
    json_object_object_add(rq, "compare", ca);
    json_object_object_add(rq, "success", sa);
    int rc = post(e, "/v3/kv/txn", rq, &r);
    json_object_put(rq);
    *succeeded = 0;
    if (revision)
        *revision = 0;
    if (rc == SCL_OK)
        rc = scl_reply_txn(r, succeeded, revision, e->msg, sizeof e->msg);
    json_object_put(r);
    return rc;
}
