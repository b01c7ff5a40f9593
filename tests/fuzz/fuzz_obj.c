/* tests/fuzz/fuzz_obj.c - libFuzzer target for the OBJ reader, seam detection and what an atlas
 * set builds from a mesh (chart mask, chart ids, chart Traverse's seam links, the query chart's
 * triangle lists: kinds/atlas.c, atlas_links.c, atlas_locate.c): any bytes must give a mesh or a clean error, never a crash, leak or
 * unbounded allocation (caps are set small so the fuzzer explores parsing, not memory), and a
 * mesh with texture coordinates must make an atlas set of a small image that samples in every
 * mode. Seeds: tests/fuzz/seeds/fuzz_obj/. */
#include <stddef.h>
#include <stdint.h>

#include "atlas.h"
#include "mesh.h"
#include "mesh_io.h"
#include "sample.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The mesh m (taken over) as the mesh of a 24 x 20 RGBA8 atlas, sampled near every seam end
 * and at a few other points in each mode with bilinear, trilinear and aniso. */
static void atlas_of(st_mesh *m)
{
    static uint8_t px[20][24][4];
    for (int j = 0; j < 20; j++)
        for (int i = 0; i < 24; i++)
            for (int c = 0; c < 4; c++)
                px[j][i][c] = (uint8_t)(i * 11 + j * 7 + c * 60);
    st_image img = {.w = 24, .h = 20, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3,
                    .data = &px[0][0][0]};
    st_set *s = NULL;
    st_error e;
    if (st_atlas_from_image(&img, m, 0, &s, &e) != ST_OK)
        return; /* the mesh was freed with the failure */
    const st_atlas *a = st_atlas_get(s);
    enum { NQ = 48 };
    st_query q[NQ] = {{0}};
    uint32_t n = 0;
    for (uint32_t i = 0; a && a->mesh && a->mesh->seams && i < a->mesh->seams->nseams && n < NQ;
         i++)
        for (int k = 0; k < 2 && n < NQ; k++, n++) {
            q[n].u = a->mesh->seams->seams[i].uv[k][0][0];
            q[n].v = a->mesh->seams->seams[i].uv[k][0][1];
            q[n].dudx = q[n].dvdy = (float)(n % 4) / 16.0f;
            q[n].dvdx = (float)(n % 3) / 64.0f;
        }
    for (; n < NQ; n++) {
        q[n].u = (float)(n % 7) / 6.0f;
        q[n].v = (float)(n % 5) / 4.0f;
        q[n].dudx = q[n].dvdy = (float)(n % 4) / 8.0f;
    }
    static const uint8_t filters[3] = {ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR, ST_FILTER_ANISO};
    for (unsigned mode = 0; mode < 3; mode++)
        for (int f = 0; f < 3; f++) {
            st_sample_opts o = {.mode = (uint8_t)mode, .filter = filters[f], .max_aniso = 8};
            float out[NQ * 4], cov[NQ];
            uint8_t st[NQ];
            if (st_sample_batch(s, &o, q, NQ, out, cov, st) < 0)
                __builtin_trap(); /* valid options: never an error */
            for (int i = 0; i < NQ; i++)
                if (st[i] == ST_Q_OK && !(cov[i] >= 0.0f && cov[i] <= 1.0f))
                    __builtin_trap(); /* coverage outside [0, 1] */
        }
    st_set_free(s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    st_mesh_caps caps = {1u << 14, 1u << 14, 1u << 20, 0};
    st_mesh *m = NULL;
    st_error e;
    if (st_obj_read_mem((const char *)data, size, NULL, &caps, &m, &e) == ST_OK) {
        if (st_mesh_find_seams(m, &e) == ST_OK) {
            /* touch the results so the sanitizers see every record */
            volatile uint32_t sum = m->seams->nseams + m->seams->nboundary + m->seams->ncharts;
            for (uint32_t i = 0; i < m->seams->nseams; i++)
                sum += m->seams->seams[i].pos[0];
            (void)sum;
        }
        if (st_mesh_require_uv(m, &e) == ST_OK)
            atlas_of(m);
        else
            st_mesh_free(m);
    }
    return 0;
}
