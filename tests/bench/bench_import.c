/* tests/bench/bench_import.c - import cost: images per megapixel (OIIO and the OpenEXR C API),
 * meshes per thousand triangles (OBJ, Draco, with welding and seam detection), whole atlas
 * imports (mesh + texture + seams + chart mask + mips) and cube conversions.
 *
 * Usage: bench_import [--json PATH] [--reps N]
 *
 * Each figure is the median of --reps runs (default 5) of one import of the file, wall time
 * and process CPU time, one thread; per-megapixel and per-kilotriangle figures use CPU time. Files come from SEAMTEX_DATA (default ../shared/data);
 * a missing file is reported and skipped.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "exr.h"
#include "image.h"
#include "import.h"
#include "mesh.h"
#include "image_io.h"
#include "mesh_io.h"
#include "../common/benchstat.h"

typedef enum { K_IMAGE, K_EXR, K_OBJ, K_DRACO, K_IMPORT, K_LATLONG } kind;

typedef struct job {
    const char *name;
    const char *rel;
    kind k;
    const char *tex;       /* K_IMPORT: texture to pair with a Draco mesh */
} job;

static const job JOBS[] = {
    {"png 2048^2 rgb8 (OIIO)", "meshes/waterbottle/WaterBottle_baseColor.png", K_IMAGE, NULL},
    {"png 512^2 rgb8 (OIIO)", "images/astronaut.png", K_IMAGE, NULL},
    {"jpeg 1240x846 (OIIO)", "images/StillLife.jpg", K_IMAGE, NULL},
    {"hdr 1024x512 float (OIIO)", "env/converted/forest.hdr", K_IMAGE, NULL},
    {"exr 256x1536 half tiled (C API)", "env/StageEnvCube.exr", K_EXR, NULL},
    {"exr 1000x500 half tiled (C API)", "env/StageEnvLatLong.exr", K_EXR, NULL},
    {"exr 512x3072 rgba half (C API)", "env/OrientationCube.exr", K_EXR, NULL},
    {"exr 1000x500 half (OIIO, compare)", "env/StageEnvLatLong.exr", K_IMAGE, NULL},
    {"exr 1024x512 float DWAB (OIIO)", "env/forest.exr", K_IMAGE, NULL},
    {"obj duck 4212 tris + seams", "meshes/duck/Duck.obj", K_OBJ, NULL},
    {"obj waterbottle 4510 tris + seams", "meshes/waterbottle/WaterBottle.obj", K_OBJ, NULL},
    {"obj milktruck 3624 tris + seams", "meshes/cesiummilktruck/CesiumMilkTruck.obj", K_OBJ, NULL},
    {"obj spider 1368 tris + seams", "meshes/spider/spider.obj", K_OBJ, NULL},
    {"drc duck 4212 tris + seams", "drc/converted/Duck.drc", K_DRACO, NULL},
    {"drc bunny 69451 tris + seams", "drc/bunny_gltf.drc", K_DRACO, NULL},
    {"atlas: duck obj + 512^2 png", "meshes/duck/Duck.obj", K_IMPORT, NULL},
    {"atlas: waterbottle obj + 2048^2 png", "meshes/waterbottle/WaterBottle.obj", K_IMPORT, NULL},
    {"atlas: duck drc + 512^2 png", "drc/converted/Duck.drc", K_IMPORT, "meshes/duck/DuckCM.png"},
    {"cube: exr strip 6x256^2 + mips", "env/StageEnvCube.exr", K_IMPORT, NULL},
    {"cube: latlong 1000x500 -> 6x256^2", "env/StageEnvLatLong.exr", K_LATLONG, NULL},
};

/* Runs one job; returns 0 and the work size (megapixels, kilotriangles) or -1. */
static int run_job(const job *j, const char *path, const char *tex, double *mpix, double *ktri)
{
    st_error e;
    *mpix = *ktri = 0;
    switch (j->k) {
    case K_IMAGE:
    case K_EXR: {
        st_image img;
        int rc = j->k == K_EXR ? st_exr_read(path, NULL, &img, &e) : st_image_read(path, NULL, &img, &e);
        if (rc) {
            fprintf(stderr, "%s: %s\n", j->name, e.msg);
            return -1;
        }
        *mpix = (double)img.w * img.h / 1e6;
        st_image_free(&img);
        return 0;
    }
    case K_OBJ:
    case K_DRACO: {
        st_mesh *m = NULL;
        int rc = j->k == K_OBJ ? st_obj_read_file(path, NULL, &m, &e) : st_draco_read_file(path, NULL, &m, &e);
        if (!rc)
            rc = st_mesh_find_seams(m, &e);
        if (rc) {
            fprintf(stderr, "%s: %s\n", j->name, e.msg);
            st_mesh_free(m);
            return -1;
        }
        *ktri = m->ntri / 1e3;
        st_mesh_free(m);
        return 0;
    }
    default: {
        st_import_opts o;
        st_import_opts_init(&o);
        o.texture_path = tex;
        if (j->k == K_LATLONG) {
            o.cube = ST_IMPORT_CUBE_LATLONG;
            o.face_size = 256;
        }
        st_set *s = NULL;
        if (st_import_file(path, &o, &s, &e)) {
            fprintf(stderr, "%s: %s\n", j->name, e.msg);
            return -1;
        }
        for (uint32_t f = 0; f < s->info.nfaces; f++)
            *mpix += (double)s->faces[f].w * s->faces[f].h / 1e6;
        st_set_free(s);
        return 0;
    }
    }
}

int main(int argc, char **argv)
{
    const char *json = NULL;
    int reps = 5;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            reps = atoi(argv[++i]);
    }
    if (reps < 1 || reps > 50)
        reps = 5;
    const char *data = getenv("SEAMTEX_DATA");
    if (!data || !*data)
        data = "../shared/data";
    FILE *js = json ? fopen(json, "w") : NULL;
    if (js)
        fprintf(js, "{\"bench\":\"import\",\"reps\":%d,\"results\":[", reps);
    printf("import, median of %d runs, one thread; wall and process CPU time, the ratios from CPU\n"
           "time (the machine is shared)\n", reps);
    printf("%-38s %9s %9s %10s %12s\n", "job", "wall ms", "cpu ms", "cpu ms/MPix", "cpu ms/ktri");
    int first = 1;
    for (size_t k = 0; k < sizeof JOBS / sizeof JOBS[0]; k++) {
        const job *j = &JOBS[k];
        char path[2048], tex[2048];
        snprintf(path, sizeof path, "%s/%s", data, j->rel);
        if (j->tex)
            snprintf(tex, sizeof tex, "%s/%s", data, j->tex);
        if (access(path, R_OK)) {
            printf("%-38s skipped (%s missing)\n", j->name, path);
            continue;
        }
        double wall[50], cpu[50], mpix = 0, ktri = 0;
        int ok = 1;
        for (int r = 0; r < reps && ok; r++) {
            double w0 = st_bench_clock(CLOCK_MONOTONIC);
            double c0 = st_bench_clock(CLOCK_PROCESS_CPUTIME_ID);
            if (run_job(j, path, j->tex ? tex : NULL, &mpix, &ktri))
                ok = 0;
            wall[r] = (st_bench_clock(CLOCK_MONOTONIC) - w0) * 1e3;
            cpu[r] = (st_bench_clock(CLOCK_PROCESS_CPUTIME_ID) - c0) * 1e3;
        }
        if (!ok) {
            printf("%-38s failed\n", j->name);
            continue;
        }
        qsort(wall, (size_t)reps, sizeof(double), st_bench_cmp_double);
        qsort(cpu, (size_t)reps, sizeof(double), st_bench_cmp_double);
        double wm = wall[reps / 2], cm = cpu[reps / 2];
        char per_mp[32] = "-", per_kt[32] = "-";
        if (mpix > 0)
            snprintf(per_mp, sizeof per_mp, "%.1f", cm / mpix);
        if (ktri > 0)
            snprintf(per_kt, sizeof per_kt, "%.3f", cm / ktri);
        printf("%-38s %9.2f %9.2f %10s %12s\n", j->name, wm, cm, per_mp, per_kt);
        if (js) {
            fprintf(js, "%s{\"job\":\"%s\",\"wall_ms\":%.3f,\"cpu_ms\":%.3f,\"mpix\":%.4f,\"ktri\":%.4f}",
                    first ? "" : ",", j->name, wm, cm, mpix, ktri);
            first = 0;
        }
    }
    if (js) {
        fprintf(js, "]}\n");
        fclose(js);
    }
    return 0;
}
