/* store/core/trilevel.h - the texel layout of a triangle face (Ptex meshtype triangle) and its
 * reduction to the next level.
 *
 * Layout (Ptex's, docs/ptex.md "Triangle meshes"): a triangle face of resolution R = 2^k is
 * stored in an R x R level, rows of u. The face is cut into R^2 small triangles by lines
 * u = i/R, v = j/R and u + v = m/R. Square cell (i, j) (u in [i, i+1]/R, v in [j, j+1]/R) holds
 * an upright ("even") triangle below its diagonal and, when i + j <= R - 2, an inverted ("odd")
 * one above it. The even triangle of cell (i, j), i + j <= R - 1, is texel (i, j); the odd
 * triangle of cell (i, j) is texel (R-1-j, R-1-i). So the lower-left half of the square (x + y
 * <= R - 1) holds the even triangles, the upper-right half the odd ones, mirrored through the
 * anti-diagonal. A texel's value belongs to its small triangle's centroid: (i + 1/3, j + 1/3) / R
 * for an even one, (i + 2/3, j + 2/3) / R for an odd one.
 *
 * Owns: the point rule (which texel holds (u, v)) and the 2:1 reduction, shared by the set
 * (st_set_build_mips), the .ptx reader (levels a file does not store), the Ptex point filter,
 * the triangle filter's Clamp mode (st_tri_texel_t) and the GPU-style point filter. Does not own: filtering across faces (ptex/ptextri_filter.c).
 * No allocation, no globals.
 */
#ifndef ST_TRILEVEL_H
#define ST_TRILEVEL_H

#include <stddef.h>
#include <stdint.h>

/* The texel (*x, *y) of an R x R triangle level that holds the point (ut, vt) given in texel
 * units (u R, v R): the cell is (int)ut, (int)vt clamped to 0..R-1; inside it, the even texel
 * when the fractional parts sum to <= 1, else the odd one. */
static inline void st_tri_texel_t(uint32_t R, float ut, float vt, uint32_t *x, uint32_t *y)
{
    int r1 = (int)R - 1;
    int ui = (int)ut, vi = (int)vt;
    ui = ui < 0 ? 0 : ui > r1 ? r1 : ui;
    vi = vi < 0 ? 0 : vi > r1 ? r1 : vi;
    float uf = ut - (float)ui, vf = vt - (float)vi;
    if (uf + vf <= 1.0f) {
        *x = (uint32_t)ui;
        *y = (uint32_t)vi;
    } else {
        *x = (uint32_t)(r1 - vi);
        *y = (uint32_t)(r1 - ui);
    }
}

/* The texel (*x, *y) of an R x R triangle level that holds the point (u, v): Ptex's triangle
 * point rule, st_tri_texel_t of (u R, v R). (u, v) beyond the triangle (u + v > 1) is not
 * moved first: it lands on a texel near edge 1, as in Ptex. |u|, |v| must be below 2^31 / R
 * (the caller caps coordinates). */
static inline void st_tri_texel(uint32_t R, float u, float v, uint32_t *x, uint32_t *y)
{
    st_tri_texel_t(R, u * (float)R, v * (float)R, x, y);
}

/* The barycentric coordinates p = (u, v, w) of a point of a triangle face, on or beyond its
 * edge e (0..2), in the frame of the neighbour whose edge ae (0..2) it is: the neighbour is
 * unfolded across the shared edge (parallelogram completion). Edge e is where coordinate
 * (e + 1) % 3 is 0 and runs from the corner where coordinate (e + 2) % 3 is 1 to the one where
 * coordinate e is 1; the neighbour runs along it the other way. So the neighbour's coordinate
 * (ae + 1) % 3 is minus ours (e + 1) % 3 (the distance past the edge), its coordinate ae is 1 -
 * ours e and its (ae + 2) % 3 is 1 - ours (e + 2) % 3: new coordinate i reads old (i + s) % 3,
 * s = (e - ae) mod 3, and decreases with it (so bounds map lo <-> hi). */
static inline void st_tri_across_edge(unsigned e, unsigned ae, const float p[3], float np[3])
{
    unsigned s = (e + 3 - ae) % 3, cz = (ae + 1) % 3;
#pragma GCC unroll 3
    for (unsigned i = 0; i < 3; i++) {
        unsigned o = i + s < 3 ? i + s : i + s - 3; /* (i + s) % 3 without a division */
        np[i] = i == cz ? -p[o] : 1.0f - p[o];
    }
}

/* Reduces the R x R triangle level src (R >= 2, a power of two) into the R/2 x R/2 level dst:
 * each small triangle of the coarser level is the mean of the four it splits into (three of
 * the same orientation at its corners and the opposite one in the middle). Texel (i, j) of dst
 * = quarter(src(2i, 2j) + src(2i+1, 2j) + src(2i, 2j+1) + src(R-1-2j, R-1-2i)), per channel,
 * exactly as Ptex's reader makes triangle reductions: integers summed and shifted right by 2
 * (truncating), half and float summed in float in that order and multiplied by 0.25 (half
 * converted back as PtexHalf does, st_float_to_half_ptex: ties away from zero). dt is
 * st_dtype, nc the channel count; texels interleaved, rows of u. */
void st_tri_reduce(unsigned dt, unsigned nc, const uint8_t *src, uint32_t R, uint8_t *dst);

#endif
