/* tests/integration/test_server_triangles.c - triangle-mesh Ptex sets through the daemon:
 * UPLOAD of the shared triangle files, INFO (mesh type, square faces, three edges), SAMPLE with
 * the Ptex filters against the Ptex library's own outputs (ptex-ref/ref_tri.txt), GPU-style
 * bilinear refused, FETCH as .ptx equal to the store's writer and a fixed point through a second
 * upload, COMPRESS refused up front.
 *
 * One daemon on 127.0.0.1 port 0 (tests/common/daemon_fixture.h). Needs SEAMTEX_DATA
 * (ptx/wdas-ptex-2009/tri/tri.ptx, ptex-ref/ref_tri.txt); skipped without it.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <sys/stat.h>

#include <cmocka.h>

#include "../common/ptexref.h"
#include "../common/daemon_client.h"
#include "../common/testdata.h"
#include "ptex.h"
#include "seamtex.h"

#define D ST_GROUP


static void upload(stc_conn *c, const char *path, const char *name)
{
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.flags = STC_UPLOAD_REPLACE;
    stc_upload_result ur;
    int rc = stc_upload_file(c, path, name, &uo, &ur);
    if (rc)
        fail_msg("upload %s as %s: %s: %s", path, name, stc_strerror(rc), stc_errmsg(c));
}

static void triangle_sets_upload_sample_fetch_and_refuse_compress(void **state)
{
    (void)state;
    char ptx[1024], ref[1024], dir[600], p1[700], p2[700];
    if (st_test_data_path(ptx, sizeof ptx, "ptx/wdas-ptex-2009/tri/tri.ptx") ||
        st_test_data_path(ref, sizeof ref, "ptex-ref/ref_tri.txt"))
        skip();
    stc_conn *c = st_daemon_client(&D, NULL);
    assert_non_null(c);
    upload(c, ptx, "tri");

    /* INFO: a triangle mesh of 9 square faces with three edges each */
    st_set *local;
    st_error e = {0};
    assert_int_equal(st_ptex_read_file(ptx, 0, &local, &e), 0);
    stc_info in;
    assert_int_equal(stc_info_get(c, "tri", 0, 9, &in), 0);
    assert_int_equal(in.meshtype, 1);
    assert_int_equal(in.nfaces, 9);
    assert_int_equal(in.nrec, 9);
    uint32_t boundary = 0;
    for (uint32_t f = 0; f < 9; f++) {
        assert_int_equal(in.faces[f].w, in.faces[f].h);
        assert_int_equal(in.faces[f].adjface[3], -1);
        for (int ed = 0; ed < 3; ed++) {
            assert_int_equal(in.faces[f].adjface[ed], local->faces[f].adjface[ed]);
            boundary += in.faces[f].adjface[ed] < 0;
        }
    }
    assert_int_equal(in.boundary_edges, boundary);

    /* SAMPLE: the first 100 reference lines, Traverse, each with the filter it names */
    FILE *fp = fopen(ref, "r");
    assert_non_null(fp);
    char line[512];
    int lines = 0;
    while (lines < 100 && fgets(line, sizeof line, fp)) {
        st_refline L;
        if (st_refline_parse(line, &L) != 1 || L.nref < 3)
            continue;
        stc_query q = {L.face, L.u, L.v, L.dudx, L.dvdx, L.dudy, L.dvdy};
        const float *want = L.ref;
        stc_sample_opts o;
        memset(&o, 0, sizeof o);
        o.mode = 1;
        o.filter = (uint8_t)(8 + L.filter);     /* the wire's Ptex filters are 8..15 */
        stc_sample_result r;
        int rc = stc_sample(c, "tri", &o, &q, 1, &r);
        if (rc)
            fail_msg("sample: %s: %s", stc_strerror(rc), stc_errmsg(c));
        const float *v = r.values;
        for (int ch = 0; ch < 3; ch++)
            if (!(fabsf(v[ch] - want[ch]) <= 1e-4f))
                fail_msg("line %d: %g, Ptex %g: %s", lines + 1, (double)v[ch], (double)want[ch],
                         line);
        lines++;
    }
    fclose(fp);
    assert_int_equal(lines, 100);

    /* GPU-style bilinear has no meaning on the packed triangle layout */
    stc_query q0 = {0, 0.2f, 0.3f, 0.01f, 0, 0, 0.01f};
    stc_sample_opts bl;
    memset(&bl, 0, sizeof bl);
    bl.mode = 1;
    bl.filter = 1;
    stc_sample_result r;
    assert_int_equal(stc_sample(c, "tri", &bl, &q0, 1, &r), STC_EUNSUPPORTED);
    assert_non_null(strstr(stc_errmsg(c), "triangle"));
    bl.filter = 0; /* point works */
    assert_int_equal(stc_sample(c, "tri", &bl, &q0, 1, &r), 0);

    /* FETCH as .ptx: the writer's bytes; uploaded again and fetched: the same bytes */
    snprintf(dir, sizeof dir, "%s/tri_fetch", D.dir);
    assert_int_equal(mkdir(dir, 0700), 0);
    snprintf(p1, sizeof p1, "%s/tri.ptx", dir);
    snprintf(p2, sizeof p2, "%s/tri2.ptx", dir);
    assert_int_equal(stc_fetch_file(c, "tri", STC_FETCH_PTX, p1, NULL, NULL), 0);
    void *mine;
    size_t mlen, l1, l2;
    assert_int_equal(st_ptex_write_mem(local, &mine, &mlen, &e), 0);
    void *b1 = st_test_read_file(p1, &l1);
    assert_non_null(b1);
    assert_int_equal(l1, mlen);
    assert_memory_equal(b1, mine, mlen);
    upload(c, p1, "tri2");
    assert_int_equal(stc_fetch_file(c, "tri2", STC_FETCH_PTX, p2, NULL, NULL), 0);
    void *b2 = st_test_read_file(p2, &l2);
    assert_non_null(b2);
    assert_int_equal(l2, l1);
    assert_memory_equal(b2, b1, l1);
    free(mine);
    free(b1);
    free(b2);

    /* COMPRESS: refused at the request, no job */
    uint64_t job = 0;
    assert_int_equal(stc_compress(c, "tri", "tri_bc1", 0, 0, &job), STC_EUNSUPPORTED);
    assert_non_null(strstr(stc_errmsg(c), "triangle"));
    st_set_free(local);
    stc_close(c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(triangle_sets_upload_sample_fetch_and_refuse_compress),
    };
    return cmocka_run_group_tests_name("server_triangles", tests, st_group_setup,
                                       st_group_teardown);
}
