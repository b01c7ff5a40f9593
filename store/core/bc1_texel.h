/* store/core/bc1_texel.h - the BC1 (DXT1) block as a set stores it: exact decode of one
 * texel, inline, no tables, and what a BC1 set keeps of its source (st_bc1_ext).
 *
 * Owns: the bit-exact BC1 decoding rule shared by the sampler (sample*.c decodes on tap) and
 * the BC1 encoder (which measures its error with the same rule). Does not own: block layout
 * inside a set (set.h, ST_KIND_BC1) or encoding.
 *
 * Block: 8 bytes. c0 = bytes 0..1, c1 = bytes 2..3 (RGB565, little-endian, red in the top 5
 * bits), then 32 bits of selectors (bytes 4..7, little-endian), 2 bits per texel, texels in
 * row-major order (t = 4*y + x), texel 0 in the lowest bits.
 * Palette: endpoints expanded by bit replication (r8 = r5<<3 | r5>>2, g8 = g6<<2 | g6>>4);
 * if c0 > c1 (as 16-bit integers): c2 = (2*c0 + c1) / 3, c3 = (c0 + 2*c1) / 3 per channel with
 * integer truncation, alpha 255; else c2 = (c0 + c1) / 2 (truncated), c3 = transparent black
 * (0, 0, 0, 0).
 */
#ifndef ST_BC1_TEXEL_H
#define ST_BC1_TEXEL_H

#include <stdint.h>

/* What a BC1 set keeps of its source (the ST_EXT_BC1 extension of an
 * ST_KIND_BC1 set, set.h; owned by the set). */
typedef struct st_bc1_ext {
    uint8_t  src_kind;      /* st_kind of the set it was encoded from (CUBE -> DDS cube) */
    uint8_t  src_nchan;     /* channel count of the source */
    int8_t   src_alpha;     /* alpha channel of the source, -1 none */
    uint8_t  punchthrough;  /* 1 when some texel had alpha < 128 (3-colour blocks used) */
    uint8_t  level;         /* encoder level used */
    uint8_t  seam_mode;     /* st_bc1_seam_mode used */
    uint8_t  reserved[2];
} st_bc1_ext;

/* RGB565 -> RGB8 by bit replication. */
static inline void st_bc1_565_to_rgb8(uint16_t c, uint8_t rgb[3])
{
    unsigned r = (c >> 11) & 31u, g = (c >> 5) & 63u, b = c & 31u;
    rgb[0] = (uint8_t)((r << 3) | (r >> 2));
    rgb[1] = (uint8_t)((g << 2) | (g >> 4));
    rgb[2] = (uint8_t)((b << 3) | (b >> 2));
}

/* Decodes texel (x, y), 0 <= x, y < 4, of the 8-byte block `blk` into rgba[4]. */
static inline void st_bc1_texel(const uint8_t *blk, unsigned x, unsigned y, uint8_t rgba[4])
{
    uint16_t c0 = (uint16_t)(blk[0] | (blk[1] << 8));
    uint16_t c1 = (uint16_t)(blk[2] | (blk[3] << 8));
    uint32_t sel = (uint32_t)blk[4] | ((uint32_t)blk[5] << 8) | ((uint32_t)blk[6] << 16) |
                   ((uint32_t)blk[7] << 24);
    unsigned idx = (sel >> (2 * (4 * (y & 3) + (x & 3)))) & 3u;
    uint8_t e0[3], e1[3];
    rgba[3] = 255;
    switch (idx) {
    case 0:
        st_bc1_565_to_rgb8(c0, rgba);
        return;
    case 1:
        st_bc1_565_to_rgb8(c1, rgba);
        return;
    default:
        break;
    }
    st_bc1_565_to_rgb8(c0, e0);
    st_bc1_565_to_rgb8(c1, e1);
    if (c0 > c1) {
        for (int k = 0; k < 3; k++)
            rgba[k] = (uint8_t)(idx == 2 ? (2u * e0[k] + e1[k]) / 3u : (e0[k] + 2u * e1[k]) / 3u);
    } else if (idx == 2) {
        for (int k = 0; k < 3; k++)
            rgba[k] = (uint8_t)((e0[k] + e1[k]) / 2u);
    } else {
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 0;
    }
}

#endif
