/* tests/unit/test_ptex_writer_files.c - cases found by comparing seamtex with the Ptex library
 * (2.4.3) on .ptx files written by Ptex's own writer (docs/ptex-log.md, "xw25"): half
 * float levels made the way Ptex makes them, and stored reductions of a file with face edits.
 *
 * The Ptex reader fills the levels a .ptx does not store (the reductions past min(ulog2,
 * vlog2) of a non-square face, every reduction of a file written without mipmaps, the
 * triangle reductions) by averaging in float and converting back with PtexHalf::fromFloat,
 * which rounds a tie away from zero (mantissa + 0x1000, >> 13), not to the nearest even. The
 * levels seamtex makes for a Ptex set (store/ptex/ptexres.c, core/trilevel.c) must use the
 * same conversion (st_float_to_half_ptex, core/half.h): with nearest-even rounding, half
 * files written by Ptex's writer filtered up to 2 half steps off Ptex at coarse levels
 * (found by comparing with Ptex 2.4.3 on generated files, docs/ptex-log.md, "xw25").
 * The cases are built here (no Ptex, no shared files): the conversion itself, a non-square
 * half face written with the project's writer and read back (its unstored levels made by
 * ptexres), and the triangle reduction. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "half.h"
#include "ptex.h"
#include "ptex_format.h"
#include "set.h"
#include "trilevel.h"

static uint16_t h_of(float f) { return st_float_to_half_ptex(f); }

static void ptex_half_rounding_is_ties_away_from_zero(void **state)
{
    (void)state;
    /* 1 + 2^-11 lies halfway between 1 (0x3c00) and 1 + 2^-10 (0x3c01) */
    assert_int_equal(h_of(1.00048828125f), 0x3c01);
    assert_int_equal(st_float_to_half(1.00048828125f), 0x3c00);
    assert_int_equal(h_of(-1.00048828125f), 0xbc01);
    /* not a tie: both round the same way */
    assert_int_equal(h_of(1.0002f), 0x3c00);
    assert_int_equal(h_of(1.0007f), 0x3c01);
    assert_int_equal(h_of(0.5f), 0x3800);
    assert_int_equal(h_of(65504.0f), 0x7bff);
    /* a carry into the exponent; too large -> infinity */
    assert_int_equal(h_of(2047.5f), 0x6800); /* 2047.5 is halfway from 2047 to 2048 */
    assert_int_equal(h_of(65520.0f), 0x7c00);
    assert_int_equal(h_of(1e10f), 0x7c00);
    assert_int_equal(h_of(-1e10f), 0xfc00);
    /* +-0 -> +0 (Ptex tests val == 0 first) */
    assert_int_equal(h_of(0.0f), 0);
    assert_int_equal(h_of(-0.0f), 0);
    /* subnormal results: int(|f| * 2^24 + 0.5): 2.5 steps -> 3 (nearest even gives 2) */
    assert_int_equal(h_of(2.5f / 16777216.0f), 3);
    assert_int_equal(st_float_to_half(2.5f / 16777216.0f), 2);
    assert_int_equal(h_of(-2.5f / 16777216.0f), 0x8003);
    assert_int_equal(h_of(1.0f / 16777216.0f), 1);
    assert_int_equal(h_of(0.25f / 16777216.0f), 0);
    /* every half value converts back to itself (NaNs aside) */
    for (uint32_t b = 0; b < 0x10000u; b++) {
        if ((b & 0x7c00u) == 0x7c00u && (b & 0x3ffu))
            continue;
        uint16_t want = b == 0x8000u ? 0 : (uint16_t)b;
        if (h_of(st_half_to_float((uint16_t)b)) != want)
            fail_msg("half 0x%04x does not round-trip", b);
    }
}

/* One 4x1 half face: Ptex stores level 0 only (min(ulog2, vlog2) = 0); the reader makes the
 * 2x1 level by halving in u: 0.5 * (a + b) per pair, which is a tie here. */
static void unstored_half_levels_round_like_ptex(void **state)
{
    (void)state;
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = 1;
    info.nchan = 1;
    info.dtype = ST_DT_HALF;
    info.alpha_chan = -1;
    st_face_desc fd;
    memset(&fd, 0, sizeof fd);
    fd.w = 4;
    fd.h = 1;
    for (int k = 0; k < 4; k++)
        fd.adjface[k] = -1;
    st_set *s = NULL;
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_set_create(&info, &fd, 0, &s, &e), 0);
    /* 1, 1 + 2^-10 | -1, -(1 + 2^-10): both pairs average to a tie */
    uint16_t l0[4] = {0x3c00, 0x3c01, 0xbc00, 0xbc01};
    memcpy(st_face_level(s, 0, 0), l0, sizeof l0);
    st_set_build_mips(s, UINT32_MAX);
    void *buf = NULL;
    size_t len = 0;
    assert_int_equal(st_ptex_write_mem(s, &buf, &len, &e), 0);
    st_set_free(s);
    st_set *r = NULL;
    assert_int_equal(st_ptex_read_mem(buf, len, 0, &r, &e), 0);
    free(buf);
    assert_int_equal(st_set_levels(r, &e), 0);
    assert_true(r->faces[0].nlevels >= 2);
    uint16_t l1[2];
    memcpy(l1, st_face_level(r, 0, 1), sizeof l1);
    assert_int_equal(l1[0], 0x3c01); /* nearest even would give 0x3c00 */
    assert_int_equal(l1[1], 0xbc01);
    st_set_free(r);
}

/* Triangle reduction (Ptex's reduceTri): 0.25 * (a + b + c + d) in float, then fromFloat. */
static void triangle_half_reduction_rounds_like_ptex(void **state)
{
    (void)state;
    uint16_t src[16], dst[4];
    for (int i = 0; i < 16; i++)
        src[i] = 0x3c00; /* 1.0 */
    src[0] = 0x3c02;     /* 1 + 2^-9: any sum with it, times 0.25, is 1 + 2^-11, a tie */
    memset(dst, 0, sizeof dst);
    st_tri_reduce(ST_DT_HALF, 1, (const uint8_t *)src, 4, (uint8_t *)dst);
    int ties = 0;
    for (int i = 0; i < 4; i++) {
        assert_true(dst[i] == 0x3c00 || dst[i] == 0x3c01);
        ties += dst[i] == 0x3c01;
    }
    assert_true(ties >= 1);
}

/* A face edit appended to a file (PtexWriter::edit, incremental) that changes a face's size or
 * makes it constant must not move the other faces' stored reductions: they stay in the
 * rfaceid order of the face info as first written (Ptex's reader sorts before reading the
 * edits). Face 0 (16x16) is edited into a constant face; before the fix the reader sorted the
 * edited face info, took face 0's 8x8 reduction for face 1's 4x4 and refused the file (or,
 * with sizes that happen to fit, served another face's texels). */
static void face_edits_keep_the_stored_reduction_order(void **state)
{
    (void)state;
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = 2;
    info.nchan = 1;
    info.dtype = ST_DT_U8;
    info.alpha_chan = -1;
    st_face_desc fd[2];
    memset(fd, 0, sizeof fd);
    fd[0].w = fd[0].h = 16;
    fd[1].w = fd[1].h = 8;
    for (int f = 0; f < 2; f++)
        for (int k = 0; k < 4; k++)
            fd[f].adjface[k] = -1;
    st_set *s = NULL;
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    for (int i = 0; i < 256; i++)
        st_face_level(s, 0, 0)[i] = (uint8_t)(i * 7 + 3);
    for (int i = 0; i < 64; i++)
        st_face_level(s, 1, 0)[i] = (uint8_t)(200 - i * 3);
    st_set_build_mips(s, UINT32_MAX);
    uint8_t want[16];
    memcpy(want, st_face_level(s, 1, 1), 16);
    void *buf = NULL;
    size_t len = 0;
    assert_int_equal(st_ptex_write_mem(s, &buf, &len, &e), 0);
    st_set_free(s);

    /* append one face edit record: face 0 becomes a constant face of value 99 */
    const size_t rec = 1 + 4 + PTX_EDIT_FACE_SIZE + 1;
    uint8_t *b = realloc(buf, len + rec);
    assert_non_null(b);
    uint8_t *p = b + len;
    memset(p, 0, rec);
    p[0] = PTX_EDIT_FACEDATA;
    uint32_t esz = PTX_EDIT_FACE_SIZE + 1;
    memcpy(p + 1, &esz, 4);
    /* faceid 0 (4 bytes), FaceInfo: ulog2 0, vlog2 0, adjedges 0, flags constant, adjfaces */
    p[5 + 4 + 3] = PTX_FLAG_CONSTANT;
    int32_t none = -1;
    for (int k = 0; k < 4; k++)
        memcpy(p + 5 + 4 + 4 + 4 * k, &none, 4);
    /* FaceDataHeader 0 (constant), then the constant value */
    p[5 + PTX_EDIT_FACE_SIZE] = 99;
    uint64_t editsize = rec;
    memcpy(b + PTX_HEADER_SIZE + 24, &editsize, 8); /* ExtHeader.editdatasize */
    len += rec;

    for (int eager = 0; eager < 2; eager++) {
        st_set *r = NULL;
        int rc = eager ? st_ptex_read_mem_eager(b, len, 0, &r, &e)
                       : st_ptex_read_mem(b, len, 0, &r, &e);
        if (rc)
            fail_msg("import: %s", e.msg);
        assert_int_equal(st_set_levels(r, &e), 0);
        assert_true(r->faces[0].flags & ST_FACE_CONSTANT);
        assert_int_equal(st_face_level(r, 0, 0)[0], 99);
        assert_memory_equal(st_face_level(r, 1, 1), want, 16);
        st_set_free(r);
    }
    free(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(ptex_half_rounding_is_ties_away_from_zero),
        cmocka_unit_test(unstored_half_levels_round_like_ptex),
        cmocka_unit_test(triangle_half_reduction_rounds_like_ptex),
        cmocka_unit_test(face_edits_keep_the_stored_reduction_order),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
