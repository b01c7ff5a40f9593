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
#include <cmocka.h>

#include "atlas.h"
#include "bc1.h"
#include "cube.h"
#include "export.h"
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(formats_fit_the_set_kinds),
        cmocka_unit_test(a_cube_comes_back_from_a_ptex_env_cube_and_an_exr_cube),
        cmocka_unit_test(an_atlas_comes_back_as_its_image_and_its_mesh),
        cmocka_unit_test(a_float_atlas_image_comes_back_as_exr),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
