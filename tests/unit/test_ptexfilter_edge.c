/* tests/unit/test_ptexfilter_edge.c - the Ptex filters' general path (kernels that cross face
 * edges, corners, small faces, subfaces, boundaries; ptexfilter.c) gives exactly the outputs
 * of the build before its rewrite (main at 032b914): every shared quad .ptx file, the box and
 * width-4 filters (gaussian, bicubic with sharpness 0.3, B-spline, Catmull-Rom, Mitchell;
 * every other filter with the width option 1.5) in
 * Traverse, Discard and Clamp, 2500 queries each - most of them on or over an edge: uv near an
 * edge or a corner or outside the face, footprints from a quarter texel to 32 texels,
 * anisotropic and rotated. Outputs, coverage and status of each (file, filter, mode) are
 * hashed (FNV-1a over their bytes) and compared with the hash the old build gave for the same
 * queries (this file built against it; on a mismatch the test prints the line to compare).
 * Bit for bit, so skipped on a CPU without AVX2 + FMA + F16C (the portable loops sum in
 * another order). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "../common/skip_unless.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "sample.h"
#include "set.h"
#include "../common/testdata.h"
#include "../common/testhash.h"

enum { NQ = 2500 };

static const char *const files[] = {
    "ptex-ref/cube1_k6_u8.ptx",
    "ptex-ref/cube8_k6_u8.ptx",
    "ptex-ref/cube8_k6_u8_rot.ptx",
    "ptex-ref/cube8_k7varrot_f32.ptx",
    "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    "ptx/wdas-ptex-samples/envcube/envcube.ptx",
    "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
    "ptx/wdas-ptex-2009/cube/text/cube.ptx",
    "ptx/wdas-ptex-2009/dispplane/rand/pPlane1.ptx",
    "ptx/wdas-ptex-2009/dispplane/wave_lo/pPlane1.ptx",
    "ptx/wdas-ptex-2009/bordermodes/black.ptx",
    "ptx/wdas-ptex-2009/bordermodes/clamp.ptx",
    "ptx/wdas-ptex-2009/bordermodes/periodic.ptx",
    "ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx",
    "ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx",
    "ptx/wdas-ptex-2009/tri/quad.ptx",
};
#define NFILES (sizeof files / sizeof files[0])
#define NFILT 6 /* ST_FILTER_PTEX_BOX .. ST_FILTER_PTEX_MITCHELL */

/* The old build's hashes, [file][filter - box][mode] (st_mode order: discard, traverse,
 * clamp). */
static const uint64_t want[NFILES][NFILT][3] = {
#include "ptexfilter_edge_hashes.inc"
};

static uint32_t rng;
/* The queries of one file: faces uniform; uv inside (40%), within two texels of an edge or a
 * corner (40%) or up to 5% outside the face (20%); footprints 2^[-2, 5] texels of the face,
 * anisotropic, a third of them rotated. */
static void make_queries(const st_set *s, st_query *q, uint32_t seed)
{
    rng = seed;
    for (int i = 0; i < NQ; i++) {
        uint32_t f = (uint32_t)(st_test_rndf(&rng) * (float)s->info.nfaces) % s->info.nfaces;
        const st_face *F = &s->faces[f];
        float w = (float)F->w, h = (float)F->h;
        float u = st_test_rndf(&rng), v = st_test_rndf(&rng), r = st_test_rndf(&rng);
        if (r < 0.4f) {
            float du = 2.0f * st_test_rndf(&rng) / w, dv = 2.0f * st_test_rndf(&rng) / h;
            int side = (int)(st_test_rndf(&rng) * 4.0f);
            if (side & 1)
                u = side & 2 ? 1.0f - du : du;
            if (side != 1 || st_test_rndf(&rng) < 0.5f)
                v = side & 2 ? 1.0f - dv : dv;
        } else if (r < 0.6f) {
            u = -0.05f + 1.1f * u;
            v = -0.05f + 1.1f * v;
        }
        float fpu = exp2f(-2.0f + 7.0f * st_test_rndf(&rng)), fpv = fpu * exp2f(-1.0f + 2.0f * st_test_rndf(&rng));
        float rot = st_test_rndf(&rng) < 0.33f ? st_test_rndf(&rng) * 6.2831853f : 0.0f;
        float c = cosf(rot), sn = sinf(rot);
        q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = c * fpu / w, .dvdx = sn * fpv / h,
                          .dudy = -sn * fpu / w, .dvdy = c * fpv / h};
    }
}

static void general_path_gives_the_old_builds_outputs_bit_for_bit(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    char path[1024];
    if (st_test_data_path(path, sizeof path, files[0]))
        skip();
    st_query *q = malloc(sizeof *q * NQ);
    float *out = malloc(sizeof(float) * 4 * NQ), *cov = malloc(sizeof(float) * NQ);
    uint8_t *stat = malloc(NQ);
    assert_true(q && out && cov && stat);
    int bad = 0, checked = 0;
    for (size_t fi = 0; fi < NFILES; fi++) {
        if (st_test_data_path(path, sizeof path, files[fi]))
            continue;
        st_set *s;
        st_error e = {0};
        assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
        make_queries(s, q, 1000u + (uint32_t)fi);
        for (int ft = 0; ft < NFILT; ft++)
            for (int mode = 0; mode < 3; mode++) {
                st_sample_opts o = {.filter = (uint8_t)(ST_FILTER_PTEX_BOX + ft),
                                    .mode = (uint8_t)mode, .sharpness = 0.3f,
                                    .width = ft & 1 ? 1.5f : 0.0f};
                memset(out, 0, sizeof(float) * 4 * NQ);
                int r = st_ptexfilter_batch(s, &o, q, NQ, out, cov, stat);
                assert_true(r >= 0);
                uint64_t h = 0xcbf29ce484222325ull;
                h = st_test_fnv(h, out, sizeof(float) * s->info.nchan * NQ);
                h = st_test_fnv(h, cov, sizeof(float) * NQ);
                h = st_test_fnv(h, stat, NQ);
                checked++;
                if (h != want[fi][ft][mode]) {
                    bad++;
                    print_message("differs: %s filter %d mode %d: [%zu][%d][%d] = "
                                  "0x%016llxull\n", files[fi], ST_FILTER_PTEX_BOX + ft, mode,
                                  fi, ft, mode, (unsigned long long)h);
                }
            }
        st_set_free(s);
    }
    free(q);
    free(out);
    free(cov);
    free(stat);
    print_message("%d (file, filter, mode) groups of %d queries, %d differ from the old "
                  "build\n", checked, NQ, bad);
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(general_path_gives_the_old_builds_outputs_bit_for_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
