/* tests/fuzz/fuzz_etcd.c - libFuzzer target for what seamtexd and libseamtex_etcd read from
 * etcd: the v3 JSON gateway's replies (cluster/etcd_reply.c: range, lease grant, keepalive,
 * txn; base64 keys and values) and the records kept in the values (cluster/catalog.c: node,
 * set and copy records), plus the etcd:// URL grammar (cluster/etcd.c). The first byte picks
 * the parser, the rest (cut at its first NUL) is the text. Invariants:
 *   - an error always comes with a message, and a failed range leaves no keys behind;
 *   - a range that decodes gives non-empty NUL-terminated keys of key_len bytes, values of
 *     val_len bytes, no negative revision; base64 round-trips (dec(enc(x)) == x); each value
 *     also goes through the three record parsers;
 *   - a record that parses formats back and parses again to the same fields; a copy record
 *     is exactly 8 hex digits;
 *   - a URL that checks gives a prefix that starts with '/' and does not end with one.
 * The fuzz build links only the store and protocol objects, so the cluster sources are
 * compiled into this target directly (with json-c and libcurl). Seeds:
 * tests/fuzz/seeds/fuzz_etcd/. */
#include "../../cluster/catalog.c"
#include "../../cluster/etcd.c"
#include "../../cluster/etcd_reply.c"

#include <stdint.h>

/* an invariant: on failure, names it and stops (libFuzzer keeps the input) */
#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void b64_roundtrip(const char *s, size_t n)
{
    char *e = scl_b64_enc(s, n);
    CHECK(e != NULL);
    size_t m = 0;
    char *d = scl_b64_dec(e, &m);
    CHECK(d != NULL && m == n && !memcmp(d, s, n) && d[n] == 0);
    free(d);
    free(e);
}

static void check_records(const char *val)
{
    char addr[STP_MAX_NODE_ADDR + 1], buf[4096];
    uint64_t inc = 0;
    if (scl_node_parse(val, addr, sizeof addr, &inc) == 0) {
        CHECK(addr[0] && strchr(addr, ':'));
        char addr2[sizeof addr];
        uint64_t inc2 = 1;
        CHECK(scl_node_format(buf, sizeof buf, addr, inc) == 0);
        CHECK(scl_node_parse(buf, addr2, sizeof addr2, &inc2) == 0);
        CHECK(!strcmp(addr, addr2) && inc == inc2);
    }
    scl_setrec r, r2;
    if (scl_setrec_parse(val, &r) == 0) {
        CHECK(r.version >= 1 && r.kind >= -1 && r.kind <= 255);
        CHECK(r.state == SCL_SET_OK || r.state == SCL_SET_PENDING);
        CHECK(scl_setrec_format(buf, sizeof buf, &r) == 0);
        CHECK(scl_setrec_parse(buf, &r2) == 0);
        CHECK(r.crc32c == r2.crc32c && r.crc32 == r2.crc32 && r.size == r2.size &&
              r.version == r2.version && r.state == r2.state && r.kind == r2.kind &&
              r.inc == r2.inc && !strcmp(r.fmt, r2.fmt) && !strcmp(r.options, r2.options) &&
              !strcmp(r.origin, r2.origin));
    }
    uint32_t crc;
    if (scl_copy_parse(val, &crc) == 0) {
        char hex[9];
        scl_copy_format(hex, crc);
        CHECK(strlen(val) == 8 && !strcasecmp(hex, val));
    }
}

static void fuzz_range(json_object *j)
{
    scl_kvs kvs;
    char msg[256] = "";
    int rc = scl_reply_range(j, &kvs, msg, sizeof msg);
    CHECK(rc == SCL_OK || rc == SCL_EBADREPLY || rc == SCL_ENOMEM);
    if (rc != SCL_OK) {
        CHECK(msg[0] && kvs.n == 0 && kvs.v == NULL);
        return;
    }
    CHECK(kvs.revision >= 0);
    for (size_t i = 0; i < kvs.n; i++) {
        scl_kv *kv = &kvs.v[i];
        CHECK(kv->key && kv->val && kv->key_len > 0);
        CHECK(kv->key[kv->key_len] == 0 && kv->val[kv->val_len] == 0);
        CHECK(kv->create_rev >= 0 && kv->mod_rev >= 0 && kv->version >= 0 && kv->lease >= 0);
        b64_roundtrip(kv->key, kv->key_len);
        b64_roundtrip(kv->val, kv->val_len);
        check_records(kv->val);
    }
    scl_kvs_free(&kvs);
    CHECK(kvs.n == 0 && kvs.v == NULL);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    int which = data[0] % 8;
    char *text = malloc(size);
    if (!text)
        return 0;
    memcpy(text, data + 1, size - 1);
    text[size - 1] = 0;
    char msg[256] = "";
    json_object *j = which <= 3 ? json_tokener_parse(text) : NULL;
    if (which <= 3 && !j) {
        free(text);
        return 0;            /* etcd.c refuses a reply that is not JSON before any decoder */
    }
    switch (which) {
    case 0:
        fuzz_range(j);
        break;
    case 1: {
        int64_t lease = -1;
        int rc = scl_reply_grant(j, &lease, msg, sizeof msg);
        CHECK(rc == SCL_OK ? lease > 0 : (msg[0] && lease == 0));
        break;
    }
    case 2: {
        int64_t ttl = -1;
        int rc = scl_reply_keepalive(j, &ttl, msg, sizeof msg);
        CHECK(rc == SCL_OK ? ttl >= 0 : (msg[0] && ttl == 0));
        break;
    }
    case 3: {
        int ok = -1;
        int64_t rev = -1;
        int rc = scl_reply_txn(j, &ok, &rev, msg, sizeof msg);
        CHECK(rc == SCL_OK ? (ok == 0 || ok == 1) && rev >= 0 : (msg[0] != 0 && ok == 0));
        break;
    }
    case 7: {
        char prefix[256];
        if (scl_etcd_url_check(text, prefix, sizeof prefix, msg, sizeof msg) == 0) {
            size_t n = strlen(prefix);
            CHECK(n >= 2 && prefix[0] == '/' && prefix[n - 1] != '/');
        } else {
            CHECK(msg[0]);
        }
        break;
    }
    default:
        check_records(text);
        break;
    }
    json_object_put(j);
    free(text);
    return 0;
}
