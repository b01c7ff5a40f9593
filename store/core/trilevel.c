/* store/core/trilevel.c - the 2:1 reduction of a triangle face level (layout and rule in
 * trilevel.h). Called once per level at import or mip building; a plain loop per dtype.
 */
#include "trilevel.h"

#include <string.h>

#include "half.h"
#include "set.h"

void st_tri_reduce(unsigned dt, unsigned nc, const uint8_t *src, uint32_t R, uint8_t *dst)
{
    uint32_t h = R / 2;
    size_t row = (size_t)R * nc; /* channel values per source row */
    for (uint32_t j = 0; j < h; j++) {
        for (uint32_t i = 0; i < h; i++) {
            size_t a = ((size_t)(2 * j) * R + 2 * i) * nc;        /* (2i, 2j) */
            size_t b = a + nc;                                    /* (2i+1, 2j) */
            size_t c = a + row;                                   /* (2i, 2j+1) */
            size_t d = ((size_t)(R - 1 - 2 * i) * R + (R - 1 - 2 * j)) * nc; /* odd middle */
            size_t o = ((size_t)j * h + i) * nc;
            for (unsigned k = 0; k < nc; k++) {
                switch (dt) {
                case ST_DT_U8:
                    dst[o + k] = (uint8_t)((src[a + k] + src[b + k] + src[c + k] + src[d + k]) >> 2);
                    break;
                case ST_DT_U16: {
                    const uint16_t *s = (const uint16_t *)(const void *)src;
                    ((uint16_t *)(void *)dst)[o + k] =
                        (uint16_t)(((uint32_t)s[a + k] + s[b + k] + s[c + k] + s[d + k]) >> 2);
                    break;
                }
                case ST_DT_HALF: {
                    const uint16_t *s = (const uint16_t *)(const void *)src;
                    float sum = st_half_to_float(s[a + k]) + st_half_to_float(s[b + k]);
                    sum += st_half_to_float(s[c + k]);
                    sum += st_half_to_float(s[d + k]);
                    ((uint16_t *)(void *)dst)[o + k] = st_float_to_half_ptex(0.25f * sum);
                    break;
                }
                default: {
                    const float *s = (const float *)(const void *)src;
                    float sum = s[a + k] + s[b + k];
                    sum += s[c + k];
                    sum += s[d + k];
                    ((float *)(void *)dst)[o + k] = 0.25f * sum;
                    break;
                }
                }
            }
        }
    }
}
