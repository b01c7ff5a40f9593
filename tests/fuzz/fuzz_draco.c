/* tests/fuzz/fuzz_draco.c - libFuzzer target for the Draco mesh reader
 * (store/import/mesh_io.h, st_draco_read_mem; the Draco library itself is not instrumented,
 * the shim draco.cpp is). Any bytes must give a mesh or a clean error. A mesh that was read
 * must be consistent: counts within the caps, every corner's position index < npos, every
 * uv index < nuv or ST_MESH_NO_UV (and all of them NO_UV when nuv = 0), ntri_nouv counted
 * right, every coordinate finite; seams must then be found without fault.
 * Seeds: tests/fuzz/seeds/fuzz_draco/ (small .drc files, edgebreaker and sequential). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "mesh.h"
#include "mesh_io.h"

/* an invariant: on failure, names it and stops (libFuzzer keeps the input) */
#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    st_mesh_caps caps = {1u << 14, 1u << 14, 1u << 20, 0};
    st_mesh *m = NULL;
    st_error e;
    int rc = st_draco_read_mem(data, size, &caps, &m, &e);
    if (rc != ST_OK) {
        CHECK(m == NULL && e.msg[0]);
        return 0;
    }
    CHECK(m->ntri >= 1 && m->ntri <= caps.max_tris && m->npos <= caps.max_verts &&
          m->nuv <= caps.max_verts && m->nfaces_src == m->ntri);
    uint32_t nouv = 0;
    for (uint32_t t = 0; t < m->ntri; t++) {
        int missing = 0;
        for (int k = 0; k < 3; k++) {
            CHECK(m->tri_pos[t * 3 + k] < m->npos);
            uint32_t uv = m->tri_uv[t * 3 + k];
            CHECK(uv == ST_MESH_NO_UV ? 1 : uv < m->nuv);
            CHECK(m->nuv > 0 || uv == ST_MESH_NO_UV);
            missing |= uv == ST_MESH_NO_UV;
        }
        nouv += (uint32_t)missing;
        CHECK(m->tri_face[t] < m->nfaces_src);
    }
    CHECK(nouv == m->ntri_nouv);
    for (uint32_t i = 0; i < m->npos * 3; i++)
        CHECK(isfinite(m->pos[i]));
    for (uint32_t i = 0; i < m->nuv * 2; i++)
        CHECK(isfinite(m->uv[i]));
    if (st_mesh_find_seams(m, &e) == ST_OK) {
        volatile uint32_t sum = m->seams->nseams + m->seams->nboundary + m->seams->ncharts;
        (void)sum;
    }
    (void)st_mesh_require_uv(m, &e);
    st_mesh_free(m);
    return 0;
}
