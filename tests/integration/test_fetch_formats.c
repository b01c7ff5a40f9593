/* tests/integration/test_fetch_formats.c - FETCH of every set kind: a cube (from an EXR cube)
 * and an OBJ atlas (mesh + PNG image) are fetched in every format that fits them, the fetched
 * files are uploaded back under new names and sampled at the same queries as the originals:
 * identical values; an EXR fetched twice a second apart is the same bytes. A format that
 * does not fit is UNSUPPORTED naming the ones that do. Open fetches count against max-memory
 * and conn-fetch-cap: a connection that opens fetches without closing them is refused (BUSY),
 * the daemon's fetch memory stays under the cap, and closing fetches frees the room.
 *
 * Daemons on 127.0.0.1 port 0 (tests/common/daemon_fixture.h). Needs SEAMTEX_DATA
 * (env/StageEnvCube.exr, meshes/duck/Duck.obj + DuckCM.png); skipped without it.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "proto.h"

#define D ST_GROUP

static const char *const EXT[5] = {"ptx", "dds", "exr", "png", "obj"};

static void upload(stc_conn *c, const char *path, const char *name, const char *options)
{
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.options = options;
    uo.flags = STC_UPLOAD_REPLACE;
    stc_upload_result ur;
    int rc = stc_upload_file(c, path, name, &uo, &ur);
    if (rc)
        fail_msg("upload %s as %s: %s: %s", path, name, stc_strerror(rc), stc_errmsg(c));
}

/* Fetches set in every format into dir/<set>.<ext>; returns the bit set of those that
 * worked and checks the others were UNSUPPORTED naming the formats that fit. */
static unsigned fetch_all(stc_conn *c, const char *set, const char *dir)
{
    unsigned ok = 0;
    for (unsigned f = 0; f < 5; f++) {
        char path[600];
        snprintf(path, sizeof path, "%s/%s.%s", dir, set, EXT[f]);
        int rc = stc_fetch_file(c, set, STC_FETCH_AUTO, path, NULL, NULL);
        if (rc == 0) {
            ok |= 1u << f;
            continue;
        }
        if (rc != STC_EUNSUPPORTED || !strstr(stc_errmsg(c), "it can be as:") ||
            !strstr(stc_errmsg(c), set))
            fail_msg("fetch %s as %s: %s: %s", set, EXT[f], stc_strerror(rc), stc_errmsg(c));
    }
    return ok;
}

static void same_dir_samples(stc_conn *c, const char *a, const char *b)
{
    enum { N = 200 };
    stc_dir_query q[N];
    memset(q, 0, sizeof q);
    for (int i = 0; i < N; i++) {
        float t = (float)i * 0.37f;
        q[i].dir[0] = (float)(i % 7) - 3.1f + 0.3f * (float)__builtin_sinf(t);
        q[i].dir[1] = (float)(i % 5) - 2.05f;
        q[i].dir[2] = (float)(i % 3) - 1.02f + 0.2f * (float)__builtin_cosf(t);
    }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 1;
    stc_sample_result r;
    assert_int_equal(stc_sample_dir(c, a, &o, q, N, &r), 0);
    size_t bytes = (size_t)N * r.nchan * 4;
    float *keep = malloc(bytes);
    memcpy(keep, r.values, bytes);
    unsigned nchan = r.nchan;
    assert_int_equal(stc_sample_dir(c, b, &o, q, N, &r), 0);
    assert_int_equal(r.nchan, nchan);
    if (memcmp(keep, r.values, bytes))
        fail_msg("SAMPLE_DIR of %s and %s differ", a, b);
    free(keep);
}

static void same_uv_samples(stc_conn *c, const char *a, const char *b, unsigned filter)
{
    enum { N = 300 };
    stc_query q[N];
    memset(q, 0, sizeof q);
    for (int i = 0; i < N; i++) {
        q[i].face = 0;
        q[i].u = (float)((i * 37) % 101) / 100.0f;
        q[i].v = (float)((i * 53) % 97) / 96.0f;
        q[i].dudx = q[i].dvdy = (float)(i % 4) * 0.004f;
    }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = filter;
    stc_sample_result r;
    int rc = stc_sample(c, a, &o, q, N, &r);
    if (rc)
        fail_msg("sample %s: %s: %s", a, stc_strerror(rc), stc_errmsg(c));
    size_t bytes = (size_t)N * r.nchan * 4;
    float *keep = malloc(bytes);
    memcpy(keep, r.values, bytes);
    unsigned nchan = r.nchan;
    rc = stc_sample(c, b, &o, q, N, &r);
    if (rc)
        fail_msg("sample %s: %s: %s", b, stc_strerror(rc), stc_errmsg(c));
    assert_int_equal(r.nchan, nchan);
    if (memcmp(keep, r.values, bytes))
        fail_msg("SAMPLE of %s and %s differ (filter %u)", a, b, filter);
    free(keep);
}

static void every_set_kind_fetches_and_uploads_back(void **state)
{
    (void)state;
    char cube[1024], obj[1024], png[1024], dir[600], p[700];
    if (st_test_data_path(cube, sizeof cube, "env/StageEnvCube.exr") ||
        st_test_data_path(obj, sizeof obj, "meshes/duck/Duck.obj") ||
        st_test_data_path(png, sizeof png, "meshes/duck/DuckCM.png")) {
        skip();
    }
    stc_conn *c = st_daemon_client(&D, NULL);
    assert_non_null(c);
    snprintf(dir, sizeof dir, "%s/fetched", D.dir);
    assert_int_equal(mkdir(dir, 0700), 0);

    /* a cube: .ptx (Ptex environment cube) and .exr (EXR cube) */
    upload(c, cube, "env", NULL);
    unsigned fits = fetch_all(c, "env", dir);
    assert_true(fits & (1u << STC_FETCH_PTX));
    assert_true(fits & (1u << STC_FETCH_EXR));
    assert_false(fits & (1u << STC_FETCH_DDS | 1u << STC_FETCH_PNG | 1u << STC_FETCH_OBJ));
    snprintf(p, sizeof p, "%s/env.ptx", dir);
    upload(c, p, "env_from_ptx", NULL);
    snprintf(p, sizeof p, "%s/env.exr", dir);
    upload(c, p, "env_from_exr", NULL);
    same_dir_samples(c, "env", "env_from_ptx");
    same_dir_samples(c, "env", "env_from_exr");
    /* fetched again with the wall clock a second on: the same bytes (4.10; an EXR carried its
     * time of writing as capDate before) */
    usleep(1100 * 1000);
    char again[720];
    snprintf(again, sizeof again, "%s/env_again.exr", dir);
    assert_int_equal(stc_fetch_file(c, "env", STC_FETCH_EXR, again, NULL, NULL), 0);
    size_t la = 0, lb = 0;
    char *fa = st_test_read_file(p, &la), *fb = st_test_read_file(again, &lb);
    assert_non_null(fa);
    assert_non_null(fb);
    assert_int_equal(la, lb);
    assert_memory_equal(fa, fb, la);
    free(fa);
    free(fb);

    /* an atlas: its image (.png at u8) and its mesh (.obj, uploaded with texture=) */
    upload(c, png, "duck_tex", NULL);
    upload(c, obj, "duck", "texture=duck_tex");
    fits = fetch_all(c, "duck", dir);
    assert_int_equal(fits, 1u << STC_FETCH_PNG | 1u << STC_FETCH_OBJ);
    fits = fetch_all(c, "duck_tex", dir);
    assert_int_equal(fits, 1u << STC_FETCH_PNG);
    snprintf(p, sizeof p, "%s/duck.png", dir);
    upload(c, p, "duck_png", NULL);
    snprintf(p, sizeof p, "%s/duck.obj", dir);
    upload(c, p, "duck_again", "texture=duck_png");
    same_uv_samples(c, "duck_tex", "duck_png", 1);
    same_uv_samples(c, "duck", "duck_again", 1);
    same_uv_samples(c, "duck", "duck_again", 2);

    /* a per-face set: .ptx only, as before; --format wins over the extension */
    size_t len = 0;
    void *ptx = st_fixture_uniform_ptx(&len);
    assert_non_null(ptx);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "faces", &uo, &ur), 0);
    free(ptx);
    assert_int_equal(fetch_all(c, "faces", dir), 1u << STC_FETCH_PTX);
    snprintf(p, sizeof p, "%s/faces.bin", dir);
    assert_int_equal(stc_fetch_file(c, "faces", STC_FETCH_PTX, p, NULL, NULL), 0);
    assert_int_equal(stc_fetch_file(c, "faces", STC_FETCH_AUTO, p, NULL, NULL), 0);  /* ptx */
    stc_close(c);
}

/* ---- fetch memory ----------------------------------------------------------------------------- */

static int open_fetch(int fd, uint32_t reqid, const char *set, uint64_t *id)
{
    stp_buf b;
    stp_buf_init(&b);
    stp_fetch_open fo;
    memset(&fo, 0, sizeof fo);
    snprintf(fo.name, sizeof fo.name, "%s", set);
    fo.format = STP_FETCH_PTX;
    assert_int_equal(stp_enc_fetch_open(&b, reqid, 0, &fo), 0);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    stp_buf_free(&b);
    st_wire_reply r;
    assert_int_equal(st_wire_read_reply(fd, &r, 90000), 0);
    assert_int_equal(r.reqid, reqid);
    if (r.status == 0)
        *id = stp_rd64(r.body);
    return (int)r.status;
}

static void close_fetch(int fd, uint32_t reqid, uint64_t id)
{
    stp_buf b;
    stp_buf_init(&b);
    stp_enc_id_req(&b, STP_OP_FETCH_CLOSE, reqid, 0, id);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    stp_buf_free(&b);
    st_wire_reply r;
    assert_int_equal(st_wire_read_reply(fd, &r, 90000), 0);
    assert_int_equal(r.status, 0);
}

static void open_fetches_are_bounded_by_the_memory_caps(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--max-memory", "24M", "--conn-fetch-cap", "12M", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    /* the default set serialises to ~0.6 MB as .ptx: 40 of them would be ~24 MB */
    int fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    uint64_t ids[64];
    int n = 0, st = 0;
    for (n = 0; n < 40; n++) {
        st = open_fetch(fd, (uint32_t)n + 1, "default", &ids[n]);
        if (st)
            break;
    }
    assert_true(n >= 2 && n < 40);
    assert_int_equal(st, STP_S_BUSY);   /* over conn-fetch-cap: close one first */
    uint64_t held = st_conn_stat(c, "fetch_memory");
    assert_true(held > 0 && held <= (12u << 20));
    assert_true(st_conn_stat(c, "fetches_refused") >= 1);
    /* a second connection fills the rest of max-memory; past it, BUSY too */
    int fd2 = st_daemon_connect(&d);
    assert_true(fd2 >= 0);
    uint64_t ids2[64];
    int n2 = 0;
    for (n2 = 0; n2 < 40; n2++) {
        st = open_fetch(fd2, (uint32_t)n2 + 1, "default", &ids2[n2]);
        if (st)
            break;
    }
    assert_int_equal(st, STP_S_BUSY);
    held = st_conn_stat(c, "fetch_memory");
    uint64_t bufs = st_conn_stat(c, "buffer_memory");
    assert_true(held + bufs <= (24u << 20));
    /* closing fetches frees the room */
    for (int i = 0; i < n; i++)
        close_fetch(fd, 100 + (uint32_t)i, ids[i]);
    assert_int_equal(open_fetch(fd, 300, "default", &ids[0]), 0);
    close(fd);
    close(fd2);   /* a closing connection releases its fetches */
    assert_int_equal(st_wait_stat(&d, c, "fetch_memory", ST_STAT_EQ, 0, 10000), 0);
    stc_close(c);
    /* a file larger than conn-fetch-cap can never fit: TOO_LARGE */
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    const char *tiny[] = {"--conn-fetch-cap", "100K", NULL};
    assert_int_equal(st_daemon_start(&d, tiny), 0);
    fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    assert_int_equal(open_fetch(fd, 1, "default", &ids[0]), STP_S_TOO_LARGE);
    close(fd);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_set_kind_fetches_and_uploads_back),
        cmocka_unit_test(open_fetches_are_bounded_by_the_memory_caps),
    };
    return cmocka_run_group_tests_name("fetch_formats", tests, st_group_setup, st_group_teardown);
}
