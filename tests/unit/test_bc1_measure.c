/* tests/unit/test_bc1_measure.c - st_bc1_measure: the quality figures of a BC1 set against
 * its source (what a COMPRESS job reports), on the duck atlas of the shared data. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "bc1.h"
#include "bc1_measure.h"
#include "import.h"
#include "seammask.h"
#include "../common/faces.h"
#include "../common/testdata.h"

static st_set *compress(const st_set *src, int seam_mode)
{
    st_bc1_opts o;
    st_bc1_opts_default(&o);
    o.level = ST_BC1_FAST;
    o.seam_mode = seam_mode;
    o.threads = 1;
    st_set *out = NULL;
    st_error e;
    if (st_bc1_compress_set(src, &o, NULL, NULL, NULL, &out, &e) != 0)
        fail_msg("compress: %s", e.msg);
    return out;
}

/* Plain BC1 keeps the duck's seams (its texture has colour edges on them); seam-aware BC1
 * hides them; both stay close to the source inside charts. The source against itself: 99 dB,
 * equal RMS. */
static void seam_aware_bc1_measures_lower_seam_rms_than_plain(void **state)
{
    (void)state;
    char path[512];
    if (st_test_data_path(path, sizeof path, "meshes/duck/Duck.obj"))
        skip();
    st_set *src = NULL;
    st_error e;
    assert_int_equal(st_import_file(path, NULL, &src, &e), ST_OK);
    st_set *plain = compress(src, ST_BC1_SEAM_NONE), *aware = compress(src, ST_BC1_SEAM_AWARE);
    st_bc1_quality qp, qa;
    assert_int_equal(st_bc1_measure(src, plain, 0, &qp, &e), ST_OK);
    assert_int_equal(st_bc1_measure(src, aware, 0, &qa, &e), ST_OK);
    printf("# duck: plain PSNR %.2f dB, seam RMS %.2f -> %.2f; seam-aware %.2f dB, %.2f -> %.2f "
           "(%u seams, %zu points)\n", qp.psnr, qp.seam_rms_src, qp.seam_rms_bc1, qa.psnr,
           qa.seam_rms_src, qa.seam_rms_bc1, qa.nseams, qa.npts);
    assert_int_equal(qa.nseams, qp.nseams);
    assert_true(qa.nseams > 100);
    assert_true(qa.seam_rms_src == qp.seam_rms_src);
    assert_true(qp.seam_rms_src > 20);                    /* seams by design in the texture */
    assert_true(qp.seam_rms_bc1 > 0.8 * qp.seam_rms_src); /* plain BC1 keeps them */
    assert_true(qa.seam_rms_bc1 < 0.25 * qa.seam_rms_src); /* seam-aware hides them */
    assert_true(qp.psnr > 35 && qp.psnr < 99);
    assert_true(qa.psnr > 30 && qa.psnr < qp.psnr);       /* masking moves texels */
    /* a set that is not BC1, or a BC1 set of other faces, is refused */
    assert_int_equal(st_bc1_measure(src, src, 0, &qa, &e), ST_EINVAL);
    char cube[512];
    if (st_test_data_path(cube, sizeof cube, "ptex-ref/cube1_k6_u8.ptx") == 0) {
        st_set *other = NULL;
        assert_int_equal(st_import_file(cube, NULL, &other, &e), ST_OK);
        st_set *obc1 = compress(other, ST_BC1_SEAM_NONE);
        assert_int_equal(st_bc1_measure(src, obc1, 0, &qa, &e), ST_EINVAL);
        printf("# mismatched: %s\n", e.msg);
        st_set_free(obc1);
        st_set_free(other);
    }
    st_set_free(aware);
    st_set_free(plain);
    st_set_free(src);
}

/* Punch-through alpha: a 16 x 16 RGBA checker of opaque colour and fully transparent texels.
 * BC1 stores the transparent ones as transparent black, as designed, so their colour is no
 * error: the figure is the opaque texels' (it was 7.8 dB when their RGB counted against the
 * source colour). A BC1 set that made an opaque texel transparent still pays for it. */
static void psnr_leaves_out_texels_transparent_in_both(void **state)
{
    (void)state;
    st_face_desc fd;
    st_test_faces(&fd, 1, 16, 16);
    st_set_info in = {.nfaces = 1, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3,
                      .kind = ST_KIND_ATLAS};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_set_create(&in, &fd, 0, &s, &e), ST_OK);
    uint8_t *p = st_face_level(s, 0, 0);
    for (int i = 0; i < 256; i++) {
        int opaque = ((i % 16) / 4 + (i / 16) / 4) % 2;
        uint8_t px[4] = {200, 180, 40, (uint8_t)(opaque ? 255 : 0)};
        memcpy(p + 4 * i, px, 4);
    }
    st_set_build_mips(s, 0);
    st_set *b = compress(s, ST_BC1_SEAM_NONE);
    st_bc1_quality q;
    assert_int_equal(st_bc1_measure(s, b, 0, &q, &e), ST_OK);
    printf("# checker with punch-through alpha: PSNR %.2f dB\n", q.psnr);
    assert_true(q.psnr > 40);
    /* a BC1 set that dropped opaque texels: one block made all transparent black */
    st_bc1_quality qb;
    uint8_t blk[8] = {0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff}; /* c0 <= c1, every selector 3 */
    uint8_t *t = st_face_level(b, 0, 0);
    for (int k = 0; k < 16; k++)
        memcpy(t + 8 * k, blk, 8);
    assert_int_equal(st_bc1_measure(s, b, 0, &qb, &e), ST_OK);
    printf("# every texel transparent: PSNR %.2f dB\n", qb.psnr);
    assert_true(qb.psnr < 15);
    st_set_free(b);
    st_set_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(seam_aware_bc1_measures_lower_seam_rms_than_plain),
        cmocka_unit_test(psnr_leaves_out_texels_transparent_in_both),
    };
    return cmocka_run_group_tests_name("bc1_measure", tests, NULL, NULL);
}
