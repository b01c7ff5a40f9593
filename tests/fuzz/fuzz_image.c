/* tests/fuzz/fuzz_image.c - libFuzzer target for the OpenImageIO reader
 * (store/import/image_io.h, st_image_read_any: OIIO for every format, the OpenEXR C API for
 * EXR magic with OIIO as its fallback). The readers take a path, so each input is written to
 * one temp file whose extension is picked from the input's magic (png, jpg, tif, hdr, bmp,
 * gif, psd, ppm, exr; anything else .tga, which has no magic), as an upload named after its
 * format would be. OIIO is slow: run with a small -max_len (make fuzz passes none; the seeds
 * are under 2 KB). Invariants: an error comes with a message and no data; an image has
 * 1 <= w, h <= max_dim, 1..4 channels, a known dtype, its bytes within max_bytes, an alpha
 * index inside the channels, and every texel readable.
 * Seeds: tests/fuzz/seeds/fuzz_image/. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "image_io.h"
#include "set.h"

/* an invariant: on failure, names it and stops (libFuzzer keeps the input) */
#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char *ext_of(const uint8_t *d, size_t n)
{
    static const struct { const char *magic; size_t len; const char *ext; } M[] = {
        {"\x89PNG", 4, "png"}, {"\xff\xd8\xff", 3, "jpg"}, {"II*\0", 4, "tif"},
        {"MM\0*", 4, "tif"}, {"#?", 2, "hdr"}, {"BM", 2, "bmp"}, {"GIF8", 4, "gif"},
        {"8BPS", 4, "psd"}, {"v/1\x01", 4, "exr"}, {"P6", 2, "ppm"}, {"P5", 2, "pgm"},
        {"P3", 2, "ppm"}, {"P2", 2, "pgm"},
    };
    for (size_t i = 0; i < sizeof M / sizeof M[0]; i++)
        if (n >= M[i].len && !memcmp(d, M[i].magic, M[i].len))
            return M[i].ext;
    return "tga";
}

static char dir_path[256];
static char file_path[300];

static void cleanup(void)
{
    if (file_path[0])
        unlink(file_path);
    if (dir_path[0])
        rmdir(dir_path);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!dir_path[0]) {
        const char *t = getenv("TMPDIR");
        snprintf(dir_path, sizeof dir_path, "%s/seamtex-fuzz-image-XXXXXX", t ? t : "/tmp");
        CHECK(mkdtemp(dir_path) != NULL);
        atexit(cleanup);
    }
    if (file_path[0])
        unlink(file_path);
    snprintf(file_path, sizeof file_path, "%s/in.%s", dir_path, ext_of(data, size));
    FILE *f = fopen(file_path, "wb");
    CHECK(f != NULL);
    CHECK(fwrite(data, 1, size, f) == size || size == 0);
    CHECK(fclose(f) == 0);

    st_image_caps caps = {1024, (size_t)16 << 20};
    st_image img;
    st_error e;
    memset(&e, 0, sizeof e);
    if (st_image_read_any(file_path, &caps, &img, &e) != ST_OK) {
        CHECK(e.msg[0] != 0 && img.data == NULL);
        return 0;
    }
    CHECK(img.w >= 1 && img.h >= 1 && img.w <= caps.max_dim && img.h <= caps.max_dim);
    CHECK(img.nchan >= 1 && img.nchan <= 4);
    CHECK(img.dtype == ST_DT_U8 || img.dtype == ST_DT_U16 || img.dtype == ST_DT_HALF ||
          img.dtype == ST_DT_F32);
    CHECK(img.alpha_chan >= -1 && img.alpha_chan < (int)img.nchan);
    size_t n = (size_t)img.w * img.h * img.nchan * st_dtype_size(img.dtype);
    CHECK(n <= caps.max_bytes && img.data != NULL);
    volatile uint8_t sum = 0;
    for (size_t i = 0; i < n; i++)
        sum ^= ((const uint8_t *)img.data)[i];
    (void)sum;
    st_image_free(&img);
    return 0;
}
