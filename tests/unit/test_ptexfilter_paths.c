/* tests/unit/test_ptexfilter_paths.c - the Ptex filters' per-batch shortcuts (point and bilinear
 * per texel type, bilinear inside a face and across its edges and corners, the fused path of
 * box and width-4 kernels of every width, the shortcut walk and ptexfilter_walk.c's split of
 * kernels of any size that overhang a plain face, the small-window loop) give the general
 * path's outputs bit for bit:
 * on every shared .ptx file (SEAMTEX_DATA ptex-ref/ and ptx/, walked, so a new file is
 * covered), every filter, Traverse, Discard and Clamp, many random queries - a third of them
 * near a face edge or corner, some on texel centres - at footprints from a quarter texel to 32 texels, isotropic and
 * not, with default and non-default width and blur. Outputs, coverage and status are compared
 * as bytes (pf_batch_general runs every query through eval). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "sample.h"
#include "../common/testdata.h"

enum { NQ = 2000, MAXF = 64 };

static uint32_t rng = 11;
static float rndf(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

/* NQ queries on s: uniform, or (one in three) within a level-0 texel or two of an edge or
 * corner; footprints 0.25..32 texels, some anisotropic or with cross terms. */
static void make_queries(const st_set *s, st_query *q)
{
    static const float fps[] = {0.25f, 0.5f, 1.0f, 2.0f, 4.0f, 7.0f, 16.0f, 32.0f};
    for (int i = 0; i < NQ; i++) {
        uint32_t f = (uint32_t)(rndf() * (float)s->info.nfaces) % s->info.nfaces;
        const st_face *F = &s->faces[f];
        float u = rndf(), v = rndf();
        if (i % 3 == 0) { /* near an edge: within 2 texels of 0 or 1 */
            float du = rndf() * 2.0f / (float)F->w, dv = rndf() * 2.0f / (float)F->h;
            u = rndf() < 0.5f ? du : 1.0f - du;
            if (i % 2)
                v = rndf() < 0.5f ? dv : 1.0f - dv; /* a corner */
            if (u >= 1.0f)
                u = 0.99999994f;
            if (v >= 1.0f)
                v = 0.99999994f;
        }
        float fu = fps[(int)(rndf() * 8) & 7], fv = i % 4 == 1 ? fps[(int)(rndf() * 8) & 7] : fu;
        q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = fu / (float)F->w,
                          .dvdy = fv / (float)F->h};
        if (i % 5 == 2) { /* on a texel centre at 16 x 16: bilinear fractions of 0 */
            q[i].u = ((float)(int)(rndf() * 16.0f) + 0.5f) / 16.0f;
            q[i].dudx = 1.0f / 16.0f;
            if (i % 2) {
                q[i].v = ((float)(int)(rndf() * 16.0f) + 0.5f) / 16.0f;
                q[i].dvdy = 1.0f / 16.0f;
            }
        }
        if (i % 7 == 3) { /* cross terms */
            q[i].dudy = 0.5f * q[i].dudx;
            q[i].dvdx = -0.25f * q[i].dvdy;
        }
    }
}

static void shortcuts_give_the_general_paths_results_bit_for_bit(void **state)
{
    (void)state;
    static char rel[MAXF][512], paths[MAXF][1024];
    int n = st_test_ptx_files(rel, MAXF);
    for (int i = 0; i < n; i++)
        if (snprintf(paths[i], sizeof paths[i], "%s/%s", st_test_data_dir(), rel[i]) >=
            (int)sizeof paths[i])
            fail_msg("data dir path too long: %s", st_test_data_dir());
    if (n == 0) {
        print_message("SEAMTEX_DATA (%s) has no .ptx files: skipped\n", st_test_data_dir());
        skip();
    }
    static st_query q[NQ];
    static float o1[NQ * 4], o2[NQ * 4], c1[NQ], c2[NQ];
    static uint8_t s1[NQ], s2[NQ];
    static const float widths[2][2] = {{0.0f, 0.0f}, {1.5f, 0.01f}}; /* width, blur */
    long compared = 0;
    for (int i = 0; i < n; i++) {
        st_set *s;
        st_error e = {0};
        assert_int_equal(st_ptex_read_file(paths[i], 0, &s, &e), 0);
        make_queries(s, q);
        size_t nv = (size_t)NQ * s->info.nchan;
        for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++) {
            for (unsigned flt = ST_FILTER_PTEX_POINT; flt <= ST_FILTER_PTEX_MITCHELL; flt++) {
                for (int w = 0; w < 2; w++) {
                    st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)flt,
                                        .width = widths[w][0], .blur = widths[w][1],
                                        .sharpness = 0.5f};
                    memset(o1, 0x5a, sizeof o1);
                    memset(o2, 0xa5, sizeof o2);
                    int b1 = st_ptexfilter_batch(s, &o, q, NQ, o1, c1, s1);
                    int b2 = pf_batch_general(s, &o, q, NQ, o2, c2, s2);
                    assert_int_equal(b1, b2);
                    for (size_t k = 0; k < nv; k++) {
                        if (memcmp(&o1[k], &o2[k], sizeof(float))) {
                            size_t qi = k / s->info.nchan;
                            print_message("%s mode %u filter %u width %d query %zu (face %u u %.9g "
                                          "v %.9g dudx %.9g dvdy %.9g): %.9g != %.9g\n",
                                          paths[i], m, flt, w, qi, q[qi].face,
                                          (double)q[qi].u, (double)q[qi].v,
                                          (double)q[qi].dudx, (double)q[qi].dvdy,
                                          (double)o1[k], (double)o2[k]);
                            fail();
                        }
                    }
                    assert_memory_equal(c1, c2, sizeof c1);
                    assert_memory_equal(s1, s2, sizeof s1);
                    compared += NQ;
                }
            }
        }
        st_set_free(s);
    }
    print_message("%d files, %ld queries compared\n", n, compared);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(shortcuts_give_the_general_paths_results_bit_for_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
