/* tests/bench/bench_bc1.c - BC1 encoder quality and speed on the shared BC1 benchmark set
 * ($SEAMTEX_DATA/images/bc1-set/, figures of other encoders in the data README), and the
 * multi-threaded encode of a big texture.
 *
 * Per level: RGB PSNR of each image (exact truncating decoder, all texels) and single-core
 * speed in MPix/s (median of REPS runs per image); the mean PSNR over the images and the
 * speed over all texels. Then a 4096^2 texture (the 1024^2 atlas tiled 4x4) encoded with one
 * thread and with one thread per core (--no-big leaves it out). --extra: the same table for
 * nine images outside the benchmark set (photos, a grey texture, glTF base colour and normal
 * maps), to check that the encoder's choices are not tuned to the five.
 * Usage: bench_bc1 [--json PATH] [--reps N] [--extra] [--no-big]
 */
#include "bc1.h"
#include "image.h"
#include "image_io.h"
#include "../common/benchstat.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const char *IMAGES[] = {"kodim01.png", "kodim03.png", "kodim23.png", "colobot_green02.png",
                               "colobot_apollo.png"};
#define NIMG 5
/* outside the benchmark set, relative to SEAMTEX_DATA (see its README) */
static const char *EXTRA[] = {"images/StillLife.jpg", "images/astronaut.png", "images/brick.png",
                              "meshes/cesiummilktruck/CesiumMilkTruck.png",
                              "meshes/waterbottle/WaterBottle_baseColor.png",
                              "meshes/waterbottle/WaterBottle_normal.png",
                              "meshes/spider/SpiderTex.jpg", "meshes/duck/DuckCM.png",
                              "meshes/spider/drkwood2.jpg"};
#define NEXTRA 9

/* single-core figures are per CPU-second of this thread: the machine is shared */
static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static uint8_t *to_rgba8(const st_image *im)
{
    uint8_t *o = malloc((size_t)im->w * im->h * 4);
    if (!o)
        return NULL;
    for (size_t i = 0; i < (size_t)im->w * im->h; i++) {
        const uint8_t *p = (const uint8_t *)im->data + i * im->nchan;
        uint8_t *q = o + 4 * i;
        if (im->nchan >= 3) {
            q[0] = p[0];
            q[1] = p[1];
            q[2] = p[2];
        } else {
            q[0] = q[1] = q[2] = p[0];
        }
        q[3] = 255; /* the benchmark measures opaque RGB */
    }
    return o;
}

/* One level over n images: a row per image, the mean row; JSON into jf when not NULL. */
static void run_level(int level, const char *const *names, uint8_t *const *img, const uint32_t *W,
                      const uint32_t *H, int n, int reps, FILE *jf)
{
    const char *ln = level == ST_BC1_FAST ? "fast" : level == ST_BC1_HQ ? "hq" : "best";
    double psum = 0, tsum = 0, pix = 0;
    if (jf)
        fprintf(jf, "{\"level\":\"%s\",\"images\":[", ln);
    for (int i = 0; i < n; i++) {
        size_t np = (size_t)W[i] * H[i];
        uint8_t *blk = malloc((size_t)((W[i] + 3) / 4) * ((H[i] + 3) / 4) * 8);
        uint8_t *dec = malloc(np * 4);
        double t[50];
        for (int r = 0; r < reps; r++) {
            double t0 = cpu_now();
            st_bc1_encode_image(img[i], W[i], H[i], (size_t)W[i] * 4, level, 1, blk, NULL);
            t[r] = cpu_now() - t0;
        }
        qsort(t, (size_t)reps, sizeof *t, st_bench_cmp_double);
        double med = t[reps / 2];
        st_bc1_decode_image(blk, W[i], H[i], ST_BC1_DEC_EXACT, dec);
        double p = st_bc1_psnr_rgb(img[i], dec, np);
        const char *nm = strrchr(names[i], '/') ? strrchr(names[i], '/') + 1 : names[i];
        printf("%-6s %-28s %10.3f %10.1f\n", ln, nm, p, (double)np / med / 1e6);
        if (jf)
            fprintf(jf, "%s{\"image\":\"%s\",\"psnr\":%.4f,\"mpix_s\":%.2f}", i ? "," : "", nm,
                    p, (double)np / med / 1e6);
        psum += p;
        tsum += med;
        pix += (double)np;
        free(blk);
        free(dec);
    }
    printf("%-6s %-28s %10.3f %10.1f\n\n", ln, "MEAN", psum / n, pix / tsum / 1e6);
    if (jf)
        fprintf(jf, "],\"mean_psnr\":%.4f,\"mpix_s\":%.2f}", psum / n, pix / tsum / 1e6);
}

/* Reads path into RGBA8 (opaque); 0 or -1. */
static int load_rgba(const char *path, uint8_t **out, uint32_t *w, uint32_t *h)
{
    st_image im;
    st_error e;
    if (st_image_read(path, NULL, &im, &e) || im.dtype != ST_DT_U8) {
        printf("bench_bc1: %s unreadable (%s)\n", path, e.msg);
        return -1;
    }
    *out = to_rgba8(&im);
    *w = im.w;
    *h = im.h;
    st_image_free(&im);
    return *out ? 0 : -1;
}

int main(int argc, char **argv)
{
    const char *json = NULL;
    int reps = 5, extra = 0, with_big = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--extra"))
            extra = 1;
        else if (!strcmp(argv[i], "--no-big"))
            with_big = 0;
    }
    if (reps < 1 || reps > 50)
        reps = 5;
    const char *data = getenv("SEAMTEX_DATA");
    if (!data)
        data = "../shared/data";
    uint8_t *img[NIMG];
    uint32_t W[NIMG], H[NIMG];
    for (int i = 0; i < NIMG; i++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/images/bc1-set/%s", data, IMAGES[i]);
        if (load_rgba(path, &img[i], &W[i], &H[i]) != 0) {
            printf("bench_bc1: skipped (SEAMTEX_DATA=%s)\n", data);
            if (json) {
                FILE *f = fopen(json, "w");
                if (f) {
                    fprintf(f, "{\"skipped\":\"no bc1-set under SEAMTEX_DATA\"}\n");
                    fclose(f);
                }
            }
            return 0;
        }
    }
    FILE *jf = json ? fopen(json, "w") : NULL;
    if (jf)
        fprintf(jf, "{\"benchmark\":\"bc1\",\"reps\":%d,\"levels\":[", reps);
    printf("BC1 encoder on images/bc1-set (exact decoder, RGB PSNR over all texels; MPix per "
           "CPU-second of one thread, median of %d runs)\n", reps);
    printf("%-6s %-28s %10s %10s\n", "level", "image", "PSNR dB", "MPix/s");
    for (int level = ST_BC1_FAST; level <= ST_BC1_BEST; level++) {
        if (jf && level)
            fprintf(jf, ",");
        run_level(level, IMAGES, img, W, H, NIMG, reps, jf);
    }
    if (extra) {
        uint8_t *ximg[NEXTRA];
        uint32_t XW[NEXTRA], XH[NEXTRA];
        const char *xn[NEXTRA];
        int nx = 0;
        for (int i = 0; i < NEXTRA; i++) {
            char path[1024];
            snprintf(path, sizeof path, "%s/%s", data, EXTRA[i]);
            if (load_rgba(path, &ximg[nx], &XW[nx], &XH[nx]) == 0)
                xn[nx++] = EXTRA[i];
        }
        printf("outside the benchmark set (%d images):\n", nx);
        if (jf)
            fprintf(jf, "],\"extra\":[");
        for (int level = ST_BC1_FAST; level <= ST_BC1_BEST && nx > 0; level++) {
            if (jf && level)
                fprintf(jf, ",");
            run_level(level, xn, ximg, XW, XH, nx, reps, jf);
        }
        for (int i = 0; i < nx; i++)
            free(ximg[i]);
    }
    if (!with_big) {
        if (jf) {
            fprintf(jf, "]}\n");
            fclose(jf);
        }
        for (int i = 0; i < NIMG; i++)
            free(img[i]);
        return 0;
    }
    /* a big texture: colobot_apollo (1024^2) tiled 4x4 = 4096^2 */
    uint32_t BW = 4096, BH = 4096;
    uint8_t *big = malloc((size_t)BW * BH * 4), *blk = malloc((size_t)BW * BH / 2);
    int src = 4;
    for (uint32_t y = 0; y < BH; y++)
        for (uint32_t x = 0; x < BW; x++)
            memcpy(big + ((size_t)y * BW + x) * 4,
                   img[src] + (((size_t)(y % H[src])) * W[src] + x % W[src]) * 4, 4);
    if (jf)
        fprintf(jf, "],\"big\":[");
    printf("4096x4096 (colobot_apollo tiled), one run each, wall clock (shared machine):\n"
           "%-6s %8s %10s\n", "level", "threads", "MPix/s");
    for (int level = ST_BC1_FAST; level <= ST_BC1_HQ; level++)
        for (int th = 1; th >= 0; th--) {
            double t0 = st_bench_now();
            st_bc1_encode_image(big, BW, BH, (size_t)BW * 4, level, th, blk, NULL);
            double dt = st_bench_now() - t0;
            printf("%-6s %8s %10.1f\n", level ? "hq" : "fast", th ? "1" : "all",
                   (double)BW * BH / dt / 1e6);
            if (jf)
                fprintf(jf, "%s{\"level\":\"%s\",\"threads\":\"%s\",\"mpix_s\":%.2f}",
                        level || !th ? "," : "", level ? "hq" : "fast", th ? "1" : "all",
                        (double)BW * BH / dt / 1e6);
        }
    if (jf) {
        fprintf(jf, "]}\n");
        fclose(jf);
    }
    free(big);
    free(blk);
    for (int i = 0; i < NIMG; i++)
        free(img[i]);
    return 0;
}
