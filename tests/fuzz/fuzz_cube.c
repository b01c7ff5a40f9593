/* tests/fuzz/fuzz_cube.c - libFuzzer target for the cube conversions an upload goes through
 * after its decoder (store/kinds/cube_convert.c: cube=strip_v|strip_h|cross_h|cross_v|latlong|
 * auto on an image, a 6-face Ptex environment cube; store/kinds/atlas.c for an image that
 * stays one). The decoders have their own targets; here the decoded image is made from the
 * input directly, so that hostile sizes, aspect ratios, channel counts, types and texel values
 * (NaN, infinities in half and float) reach the conversions at fuzzing speed.
 *
 * Input: byte 0 picks the conversion (bit 7: the rest is a Ptex file for
 * st_cube_from_ptex_env), byte 1 nchan (1..4), dtype and the envmap tag, bytes 2-5 the width
 * and height (1..512 each), byte 6 the lat-long face size (0 or a power of two up to 512,
 * or a value that is not one), the rest the texels (repeated to fill the image).
 * Invariants:
 *   - a refusal has a message; no crash, leak or read outside the image (ASan);
 *   - a cube that is built is a cube (st_cube_is_cube), samples by direction (a NaN and a zero
 *     direction included: status ST_Q_NONFINITE, never a crash) and, for the strips, lays
 *     back out as the same image texel for texel (st_cube_to_image);
 *   - st_cube_guess_layout's answer is one of the layouts or -1.
 * Seeds: tests/fuzz/seeds/fuzz_cube/. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "atlas.h"
#include "cube.h"
#include "image.h"
#include "ptex.h"
#include "sample.h"

#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

#define MAX_BYTES ((size_t)16 << 20)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void sample_cube(const st_set *c)
{
    CHECK(st_cube_is_cube(c));
    st_cube_query q[6];
    memset(q, 0, sizeof q);
    static const float dirs[6][3] = {{1, 0.2f, -0.3f}, {-0.5f, 1, 0.5f}, {0.3f, -0.3f, -1},
                                     {1, 1, 1}, {0, 0, 0}, {NAN, 0, 1}};
    for (int i = 0; i < 6; i++) {
        memcpy(q[i].dir, dirs[i], sizeof q[i].dir);
        q[i].cone = i & 1 ? 0.05f * (float)i : 0;
    }
    float out[6 * ST_MAX_CHANNELS], cov[6];
    uint8_t st[6];
    for (unsigned m = 0; m <= ST_MODE_CLAMP; m++) {
        st_sample_opts o = {.mode = (uint8_t)m, .filter = ST_FILTER_BILINEAR, .max_aniso = 4};
        int bad = st_cube_sample_dir(c, &o, m & 1, q, 6, out, cov, st);
        CHECK(bad >= 2);                      /* the zero and the NaN directions at least */
        CHECK(st[4] == ST_Q_NONFINITE && st[5] == ST_Q_NONFINITE);
    }
}

static void from_ptex(const uint8_t *p, size_t n)
{
    st_set *px = NULL, *c = NULL, *back = NULL;
    st_error e;
    if (st_ptex_read_mem(p, n, MAX_BYTES, &px, &e) != ST_OK)
        return;
    e.msg[0] = 0;
    if (st_cube_from_ptex_env(px, MAX_BYTES, &c, &e) == ST_OK) {
        sample_cube(c);
        if (st_cube_to_ptex_env(c, MAX_BYTES, &back, &e) == ST_OK) {
            CHECK(back->info.nfaces == 6 && st_cube_is_ptex_env_layout(back));
            st_set_free(back);
        }
        st_set_free(c);
    } else {
        CHECK(e.msg[0]);
    }
    st_set_free(px);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 8)
        return 0;
    if (data[0] & 0x80) {
        from_ptex(data + 1, size - 1);
        return 0;
    }
    st_image img;
    memset(&img, 0, sizeof img);
    img.nchan = (uint8_t)(1 + (data[1] & 3));
    img.dtype = (uint8_t)((data[1] >> 2) & 3);
    img.envmap = (uint8_t)((data[1] >> 4) % 3);
    img.alpha_chan = img.nchan == 4 ? 3 : -1;
    img.w = 1 + ((uint32_t)(data[2] | data[3] << 8) % 512);
    img.h = 1 + ((uint32_t)(data[4] | data[5] << 8) % 512);
    uint32_t face_n = data[6] < 11 ? (data[6] ? 1u << (data[6] - 1) : 0) : data[6];
    size_t bytes = (size_t)img.w * img.h * img.nchan * st_dtype_size(img.dtype);
    img.data = malloc(bytes);
    if (!img.data)
        return 0;
    const uint8_t *tex = data + 7;
    size_t tn = size - 7;
    for (size_t i = 0; i < bytes; i++)
        ((uint8_t *)img.data)[i] = tex[i % tn];

    int guess = st_cube_guess_layout(&img);
    CHECK(guess >= -1 && guess <= ST_CUBE_LATLONG);
    int layout = data[0] % 7;                 /* 0..4 a layout, 5 the guess, 6 an atlas */
    if (layout == 5)
        layout = guess;
    st_set *s = NULL;
    st_error e;
    e.msg[0] = 0;
    if (layout < 0 || layout == 6) {
        if (st_atlas_from_image(&img, NULL, MAX_BYTES, &s, &e) == ST_OK) {
            CHECK(s->info.nfaces == 1 && s->faces[0].w == img.w && s->faces[0].h == img.h);
            st_set_free(s);
        } else {
            CHECK(e.msg[0]);
        }
    } else if (st_cube_from_image(&img, (st_cube_layout)layout, face_n, MAX_BYTES, &s, &e) ==
               ST_OK) {
        sample_cube(s);
        if (layout == ST_CUBE_STRIP_V || layout == ST_CUBE_STRIP_H) {
            st_image back;
            CHECK(st_cube_to_image(s, 0, (st_cube_layout)layout, &back, &e) == ST_OK);
            CHECK(back.w == img.w && back.h == img.h && back.nchan == img.nchan &&
                  back.dtype == img.dtype);
            CHECK(!memcmp(back.data, img.data, bytes));
            st_image_free(&back);
        }
        st_set_free(s);
    } else {
        CHECK(e.msg[0]);
    }
    free(img.data);
    return 0;
}
