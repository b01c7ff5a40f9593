/* store/kinds/cube_convert.c - building cube sets from images (strips, crosses, six faces,
 * lat-long, Ptex environment cubes), baking Castano edge-fixup faces and laying a cube out as
 * one image.
 *
 * Owns: st_cube_from_image, st_cube_guess_layout, st_cube_from_faces, st_cube_from_ptex_env,
 * st_cube_bake_fixup, st_cube_to_image, st_cube_to_ptex_env (and the Ptex env-cube layout). Does not own: face frames and lookup (cube.c), files
 * (import/: cube_write.c writes the image st_cube_to_image lays out).
 *
 * Strips and crosses are exact texel copies (a face is placed with a rotation of 0 or 180
 * degrees, see PLACE below); lat-long images and Ptex cubes are resampled by direction
 * (bilinear, with k x k supersampling when the source is denser than the face).
 */
#include "cube.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Face placement in a layout: cell (cx, cy) in units of n, rotated 180 degrees or not. */
typedef struct place { uint8_t cx, cy, rot180; } place;

static const place PLACE_CROSS_H[6] = {{0, 1, 0}, {2, 1, 0}, {1, 0, 1}, {1, 2, 1}, {1, 1, 0}, {3, 1, 0}};
static const place PLACE_CROSS_V[6] = {{0, 1, 0}, {2, 1, 0}, {1, 0, 1}, {1, 2, 1}, {1, 1, 0}, {1, 3, 1}};

static int is_pow2(uint32_t x) { return x && !(x & (x - 1)); }

static int layout_place(st_cube_layout l, unsigned f, place *p)
{
    switch (l) {
    case ST_CUBE_STRIP_V: p->cx = 0; p->cy = (uint8_t)f; p->rot180 = 0; return 0;
    case ST_CUBE_STRIP_H: p->cx = (uint8_t)f; p->cy = 0; p->rot180 = 0; return 0;
    case ST_CUBE_CROSS_H: *p = PLACE_CROSS_H[f]; return 0;
    case ST_CUBE_CROSS_V: *p = PLACE_CROSS_V[f]; return 0;
    default: return -1;
    }
}

static void layout_cells(st_cube_layout l, unsigned *cw, unsigned *ch)
{
    switch (l) {
    case ST_CUBE_STRIP_V: *cw = 1; *ch = 6; break;
    case ST_CUBE_STRIP_H: *cw = 6; *ch = 1; break;
    case ST_CUBE_CROSS_H: *cw = 4; *ch = 3; break;
    case ST_CUBE_CROSS_V: *cw = 3; *ch = 4; break;
    default: *cw = *ch = 0; break;
    }
}

int st_cube_guess_layout(const st_image *img)
{
    uint64_t w = img->w, h = img->h;
    if (h == 6 * w)
        return ST_CUBE_STRIP_V;
    if (w == 6 * h)
        return ST_CUBE_STRIP_H;
    if (3 * w == 4 * h)
        return ST_CUBE_CROSS_H;
    if (4 * w == 3 * h)
        return ST_CUBE_CROSS_V;
    if (w == 2 * h || img->envmap == ST_ENVMAP_LATLONG)
        return ST_CUBE_LATLONG;
    return -1;
}

static void cube_info_of(const st_image *img, st_set_info *info)
{
    memset(info, 0, sizeof *info);
    info->nchan = img->nchan;
    info->dtype = img->dtype;
    info->alpha_chan = img->alpha_chan;
    info->colorspace = img->colorspace;
    info->premultiplied = img->alpha_chan >= 0 && img->premultiplied;
}

static uint32_t pow2_near(uint32_t x)
{
    uint32_t p = 1;
    while (p < x && p < ST_MAX_DIM)
        p <<= 1;
    if (p > 1 && (p - x) > (x - p / 2))
        p >>= 1;
    return p ? p : 1;
}

/* Bilinear lookup in a lat-long image at a direction (OpenEXR convention). */
static void latlong_lookup(const st_image *img, const float d[3], float *out)
{
    float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    float lon = atan2f(d[0], d[2]);
    float lat = asinf(fmaxf(-1.0f, fminf(1.0f, d[1] / len)));
    float x = (lon / (-2.0f * (float)M_PI) + 0.5f) * (float)(img->w - 1);
    float y = (lat / (-(float)M_PI) + 0.5f) * (float)(img->h - 1);
    x = fminf(fmaxf(x, 0.0f), (float)(img->w - 1));
    y = fminf(fmaxf(y, 0.0f), (float)(img->h - 1));
    uint32_t x0 = (uint32_t)x, y0 = (uint32_t)y;
    uint32_t x1 = x0 + 1 < img->w ? x0 + 1 : x0, y1 = y0 + 1 < img->h ? y0 + 1 : y0;
    float fx = x - (float)x0, fy = y - (float)y0;
    size_t ts = st_dtype_size(img->dtype) * img->nchan;
    const uint8_t *p = img->data;
    const uint8_t *a = p + ((size_t)y0 * img->w + x0) * ts, *b = p + ((size_t)y0 * img->w + x1) * ts;
    const uint8_t *c = p + ((size_t)y1 * img->w + x0) * ts, *dd = p + ((size_t)y1 * img->w + x1) * ts;
    for (unsigned k = 0; k < img->nchan; k++) {
        float top = st_channel_get(img->dtype, a, k) * (1 - fx) + st_channel_get(img->dtype, b, k) * fx;
        float bot = st_channel_get(img->dtype, c, k) * (1 - fx) + st_channel_get(img->dtype, dd, k) * fx;
        out[k] = top * (1 - fy) + bot * fy;
    }
}

static int from_latlong(const st_image *img, uint32_t n, size_t max_bytes, st_set **out,
                        st_error *e)
{
    if (img->w < 2 || img->h < 2)
        return st_fail(e, ST_EINVAL, "lat-long image %ux%u is too small", img->w, img->h);
    if (!n)
        n = pow2_near(img->w / 4 ? img->w / 4 : 1);
    if (!is_pow2(n))
        return st_fail(e, ST_EINVAL, "cube face size %u is not a power of two", n);
    st_set_info info;
    cube_info_of(img, &info);
    int rc = st_cube_create(&info, n, max_bytes, out, e);
    if (rc)
        return rc;
    st_set *s = *out;
    /* supersampling so that each face texel averages the lat-long texels it covers */
    float density = (float)img->w / (4.0f * (float)n);
    unsigned k = density > 1.0f ? (unsigned)ceilf(density) : 1;
    if (k > 4)
        k = 4;
    size_t ts = st_texel_size(s);
    for (unsigned f = 0; f < 6; f++) {
        uint8_t *dst = st_face_level(s, f, 0);
        for (uint32_t j = 0; j < n; j++)
            for (uint32_t i = 0; i < n; i++) {
                float acc[4] = {0, 0, 0, 0}, smp[4];
                for (unsigned sj = 0; sj < k; sj++)
                    for (unsigned si = 0; si < k; si++) {
                        float u = ((float)i + ((float)si + 0.5f) / (float)k) / (float)n;
                        float v = ((float)j + ((float)sj + 0.5f) / (float)k) / (float)n;
                        float d[3];
                        st_cube_face_dir(f, u, v, d);
                        latlong_lookup(img, d, smp);
                        for (unsigned c = 0; c < img->nchan; c++)
                            acc[c] += smp[c];
                    }
                for (unsigned c = 0; c < img->nchan; c++)
                    st_channel_put(s->info.dtype, dst + ((size_t)j * n + i) * ts, c,
                                   acc[c] / (float)(k * k));
            }
    }
    st_set_build_mips(s, UINT32_MAX);
    return ST_OK;
}

int st_cube_from_image(const st_image *img, st_cube_layout layout, uint32_t face_n,
                       size_t max_bytes, st_set **out, st_error *e)
{
    *out = NULL;
    if (!img || !img->data || img->nchan < 1 || img->nchan > 4 || !st_dtype_size(img->dtype))
        return st_fail(e, ST_EINVAL, "no image to make a cube of");
    if (layout == ST_CUBE_LATLONG)
        return from_latlong(img, face_n, max_bytes, out, e);
    unsigned cw, ch;
    layout_cells(layout, &cw, &ch);
    if (!cw)
        return st_fail(e, ST_EINVAL, "cube layout %d unknown", (int)layout);
    if (img->w % cw || img->h % ch || img->w / cw != img->h / ch)
        return st_fail(e, ST_EINVAL, "image %ux%u does not fit a %ux%u cube layout", img->w, img->h,
                       cw, ch);
    uint32_t n = img->w / cw;
    if (!is_pow2(n))
        return st_fail(e, ST_EUNSUPPORTED,
                       "cube face size %u is not a power of two (resample through lat-long)", n);
    st_set_info info;
    cube_info_of(img, &info);
    int rc = st_cube_create(&info, n, max_bytes, out, e);
    if (rc)
        return rc;
    st_set *s = *out;
    size_t ts = st_texel_size(s);
    const uint8_t *src = img->data;
    for (unsigned f = 0; f < 6; f++) {
        place p;
        layout_place(layout, f, &p);
        uint8_t *dst = st_face_level(s, f, 0);
        for (uint32_t j = 0; j < n; j++)
            for (uint32_t i = 0; i < n; i++) {
                uint32_t x = p.rot180 ? n - 1 - i : i, y = p.rot180 ? n - 1 - j : j;
                size_t sx = (size_t)p.cx * n + x, sy = (size_t)p.cy * n + y;
                memcpy(dst + ((size_t)j * n + i) * ts, src + (sy * img->w + sx) * ts, ts);
            }
    }
    st_set_build_mips(s, UINT32_MAX);
    return ST_OK;
}

int st_cube_from_faces(const st_image faces[6], st_cube_faces_conv conv, size_t max_bytes,
                       st_set **out, st_error *e)
{
    *out = NULL;
    if ((unsigned)conv > ST_CUBE_FACES_GL_FLIPPED)
        return st_fail(e, ST_EINVAL, "six-face convention %d unknown (0 exr, 1 gl, 2 gl-flipped)",
                       (int)conv);
    for (int f = 0; f < 6; f++) {
        if (!faces[f].data || faces[f].w != faces[f].h)
            return st_fail(e, ST_EINVAL, "cube face %d: %ux%u is not square", f, faces[f].w, faces[f].h);
        if (faces[f].w != faces[0].w || faces[f].nchan != faces[0].nchan ||
            faces[f].dtype != faces[0].dtype)
            return st_fail(e, ST_EINVAL, "cube face %d: size, channels or type differ from face 0", f);
    }
    uint32_t n = faces[0].w;
    if (!is_pow2(n))
        return st_fail(e, ST_EUNSUPPORTED, "cube face size %u is not a power of two", n);
    st_set_info info;
    cube_info_of(&faces[0], &info);
    int rc = st_cube_create(&info, n, max_bytes, out, e);
    if (rc)
        return rc;
    st_set *s = *out;
    size_t ts = st_texel_size(s);
    for (unsigned f = 0; f < 6; f++) {
        /* GL's frame is ours with z negated: +Z and -Z exchange, images are the same */
        unsigned src_f = f;
        if (conv != ST_CUBE_FACES_EXR && f >= 4)
            src_f = f == 4 ? 5 : 4;
        const uint8_t *src = faces[src_f].data;
        uint8_t *dst = st_face_level(s, f, 0);
        for (uint32_t j = 0; j < n; j++) {
            uint32_t sj = conv == ST_CUBE_FACES_GL_FLIPPED ? n - 1 - j : j;
            memcpy(dst + (size_t)j * n * ts, src + (size_t)sj * n * ts, (size_t)n * ts);
        }
    }
    st_set_build_mips(s, UINT32_MAX);
    return ST_OK;
}

/* Ptex envcube frames (wdas envcube sample, faces px nx py ny pz nz): P = N + s S + t T */
static const float PN[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
static const float PS[6][3] = {{0, 0, -1}, {0, 0, 1}, {1, 0, 0}, {1, 0, 0}, {1, 0, 0}, {-1, 0, 0}};
static const float PT[6][3] = {{0, 1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}, {0, 1, 0}, {0, 1, 0}};

static float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Bilinear lookup at (u, v) in level 0 of face f of a set (texel centres, clamped). */
static void face_bilinear(const st_set *s, unsigned f, float u, float v, float *out)
{
    const st_face *F = &s->faces[f];
    size_t ts = st_texel_size(s);
    const uint8_t *p = st_face_level(s, f, 0);
    unsigned nc = s->info.nchan, dt = s->info.dtype;
    if (F->flags & ST_FACE_CONSTANT) {
        for (unsigned c = 0; c < nc; c++)
            out[c] = st_channel_get(dt, p, c);
        return;
    }
    float x = u * (float)F->w - 0.5f, y = v * (float)F->h - 0.5f;
    x = fminf(fmaxf(x, 0.0f), (float)(F->w - 1));
    y = fminf(fmaxf(y, 0.0f), (float)(F->h - 1));
    uint32_t x0 = (uint32_t)x, y0 = (uint32_t)y;
    uint32_t x1 = x0 + 1 < F->w ? x0 + 1 : x0, y1 = y0 + 1 < F->h ? y0 + 1 : y0;
    float fx = x - (float)x0, fy = y - (float)y0;
    for (unsigned c = 0; c < nc; c++) {
        float a = st_channel_get(dt, p + ((size_t)y0 * F->w + x0) * ts, c);
        float b = st_channel_get(dt, p + ((size_t)y0 * F->w + x1) * ts, c);
        float cc = st_channel_get(dt, p + ((size_t)y1 * F->w + x0) * ts, c);
        float d = st_channel_get(dt, p + ((size_t)y1 * F->w + x1) * ts, c);
        out[c] = (a * (1 - fx) + b * fx) * (1 - fy) + (cc * (1 - fx) + d * fx) * fy;
    }
}

/* Fills level 0 of dst's 6 faces (n x n) from src by direction, then its mips: from a Ptex
 * env cube to a cube (to_ptex 0: the same major axis gives the Ptex face with the same index)
 * or back (to_ptex 1). Ptex face f and cube face f differ by a rotation / flip, so at equal
 * sizes texel centres land on texel centres and the bilinear lookup copies texels exactly. */
static void remap_env(const st_set *src, st_set *dst, uint32_t n, int to_ptex)
{
    size_t ts = st_texel_size(dst);
    float smp[4];
    for (unsigned f = 0; f < 6; f++) {
        uint8_t *out = st_face_level(dst, f, 0);
        for (uint32_t j = 0; j < n; j++)
            for (uint32_t i = 0; i < n; i++) {
                float fu = ((float)i + 0.5f) / (float)n, fv = ((float)j + 0.5f) / (float)n;
                float d[3], u, v;
                unsigned sf = f;
                if (to_ptex) {
                    for (int a = 0; a < 3; a++)
                        d[a] = PN[f][a] + (2.0f * fu - 1.0f) * PS[f][a] + (2.0f * fv - 1.0f) * PT[f][a];
                    int cf = st_cube_dir_to_face(d, &u, &v);
                    sf = cf < 0 ? f : (unsigned)cf;
                } else {
                    st_cube_face_dir(f, fu, fv, d);
                    float dn = dot3(d, PN[f]);
                    u = 0.5f * (dot3(d, PS[f]) / dn + 1.0f);
                    v = 0.5f * (dot3(d, PT[f]) / dn + 1.0f);
                }
                face_bilinear(src, sf, u, v, smp);
                for (unsigned c = 0; c < dst->info.nchan; c++)
                    st_channel_put(dst->info.dtype, out + ((size_t)j * n + i) * ts, c, smp[c]);
            }
    }
    st_set_build_mips(dst, UINT32_MAX);
}

int st_cube_from_ptex_env(const st_set *px, size_t max_bytes, st_set **out, st_error *e)
{
    *out = NULL;
    if (!px || px->info.nfaces != 6)
        return st_fail(e, ST_EINVAL, "a Ptex environment cube has 6 faces (this one has %u)",
                       px ? px->info.nfaces : 0);
    uint32_t n = 1;
    for (unsigned f = 0; f < 6; f++) {
        uint32_t m = px->faces[f].w > px->faces[f].h ? px->faces[f].w : px->faces[f].h;
        if (!(px->faces[f].flags & ST_FACE_CONSTANT) && m > n)
            n = m;
    }
    st_set_info info = px->info;
    info.meshtype = 0;
    int rc = st_cube_create(&info, n, max_bytes, out, e);
    if (rc)
        return rc;
    remap_env(px, *out, n, 0);
    return ST_OK;
}

/* Ptex's environment-cube layout (faces px nx py ny pz nz, frames of the wdas envcube
 * sample's envcube.obj): neighbour face and edge across edges 0..3 of each face. */
static const int32_t ENV_ADJF[6][4] = {{3, 5, 2, 4}, {3, 4, 2, 5}, {4, 0, 5, 1},
                                       {5, 0, 4, 1}, {3, 0, 2, 1}, {3, 1, 2, 0}};
static const int8_t ENV_ADJE[6][4] = {{1, 3, 1, 1}, {3, 3, 3, 1}, {2, 2, 2, 2},
                                      {0, 0, 0, 0}, {2, 3, 0, 1}, {0, 3, 2, 1}};

int st_cube_is_ptex_env_layout(const st_set *s)
{
    if (!s || s->info.nfaces != 6)
        return 0;
    for (int f = 0; f < 6; f++)
        for (int k = 0; k < 4; k++)
            if (s->faces[f].adjface[k] != ENV_ADJF[f][k] ||
                s->faces[f].adjedge[k] != ENV_ADJE[f][k])
                return 0;
    return 1;
}

int st_cube_to_ptex_env(const st_set *cube, size_t max_bytes, st_set **out, st_error *e)
{
    *out = NULL;
    if (!cube || cube->info.kind != ST_KIND_CUBE || cube->info.nfaces != 6)
        return st_fail(e, ST_EINVAL, "not a cube set");
    uint32_t n = cube->faces[0].w;
    int rc = st_cube_six_faces(&cube->info, n, ST_KIND_PERFACE, ENV_ADJF, ENV_ADJE, max_bytes,
                               out, e);
    if (rc)
        return rc;
    st_set *s = *out;
    remap_env(cube, s, n, 1);
    if (cube->info.colorspace == ST_CS_SRGB &&
        (rc = st_set_meta_add(s, ST_META_COLORSPACE, 0, "srgb", 5, e)) != ST_OK) {
        st_set_free(s);
        *out = NULL;
        return rc;
    }
    for (uint32_t i = 0; i < cube->nmeta; i++) {
        const st_meta_entry *m = &cube->meta[i];
        if ((rc = st_set_meta_add(s, m->key, m->type, m->data, m->count, e)) != ST_OK) {
            st_set_free(s);
            *out = NULL;
            return rc;
        }
    }
    return ST_OK;
}

int st_cube_bake_fixup(const st_set *cube, size_t max_bytes, st_set **out, st_error *e)
{
    *out = NULL;
    if (!cube || cube->info.kind != ST_KIND_CUBE)
        return st_fail(e, ST_EINVAL, "not a cube set");
    uint32_t n = cube->faces[0].w;
    int rc = st_cube_create(&cube->info, n, max_bytes, out, e);
    if (rc)
        return rc;
    st_set *s = *out;
    size_t ts = st_texel_size(s);
    unsigned nc = s->info.nchan;
    st_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = ST_MODE_TRAVERSE;
    o.filter = ST_FILTER_BILINEAR;
    enum { B = 256 };
    st_query q[B];
    float res[B * 4];
    for (unsigned f = 0; f < 6; f++)
        for (unsigned l = 0; l < s->faces[f].nlevels; l++) {
            uint32_t m = st_level_w(&s->faces[f], l);
            uint8_t *dst = st_face_level(s, f, l);
            /* footprint of one level-l texel, so the sampler reads level l */
            float fp = (float)(1u << l) / (float)n;
            size_t total = (size_t)m * m, done = 0;
            while (done < total) {
                size_t k = total - done < B ? total - done : B;
                for (size_t i = 0; i < k; i++) {
                    uint32_t x = (uint32_t)((done + i) % m), y = (uint32_t)((done + i) / m);
                    /* Castano's map_2: texel x of m -> s = 2x/(m-1) - 1 (centre for m = 1) */
                    float sx = m > 1 ? 2.0f * (float)x / (float)(m - 1) - 1.0f : 0.0f;
                    float sy = m > 1 ? 2.0f * (float)y / (float)(m - 1) - 1.0f : 0.0f;
                    q[i].face = f;
                    q[i].u = 0.5f * (sx + 1.0f);
                    q[i].v = 0.5f * (sy + 1.0f);
                    q[i].dudx = fp;
                    q[i].dvdx = 0;
                    q[i].dudy = 0;
                    q[i].dvdy = fp;
                }
                int r = st_sample_batch(cube, &o, q, k, res, NULL, NULL);
                if (r < 0) {
                    st_set_free(s);
                    *out = NULL;
                    return st_fail(e, r, "sampling the cube for edge fixup failed");
                }
                for (size_t i = 0; i < k; i++)
                    for (unsigned c = 0; c < nc; c++)
                        st_channel_put(s->info.dtype, dst + (done + i) * ts, c, res[i * nc + c]);
                done += k;
            }
        }
    return ST_OK;
}

int st_cube_to_image(const st_set *cube, unsigned level, st_cube_layout layout, st_image *out,
                     st_error *e)
{
    memset(out, 0, sizeof *out);
    if (!cube || cube->info.kind != ST_KIND_CUBE)
        return st_fail(e, ST_EINVAL, "not a cube set");
    if (level >= cube->faces[0].nlevels)
        return st_fail(e, ST_EINVAL, "level %u not in the cube (%u levels)", level,
                       cube->faces[0].nlevels);
    unsigned cw, ch;
    layout_cells(layout, &cw, &ch);
    if (!cw)
        return st_fail(e, ST_EINVAL, "cube layout %d cannot be written", (int)layout);
    uint32_t n = st_level_w(&cube->faces[0], level);
    size_t ts = st_texel_size(cube);
    size_t W = (size_t)cw * n, H = (size_t)ch * n;
    uint8_t *img = calloc(W * H, ts);
    if (!img)
        return st_fail(e, ST_ENOMEM, "out of memory for a %zux%zu cube image", W, H);
    for (unsigned f = 0; f < 6; f++) {
        place p;
        layout_place(layout, f, &p);
        const uint8_t *src = st_face_level(cube, f, level);
        int cst = (cube->faces[f].flags & ST_FACE_CONSTANT) != 0;
        for (uint32_t j = 0; j < n; j++)
            for (uint32_t i = 0; i < n; i++) {
                uint32_t x = p.rot180 ? n - 1 - i : i, y = p.rot180 ? n - 1 - j : j;
                size_t dx = (size_t)p.cx * n + x, dy = (size_t)p.cy * n + y;
                memcpy(img + (dy * W + dx) * ts, cst ? src : src + ((size_t)j * n + i) * ts, ts);
            }
    }
    out->w = (uint32_t)W;
    out->h = (uint32_t)H;
    out->nchan = cube->info.nchan;
    out->dtype = cube->info.dtype;
    out->colorspace = cube->info.colorspace;
    out->alpha_chan = cube->info.alpha_chan;
    out->premultiplied = cube->info.premultiplied;
    /* only the vertical strip is OpenEXR's envmap=cube layout: a cross or a horizontal strip
     * tagged so would be read as a vertical strip (and refused: it does not fit 1 x 6) */
    out->envmap = layout == ST_CUBE_STRIP_V ? ST_ENVMAP_CUBE : ST_ENVMAP_NONE;
    out->nlevels_file = 1;
    out->data = img;
    return ST_OK;
}
