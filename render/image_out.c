/* render/image_out.c - seamtex-render's PNG output through the store's OpenImageIO writer
 * (store/import st_image_write), reused rather than written twice; one of the two render/
 * files that see the store (render/module.mk).
 *
 * Owns: float linear RGB to 8-bit, the call. Does not own: encoding.
 */
#include "render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "image_io.h"
#include "set.h"

int ri_write_png(const char *path, const float *rgb, unsigned w, unsigned h, char *msg,
                 size_t ml)
{
    size_t n = (size_t)w * h * 3;
    uint8_t *px = malloc(n ? n : 1);
    if (!px) {
        snprintf(msg, ml, "out of memory for a %ux%u image", w, h);
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        float v = rgb[i];
        v = isnan(v) ? 0 : v < 0 ? 0 : v > 1 ? 1 : v;
        px[i] = (uint8_t)lrintf(v * 255.0f);
    }
    st_error e;
    st_error_clear(&e);
    int rc = st_image_write(path, w, h, 3, ST_DT_U8, px, &e);
    free(px);
    if (rc != 0) {
        snprintf(msg, ml, "%s: %s", path, e.msg);
        return -1;
    }
    return 0;
}
