/* tests/unit/test_ptexfilter_walk.c - the split of a box or width-4 kernel that overhangs a
 * plain face (the shortcut walks of ptexfilter_walk.c: Traverse's splits, Discard's and
 * Clamp's merges since session 13; the fused path's wide
 * kernels and its hand-over) gives the general path's outputs bit for bit where the walk has
 * choices to make: boundary edges folded back or dropped (each file also sampled with its
 * border modes set to black and to periodic), neighbours at other resolutions (reductions),
 * rotated frames, vertices of valence 3 and 5 (holeycube), and neighbours the walk declines
 * (a tenth of the faces flagged constant, then a tenth flagged subface, after the resolution
 * table is built: both paths then read the same memory, and the walk must hand those queries
 * back to the general walk from the start). Queries sit within two texels of an edge or a
 * corner, footprints 1-64 texels (kernels of a quarter face and wider on small faces),
 * isotropic and not; box, gaussian, bicubic, Catmull-Rom and Mitchell (negative lobes); all
 * three modes. Outputs, coverage and status are compared as bytes against
 * pf_batch_path(PF_PATH_GENERAL) (every query through eval). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <string.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "half.h"
#include "ptexfilter_kernel.h"
#include "sample.h"
#include "../common/pffiles.h"
#include "../common/pfpaths.h"
#include "../common/testdata.h"

enum { NQ = 3000 };

static uint32_t rng = 17;
static float rnd01(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

/* Within two level-0 texels of an edge (half the queries) or a corner (the other half). */
static void edge_queries(const st_set *s, st_query *q)
{
    static const float fps[] = {1.0f, 2.0f, 3.0f, 4.0f, 6.0f, 8.0f, 16.0f, 64.0f};
    for (int i = 0; i < NQ; i++) {
        uint32_t f = (uint32_t)(rnd01() * (float)s->info.nfaces) % s->info.nfaces;
        const st_face *F = &s->faces[f];
        float du = rnd01() * 2.0f / (float)F->w, dv = rnd01() * 2.0f / (float)F->h;
        float u = rnd01() < 0.5f ? du : 1.0f - du, v = rnd01();
        if (i % 2)
            v = rnd01() < 0.5f ? dv : 1.0f - dv;
        if (i % 4 == 3) { /* the same, edges v = 0 and v = 1 */
            float t = u;
            u = v;
            v = t;
        }
        u = u < 0.99999994f ? u : 0.99999994f;
        v = v < 0.99999994f ? v : 0.99999994f;
        float fu = fps[(int)(rnd01() * 8) & 7], fv = i % 3 == 1 ? fps[(int)(rnd01() * 8) & 7] : fu;
        q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = fu / (float)F->w,
                          .dvdy = fv / (float)F->h};
    }
}

/* Both paths on q for the nf filters in every mode (pfpaths.h); returns the queries
 * compared. */
static long compare_filters(const st_set *s, const st_query *q, const char *what,
                            const unsigned *filters, size_t nf)
{
    long n = st_pf_paths_agree(s, q, NQ, what, filters, nf);
    if (n < 0)
        fail();
    return n;
}

/* The kernel filters. */
static const unsigned kernel_filters[] = {ST_FILTER_PTEX_BOX, ST_FILTER_PTEX_GAUSSIAN,
                                          ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_CATMULLROM,
                                          ST_FILTER_PTEX_MITCHELL};
enum { NKF = sizeof kernel_filters / sizeof kernel_filters[0] };

/* Both paths on q for the kernel filters in every mode; returns the queries compared. */
static long compare_paths(const st_set *s, const st_query *q, const char *what)
{
    return compare_filters(s, q, what, kernel_filters, NKF);
}

/* compare_filters with the set's border modes set to clamp, black and periodic in turn (then
 * put back). */
static long compare_border_modes(st_set *s, const st_query *q, const char *what,
                                 const unsigned *filters, size_t nf)
{
    long n = 0;
    uint8_t bu = s->info.border_u, bv = s->info.border_v;
    for (uint8_t b = 0; b <= 2; b++) { /* clamp, black, periodic */
        s->info.border_u = s->info.border_v = b;
        n += compare_filters(s, q, what, filters, nf);
    }
    s->info.border_u = bu;
    s->info.border_v = bv;
    return n;
}

/* compare_paths with a tenth of the faces flagged constant, then (that flag cleared) with a
 * tenth flagged subface: flags set after the table and the corners are made. */
static long compare_flagged(st_set *s, const st_query *q, const char *path)
{
    long n = 0;
    st_pf_flag_faces(s, ST_FACE_CONSTANT, 0); /* pffiles.h: every tenth face */
    n += compare_paths(s, q, path);
    st_pf_flag_faces(s, ST_FACE_SUBFACE, ST_FACE_CONSTANT);
    n += compare_paths(s, q, path);
    return n;
}

/* compare_paths on q as the set is, then compare_flagged. */
static long compare_plain_flagged(st_set *s, const st_query *q, const char *path)
{
    long n = compare_paths(s, q, path);
    return n + compare_flagged(s, q, path);
}

/* fn(set, queries, path) for each of the n shared files the data folder has, each read into
 * its own set (freed after: st_pf_each_file); fn returns how many queries it compared.
 * Skipped when the data folder has none of the files. */
typedef long (*file_check)(st_set *s, st_query *q, const char *path);
typedef struct {
    file_check fn;
    st_query *q;
} check_ctx;

static long run_check(st_set *s, void *ctx, const char *path)
{
    const check_ctx *c = ctx;
    return c->fn(s, c->q, path);
}

static void check_files(const char *const *files, size_t n, file_check fn)
{
    static st_query q[NQ];
    check_ctx c = {fn, q};
    int found;
    long compared = st_pf_each_file(files, n, run_check, &c, &found);
    assert_true(compared >= 0);
    if (!found) {
        print_message("SEAMTEX_DATA (%s) has none of the files: skipped\n", st_test_data_dir());
        skip();
    }
    print_message("%d files, %ld queries compared\n", found, compared);
}

static long overhanging_file(st_set *s, st_query *q, const char *path)
{
    long n = 0;
    edge_queries(s, q);
    n += compare_paths(s, q, path); /* also builds the table */
    uint8_t bu = s->info.border_u, bv = s->info.border_v;
    for (uint8_t b = 1; b <= 2; b++) { /* black, periodic */
        s->info.border_u = s->info.border_v = b;
        n += compare_paths(s, q, path);
    }
    s->info.border_u = bu;
    s->info.border_v = bv;
    n += compare_flagged(s, q, path);
    return n;
}

static void overhanging_kernels_match_the_general_walk(void **state)
{
    (void)state;
    static const char *files[] = {
        "ptx/wdas-ptex-samples/teapot/teapot.ptx",
        "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
        "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx",
        "ptex-ref/cube8_k6_u8_rot.ptx",
        "ptex-ref/cube8_k7varrot_f32.ptx",
    };
    check_files(files, sizeof files / sizeof files[0], overhanging_file);
}

/* Session 14 (walk7): in Traverse a kernel of a face at a mesh boundary goes to
 * ptexfilter_walk.c's walk_boundary (the fold when no edge it overhangs has a neighbour, the
 * whole walk with its folds otherwise) and the corner piece of a valence-3 vertex is dropped
 * by corner() itself; the half texels of the point filter load through pk_half4. The
 * one-face files of bordermodes (every overhang a boundary fold; black and clamp.ptx half
 * texels, each also sampled with the other border modes) and cube1_k6_u8 (every corner of
 * valence 3), every filter but the triangle's, all three modes, against the general path. */
static long boundary_file(st_set *s, st_query *q, const char *path)
{
    static const unsigned filters[] = {ST_FILTER_PTEX_POINT, ST_FILTER_PTEX_BILINEAR,
                                       ST_FILTER_PTEX_BOX, ST_FILTER_PTEX_GAUSSIAN,
                                       ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_MITCHELL};
    const size_t nf = sizeof filters / sizeof filters[0];
    long n = 0;
    edge_queries(s, q);
    n += compare_filters(s, q, path, filters, nf);
    return n + compare_border_modes(s, q, path, filters, nf);
}

/* The one-face files of bordermodes and cube1_k6_u8 (valence-3 corners). */
static const char *const bordermode_files[] = {
    "ptx/wdas-ptex-2009/bordermodes/black.ptx",
    "ptx/wdas-ptex-2009/bordermodes/clamp.ptx",
    "ptx/wdas-ptex-2009/bordermodes/periodic.ptx",
    "ptex-ref/cube1_k6_u8.ptx",
};
enum { NBF = sizeof bordermode_files / sizeof bordermode_files[0] };

static void boundary_folds_and_valence3_corners_match_the_general_path(void **state)
{
    (void)state;
    check_files(bordermode_files, NBF, boundary_file);
}

/* Session 15 (walk8): a kernel that overhangs one u edge and one v edge, each to a
 * neighbour, takes walk_two (ptexfilter_walk.c), and a regular corner's diagonal face comes
 * from the set's cornerface (its subface flags tested at run time). Queries as bench_ptex
 * makes them (uniform face and (u, v), footprints of 2 to 24 level-0 texels, isotropic and
 * not: at 4 and more most of the teapot's kernels overhang two edges), on files with mixed
 * face sizes (teapot: reductions), rotated neighbours (cube8_k6_u8_rot, cube8_k7varrot_f32),
 * vertices of valence 3 (cube1_k6_u8) and 5 (holeycube); every kernel filter in every mode,
 * then with a tenth of the faces flagged subface and, separately, constant (after the table
 * and the corners are made: the cornerface of a vertex with a subface is still set, so the
 * run-time test must send it back to the general walk). Against the general path. */
static long two_edge_file(st_set *s, st_query *q, const char *path)
{
    static const float fps[] = {2.0f, 3.0f, 4.0f, 6.0f, 8.0f, 12.0f, 16.0f, 24.0f};
    for (int j = 0; j < NQ; j++) {
        uint32_t f = (uint32_t)(rnd01() * (float)s->info.nfaces) % s->info.nfaces;
        const st_face *F = &s->faces[f];
        float fu = fps[(int)(rnd01() * 8) & 7];
        float fv = j % 3 == 1 ? fps[(int)(rnd01() * 8) & 7] : fu;
        q[j] = (st_query){.face = f, .u = rnd01(), .v = rnd01(),
                          .dudx = fu / (float)F->w, .dvdy = fv / (float)F->h};
    }
    return compare_plain_flagged(s, q, path);
}

/* Files with mixed face sizes (teapot: reductions), rotated neighbours (cube8_k6_u8_rot,
 * cube8_k7varrot_f32), vertices of valence 3 (cube1_k6_u8) and 5 (holeycube). */
static const char *const mixed_files[] = {
    "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
    "ptex-ref/cube8_k6_u8_rot.ptx",
    "ptex-ref/cube8_k7varrot_f32.ptx",
    "ptex-ref/cube1_k6_u8.ptx",
};

static void two_edge_kernels_match_the_general_walk(void **state)
{
    (void)state;
    check_files(mixed_files, sizeof mixed_files / sizeof mixed_files[0], two_edge_file);
}

/* Query j of a walk test with widths relative to the face: a uniform face, widths from rel
 * (8 of them; the axes alike but for every third query), (u, v) uniform, u near an edge for
 * every fourth (j % 4 == 1); not clamped below 1. */
static void rel_query(const st_set *s, const float *rel, int j, st_query *q)
{
        uint32_t f = (uint32_t)(rnd01() * (float)s->info.nfaces) % s->info.nfaces;
        float ru = rel[(int)(rnd01() * 8) & 7];
        float rv = j % 3 == 1 ? rel[(int)(rnd01() * 8) & 7] : ru;
        float u = rnd01(), v = rnd01();
        if (j % 4 == 1) /* near an edge */
            u = rnd01() < 0.5f ? u * 0.1f : 1.0f - u * 0.1f;
    *q = (st_query){.face = f, .u = u, .v = v, .dudx = ru, .dvdy = rv};
}

/* Session 23 (gauss23): the width-4 kernels the per-query path builds one by one
 * (kernel_declined_with: a width of 1/4 face or more, or a face under 8 x 8 texels) are
 * built 8 at a time in blocks that offer the 8-query fused path under 3 lanes (pf_b8:
 * widths under 1/4, [1/4, 1/2), [1/2, 1) and 1 or more after the clamp to a texel of the
 * face, each with its own resolution, taps and weights; zero end taps stripped) and handed
 * to kernel_built (inside the face: apply; else the walk; else eval_kernel). Widths per
 * axis drawn independently from every band and its edges (1/4, 1/2, 1, and kernel_r0's
 * both 1 or more, which pf_b8 leaves), scaled so that faces of 2 to 64 texels see each
 * band; (u, v) anywhere, on the texel centres of 2, 4 and 8-texel grids (the bicubic
 * family's zero end taps, the hermite's zero second tap) or near an edge; the faces as they are, then
 * flagged constant and subface; every kernel filter, every mode, against the general path. */
static long built8_file(st_set *s, st_query *q, const char *path)
{
    static const float wsel[] = {0.25f, 0.5f, 1.0f, 2.0f, 0.3f, 0.7f, 1.4f, 0.125f,
                                 0.2f, 0.0625f, 0.45f, 0.99f, 0.03f, 0.6f, 0.26f, 3.0f};
    for (int j = 0; j < NQ; j++) {
        uint32_t f = (uint32_t)(rnd01() * (float)s->info.nfaces) % s->info.nfaces;
        float bu = wsel[(int)(rnd01() * 16) & 15], bv = wsel[(int)(rnd01() * 16) & 15];
        if (j % 5 == 4) /* a random width, up to 2 faces */
            bu = rnd01() * 2.0f;
        float u = rnd01(), v = rnd01();
        if (j % 4 == 1) { /* on a texel centre at resolution 1, 2 or 4 */
            float r = (float)(2 << (j / 4 % 3));
            u = ((float)(int)(u * r) + 0.5f) / r;
            v = ((float)(int)(v * r) + 0.5f) / r;
        } else if (j % 4 == 2) { /* near an edge */
            u = rnd01() < 0.5f ? u * 0.05f : 1.0f - u * 0.05f;
        }
        q[j] = (st_query){.face = f,
                          .u = u < 0.99999994f ? u : 0.99999994f,
                          .v = v < 0.99999994f ? v : 0.99999994f,
                          .dudx = bu, .dvdy = bv};
    }
    return compare_plain_flagged(s, q, path);
}

static void declined_kernels_built_8_at_a_time_match_the_general_path(void **state)
{
    (void)state;
    static const char *const files[] = {
        "ptx/wdas-ptex-samples/teapot/teapot.ptx",
        "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
        "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx",
        "ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx",
        "ptex-ref/cube8_k6_u8_rot.ptx",
        "ptex-ref/cube8_k7varrot_f32.ptx",
        "ptex-ref/cube1_k6_u8.ptx",
    };
    check_files(files, sizeof files / sizeof files[0], built8_file);
}

/* Session 16 (walk9): a kernel that overhangs one edge, or one u and one v edge, into plain
 * neighbours takes ptexfilter_walk.c's lean walks first (lean_one_case, lean_two_case:
 * the faces' flags, the overhangs' widths and the pieces' resolutions checked once, then
 * the windows without put_face's per-piece checks; a kernel at resolution 1 x 1 takes one
 * texel of table entry 0 per piece, its axes' weights swapped by odd rotations), else the
 * walks as before. Footprints relative to each face's size (the kernel at resolution 1, 2,
 * 4, 8 along each axis, the axes alike or not), (u, v) near an edge, a corner or anywhere,
 * on files with rotated neighbours (teapot, cube8_k6_u8_rot, cube8_k7varrot_f32: the odd
 * rotations that swap a 1 x 1 kernel's weights), smaller neighbours (teapot, varrot: the
 * lean walks must hand reductions back), corners of valence 3 and 5 (cube1_k6_u8,
 * holeycube: no cornerface), with a tenth of the faces flagged subface and then constant
 * after the set is made; every kernel filter, every mode, against the general path. */
static long lean_file(st_set *s, st_query *q, const char *path)
{
    static const float rel[] = {1.0f, 1.5f, 3.0f, 0.75f, 0.5f, 0.3f, 0.25f, 0.125f};
    for (int j = 0; j < NQ; j++) {
        rel_query(s, rel, j, &q[j]);
        float u = q[j].u, v = q[j].v;
        if (j % 4 == 2) { /* near a corner */
            u = rnd01() < 0.5f ? u * 0.1f : 1.0f - u * 0.1f;
            v = rnd01() < 0.5f ? v * 0.1f : 1.0f - v * 0.1f;
        }
        q[j].u = u < 0.99999994f ? u : 0.99999994f;
        q[j].v = v < 0.99999994f ? v : 0.99999994f;
    }
    return compare_plain_flagged(s, q, path);
}

static void lean_walks_match_the_general_walk(void **state)
{
    (void)state;
    check_files(mixed_files, sizeof mixed_files / sizeof mixed_files[0], lean_file);
}

/* Session 17 (walk10): a width-4 kernel at resolution 1 x 1 (a footprint of a face or more
 * along both axes) is built and stripped by ptexfilter.c's kernel_r0 (1 or 2 taps an axis:
 * (u, v) = 0.5 leaves the first tap alone, 0.49999997 the second), and a boundary fold of
 * such a kernel merges its two taps and takes the face's one texel (ptexfilter_walk.c's
 * fold). Widths on either side of a face (0.999 and 1: the general build next to it), the
 * axes alike or not, (u, v) anywhere, near an edge or at those two values; the one-face
 * files of bordermodes and tri/quad.ptx under each border mode, teapot and cube1_k6_u8
 * (neighbours, valence-3 corners) plain and with a tenth of the faces flagged; every kernel
 * filter, every mode, against the general path. */
static long one_texel_file(st_set *s, st_query *q, const char *path)
{
    static const float rel[] = {1.0f, 1.5f, 4.0f, 0.999f, 2.0f, 1.0f, 16.0f, 0.5f};
    static const float at[] = {0.5f, 0.49999997f, 0.0f, 0.99999994f};
    for (int j = 0; j < NQ; j++) {
        rel_query(s, rel, j, &q[j]);
        float u = q[j].u, v = q[j].v;
        if (j % 8 == 2) /* one tap left along u, or v, or both */
            u = at[(int)(rnd01() * 4) & 3];
        if (j % 8 == 6)
            v = at[(int)(rnd01() * 4) & 3];
        if (j % 16 == 10)
            u = at[(int)(rnd01() * 2) & 1];
        q[j].u = u < 0.99999994f ? u : 0.99999994f;
        q[j].v = v < 0.99999994f ? v : 0.99999994f;
    }
    long n = compare_plain_flagged(s, q, path);
    return n + compare_border_modes(s, q, path, kernel_filters, NKF);
}

static void one_texel_kernels_match_the_general_path(void **state)
{
    (void)state;
    static const char *const more[] = {
        "ptx/wdas-ptex-2009/tri/quad.ptx",
        "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    };
    check_files(bordermode_files, NBF, one_texel_file);
    check_files(more, sizeof more / sizeof more[0], one_texel_file);
}

/* Session 24 (w424): a width-4 kernel at resolution 1 x 1 with 2 taps an axis (kernel_r0's,
 * (u, v) not on a texel centre) overhangs one u and one v edge by a texel; where both have
 * neighbours and their corner is a regular vertex, or one has a neighbour and the other is
 * a mesh boundary, pf_walk_kernel_r0 sums its four (two) one-texel windows in one
 * pf_small4 (pf_small2) call, the weights swapped by odd rotations, the boundary axis
 * folded (dropped at a black border); where their corner has no cornerface (valence 3:
 * dropped; 5 and more: shared, made symmetric), r0_other (session 30) sums the pieces in
 * walk_two's order. Widths of a face or more, the axes alike or not, (u, v)
 * anywhere; files with rotated neighbours of every rotation (cube8_k6_u8_rot), 1 to 4
 * channels of u8 to float (cube8_k7varrot_f32, teapot, rand_lo: u16), mesh boundaries
 * (rand_lo, holeycube), valence-3 and 5 corners (cube1_k6_u8, holeycube: no cornerface);
 * plain, with a tenth of the faces flagged constant then subface, under each border mode
 * and with black along one axis only; every kernel filter, every mode, against the general path. */
static long r0_walk_file(st_set *s, st_query *q, const char *path)
{
    static const float rel[] = {1.0f, 1.5f, 2.0f, 4.0f, 1.25f, 16.0f, 3.0f, 1.0f};
    for (int j = 0; j < NQ; j++) {
        rel_query(s, rel, j, &q[j]);
        if (j % 8 == 3) /* near a corner */
            q[j].v = rnd01() < 0.5f ? q[j].v * 0.05f : 1.0f - q[j].v * 0.05f;
        q[j].u = q[j].u < 0.99999994f ? q[j].u : 0.99999994f;
        q[j].v = q[j].v < 0.99999994f ? q[j].v : 0.99999994f;
    }
    long n = compare_plain_flagged(s, q, path);
    n += compare_border_modes(s, q, path, kernel_filters, NKF);
    /* black along one axis only (the fold drops that axis' overhang, keeps the other's) */
    uint8_t bu = s->info.border_u, bv = s->info.border_v;
    for (uint8_t b = 0; b <= 1; b++) {
        s->info.border_u = b;
        s->info.border_v = (uint8_t)!b;
        n += compare_paths(s, q, path);
    }
    s->info.border_u = bu;
    s->info.border_v = bv;
    return n;
}

static void one_texel_walks_in_one_call_match_the_general_path(void **state)
{
    (void)state;
    static const char *const files[] = {
        "ptex-ref/cube8_k6_u8_rot.ptx",
        "ptex-ref/cube8_k7varrot_f32.ptx",
        "ptx/wdas-ptex-samples/teapot/teapot.ptx",
        "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx",
        "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
        "ptex-ref/cube1_k6_u8.ptx",
    };
    check_files(files, sizeof files / sizeof files[0], r0_walk_file);
}

/* pk_half4 (the half texels' loads of the point filter and the portable bilinear) gives
 * st_half_to_float's bits for every one of the 65536 halves, in every lane, and zeros the
 * lanes past the channel count. */
static void half_loads_match_the_scalar_conversion_bit_for_bit(void **state)
{
    (void)state;
    uint8_t buf[16] = {0};
    long bad = 0;
    for (uint32_t h = 0; h < 65536; h++) {
        for (unsigned lane = 0; lane < 4; lane++) {
            uint16_t x[8] = {0x3c00, 0xbc00, 0x7e01, 0x0001, 0, 0, 0, 0};
            x[lane] = (uint16_t)h;
            memcpy(buf, x, sizeof buf);
            for (unsigned nc = 1; nc <= 4; nc++) {
                pk_v4f r = pk_half4(buf, nc);
                for (unsigned ch = 0; ch < 4; ch++) {
                    float want = ch < nc ? st_half_to_float(x[ch]) : 0.0f, got = r[ch];
                    uint32_t wb, gb;
                    memcpy(&wb, &want, 4);
                    memcpy(&gb, &got, 4);
                    bad += wb != gb;
                }
            }
        }
    }
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(overhanging_kernels_match_the_general_walk),
        cmocka_unit_test(boundary_folds_and_valence3_corners_match_the_general_path),
        cmocka_unit_test(two_edge_kernels_match_the_general_walk),
        cmocka_unit_test(lean_walks_match_the_general_walk),
        cmocka_unit_test(declined_kernels_built_8_at_a_time_match_the_general_path),
        cmocka_unit_test(one_texel_kernels_match_the_general_path),
        cmocka_unit_test(one_texel_walks_in_one_call_match_the_general_path),
        cmocka_unit_test(half_loads_match_the_scalar_conversion_bit_for_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
