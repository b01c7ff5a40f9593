/* store/bc1/bc1_measure.h - how good a BC1 set is against the set it was encoded from: RGB PSNR
 * inside charts and the seam RMS before and after, measured the way the seam report does
 * (seammask.h: the same seam sample points, exact decoder).
 *
 * Owns: st_bc1_measure and its result. Does not own: encoding (bc1.h), the seam system and
 * the metrics themselves (seammask.h).
 *
 * Ownership: nothing is kept; the function allocates its work buffers and frees them.
 * Threading: pure apart from allocation; any number of threads may call it.
 */
#ifndef ST_BC1_MEASURE_H
#define ST_BC1_MEASURE_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"

typedef struct st_bc1_quality {
    double   psnr;          /* RGB PSNR (dB) of the decoded level 0 against the source's, over
                               the texels inside charts (all texels of per-face and cube sets)
                               but those transparent (alpha < 0.5) in both, which BC1 stores as
                               transparent black; 99 when identical */
    double   seam_rms_src;  /* seam RMS per channel (0..255) of the source */
    double   seam_rms_bc1;  /* the same of the decoded BC1 set */
    uint32_t nseams;        /* seams (edge pairs) measured; 0: the set has no seams */
    size_t   npts;          /* seam sample points */
} st_bc1_quality;

/* Measures bc1 (ST_KIND_BC1, from st_bc1_compress_set or a DDS) against src, the set it was
 * encoded from (same faces and level-0 sizes, else ST_EINVAL). step: seam sample spacing in
 * texels (0 = 0.5, as st_bc1_compress_set). 0 or a negative ST_E* code. */
int st_bc1_measure(const st_set *src, const st_set *bc1, float step, st_bc1_quality *q,
                   st_error *e);

#endif
