/* store/kinds/cube.c - cube map core: face frames, adjacency, direction <-> face uv, footprints,
 * Castano's edge-fixup lookup and the batch sampler front end.
 *
 * Owns: st_cube_create, st_cube_face_dir, st_cube_dir_to_face, st_cube_fixup_dir,
 * st_cube_queries, st_cube_sample_dir. Does not own: conversions from images and edge-fixup
 * baking (cube_convert.c), filtering (sample.c). Conventions are in cube.h.
 *
 * Hot path: st_cube_sample_dir converts directions in chunks of CHUNK queries on the stack
 * and hands each chunk to st_sample_batch; nothing is allocated.
 */
#include "cube.h"

#include "bc1_texel.h"

#include <math.h>
#include <string.h>

/* dir = N + s S + t T for face f (s = 2u - 1, t = 2v - 1) */
static const float FN[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
static const float FS[6][3] = {{0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {1, 0, 0}, {-1, 0, 0}, {1, 0, 0}};
static const float FT[6][3] = {{0, -1, 0}, {0, -1, 0}, {0, 0, -1}, {0, 0, 1}, {0, -1, 0}, {0, -1, 0}};

static const int32_t ADJF[6][4] = {{2, 4, 3, 5}, {2, 5, 3, 4}, {4, 0, 5, 1},
                                   {5, 0, 4, 1}, {2, 1, 3, 0}, {2, 0, 3, 1}};
static const int8_t ADJE[6][4] = {{1, 3, 1, 1}, {3, 3, 3, 1}, {0, 0, 0, 0},
                                  {2, 2, 2, 2}, {0, 3, 2, 1}, {2, 3, 0, 1}};

static int is_pow2(uint32_t x) { return x && !(x & (x - 1)); }

int st_cube_six_faces(const st_set_info *info, uint32_t n, unsigned kind,
                      const int32_t adjf[6][4], const int8_t adje[6][4], size_t max_bytes,
                      st_set **out, st_error *e)
{
    *out = NULL;
    if (!is_pow2(n) || n > ST_MAX_DIM)
        return st_fail(e, ST_EINVAL, "cube face size %u is not a power of two in 1..%u", n,
                       ST_MAX_DIM);
    st_set_info in = *info;
    in.nfaces = 6;
    in.kind = (uint8_t)kind;
    in.meshtype = 0;
    st_face_desc fd[6];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 6; f++) {
        fd[f].w = fd[f].h = n;
        for (int k = 0; k < 4; k++) {
            fd[f].adjface[k] = adjf[f][k];
            fd[f].adjedge[k] = adje[f][k];
        }
    }
    return st_set_create(&in, fd, max_bytes, out, e);
}

int st_cube_create(const st_set_info *info, uint32_t n, size_t max_bytes, st_set **out,
                   st_error *e)
{
    return st_cube_six_faces(info, n, ST_KIND_CUBE, ADJF, ADJE, max_bytes, out, e);
}

void st_cube_face_dir(unsigned face, float u, float v, float dir[3])
{
    if (face > 5)
        face = 0;
    float s = 2.0f * u - 1.0f, t = 2.0f * v - 1.0f;
    for (int k = 0; k < 3; k++)
        dir[k] = FN[face][k] + s * FS[face][k] + t * FT[face][k];
}

static float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Major axis 0..2 of a direction (ties: x, then y, as OpenEXR), -1 for a zero, NaN or
 * infinite one. Each component is tested alone: a sum of magnitudes would overflow to
 * infinity for finite directions near FLT_MAX and refuse them. */
static int major_axis(const float d[3])
{
    float ax = fabsf(d[0]), ay = fabsf(d[1]), az = fabsf(d[2]);
    if (!isfinite(ax) || !isfinite(ay) || !isfinite(az))
        return -1;
    if (ax >= ay && ax >= az)
        return ax > 0.0f ? 0 : -1;
    return ay >= az ? 1 : 2;
}

static int major_face(const float d[3])
{
    int a = major_axis(d);
    return a < 0 ? -1 : 2 * a + (d[a] > 0 ? 0 : 1);
}

static float clamp01(float x) { return x < 0.0f ? 0.0f : x > 1.0f ? 1.0f : x; }

int st_cube_dir_to_face(const float dir[3], float *u, float *v)
{
    int f = major_face(dir);
    if (f < 0)
        return -1;
    float dn = dot3(dir, FN[f]);
    *u = clamp01(0.5f * (dot3(dir, FS[f]) / dn + 1.0f));
    *v = clamp01(0.5f * (dot3(dir, FT[f]) / dn + 1.0f));
    return f;
}

void st_cube_fixup_dir(const float dir[3], float n, float lod, float out[3])
{
    /* the major axis by the lookup's own rule: at an exact tie (a cube edge or corner) the
     * tied component that does not pick the face is scaled too, as OpenEXR's lookup does */
    int a = major_axis(dir);
    float scale = n > 0 ? 1.0f - exp2f(lod > 0 ? lod : 0) / n : 1.0f;
    if (scale < 0)
        scale = 0;
    for (int k = 0; k < 3; k++)
        out[k] = k != a ? dir[k] * scale : dir[k];
}

/* uv derivative of the face mapping along a direction change dd at direction d on face f */
static void uv_deriv(int f, const float d[3], const float dd[3], float *du, float *dv)
{
    float dn = dot3(d, FN[f]), ddn = dot3(dd, FN[f]);
    float inv = 0.5f / (dn * dn);
    *du = (dot3(dd, FS[f]) * dn - dot3(d, FS[f]) * ddn) * inv;
    *dv = (dot3(dd, FT[f]) * dn - dot3(d, FT[f]) * ddn) * inv;
}

/* One query: face, uv and footprint in uv units; lod0 is used by the fixup lookup.
 * Returns 0, or the status of a query that gets no value: ST_Q_NONFINITE (a zero / non-finite
 * direction, a non-finite cone or footprint), ST_Q_BAD_FOOTPRINT (a negative cone: neither a
 * cone nor the "derivatives" of cone == 0). */
static int map_query(const st_set *cube, unsigned lookup, const st_cube_query *q, st_query *fq)
{
    float d[3] = {q->dir[0], q->dir[1], q->dir[2]};
    int f = major_face(d);
    if (f < 0 || !isfinite(q->cone))
        return ST_Q_NONFINITE;
    if (q->cone < 0.0f)
        return ST_Q_BAD_FOOTPRINT;
    float dn = fabsf(dot3(d, FN[f]));
    /* normalise so the major component is 1: derivatives scale with it */
    float dxs[3], dys[3];
    for (int k = 0; k < 3; k++) {
        d[k] /= dn;
        dxs[k] = q->ddx[k] / dn;
        dys[k] = q->ddy[k] / dn;
    }
    float s = dot3(d, FS[f]), t = dot3(d, FT[f]);
    float dudx, dvdx, dudy, dvdy;
    if (q->cone > 0) {
        /* a cone of apex angle c: radial extent c r^2, tangential c r (plane units) */
        float r2 = 1.0f + s * s + t * t, r = sqrtf(r2);
        float l = sqrtf(s * s + t * t);
        float ex = l > 1e-6f ? s / l : 1.0f, ey = l > 1e-6f ? t / l : 0.0f;
        float a = 0.5f * q->cone * r2, b = 0.5f * q->cone * r;
        dudx = ex * a;
        dvdx = ey * a;
        dudy = -ey * b;
        dvdy = ex * b;
    } else {
        uv_deriv(f, d, dxs, &dudx, &dvdx);
        uv_deriv(f, d, dys, &dudy, &dvdy);
    }
    if (!isfinite(dudx + dvdx + dudy + dvdy))
        return ST_Q_NONFINITE;
    if (lookup == ST_CUBE_LOOKUP_FIXUP) {
        float n = (float)cube->faces[0].w;
        float lx = sqrtf(dudx * dudx + dvdx * dvdx), ly = sqrtf(dudy * dudy + dvdy * dvdy);
        float len = fmaxf(lx, ly) * n;
        float lod = len > 1.0f ? log2f(len) : 0.0f;
        float fd[3];
        st_cube_fixup_dir(d, n, lod, fd);
        int g = major_face(fd);
        if (g < 0)
            return ST_Q_NONFINITE;
        f = g;
        float gn = dot3(fd, FN[f]);
        s = dot3(fd, FS[f]) / gn;
        t = dot3(fd, FT[f]) / gn;
    }
    fq->face = (uint32_t)f;
    fq->u = clamp01(0.5f * (s + 1.0f));
    fq->v = clamp01(0.5f * (t + 1.0f));
    fq->dudx = dudx;
    fq->dvdx = dvdx;
    fq->dudy = dudy;
    fq->dvdy = dvdy;
    return 0;
}

void st_cube_queries(const st_set *cube, unsigned lookup, const st_cube_query *q, size_t n,
                     st_query *fq, uint8_t *status)
{
    for (size_t i = 0; i < n; i++) {
        int r = map_query(cube, lookup, &q[i], &fq[i]);
        if (r) {
            memset(&fq[i], 0, sizeof fq[i]);
            fq[i].u = fq[i].v = 0.5f;
            if (status)
                status[i] = (uint8_t)r;
        } else if (status) {
            status[i] = ST_Q_OK;
        }
    }
}

int st_cube_is_cube(const st_set *s)
{
    if (!s || s->info.nfaces != 6)
        return 0;
    if (s->info.kind == ST_KIND_CUBE)
        return 1;
    const st_bc1_ext *x = st_set_ext_get(s, ST_EXT_BC1);
    return x && x->src_kind == ST_KIND_CUBE;
}

#define CHUNK 128

int st_cube_sample_dir(const st_set *cube, const st_sample_opts *o, unsigned lookup,
                       const st_cube_query *q, size_t n, float *out, float *coverage,
                       uint8_t *status)
{
    if (!cube || !st_cube_is_cube(cube) || !out || !o)
        return ST_EINVAL;
    if (lookup > ST_CUBE_LOOKUP_FIXUP)
        return ST_EINVAL;
    unsigned nc = cube->info.nchan;
    st_query fq[CHUNK];
    uint8_t pre[CHUNK], st[CHUNK];
    int bad = 0;
    for (size_t i0 = 0; i0 < n; i0 += CHUNK) {
        size_t m = n - i0 < CHUNK ? n - i0 : CHUNK;
        st_cube_queries(cube, lookup, q + i0, m, fq, pre);
        int r = st_sample_batch(cube, o, fq, m, out + i0 * nc,
                                coverage ? coverage + i0 : NULL, st);
        if (r < 0)
            return r;
        for (size_t k = 0; k < m; k++) {
            if (pre[k] != ST_Q_OK) {
                st[k] = pre[k];
                for (unsigned c = 0; c < nc; c++)
                    out[(i0 + k) * nc + c] = NAN;
                if (coverage)
                    coverage[i0 + k] = 0.0f;
            }
            if (st[k] != ST_Q_OK)
                bad++;
            if (status)
                status[i0 + k] = st[k];
        }
    }
    return bad;
}
