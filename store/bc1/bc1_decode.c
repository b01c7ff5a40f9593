/* store/bc1/bc1_decode.c - BC1 block, image and set decoding, with the exact rule and the
 * vendor variants (bc1.h), and the PSNR helper the benchmarks and the report use.
 *
 * Owns: palettes under each decoder, block/image/set decode. Does not own: the one-texel
 * decode used by the sampler (bc1_texel.h, which this file must agree with: the EXACT
 * palette here is checked against st_bc1_texel by test_bc1), encoding (bc1_encode.c).
 */
#include "bc1.h"
#include "bc1_texel.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void st_bc1_palette(uint16_t c0, uint16_t c1, st_bc1_decoder dec, uint8_t pal[16])
{
    uint8_t e0[3], e1[3];
    st_bc1_565_to_rgb8(c0, e0);
    st_bc1_565_to_rgb8(c1, e1);
    int four = c0 > c1;
    unsigned q0[3] = {(c0 >> 11) & 31u, (c0 >> 5) & 63u, c0 & 31u};
    unsigned q1[3] = {(c1 >> 11) & 31u, (c1 >> 5) & 63u, c1 & 31u};
    for (int k = 0; k < 3; k++) {
        int a = e0[k], b = e1[k], p2, p3;
        int ra = a, rb = b;
        if (dec == ST_BC1_DEC_NVIDIA && k != 1) {
            /* NVIDIA expands 5-bit red/blue as (3*q*22)/8 and interpolates on q */
            ra = (int)(3 * q0[k] * 22) / 8;
            rb = (int)(3 * q1[k] * 22) / 8;
        }
        if (four) {
            switch (dec) {
            case ST_BC1_DEC_IDEAL:
                p2 = (2 * a + b + 1) / 3;
                p3 = (a + 2 * b + 1) / 3;
                break;
            case ST_BC1_DEC_AMD:
                p2 = (43 * a + 21 * b + 32) >> 6;
                p3 = (21 * a + 43 * b + 32) >> 6;
                break;
            case ST_BC1_DEC_NVIDIA:
                if (k == 1) {
                    int gd = b - a;
                    p2 = (256 * a + gd / 4 + 128 + gd * 80) / 256;
                    p3 = (256 * b - gd / 4 + 128 - gd * 80) / 256;
                } else {
                    p2 = (int)((2 * q0[k] + q1[k]) * 22) / 8;
                    p3 = (int)((q0[k] + 2 * q1[k]) * 22) / 8;
                }
                break;
            default:
                p2 = (2 * a + b) / 3;
                p3 = (a + 2 * b) / 3;
                break;
            }
        } else {
            switch (dec) {
            case ST_BC1_DEC_IDEAL:
            case ST_BC1_DEC_AMD:
                p2 = (a + b + 1) >> 1;
                break;
            case ST_BC1_DEC_NVIDIA:
                if (k == 1) {
                    int gd = b - a;
                    p2 = (256 * a + gd / 4 + 128 + gd * 128) / 256;
                } else {
                    p2 = (int)((q0[k] + q1[k]) * 33) / 8;
                }
                break;
            default:
                p2 = (a + b) / 2;
                break;
            }
            p3 = 0;
        }
        pal[k] = (uint8_t)ra;
        pal[4 + k] = (uint8_t)rb;
        pal[8 + k] = (uint8_t)(p2 < 0 ? 0 : p2 > 255 ? 255 : p2);
        pal[12 + k] = (uint8_t)(p3 < 0 ? 0 : p3 > 255 ? 255 : p3);
    }
    pal[3] = pal[7] = pal[11] = 255;
    pal[15] = four ? 255 : 0;
}

void st_bc1_decode_block(const uint8_t blk[8], st_bc1_decoder dec, uint8_t rgba[64])
{
    uint8_t pal[16];
    st_bc1_palette((uint16_t)(blk[0] | (blk[1] << 8)), (uint16_t)(blk[2] | (blk[3] << 8)), dec,
                   pal);
    uint32_t sel = (uint32_t)blk[4] | ((uint32_t)blk[5] << 8) | ((uint32_t)blk[6] << 16) |
                   ((uint32_t)blk[7] << 24);
    for (int t = 0; t < 16; t++)
        memcpy(rgba + 4 * t, pal + 4 * ((sel >> (2 * t)) & 3u), 4);
}

void st_bc1_decode_image(const uint8_t *blocks, uint32_t w, uint32_t h, st_bc1_decoder dec,
                         uint8_t *rgba)
{
    uint32_t bw = (w + 3) / 4, bh = (h + 3) / 4;
    uint8_t tmp[64];
    for (uint32_t by = 0; by < bh; by++)
        for (uint32_t bx = 0; bx < bw; bx++) {
            st_bc1_decode_block(blocks + ((size_t)by * bw + bx) * 8, dec, tmp);
            for (uint32_t y = 0; y < 4 && by * 4 + y < h; y++)
                for (uint32_t x = 0; x < 4 && bx * 4 + x < w; x++)
                    memcpy(rgba + (((size_t)(by * 4 + y)) * w + bx * 4 + x) * 4,
                           tmp + 4 * (4 * y + x), 4);
        }
}

double st_bc1_psnr_rgb(const uint8_t *a, const uint8_t *b, size_t n)
{
    double se = 0;
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            int d = (int)a[4 * i + k] - (int)b[4 * i + k];
            se += d * d;
        }
    if (se == 0 || n == 0)
        return 99.0;
    double mse = se / (3.0 * (double)n);
    return 10.0 * log10(255.0 * 255.0 / mse);
}

int st_bc1_decode_set(const st_set *bc1, st_bc1_decoder dec, st_set **out, st_error *e)
{
    *out = NULL;
    if (bc1->info.kind != ST_KIND_BC1)
        return st_fail(e, ST_EINVAL, "set is not a BC1 set");
    const st_bc1_ext *x = st_set_ext_get(bc1, ST_EXT_BC1);
    st_set_info info = bc1->info;
    info.kind = x ? x->src_kind : ST_KIND_PERFACE;
    if (info.kind == ST_KIND_BC1)
        info.kind = ST_KIND_PERFACE;
    st_face_desc *fd = calloc(info.nfaces, sizeof *fd);
    if (!fd)
        return st_fail(e, ST_ENOMEM, "out of memory for %u face descriptions", info.nfaces);
    for (uint32_t f = 0; f < info.nfaces; f++) {
        const st_face *F = &bc1->faces[f];
        fd[f].w = F->w;
        fd[f].h = F->h;
        fd[f].flags = F->flags;
        for (int k = 0; k < 4; k++) {
            fd[f].adjface[k] = F->adjface[k];
            fd[f].adjedge[k] = (int8_t)F->adjedge[k];
        }
    }
    st_set *s;
    int rc = st_set_create(&info, fd, 0, &s, e);
    free(fd);
    if (rc)
        return rc;
    for (uint32_t f = 0; f < info.nfaces; f++) {
        const st_face *F = &bc1->faces[f];
        if (F->flags & ST_FACE_CONSTANT) {
            memcpy(st_face_level(s, f, 0), st_face_level(bc1, f, 0), 4);
            continue;
        }
        for (unsigned l = 0; l < F->nlevels; l++)
            st_bc1_decode_image(st_face_level(bc1, f, l), st_level_w(F, l), st_level_h(F, l), dec,
                                st_face_level(s, f, l));
    }
    *out = s;
    return ST_OK;
}
