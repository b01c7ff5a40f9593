/* tools/seamreport.c - seamtex-seamreport: the measured seam report of BC1 compression.
 *
 * Owns: the report (a table per data set) and the close-up PNGs. Does not own any method:
 * everything measured here is the store's (seammask.h, bc1.h).
 *
 * For each atlas mesh under $SEAMTEX_DATA/meshes/ and a few per-face sets from ptx/, five
 * variants of level 0:
 *   original | masked (8-bit, uncompressed) | plain BC1 of the original | plain BC1 of the
 *   masked texture | seam-aware BC1
 * with PSNR inside charts (RGB, against the original) and seam RMS (per channel, 0..255,
 * over the seam sample points, length-weighted). BC1 is decoded with the exact decoder.
 * Close-ups: at the seam point at the 90th percentile of plain BC1 (masked)'s residual, 16 x 16
 * texel window stitched across the seam (left half from side A's chart or face, right half
 * from side B's, as a renderer magnifies the surface there), magnified 8x with bilinear
 * filtering; the five variants left to right in the order above; one PNG per data set in
 * OUT (default build/report/<name>_closeup.png).
 *
 * Usage: seamtex-seamreport [--data DIR] [--out DIR] [--level fast|hq|best] [--step S] [--alpha A]
 *                           [--boost B] [--only NAME] [--json PATH] [--big]
 * (alpha: masking seam weight; the seam-aware BC1 stage uses alpha * boost, raised while its
 * seam RMS is above goal x the masked texture's, as st_bc1_compress_set does with its
 * defaults 2, 1.25 and 1.1; --goal 0 keeps alpha * boost.) --big instead times the whole
 * st_bc1_compress_set of a 4096^2 atlas (the milk truck texture upscaled 2x, its mesh).
 */
#include "atlas.h"
#include "bc1.h"
#include "image.h"
#include "mesh.h"
#include "ptex.h"
#include "seammask.h"
#include "image_io.h"
#include "mesh_io.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>

typedef struct dataset {
    const char *name;
    const char *obj;     /* atlas: mesh file, NULL for per-face */
    const char *tex;     /* atlas: texture; per-face: the .ptx */
} dataset;

static const dataset SETS[] = {
    {"duck", "meshes/duck/Duck.obj", "meshes/duck/DuckCM.png"},
    {"waterbottle", "meshes/waterbottle/WaterBottle.obj",
     "meshes/waterbottle/WaterBottle_baseColor.png"},
    {"cesiummilktruck", "meshes/cesiummilktruck/CesiumMilkTruck.obj",
     "meshes/cesiummilktruck/CesiumMilkTruck.png"},
    {"spider", "meshes/spider/spider.obj", "meshes/spider/drkwood2.jpg"},
    {"ptex-teapot", NULL, "ptx/wdas-ptex-samples/teapot/teapot.ptx"},
    {"ptex-holeycube", NULL, "ptx/wdas-ptex-samples/holeycube/holeycube.ptx"},
    {"ptex-cube8rot", NULL, "ptex-ref/cube8_k6_u8_rot.ptx"},
    {"ptex-nonquad", NULL, "ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx"},
    {"ptex-textcube", NULL, "ptx/wdas-ptex-2009/cube/text/cube.ptx"},
};

enum { V_ORIG, V_MASK, V_BC1, V_BC1M, V_AWARE, NV };
static const char *VNAME[NV] = {"original", "masked 8-bit", "plain BC1 (orig)",
                                "plain BC1 (masked)", "seam-aware BC1"};

/* CPU time of this thread: the machine is shared, wall time would measure the neighbours */
static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static void path_join(char *out, size_t n, const char *a, const char *b)
{
    snprintf(out, n, "%s/%s", a, b);
}

/* Encodes every face of a global RGBA8 buffer; blocks[f] NULL for 1x1 constant faces. */
static int encode_global(const st_set *s, const st_seam_sys *sys, const uint8_t *rgba, int level,
                         float outside_weight, uint8_t **blocks, st_error *e)
{
    for (uint32_t f = 0; f < sys->nfaces; f++) {
        blocks[f] = NULL;
        if (s->faces[f].flags & ST_FACE_CONSTANT)
            continue;
        size_t nb = (size_t)((sys->fw[f] + 3) / 4) * ((sys->fh[f] + 3) / 4);
        blocks[f] = malloc(nb * 8);
        if (!blocks[f])
            return st_fail(e, ST_ENOMEM, "out of memory");
        float *wt = NULL;
        if (outside_weight >= 0) {
            size_t n = (size_t)sys->fw[f] * sys->fh[f];
            wt = malloc(n * sizeof *wt);
            if (!wt)
                return st_fail(e, ST_ENOMEM, "out of memory");
            for (size_t i = 0; i < n; i++)
                wt[i] = sys->inside[sys->base[f] + i] ? 1.0f : outside_weight;
        }
        int rc = st_bc1_encode_image_w(rgba + sys->base[f] * 4, wt, sys->fw[f], sys->fh[f],
                                       (size_t)sys->fw[f] * 4, level, 1, blocks[f], e);
        free(wt);
        if (rc)
            return rc;
    }
    return ST_OK;
}

static void decode_global(const st_seam_sys *sys, uint8_t *const *blocks, const uint8_t *fallback,
                          uint8_t *out)
{
    for (uint32_t f = 0; f < sys->nfaces; f++) {
        if (!blocks[f]) {
            memcpy(out + sys->base[f] * 4, fallback + sys->base[f] * 4,
                   (size_t)(sys->base[f + 1] - sys->base[f]) * 4);
            continue;
        }
        st_bc1_decode_image(blocks[f], sys->fw[f], sys->fh[f], ST_BC1_DEC_EXACT,
                            out + sys->base[f] * 4);
    }
}

static void free_blocks(uint8_t **b, uint32_t n)
{
    if (!b)
        return;
    for (uint32_t f = 0; f < n; f++)
        free(b[f]);
    free(b);
}

/* Residual magnitude of point p in buffer rgba. */
static double point_resid(const st_seam_sys *sys, size_t k, const uint8_t *rgba)
{
    const st_seam_pt *p = &sys->pts[k];
    double acc = 0;
    for (int c = 0; c < 3; c++) {
        double r = 0;
        for (int j = 0; j < 4; j++)
            r += p->wa[j] * rgba[sys->vars[p->va[j]] * 4 + (uint64_t)c] -
                 p->wb[j] * rgba[sys->vars[p->vb[j]] * 4 + (uint64_t)c];
        acc += r * r;
    }
    return sqrt(acc / 3);
}

/* E = Ec + alpha Es over every texel of the buffer (data weight 1 inside charts, 0.01
 * outside, as masking uses), against the original: comparable across variants. */
static double energy(const st_seam_sys *sys, const uint8_t *orig, const uint8_t *rgba, double alpha,
                     double *ec_out)
{
    double ec = 0, es = 0;
    for (uint64_t t = 0; t < sys->ntexels; t++) {
        double d = sys->inside[t] ? 1.0 : 0.01, s2 = 0;
        for (int c = 0; c < 3; c++) {
            double x = (double)rgba[4 * t + c] - orig[4 * t + c];
            s2 += x * x;
        }
        ec += d * s2;
    }
    for (size_t k = 0; k < sys->npts; k++) {
        double r = point_resid(sys, k, rgba);
        es += sys->pts[k].len * 3 * r * r;
    }
    if (ec_out)
        *ec_out = ec;
    return ec + alpha * es;
}

/* Bilinear sample of global RGBA8 texels of face f at texel coordinates (x, y) (centres at
 * +.5), REPEAT or clamp addressing. */
static void sample_face(const st_seam_sys *sys, const uint8_t *rgba, uint32_t f, double x, double y,
                        int wrap, double out[3])
{
    int64_t W = sys->fw[f], H = sys->fh[f];
    x -= 0.5;
    y -= 0.5;
    double fx = floor(x), fy = floor(y);
    double ax = x - fx, ay = y - fy;
    out[0] = out[1] = out[2] = 0;
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            int64_t xx = (int64_t)fx + i, yy = (int64_t)fy + j;
            if (wrap) {
                xx = ((xx % W) + W) % W;
                yy = ((yy % H) + H) % H;
            } else {
                xx = xx < 0 ? 0 : xx >= W ? W - 1 : xx;
                yy = yy < 0 ? 0 : yy >= H ? H - 1 : yy;
            }
            double w = (i ? ax : 1 - ax) * (j ? ay : 1 - ay);
            const uint8_t *p = rgba + (sys->base[f] + (uint64_t)(yy * W + xx)) * 4;
            for (int c = 0; c < 3; c++)
                out[c] += w * p[c];
        }
}

/* Stitched close-up of seam point k: an R x R texel window magnified M x, the left half read
 * from side A's chart (or face) and the right half from side B's, meeting at the seam in the
 * middle, the way a renderer magnifies the surface there. A seam shows as a vertical line. */
static void stitched(const st_seam_sys *sys, const uint8_t *rgba, size_t k, int R, int M,
                     uint8_t *dst, size_t dstride)
{
    const st_seam_pt *p = &sys->pts[k];
    const st_seam_frame *F = &sys->frames[p->seam];
    size_t first = k, last = k;
    while (first > 0 && sys->pts[first - 1].seam == p->seam)
        first--;
    while (last + 1 < sys->npts && sys->pts[last + 1].seam == p->seam)
        last++;
    double t = ((double)(k - first) + 0.5) / (double)(last - first + 1);
    double lm = 0.5 * (F->len[0] + F->len[1]);
    if (lm <= 0)
        lm = 1;
    for (int py = 0; py < R * M; py++)
        for (int px = 0; px < R * M; px++) {
            double along = ((double)py + 0.5) / M - R / 2.0, across = ((double)px + 0.5) / M - R / 2.0;
            int side = across < 0 ? 0 : 1;
            double d = fabs(across), sc = F->len[side] / lm;
            double x = F->org[side][0] + F->tan[side][0] * (t * F->len[side] + along * sc) +
                       F->nrm[side][0] * d;
            double y = F->org[side][1] + F->tan[side][1] * (t * F->len[side] + along * sc) +
                       F->nrm[side][1] * d;
            double v[3];
            sample_face(sys, rgba, F->face[side], x, y, F->wrap, v);
            for (int c = 0; c < 3; c++)
                dst[(size_t)py * dstride + (size_t)px * 3 + c] = (uint8_t)(v[c] + 0.5);
        }
}

typedef struct result {
    double psnr[NV], rms[NV];
    double t_mask, t_enc, t_aware;
    double e_start, e_end;   /* E of the seam-aware stage at its alpha: start state, result */
    double en[NV + 1];       /* E at the stage's alpha over all texels; [NV]: masking at that alpha */
    double ec[NV + 1];       /* its data part Ec */
    double alpha_used;       /* the seam-aware stage's final alpha */
    double psnr_enc[NV];     /* PSNR inside charts against the texture each variant encodes */
    uint32_t w, h, nfaces, nseams;
    size_t npts;
    int ok;
} result;

static int run_set(const dataset *d, const char *data, const char *outdir, int level, float step,
                   float alpha, float boost, float goal, result *res, st_error *e)
{
    char p1[1024], p2[1024];
    st_set *s = NULL;
    int rc;
    memset(res, 0, sizeof *res);
    if (d->obj) {
        path_join(p1, sizeof p1, data, d->obj);
        path_join(p2, sizeof p2, data, d->tex);
        st_mesh *m = NULL;
        rc = st_obj_read_file(p1, NULL, &m, e);
        if (rc)
            return rc;
        st_image img;
        rc = st_image_read(p2, NULL, &img, e);
        if (rc) {
            st_mesh_free(m);
            return rc;
        }
        rc = st_atlas_from_image(&img, m, 0, &s, e);
        st_image_free(&img);
        if (rc)
            return rc;
        st_atlas *at = st_set_ext_get(s, ST_EXT_ATLAS);
        const char *b = strrchr(d->tex, '/');
        snprintf(at->texture_name, sizeof at->texture_name, "%s", b ? b + 1 : d->tex);
    } else {
        path_join(p1, sizeof p1, data, d->tex);
        rc = st_ptex_read_file(p1, 0, &s, e);
        if (rc)
            return rc;
    }
    st_seam_sys *sys = NULL;
    uint8_t *buf[NV] = {NULL};
    uint8_t **bl_orig = NULL, **bl_mask = NULL, **bl_aw = NULL;
    rc = st_seam_sys_build(s, step, &sys, e);
    if (rc)
        goto out;
    res->w = s->faces[0].w;
    res->h = s->faces[0].h;
    res->nfaces = s->info.nfaces;
    res->nseams = sys->nseams;
    res->npts = sys->npts;
    rc = st_seam_gather_rgba8(s, sys, &buf[V_ORIG], e);
    if (rc)
        goto out;
    size_t bytes = (size_t)sys->ntexels * 4;
    for (int v = 1; v < NV; v++) {
        buf[v] = malloc(bytes);
        if (!buf[v]) {
            rc = st_fail(e, ST_ENOMEM, "out of memory");
            goto out;
        }
    }
    memcpy(buf[V_MASK], buf[V_ORIG], bytes);
    double t0 = now();
    rc = st_seam_mask_rgba8(sys, alpha, 0, buf[V_MASK], NULL, e);
    if (rc)
        goto out;
    res->t_mask = now() - t0;
    bl_orig = calloc(sys->nfaces, sizeof *bl_orig);
    bl_mask = calloc(sys->nfaces, sizeof *bl_mask);
    bl_aw = calloc(sys->nfaces, sizeof *bl_aw);
    if (!bl_orig || !bl_mask || !bl_aw) {
        rc = st_fail(e, ST_ENOMEM, "out of memory");
        goto out;
    }
    t0 = now();
    if ((rc = encode_global(s, sys, buf[V_ORIG], level, -1, bl_orig, e)) ||
        (rc = encode_global(s, sys, buf[V_MASK], level, -1, bl_mask, e)))
        goto out;
    res->t_enc = (now() - t0) / 2;
    decode_global(sys, bl_orig, buf[V_ORIG], buf[V_BC1]);
    decode_global(sys, bl_mask, buf[V_MASK], buf[V_BC1M]);
    t0 = now();
    /* seam-aware: the masked texture encoded with texels outside the charts weighted down,
     * then the endpoint solve (st_bc1_compress_set does the same) */
    if ((rc = encode_global(s, sys, buf[V_MASK], level, 0.05f, bl_aw, e)))
        goto out;
    st_bc1_seam_stats st;
    double rms_goal = goal > 0 ? goal * st_seam_rms_rgba8(sys, buf[V_MASK]) : 0;
    rc = st_bc1_seam_solve(sys, buf[V_ORIG], buf[V_MASK], bl_aw, alpha * boost, 0, 3, rms_goal,
                           NULL, NULL, NULL, &st, e);
    if (rc)
        goto out;
    res->t_aware = now() - t0;
    res->e_start = st.e_before;
    res->e_end = st.e_after;
    res->alpha_used = st.alpha;
    decode_global(sys, bl_aw, buf[V_MASK], buf[V_AWARE]);
    for (int v = 0; v < NV; v++) {
        res->psnr[v] = st_seam_psnr_inside(sys, buf[V_ORIG], buf[v]);
        res->rms[v] = st_seam_rms_rgba8(sys, buf[v]);
        res->en[v] = energy(sys, buf[V_ORIG], buf[v], res->alpha_used, &res->ec[v]);
        res->psnr_enc[v] = st_seam_psnr_inside(sys, v == V_BC1 ? buf[V_ORIG] : buf[V_MASK], buf[v]);
    }
    {
        /* masking at the stage's own alpha: the 8-bit optimum no BC1 state can beat by much */
        uint8_t *m2 = malloc(bytes);
        if (!m2) {
            rc = st_fail(e, ST_ENOMEM, "out of memory");
            goto out;
        }
        memcpy(m2, buf[V_ORIG], bytes);
        rc = st_seam_mask_rgba8(sys, (float)res->alpha_used, 0, m2, NULL, e);
        if (!rc)
            res->en[NV] = energy(sys, buf[V_ORIG], m2, res->alpha_used, &res->ec[NV]);
        free(m2);
        if (rc)
            goto out;
    }
    res->ok = 1;
    /* close-up of the worst point of plain BC1 (masked) */
    if (sys->npts && outdir) {
        /* the point at the 90th percentile of plain BC1 (masked)'s residual among the points
         * where it is visible at all (> 1 step of 255: on a flat background most points
         * have none, and the picture would show nothing): a bad but typical spot (the very
         * worst is usually a colour edge the artist put on the seam) */
        double *res = malloc(sys->npts * sizeof *res);
        size_t *idx = malloc(sys->npts * sizeof *idx);
        size_t worst = 0;
        if (res && idx) {
            size_t visible = 0;
            for (size_t k = 0; k < sys->npts; k++) {
                res[k] = point_resid(sys, k, buf[V_BC1M]);
                visible += res[k] > 1.0;
            }
            if (visible == 0)
                visible = sys->npts;
            double lo = 0, hi = 1e9; /* bisection on the value: no sort needed */
            for (int it = 0; it < 60; it++) {
                double mid = 0.5 * (lo + hi);
                size_t above = 0;
                for (size_t k = 0; k < sys->npts; k++)
                    above += res[k] > mid;
                if (above > visible / 10)
                    lo = mid;
                else
                    hi = mid;
            }
            double best = 1e30;
            for (size_t k = 0; k < sys->npts; k++)
                if (fabs(res[k] - hi) < best) {
                    best = fabs(res[k] - hi);
                    worst = k;
                }
        }
        free(res);
        free(idx);
        const int R = 16, M = 8, gap = 4;
        int tile = R * M;
        int W = NV * (tile + gap) - gap, H = tile;
        uint8_t *img = calloc((size_t)W * H, 3);
        if (img) {
            memset(img, 255, (size_t)W * H * 3);
            for (int v = 0; v < NV; v++)
                stitched(sys, buf[v], worst, R, M, img + (size_t)v * (tile + gap) * 3,
                         (size_t)W * 3);
            char path[1200];
            snprintf(path, sizeof path, "%s/%s_closeup.png", outdir, d->name);
            st_error we;
            if (st_image_write(path, (uint32_t)W, (uint32_t)H, 3, ST_DT_U8, img, &we))
                fprintf(stderr, "seamreport: %s: %s\n", path, we.msg);
            free(img);
        }
    }
out:
    for (int v = 0; v < NV; v++)
        free(buf[v]);
    if (sys) {
        free_blocks(bl_orig, sys->nfaces);
        free_blocks(bl_mask, sys->nfaces);
        free_blocks(bl_aw, sys->nfaces);
    } else {
        free(bl_orig);
        free(bl_mask);
        free(bl_aw);
    }
    st_seam_sys_free(sys);
    st_set_free(s);
    return rc;
}

static double wall(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static double cpu_process(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* --big: the milk truck texture upscaled 2x (bilinear) to 4096^2 with its mesh, through
 * st_bc1_compress_set with the defaults on 2 threads: wall and CPU seconds of the read +
 * upscale + compress, and of the compress alone; peak RSS; before that the same without the
 * seam-aware stage (seam mode MASK). */
static int run_big(const char *data, int level, float boost, float goal)
{
    char p1[1024], p2[1024];
    st_error e = {0};
    double w0 = wall(), c0 = cpu_process();
    path_join(p1, sizeof p1, data, "meshes/cesiummilktruck/CesiumMilkTruck.obj");
    path_join(p2, sizeof p2, data, "meshes/cesiummilktruck/CesiumMilkTruck.png");
    st_mesh *m = NULL;
    st_image img;
    if (st_obj_read_file(p1, NULL, &m, &e) || st_image_read(p2, NULL, &img, &e)) {
        fprintf(stderr, "seamreport --big: %s\n", e.msg);
        st_mesh_free(m);
        return 1;
    }
    if (img.dtype != ST_DT_U8) {
        fprintf(stderr, "seamreport --big: the truck texture is not 8-bit\n");
        st_image_free(&img);
        st_mesh_free(m);
        return 1;
    }
    uint32_t W = img.w * 2, H = img.h * 2, n = img.nchan;
    uint8_t *up = malloc((size_t)W * H * n);
    if (!up) {
        st_image_free(&img);
        st_mesh_free(m);
        return 1;
    }
    const uint8_t *src = img.data;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            double sx = (x + 0.5) / 2 - 0.5, sy = (y + 0.5) / 2 - 0.5;
            int x0 = (int)floor(sx), y0 = (int)floor(sy);
            double ax = sx - x0, ay = sy - y0;
            int x1 = x0 + 1 >= (int)img.w ? (int)img.w - 1 : x0 + 1;
            int y1 = y0 + 1 >= (int)img.h ? (int)img.h - 1 : y0 + 1;
            x0 = x0 < 0 ? 0 : x0;
            y0 = y0 < 0 ? 0 : y0;
            for (uint32_t c = 0; c < n; c++) {
                double v = (1 - ay) * ((1 - ax) * src[((size_t)y0 * img.w + x0) * n + c] +
                                       ax * src[((size_t)y0 * img.w + x1) * n + c]) +
                           ay * ((1 - ax) * src[((size_t)y1 * img.w + x0) * n + c] +
                                 ax * src[((size_t)y1 * img.w + x1) * n + c]);
                up[((size_t)y * W + x) * n + c] = (uint8_t)(v + 0.5);
            }
        }
    free(img.data);
    img.data = up;
    img.w = W;
    img.h = H;
    st_set *s = NULL, *out = NULL;
    int rc = st_atlas_from_image(&img, m, 0, &s, &e);
    st_image_free(&img);
    if (rc) {
        fprintf(stderr, "seamreport --big: %s\n", e.msg);
        return 1;
    }
    st_atlas *at = st_set_ext_get(s, ST_EXT_ATLAS);
    snprintf(at->texture_name, sizeof at->texture_name, "%s", "CesiumMilkTruck.png");
    st_bc1_opts o;
    st_bc1_opts_default(&o);
    o.level = level;
    o.seam_boost = boost;
    o.seam_rms_goal = goal;
    o.threads = 2;
    /* first without the seam-aware stage (masking + plain BC1), to show what the stage costs */
    o.seam_mode = ST_BC1_SEAM_MASK;
    double w1 = wall(), c1 = cpu_process();
    rc = st_bc1_compress_set(s, &o, NULL, NULL, NULL, &out, &e);
    double wm = wall() - w1, cm = cpu_process() - c1;
    st_set_free(out);
    out = NULL;
    if (!rc)
        printf("4096^2 atlas, masking + plain BC1 only: %.2f s wall / %.2f CPU-s\n", wm, cm);
    o.seam_mode = ST_BC1_SEAM_AWARE;
    w1 = wall();
    c1 = cpu_process();
    if (!rc)
        rc = st_bc1_compress_set(s, &o, NULL, NULL, NULL, &out, &e);
    double w2 = wall(), c2 = cpu_process();
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    if (rc)
        fprintf(stderr, "seamreport --big: %s\n", e.msg);
    else
        printf("4096^2 atlas (milk truck upscaled 2x, its mesh), st_bc1_compress_set, 2 threads: "
               "compress %.2f s wall / %.2f CPU-s; with reading and upscaling %.2f s wall / %.2f "
               "CPU-s; peak RSS %ld MB\n",
               w2 - w1, c2 - c1, w2 - w0 - wm, c2 - c0 - cm, ru.ru_maxrss / 1024);
    st_set_free(out);
    st_set_free(s);
    return rc ? 1 : 0;
}

int main(int argc, char **argv)
{
    const char *data = getenv("SEAMTEX_DATA");
    if (!data)
        data = "../shared/data";
    const char *outdir = "build/report", *only = NULL, *json = NULL;
    int level = ST_BC1_HQ;
    float step = 0.5f, alpha = 2.0f, boost = 1.25f, goal = 1.1f;
    int big = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--data") && i + 1 < argc)
            data = argv[++i];
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            outdir = argv[++i];
        else if (!strcmp(argv[i], "--level") && i + 1 < argc)
        {
            i++;
            level = !strcmp(argv[i], "fast") ? ST_BC1_FAST : !strcmp(argv[i], "best") ? ST_BC1_BEST
                                                                                    : ST_BC1_HQ;
        }
        else if (!strcmp(argv[i], "--step") && i + 1 < argc)
            step = strtof(argv[++i], NULL);
        else if (!strcmp(argv[i], "--alpha") && i + 1 < argc)
            alpha = strtof(argv[++i], NULL);
        else if (!strcmp(argv[i], "--boost") && i + 1 < argc)
            boost = strtof(argv[++i], NULL);
        else if (!strcmp(argv[i], "--only") && i + 1 < argc)
            only = argv[++i];
        else if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--goal") && i + 1 < argc)
            goal = strtof(argv[++i], NULL);
        else if (!strcmp(argv[i], "--big"))
            big = 1;
        else {
            fprintf(stderr, "usage: %s [--data DIR] [--out DIR] [--level fast|hq|best] [--step S] "
                            "[--alpha A] [--boost B] [--goal G] [--only NAME] [--json PATH] [--big]\n", argv[0]);
            return 2;
        }
    }
    if (big)
        return run_big(data, level, boost, goal);
    mkdir(outdir, 0755);
    printf("seam report: BC1 level %s, seam samples every %.2f texel, alpha %.2f (masking) and "
           "%.2f (seam-aware BC1 stage; raised 1.2x up to 8 times while its seam RMS > %.2f x "
           "masked), exact decoder\n",
           level == ST_BC1_FAST ? "fast" : level == ST_BC1_BEST ? "best" : "hq", step, alpha,
           alpha * boost, goal);
    printf("PSNR = RGB PSNR inside charts vs the original (dB); RMS = seam RMS per channel (0..255)\n\n");
    FILE *jf = json ? fopen(json, "w") : NULL;
    if (jf)
        fprintf(jf, "{\"level\":\"%s\",\"step\":%g,\"alpha\":%g,\"boost\":%g,\"sets\":[",
                level == ST_BC1_FAST ? "fast" : level == ST_BC1_BEST ? "best" : "hq", step, alpha, boost);
    int first = 1, failures = 0;
    for (size_t i = 0; i < sizeof SETS / sizeof *SETS; i++) {
        const dataset *d = &SETS[i];
        if (only && !strstr(d->name, only))
            continue;
        result r;
        st_error e = {0};
        double t0 = now();
        int rc = run_set(d, data, outdir, level, step, alpha, boost, goal, &r, &e);
        if (rc) {
            printf("%-16s  skipped: %s (%s)\n\n", d->name, e.msg, st_strerror(rc));
            failures++;
            continue;
        }
        printf("%-16s %u face%s %ux%u%s, %u seams, %zu points; CPU s: mask %.2f, encode %.2f, "
               "seam-aware %.2f (total %.1f)\n",
               d->name, r.nfaces, r.nfaces > 1 ? "s" : "", r.w, r.h, r.nfaces > 1 ? " (face 0)" : "",
               r.nseams, r.npts, r.t_mask, r.t_enc, r.t_aware, now() - t0);
        printf("  %-20s %10s %10s %14s %12s %12s\n", "variant", "PSNR", "seam RMS", "PSNR vs input",
               "Ec", "a Es (stage)");
        for (int v = 0; v < NV; v++)
            printf("  %-20s %10.2f %10.2f %14.2f %12.5g %12.5g\n", VNAME[v], r.psnr[v], r.rms[v],
                   r.psnr_enc[v], r.ec[v], r.en[v] - r.ec[v]);
        printf("  %-20s %10s %10s %14s %12.5g %12.5g\n", "(masked at stage a)", "", "", "", r.ec[NV],
               r.en[NV] - r.ec[NV]);
        double ratio_m = r.rms[V_MASK] > 0 ? r.rms[V_AWARE] / r.rms[V_MASK] : 0;
        double ratio_b = r.rms[V_AWARE] > 0 ? r.rms[V_BC1M] / r.rms[V_AWARE] : 0;
        printf("  seam-aware/masked RMS %.2fx (target <= 1.2), plain BC1 (masked)/seam-aware RMS "
               "%.2fx (target >= 2), PSNR seam-aware - plain BC1 (masked) %+.2f dB, - plain BC1 "
               "(orig) %+.2f dB (target >= -0.2)\n",
               ratio_m, ratio_b, r.psnr[V_AWARE] - r.psnr[V_BC1M], r.psnr[V_AWARE] - r.psnr[V_BC1]);
        printf("  seam-aware stage: alpha %.3g; E (Ec + alpha Es over its blocks) start %.6g, result "
               "%.6g (%.1f%% lower)\n\n", r.alpha_used, r.e_start, r.e_end,
               r.e_start > 0 ? 100.0 * (1 - r.e_end / r.e_start) : 0.0);
        if (jf) {
            fprintf(jf, "%s{\"name\":\"%s\",\"seams\":%u,\"points\":%zu,\"stage_alpha\":%.4g,"
                        "\"variants\":[", first ? "" : ",", d->name, r.nseams, r.npts, r.alpha_used);
            for (int v = 0; v < NV; v++)
                fprintf(jf, "%s{\"variant\":\"%s\",\"psnr\":%.3f,\"seam_rms\":%.3f,"
                            "\"psnr_vs_input\":%.3f}", v ? "," : "", VNAME[v], r.psnr[v], r.rms[v],
                        r.psnr_enc[v]);
            fprintf(jf, "]}");
            first = 0;
        }
        fflush(stdout);
    }
    if (jf) {
        fprintf(jf, "]}\n");
        fclose(jf);
    }
    return failures ? 1 : 0;
}
