/* tests/integration/test_upload_checks.c - how seamtexd refuses uploads: the options and the
 * format hint are checked at UPLOAD_BEGIN with the store's one grammar (before any chunk),
 * every refusal is logged with its reason and the peer, and no reply names a server path
 * whatever the import failure; an uploaded mesh opens no file it names (mtllib / map_Kd).
 *
 * One daemon for the group (tests/common/daemon_fixture.h, a temp data dir). Bad files are
 * made in memory from the fixture .ptx or from the shared data (skipped when it is missing).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "proto.h"

#define D ST_GROUP

/* UPLOAD_BEGIN on a raw socket; returns the reply's status, its message in msg. */
static unsigned begin_raw(int fd, const char *name, const char *hint, const char *options,
                          char *msg, size_t cap, uint64_t *id)
{
    static uint32_t reqid = 1;
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(st_wire_upload_begin(&b, reqid++, name, hint, options, 1000, 0, 0), 0);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    stp_buf_free(&b);
    st_wire_reply r;
    assert_int_equal(st_wire_read_reply(fd, &r, 10000), 0);
    size_t n = r.status ? (r.len < cap - 1 ? r.len : cap - 1) : 0;
    memcpy(msg, r.body, n);
    msg[n] = 0;
    if (id && r.status == 0)
        *id = stp_rd64(r.body);
    return r.status;
}

static void bad_options_and_hints_are_invalid_at_begin(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D);
    assert_true(fd >= 0);
    char msg[1100];
    static const struct { const char *hint, *options, *says; } bad[] = {
        {"exr", "cube=latlong:abc", "power of two"},
        {"exr", "cube=latlong:300", "power of two"},
        {"exr", "cube=sideways", "not one of"},
        {"exr", "cube=strip_v:64", "only latlong"},
        {"png", "colorspace=purple", "colorspace"},
        {"obj", "texture=../up", "texture="},
        {"obj", "texture=.hidden", "texture="},
        {"png", "frobnicate=1", "unknown option"},
        {"png", "cube=auto cube=none", "twice"},
        {"png", "cube=auto  colorspace=srgb", "two spaces"},
        {"png", "novalue", "key=value"},
        {"zzz", "", "format hint"},
        {"ptx2", "", "format hint"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        unsigned st = begin_raw(fd, "opt_check", bad[i].hint, bad[i].options, msg, sizeof msg,
                                NULL);
        if (st != STP_S_INVALID || !strstr(msg, bad[i].says))
            fail_msg("hint '%s' options '%s': status %u '%s', want INVALID saying '%s'",
                     bad[i].hint, bad[i].options, st, msg, bad[i].says);
    }
    /* what the grammar allows is accepted at BEGIN (and aborted here) */
    static const struct { const char *hint, *options; } good[] = {
        {"exr", "cube=latlong:256"}, {"png", "colorspace=srgb cube=auto"},
        {"obj", "texture=some.set-1"}, {"", ""}, {"jpeg", ""}, {"penv", "cube=ptex"},
    };
    for (size_t i = 0; i < sizeof good / sizeof good[0]; i++) {
        uint64_t id = 0;
        unsigned st = begin_raw(fd, "opt_check", good[i].hint, good[i].options, msg, sizeof msg,
                                &id);
        if (st != 0)
            fail_msg("hint '%s' options '%s': status %u '%s'", good[i].hint, good[i].options, st,
                     msg);
        stp_buf b;
        stp_buf_init(&b);
        stp_enc_id_req(&b, STP_OP_UPLOAD_ABORT, 900 + (uint32_t)i, 0, id);
        assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
        stp_buf_free(&b);
        st_wire_reply r;
        assert_int_equal(st_wire_read_reply(fd, &r, 10000), 0);
        assert_int_equal(r.status, 0);
    }
    close(fd);
    /* the refusals are in the log at the default level, with the peer and the reason */
    assert_int_equal(st_wait_file_has(D.log, "refused at UPLOAD_BEGIN (INVALID): cube=latlong:300",
                                      10000), 0);
    assert_int_equal(st_wait_file_has(D.log, "from 127.0.0.1:", 10000), 0);
    assert_int_equal(st_wait_file_has(D.log, "format hint 'zzz'", 10000), 0);
}

/* 1 when msg holds a server path: the data dir, the temp dirs, or any token starting '/'. */
static int names_a_path(const char *msg)
{
    const char *tmp = getenv("TMPDIR");
    if (strstr(msg, D.datadir) || strstr(msg, D.dir) || strstr(msg, "/tmp") ||
        (tmp && *tmp && strstr(msg, tmp)) || strstr(msg, ".part"))
        return 1;
    for (const char *p = msg; (p = strchr(p, '/')) != NULL; p++)
        if (p[1] && p[1] != ' ')
            return 1;
    return 0;
}

static void upload_expect_failure(stc_conn *c, const void *data, size_t len, const char *name,
                                  const char *hint, const char *options)
{
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = hint;
    uo.options = options;
    stc_upload_result ur;
    int rc = stc_upload_buffer(c, data, len, name, &uo, &ur);
    const char *msg = stc_errmsg(c);
    if (rc == 0)
        fail_msg("upload %s (%s) succeeded", name, hint);
    if (names_a_path(msg))
        fail_msg("upload %s: the reply names a server path: %s", name, msg);
    if (!strstr(msg, name) && rc != STC_EINVALID)
        fail_msg("upload %s: the reply does not name the set: %s", name, msg);
    printf("# %s: %s: %s\n", name, stc_strerror(rc), msg);
}

static void import_failures_name_no_server_path(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D, NULL);
    assert_non_null(c);
    size_t len = 0;
    uint8_t *ptx = st_fixture_default_ptx(&len, 0);
    assert_non_null(ptx);
    upload_expect_failure(c, ptx, len / 2, "trunc_ptx", "ptx", NULL);
    upload_expect_failure(c, ptx, len / 2, "trunc_ptx_nohint", "", NULL);
    static const uint8_t exr[64] = {0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0, 'x', 'y', 0};
    upload_expect_failure(c, exr, sizeof exr, "bad_exr", "exr", NULL);
    static const char obj[] = "v 0 0 0\nv 1 0 0\nvt 0 0\nf 1/1 2/1 7/1\n";
    upload_expect_failure(c, obj, sizeof obj - 1, "bad_obj", "obj", NULL);
    static const char obj2[] = "mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n"
                               "f 1/1 2/1 3/1\n";
    upload_expect_failure(c, obj2, sizeof obj2 - 1, "obj_no_texture", "obj", NULL);
    upload_expect_failure(c, obj2, sizeof obj2 - 1, "obj_missing_tex", "obj",
                          "texture=not_there");
    upload_expect_failure(c, "garbage!", 8, "garbage", "", NULL);
    char path[1024];
    if (st_test_data_path(path, sizeof path, "meshes/duck/DuckCM.png") == 0) {
        size_t plen = 0;
        uint8_t *png = st_test_read_file(path, &plen);
        assert_non_null(png);
        upload_expect_failure(c, png, plen / 2, "trunc_png", "png", NULL);
        upload_expect_failure(c, png, plen / 2, "trunc_png_nohint", "", NULL);
        free(png);
    }
    if (st_test_data_path(path, sizeof path, "env/StageEnvCube.exr") == 0) {
        size_t elen = 0;
        uint8_t *e = st_test_read_file(path, &elen);
        assert_non_null(e);
        upload_expect_failure(c, e, elen / 3, "trunc_exr", "exr", NULL);
        free(e);
    }
    free(ptx);
    /* every refusal at COMMIT is logged with its reason; the log may keep the path */
    assert_int_equal(st_wait_file_has(D.log, "upload of 'bad_exr' from 127.0.0.1:", 10000), 0);
    assert_int_equal(st_wait_file_has(D.log, "refused at UPLOAD_COMMIT", 10000), 0);
    stc_close(c);
}

static void chunk_refusals_are_logged(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D);
    assert_true(fd >= 0);
    char msg[1100];
    uint64_t id = 0;
    assert_int_equal(begin_raw(fd, "chunky", "ptx", "", msg, sizeof msg, &id), 0);
    stp_buf b;
    stp_buf_init(&b);
    uint8_t data[16] = {0};
    stp_upload_chunk ch = {id, 500, sizeof data, data};   /* not at offset 0 */
    stp_enc_upload_chunk(&b, 77, 0, &ch);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    stp_buf_free(&b);
    st_wire_reply r;
    assert_int_equal(st_wire_read_reply(fd, &r, 10000), 0);
    assert_int_equal(r.status, STP_S_INVALID);
    close(fd);
    assert_int_equal(st_wait_file_has(D.log, "upload of 'chunky' from 127.0.0.1:", 10000), 0);
    assert_int_equal(st_wait_file_has(D.log, "refused at UPLOAD_CHUNK (INVALID): chunk offset 500",
                                      10000), 0);
}

/* An uploaded mesh pairs only with its texture= set: the uploads folder (<data>/tmp/) holds
 * other clients' uploads, so the server follows no mtllib / map_Kd an upload names. A .mtl
 * and an image planted there must not make the mesh an atlas of someone else's image. */
static void an_uploaded_mesh_opens_no_other_file(void **state)
{
    (void)state;
    char png[1024], path[1400];
    if (st_test_data_path(png, sizeof png, "meshes/duck/DuckCM.png") != 0)
        skip();
    size_t plen = 0;
    uint8_t *img = st_test_read_file(png, &plen);
    assert_non_null(img);
    snprintf(path, sizeof path, "%s/tmp/planted.png", D.datadir);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(img, 1, plen, f), plen);
    assert_int_equal(fclose(f), 0);
    free(img);
    snprintf(path, sizeof path, "%s/tmp/planted.mtl", D.datadir);
    f = fopen(path, "wb");
    assert_non_null(f);
    fputs("newmtl m\nmap_Kd planted.png\n", f);
    assert_int_equal(fclose(f), 0);
    stc_conn *c = st_daemon_client(&D, NULL);
    assert_non_null(c);
    static const char obj[] = "mtllib planted.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                              "vt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n";
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "obj";
    stc_upload_result ur;
    int rc = stc_upload_buffer(c, obj, sizeof obj - 1, "planted_mesh", &uo, &ur);
    if (rc == 0)
        fail_msg("a mesh upload was paired with a file in the uploads folder");
    assert_non_null(strstr(stc_errmsg(c), "needs a texture"));
    stc_close(c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(bad_options_and_hints_are_invalid_at_begin),
        cmocka_unit_test(import_failures_name_no_server_path),
        cmocka_unit_test(chunk_refusals_are_logged),
        cmocka_unit_test(an_uploaded_mesh_opens_no_other_file),
    };
    return cmocka_run_group_tests_name("upload_checks", tests, st_group_setup, st_group_teardown);
}
