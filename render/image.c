/* render/image.c - small image operations of seamtex-render on linear RGB float images
 * (rows top first, 3 floats per pixel): crops magnified by pixel replication, pasting into a
 * canvas, the per-pixel deviation of Toth's Figure 5.
 *
 * Owns: those three. Does not own: writing files (image_out.c).
 */
#include "render.h"

#include <math.h>
#include <string.h>

void ri_crop_zoom(const float *rgb, unsigned w, unsigned h, int x0, int y0, unsigned cw,
                  unsigned ch, unsigned zoom, float *out)
{
    unsigned ow = cw * zoom;
    for (unsigned y = 0; y < ch * zoom; y++)
        for (unsigned x = 0; x < ow; x++) {
            long sx = x0 + (long)(x / zoom), sy = y0 + (long)(y / zoom);
            float *o = out + 3 * ((size_t)y * ow + x);
            if (sx < 0 || sy < 0 || sx >= (long)w || sy >= (long)h)
                o[0] = o[1] = o[2] = 0;
            else
                memcpy(o, rgb + 3 * ((size_t)sy * w + (size_t)sx), 3 * sizeof *o);
        }
}

void ri_paste(float *canvas, unsigned w, unsigned h, const float *tile, unsigned tw, unsigned th,
              unsigned x, unsigned y)
{
    for (unsigned j = 0; j < th && y + j < h; j++) {
        unsigned n = tw;
        if (x >= w)
            return;
        if (x + n > w)
            n = w - x;
        memcpy(canvas + 3 * ((size_t)(y + j) * w + x), tile + 3 * (size_t)j * tw,
               (size_t)n * 3 * sizeof *canvas);
    }
}

double ri_pixel_dist(const float *a, const float *b, size_t i)
{
    double d0 = (double)a[3 * i] - b[3 * i], d1 = (double)a[3 * i + 1] - b[3 * i + 1],
           d2 = (double)a[3 * i + 2] - b[3 * i + 2];
    return sqrt(d0 * d0 + d1 * d1 + d2 * d2);
}
