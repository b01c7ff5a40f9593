/* tests/integration/test_render_shm.c - seamtex-render sampling through shared memory
 * (rs_net_shm, --shm; PROTOCOL.md 4.12): a frame rendered over a Unix socket with the region
 * is bit for bit the frame rendered over the same socket without it and the frame sampled
 * in-process, in every mode, with batches small enough that the region's ring wraps; every
 * batch really went through the region (or, without it, none did); a daemon that refuses the
 * region (shm-max too small: TOO_LARGE; shm-max 0: no SHM capability) or a TCP daemon gets the
 * socket under --shm auto and a clear error under --shm on; and the seamtex-render program
 * writes byte-identical PNGs with --shm on, --shm off and --inproc.
 *
 * The texture is a generated subdivided cube (54 faces of 8..32 texels, rotated frames), its
 * .ptx and .obj written into the test's temp dir; each test starts its own daemon
 * (unix_daemon.h; daemon_fixture.h for TCP).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/cube_fixture.h"
#include "../common/unix_daemon.h"
#include "ptex.h"
#include "render.h"

#define W 96
#define H 72

typedef struct fixture {
    st_unix_daemon *u;
    cf_cube  cube;
    rm_mesh *mesh;
    char     ptx[400], obj[400];
} fixture;

/* The cube's texture as .ptx and its quads as an OBJ (v / f lines, 1-based) in dir. */
static void write_files(fixture *f, const char *dir)
{
    st_error e;
    snprintf(f->ptx, sizeof f->ptx, "%.300s/cube.ptx", dir);
    snprintf(f->obj, sizeof f->obj, "%.300s/cube.obj", dir);
    assert_int_equal(st_ptex_write_file(f->cube.set, f->ptx, &e), 0);
    FILE *o = fopen(f->obj, "w");
    assert_non_null(o);
    const st_quadmesh *m = &f->cube.mesh;
    for (uint32_t i = 0; i < m->nverts; i++)
        fprintf(o, "v %.9g %.9g %.9g\n", m->pos[3 * i], m->pos[3 * i + 1], m->pos[3 * i + 2]);
    for (uint32_t q = 0; q < m->nquads; q++)
        fprintf(o, "f %u %u %u %u\n", m->quads[4 * q] + 1, m->quads[4 * q + 1] + 1,
                m->quads[4 * q + 2] + 1, m->quads[4 * q + 3] + 1);
    assert_int_equal(fclose(o), 0);
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    void *u = NULL;
    if (!f || st_unix_setup(&u) != 0)
        return -1;
    f->u = u;
    if (cf_cube_build(&f->cube, 3, 7, 3, 5, 11, ST_DT_U8, 4) != 0)
        return -1;
    char msg[256];
    f->mesh = rm_from_quads(f->cube.mesh.pos, f->cube.mesh.nverts, f->cube.mesh.quads,
                            f->cube.mesh.nquads, msg, sizeof msg);
    if (!f->mesh)
        return -1;
    write_files(f, f->u->d.dir);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    void *u = f->u;
    st_unix_teardown(&u);
    rm_free(f->mesh);
    cf_cube_free(&f->cube);
    free(f);
    return 0;
}

static stc_conn *connect_to(const char *host, unsigned port)
{
    stc_opts o = { .connect_timeout_ms = 10000, .request_timeout_ms = 60000 };
    int err = 0;
    char msg[256];
    stc_conn *c = stc_connect_opts(host, port, &o, &err, msg, sizeof msg);
    if (!c)
        fail_msg("connect %s: %s", host, msg);
    return c;
}

static void upload(stc_conn *c, const char *path)
{
    stc_upload_opts o = { .flags = STC_UPLOAD_REPLACE };
    stc_upload_result r;
    int rc = stc_upload_file(c, path, "cube", &o, &r);
    if (rc != 0)
        fail_msg("upload: %s (%s)", stc_strerror(rc), stc_errmsg(c));
}

/* Renders frame `frame` of the orbit in `mode` through s into rgb (W x H x 3). */
static void render(const fixture *f, rs_sampler *s, unsigned mode, unsigned frame, float *rgb,
                   rs_stats *st)
{
    rc_orbit orbit = { .frames = 6, .elev_deg = 30, .dist = 0.9, .fov_deg = 40 };
    rc_camera cam;
    rc_orbit_camera(&orbit, f->mesh, frame, W, H, &cam);
    rf_opts o = { .width = W, .height = H, .msaa = 4, .mode = mode, .filter = 3,
                  .max_aniso = 16, .outfmt = STC_OUT_F32, .bg = { 0.05f, 0.05f, 0.06f } };
    rr_target t = { 0 };
    char msg[512];
    memset(st, 0, sizeof *st);
    if (rf_render(f->mesh, &cam, &o, s, &t, rgb, NULL, st, msg, sizeof msg) != 0)
        fail_msg("render: %s", msg);
    rr_target_free(&t);
}

/* batch 300 x inflight 3: a frame of 3000-4000 queries is 10-14 batches, so the region
 * (sized for 3) is reused round the ring several times per frame. */
#define BATCH 300
#define INFLIGHT 3

static void test_shm_frames_equal_socket_and_inproc(void **state)
{
    fixture *f = *state;
    assert_int_equal(st_unix_start(f->u, "0600"), 0);
    stc_conn *cs = connect_to(f->u->addr, 0), *cp = connect_to(f->u->addr, 0);
    upload(cp, f->ptx);
    char note[512], msg[512];
    assert_int_equal(rs_net_shm(cs, f->u->addr, RS_SHM_ON, BATCH, INFLIGHT, STC_OUT_F32, note,
                                sizeof note, msg, sizeof msg), 1);
    assert_non_null(strstr(note, "shared memory"));
    /* a second attach on the same connection is an error, not a silent second region */
    assert_int_equal(rs_net_shm(cs, f->u->addr, RS_SHM_ON, BATCH, INFLIGHT, STC_OUT_F32, note,
                                sizeof note, msg, sizeof msg), -1);
    assert_int_equal(rs_net_shm(cp, f->u->addr, RS_SHM_OFF, BATCH, INFLIGHT, STC_OUT_F32, note,
                                sizeof note, msg, sizeof msg), 0);
    assert_string_equal(note, "");
    rs_sampler *shm = rs_net_new(cs, "cube", BATCH, INFLIGHT, msg, sizeof msg);
    rs_sampler *sock = rs_net_new(cp, "cube", BATCH, INFLIGHT, msg, sizeof msg);
    rs_sampler *inp = rs_inproc_new(f->ptx, NULL, msg, sizeof msg);
    assert_non_null(shm);
    assert_non_null(sock);
    assert_non_null(inp);
    static float a[W * H * 3], b[W * H * 3], c[W * H * 3];
    for (unsigned mode = 0; mode < 3; mode++)
        for (unsigned frame = 0; frame < 6; frame += 5) {
            rs_stats sa, sb, sc;
            render(f, shm, mode, frame, a, &sa);
            render(f, sock, mode, frame, b, &sb);
            render(f, inp, mode, frame, c, &sc);
            if (sa.batches <= 2 * INFLIGHT)
                fail_msg("%llu queries in %llu batches: the ring is not reused",
                         (unsigned long long)sa.queries, (unsigned long long)sa.batches);
            assert_int_equal(sa.shm_batches, sa.batches);     /* all through the region */
            assert_int_equal(sb.shm_batches, 0);
            assert_int_equal(sa.queries, sb.queries);
            assert_true(sa.bytes_out * 20 < sb.bytes_out);   /* only small frames crossed */
            assert_memory_equal(a, b, sizeof a);
            assert_memory_equal(a, c, sizeof a);
        }
    uint64_t via_shm = 0, via_sock = 0;
    stc_shm_counts(cs, &via_shm, &via_sock);
    assert_true(via_shm > 0);
    rs_free(shm);
    rs_free(sock);
    rs_free(inp);
    stc_close(cs);
    stc_close(cp);
    assert_int_equal(st_unix_stop(f->u), 0);
}

/* A daemon that refuses: under auto the sampler uses the socket (same frame), under on it is
 * an error naming the reason; the connection stays usable either way. */
static void refused(fixture *f, const char *const *args, const char *why)
{
    assert_int_equal(st_unix_start_args(f->u, "0600", args), 0);
    stc_conn *c = connect_to(f->u->addr, 0);
    upload(c, f->ptx);
    char note[512], msg[512] = "";
    assert_int_equal(rs_net_shm(c, f->u->addr, RS_SHM_ON, BATCH, INFLIGHT, STC_OUT_F32, note,
                                sizeof note, msg, sizeof msg), -1);
    if (!strstr(msg, "--shm on") || !strstr(msg, why))
        fail_msg("--shm on: '%s' does not say '%s'", msg, why);
    assert_int_equal(rs_net_shm(c, f->u->addr, RS_SHM_AUTO, BATCH, INFLIGHT, STC_OUT_F32,
                                note, sizeof note, msg, sizeof msg), 0);
    if (!strstr(note, why))
        fail_msg("auto: '%s' does not say '%s'", note, why);
    rs_sampler *s = rs_net_new(c, "cube", BATCH, INFLIGHT, msg, sizeof msg);
    rs_sampler *inp = rs_inproc_new(f->ptx, NULL, msg, sizeof msg);
    assert_non_null(s);
    assert_non_null(inp);
    static float a[W * H * 3], b[W * H * 3];
    rs_stats sa, sb;
    render(f, s, 1, 0, a, &sa);
    render(f, inp, 1, 0, b, &sb);
    assert_int_equal(sa.shm_batches, 0);
    assert_true(sa.batches > 0);
    assert_memory_equal(a, b, sizeof a);
    rs_free(s);
    rs_free(inp);
    stc_close(c);
    assert_int_equal(st_unix_stop(f->u), 0);
}

static void test_too_small_shm_max_falls_back(void **state)
{
    static const char *const args[] = { "--shm-max", "4096", NULL };
    refused(*state, args, "TOO_LARGE");
}

static void test_shm_off_daemon_falls_back(void **state)
{
    static const char *const args[] = { "--shm-max", "0", NULL };
    refused(*state, args, "does not offer it");
}

static void test_tcp_daemon_gets_the_socket(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, NULL), 0);
    stc_conn *c = connect_to(d.host, (unsigned)d.port);
    char note[512], msg[512] = "";
    assert_int_equal(rs_net_shm(c, d.host, RS_SHM_ON, BATCH, INFLIGHT, STC_OUT_F32, note,
                                sizeof note, msg, sizeof msg), -1);
    assert_non_null(strstr(msg, "not on a unix: address"));
    assert_int_equal(rs_net_shm(c, d.host, RS_SHM_AUTO, BATCH, INFLIGHT, STC_OUT_F32, note,
                                sizeof note, msg, sizeof msg), 0);
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 10000), 0);
}

/* The program: --shm on, --shm off (both over the Unix socket) and --inproc write the same
 * PNG bytes; the frame line says where the batches went. */
static int sh(const char *cmd)
{
    int rc = system(cmd);
    return rc == -1 ? -1 : WEXITSTATUS(rc);
}

static void test_program_pngs_identical(void **state)
{
    fixture *f = *state;
    assert_int_equal(st_unix_start(f->u, "0600"), 0);
    const char *dir = f->u->d.dir;
    char cmd[4096];
    const char *variants[3] = { "--host %s --shm on", "--host %s --shm off", "--inproc" };
    for (int i = 0; i < 3; i++) {
        char how[400];
        snprintf(how, sizeof how, variants[i], f->u->addr);
        snprintf(cmd, sizeof cmd, "%s/seamtex-render %s --size 80x60 --mode traverse "
                 "--batch 500 --inflight 2 --frames 6 --frame 1 --out %s/out%d %s > %s/out%d.txt "
                 "2>&1", st_build_dir(), how, dir, i, f->obj, dir, i);
        if (sh(cmd) != 0) {
            snprintf(cmd, sizeof cmd, "cat %s/out%d.txt >&2", dir, i);
            (void)sh(cmd);
            fail_msg("seamtex-render %s failed", how);
        }
    }
    snprintf(cmd, sizeof cmd, "grep -q 'batches through shared memory' %s/out0.txt && "
             "! grep -q 'shared memory' %s/out1.txt && "
             "cmp %s/out0/cube_traverse_4x_f001.png %s/out1/cube_traverse_4x_f001.png && "
             "cmp %s/out0/cube_traverse_4x_f001.png %s/out2/cube_traverse_4x_f001.png",
             dir, dir, dir, dir, dir, dir);
    assert_int_equal(sh(cmd), 0);
    /* a bad value is a usage error */
    snprintf(cmd, sizeof cmd, "%s/seamtex-render --host %s --shm maybe %s 2>/dev/null",
             st_build_dir(), f->u->addr, f->obj);
    assert_int_equal(sh(cmd), 2);
    assert_int_equal(st_unix_stop(f->u), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_shm_frames_equal_socket_and_inproc, setup, teardown),
        cmocka_unit_test_setup_teardown(test_too_small_shm_max_falls_back, setup, teardown),
        cmocka_unit_test_setup_teardown(test_shm_off_daemon_falls_back, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tcp_daemon_gets_the_socket, setup, teardown),
        cmocka_unit_test_setup_teardown(test_program_pngs_identical, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
