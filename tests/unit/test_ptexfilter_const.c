/* tests/unit/test_ptexfilter_const.c - eval's shortcut for a kernel inside a constant face
 * (ptexfilter.c's const_write, session 19): the face's one texel times the kernel's weight,
 * divided by that weight, without eval_kernel's frame; for the bilinear without building the
 * kernel. Its outputs, coverage and status must be the general path's
 * (pf_batch_path(PF_PATH_GENERAL), which does not take the shortcut) bit for bit: evblur
 * (every face constant, 64 x 64 declared, u8 x 3), and files of other texel types with every
 * third face flagged constant after the resolution table is built (teapot u8 x 1, holeycube
 * u16 x 1, cube8_k7varrot_f32 float x 3, black half x 4); (u, v) anywhere in the face, on
 * texel centres of the kernel's level (a zero tap stripped: the bilinear then takes the
 * kernel) and next to the edges (kernels that overhang: the general walk); footprints from
 * a quarter texel to a whole face, isotropic and not; every filter but the point and the
 * triangle's, every mode. The lanes that pf_cst8_select's functions serve 8 at a time
 * (session 20: the box's and the width-4 filters' kernels inside a constant face) are
 * counted through klanes8 on the same blocks, so that the comparison is known to cover
 * them. Faces whose whole ring is constant zero (session 29: ptexres.c's zero_ring flags
 * them, and a Traverse query there is written +0 without the kernel's walk) are checked
 * against the rule worked out here by Ptex's own walk around each corner, and their
 * kernels that overhang them against the general path. */
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
#include "ptexfilter_lanes.h"
#include "ptexres.h"
#include "sample.h"
#include "../common/pffiles.h"
#include "../common/pfpaths.h"
#include "../common/testdata.h"
#include "../common/testhash.h"

enum { NQ = 4000 };

static const unsigned *const filters = st_pf_kernel_filters; /* every one (pfpaths.h) */
enum { NF = ST_PF_NKERNEL_FILTERS };

/* A coordinate of a face of res texels at footprint fp texels: anywhere, on a texel centre
 * of the level the kernel is built at (about res / fp texels), or within fp texels of an
 * edge. */
static float coord(int j, int res, float fp, uint32_t *rng)
{
    float u = st_test_rndf(rng);
    if (j % 3 == 1) {
        int lres = 1;
        while (lres * 2 <= res && (float)(lres * 2) * fp <= (float)res * 1.5f)
            lres *= 2;
        u = ((float)(int)(u * (float)lres) + 0.5f) / (float)lres;
    } else if (j % 3 == 2) {
        float d = st_test_rndf(rng) * fp / (float)res;
        u = st_test_rndf(rng) < 0.5f ? d : 1.0f - d;
    }
    u = u < 0.0f ? 0.0f : u;
    return u < 0.99999994f ? u : 0.99999994f;
}

/* NQ queries on faces drawn uniformly; returns how many of them sit on a constant face. */
static size_t const_queries(const st_set *s, st_query *q, uint32_t *rng)
{
    static const float fps[] = {0.25f, 0.5f, 1.0f, 1.93f, 4.0f, 7.7f, 16.0f, 64.0f};
    size_t on = 0;
    for (int j = 0; j < NQ; j++) {
        uint32_t f = (uint32_t)(st_test_rndf(rng) * (float)s->info.nfaces) % s->info.nfaces;
        const st_face *F = &s->faces[f];
        float fu = fps[(int)(st_test_rndf(rng) * 8) & 7];
        float fv = j % 4 == 1 ? fps[(int)(st_test_rndf(rng) * 8) & 7] : fu;
        q[j] = (st_query){.face = f, .u = coord(j, (int)F->w, fu, rng),
                          .v = coord(j / 3, (int)F->h, fv, rng),
                          .dudx = fu / (float)F->w, .dvdy = fv / (float)F->h};
        on += (F->flags & ST_FACE_CONSTANT) != 0;
    }
    return on;
}

/* The lanes of k->cst that the filter's pf_cst8 function (arg: its pk_params) serves. */
static unsigned serve_cst8(const pf_klanes *k, void *arg)
{
    const pk_params *pp = arg;
    float w[8];
    unsigned m = pf_cst8_select(pp->ftype)(pp, k, k->cst, w);
    assert_int_equal(m & ~k->cst, 0);
    return m;
}

/* Shared file rel read into *s (its path in path), its resolution table built before any
 * flag changes so that both paths read the same texels: 1; 0 when SEAMTEX_DATA lacks it. */
static int open_shared(const char *rel, char *path, size_t n, st_set **s)
{
    int r = st_pf_read_shared(rel, path, n, s);
    if (r == 0)
        return 0;
    assert_int_equal(r, 1);
    st_query q0 = {.face = 0, .u = 0.5f, .v = 0.5f};
    assert_true(st_pf_paths_agree(*s, &q0, 1, path, filters, 1) >= 0);
    return 1;
}

static void const_faces_match_the_general_path(void **state)
{
    (void)state;
    static const struct {
        const char *rel;
        uint32_t every; /* flag every n-th face constant (0: the file's own flags) */
    } files[] = {
        {"ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx", 0},
        {"ptx/wdas-ptex-samples/teapot/teapot.ptx", 3},
        {"ptx/wdas-ptex-samples/holeycube/holeycube.ptx", 3},
        {"ptex-ref/cube8_k7varrot_f32.ptx", 3},
        {"ptx/wdas-ptex-2009/bordermodes/black.ptx", 1},
    };
    static st_query q[NQ];
    uint32_t rng = 41; /* the queries' generator (testhash.h) */
    long compared = 0, served[2] = {0};
    size_t on = 0;
    int found = 0;
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        char path[1024];
        st_set *s;
        if (!open_shared(files[i].rel, path, sizeof path, &s))
            continue;
        found++;
        if (files[i].every)
            for (uint32_t f = 0; f < s->info.nfaces; f++)
                if (f % files[i].every == 0)
                    s->faces[f].flags |= ST_FACE_CONSTANT;
        size_t n_on = const_queries(s, q, &rng);
        assert_true(n_on * 4 >= NQ); /* a quarter of the queries or more (fewer: bad test) */
        on += n_on;
        long n = st_pf_paths_agree(s, q, NQ, path, filters, NF);
        if (n < 0)
            fail();
        compared += n;
        for (int b = 0; b < 2 && pf_cst8_select(ST_FILTER_PTEX_BOX); b++) {
            pk_params pp;
            pk_params_init(&pp, b ? ST_FILTER_PTEX_BICUBIC : ST_FILTER_PTEX_BOX, 0.0f, 1);
            long m = st_pf_lanes_served(s, q, NQ, pp.ftype, serve_cst8, &pp);
            assert_true(m >= 0);
            served[b] += m;
        }
        st_set_free(s);
    }
    if (!found) {
        print_message("SEAMTEX_DATA (%s) has none of the files: skipped\n", st_test_data_dir());
        skip();
    }
    print_message("%d files, %ld queries compared, %zu on constant faces; served 8 at a time: "
                  "box %ld, bicubic %ld\n", found, compared, on, served[0], served[1]);
    /* the kernels of footprints up to 8 texels that lie inside the face: a good share */
    if (pf_cst8_select(ST_FILTER_PTEX_BOX))
        assert_true(served[0] * 5 > (long)on && served[1] * 8 > (long)on);
}

/* Kernels of a constant face that overhang it, near a corner or an edge (session 21: the
 * Traverse walk's lean cases take constant faces, pf_walk_kernel_cst): on files whose
 * neighbours are rotated (cube8_k6_u8_rot: every rotation of a piece), whose corners have
 * valence 3 (cube1_k6_u8: the corner piece dropped) or 4 (teapot), every other face flagged
 * constant (so constant faces next to constant and plain ones); footprints of 1 to 16
 * texels; every kernel filter and mode against the general path, bit for bit. */
static void walked_const_kernels_match_the_general_path(void **state)
{
    (void)state;
    static const char *const rels[] = {
        "ptex-ref/cube8_k6_u8_rot.ptx",
        "ptex-ref/cube1_k6_u8.ptx",
        "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    };
    static const float fps[] = {1.0f, 2.0f, 3.3f, 4.0f, 7.7f, 16.0f};
    static st_query q[NQ];
    uint32_t rng = 43;
    long compared = 0, over = 0;
    int found = 0;
    for (size_t i = 0; i < sizeof rels / sizeof rels[0]; i++) {
        char path[1024];
        st_set *s;
        if (!open_shared(rels[i], path, sizeof path, &s))
            continue;
        found++;
        for (uint32_t f = 0; f < s->info.nfaces; f += 2)
            s->faces[f].flags |= ST_FACE_CONSTANT;
        for (int j = 0; j < NQ; j++) {
            /* a constant face; (u, v) within the footprint of a corner (j even) or of one
             * edge */
            uint32_t f = 2 * ((uint32_t)(st_test_rndf(&rng) * (float)s->info.nfaces) / 2);
            const st_face *F = &s->faces[f % s->info.nfaces];
            float fu = fps[(int)(st_test_rndf(&rng) * 6) % 6];
            float fv = j % 3 == 1 ? fps[(int)(st_test_rndf(&rng) * 6) % 6] : fu;
            float du = st_test_rndf(&rng) * fu / (float)F->w;
            float dv = st_test_rndf(&rng) * fv / (float)F->h;
            float u = st_test_rndf(&rng) < 0.5f ? du : 1.0f - du;
            float v = j % 2 ? st_test_rndf(&rng) : st_test_rndf(&rng) < 0.5f ? dv : 1.0f - dv;
            u = u < 0.99999994f ? u : 0.99999994f;
            v = v < 0.99999994f ? v : 0.99999994f;
            q[j] = (st_query){.face = f % s->info.nfaces, .u = u, .v = v,
                              .dudx = fu / (float)F->w, .dvdy = fv / (float)F->h};
            over += du * 2.0f < fu / (float)F->w; /* about: within half the kernel */
        }
        long n = st_pf_paths_agree(s, q, NQ, path, filters, NF);
        if (n < 0)
            fail();
        compared += n;
        st_set_free(s);
    }
    if (!found) {
        print_message("SEAMTEX_DATA (%s) has none of the files: skipped\n", st_test_data_dir());
        skip();
    }
    print_message("%d files, %ld queries compared, about %ld near an edge\n", found, compared,
                  over);
    assert_true(over * 3 > (long)found * NQ); /* a good share overhang (fewer: bad test) */
}

/* Face f (or a mesh boundary, f < 0) is constant, not a subface, with a texel of zero bytes. */
static int zero_face(const st_set *s, int32_t f)
{
    if (f < 0)
        return 1;
    const st_face *F = &s->faces[f];
    if ((F->flags & (ST_FACE_CONSTANT | ST_FACE_SUBFACE)) != ST_FACE_CONSTANT)
        return 0;
    const uint8_t *d = st_face_level(s, (uint32_t)f, 0);
    for (size_t i = 0; i < st_texel_size(s); i++)
        if (d[i])
            return 0;
    return 1;
}

/* The faces Ptex's Traverse split reaches from f all zero (zero_face) and its weight never
 * changed, worked out as PtexSeparableFilter::splitAndApply walks: the neighbour across each
 * edge, and where both edges of a corner have one, the faces around the corner's vertex by
 * applyToCorner's steps (to the next face across the edge, then the edge after the one
 * arrived by), which must come back to (f, corner) after 4 (valence 4: the one diagonal
 * face; any other count changes the weight). */
static int expect_zero_ring(const st_set *s, uint32_t f)
{
    const st_face *F = &s->faces[f];
    if (!zero_face(s, (int32_t)f))
        return 0;
    for (int e = 0; e < 4; e++) {
        if (!zero_face(s, F->adjface[e]))
            return 0;
        if (F->adjface[e] < 0 || F->adjface[(e + 3) & 3] < 0)
            continue;
        int32_t af = (int32_t)f, ae = e, steps = 0, diag = -1;
        for (;;) {
            int32_t nf = s->faces[af].adjface[ae];
            ae = (s->faces[af].adjedge[ae] + 1) % 4;
            af = nf;
            steps++;
            if (af < 0 || (af == (int32_t)f && ae == e) || steps > 10)
                break;
            if (steps == 2)
                diag = af;
        }
        if (af != (int32_t)f || steps != 4 || !zero_face(s, diag))
            return 0;
    }
    return 1;
}

/* evblur (64 of its 66 faces constant black, 2 white; boundaries, and a vertex of valence 5)
 * as read, with every face black but one, and all black: the faces the table flags
 * ST_PTEXRES_ZRING are the ones expect_zero_ring finds (some of them, and not all, in each
 * form), those it flags ST_PTEXRES_ZFACE the ones zero_face finds; kernels of every filter
 * on flagged faces (and on any face, a quarter of them), overhanging edges and corners at
 * footprints of 1 to 64 texels, every mode, give the general path's bits (Traverse and Clamp
 * take the shortcut: +0, with the same status and coverage; Discard does not). */
static void zero_ring_faces_match_the_general_path(void **state)
{
    (void)state;
    static const float fps[] = {1.0f, 2.5f, 4.0f, 9.0f, 16.0f, 31.0f, 64.0f};
    static st_query q[NQ];
    uint32_t rng = 47;
    long compared = 0;
    for (int form = 0; form < 3; form++) {
        char path[1024];
        st_set *s;
        int r = st_pf_read_shared("ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx", path,
                                  sizeof path, &s);
        if (r == 0) {
            print_message("SEAMTEX_DATA (%s) lacks evblur: skipped\n", st_test_data_dir());
            skip();
        }
        assert_int_equal(r, 1);
        size_t ts = st_texel_size(s);
        /* form 1: every face black but face 35; form 2: all black (before the table) */
        for (uint32_t f = 0; form && f < s->info.nfaces; f++)
            if (s->faces[f].flags & ST_FACE_CONSTANT)
                memset(st_face_level(s, f, 0), form == 1 && f == 35 ? 0xff : 0, ts);
        st_error e;
        const st_ptexres *t = st_ptexres_table(s, &e);
        assert_non_null(t);
        uint32_t flagged = 0, cand[64], nc = 0;
        for (uint32_t f = 0; f < s->info.nfaces; f++) {
            int got = (t->lanef[f] & ST_PTEXRES_ZRING) != 0;
            if (got != expect_zero_ring(s, f))
                fail_msg("form %d face %u: flag %d, expected %d", form, f, got, !got);
            flagged += (uint32_t)got;
            if (got && nc < 64)
                cand[nc++] = f;
            got = (t->lanef[f] & ST_PTEXRES_ZFACE) != 0;
            if (got != zero_face(s, (int32_t)f))
                fail_msg("form %d face %u: face flag %d, expected %d", form, f, got, !got);
        }
        print_message("form %d: %u of %u faces flagged\n", form, flagged, s->info.nfaces);
        assert_true(flagged > 0 && flagged < s->info.nfaces);
        for (int j = 0; j < NQ; j++) {
            /* a flagged face (3 in 4), or any (Clamp's zero faces next to white ones) */
            uint32_t f = j % 4 ? cand[(uint32_t)(st_test_rndf(&rng) * (float)nc) % nc]
                               : (uint32_t)(st_test_rndf(&rng) * (float)s->info.nfaces) %
                                     s->info.nfaces;
            const st_face *F = &s->faces[f];
            float fu = fps[(int)(st_test_rndf(&rng) * 7) % 7];
            float fv = j % 3 == 1 ? fps[(int)(st_test_rndf(&rng) * 7) % 7] : fu;
            float du = st_test_rndf(&rng) * fu / (float)F->w;
            float dv = st_test_rndf(&rng) * fv / (float)F->h;
            float u = j % 4 == 3 ? st_test_rndf(&rng) : st_test_rndf(&rng) < 0.5f ? du : 1.0f - du;
            float v = j % 2 ? st_test_rndf(&rng) : st_test_rndf(&rng) < 0.5f ? dv : 1.0f - dv;
            u = u < 0.99999994f ? u : 0.99999994f;
            v = v < 0.99999994f ? v : 0.99999994f;
            q[j] = (st_query){.face = f, .u = u, .v = v, .dudx = fu / (float)F->w,
                              .dvdy = fv / (float)F->h, .dvdx = j % 5 == 2 ? dv : 0.0f};
        }
        long n = st_pf_paths_agree(s, q, NQ, path, filters, NF);
        if (n < 0)
            fail();
        compared += n;
        st_set_free(s);
    }
    print_message("%ld queries compared\n", compared);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(const_faces_match_the_general_path),
        cmocka_unit_test(walked_const_kernels_match_the_general_path),
        cmocka_unit_test(zero_ring_faces_match_the_general_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
