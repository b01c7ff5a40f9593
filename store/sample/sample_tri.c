/* store/sample/sample_tri.c - the GPU-style filters on a triangle-mesh set (st_meshtype
 * ST_MESH_TRIANGLE; layout in core/trilevel.h).
 *
 * Only `point` is defined there. Its footprint maps as on a quad face of the same size: a
 * triangle face of resolution R keeps its texels on an R x R grid of barycentric (u, v)
 * (small triangles of side 1/R along u and v), so (du/dx, dv/dx) and (du/dy, dv/dy) times R
 * are the footprint in texels and GL's rule picks the level (docs/sampler.md); the small
 * triangle holding (u, v) at that level is returned (the Ptex point rule, trilevel.h). A point
 * never leaves the face, so Discard, Traverse and Clamp agree and the coverage is 1.
 * Bilinear, trilinear and anisotropic are refused (ST_EUNSUPPORTED): the texels of a triangle
 * level are not a grid that bilinear weights apply to (the 2x2 square around a point mixes
 * upright triangles with mirrored inverted ones from the other half of the face); the
 * filtered path for triangles is the Ptex triangle filter (ptex/ptextri.h).
 */
#include <math.h>

#include "sample_internal.h"
#include "trilevel.h"

int st_sample_tri_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                        float *out, float *coverage, uint8_t *status)
{
    if (o->filter != ST_FILTER_POINT)
        return ST_EUNSUPPORTED;
    unsigned nc = s->info.nchan, dt = s->info.dtype;
    size_t ts = st_texel_size(s);
    int bad = 0;
    for (size_t i = 0; i < n; i++) {
        float *oi = out + i * nc;
        int st = st_check_query(s, &q[i]);
        if (st == ST_Q_OK) {
            const st_face *F = &s->faces[q[i].face];
            const float R0 = (float)F->w;
            const float ax = q[i].dudx * R0, ay = q[i].dvdx * R0;
            const float bx = q[i].dudy * R0, by = q[i].dvdy * R0;
            const float rx2 = ax * ax + ay * ay, ry2 = bx * bx + by * by;
            const float rho2 = rx2 > ry2 ? rx2 : ry2;
            unsigned level = rho2 > 2.0f ? st_nearest_level(st_lod_of_rho2(rho2), F->nlevels) : 0;
            const uint8_t *p = st_face_level(s, q[i].face, 0);
            if (!(F->flags & ST_FACE_CONSTANT)) {
                uint32_t R = st_level_w(F, level), x, y;
                p = st_face_level(s, q[i].face, level);
                st_tri_texel(R, q[i].u, q[i].v, &x, &y);
                p += ((size_t)y * R + x) * ts;
            }
            for (unsigned c = 0; c < nc; c++)
                oi[c] = st_channel_get(dt, p, c);
        } else {
            for (unsigned c = 0; c < nc; c++)
                oi[c] = NAN;
        }
        if (coverage)
            coverage[i] = st == ST_Q_OK ? 1.0f : 0.0f;
        if (status)
            status[i] = (uint8_t)st;
        bad += st != ST_Q_OK;
    }
    return bad;
}
