/* tests/fuzz/fuzz_obj.c - libFuzzer target for the OBJ reader and seam detection: any bytes
 * must give a mesh or a clean error, never a crash, leak or unbounded allocation (caps are
 * set small so the fuzzer explores parsing, not memory). Seeds: tests/fuzz/seeds/fuzz_obj/. */
#include <stddef.h>
#include <stdint.h>

#include "mesh.h"
#include "mesh_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

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
        (void)st_mesh_require_uv(m, &e);
        st_mesh_free(m);
    }
    return 0;
}
