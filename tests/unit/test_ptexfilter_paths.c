/* tests/unit/test_ptexfilter_paths.c - the Ptex filters' per-batch shortcuts (point and bilinear
 * per texel type, bilinear inside a face and across its edges and corners, the fused path of
 * box and width-4 kernels of every width, the shortcut walk and ptexfilter_walk.c's split of
 * kernels of any size that overhang a plain face, the small-window loop) give the general
 * path's outputs bit for bit:
 * on every shared .ptx file (SEAMTEX_DATA ptex-ref/ and ptx/, walked, so a new file is
 * covered), every filter, Traverse, Discard and Clamp, many random queries - a third of them
 * near a face edge or corner, some on texel centres - at footprints from a quarter texel to 32 texels, isotropic and
 * not, with default and non-default width and blur. Outputs, coverage and status are compared
 * as bytes (pf_batch_path with PF_PATH_GENERAL runs every query through eval). The bilinear is
 * also compared along its per-query path and its 4-lane (SSE2) lanes, whatever the CPU, and
 * its lanes on blocks that mix queries they serve with every kind they must leave to the
 * per-query path, in batches of every length up to 40 (ptexfilter_lanes.h), and its 2 x 2
 * kernel over every edge and corner of every face at every resolution; the batch loop of
 * the box and width-4 filters (kernel_run) on the same mix, and their kernels over every
 * edge and corner of every face (the walks they take in Traverse). */
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

/* Reads every shared .ptx file and runs body on it (compared counts the queries compared);
 * skips the test when there are none. */
typedef void ptx_body(const char *path, st_set *s, long *compared);
static void for_each_ptx(ptx_body *body)
{
    static char rel[MAXF][512], path[1024];
    int n = st_test_ptx_files(rel, MAXF);
    if (n == 0) {
        print_message("SEAMTEX_DATA (%s) has no .ptx files: skipped\n", st_test_data_dir());
        skip();
    }
    long compared = 0;
    for (int i = 0; i < n; i++) {
        if (snprintf(path, sizeof path, "%s/%s", st_test_data_dir(), rel[i]) >= (int)sizeof path)
            fail_msg("data dir path too long: %s", st_test_data_dir());
        st_set *s;
        st_error e = {0};
        assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
        body(path, s, &compared);
        st_set_free(s);
    }
    print_message("%d files, %ld queries compared\n", n, compared);
}

/* Runs q[0..nq) through path and through the general path; fails unless outputs, coverage,
 * status and the return value are the same bytes. */
static void compare_paths(const char *name, const st_set *s, const st_sample_opts *o,
                          const st_query *q, size_t nq, int path)
{
    static float o1[NQ * 4], o2[NQ * 4], c1[NQ], c2[NQ];
    static uint8_t s1[NQ], s2[NQ];
    assert_true(nq <= NQ);
    size_t nv = nq * s->info.nchan;
    memset(o1, 0x5a, sizeof o1);
    memset(o2, 0xa5, sizeof o2);
    memset(c1, 0x5a, sizeof c1);
    memset(c2, 0xa5, sizeof c2);
    memset(s1, 0x5a, sizeof s1);
    memset(s2, 0xa5, sizeof s2);
    int b1 = pf_batch_path(s, o, q, nq, o1, c1, s1, path);
    int b2 = pf_batch_path(s, o, q, nq, o2, c2, s2, PF_PATH_GENERAL);
    assert_int_equal(b1, b2);
    for (size_t k = 0; k < nv; k++) {
        if (memcmp(&o1[k], &o2[k], sizeof(float))) {
            size_t qi = k / s->info.nchan;
            print_message("%s path %d mode %u filter %u width %g blur %g query %zu of %zu (face "
                          "%u u %.9g v %.9g dudx %.9g dvdy %.9g): %.9g != %.9g\n",
                          name, path, o->mode, o->filter, (double)o->width, (double)o->blur,
                          qi, nq, q[qi].face, (double)q[qi].u, (double)q[qi].v,
                          (double)q[qi].dudx, (double)q[qi].dvdy, (double)o1[k], (double)o2[k]);
            fail();
        }
    }
    assert_memory_equal(c1, c2, nq * sizeof c1[0]);
    assert_memory_equal(s1, s2, nq);
}

/* the options' width and blur: the defaults, and others */
static const float WIDTH_BLUR[2][2] = {{0.0f, 0.0f}, {1.5f, 0.01f}};

static void every_path(const char *path, st_set *s, long *compared)
{
    static st_query q[NQ];
    make_queries(s, q);
    for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++) {
        for (unsigned flt = ST_FILTER_PTEX_POINT; flt <= ST_FILTER_PTEX_MITCHELL; flt++) {
            for (int w = 0; w < 2; w++) {
                st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)flt,
                                    .width = WIDTH_BLUR[w][0], .blur = WIDTH_BLUR[w][1],
                                    .sharpness = 0.5f};
                /* st_ptexfilter_batch's own path, then (bilinear only here; the box and
                 * width-4 filters' per-query path is checked on the mix of kernel_mixed) the
                 * per-query shortcuts and the 4-lane bilinear */
                compare_paths(path, s, &o, q, NQ, PF_PATH_BEST);
                *compared += NQ;
                if (flt != ST_FILTER_PTEX_BILINEAR)
                    continue;
                compare_paths(path, s, &o, q, NQ, PF_PATH_QUERY);
                compare_paths(path, s, &o, q, NQ, PF_PATH_LANES4);
                *compared += 2 * NQ;
            }
        }
    }
}

static void shortcuts_give_the_general_paths_results_bit_for_bit(void **state)
{
    (void)state;
    for_each_ptx(every_path);
}

/* The bilinear lanes (8 with AVX2, 4 with SSE2) take the queries of a block that they can
 * serve, hand the kernel set-up of those that overhang their face or sit on a texel centre
 * to the 2 x 2 kernel's path and leave the others to the per-query path (and the point
 * filter's batch loop checks each query itself): blocks that mix in-face queries with
 * every kind the lanes must refuse - a face out of range, NaN, infinite and too large
 * derivatives, u or v outside [0, 1) (1 itself, just below 0, NaN), queries on texel
 * centres (a fraction of 0), next to an edge, on subfaces, constant faces and faces with a
 * constant neighbourhood (whichever the file has), tiny and huge footprints, negative
 * derivatives and -0 - in batches of every length from 1 to 40 (tails of every size) and at
 * every offset, with default and non-default width and blur, in the three modes. */
static void make_mix(const st_set *s, st_query *q)
{
    const float inf = 1.0f / 0.0f;
    uint32_t nf = s->info.nfaces;
    for (int k = 0; k < NQ; k++) {
        uint32_t f = (uint32_t)(rndf() * (float)nf) % nf;
        const st_face *F = &s->faces[f];
        float fp = k % 11 == 0 ? 0.01f : k % 13 == 0 ? 40.0f : 0.25f + 4.0f * rndf();
        st_query x = {.face = f, .u = rndf(), .v = rndf(), .dudx = fp / (float)F->w,
                      .dvdy = fp / (float)F->h};
        switch (k % 17) {
        case 1: x.face = nf + (uint32_t)(rndf() * 5.0f); break;
        case 2: x.face = 0xffffffffu; break;
        case 3: x.dudx = 0.0f / 0.0f; break;
        case 4: x.dvdy = inf; break;
        case 5: x.dudy = 2.0e4f; break;
        case 6: x.u = 1.0f; break;
        case 7: x.v = -1e-7f; break;
        case 8: x.u = 0.0f / 0.0f; break;
        case 9: x.u = ((float)(int)(rndf() * (float)F->w) + 0.5f) / (float)F->w;
                x.dudx = 1.0f / (float)F->w; break;
        case 10: x.v = 0.5f / (float)F->h; x.dvdy = 1.0f / (float)F->h; break;
        case 11: x.dudx = -x.dudx; x.dvdx = -0.0f; x.dudy = -0.0f; break;
        case 12: x.dvdx = 0.5f * x.dudx; x.dudy = -0.25f * x.dvdy; break;
        case 13: x.u = 0.0f; x.v = 0.99999994f; break;
        default: break;
        }
        q[k] = x;
    }
}

static void mixed_blocks(const char *path, st_set *s, long *compared)
{
    static st_query q[NQ];
    static const float widths[3][2] = {{0.0f, 0.0f}, {1.5f, 0.01f}, {0.3f, 0.0f}};
    make_mix(s, q);
    for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++) {
        for (int w = 0; w < 3; w++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = ST_FILTER_PTEX_BILINEAR,
                                .width = widths[w][0], .blur = widths[w][1]};
            compare_paths(path, s, &o, q, NQ, PF_PATH_BEST);
            compare_paths(path, s, &o, q, NQ, PF_PATH_LANES4);
            *compared += 2 * NQ;
        }
    }
    for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++) {
        /* the point filter's own batch loop (its checks inline) on the same mix */
        st_sample_opts op = {.mode = (uint8_t)m, .filter = ST_FILTER_PTEX_POINT};
        compare_paths(path, s, &op, q, NQ, PF_PATH_BEST);
        *compared += NQ;
    }
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_BILINEAR};
    for (size_t len = 1; len <= 40; len++) {
        for (size_t at = 0; at < 9; at++) {
            compare_paths(path, s, &o, q + at * 41 + len, len, PF_PATH_BEST);
            compare_paths(path, s, &o, q + at * 41 + len, len, PF_PATH_LANES4);
            *compared += 2 * (long)len;
        }
    }
}

static void bilinear_lanes_serve_mixed_blocks_bit_for_bit(void **state)
{
    (void)state;
    for_each_ptx(mixed_blocks);
}

/* The box and width-4 filters' batch loop (kernel_run: the query checks and the fused path
 * inline) on the same mix of queries it must serve and queries it must leave to serve
 * (faces out of range, NaN, infinite and too large derivatives, coordinates outside
 * [0, 1), subfaces, constant faces, overhanging kernels): bit for bit the general path and
 * the per-query path (PF_PATH_QUERY: kernel_q through serve), in the three modes with
 * default and non-default width and blur, whole and in batches of every length 1-40. */
static void kernel_mixed(const char *path, st_set *s, long *compared)
{
    static st_query q[NQ];
    make_mix(s, q);
    for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++) {
        for (unsigned flt = ST_FILTER_PTEX_BOX; flt <= ST_FILTER_PTEX_MITCHELL; flt++) {
            for (int w = 0; w < 2; w++) {
                st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)flt,
                                    .width = WIDTH_BLUR[w][0], .blur = WIDTH_BLUR[w][1],
                                    .sharpness = 0.5f};
                compare_paths(path, s, &o, q, NQ, PF_PATH_BEST);
                compare_paths(path, s, &o, q, NQ, PF_PATH_QUERY);
                *compared += 2 * NQ;
            }
        }
    }
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_GAUSSIAN};
    for (size_t len = 1; len <= 40; len++) {
        compare_paths(path, s, &o, q + len * 41, len, PF_PATH_BEST);
        *compared += (long)len;
    }
}

static void kernel_batch_loop_serves_mixed_blocks_bit_for_bit(void **state)
{
    (void)state;
    for_each_ptx(kernel_mixed);
}

/* Every face's four edges and four corners, overhung by a kernel at every resolution from
 * level 0 to the smallest (footprints 0.25 to 64 texels, so the pieces are reduced to
 * smaller neighbours and rotated into every neighbour's frame the files have): the u and v
 * of each query within half a kernel texel of the edge, each block of 8 mixing positions;
 * each full block (and the last) goes to flush. */
typedef void edge_flush(const char *path, st_set *s, const st_query *q, size_t n,
                        long *compared);
static void every_edge_with(const char *path, st_set *s, long *compared, edge_flush *flush)
{
    static st_query q[NQ];
    static const float fps[] = {0.25f, 1.0f, 2.0f, 4.0f, 8.0f, 16.0f, 64.0f};
    size_t n = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        for (int fi = 0; fi < 7; fi++) {
            float fp = fps[fi];
            float hu = 0.5f * (fp < 1.0f ? 1.0f : fp) / (float)F->w;
            float hv = 0.5f * (fp < 1.0f ? 1.0f : fp) / (float)F->h;
            for (int pos = 0; pos < 8; pos++) {
                /* 0-3: the edges (v = 0, u = 1, v = 1, u = 0), 4-7: the corners */
                float u = 0.05f + 0.9f * rndf(), v = 0.05f + 0.9f * rndf();
                float du = rndf() * hu, dv = rndf() * hv;
                int e = pos & 3;
                if (pos < 4) {
                    if (e == 0) v = dv;
                    if (e == 1) u = 1.0f - du;
                    if (e == 2) v = 1.0f - dv;
                    if (e == 3) u = du;
                } else {
                    u = e == 1 || e == 2 ? 1.0f - du : du;
                    v = e >= 2 ? 1.0f - dv : dv;
                }
                if (u >= 1.0f)
                    u = 0.99999994f;
                if (v >= 1.0f)
                    v = 0.99999994f;
                q[n++] = (st_query){.face = f, .u = u, .v = v, .dudx = fp / (float)F->w,
                                    .dvdy = fp / (float)F->h};
                if (n == NQ || (f + 1 == s->info.nfaces && fi == 6 && pos == 7)) {
                    flush(path, s, q, n, compared);
                    n = 0;
                }
            }
        }
    }
}

/* The bilinear's 2 x 2 kernel: on the path with the lanes (whose hand-over runs the 2 x 2
 * kernel's Traverse walk, ptexfilter_simd.c's pf_edge2_select), without them and with the
 * 4-lane lanes, against the general path, in the three modes. */
static void bilinear_edge_block(const char *path, st_set *s, const st_query *q, size_t n,
                                long *compared)
{
    for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++) {
        st_sample_opts o = {.mode = (uint8_t)m, .filter = ST_FILTER_PTEX_BILINEAR};
        compare_paths(path, s, &o, q, n, PF_PATH_BEST);
        compare_paths(path, s, &o, q, n, PF_PATH_QUERY);
        compare_paths(path, s, &o, q, n, PF_PATH_LANES4);
        *compared += 3 * (long)n;
    }
}

static void every_edge(const char *path, st_set *s, long *compared)
{
    every_edge_with(path, s, compared, bilinear_edge_block);
}

static void bilinear_overhangs_every_edge_and_corner_bit_for_bit(void **state)
{
    (void)state;
    for_each_ptx(every_edge);
}

/* The box and width-4 kernels (gaussian, the bicubic family): in Traverse their overhangs go
 * from the fused path's hand-over and from the declined kernel's build straight to
 * ptexfilter_walk.c's pf_walk_kernel (the one-edge walk walk_one on any face, the whole walk
 * on faces with four neighbours) and a declined kernel inside its face is applied directly
 * outside Discard: the batch loop's path and the per-query path against the general path,
 * Traverse and Clamp, default and non-default width and blur. */
static void kernel_edge_block(const char *path, st_set *s, const st_query *q, size_t n,
                              long *compared)
{
    for (unsigned m = ST_MODE_TRAVERSE; m <= ST_MODE_CLAMP; m++) { /* Traverse, Clamp */
        for (unsigned flt = ST_FILTER_PTEX_BOX; flt <= ST_FILTER_PTEX_MITCHELL; flt++) {
            for (int w = 0; w < 2; w++) {
                st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)flt,
                                    .width = WIDTH_BLUR[w][0], .blur = WIDTH_BLUR[w][1],
                                    .sharpness = 0.3f};
                compare_paths(path, s, &o, q, n, PF_PATH_BEST);
                compare_paths(path, s, &o, q, n, PF_PATH_QUERY);
                *compared += 2 * (long)n;
            }
        }
    }
}

static void every_edge_kernel(const char *path, st_set *s, long *compared)
{
    every_edge_with(path, s, compared, kernel_edge_block);
}

static void kernels_overhang_every_edge_and_corner_bit_for_bit(void **state)
{
    (void)state;
    for_each_ptx(every_edge_kernel);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(shortcuts_give_the_general_paths_results_bit_for_bit),
        cmocka_unit_test(bilinear_lanes_serve_mixed_blocks_bit_for_bit),
        cmocka_unit_test(kernel_batch_loop_serves_mixed_blocks_bit_for_bit),
        cmocka_unit_test(bilinear_overhangs_every_edge_and_corner_bit_for_bit),
        cmocka_unit_test(kernels_overhang_every_edge_and_corner_bit_for_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
