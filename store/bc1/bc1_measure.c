/* store/bc1/bc1_measure.c - PSNR inside charts and seam RMS of a BC1 set against its source (see
 * bc1_measure.h). Level 0 of both sets is gathered into the seam system's global RGBA8
 * layout (seammask.h) and compared there, so the figures are the seam report's.
 */
#include "bc1_measure.h"

#include <stdlib.h>
#include <string.h>

#include "bc1.h"
#include "seammask.h"

int st_bc1_measure(const st_set *src, const st_set *bc1, float step, st_bc1_quality *q,
                   st_error *e)
{
    memset(q, 0, sizeof *q);
    if (!src || !bc1 || bc1->info.kind != ST_KIND_BC1)
        return st_fail(e, ST_EINVAL, "st_bc1_measure needs a BC1 set and its source");
    if (src->info.nfaces != bc1->info.nfaces)
        return st_fail(e, ST_EINVAL, "the BC1 set has %u faces, its source %u",
                       bc1->info.nfaces, src->info.nfaces);
    for (uint32_t f = 0; f < src->info.nfaces; f++)
        if (src->faces[f].w != bc1->faces[f].w || src->faces[f].h != bc1->faces[f].h)
            return st_fail(e, ST_EINVAL, "face %u is %ux%u in the BC1 set, %ux%u in its source",
                           f, bc1->faces[f].w, bc1->faces[f].h, src->faces[f].w,
                           src->faces[f].h);
    st_seam_sys *sys = NULL;
    st_set *dec = NULL;
    uint8_t *a = NULL, *b = NULL;
    int rc = st_seam_sys_build(src, step, &sys, e);
    if (rc == ST_OK)
        rc = st_bc1_decode_set(bc1, ST_BC1_DEC_EXACT, &dec, e);
    if (rc == ST_OK)
        rc = st_seam_gather_rgba8(src, sys, &a, e);
    if (rc == ST_OK)
        rc = st_seam_gather_rgba8(dec, sys, &b, e);
    if (rc == ST_OK) {
        q->psnr = st_seam_psnr_inside(sys, a, b);
        q->seam_rms_src = st_seam_rms_rgba8(sys, a);
        q->seam_rms_bc1 = st_seam_rms_rgba8(sys, b);
        q->nseams = sys->nseams;
        q->npts = sys->npts;
    }
    free(a);
    free(b);
    st_set_free(dec);
    st_seam_sys_free(sys);
    return rc;
}
