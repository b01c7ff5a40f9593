/* tests/unit/test_ptexfilter_nonb.c - the width-4 filters' kernels on faces without
 * neighbours 8 queries at a time (session 19): pf_r0x8_select and pf_iso8_select
 * (ptexfilter_simd.c), with which kernel_run serves the lanes of klanes8's nonb mask whose
 * widths are a face or more along both axes (kernel_r0's kernels at resolution 1 x 1: 2
 * hermite taps an axis) or half a face to under a face (kernel_iso's at resolution 2 x 2: 4
 * taps an axis, zeros stripped), folded at the border. Outputs, coverage and status must be
 * (and, session 20, pf_q8_select's: widths in [1/4, 1/2) once clamped to a texel of the face,
 * resolution 2 x 2, 4 or 6 evaluated taps an axis, on every kernel filter) must be
 * the general path's (pf_batch_path(PF_PATH_GENERAL): every query through eval) bit for
 * bit, for every width-4 filter and mode, on the one-face files of bordermodes and
 * tri/quad.ptx under each border mode (black drops the overhang, clamp folds it; periodic's
 * file has itself as neighbour: not these paths'), one axis black and the other not, plain
 * and with the face flagged constant, then subface. The queries: r0 - widths of a face or
 * more (1, just over, 4, 16, one axis so and the other half a face or under), (u, v)
 * anywhere, near an edge, at 0.5 and a few ulps either side (where the first tap moves from
 * texel -1 to 0 and where one tap's hermite weight is 0: one tap left, on the texel or past
 * it, or a kernel inside the face), with an invalid face or a NaN width among them; iso -
 * widths in [1/2, 1) and next to both ends, (u, v) where an end tap's weight crosses zero
 * (the window a texel narrower, or no overhang left) or as above. The lanes the 8-query
 * functions serve are counted through klanes8 on the same blocks, so that the comparison
 * is known to cover them. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "ptexfilter_lanes.h"
#include "ptexres.h"
#include "sample.h"
#include "../common/pffiles.h"
#include "../common/pfpaths.h"
#include "../common/skip_unless.h"
#include "../common/testdata.h"
#include "../common/testhash.h"

enum { NQ = 4096 };

static uint32_t rng = 41;
static float rnd01(void) /* [0, 1): testhash.h's generator on this file's state */
{
    return st_test_rndf(&rng);
}

static const unsigned *const filters = st_pf_kernel_filters; /* every one (pfpaths.h) */
enum { NF = ST_PF_NKERNEL_FILTERS };

/* A coordinate: anywhere, near an edge, or at / next to 0.5 (the ulps below it make the
 * first tap's weight 1 - tiny, or 0 where upix + 1 rounds to 1). */
static float coord(void)
{
    static const float at[] = {0.5f,        0.49999997f, 0.49999994f, 0.4999999f,
                               0.50000006f, 0.5000001f,  0.0f,        0.99999994f};
    float u = rnd01();
    switch ((int)(rnd01() * 4)) {
    case 1: return rnd01() < 0.5f ? u * 1e-3f : 1.0f - u * 1e-3f;
    case 2: return at[(int)(rnd01() * 8) & 7];
    default: return u;
    }
}

/* A width for the r0 lanes (in units of the face: dudx = w here): a face or more mostly,
 * sometimes half a face or under (that lane is not the path's, the block still is). */
static float width(void)
{
    static const float w[] = {1.0f, 1.00000012f, 4.0f, 16.0f, 1.5f, 2.0f, 0.5f, 0.1f};
    return w[(int)(rnd01() * 8) & 7];
}

/* A width for the iso lanes: half a face to under a face (0.5 and the float below it, the
 * float below 1 and 1: the builds next to it), sometimes a face or more. */
static float iso_width(void)
{
    static const float w[] = {0.5f, 0.75f, 0.6f, 0.99999994f, 0.9f, 0.49999997f, 1.0f, 0.55f};
    int i = (int)(rnd01() * 10);
    return i < 8 ? w[i] : 0.5f + rnd01() * 0.5f;
}

/* A coordinate where an end tap of the iso kernel of width w (resolution 2) has a weight
 * next to 0 (|x| s at 1 for s = 1 / (w * 1.5 + 0.5): the tap at (u * 2 - 0.5) + t, t = +-1.5
 * / s, moved by a few ulps), near 0 or 1 or 0.5 (the first tap from -2 to 0), or anywhere. */
static float iso_coord(float w)
{
    float u;
    switch ((int)(rnd01() * 4)) {
    case 0: case 1: {
        float r = w * 1.5f + 0.5f;
        float x = (rnd01() < 0.5f ? 1.5f : 0.5f) - r + (float)((int)(rnd01() * 7) - 3) * 1e-6f;
        u = rnd01() < 0.5f ? (x + 0.5f) / 2.0f : (2.0f + x + 0.5f) / 2.0f - 1.0f;
        if (rnd01() < 0.5f)
            u = 1.0f - u;
        break;
    }
    case 2: return coord();
    default: u = rnd01(); break;
    }
    u = u < 0.0f ? 0.0f : u;
    return u < 0.99999994f ? u : 0.99999994f;
}

/* A width for the q8 lanes: [1/4, 1/2) and next to both ends, sometimes under 1/4 (on the
 * 4 x 4 faces clamped to 1/4: the band; on quad's 8 x 8 not) or 1/2 (not the band). */
static float q8_width(void)
{
    static const float w[] = {0.25f, 0.3f, 0.4f, 0.49999997f, 0.24999999f, 0.0625f, 0.5f, 0.45f};
    int i = (int)(rnd01() * 10);
    return i < 8 ? w[i] : 0.25f + rnd01() * 0.25f;
}

/* A coordinate for the q8 lanes: where the first tap moves (u * 4 - 2.5 an integer: u =
 * 1/8, 3/8, 5/8, 7/8) or an end tap's x reaches 2 (the bicubic family's zero: the window a
 * texel narrower; u = k / 4 + 1/8 moved by the tap's offset), a few ulps either side, or as
 * coord(). */
static float q8_coord(void)
{
    float b = (float)((int)(rnd01() * 4)) * 0.25f + 0.125f;
    switch ((int)(rnd01() * 3)) {
    case 0: {
        float u = b + (float)((int)(rnd01() * 7) - 3) * 3e-8f;
        u = u < 0.0f ? 0.0f : u;
        return u < 0.99999994f ? u : 0.99999994f;
    }
    case 1: return coord();
    default: return rnd01();
    }
}

static void make_queries(st_query *q, int iso)
{
    for (int j = 0; j < NQ; j++) {
        if (iso == 2) {
            float wu = q8_width(), wv = rnd01() < 0.6f ? wu : q8_width();
            q[j] = (st_query){.face = 0, .u = q8_coord(), .v = q8_coord(), .dudx = wu,
                              .dvdy = wv};
            if (j % 101 == 7)
                q[j].dudx = NAN; /* clamped to the face's texel, as pk_width4_axis does */
            continue;
        }
        if (iso) {
            float wu = iso_width(), wv = rnd01() < 0.6f ? wu : iso_width();
            q[j] = (st_query){.face = 0, .u = iso_coord(wu), .v = iso_coord(wv), .dudx = wu,
                              .dvdy = wv};
            continue;
        }
        float wu = width(), wv = rnd01() < 0.7f ? wu : width();
        q[j] = (st_query){.face = 0, .u = coord(), .v = coord(), .dudx = wu, .dvdy = wv};
        if (rnd01() < 0.3f) /* the width as the sum of two derivatives */
            q[j].dudx = wu * 0.25f, q[j].dudy = wu * 0.75f;
        if (j % 97 == 5)
            q[j].face = 7; /* past the faces: a query that fails */
        if (j % 89 == 11)
            q[j].dvdy = NAN;
    }
}

/* What lanes_served's blocks go through: the 8-query function under test and its options. */
typedef struct {
    int iso, blu, blv, discard;
    unsigned dt, nc;
    pk_params pp;
} served_arg;

static unsigned serve8(const pf_klanes *k, void *arg)
{
    served_arg *a = arg;
    float out[8 * 4], cov[8];
    unsigned m;
    if (a->iso == 2) {
        pf_q8 t;
        m = pf_q8_select()(&a->pp, k, k->nonb, a->blu, a->blv, a->discard, a->dt, &t);
    } else
        m = (a->iso ? pf_iso8_select : pf_r0x8_select)(a->dt, a->nc)(a->blu, a->blv, a->discard,
                                                                    k, out, cov);
    assert_int_equal(m & ~k->nonb, 0);
    return m;
}

/* The lanes of q's blocks that the 8-query function of iso (0 r0x8, 1 iso8, 2 q8) serves
 * for filter ft in mode `mode` (klanes8 first, as kernel_run calls them). */
static long lanes_served(const st_set *s, const st_query *q, unsigned ft, unsigned mode,
                         int iso)
{
    served_arg a = {.iso = iso, .blu = s->info.border_u == 1, .blv = s->info.border_v == 1,
                    .discard = mode == ST_MODE_DISCARD, .dt = s->info.dtype,
                    .nc = s->info.nchan};
    pk_params_init(&a.pp, ft, 0.0f, 1);
    assert_non_null(pf_r0x8_select(a.dt, a.nc));
    assert_non_null(pf_q8_select());
    long n = st_pf_lanes_served(s, q, NQ, ft, serve8, &a);
    assert_true(n >= 0);
    return n;
}

static long compare(const st_set *s, const st_query *q, const char *what)
{
    long n = st_pf_paths_agree(s, q, NQ, what, filters, NF);
    if (n < 0)
        fail();
    return n;
}

/* The one-face file rel of SEAMTEX_DATA read (its path in path), or NULL when it is not
 * there. */
static st_set *one_face_file(const char *rel, char *path, size_t cap)
{
    st_set *s;
    assert_true(st_pf_read_shared(rel, path, cap, &s) >= 0);
    return s;
}

static void lanes_match_the_general_path(int iso)
{
    ST_SKIP_WITHOUT_AVX2();
    static const char *const rels[] = {"tri/quad", "bordermodes/black", "bordermodes/clamp",
                                       "bordermodes/periodic"};
    static st_query q[NQ];
    long compared = 0, served[3] = {0};
    int found = 0;
    for (size_t i = 0; i < sizeof rels / sizeof rels[0]; i++) {
        char rel[128], path[1024];
        snprintf(rel, sizeof rel, "ptx/wdas-ptex-2009/%s.ptx", rels[i]);
        st_set *s = one_face_file(rel, path, sizeof path);
        if (!s)
            continue;
        found++;
        make_queries(q, iso);
        uint8_t bu = s->info.border_u, bv = s->info.border_v;
        for (uint8_t b = 0; b <= 4; b++) { /* as read, clamp, black, periodic, mixed */
            if (b == 4)
                s->info.border_u = 1, s->info.border_v = 0;
            else if (b)
                s->info.border_u = s->info.border_v = (uint8_t)(b - 1);
            compared += compare(s, q, path);
            for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++)
                served[m - ST_MODE_DISCARD] +=
                    lanes_served(s, q, ST_FILTER_PTEX_GAUSSIAN, m, iso);
        }
        s->info.border_u = bu;
        s->info.border_v = bv;
        uint8_t fl = s->faces[0].flags;
        s->faces[0].flags = (uint8_t)(fl | ST_FACE_CONSTANT);
        compared += compare(s, q, path);
        s->faces[0].flags = (uint8_t)(fl | ST_FACE_SUBFACE);
        compared += compare(s, q, path);
        s->faces[0].flags = fl;
        st_set_free(s);
    }
    if (!found) {
        print_message("SEAMTEX_DATA (%s) has none of the files: skipped\n", st_test_data_dir());
        skip();
    }
    print_message("%s: %d files, %ld queries compared; lanes served 8 at a time: Discard "
                  "%ld, Traverse %ld, Clamp %ld\n", iso == 2 ? "q8" : iso ? "iso8" : "r0x8",
                  found, compared, served[0], served[1], served[2]);
    /* 3 of the files have no neighbours, 5 border settings: most lanes are served (q8 in
     * Discard too, inside the face as well as overhanging it: session 21) */
    for (int m = 0; m < 3; m++)
        assert_true(served[m] > 3 * 5 * NQ / (iso == 2 ? 2 : iso ? 3 : 4));
}

static void r0_lanes_match_the_general_path(void **state)
{
    (void)state;
    lanes_match_the_general_path(0);
}

static void iso_lanes_match_the_general_path(void **state)
{
    (void)state;
    lanes_match_the_general_path(1);
}

static void q8_lanes_match_the_general_path(void **state)
{
    (void)state;
    lanes_match_the_general_path(2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(r0_lanes_match_the_general_path),
        cmocka_unit_test(iso_lanes_match_the_general_path),
        cmocka_unit_test(q8_lanes_match_the_general_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
