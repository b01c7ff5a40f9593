/* tests/unit/test_ptextri.c - triangle-mesh Ptex files: reading them (square faces, three
 * edges, the packed triangle layout and its reductions), Ptex's point and triangle filters
 * against the Ptex library's own outputs (SEAMTEX_DATA/ptex-ref/ref_tri.txt and
 * ref_triangle.txt: PtexFilter::eval of Ptex v2.4.3), Discard and Clamp, the GPU-style point
 * filter, and round trips through the .ptx writer and the native set file.
 *
 * The reference check requires, per file and filter, at least 99.9% of the queries within
 * 1e-4 on every channel (float data, the tolerance of the quad files) and prints the table. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "native.h"
#include "ptex.h"
#include "ptexfilter.h"
#include "sample.h"
#include "trilevel.h"
#include "../common/testdata.h"

static const char *fnames[8] = {"point", "bilinear", "box", "gaussian", "bicubic", "bspline",
                                "catmullrom", "mitchell"};

static int filter_of(const char *n)
{
    for (int i = 0; i < 8; i++)
        if (!strcmp(n, fnames[i]))
            return ST_FILTER_PTEX_POINT + i;
    return -1;
}

static const char *const tri_files[2][2] = {
    {"ptx/wdas-ptex-2009/tri/tri.ptx", "ptex-ref/ref_tri.txt"},
    {"ptx/wdas-ptex-samples/triangle/triangle.ptx", "ptex-ref/ref_triangle.txt"},
};

static st_set *read_rel(const char *rel)
{
    char path[1024];
    if (st_test_data_path(path, sizeof path, rel))
        return NULL;
    st_set *s;
    st_error e = {0};
    int rc = st_ptex_read_file(path, 0, &s, &e);
    if (rc)
        print_message("%s: %s\n", rel, e.msg);
    assert_int_equal(rc, 0);
    return s;
}

static void triangle_filters_match_the_ptex_library(void **state)
{
    (void)state;
    char path[1024];
    if (st_test_data_path(path, sizeof path, tri_files[0][1]))
        skip();
    print_message("%-14s %-10s %7s %8s %10s\n", "file", "filter", "queries", "match%", "max|diff|");
    for (int r = 0; r < 2; r++) {
        st_set *s = read_rel(tri_files[r][0]);
        assert_non_null(s);
        assert_int_equal(s->info.meshtype, ST_MESH_TRIANGLE);
        assert_int_equal(st_test_data_path(path, sizeof path, tri_files[r][1]), 0);
        FILE *fp = fopen(path, "r");
        assert_non_null(fp);
        float tol = s->info.dtype == ST_DT_U8 ? 0.5f / 255.0f : 1e-4f;
        int total[8] = {0}, ok[8] = {0};
        float maxd[8] = {0};
        char line[512];
        while (fgets(line, sizeof line, fp)) {
            st_query q;
            char fn[32];
            float ref[4] = {0};
            int n = sscanf(line, "%u %f %f %f %f %f %f %31s -> %f %f %f %f", &q.face, &q.u, &q.v,
                           &q.dudx, &q.dvdx, &q.dudy, &q.dvdy, fn, &ref[0], &ref[1], &ref[2],
                           &ref[3]);
            if (n < 9)
                continue;
            int flt = filter_of(fn);
            assert_true(flt >= 0);
            st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = (uint8_t)flt};
            float out[4];
            uint8_t st;
            assert_int_equal(st_sample_batch(s, &o, &q, 1, out, NULL, &st), 0);
            int good = 1, fi = flt - ST_FILTER_PTEX_POINT;
            for (int c = 0; c < n - 8 && c < s->info.nchan; c++) {
                float d = fabsf(out[c] - ref[c]);
                if (!(d <= tol))
                    good = 0;
                if (d > maxd[fi])
                    maxd[fi] = d;
            }
            if (!good && getenv("PTEXTRI_VERBOSE"))
                print_message("miss: %s", line);
            total[fi]++;
            ok[fi] += good;
        }
        fclose(fp);
        const char *base = strrchr(tri_files[r][0], '/') + 1;
        for (int fi = 0; fi < 8; fi++) {
            if (!total[fi])
                continue;
            print_message("%-14s %-10s %7d %8.2f %10.2g\n", base, fnames[fi], total[fi],
                          100.0 * ok[fi] / total[fi], (double)maxd[fi]);
            assert_true(ok[fi] * 1000 >= total[fi] * 999);
        }
        st_set_free(s);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(triangle_filters_match_the_ptex_library),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
