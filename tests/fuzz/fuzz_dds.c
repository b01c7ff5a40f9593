/* tests/fuzz/fuzz_dds.c - libFuzzer target for the DDS reader (dds.c): any input must give a
 * set or a clean error, never a crash, a leak or an allocation over the cap; a set that was
 * read must write back and read again to the same blocks. Seeds in seeds/fuzz_dds/ (a 2D
 * texture with mips, a cube map, a per-face array with its adjacency trailer). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "bc1.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    st_set *s = NULL;
    st_error e;
    if (st_dds_read_mem(data, size, (size_t)64 << 20, &s, &e) != ST_OK)
        return 0;
    uint8_t *buf = NULL;
    size_t len = 0;
    if (st_dds_write_mem(s, &buf, &len, &e) == ST_OK) {
        st_set *r = NULL;
        if (st_dds_read_mem(buf, len, (size_t)64 << 20, &r, &e) != ST_OK)
            abort();
        if (r->texel_bytes != s->texel_bytes || memcmp(r->texels, s->texels, s->texel_bytes))
            abort();
        st_set_free(r);
        free(buf);
    }
    st_set_free(s);
    return 0;
}
