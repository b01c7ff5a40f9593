/* render/study.c - seamtex-render --toth: Toth 2013's section 4 reproduced with seamtexd.
 *
 * For each mesh and each frame of the orbit: the reference (Traverse at ref_ss x ref_ss the
 * resolution, Mitchell-Netravali downsampled, sampled in-process: it is a picture, not a
 * timing), then Traverse and Discard at 1, 2, 4, 8 samples per pixel sampled through the
 * daemon (the order of the two modes alternates frame by frame: A B, B A), and the same
 * queries sampled in-process for the sampling time alone. Writes:
 *   fig5_<mesh>.csv, fig5_all.csv  fraction of pixels whose linear-RGB 2-norm deviation is at
 *                                  least x: Traverse vs Discard, Traverse vs reference,
 *                                  Discard vs reference, per MSAA rate (Figure 5)
 *   table1_frames.csv              every frame's times, queries and bytes per mode and rate
 *   table1.csv, table1.md          medians per mesh, mode and rate, and Traverse / Discard
 *   closeup_*.png                  a seam (the pixel where Clamp and Traverse differ most)
 *                                  for Clamp, Discard, Traverse at 1x and 4x
 *   bc1_*.png, bc1.txt             the same seam magnified on BC1 sets made by COMPRESS,
 *                                  plainly and with seam masking (the poster's Figure 1)
 * Plots are drawn from the CSVs by tools/toth-study.sh (gnuplot).
 *
 * Owns: the study's loop, histograms, tables, close-ups. Does not own: rendering.
 */
#include "app.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define NBINS 1024             /* deviation histogram: bins of 1/512, the last one open */
#define BIN_W (1.0 / 512)
#define NRATES 4
static const unsigned RATES[NRATES] = { 1, 2, 4, 8 };
enum { M_DISCARD = 0, M_TRAVERSE = 1, M_CLAMP = 2 };
static const char *MODE_NAMES[3] = { "discard", "traverse", "clamp" };
enum { H_TD, H_TREF, H_DREF, NH };
static const char *H_NAMES[NH] = { "traverse_vs_discard", "traverse_vs_ref", "discard_vs_ref" };
enum { V_RASTER, V_NET, V_FRAME, V_INPROC, V_QUERIES, V_BYTES, NV };

typedef struct hist {
    uint64_t n[NBINS];
    uint64_t total;
} hist;

typedef struct mesh_res {
    char   name[128];
    hist   h[NH][NRATES];
    double *v;                 /* frames x 2 modes x NRATES x NV */
} mesh_res;

static double *vslot(mesh_res *r, unsigned f, unsigned mode, unsigned ri)
{
    return r->v + (((size_t)f * 2 + mode) * NRATES + ri) * NV;
}

static void hist_add(hist *h, double d)
{
    long b = isnan(d) ? NBINS - 1 : (long)(d / BIN_W);
    if (b >= NBINS)
        b = NBINS - 1;
    h->n[b]++;
    h->total++;
}

static void hist_merge(hist *a, const hist *b)
{
    for (int i = 0; i < NBINS; i++)
        a->n[i] += b->n[i];
    a->total += b->total;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median_of(const mesh_res *r, unsigned frames, unsigned mode, unsigned ri,
                        unsigned v, double *tmp)
{
    for (unsigned f = 0; f < frames; f++)
        tmp[f] = vslot((mesh_res *)r, f, mode, ri)[v];
    qsort(tmp, frames, sizeof *tmp, cmp_double);
    return frames % 2 ? tmp[frames / 2] : 0.5 * (tmp[frames / 2 - 1] + tmp[frames / 2]);
}

static int write_fig5(const char *dir, const char *name, hist h[NH][NRATES], char *msg,
                      size_t ml)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/fig5_%s.csv", dir, name);
    FILE *f = fopen(path, "w");
    if (!f) {
        snprintf(msg, ml, "%.900s: %s", path, strerror(errno));
        return -1;
    }
    fprintf(f, "x");
    for (int k = 0; k < NH; k++)
        for (int r = 0; r < NRATES; r++)
            fprintf(f, ",%s_%ux", H_NAMES[k], RATES[r]);
    fprintf(f, "\n");
    uint64_t above[NH][NRATES];
    for (int k = 0; k < NH; k++)
        for (int r = 0; r < NRATES; r++)
            above[k][r] = h[k][r].total;
    for (int i = 0; i < NBINS; i++) {
        fprintf(f, "%.6f", i * BIN_W);
        for (int k = 0; k < NH; k++)
            for (int r = 0; r < NRATES; r++) {
                fprintf(f, ",%.8g", h[k][r].total ? (double)above[k][r] / h[k][r].total : 0.0);
                above[k][r] -= h[k][r].n[i];
            }
        fprintf(f, "\n");
    }
    if (fclose(f) != 0) {
        snprintf(msg, ml, "%.900s: %s", path, strerror(errno));
        return -1;
    }
    return 0;
}

typedef struct study {
    const app_cfg *c;
    stc_conn *conn;
    rf_opts o;
    size_t npix;
} study;

/* Renders a frame of m at o's size/rate/mode through s; rgb must hold the frame. */
static int shot(study *S, const rm_mesh *m, const rc_camera *cam, unsigned w, unsigned h,
                unsigned msaa, unsigned mode, rs_sampler *s, rr_target *t, float *rgb,
                rf_times *tm, rs_stats *st, char *msg, size_t ml)
{
    rf_opts o = S->o;
    o.width = w;
    o.height = h;
    o.msaa = msaa;
    o.mode = mode;
    rs_stats ign = { 0 }, *sp = st ? st : &ign;
    uint64_t r0 = sp->refused;
    int rc = rf_render(m, cam, &o, s, t, rgb, tm, sp, msg, ml);
    if (rc == 0 && sp->refused > r0)
        fprintf(stderr, "seamtex-render --toth: %ux%u %ux mode %u: %llu queries refused by the "
                "sampler, drawn magenta\n", w, h, msaa, mode,
                (unsigned long long)(sp->refused - r0));
    return rc;
}

/* The pixel where a and b differ most among pixels whose (2r+1)^2 neighbourhood is covered
 * (owner of a 1x target), so that a silhouette is not taken for a seam. */
static long seam_pixel(const float *a, const float *b, const rr_target *t, int r)
{
    long best = -1;
    double bd = -1;
    for (int y = r; y < (int)t->height - r; y++)
        for (int x = r; x < (int)t->width - r; x++) {
            int ok = 1;
            for (int dy = -r; dy <= r && ok; dy++)
                for (int dx = -r; dx <= r && ok; dx++)
                    ok = t->owner[(size_t)(y + dy) * t->width + (size_t)(x + dx)] != UINT32_MAX;
            if (!ok)
                continue;
            double d = ri_pixel_dist(a, b, (size_t)y * t->width + (size_t)x);
            if (d > bd) {
                bd = d;
                best = (long)y * t->width + x;
            }
        }
    return best;
}

/* Mean colour step between 4-neighbour pixels whose first samples lie on different faces of m
 * (both covered): how visible the seams are. */
static double seam_step(const rr_target *t, const rm_mesh *m, const float *rgb)
{
    double sum = 0;
    size_t n = 0;
    for (unsigned y = 0; y + 1 < t->height; y++)
        for (unsigned x = 0; x + 1 < t->width; x++) {
            size_t p = (size_t)y * t->width + x, nb[2] = { p + 1, p + t->width };
            uint32_t a = t->owner[p * t->nsamp];
            if (a == UINT32_MAX)
                continue;
            for (int k = 0; k < 2; k++) {
                uint32_t b = t->owner[nb[k] * t->nsamp];
                if (b != UINT32_MAX && m->face[a] != m->face[b]) {
                    double d = 0;
                    for (int c = 0; c < 3; c++) {
                        double e = (double)rgb[3 * p + c] - rgb[3 * nb[k] + c];
                        d += e * e;
                    }
                    sum += sqrt(d);
                    n++;
                }
            }
        }
    return n ? sum / n : 0;
}

/* Crops cw x cw around (cx, cy) of a w x h image, zoomed, into the montage cell (col, row). */
static void cell(float *canvas, unsigned cw_canvas, unsigned ch_canvas, const float *img,
                 unsigned w, unsigned h, long cx, long cy, unsigned cw, unsigned zoom,
                 unsigned col, unsigned row, float *tile)
{
    ri_crop_zoom(img, w, h, (int)(cx - cw / 2), (int)(cy - cw / 2), cw, cw, zoom, tile);
    unsigned gap = 6, side = cw * zoom;
    ri_paste(canvas, cw_canvas, ch_canvas, tile, side, side, gap + col * (side + gap),
             gap + row * (side + gap));
}

static float *canvas_new(unsigned cols, unsigned rows, unsigned side, unsigned *w, unsigned *h)
{
    unsigned gap = 6;
    *w = gap + cols * (side + gap);
    *h = gap + rows * (side + gap);
    float *c = malloc((size_t)*w * *h * 3 * sizeof *c);
    if (c)
        for (size_t i = 0; i < (size_t)*w * *h * 3; i++)
            c[i] = 1.0f;
    return c;
}

static int closeups(study *S, const rm_mesh *m, rs_sampler *net, const char *tex,
                    const char *set, char *msg, size_t ml)
{
    const app_cfg *c = S->c;
    unsigned w = 2 * c->width, h = 2 * c->height, cw = c->closeup_size;
    unsigned zoom = (320 + cw - 1) / cw, side = cw * zoom;
    rc_camera cam;
    rc_orbit_camera(&c->orbit, m, c->frame, w, h, &cam);
    size_t np = (size_t)w * h * 3;
    float *img[3][2] = { { 0 } };
    float *tile = malloc((size_t)side * side * 3 * sizeof *tile);
    rr_target t1 = { 0 }, t4 = { 0 };
    int rc = -1;
    FILE *rep = NULL;
    float *cv = NULL;
    unsigned cvw, cvh;
    if (!tile)
        goto oom;
    for (int md = 0; md < 3; md++)
        for (int k = 0; k < 2; k++)
            if (!(img[md][k] = malloc(np * sizeof(float))))
                goto oom;
    for (int md = 0; md < 3; md++) {
        if (shot(S, m, &cam, w, h, 1, (unsigned)md, net, &t1, img[md][0], NULL, NULL, msg, ml) ||
            shot(S, m, &cam, w, h, 4, (unsigned)md, net, &t4, img[md][1], NULL, NULL, msg, ml))
            goto out;
    }
    long p = seam_pixel(img[M_CLAMP][0], img[M_TRAVERSE][0], &t1, 3);
    if (p < 0) {
        snprintf(msg, ml, "close-ups: no covered pixel in frame %u", c->frame);
        goto out;
    }
    long cx = p % w, cy = p / w;
    if (!(cv = canvas_new(3, 2, side, &cvw, &cvh)))
        goto oom;
    char path[1024];
    static const int ORDER[3] = { M_CLAMP, M_DISCARD, M_TRAVERSE };
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < 3; i++) {
            int md = ORDER[i];
            cell(cv, cvw, cvh, img[md][k], w, h, cx, cy, cw, zoom, (unsigned)i, (unsigned)k, tile);
            snprintf(path, sizeof path, "%s/closeup_%s_%ux.png", c->toth, MODE_NAMES[md],
                     k ? 4u : 1u);
            if (ri_write_png(path, tile, side, side, msg, ml) != 0)
                goto out;
        }
    snprintf(path, sizeof path, "%s/closeup_seam.png", c->toth);
    if (ri_write_png(path, cv, cvw, cvh, msg, ml) != 0)
        goto out;
    snprintf(path, sizeof path, "%s/bc1.txt", c->toth);
    rep = fopen(path, "w");
    if (!rep) {
        snprintf(msg, ml, "%.900s: %s", path, strerror(errno));
        goto out;
    }
    fprintf(rep, "close-ups: frame %u at %ux%u, seam pixel (%ld, %ld) where Clamp and Traverse "
            "differ most at 1x; crops of %u pixels magnified %ux (closeup_seam.png: columns "
            "Clamp, Discard, Traverse; rows 1x, 4x)\n", c->frame, w, h, cx, cy, cw, zoom);
    (void)tex;
    /* BC1: the same seam magnified, at 2x the close-ups' resolution, Clamp 4x */
    if (S->conn) {
        char names[2][300];
        const unsigned flags[2] = { STC_COMPRESS_REPLACE,
                                    STC_COMPRESS_REPLACE | STC_COMPRESS_SEAM_AWARE };
        snprintf(names[0], sizeof names[0], "%s-bc1", set);
        snprintf(names[1], sizeof names[1], "%s-bc1seam", set);
        for (int k = 0; k < 2; k++) {
            uint64_t job;
            stc_job js;
            int e = stc_compress(S->conn, set, names[k], c->bc1_level, flags[k], &job);
            if (e == 0)
                e = stc_job_wait(S->conn, job, 600000, &js);
            if (e != 0) {
                snprintf(msg, ml, "COMPRESS %s -> %s: %s (%s)", set, names[k], stc_strerror(e),
                         e == STC_ETIMEDOUT ? "waited 600 s" : stc_errmsg(S->conn));
                goto out;
            }
            fprintf(rep, "COMPRESS level %u %s: %s\n", c->bc1_level,
                    k ? "seam-aware" : "plain", js.message);
        }
        unsigned W2 = 2 * w, H2 = 2 * h, z2 = zoom;
        rc_camera cam2;
        rc_orbit_camera(&c->orbit, m, c->frame, W2, H2, &cam2);
        size_t n2 = (size_t)W2 * H2 * 3;
        float *big = malloc(n2 * sizeof *big), *src = malloc(n2 * sizeof *src);
        float *cv2 = NULL;
        unsigned c2w, c2h;
        rr_target t = { 0 };
        if (!big || !src || !(cv2 = canvas_new(3, 2, side, &c2w, &c2h))) {
            free(big);
            free(src);
            goto oom;
        }
        const char *sets[3] = { set, names[0], names[1] };
        static const char *LABEL[3] = { "source", "plain", "seammask" };
        int bad = 0;
        for (int k = 0; k < 3 && !bad; k++) {
            rs_sampler *s = k ? rs_net_new(S->conn, sets[k], c->batch, c->inflight, msg, ml)
                              : net;
            /* Clamp: what a GPU without Traverse shows; seam masking is for it */
            if (!s || shot(S, m, &cam2, W2, H2, 4, M_CLAMP, s, &t, big, NULL, NULL, msg, ml)) {
                bad = 1;
            } else {
                double st = seam_step(&t, m, big);
                fprintf(rep, "%s: mean colour step between neighbouring pixels on different "
                        "faces %.5f\n", k ? sets[k] : "source", st);
                cell(cv2, c2w, c2h, big, W2, H2, 2 * cx, 2 * cy, cw, z2, (unsigned)k, 0, tile);
                snprintf(path, sizeof path, "%s/bc1_%s.png", c->toth, LABEL[k]);
                bad = ri_write_png(path, tile, side, side, msg, ml) != 0;
                if (k == 0) {
                    memcpy(src, big, n2 * sizeof *src);
                } else {
                    /* second row: the error against the source, 8x */
                    double sum = 0, mx = 0;
                    size_t np = 0;
                    for (size_t i = 0; i < n2 / 3; i++) {
                        double d = ri_pixel_dist(big, src, i);
                        if (t.owner[i * t.nsamp] != UINT32_MAX) {
                            sum += d;
                            np++;
                            mx = d > mx ? d : mx;
                        }
                        for (int ch = 0; ch < 3; ch++)
                            big[3 * i + ch] = 8 * fabsf(big[3 * i + ch] - src[3 * i + ch]);
                    }
                    cell(cv2, c2w, c2h, big, W2, H2, 2 * cx, 2 * cy, cw, z2, (unsigned)k, 1,
                         tile);
                    fprintf(rep, "BC1 %s vs source over the frame's %zu covered pixels: mean "
                            "deviation %.5f, max %.5f\n", LABEL[k], np, np ? sum / np : 0, mx);
                }
            }
            if (s && s != net)
                rs_free(s);
        }
        if (!bad) {
            snprintf(path, sizeof path, "%s/bc1_seam.png", c->toth);
            bad = ri_write_png(path, cv2, c2w, c2h, msg, ml) != 0;
            fprintf(rep, "bc1_seam.png: the seam at (%ld, %ld) of a %ux%u frame, "
                    "Clamp 4x, magnified %ux: source, BC1 plain, BC1 with seam masking; "
                    "second row: "
                    "their difference from the source, 8x\n", 2 * cx, 2 * cy,
                    W2, H2, z2);
        }
        rr_target_free(&t);
        free(big);
        free(src);
        free(cv2);
        if (bad)
            goto out;
    }
    rc = 0;
    goto out;
oom:
    snprintf(msg, ml, "close-ups: out of memory");
out:
    if (rep && fclose(rep) != 0 && rc == 0) {
        snprintf(msg, ml, "bc1.txt: %s", strerror(errno));
        rc = -1;
    }
    for (int md = 0; md < 3; md++)
        for (int k = 0; k < 2; k++)
            free(img[md][k]);
    free(tile);
    free(cv);
    rr_target_free(&t1);
    rr_target_free(&t4);
    return rc;
}

static int study_mesh(study *S, unsigned mi, mesh_res *R, FILE *frames_csv, char *msg,
                      size_t ml)
{
    const app_cfg *c = S->c;
    const char *mesh = c->meshes[mi];
    char tex[1024], set[256];
    int kind, rc = -1;
    const char *image;
    if (app_texture_for(c, mesh, tex, sizeof tex, &kind, &image, msg, ml) != 0)
        return -1;
    app_set_name(mesh, "", R->name, sizeof R->name);
    app_set_name(tex, "toth-", set, sizeof set);
    rm_mesh *m = rm_load_obj(mesh, kind, msg, ml);
    rs_sampler *net = NULL, *inp = NULL;
    float *img[2] = { NULL, NULL }, *ref = NULL, *tmp = NULL;
    rr_target t[NRATES] = { { 0 } };
    if (!m)
        return -1;
    if (!(inp = rs_inproc_new(tex, image, msg, ml)))
        goto out;
    if (c->inproc) {
        net = inp;
    } else if (app_connect(c, &S->conn, msg, ml) != 0 ||
               app_upload(c, S->conn, tex, image, set, msg, ml) != 0 ||
               !(net = rs_net_new(S->conn, set, c->batch, c->inflight, msg, ml))) {
        goto out;
    }
    S->npix = (size_t)c->width * c->height;
    for (int k = 0; k < 2; k++)
        img[k] = malloc(S->npix * 3 * sizeof(float));
    ref = malloc(S->npix * 3 * sizeof(float));
    R->v = calloc((size_t)c->orbit.frames * 2 * NRATES * NV, sizeof *R->v);
    if (!img[0] || !img[1] || !ref || !R->v) {
        snprintf(msg, ml, "out of memory");
        goto out;
    }
    for (unsigned f = 0; f < c->orbit.frames; f++) {
        rc_camera cam;
        rc_orbit_camera(&c->orbit, m, f, c->width, c->height, &cam);
        rf_opts ro = S->o;
        ro.mode = M_TRAVERSE;
        rs_stats ign = { 0 };
        if (rf_reference(m, &cam, &ro, c->ref_ss, inp, ref, &ign, msg, ml) != 0)
            goto out;
        if (f == c->frame) {
            char path[1024];
            snprintf(path, sizeof path, "%s/%s_reference_f%03u.png", c->toth, R->name, f);
            if (ri_write_png(path, ref, c->width, c->height, msg, ml) != 0)
                goto out;
        }
        for (unsigned ri = 0; ri < NRATES; ri++) {
            for (unsigned k = 0; k < 2; k++) {
                /* A B on even frames, B A on odd ones */
                unsigned mode = (f % 2 == 0) == (k == 0) ? M_TRAVERSE : M_DISCARD;
                rf_times tm;
                rs_stats st = { 0 };
                if (shot(S, m, &cam, c->width, c->height, RATES[ri], mode, net, &t[ri],
                         img[mode], &tm, &st, msg, ml) != 0)
                    goto out;
                /* the same queries in-process: the sampling work alone */
                size_t nq = t[ri].nfrag;
                free(tmp);
                tmp = malloc((nq ? nq : 1) * 4 * sizeof *tmp);
                if (!tmp) {
                    snprintf(msg, ml, "out of memory");
                    goto out;
                }
                stc_sample_opts so = { .mode = mode, .filter = S->o.filter, .zero_rule = 1,
                                       .max_aniso = S->o.max_aniso };
                double t0 = rt_now_ms();
                if (nq && inp->sample(inp, &so, t[ri].queries, nq, tmp, NULL, &ign, msg, ml))
                    goto out;
                double *v = vslot(R, f, mode, ri);
                v[V_INPROC] = rt_now_ms() - t0;
                v[V_RASTER] = tm.raster_ms;
                v[V_NET] = tm.sample_ms;
                v[V_FRAME] = tm.total_ms;
                v[V_QUERIES] = (double)st.queries;
                v[V_BYTES] = (double)(st.bytes_out + st.bytes_in);
                fprintf(frames_csv, "%s,%u,%s,%u,%.3f,%.3f,%.3f,%.3f,%llu,%llu,%llu\n", R->name,
                        f, MODE_NAMES[mode], RATES[ri], tm.raster_ms, v[V_INPROC], tm.sample_ms,
                        tm.total_ms, (unsigned long long)st.queries,
                        (unsigned long long)st.bytes_out, (unsigned long long)st.bytes_in);
                if (f == c->frame && (RATES[ri] == 1 || RATES[ri] == 4)) {
                    char path[1024];
                    snprintf(path, sizeof path, "%s/%s_%s_%ux_f%03u.png", c->toth, R->name,
                             MODE_NAMES[mode], RATES[ri], f);
                    if (ri_write_png(path, img[mode], c->width, c->height, msg, ml) != 0)
                        goto out;
                }
            }
            for (size_t p = 0; p < S->npix; p++) {
                hist_add(&R->h[H_TD][ri], ri_pixel_dist(img[M_TRAVERSE], img[M_DISCARD], p));
                hist_add(&R->h[H_TREF][ri], ri_pixel_dist(img[M_TRAVERSE], ref, p));
                hist_add(&R->h[H_DREF][ri], ri_pixel_dist(img[M_DISCARD], ref, p));
            }
        }
        if (!c->quiet && (f % 10 == 0 || f + 1 == c->orbit.frames)) {
            printf("toth: %s frame %u/%u done\n", R->name, f + 1, c->orbit.frames);
            fflush(stdout);
        }
    }
    if (write_fig5(c->toth, R->name, R->h, msg, ml) != 0)
        goto out;
    if (mi == 0 && closeups(S, m, net, tex, set, msg, ml) != 0)
        goto out;
    rc = 0;
out:
    for (unsigned ri = 0; ri < NRATES; ri++)
        rr_target_free(&t[ri]);
    free(img[0]);
    free(img[1]);
    free(ref);
    free(tmp);
    if (net != inp)
        rs_free(net);
    rs_free(inp);
    rm_free(m);
    return rc;
}

static int write_table1(const app_cfg *c, mesh_res *R, unsigned n, char *msg, size_t ml)
{
    char p1[1024], p2[1024];
    snprintf(p1, sizeof p1, "%s/table1.csv", c->toth);
    snprintf(p2, sizeof p2, "%s/table1.md", c->toth);
    FILE *f = fopen(p1, "w"), *md = fopen(p2, "w");
    double *tmp = malloc(c->orbit.frames * sizeof *tmp);
    if (!f || !md || !tmp) {
        snprintf(msg, ml, "%.900s: %s", !f ? p1 : p2, strerror(errno));
        if (f)
            fclose(f);
        if (md)
            fclose(md);
        free(tmp);
        return -1;
    }
    fprintf(f, "mesh,mode,msaa,raster_ms,sampling_ms,sampling_loopback_ms,frame_ms,queries,"
               "bytes\n");
    fprintf(md, "Medians over %u frames of %ux%u (%s sampling); sampling = the frame's queries "
                "sampled in-process (the daemon's work), frame = end to end with sampling over "
                "%s.\n\n", c->orbit.frames, c->width, c->height,
            c->inproc ? "in-process" : "daemon", c->inproc ? "in-process calls" : "loopback");
    fprintf(md, "| mesh | quantity | mode | 1x | 2x | 4x | 8x |\n|---|---|---|---|---|---|---|\n");
    static const char *VN[NV] = { "raster ms", "sampling over loopback ms", "frame ms",
                                  "sampling ms", "queries", "bytes" };
    static const unsigned ORDERV[] = { V_INPROC, V_FRAME, V_NET, V_RASTER, V_QUERIES, V_BYTES };
    for (unsigned i = 0; i < n; i++) {
        double med[2][NRATES][NV];
        for (unsigned mode = 0; mode < 2; mode++)
            for (unsigned ri = 0; ri < NRATES; ri++) {
                for (unsigned v = 0; v < NV; v++)
                    med[mode][ri][v] = median_of(&R[i], c->orbit.frames, mode, ri, v, tmp);
                fprintf(f, "%s,%s,%u,%.3f,%.3f,%.3f,%.3f,%.0f,%.0f\n", R[i].name,
                        MODE_NAMES[mode], RATES[ri], med[mode][ri][V_RASTER],
                        med[mode][ri][V_INPROC], med[mode][ri][V_NET], med[mode][ri][V_FRAME],
                        med[mode][ri][V_QUERIES], med[mode][ri][V_BYTES]);
            }
        for (unsigned ri = 0; ri < NRATES; ri++)
            fprintf(f, "%s,traverse/discard,%u,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n", R[i].name,
                    RATES[ri], med[1][ri][V_RASTER] / med[0][ri][V_RASTER],
                    med[1][ri][V_INPROC] / med[0][ri][V_INPROC],
                    med[1][ri][V_NET] / med[0][ri][V_NET],
                    med[1][ri][V_FRAME] / med[0][ri][V_FRAME],
                    med[1][ri][V_QUERIES] / med[0][ri][V_QUERIES],
                    med[1][ri][V_BYTES] / med[0][ri][V_BYTES]);
        for (unsigned k = 0; k < sizeof ORDERV / sizeof *ORDERV; k++) {
            unsigned v = ORDERV[k];
            for (unsigned mode = 2; mode-- > 0;) {
                fprintf(md, "| %s | %s | %s |", R[i].name, VN[v], mode ? "Traverse" : "Discard");
                for (unsigned ri = 0; ri < NRATES; ri++)
                    fprintf(md, v >= V_QUERIES ? " %.0f |" : " %.2f |", med[mode][ri][v]);
                fprintf(md, "\n");
            }
            if (v <= V_INPROC) {
                fprintf(md, "| %s | %s | T/D |", R[i].name, VN[v]);
                for (unsigned ri = 0; ri < NRATES; ri++)
                    fprintf(md, " %.3f |", med[1][ri][v] / med[0][ri][v]);
                fprintf(md, "\n");
            }
        }
    }
    free(tmp);
    int bad = fclose(f) != 0;
    bad |= fclose(md) != 0;
    if (bad) {
        snprintf(msg, ml, "writing table1: %s", strerror(errno));
        return -1;
    }
    return 0;
}

int study_run(const app_cfg *c)
{
    char msg[1024];
    study S = { .c = c, .o = { .width = c->width, .height = c->height, .filter = c->filter,
                               .max_aniso = c->max_aniso, .outfmt = c->outfmt,
                               .bg = { 0.05f, 0.05f, 0.06f } } };
    mesh_res *R = calloc(c->nmeshes, sizeof *R);
    hist(*all)[NRATES] = calloc(NH, sizeof *all);
    FILE *fc = NULL;
    int rc = -1;
    if (!R || !all) {
        snprintf(msg, sizeof msg, "out of memory");
        goto fail;
    }
    if (mkdir(c->toth, 0777) != 0 && errno != EEXIST) {
        snprintf(msg, sizeof msg, "%.900s: %s", c->toth, strerror(errno));
        goto fail;
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/table1_frames.csv", c->toth);
    if (!(fc = fopen(path, "w"))) {
        snprintf(msg, sizeof msg, "%.900s: %s", path, strerror(errno));
        goto fail;
    }
    fprintf(fc, "mesh,frame,mode,msaa,raster_ms,sampling_ms,sampling_loopback_ms,frame_ms,"
                "queries,bytes_out,bytes_in\n");
    double t0 = rt_now_ms();
    for (unsigned i = 0; i < c->nmeshes; i++) {
        if (study_mesh(&S, i, &R[i], fc, msg, sizeof msg) != 0)
            goto fail;
        for (int k = 0; k < NH; k++)
            for (int r = 0; r < NRATES; r++)
                hist_merge(&all[k][r], &R[i].h[k][r]);
    }
    if (fclose(fc) != 0) {
        fc = NULL;
        snprintf(msg, sizeof msg, "table1_frames.csv: %s", strerror(errno));
        goto fail;
    }
    fc = NULL;
    if (write_fig5(c->toth, "all", all, msg, sizeof msg) != 0 ||
        write_table1(c, R, c->nmeshes, msg, sizeof msg) != 0)
        goto fail;
    printf("toth: %u meshes x %u frames at %ux%u in %.1f s; results in %s/ (fig5_*.csv, "
           "table1.csv, table1.md, closeup_seam.png, bc1_seam.png)\n", c->nmeshes,
           c->orbit.frames, c->width, c->height, (rt_now_ms() - t0) / 1e3, c->toth);
    rc = 0;
    goto out;
fail:
    fprintf(stderr, "seamtex-render --toth: %s\n", msg);
out:
    if (fc)
        fclose(fc);
    if (R)
        for (unsigned i = 0; i < c->nmeshes; i++)
            free(R[i].v);
    free(R);
    free(all);
    stc_close(S.conn);
    return rc;
}
