/* tests/unit/test_export.c - every kind of set is fetchable in a standard format that imports
 * back as an equivalent set (store/import/export.h): per-face and cube sets as .ptx (a cube as
 * a Ptex environment cube), float cubes as an OpenEXR cube, atlas images at their precision
 * (PNG / EXR) and atlas meshes as OBJ, BC1 sets as DDS. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>

#include "atlas.h"
#include "bc1.h"
#include "cube.h"
#include "export.h"
#include "half.h"
#include "image_io.h"
#include "import.h"
#include "mesh.h"
#include "../common/testdata.h"

static char tmpdir[256];

static int setup(void **state)
{
    (void)state;
    return st_test_mkdtemp(tmpdir, sizeof tmpdir, "test_export");
}

static int teardown(void **state)
{
    (void)state;
    return st_test_rmtree(tmpdir);
}

/* Exports s as `format`, writes the bytes to <tmpdir>/<name>, imports that file (o may be
 * NULL) and returns the new set. */
static st_set *round_trip(const st_set *s, int format, const char *name, const st_import_opts *o)
{
    void *buf = NULL;
    size_t len = 0;
    st_error e;
    st_error_clear(&e);
    int rc = st_export_mem(s, format, tmpdir, &buf, &len, &e);
    if (rc)
        print_message("export %s: %s\n", name, e.msg);
    assert_int_equal(rc, ST_OK);
    assert_true(len > 0);
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(buf, 1, len, f), len);
    fclose(f);
    free(buf);
    st_set *r = NULL;
    rc = st_import_file(path, o, &r, &e);
    if (rc)
        print_message("import %s: %s\n", name, e.msg);
    assert_int_equal(rc, ST_OK);
    return r;
}

/* Same kind, texel type, channels and faces, and level 0 of every face bit for bit. */
static void assert_same_texels(const st_set *a, const st_set *b)
{
    assert_int_equal(a->info.kind, b->info.kind);
    assert_int_equal(a->info.dtype, b->info.dtype);
    assert_int_equal(a->info.nchan, b->info.nchan);
    assert_int_equal(a->info.nfaces, b->info.nfaces);
    assert_int_equal(a->info.colorspace, b->info.colorspace);
    size_t ts = st_texel_size(a);
    for (uint32_t f = 0; f < a->info.nfaces; f++) {
        const st_face *A = &a->faces[f], *B = &b->faces[f];
        assert_int_equal(A->w, B->w);
        assert_int_equal(A->h, B->h);
        int ca = (A->flags & ST_FACE_CONSTANT) != 0, cb = (B->flags & ST_FACE_CONSTANT) != 0;
        const uint8_t *pa = st_face_level(a, f, 0), *pb = st_face_level(b, f, 0);
        for (size_t t = 0; t < (size_t)A->w * A->h; t++)
            assert_memory_equal(pa + (ca ? 0 : t * ts), pb + (cb ? 0 : t * ts), ts);
    }
}

static st_set *import_shared(const char *rel, const st_import_opts *o)
{
    char path[1024];
    if (st_test_data_path(path, sizeof path, rel))
        return NULL;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(path, o, &s, &e), ST_OK);
    return s;
}

static void formats_fit_the_set_kinds(void **state)
{
    (void)state;
    st_set *c = import_shared("env/StageEnvCube.exr", NULL);
    if (!c)
        skip();
    assert_int_equal(c->info.kind, ST_KIND_CUBE);
    assert_int_equal(st_export_formats(c), 1u << ST_EXPORT_PTX | 1u << ST_EXPORT_EXR);
    void *buf = NULL;
    size_t len = 0;
    st_error e;
    assert_int_equal(st_export_mem(c, ST_EXPORT_DDS, tmpdir, &buf, &len, &e), ST_EUNSUPPORTED);
    assert_null(buf);
    assert_non_null(strstr(e.msg, "ptx exr"));
    assert_int_equal(st_export_mem(c, 99, tmpdir, &buf, &len, &e), ST_EUNSUPPORTED);
    st_set_free(c);
}

static void a_cube_comes_back_from_a_ptex_env_cube_and_an_exr_cube(void **state)
{
    (void)state;
    st_set *c = import_shared("env/StageEnvCube.exr", NULL);
    if (!c)
        skip();
    st_set *r = round_trip(c, ST_EXPORT_PTX, "cube.ptx", NULL);
    assert_same_texels(c, r);
    st_set_free(r);
    r = round_trip(c, ST_EXPORT_EXR, "cube.exr", NULL);
    assert_same_texels(c, r);
    st_set_free(r);
    st_set_free(c);
    /* an 8-bit cube (six JPEG faces) goes as a Ptex env cube at its precision */
    char pat[1024];
    if (st_test_data_path(pat, sizeof pat, "cube/humus-6face/+x.jpg"))
        skip();
    strcpy(strrchr(pat, '/') + 1, "%s.jpg");
    st_import_opts o;
    st_import_opts_init(&o);
    o.cube = ST_IMPORT_CUBE_SIX;
    st_error e;
    assert_int_equal(st_import_file(pat, &o, &c, &e), ST_OK);
    assert_int_equal(c->info.dtype, ST_DT_U8);
    assert_int_equal(st_export_formats(c), 1u << ST_EXPORT_PTX);
    r = round_trip(c, ST_EXPORT_PTX, "cube8.ptx", NULL);
    assert_same_texels(c, r);
    st_set_free(r);
    st_set_free(c);
}

static void an_atlas_comes_back_as_its_image_and_its_mesh(void **state)
{
    (void)state;
    char obj[1024], png[1024];
    if (st_test_data_path(obj, sizeof obj, "meshes/duck/Duck.obj") ||
        st_test_data_path(png, sizeof png, "meshes/duck/DuckCM.png"))
        skip();
    st_set *a = import_shared("meshes/duck/Duck.obj", NULL);
    assert_int_equal(a->info.kind, ST_KIND_ATLAS);
    assert_int_equal(st_export_formats(a), 1u << ST_EXPORT_PNG | 1u << ST_EXPORT_OBJ);
    st_set *img = round_trip(a, ST_EXPORT_PNG, "duck.png", NULL);
    assert_same_texels(a, img);
    st_import_opts o;
    st_import_opts_init(&o);
    o.texture = img;
    st_set *m = round_trip(a, ST_EXPORT_OBJ, "duck.obj", &o);
    assert_same_texels(a, m);
    const st_atlas *x = st_atlas_get(a), *y = st_atlas_get(m);
    assert_non_null(y);
    assert_non_null(y->mesh);
    assert_int_equal(x->mesh->ntri, y->mesh->ntri);
    assert_int_equal(x->mesh->seams->nseams, y->mesh->seams->nseams);
    assert_int_equal(x->mask_w, y->mask_w);
    assert_memory_equal(x->chart_mask, y->chart_mask, (size_t)x->mask_w * x->mask_h);
    for (size_t i = 0; i < (size_t)x->mesh->npos * 3; i++)
        assert_true(x->mesh->pos[i] == y->mesh->pos[i]);
    st_set_free(m);
    st_set_free(img);
    st_set_free(a);
}

static void a_float_atlas_image_comes_back_as_exr(void **state)
{
    (void)state;
    st_set *a = import_shared("env/forest.exr", NULL);
    if (!a)
        skip();
    if (a->info.kind != ST_KIND_ATLAS)
        skip();
    assert_true(a->info.dtype == ST_DT_HALF || a->info.dtype == ST_DT_F32);
    assert_int_equal(st_export_formats(a), 1u << ST_EXPORT_EXR);
    st_set *r = round_trip(a, ST_EXPORT_EXR, "forest.exr", NULL);
    assert_same_texels(a, r);
    st_set_free(r);
    st_set_free(a);
}

/* imp34: a half grey + alpha atlas went out as an EXR of channels R, G (OpenImageIO's default
 * names for two channels), which uploads back as two channels without alpha and not
 * premultiplied: not an equivalent set. It goes out as Y, A now; a 2-channel set without
 * alpha stays R, G and comes back without one. */
static void a_grey_alpha_exr_comes_back_with_its_alpha(void **state)
{
    (void)state;
    enum { W = 8, H = 4 };
    uint16_t px[W * H * 2];
    for (int i = 0; i < W * H * 2; i++)
        px[i] = st_float_to_half((float)i / 64.0f);
    for (int alpha = -1; alpha <= 1; alpha += 2) {
        st_image img = {.w = W, .h = H, .nchan = 2, .dtype = ST_DT_HALF,
                        .colorspace = ST_CS_LINEAR, .alpha_chan = (int8_t)alpha,
                        .premultiplied = alpha >= 0, .nlevels_file = 1, .data = px};
        st_set *a = NULL;
        st_error e;
        st_error_clear(&e);
        assert_int_equal(st_atlas_from_image(&img, NULL, 0, &a, &e), ST_OK);
        st_set *r = round_trip(a, ST_EXPORT_EXR, "ya.exr", NULL);
        if (r->info.alpha_chan != alpha)
            print_message("alpha %d came back as %d\n", alpha, r->info.alpha_chan);
        assert_int_equal(r->info.alpha_chan, alpha);
        assert_int_equal(r->info.premultiplied, alpha >= 0);
        assert_same_texels(a, r);
        st_set_free(r);
        st_set_free(a);
    }
}

/* Exports s as `format` with the process's local clock set to the time zone tz (OpenImageIO
 * 2.4 stamps an EXR it is not given a date for with the local time: two zones are two
 * clocks, without waiting for one to tick) and returns the bytes. */
static void *export_in_zone(const st_set *s, int format, const char *tz, size_t *len)
{
    setenv("TZ", tz, 1);
    tzset();
    void *buf = NULL;
    st_error e;
    st_error_clear(&e);
    int rc = st_export_mem(s, format, tmpdir, &buf, len, &e);
    if (rc)
        print_message("export in %s: %s\n", tz, e.msg);
    assert_int_equal(rc, ST_OK);
    return buf;
}

/* The EXR written for a set is a function of the set (PROTOCOL.md 4.10: FETCH is byte-stable):
 * two exports with clocks 5 h and 1.1 s apart give the same bytes, whose header's capDate
 * is empty, and the file still imports as the set. An atlas image written here (always run),
 * and the shared float cube when the data is there. */
static void an_exr_export_is_the_same_bytes_whatever_the_clock(void **state)
{
    (void)state;
    enum { W = 16, H = 8 };
    uint16_t px[W * H * 4];
    for (unsigned i = 0; i < W * H * 4; i++)
        px[i] = (uint16_t)(0x3c00 + (i * 37u) % 1024u); /* halves in [1, 2) */
    char src[512];
    snprintf(src, sizeof src, "%s/stable_src.exr", tmpdir);
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_image_write(src, W, H, 4, ST_DT_HALF, px, &e), ST_OK);
    st_set *sets[2] = {NULL, NULL};
    assert_int_equal(st_import_file(src, NULL, &sets[0], &e), ST_OK);
    assert_int_equal(sets[0]->info.kind, ST_KIND_ATLAS);
    sets[1] = import_shared("env/StageEnvCube.exr", NULL);
    for (int k = 0; k < 2 && sets[k]; k++) {
        size_t la = 0, lb = 0, lc = 0;
        void *a = export_in_zone(sets[k], ST_EXPORT_EXR, "UTC0", &la);
        void *b = export_in_zone(sets[k], ST_EXPORT_EXR, "EST5", &lb);
        struct timespec pause = {1, 100000000};
        nanosleep(&pause, NULL);
        void *c = export_in_zone(sets[k], ST_EXPORT_EXR, "UTC0", &lc);
        unsetenv("TZ");
        tzset();
        assert_int_equal(la, lb);
        assert_memory_equal(a, b, la);
        assert_int_equal(la, lc);
        assert_memory_equal(a, c, la);
        /* the header's capDate, if any, is empty: name, type "string", a 4-byte size of 0 (the
         * header ends well before 4 KiB here) */
        static const char cap[] = "capDate\0string";
        size_t head = la < 4096 ? la : 4096;
        for (size_t i = 0; i + sizeof cap + 4 <= head; i++)
            if (!memcmp((const char *)a + i, cap, sizeof cap))
                assert_memory_equal((const char *)a + i + sizeof cap, "\0\0\0\0", 4);
        free(b);
        free(c);
        char path[512];
        snprintf(path, sizeof path, "%s/stable_%d.exr", tmpdir, k);
        FILE *f = fopen(path, "wb");
        assert_non_null(f);
        assert_int_equal(fwrite(a, 1, la, f), la);
        fclose(f);
        free(a);
        st_set *r = NULL;
        assert_int_equal(st_import_file(path, NULL, &r, &e), ST_OK);
        assert_same_texels(sets[k], r);
        st_set_free(r);
    }
    st_set_free(sets[0]);
    st_set_free(sets[1]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(formats_fit_the_set_kinds),
        cmocka_unit_test(a_cube_comes_back_from_a_ptex_env_cube_and_an_exr_cube),
        cmocka_unit_test(an_atlas_comes_back_as_its_image_and_its_mesh),
        cmocka_unit_test(a_float_atlas_image_comes_back_as_exr),
        cmocka_unit_test(a_grey_alpha_exr_comes_back_with_its_alpha),
        cmocka_unit_test(an_exr_export_is_the_same_bytes_whatever_the_clock),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
