/* render/main.c - seamtex-render: renders a textured mesh on the CPU, sampling its texture
 * through seamtexd (pipelined SAMPLE batches over libseamtex) or in-process (--inproc), in
 * Discard, Traverse or Clamp mode at 1, 2, 4 or 8 samples per pixel; writes PNG frames, an
 * animation strip or the supersampled reference; --toth runs the Toth 2013 study (study.c).
 *
 * Owns: the command line (every flag is listed in usage() and docs/render.md) and the frame
 * job. Does not own: rendering (render.h), the study.
 */
#include "app.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "unixaddr.h"

static const char *MODE_NAMES[3] = { "discard", "traverse", "clamp" };

static void usage(FILE *f)
{
    fprintf(f,
"usage: seamtex-render [options] MESH.obj            render frames of MESH\n"
"       seamtex-render --toth DIR [options] MESH.obj...  the Toth 2013 study (docs/render.md)\n"
"\n"
"Texture and sampling:\n"
"  --host H            daemon address (default 127.0.0.1), or unix:PATH (no --port)\n"
"  -p, --port P        daemon port (needed unless --inproc or a unix: host)\n"
"  --set NAME          the set to sample (default: render-<base name of the .ptx, or of\n"
"                      the mesh for an atlas mesh, its image going to render-<base>-tex>)\n"
"  --texture FILE      the texture: a .ptx (Ptex mesh) or an image (atlas mesh); default\n"
"                      MESH.ptx beside the mesh (an atlas mesh needs --texture IMAGE)\n"
"  --no-upload         the set is on the daemon already (otherwise uploaded, replacing)\n"
"  --inproc            sample in-process with the store's sampler instead of the daemon\n"
"  --batch N           queries per SAMPLE request (default 16384, at most max_batch)\n"
"  --inflight N        SAMPLE requests outstanding (default 8, at most 64)\n"
"  --outfmt F          f32 (default), unorm8, unorm16\n"
"  --shm auto|on|off   on a unix: host, queries and replies through a shared-memory\n"
"                      region (auto: when the daemon allows it, else the socket; on: it\n"
"                      must; default auto)\n"
"Rendering:\n"
"  --size WxH          image size (default 1280x720)\n"
"  --msaa N            samples per pixel: 1, 2, 4 (default), 8 (D3D standard patterns)\n"
"  --mode M            discard, traverse, clamp or all (default all)\n"
"  --filter F          point, bilinear, trilinear, aniso (default aniso)\n"
"  --max-aniso N       anisotropic probes 1..16 (default 16)\n"
"Camera orbit:\n"
"  --frames N          frames per turn (default 120)\n"
"  --frame I           the frame to render (default 0)\n"
"  --all-frames        every frame of the orbit\n"
"  --elev DEG          elevation (default 25)   --azim DEG  azimuth of frame 0 (default 30)\n"
"  --dist X            distance, 1: the bounding sphere fits the view (default 0.8)\n"
"  --fov DEG           vertical field of view (default 40)\n"
"Output:\n"
"  --out DIR           where PNGs go (default .)\n"
"  --strip K           also an animation strip of K frames spread over the orbit\n"
"  --reference SS      render the reference instead: SS x SS supersampled, Mitchell-Netravali\n"
"                      B = C = 1/3 downsampled (the study uses 8)\n"
"  --repeat N          render each frame N times and report median times (default 1)\n"
"  --breakdown         also time in-process sampling of the same queries (sampling vs network)\n"
"  --quiet             no per-frame lines\n"
"Study (--toth DIR): --frames (>= 1), --size (default 320x240), --ref-ss SS (default 8),\n"
"  --closeup N (crop of the seam close-ups, default 40), --bc1-level L (default 5);\n"
"  writes DIR/fig5_*.csv, DIR/table1*.csv, the close-ups and DIR/bc1.txt\n"
"  -h, --help          this text\n");
}

static int parse_uint(const char *s, unsigned lo, unsigned hi, unsigned *out)
{
    char *end;
    unsigned long v = strtoul(s, &end, 10);
    if (end == s || *end || v < lo || v > hi || s[0] == '-')
        return -1;
    *out = (unsigned)v;
    return 0;
}

static int parse_double(const char *s, double lo, double hi, double *out)
{
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end || !(v >= lo && v <= hi))
        return -1;
    *out = v;
    return 0;
}

/* The largest multisample target the job draws must fit the rasteriser's limits
 * (rr_target_init: 1..16384 per axis, at most 2^28 samples): a frame at --msaa, the reference
 * at --reference SS x SS the size (1 sample), and for --toth the frames at 8x, the reference at
 * --ref-ss, the close-ups at twice the size and the BC1 pictures at four times, both at 4x.
 * Refused here, with the flags named, before anything is loaded or uploaded. */
static int check_targets(const app_cfg *c)
{
    typedef struct tgt { unsigned scale, msaa; const char *what; } tgt;
    tgt t[4];
    int n = 0;
    if (c->toth) {
        t[n++] = (tgt){ 1, 8, "--toth draws frames at 8x" };
        t[n++] = (tgt){ c->ref_ss, 1, "--toth draws the reference at --ref-ss" };
        t[n++] = (tgt){ 2, 4, "--toth draws close-ups at twice --size, 4x" };
        t[n++] = (tgt){ 4, 4, "--toth draws BC1 pictures at four times --size, 4x" };
    } else if (c->reference) {
        t[n++] = (tgt){ c->reference, 1, "--reference draws at SS x SS the size" };
    } else {
        t[n++] = (tgt){ 1, c->msaa, "--msaa" };
    }
    for (int i = 0; i < n; i++) {
        uint64_t w = (uint64_t)c->width * t[i].scale, h = (uint64_t)c->height * t[i].scale;
        if (w > 16384 || h > 16384 || w * h * t[i].msaa > (1ull << 28)) {
            fprintf(stderr, "seamtex-render: bad value for --size: '%ux%u': %s, a %llux%llu "
                    "target at %ux: at most 16384 per axis and 2^28 samples\n", c->width,
                    c->height, t[i].what, (unsigned long long)w, (unsigned long long)h,
                    t[i].msaa);
            return -1;
        }
    }
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, unsigned n)
{
    qsort(v, n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

enum { OPT_HOST = 256, OPT_PORT, OPT_SET, OPT_TEXTURE, OPT_NOUPLOAD, OPT_INPROC, OPT_BATCH,
       OPT_INFLIGHT, OPT_OUTFMT, OPT_SIZE, OPT_MSAA, OPT_MODE, OPT_FILTER, OPT_ANISO, OPT_FRAMES,
       OPT_FRAME, OPT_ALL, OPT_ELEV, OPT_AZIM, OPT_DIST, OPT_FOV, OPT_OUT, OPT_STRIP, OPT_REF,
       OPT_REPEAT, OPT_BREAKDOWN, OPT_QUIET, OPT_TOTH, OPT_REFSS, OPT_CLOSEUP, OPT_BC1LEVEL, OPT_SHM };

static const struct option LONGOPTS[] = {
    { "host", 1, 0, OPT_HOST }, { "port", 1, 0, OPT_PORT }, { "set", 1, 0, OPT_SET },
    { "texture", 1, 0, OPT_TEXTURE }, { "no-upload", 0, 0, OPT_NOUPLOAD },
    { "inproc", 0, 0, OPT_INPROC }, { "batch", 1, 0, OPT_BATCH },
    { "inflight", 1, 0, OPT_INFLIGHT }, { "outfmt", 1, 0, OPT_OUTFMT },
    { "size", 1, 0, OPT_SIZE }, { "msaa", 1, 0, OPT_MSAA }, { "mode", 1, 0, OPT_MODE },
    { "filter", 1, 0, OPT_FILTER }, { "max-aniso", 1, 0, OPT_ANISO },
    { "frames", 1, 0, OPT_FRAMES }, { "frame", 1, 0, OPT_FRAME },
    { "all-frames", 0, 0, OPT_ALL }, { "elev", 1, 0, OPT_ELEV }, { "azim", 1, 0, OPT_AZIM },
    { "dist", 1, 0, OPT_DIST }, { "fov", 1, 0, OPT_FOV }, { "out", 1, 0, OPT_OUT },
    { "strip", 1, 0, OPT_STRIP }, { "reference", 1, 0, OPT_REF },
    { "repeat", 1, 0, OPT_REPEAT }, { "breakdown", 0, 0, OPT_BREAKDOWN },
    { "quiet", 0, 0, OPT_QUIET }, { "toth", 1, 0, OPT_TOTH }, { "ref-ss", 1, 0, OPT_REFSS },
    { "closeup", 1, 0, OPT_CLOSEUP }, { "bc1-level", 1, 0, OPT_BC1LEVEL },
    { "shm", 1, 0, OPT_SHM },
    { "help", 0, 0, 'h' }, { 0, 0, 0, 0 }
};

static int parse_args(int argc, char **argv, app_cfg *c)
{
    int size_given = 0;
    *c = (app_cfg){ .host = "127.0.0.1", .width = 1280, .height = 720, .msaa = 4, .mode = -1,
                    .filter = 3, .max_aniso = 16, .outfmt = STC_OUT_F32,
                    .orbit = { .frames = 120, .elev_deg = 25, .dist = 0.8, .fov_deg = 40,
                               .azim0_deg = 30 },
                    .repeat = 1, .out = ".", .ref_ss = 8, .closeup_size = 40, .bc1_level = 5,
                    .shm = RS_SHM_AUTO };
    int o;
    while ((o = getopt_long(argc, argv, "hp:", LONGOPTS, NULL)) != -1) {
        const char *a = optarg;
        if (o == 'p')
            o = OPT_PORT;
        int bad = 0;
        switch (o) {
        case OPT_HOST: c->host = a; break;
        case OPT_PORT: bad = parse_uint(a, 1, 65535, &c->port); break;
        case OPT_SET: c->set = a; break;
        case OPT_TEXTURE: c->texture = a; break;
        case OPT_NOUPLOAD: c->no_upload = 1; break;
        case OPT_INPROC: c->inproc = 1; break;
        case OPT_BATCH: bad = parse_uint(a, 1, 1u << 20, &c->batch); break;
        case OPT_INFLIGHT: bad = parse_uint(a, 1, 64, &c->inflight); break;
        case OPT_OUTFMT:
            c->outfmt = !strcmp(a, "f32") ? STC_OUT_F32 : !strcmp(a, "unorm8") ? STC_OUT_UNORM8
                      : !strcmp(a, "unorm16") ? STC_OUT_UNORM16 : 99;
            bad = c->outfmt == 99;
            break;
        case OPT_SIZE: {
            char *x = strchr(a, 'x');
            char wb[16];
            if (!x || (size_t)(x - a) >= sizeof wb) {
                bad = 1;
                break;
            }
            memcpy(wb, a, (size_t)(x - a));
            wb[x - a] = 0;
            bad = parse_uint(wb, 1, 16384, &c->width) || parse_uint(x + 1, 1, 16384, &c->height);
            size_given = 1;
            break;
        }
        case OPT_MSAA:
            bad = parse_uint(a, 1, 8, &c->msaa) || (c->msaa & (c->msaa - 1));
            break;
        case OPT_MODE:
            c->mode = !strcmp(a, "all") ? -1 : !strcmp(a, "discard") ? 0
                    : !strcmp(a, "traverse") ? 1 : !strcmp(a, "clamp") ? 2 : -2;
            bad = c->mode == -2;
            break;
        case OPT_FILTER:
            c->filter = !strcmp(a, "point") ? 0 : !strcmp(a, "bilinear") ? 1
                      : !strcmp(a, "trilinear") ? 2 : !strcmp(a, "aniso") ? 3 : 99;
            bad = c->filter == 99;
            break;
        case OPT_ANISO: bad = parse_uint(a, 1, 16, &c->max_aniso); break;
        case OPT_FRAMES: bad = parse_uint(a, 1, 100000, &c->orbit.frames); break;
        case OPT_FRAME: bad = parse_uint(a, 0, 99999, &c->frame); break;
        case OPT_ALL: c->all_frames = 1; break;
        case OPT_ELEV: bad = parse_double(a, -89, 89, &c->orbit.elev_deg); break;
        case OPT_AZIM: bad = parse_double(a, -3600, 3600, &c->orbit.azim0_deg); break;
        case OPT_DIST: bad = parse_double(a, 0.05, 1000, &c->orbit.dist); break;
        case OPT_FOV: bad = parse_double(a, 1, 170, &c->orbit.fov_deg); break;
        case OPT_OUT: c->out = a; break;
        case OPT_STRIP: bad = parse_uint(a, 1, 64, &c->strip); break;
        case OPT_REF: bad = parse_uint(a, 1, 16, &c->reference); break;
        case OPT_REPEAT: bad = parse_uint(a, 1, 1000, &c->repeat); break;
        case OPT_BREAKDOWN: c->breakdown = 1; break;
        case OPT_QUIET: c->quiet = 1; break;
        case OPT_TOTH: c->toth = a; break;
        case OPT_REFSS: bad = parse_uint(a, 1, 16, &c->ref_ss); break;
        case OPT_CLOSEUP: bad = parse_uint(a, 4, 512, &c->closeup_size); break;
        case OPT_BC1LEVEL: bad = parse_uint(a, 0, 9, &c->bc1_level); break;
        case OPT_SHM:
            c->shm = !strcmp(a, "auto") ? RS_SHM_AUTO : !strcmp(a, "on") ? RS_SHM_ON
                   : !strcmp(a, "off") ? RS_SHM_OFF : -1;
            bad = c->shm < 0;
            break;
        case 'h': usage(stdout); exit(0);
        default: usage(stderr); return -1;
        }
        if (bad) {
            fprintf(stderr, "seamtex-render: bad value for --%s: '%s'\n",
                    LONGOPTS[o - OPT_HOST].name, a);
            return -1;
        }
    }
    if (c->toth && !size_given) {
        c->width = 320;
        c->height = 240;
    }
    if (check_targets(c) != 0)
        return -1;
    for (int i = optind; i < argc; i++) {
        if (c->nmeshes == APP_MAX_MESHES) {
            fprintf(stderr, "seamtex-render: at most %d meshes\n", APP_MAX_MESHES);
            return -1;
        }
        c->meshes[c->nmeshes++] = argv[i];
    }
    if (c->nmeshes == 0) {
        usage(stderr);
        return -1;
    }
    if (!c->toth && c->nmeshes > 1) {
        fprintf(stderr, "seamtex-render: one mesh at a time outside --toth\n");
        return -1;
    }
    if (!c->all_frames && c->frame >= c->orbit.frames) {
        fprintf(stderr, "seamtex-render: --frame %u is past the orbit's %u frames\n", c->frame,
                c->orbit.frames);
        return -1;
    }
    if (!c->inproc && !c->port && !stu_is_unix_addr(c->host)) {
        fprintf(stderr, "seamtex-render: give --port of a running seamtexd (or --host "
                "unix:PATH), or --inproc\n");
        return -1;
    }
    return 0;
}

typedef struct frame_job {
    const app_cfg *c;
    const rm_mesh *m;
    rs_sampler *s, *timing;   /* timing: in-process sampler for --breakdown, or NULL */
    const char *base;
    rr_target t;
} frame_job;

static int render_one(frame_job *j, unsigned frame, unsigned mode, float *rgb, char *msg,
                      size_t ml)
{
    const app_cfg *c = j->c;
    rc_camera cam;
    rc_orbit_camera(&c->orbit, j->m, frame, c->width, c->height, &cam);
    rf_opts o = { .width = c->width, .height = c->height, .msaa = c->msaa, .mode = mode,
                  .filter = c->filter, .max_aniso = c->max_aniso, .outfmt = c->outfmt,
                  .bg = { 0.05f, 0.05f, 0.06f } };
    char path[1024];
    if (c->reference) {
        rs_stats st = { 0 };
        double t0 = rt_now_ms();
        if (rf_reference(j->m, &cam, &o, c->reference, j->s, rgb, &st, msg, ml) != 0)
            return -1;
        snprintf(path, sizeof path, "%s/%s_ref%u_%s_f%03u.png", c->out, j->base, c->reference,
                 MODE_NAMES[mode], frame);
        if (ri_write_png(path, rgb, c->width, c->height, msg, ml) != 0)
            return -1;
        if (!c->quiet)
            printf("%s reference %ux%u x%u^2 %s frame %u: %.1f ms, %llu queries -> %s\n",
                   j->base, c->width, c->height, c->reference, MODE_NAMES[mode], frame,
                   rt_now_ms() - t0, (unsigned long long)st.queries, path);
        if (st.refused)
            fprintf(stderr, "seamtex-render: %s reference frame %u: %llu of %llu queries "
                    "refused by the sampler, drawn magenta\n", j->base, frame,
                    (unsigned long long)st.refused, (unsigned long long)st.queries);
        return 0;
    }
    double tr[1000], ts[1000], tt[1000], tin[1000], tsh[1000];
    size_t edge = 0;
    rs_stats st = { 0 };
    for (unsigned r = 0; r < c->repeat; r++) {
        rf_times tm;
        rs_stats one = { 0 };
        if (rf_render(j->m, &cam, &o, j->s, &j->t, rgb, &tm, &one, msg, ml) != 0)
            return -1;
        tr[r] = tm.raster_ms;
        ts[r] = tm.sample_ms;
        tt[r] = tm.total_ms;
        tsh[r] = tm.shade_ms;
        st = one;
        tin[r] = 0;
        if (j->timing) {
            size_t nq = j->t.nfrag ? j->t.nfrag : 1;
            float *tmp = malloc(nq * 4 * sizeof *tmp), *cov = malloc(nq * sizeof *cov);
            stc_sample_opts so = { .mode = mode, .filter = c->filter, .zero_rule = 1,
                                   .max_aniso = c->max_aniso };
            rs_stats ign = { 0 };
            double t0 = rt_now_ms();
            int rc = tmp && cov ? j->timing->sample(j->timing, &so, j->t.queries, j->t.nfrag,
                                                    tmp, cov, &ign, msg, ml) : -1;
            tin[r] = rt_now_ms() - t0;
            /* how many footprints reach outside their face (Discard's coverage below 1): the
             * queries for which Traverse does its extra work */
            edge = 0;
            for (size_t i = 0; rc == 0 && mode == 0 && i < j->t.nfrag; i++)
                edge += cov[i] < 1;
            free(tmp);
            free(cov);
            if (rc != 0) {
                if (!tmp || !cov)
                    snprintf(msg, ml, "out of memory");
                return -1;
            }
        }
    }
    snprintf(path, sizeof path, "%s/%s_%s_%ux_f%03u.png", c->out, j->base, MODE_NAMES[mode],
             c->msaa, frame);
    if (ri_write_png(path, rgb, c->width, c->height, msg, ml) != 0)
        return -1;
    if (!c->quiet) {
        double mt = median(tt, c->repeat), mr = median(tr, c->repeat), ms = median(ts, c->repeat);
        printf("%s %-8s %ux %ux%u frame %u: %.1f ms (raster %.1f, %s %.1f", j->base,
               MODE_NAMES[mode], c->msaa, c->width, c->height, frame, mt, mr,
               c->inproc ? "sampling" : st.shm_batches ? "sampling through shared memory"
               : stu_is_unix_addr(c->host) ? "sampling over the socket"
               : "sampling over loopback", ms);
        if (j->timing) {
            double mi = median(tin, c->repeat);
            printf(" = in-process sampling %.1f + network and protocol %.1f", mi, ms - mi);
        }
        printf(", resolve %.1f)%s", median(tsh, c->repeat), c->repeat > 1 ? " median" : "");
        if (j->timing && mode == 0)
            printf("; %zu footprints leave their face", edge);
        printf("; %zu fragments, %llu helper lanes, %llu queries, %llu bytes "
               "out, %llu in", j->t.nfrag,
               (unsigned long long)j->t.helper_lanes, (unsigned long long)st.queries,
               (unsigned long long)st.bytes_out, (unsigned long long)st.bytes_in);
        if (st.shm_batches)
            printf(" (%llu of %llu batches through shared memory)",
                   (unsigned long long)st.shm_batches, (unsigned long long)st.batches);
        if (j->t.clamped_derivs)
            printf("; %llu with derivatives scaled down to %.0f",
                   (unsigned long long)j->t.clamped_derivs, RR_MAX_DERIV);
        if (st.refused)
            printf("; %llu refused by the sampler, drawn magenta",
                   (unsigned long long)st.refused);
        printf(" -> %s\n", path);
    }
    if (st.refused)
        fprintf(stderr, "seamtex-render: %s %s frame %u: %llu of %llu queries refused by the "
                "sampler (status BAD_FOOTPRINT, NONFINITE or BAD_FACE: |u|, |v| or a derivative "
                "over 1e4, or a face the set lacks), drawn magenta\n", j->base,
                MODE_NAMES[mode], frame, (unsigned long long)st.refused,
                (unsigned long long)st.queries);
    return 0;
}

static int frame_main(const app_cfg *c)
{
    char msg[1024], tex[1024], set[256];
    const char *mesh = c->meshes[0];
    int kind, rc = 1;
    const char *image;
    if (app_texture_for(c, mesh, tex, sizeof tex, &kind, &image, msg, sizeof msg) != 0) {
        fprintf(stderr, "seamtex-render: %s\n", msg);
        return 1;
    }
    frame_job j = { .c = c };
    char base[256];
    app_set_name(mesh, "", base, sizeof base);
    j.base = base;
    stc_conn *conn = NULL;
    float *rgb = NULL, *strip = NULL;
    rm_mesh *m = rm_load_obj(mesh, kind, msg, sizeof msg);
    if (!m)
        goto fail;
    j.m = m;
    if (c->inproc) {
        j.s = rs_inproc_new(tex, image, msg, sizeof msg);
    } else {
        if (c->set)
            snprintf(set, sizeof set, "%s", c->set);
        else
            app_set_name(tex, "render-", set, sizeof set);
        if (app_connect(c, &conn, msg, sizeof msg) != 0 ||
            app_upload(c, conn, tex, image, set, msg, sizeof msg) != 0)
            goto fail;
        j.s = rs_net_new(conn, set, c->batch, c->inflight, msg, sizeof msg);
        if (j.s && c->breakdown && !(j.timing = rs_inproc_new(tex, image, msg, sizeof msg)))
            goto fail;
    }
    if (!j.s)
        goto fail;
    if (j.s->nfaces < m->nfaces) {
        snprintf(msg, sizeof msg, "%.300s has %u faces but the texture %.300s only %u", mesh,
                 m->nfaces,
                 tex, j.s->nfaces);
        goto fail;
    }
    if (mkdir(c->out, 0777) != 0 && access(c->out, W_OK) != 0) {
        snprintf(msg, sizeof msg, "%s: cannot write there", c->out);
        goto fail;
    }
    rgb = malloc((size_t)c->width * c->height * 3 * sizeof *rgb);
    if (!rgb || (c->strip && !(strip = malloc((size_t)c->width * c->strip * c->height * 3 *
                                               sizeof *strip)))) {
        snprintf(msg, sizeof msg, "out of memory");
        goto fail;
    }
    int m0 = c->mode < 0 ? 0 : c->mode, m1 = c->mode < 0 ? 2 : c->mode;
    for (int mode = m0; mode <= m1; mode++) {
        unsigned f0 = c->all_frames ? 0 : c->frame, f1 = c->all_frames ? c->orbit.frames - 1
                                                                       : c->frame;
        for (unsigned f = f0; f <= f1; f++)
            if (render_one(&j, f, (unsigned)mode, rgb, msg, sizeof msg) != 0)
                goto fail;
        if (c->strip) {
            for (unsigned k = 0; k < c->strip; k++) {
                unsigned f = (unsigned)((uint64_t)k * c->orbit.frames / c->strip);
                app_cfg q = *c;
                q.quiet = 1;
                frame_job jq = j;
                jq.c = &q;
                int bad = render_one(&jq, f, (unsigned)mode, rgb, msg, sizeof msg);
                j.t = jq.t;   /* the target's buffers may have grown: one owner */
                if (bad)
                    goto fail;
                ri_paste(strip, c->width * c->strip, c->height, rgb, c->width, c->height,
                         k * c->width, 0);
            }
            char path[1024];
            snprintf(path, sizeof path, "%s/%s_%s_%ux_strip%u.png", c->out, base,
                     MODE_NAMES[mode], c->msaa, c->strip);
            if (ri_write_png(path, strip, c->width * c->strip, c->height, msg, sizeof msg) != 0)
                goto fail;
            printf("%s %s strip of %u frames -> %s\n", base, MODE_NAMES[mode], c->strip, path);
        }
    }
    rc = 0;
    goto out;
fail:
    fprintf(stderr, "seamtex-render: %s\n", msg);
out:
    free(rgb);
    free(strip);
    rr_target_free(&j.t);
    rs_free(j.s);
    rs_free(j.timing);
    rm_free(m);
    stc_close(conn);
    return rc;
}

int main(int argc, char **argv)
{
    app_cfg c;
    if (parse_args(argc, argv, &c) != 0)
        return 2;
    if (c.toth)
        return study_run(&c) == 0 ? 0 : 1;
    return frame_main(&c);
}
