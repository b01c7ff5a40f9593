/* tests/fuzz/fuzz_options.c - libFuzzer target for the upload options parser
 * (store/import/import.h, st_import_opts_parse; grammar in PROTOCOL.md "Upload options").
 * The input, cut at its first NUL, is the options string. Invariants:
 *   - failure: ST_EINVAL with a message, and the options struct is unchanged;
 *   - success: cube, colorspace in their enums; face_size 0, or a power of two 1..32768 given
 *     with cube=latlong only; the texture name "" or 1..255 bytes without a space; every field
 *     outside the grammar (format, six_conv, caps, ...) unchanged;
 *   - parse(serialise(o)) == o: the options written back in canonical form parse to the same
 *     fields and texture name.
 * Seeds: tests/fuzz/seeds/fuzz_options/. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "import.h"

/* an invariant: on failure, names it and stops (libFuzzer keeps the input) */
#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char *const KIND[] = {"none", "auto", "strip_v", "strip_h", "cross_h", "cross_v",
                                   "latlong", NULL, "ptex"};
static const char *const CS[] = {"auto", "linear", "srgb"};

static void sentinel(st_import_opts *o)
{
    st_import_opts_init(o);
    o->format = ST_FMT_IMAGE;
    o->six_conv = 1;
    o->cube = ST_IMPORT_CUBE_STRIP_H;
    o->colorspace = ST_IMPORT_CS_SRGB;
    o->face_size = 64;
    o->max_bytes = 12345;
    o->max_dim = 77;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    CHECK(text != NULL);
    memcpy(text, data, size);
    text[size] = 0;

    st_import_opts o, before;
    sentinel(&o);
    before = o;
    char tex[256];
    st_error e;
    memset(&e, 0, sizeof e);
    int rc = st_import_opts_parse(text, &o, tex, sizeof tex, &e);
    if (rc != ST_OK) {
        CHECK(rc == ST_EINVAL);
        CHECK(e.msg[0] != 0);
        CHECK(!memcmp(&o, &before, sizeof o));
        free(text);
        return 0;
    }
    CHECK(o.cube <= ST_IMPORT_CUBE_PTEX && o.cube != ST_IMPORT_CUBE_SIX);
    CHECK(o.colorspace <= ST_IMPORT_CS_SRGB);
    if (o.face_size != before.face_size) {
        CHECK(o.face_size == 0 || o.cube == ST_IMPORT_CUBE_LATLONG);
        CHECK(o.face_size <= 32768 && (o.face_size & (o.face_size - 1)) == 0);
    }
    size_t tl = strnlen(tex, sizeof tex);
    CHECK(tl < sizeof tex && tl <= 255 && !memchr(tex, ' ', tl));
    CHECK(o.format == before.format && o.six_conv == before.six_conv &&
          o.max_bytes == before.max_bytes && o.max_dim == before.max_dim &&
          o.texture == before.texture && o.texture_path == before.texture_path);

    /* canonical form: the keys that were given (a key left out keeps the old value, so the
     * serialised form names every field that differs from the sentinel) */
    char canon[400];
    int n = snprintf(canon, sizeof canon, "cube=%s", KIND[o.cube]);
    if (o.cube == ST_IMPORT_CUBE_LATLONG && o.face_size)
        n += snprintf(canon + n, sizeof canon - (size_t)n, ":%u", o.face_size);
    n += snprintf(canon + n, sizeof canon - (size_t)n, " colorspace=%s", CS[o.colorspace]);
    if (tl)
        n += snprintf(canon + n, sizeof canon - (size_t)n, " texture=%s", tex);
    CHECK(n > 0 && (size_t)n < sizeof canon);
    st_import_opts back;
    sentinel(&back);
    char tex2[256];
    if (st_import_opts_parse(canon, &back, tex2, sizeof tex2, &e) != ST_OK) {
        fprintf(stderr, "canonical form refused: '%s': %s\n", canon, e.msg);
        __builtin_trap();
    }
    /* cube= without a size resets face_size to 0, as the original parse did when cube was
     * given; when it was not, face_size kept the sentinel's 64 and the canonical form's
     * cube=strip_h (the sentinel's kind) resets it */
    if (o.face_size == before.face_size && o.cube != ST_IMPORT_CUBE_LATLONG)
        back.face_size = o.face_size;
    CHECK(!memcmp(&back, &o, sizeof o));
    CHECK(!strcmp(tex2, tex));
    free(text);
    return 0;
}
