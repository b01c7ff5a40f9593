/* tests/fuzz/fuzz_native.c - libFuzzer target for the native set reader (native_read.c): any
 * file must open as a set or be refused cleanly, never crash, leak or read outside the
 * mapping; a set that opens must sample (every filter family) inside its arena.
 *
 * Random bytes almost never pass the CRCs, which would keep the fuzzer at the header; so when
 * the input's first byte is odd the target first rewrites the header CRC and the CRC of every
 * section that lies inside the file, letting mutations reach the structural checks (section
 * bounds, the face table against the layout, metadata, extension records). Seeds in
 * seeds/fuzz_native/ (a per-face set with its Ptex record, an atlas with a mesh, a BC1 set, a
 * triangle-mesh set). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "crc32c.h"
#include "native.h"
#include "sample.h"

static void fix_crcs(uint8_t *p, size_t n)
{
    if (n < ST_NATIVE_PAGE)
        return;
    uint32_t ns;
    memcpy(&ns, p + 24, 4);
    for (uint32_t i = 0; i < ns && i < ST_NATIVE_MAX_SECTIONS; i++) {
        uint8_t *t = p + 1024 + 32 * i;
        uint64_t off, size;
        memcpy(&off, t + 8, 8);
        memcpy(&size, t + 16, 8);
        if (off <= n && size <= n - off) {
            uint32_t c = stu_crc32c(0, p + off, (size_t)size);
            memcpy(t + 24, &c, 4);
        }
    }
    uint32_t c = stu_crc32c(0, p, 4092);
    memcpy(p + 4092, &c, 4);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0 || size > ((size_t)16 << 20))
        return 0;
    uint8_t *buf = malloc(size);
    if (!buf)
        return 0;
    memcpy(buf, data, size);
    if (size >= ST_NATIVE_PAGE && (buf[ST_NATIVE_PAGE - 5] & 1))  /* a reserved header byte */
        fix_crcs(buf, size);
    int fd = memfd_create("fuzz_native", MFD_CLOEXEC);
    if (fd < 0 || write(fd, buf, size) != (ssize_t)size) {
        if (fd >= 0)
            close(fd);
        free(buf);
        return 0;
    }
    free(buf);
    st_set *s = NULL;
    st_error e;
    if (st_native_open_fd(fd, ST_NATIVE_VERIFY, NULL, &s, &e) != ST_OK)
        return 0;
    st_query q[8];
    float out[8 * 4], cov[8];
    uint8_t st[8];
    for (int i = 0; i < 8; i++)
        q[i] = (st_query){(uint32_t)i % s->info.nfaces, 0.13f * (float)i - 0.1f,
                          0.9f - 0.11f * (float)i, 0.05f * (float)(i & 3), 0, 0,
                          0.05f * (float)(i & 3)};
    static const uint8_t filters[] = {ST_FILTER_POINT, ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR,
                                      ST_FILTER_ANISO, ST_FILTER_PTEX_BILINEAR,
                                      ST_FILTER_PTEX_BICUBIC};
    for (unsigned m = 0; m <= ST_MODE_CLAMP; m++)
        for (size_t f = 0; f < sizeof filters; f++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = filters[f], .max_aniso = 4};
            st_sample_batch(s, &o, q, 8, out, cov, st);
        }
    st_set_free(s);
    return 0;
}
