/* tests/unit/test_ptexfilter_iso.c - ptexfilter.c's kernel_iso (session 18): a width-4
 * kernel of half a face to a face wide along both axes (resolution 2, or 1 on a face of one
 * texel, 1 to 4 taps an axis after the zeros are stripped) on a face without neighbours, in
 * Traverse and Clamp, built, folded at the boundary (or kept inside the face) and windowed
 * without the pk and the walk's dispatch. Its outputs, coverage and status must be the
 * general path's (pf_batch_path(PF_PATH_GENERAL): every query through eval) bit for bit:
 * widths on either side of half a face and of a face (0.5, 0.49999997, 0.99999994, 1: the
 * other builds next to it), the axes alike or not, (u, v) anywhere, near an edge, at 0.5
 * (where the kernel's first tap moves from -2 to 0) or next to it, and at the values where
 * an end tap's weight is zero (stripped: the window one texel narrower, or no overhang
 * left, then the in-face window); the one-face files of bordermodes and tri/quad.ptx under
 * each border mode (black drops the overhang), plain and with the face flagged constant,
 * then subface; every kernel filter, every mode. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <string.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "sample.h"
#include "../common/pffiles.h"
#include "../common/pfpaths.h"
#include "../common/testdata.h"
#include "../common/testhash.h"

enum { NQ = 4000 };

static uint32_t rng = 29;
static float rnd01(void) /* [0, 1): testhash.h's generator on this file's state */
{
    return st_test_rndf(&rng);
}

static const unsigned filters[] = {ST_FILTER_PTEX_BOX, ST_FILTER_PTEX_GAUSSIAN,
                                   ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_CATMULLROM,
                                   ST_FILTER_PTEX_MITCHELL};
enum { NF = sizeof filters / sizeof filters[0] };

/* Both paths on q for every filter and mode (pfpaths.h); returns the queries compared. */
static long compare(const st_set *s, const st_query *q, const char *what)
{
    long n = st_pf_paths_agree(s, q, NQ, what, filters, NF);
    if (n < 0)
        fail();
    return n;
}

/* A coordinate: anywhere, near an edge, at or next to 0.5, or where the kernel of width
 * w (a fraction of the face, resolution 2) has a zero end tap (|x| s at 1: the tap at
 * (u * 2 - 0.5) + t for t = +-1.5 / s with s = 1 / (w * 1.5 + 0.5), moved by a few ulps). */
static float coord(int j, float w)
{
    static const float at[] = {0.5f, 0.49999997f, 0.50000006f, 0.0f, 0.99999994f, 0.25f};
    float u = rnd01();
    switch (j % 6) {
    case 1: u = rnd01() < 0.5f ? u * 0.05f : 1.0f - u * 0.05f; break;
    case 2: u = at[(int)(rnd01() * 6) % 6]; break;
    case 3: case 4: { /* an end tap's |x| s next to 1 */
        float s = 1.0f / (w * 1.5f + 0.5f), r = 1.0f / s;
        float x = (rnd01() < 0.5f ? 1.5f : 0.5f) - r + (float)((int)(rnd01() * 7) - 3) * 1e-6f;
        u = rnd01() < 0.5f ? (x + 0.5f) / 2.0f : (2.0f + x + 0.5f) / 2.0f - 1.0f;
        if (j % 6 == 4)
            u = 1.0f - u;
        break;
    }
    default: break;
    }
    u = u < 0.0f ? 0.0f : u;
    return u < 0.99999994f ? u : 0.99999994f;
}

static long iso_file(st_set *s, st_query *q, const char *path)
{
    static const float rel[] = {0.5f,       0.75f, 0.6f, 0.99999994f, 0.9f,
                                0.49999997f, 1.0f,  0.55f};
    const st_face *F = &s->faces[0];
    for (int j = 0; j < NQ; j++) {
        float ru = rel[(int)(rnd01() * 8) & 7];
        float rv = j % 3 == 1 ? rel[(int)(rnd01() * 8) & 7] : ru;
        if (j % 5 == 0) /* widths anywhere in [0.5, 1) */
            ru = 0.5f + rnd01() * 0.5f, rv = j % 2 ? 0.5f + rnd01() * 0.5f : ru;
        q[j] = (st_query){.face = 0, .u = coord(j, ru), .v = coord(j / 6, rv), .dudx = ru,
                          .dvdy = rv};
        if (j % 7 == 3) /* a footprint in texels (the widths of the query files) */
            q[j].dudx = ru * 8.0f / (float)F->w, q[j].dvdy = rv * 8.0f / (float)F->h;
    }
    long n = 0;
    uint8_t bu = s->info.border_u, bv = s->info.border_v;
    for (uint8_t b = 0; b <= 3; b++) { /* as read, clamp, black, periodic */
        if (b)
            s->info.border_u = s->info.border_v = (uint8_t)(b - 1);
        n += compare(s, q, path);
    }
    s->info.border_u = bu;
    s->info.border_v = bv;
    /* the face flagged constant, then subface (after the table is built) */
    uint8_t fl = s->faces[0].flags;
    s->faces[0].flags = (uint8_t)(fl | ST_FACE_CONSTANT);
    n += compare(s, q, path);
    s->faces[0].flags = (uint8_t)(fl | ST_FACE_SUBFACE);
    n += compare(s, q, path);
    s->faces[0].flags = fl;
    return n;
}

static void iso_kernels_match_the_general_path(void **state)
{
    (void)state;
    static const char *const files[] = {
        "ptx/wdas-ptex-2009/tri/quad.ptx",
        "ptx/wdas-ptex-2009/bordermodes/black.ptx",
        "ptx/wdas-ptex-2009/bordermodes/clamp.ptx",
        "ptx/wdas-ptex-2009/bordermodes/periodic.ptx",
    };
    static st_query q[NQ];
    long compared = 0;
    int found = 0;
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        char path[1024];
        st_set *s;
        int r = st_pf_read_shared(files[i], path, sizeof path, &s);
        if (r == 0)
            continue;
        assert_int_equal(r, 1);
        found++;
        compared += iso_file(s, q, path);
        st_set_free(s);
    }
    if (!found) {
        print_message("SEAMTEX_DATA (%s) has none of the files: skipped\n", st_test_data_dir());
        skip();
    }
    print_message("%d files, %ld queries compared\n", found, compared);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(iso_kernels_match_the_general_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
