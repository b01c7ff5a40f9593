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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(seam_aware_bc1_measures_lower_seam_rms_than_plain),
    };
    return cmocka_run_group_tests_name("bc1_measure", tests, NULL, NULL);
}
