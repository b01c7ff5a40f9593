/* store/core/image.c - the st_image type's byte count and release (image.h).
 *
 * Owns: st_image_bytes, st_image_free. Does not own: reading or writing image files
 * (import/image_io.h).
 */
#include "image.h"

#include <stdlib.h>
#include <string.h>

#include "set.h"

size_t st_image_bytes(uint32_t w, uint32_t h, unsigned nchan, unsigned dtype,
                      const st_image_caps *caps)
{
    size_t b;
    size_t cs = st_dtype_size(dtype);
    size_t cap = caps && caps->max_bytes ? caps->max_bytes : ((size_t)2 << 30);
    if (!cs || st_mul_size(w, h, &b) || st_mul_size(b, (size_t)nchan * cs, &b))
        return 0;
    return b <= cap ? b : 0;
}

void st_image_free(st_image *img)
{
    if (!img)
        return;
    free(img->data);
    memset(img, 0, sizeof *img);
}
