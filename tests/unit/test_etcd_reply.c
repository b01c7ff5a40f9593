/* tests/unit/test_etcd_reply.c - the decoders of what etcd sends back (cluster/etcd_reply.c)
 * and of the records kept in it (cluster/catalog.c), on replies as etcd 3.4's gateway writes
 * them and on the hostile or broken ones that must be refused with a message rather than read
 * as zeros: a reply that is not an object, an int64 that is not a decimal string, a negative
 * revision, a kv without a key, a copy record strtoul alone would take (" -1", "0x..").
 * Also the header revision any reply carries (the revision watch of etcd.c: absent or broken
 * is 0, never a guess) and the watch's seed and reset.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "catalog.h"
#include "etcd_reply.h"

static int range(const char *text, scl_kvs *kvs, char *msg, size_t cap)
{
    json_object *j = json_tokener_parse(text);
    assert_non_null(j);
    msg[0] = 0;
    int rc = scl_reply_range(j, kvs, msg, cap);
    json_object_put(j);
    return rc;
}

static void a_range_reply_decodes(void **state)
{
    (void)state;
    /* key "/p/nodes/n1" and value "{\"addr\":\"h:1\"}" in base64, as etcd writes them */
    char *k = scl_b64_enc("/p/nodes/n1", 11), *v = scl_b64_enc("{\"addr\":\"h:1\"}", 14);
    char text[512], msg[256];
    snprintf(text, sizeof text,
             "{\"header\":{\"revision\":\"12\"},\"kvs\":[{\"key\":\"%s\",\"create_revision\":\"5\","
             "\"mod_revision\":\"7\",\"version\":\"2\",\"value\":\"%s\",\"lease\":\"9\"},"
             "{\"key\":\"%s\"}],\"count\":\"2\"}", k, v, k);
    scl_kvs kvs;
    assert_int_equal(range(text, &kvs, msg, sizeof msg), SCL_OK);
    assert_int_equal(kvs.revision, 12);
    assert_int_equal(kvs.n, 2);
    assert_int_equal(kvs.v[0].key_len, 11);
    assert_string_equal(kvs.v[0].key, "/p/nodes/n1");
    assert_string_equal(kvs.v[0].val, "{\"addr\":\"h:1\"}");
    assert_int_equal(kvs.v[0].create_rev, 5);
    assert_int_equal(kvs.v[0].mod_rev, 7);
    assert_int_equal(kvs.v[0].version, 2);
    assert_int_equal(kvs.v[0].lease, 9);
    /* proto3 leaves defaults out: an absent value is empty, absent numbers are 0 */
    assert_int_equal(kvs.v[1].val_len, 0);
    assert_string_equal(kvs.v[1].val, "");
    assert_int_equal(kvs.v[1].mod_rev, 0);
    scl_kvs_free(&kvs);
    free(k);
    free(v);
    assert_int_equal(range("{\"header\":{\"revision\":\"3\"}}", &kvs, msg, sizeof msg), SCL_OK);
    assert_int_equal(kvs.n, 0);
    assert_int_equal(kvs.revision, 3);
    scl_kvs_free(&kvs);
}

static void a_broken_range_reply_is_refused(void **state)
{
    (void)state;
    static const char *bad[] = {
        "[]",                                              /* not an object */
        "5",
        "{\"header\":[]}",                                 /* header not an object */
        "{\"header\":{\"revision\":\"12x\"}}",              /* not a decimal string */
        "{\"header\":{\"revision\":\"\"}}",
        "{\"header\":{\"revision\":\"-3\"}}",               /* a negative revision */
        "{\"header\":{\"revision\":\"99999999999999999999\"}}",   /* past int64 */
        "{\"header\":{\"revision\":1.5}}",
        "{\"kvs\":{}}",                                     /* kvs not an array */
        "{\"kvs\":[1]}",                                    /* a kv not an object */
        "{\"kvs\":[{\"value\":\"YQ==\"}]}",                 /* no key */
        "{\"kvs\":[{\"key\":\"\"}]}",                       /* an empty key */
        "{\"kvs\":[{\"key\":\"YQ=\"}]}",                    /* not base64 */
        "{\"kvs\":[{\"key\":5}]}",
        "{\"kvs\":[{\"key\":\"YQ==\",\"value\":\"Y\\u0000==\"}]}",
        "{\"kvs\":[{\"key\":\"YQ==\"},{\"key\":\"YQ==\",\"mod_revision\":\"x\"}]}",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        scl_kvs kvs;
        char msg[256];
        int rc = range(bad[i], &kvs, msg, sizeof msg);
        if (rc != SCL_EBADREPLY)
            fail_msg("accepted: %s", bad[i]);
        assert_true(msg[0] != 0);
        assert_int_equal(kvs.n, 0);
        assert_null(kvs.v);
    }
}

static void lease_and_txn_replies(void **state)
{
    (void)state;
    char msg[256];
    int64_t v = -1;
    int ok = -1;
    json_object *j = json_tokener_parse("{\"header\":{},\"ID\":\"7587862072446578443\",\"TTL\":\"10\"}");
    assert_int_equal(scl_reply_grant(j, &v, msg, sizeof msg), SCL_OK);
    assert_true(v == 7587862072446578443LL);
    json_object_put(j);
    j = json_tokener_parse("{\"ID\":\"0x10\"}");
    assert_int_equal(scl_reply_grant(j, &v, msg, sizeof msg), SCL_EBADREPLY);
    assert_int_equal(v, 0);
    json_object_put(j);
    j = json_tokener_parse("{\"result\":{\"ID\":\"1\"}}");   /* expired: TTL left out */
    assert_int_equal(scl_reply_keepalive(j, &v, msg, sizeof msg), SCL_OK);
    assert_int_equal(v, 0);
    json_object_put(j);
    j = json_tokener_parse("{\"result\":{\"TTL\":\"ten\"}}");
    assert_int_equal(scl_reply_keepalive(j, &v, msg, sizeof msg), SCL_EBADREPLY);
    json_object_put(j);
    j = json_tokener_parse("{\"error\":\"x\"}");
    assert_int_equal(scl_reply_keepalive(j, &v, msg, sizeof msg), SCL_EBADREPLY);
    json_object_put(j);
    j = json_tokener_parse("{\"header\":{\"revision\":\"44\"},\"succeeded\":true}");
    assert_int_equal(scl_reply_txn(j, &ok, &v, msg, sizeof msg), SCL_OK);
    assert_int_equal(ok, 1);
    assert_int_equal(v, 44);
    json_object_put(j);
    j = json_tokener_parse("{\"header\":{\"revision\":\"45\"}}");   /* false is left out */
    assert_int_equal(scl_reply_txn(j, &ok, &v, msg, sizeof msg), SCL_OK);
    assert_int_equal(ok, 0);
    json_object_put(j);
    j = json_tokener_parse("{\"succeeded\":\"true\"}");
    assert_int_equal(scl_reply_txn(j, &ok, &v, msg, sizeof msg), SCL_EBADREPLY);
    assert_int_equal(ok, 0);
    json_object_put(j);
}

/* the revision watch's input (etcd.c): header.revision of any reply, 0 when absent or not a
 * non-negative int64 - never a guess; and the watch's seed / reset */
static void the_header_revision_and_the_watch(void **state)
{
    (void)state;
    static const struct { const char *text; int64_t rev; } cases[] = {
        {"{\"header\":{\"revision\":\"322\"},\"kvs\":[]}", 322},
        {"{\"header\":{\"revision\":17}}", 17},
        {"{\"header\":{}}", 0},
        {"{}", 0},
        {"{\"header\":{\"revision\":\"-5\"}}", 0},
        {"{\"header\":{\"revision\":\"12x\"}}", 0},
        {"{\"header\":\"no\"}", 0},
        {"[1]", 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        json_object *j = json_tokener_parse(cases[i].text);
        assert_non_null(j);
        assert_int_equal(scl_reply_header_revision(j), cases[i].rev);
        json_object_put(j);
    }
    scl_revwatch w = {0};
    int64_t from, to;
    scl_revwatch_seed(&w, 40);
    scl_revwatch_seed(&w, 30);   /* never lowers */
    assert_int_equal(scl_revwatch_top(&w), 40);
    assert_int_equal(scl_revwatch_back(&w, &from, &to), 0);
    w.back_from = 40, w.back_to = 12;   /* as a reply below 40 leaves it */
    assert_int_equal(scl_revwatch_back(&w, &from, &to), 1);
    assert_int_equal(from, 40);
    assert_int_equal(to, 12);
    scl_revwatch_reset(&w, 13);   /* the catalogue adopted: its revision is the top */
    assert_int_equal(scl_revwatch_top(&w), 13);
    assert_int_equal(scl_revwatch_back(&w, &from, &to), 0);
    assert_int_equal(w.gen, 1);
}

static void records_are_checked(void **state)
{
    (void)state;
    uint32_t crc = 0;
    assert_int_equal(scl_copy_parse("0a1B2c3d", &crc), 0);
    assert_true(crc == 0x0a1b2c3du);
    /* what strtoul alone takes: a sign, blanks, a 0x */
    assert_int_equal(scl_copy_parse("-0000001", &crc), -1);
    assert_int_equal(scl_copy_parse(" 1234567", &crc), -1);
    assert_int_equal(scl_copy_parse("+1234567", &crc), -1);
    assert_int_equal(scl_copy_parse("0x123456", &crc), -1);
    assert_int_equal(scl_copy_parse("123456789", &crc), -1);
    char addr[64];
    uint64_t inc;
    assert_int_equal(scl_node_parse("{\"addr\":\"h:1\",\"inc\":\"00000000000000ff\"}", addr,
                                    sizeof addr, &inc), 0);
    assert_string_equal(addr, "h:1");
    assert_true(inc == 255);
    /* a NUL inside a JSON string would cut it short unseen */
    assert_int_equal(scl_node_parse("{\"addr\":\"h:1\\u0000x\"}", addr, sizeof addr, &inc), -1);
    scl_setrec r;
    assert_int_equal(scl_setrec_parse("{\"crc32c\":1,\"crc32\":2,\"size\":3,\"fmt\":\"ptx\","
                                      "\"options\":\"\",\"version\":1,\"state\":\"ok\","
                                      "\"origin\":\"a\",\"kind\":1}", &r), 0);
    assert_string_equal(r.fmt, "ptx");
    assert_int_equal(scl_setrec_parse("{\"crc32c\":1,\"crc32\":2,\"size\":3,\"fmt\":\"p\\u0000ng\","
                                      "\"options\":\"\",\"version\":1,\"state\":\"ok\","
                                      "\"origin\":\"a\",\"kind\":1}", &r), -1);
}

static void base64_round_trips(void **state)
{
    (void)state;
    const char bytes[] = "\0\x01\xff/seamtex/sets/x";
    for (size_t n = 0; n < sizeof bytes; n++) {
        char *e = scl_b64_enc(bytes, n);
        size_t m = 99;
        char *d = scl_b64_dec(e, &m);
        assert_non_null(d);
        assert_int_equal(m, n);
        assert_memory_equal(d, bytes, n);
        free(d);
        free(e);
    }
    size_t m;
    assert_null(scl_b64_dec("YQ=a", &m));
    assert_null(scl_b64_dec("Y===", &m));
    assert_null(scl_b64_dec("YQ==YQ==", &m));
    assert_null(scl_b64_dec("Y Q=", &m));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_range_reply_decodes),
        cmocka_unit_test(a_broken_range_reply_is_refused),
        cmocka_unit_test(lease_and_txn_replies),
        cmocka_unit_test(the_header_revision_and_the_watch),
        cmocka_unit_test(records_are_checked),
        cmocka_unit_test(base64_round_trips),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
