/* render/reference.c - the reference frame of Toth 2013, section 4: the frame rendered at
 * ss x ss its resolution (one sample per pixel) and downsampled with the Mitchell-Netravali
 * filter, B = C = 1/3, support 2 output pixels each side.
 *
 * Owns: the filter and the downsampling (separable, weights renormalised where the support
 * leaves the image). Does not own: rendering (frame.c).
 */
#include "render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

double rf_mitchell(double x)
{
    const double B = 1.0 / 3.0, C = 1.0 / 3.0;
    x = fabs(x);
    if (x < 1)
        return ((12 - 9 * B - 6 * C) * x * x * x + (-18 + 12 * B + 6 * C) * x * x + (6 - 2 * B)) /
               6;
    if (x < 2)
        return ((-B - 6 * C) * x * x * x + (6 * B + 30 * C) * x * x + (-12 * B - 48 * C) * x +
                (8 * B + 24 * C)) / 6;
    return 0;
}

/* One axis: n outputs from n*ss inputs spaced `stride` floats apart (3 channels at each). */
static void filter_axis(const float *in, size_t in_stride, float *out, size_t out_stride,
                        unsigned n, unsigned ss, const double *w, int half)
{
    long len = (long)n * ss;
    for (unsigned o = 0; o < n; o++) {
        long c0 = (long)o * ss;   /* first input pixel of this output pixel */
        double acc[3] = { 0, 0, 0 }, sw = 0;
        for (int k = -half; k < half + (int)ss; k++) {
            long i = c0 + k;
            if (i < 0 || i >= len)
                continue;
            double wk = w[k + half];
            const float *p = in + (size_t)i * in_stride;
            acc[0] += wk * p[0];
            acc[1] += wk * p[1];
            acc[2] += wk * p[2];
            sw += wk;
        }
        float *q = out + (size_t)o * out_stride;
        for (int c = 0; c < 3; c++)
            q[c] = (float)(sw != 0 ? acc[c] / sw : 0);
    }
}

int rf_mitchell_down(const float *hi, unsigned w, unsigned h, unsigned ss, float *out)
{
    if (ss == 0)
        return -1;
    int half = 2 * (int)ss;   /* the support reaches 2 output pixels beyond the pixel's edges */
    int nw = 2 * half + (int)ss;
    double *wt = malloc((size_t)nw * sizeof *wt);
    size_t W = (size_t)w * ss;
    float *mid = malloc(W * h * 3 * sizeof *mid);   /* rows filtered: W wide, h tall */
    if (!wt || !mid) {
        free(wt);
        free(mid);
        return -1;
    }
    for (int k = -half; k < half + (int)ss; k++) {
        /* input pixel centre relative to the output pixel centre, in output pixels */
        double d = ((k + 0.5) - 0.5 * ss) / ss;
        wt[k + half] = rf_mitchell(d);
    }
    for (size_t x = 0; x < W; x++)   /* vertical: each hi-res column down to h rows */
        filter_axis(hi + 3 * x, 3 * W, mid + 3 * x, 3 * W, h, ss, wt, half);
    for (unsigned y = 0; y < h; y++)   /* horizontal */
        filter_axis(mid + 3 * (size_t)y * W, 3, out + 3 * (size_t)y * w, 3, w, ss, wt, half);
    free(wt);
    free(mid);
    return 0;
}

int rf_reference(const rm_mesh *m, const rc_camera *cam, const rf_opts *o, unsigned ss,
                 rs_sampler *s, float *rgb, rs_stats *st, char *msg, size_t ml)
{
    rf_opts hi = *o;
    hi.width = o->width * ss;
    hi.height = o->height * ss;
    hi.msaa = 1;
    float *big = malloc((size_t)hi.width * hi.height * 3 * sizeof *big);
    if (!big) {
        snprintf(msg, ml, "out of memory for a %ux%u reference", hi.width, hi.height);
        return -1;
    }
    int rc = rf_render(m, cam, &hi, s, NULL, big, NULL, st, msg, ml);
    if (rc == 0 && rf_mitchell_down(big, o->width, o->height, ss, rgb) != 0) {
        snprintf(msg, ml, "out of memory downsampling the reference");
        rc = -1;
    }
    free(big);
    return rc;
}
