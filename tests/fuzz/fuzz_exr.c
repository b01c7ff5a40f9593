/* tests/fuzz/fuzz_exr.c - libFuzzer target for the OpenEXR reader on OpenEXR's C API
 * (store/import/exr.h). The input is read through st_exr_read_mem (the C API on a memory
 * stream: its custom read and size functions), with caps small enough that the fuzzer
 * explores headers and chunks rather than memory. Invariants:
 *   - an error comes with a message and leaves the image empty;
 *   - an image that was read has 1 <= w, h <= max_dim, 1..4 channels, half or float texels,
 *     an alpha channel index inside the channels (or -1), and every texel is readable;
 *   - the file entry point agrees: st_exr_read on a temp file holding the same bytes gives
 *     the same code and, on success, the same image bit for bit (one in 8 inputs, the
 *     file path is slower).
 * Seeds: tests/fuzz/seeds/fuzz_exr/ (small scanline, tiled, mip-mapped, compressed files). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "exr.h"
#include "set.h"

/* an invariant: on failure, names it and stops (libFuzzer keeps the input) */
#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char tmp_path[256];
static unsigned long nrun;

static void cleanup(void)
{
    if (tmp_path[0])
        unlink(tmp_path);
}

static int write_tmp(const uint8_t *data, size_t size)
{
    if (!tmp_path[0]) {
        const char *dir = getenv("TMPDIR");
        snprintf(tmp_path, sizeof tmp_path, "%s/seamtex-fuzz-exr-XXXXXX", dir ? dir : "/tmp");
        int fd = mkstemp(tmp_path);
        if (fd < 0)
            return -1;
        close(fd);
        atexit(cleanup);
    }
    FILE *f = fopen(tmp_path, "wb");
    if (!f)
        return -1;
    size_t w = fwrite(data, 1, size, f);
    return fclose(f) == 0 && w == size ? 0 : -1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    st_image_caps caps = {2048, (size_t)32 << 20};
    st_image img;
    st_error e;
    memset(&e, 0, sizeof e);
    int rc = st_exr_read_mem(data, size, "fuzz.exr", &caps, &img, &e);
    if (rc != ST_OK) {
        CHECK(e.msg[0] != 0 && img.data == NULL);
    } else {
        CHECK(img.w >= 1 && img.h >= 1 && img.w <= caps.max_dim && img.h <= caps.max_dim);
        CHECK(img.nchan >= 1 && img.nchan <= 4);
        CHECK(img.dtype == ST_DT_HALF || img.dtype == ST_DT_F32);
        CHECK(img.alpha_chan >= -1 && img.alpha_chan < (int)img.nchan);
        CHECK(img.data != NULL);
        size_t n = (size_t)img.w * img.h * img.nchan * st_dtype_size(img.dtype);
        volatile uint8_t sum = 0;
        for (size_t i = 0; i < n; i++)
            sum ^= ((const uint8_t *)img.data)[i];
        (void)sum;
    }
    if ((nrun++ & 7) == 0 && write_tmp(data, size) == 0) {
        st_image f;
        st_error e2;
        int rc2 = st_exr_read(tmp_path, &caps, &f, &e2);
        if (rc2 != rc) {
            fprintf(stderr, "memory %d (%s) vs file %d (%s)\n", rc, e.msg, rc2, e2.msg);
            __builtin_trap();
        }
        if (rc == ST_OK) {
            CHECK(f.w == img.w && f.h == img.h && f.nchan == img.nchan && f.dtype == img.dtype &&
                  f.alpha_chan == img.alpha_chan && f.envmap == img.envmap &&
                  f.nlevels_file == img.nlevels_file);
            CHECK(!memcmp(f.data, img.data,
                          (size_t)img.w * img.h * img.nchan * st_dtype_size(img.dtype)));
            st_image_free(&f);
        }
    }
    st_image_free(&img);
    return 0;
}
