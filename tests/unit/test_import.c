/* tests/unit/test_import.c - the import dispatcher and its readers: every shared asset that
 * should import does (kind, size, channels, precision), the ones that should fail fail with
 * the right code; EXR channel order, precision round trips, OBJ features, hostile inputs
 * (truncated files, huge dimensions, caps, NaN UVs, indices out of range). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>
#include <OpenEXR/openexr.h>
#include <cmocka.h>

#include "atlas.h"
#include "bc1.h"
#include "cube.h"
#include "exr.h"
#include "image.h"
#include "import.h"
#include "mesh.h"
#include "mesh_io.h"
#include "../common/testdata.h"
#include "image_io.h"
#include "mesh_io.h"

static char tmpdir[256];

static int setup(void **state)
{
    (void)state;
    return st_test_mkdtemp(tmpdir, sizeof tmpdir, "test_import");
}

static int teardown(void **state)
{
    (void)state;
    return st_test_rmtree(tmpdir);
}

static void tmp_path(char *buf, size_t cap, const char *name)
{
    snprintf(buf, cap, "%s/%s", tmpdir, name);
}

static void write_file(const char *path, const void *data, size_t len)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, len, f), len);
    fclose(f);
}

static void *read_file(const char *path, size_t *len)
{
    void *b = st_test_read_file(path, len);
    assert_non_null(b);
    return b;
}

typedef struct asset {
    const char *rel;
    int rc;             /* expected st_import_file result */
    int kind;
    uint32_t w, h;      /* face 0 */
    unsigned nchan, dtype, nfaces;
} asset;

static const asset ASSETS[] = {
    {"images/astronaut.png", 0, ST_KIND_ATLAS, 512, 512, 3, ST_DT_U8, 1},
    {"images/brick.png", 0, ST_KIND_ATLAS, 512, 512, 1, ST_DT_U8, 1},
    {"images/StillLife.jpg", 0, ST_KIND_ATLAS, 1240, 846, 3, ST_DT_U8, 1},
    {"images/bc1-set/kodim01.png", 0, ST_KIND_ATLAS, 768, 512, 3, ST_DT_U8, 1},
    {"images/bc1-set/colobot_apollo.png", 0, ST_KIND_ATLAS, 1024, 1024, 3, ST_DT_U8, 1},
    {"cube/humus-6face/+x.jpg", 0, ST_KIND_ATLAS, 512, 512, 3, ST_DT_U8, 1},
    {"env/StageEnvLatLong.exr", 0, ST_KIND_ATLAS, 1000, 500, 3, ST_DT_HALF, 1},
    {"env/StageEnvCube.exr", 0, ST_KIND_CUBE, 256, 256, 3, ST_DT_HALF, 6},
    {"env/WavyLinesLatLong.exr", 0, ST_KIND_ATLAS, 1024, 512, 3, ST_DT_HALF, 1},
    {"env/WavyLinesCube.exr", 0, ST_KIND_CUBE, 256, 256, 3, ST_DT_HALF, 6},
    {"env/OrientationLatLong.exr", 0, ST_KIND_ATLAS, 1024, 512, 4, ST_DT_HALF, 1},
    {"env/OrientationCube.exr", 0, ST_KIND_CUBE, 512, 512, 4, ST_DT_HALF, 6},
    {"env/forest.exr", 0, ST_KIND_ATLAS, 1024, 512, 3, ST_DT_F32, 1},
    {"env/converted/forest.hdr", 0, ST_KIND_ATLAS, 1024, 512, 3, ST_DT_F32, 1},
    {"meshes/duck/Duck.obj", 0, ST_KIND_ATLAS, 512, 512, 3, ST_DT_U8, 1},
    {"meshes/waterbottle/WaterBottle.obj", 0, ST_KIND_ATLAS, 2048, 2048, 3, ST_DT_U8, 1},
    {"meshes/cesiummilktruck/CesiumMilkTruck.obj", 0, ST_KIND_ATLAS, 2048, 2048, 3, ST_DT_U8, 1},
    {"meshes/spider/spider.obj", 0, ST_KIND_ATLAS, 250, 250, 3, ST_DT_U8, 1},
    {"ptx/wdas-ptex-samples/envcube/envcube.ptx", 0, ST_KIND_CUBE, 128, 128, 3, ST_DT_U16, 6},
    {"ptx/wdas-ptex-samples/teapot/teapot.ptx", 0, ST_KIND_PERFACE, 0, 0, 1, ST_DT_U8, 448},
    {"ptex-ref/cube1_k6_u8.ptx", 0, ST_KIND_PERFACE, 64, 64, 4, ST_DT_U8, 6}, /* a model, not an env */
    {"drc/bunny_gltf.drc", ST_ENOUV, 0, 0, 0, 0, 0, 0},
    {"ptx/wdas-ptex-2009/cube/cube.obj", ST_ENOUV, 0, 0, 0, 0, 0, 0},
    {"drc/cube_att.drc", ST_EINVAL, 0, 0, 0, 0, 0, 0},  /* a mesh with no texture to pair */
};

static void shared_assets_import_or_fail_as_expected(void **state)
{
    (void)state;
    char path[1024];
    for (size_t i = 0; i < sizeof ASSETS / sizeof ASSETS[0]; i++) {
        const asset *a = &ASSETS[i];
        if (st_test_data_path(path, sizeof path, a->rel))
            skip();
        st_set *s = NULL;
        st_error e;
        st_error_clear(&e);
        int rc = st_import_file(path, NULL, &s, &e);
        print_message("%-45s -> %s%s%s\n", a->rel, rc ? st_strerror(rc) : "ok", rc ? ": " : "",
                      rc ? e.msg : "");
        assert_int_equal(rc, a->rc);
        if (rc) {
            assert_null(s);
            assert_true(strlen(e.msg) > 10);
            continue;
        }
        assert_int_equal(s->info.kind, a->kind);
        assert_int_equal(s->info.nfaces, a->nfaces);
        assert_int_equal(s->info.nchan, a->nchan);
        assert_int_equal(s->info.dtype, a->dtype);
        if (a->w) {
            assert_int_equal(s->faces[0].w, a->w);
            assert_int_equal(s->faces[0].h, a->h);
        }
        const st_meta_entry *m = st_set_meta_find(s, "seamtex:source_format");
        assert_non_null(m);
        st_set_free(s);
    }
}

static void colour_space_is_stated_and_can_be_overridden(void **state)
{
    (void)state;
    char png[1024], exr[1024];
    if (st_test_data_path(png, sizeof png, "images/astronaut.png") ||
        st_test_data_path(exr, sizeof exr, "env/StageEnvLatLong.exr"))
        skip();
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(png, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.colorspace, ST_CS_SRGB);
    st_set_free(s);
    assert_int_equal(st_import_file(exr, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.colorspace, ST_CS_LINEAR);
    st_set_free(s);
    st_import_opts o;
    st_import_opts_init(&o);
    o.colorspace = ST_IMPORT_CS_LINEAR;
    assert_int_equal(st_import_file(png, &o, &s, &e), ST_OK);
    assert_int_equal(s->info.colorspace, ST_CS_LINEAR);
    st_set_free(s);
}

static void exr_channels_come_in_rgba_order_from_the_c_api(void **state)
{
    (void)state;
    /* a 4-channel half EXR with a different constant per channel, written by OIIO */
    char path[512];
    tmp_path(path, sizeof path, "rgba_half.exr");
    enum { W = 37, H = 21 };
    static uint16_t px[W * H * 4];
    const float val[4] = {0.125f, 0.25f, 0.5f, 1.0f};
    for (int i = 0; i < W * H; i++)
        for (int c = 0; c < 4; c++)
            px[i * 4 + c] = st_float_to_half(val[c] + (float)(i % 7) / 64.0f);
    st_error e;
    assert_int_equal(st_image_write(path, W, H, 4, ST_DT_HALF, px, &e), ST_OK);
    st_image img;
    assert_int_equal(st_exr_read(path, NULL, &img, &e), ST_OK);
    assert_int_equal(img.w, W);
    assert_int_equal(img.h, H);
    assert_int_equal(img.nchan, 4);
    assert_int_equal(img.dtype, ST_DT_HALF);
    assert_int_equal(img.alpha_chan, 3);
    assert_memory_equal(img.data, px, sizeof px);
    st_image_free(&img);
}

/* Writes a w x h scanline EXR (no compression) through the OpenEXR C API with the given
 * half channels; values[c] is channel c's constant plus x / 64; channel c sampled every
 * samp[c] pixels in x and y (samp NULL: every pixel; w, h multiples of it). */
static void write_exr_sampled(const char *path, int w, int h, int nch, const char *const *names,
                              const float *values, const int *samp)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_context_t ctx = NULL;
    int part = 0;
    assert_int_equal(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init), EXR_ERR_SUCCESS);
    assert_int_equal(exr_add_part(ctx, "main", EXR_STORAGE_SCANLINE, &part), EXR_ERR_SUCCESS);
    assert_int_equal(exr_initialize_required_attr_simple(ctx, part, w, h, EXR_COMPRESSION_NONE),
                     EXR_ERR_SUCCESS);
    for (int c = 0; c < nch; c++)
        assert_true(exr_add_channel(ctx, part, names[c], EXR_PIXEL_HALF,
                                    EXR_PERCEPTUALLY_LOGARITHMIC, samp ? samp[c] : 1,
                                    samp ? samp[c] : 1) == EXR_ERR_SUCCESS);
    assert_int_equal(exr_write_header(ctx), EXR_ERR_SUCCESS);
    /* the C API keeps channels sorted by name: fill each by its name */
    const exr_attr_chlist_t *chl = NULL;
    assert_int_equal(exr_get_channels(ctx, part, &chl), EXR_ERR_SUCCESS);
    uint16_t *rows = calloc((size_t)w * 8, sizeof *rows);
    assert_non_null(rows);
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    for (int y = 0; y < h; y++) {
        exr_chunk_info_t ci;
        assert_int_equal(exr_write_scanline_chunk_info(ctx, part, y, &ci), EXR_ERR_SUCCESS);
        if (y == 0)
            assert_int_equal(exr_encoding_initialize(ctx, part, &ci, &enc), EXR_ERR_SUCCESS);
        else
            assert_int_equal(exr_encoding_update(ctx, part, &ci, &enc), EXR_ERR_SUCCESS);
        for (int k = 0; k < enc.channel_count; k++) {
            int c = 0;
            while (c < nch && strcmp(names[c], chl->entries[k].name.str))
                c++;
            for (int x = 0; x < w; x++)
                rows[k * w + x] = st_float_to_half(values[c] + (float)x / 64.0f);
            enc.channels[k].encode_from_ptr = (const uint8_t *)(rows + k * w);
            enc.channels[k].user_pixel_stride = 2 * enc.channels[k].x_samples;
            enc.channels[k].user_line_stride = 2 * w;
        }
        assert_int_equal(exr_encoding_choose_default_routines(ctx, part, &enc), EXR_ERR_SUCCESS);
        assert_int_equal(exr_encoding_run(ctx, part, &enc), EXR_ERR_SUCCESS);
    }
    exr_encoding_destroy(ctx, &enc);
    assert_int_equal(exr_finish(&ctx), EXR_ERR_SUCCESS);
    free(rows);
}

static void write_exr_channels(const char *path, int w, int h, int nch, const char *const *names,
                               const float *values)
{
    write_exr_sampled(path, w, h, nch, names, values, NULL);
}

static void exr_takes_rgba_by_name_from_extra_channels_and_layers(void **state)
{
    (void)state;
    enum { W = 16, H = 4 };
    char p[512];
    st_error e;
    st_image img;
    /* R,G,B,A plus a depth channel: Z is left out, the order is R,G,B,A */
    const char *n1[5] = {"Z", "A", "B", "G", "R"};
    const float v1[5] = {9.0f, 0.75f, 0.5f, 0.25f, 0.125f};
    tmp_path(p, sizeof p, "rgbaz.exr");
    write_exr_channels(p, W, H, 5, n1, v1);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 4);
    assert_int_equal(img.alpha_chan, 3);
    const uint16_t *d = img.data;
    assert_float_equal(st_half_to_float(d[0]), 0.125f, 1e-3);
    assert_float_equal(st_half_to_float(d[1]), 0.25f, 1e-3);
    assert_float_equal(st_half_to_float(d[2]), 0.5f, 1e-3);
    assert_float_equal(st_half_to_float(d[3]), 0.75f, 1e-3);
    assert_float_equal(st_half_to_float(d[4 * 5 + 0]), 0.125f + 5.0f / 64.0f, 1e-3);
    st_image_free(&img);
    /* a layered file: diffuse.R/G/B beside specular.R/G/B */
    const char *n2[6] = {"specular.R", "specular.G", "specular.B", "diffuse.B", "diffuse.G",
                         "diffuse.R"};
    const float v2[6] = {7, 8, 9, 0.3f, 0.2f, 0.1f};
    tmp_path(p, sizeof p, "layers.exr");
    write_exr_channels(p, W, H, 6, n2, v2);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 3);
    assert_int_equal(img.alpha_chan, -1);
    d = img.data;
    assert_float_equal(st_half_to_float(d[0]), 0.1f, 1e-3);
    assert_float_equal(st_half_to_float(d[1]), 0.2f, 1e-3);
    assert_float_equal(st_half_to_float(d[2]), 0.3f, 1e-3);
    st_image_free(&img);
    /* luminance only */
    const char *n3[2] = {"Y", "Z"};
    const float v3[2] = {0.5f, 3.0f};
    tmp_path(p, sizeof p, "y.exr");
    write_exr_channels(p, W, H, 2, n3, v3);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 1);
    assert_float_equal(st_half_to_float(((const uint16_t *)img.data)[0]), 0.5f, 1e-3);
    st_image_free(&img);
}

static void exr_c_api_matches_openimageio_on_the_orientation_maps(void **state)
{
    (void)state;
    const char *rel[] = {"env/OrientationCube.exr", "env/OrientationLatLong.exr",
                         "env/StageEnvCube.exr"};
    for (int i = 0; i < 3; i++) {
        char path[1024];
        if (st_test_data_path(path, sizeof path, rel[i]))
            skip();
        st_image a, b;
        st_error e;
        assert_int_equal(st_exr_read(path, NULL, &a, &e), ST_OK);
        assert_int_equal(st_image_read(path, NULL, &b, &e), ST_OK);
        assert_int_equal(a.w, b.w);
        assert_int_equal(a.h, b.h);
        assert_int_equal(a.nchan, b.nchan);
        assert_int_equal(a.dtype, b.dtype);
        assert_int_equal(a.envmap, ST_ENVMAP_NONE + (strstr(rel[i], "Cube") ? 2 : 1));
        assert_true(a.nlevels_file > 1); /* tiled, mip-mapped */
        assert_memory_equal(a.data, b.data, (size_t)a.w * a.h * a.nchan * 2);
        st_image_free(&a);
        st_image_free(&b);
    }
}

static void precision_is_kept_for_16_bit_and_float(void **state)
{
    (void)state;
    enum { W = 16, H = 8 };
    uint16_t u16[W * H * 3];
    float f32[W * H * 2];
    for (int i = 0; i < W * H * 3; i++)
        u16[i] = (uint16_t)(i * 397 + 1);
    for (int i = 0; i < W * H * 2; i++)
        f32[i] = 1000.0f + (float)i * 0.001f;
    char p16[512], pf[512];
    tmp_path(p16, sizeof p16, "u16.png");
    tmp_path(pf, sizeof pf, "f32.exr");
    st_error e;
    assert_int_equal(st_image_write(p16, W, H, 3, ST_DT_U16, u16, &e), ST_OK);
    assert_int_equal(st_image_write(pf, W, H, 2, ST_DT_F32, f32, &e), ST_OK);
    st_set *s = NULL;
    assert_int_equal(st_import_file(p16, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.dtype, ST_DT_U16);
    assert_memory_equal(st_face_level(s, 0, 0), u16, sizeof u16);
    st_set_free(s);
    st_image img;
    assert_int_equal(st_image_read_any(pf, NULL, &img, &e), ST_OK);
    assert_int_equal(img.dtype, ST_DT_F32);
    assert_int_equal(img.nchan, 2);
    assert_memory_equal(img.data, f32, sizeof f32);
    st_image_free(&img);
}

static void png_writer_round_trips_8_bit_and_refuses_dds(void **state)
{
    (void)state;
    enum { W = 13, H = 7 };
    uint8_t px[W * H * 4];
    for (int i = 0; i < W * H * 4; i++)
        px[i] = (uint8_t)(i * 31);
    char p[512], d[512];
    tmp_path(p, sizeof p, "rgba8.png");
    tmp_path(d, sizeof d, "x.dds");
    st_error e;
    assert_int_equal(st_image_write(p, W, H, 4, ST_DT_U8, px, &e), ST_OK);
    st_image img;
    assert_int_equal(st_image_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 4);
    assert_int_equal(img.alpha_chan, 3);
    assert_memory_equal(img.data, px, sizeof px);
    st_image_free(&img);
    assert_int_equal(st_image_write(d, W, H, 4, ST_DT_U8, px, &e), ST_EUNSUPPORTED);
}

static void obj_reader_handles_polygons_negative_indices_groups_and_materials(void **state)
{
    (void)state;
    const char *obj =
        "# comment\r\n"
        "mtllib m.mtl\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "vn 0 0 1\n"
        "g first\nusemtl red\n"
        "f 1/1/1 2/2/1 3/3/1 4/4/1\n"          /* quad -> 2 triangles */
        "g second\nusemtl tex\n"
        "f -4/-4 -3/-3 \\\n -1/-1\n"           /* relative indices, continued line */
        "f 2//1 5//1 3//1\n";                  /* no UVs */
    const char *mtl = "newmtl red\nKd 1 0 0\nnewmtl tex\nmap_Kd -s 1 1 1 .\\sub\\t.png\n";
    char mp[512];
    tmp_path(mp, sizeof mp, "m.mtl");
    write_file(mp, mtl, strlen(mtl));
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_obj_read_mem(obj, strlen(obj), tmpdir, NULL, &m, &e), ST_OK);
    assert_int_equal(m->ntri, 4);
    assert_int_equal(m->nfaces_src, 3);
    assert_int_equal(m->ntri_nouv, 1);
    assert_int_equal(m->tri_face[1], 0);
    /* relative: -4 of 5 vertices is vertex 2 (index 1) */
    assert_int_equal(m->tri_pos[6], 1);
    assert_int_equal(m->tri_uv[6], 0);
    assert_int_equal(m->tri_pos[8], 4);
    assert_int_equal(m->tri_uv[9], ST_MESH_NO_UV);
    assert_string_equal(m->mats[m->tri_mat[0]].name, "red");
    assert_string_equal(m->mats[m->tri_mat[2]].name, "tex");
    char want[600];
    snprintf(want, sizeof want, "%s/sub/t.png", tmpdir);
    assert_string_equal(m->mats[m->tri_mat[2]].map_kd, want);
    /* vt v is flipped into texture space */
    assert_float_equal(m->uv[3 * 2 + 1], 0.0f, 1e-6); /* vt 0 1 -> v = 0 */
    st_mesh_free(m);
}

static void mtl_paths_outside_the_mesh_folder_are_not_followed(void **state)
{
    (void)state;
    const char *mtl = "newmtl up\nmap_Kd ..\\..\\etc\\x.png\nnewmtl abs\nmap_Kd /etc/x.png\n"
                      "newmtl drive\nmap_Kd C:\\tex\\x.png\nnewmtl ok\nmap_Kd sub/a..b.png\n";
    char mp[512];
    tmp_path(mp, sizeof mp, "paths.mtl");
    write_file(mp, mtl, strlen(mtl));
    const char *obj = "mtllib paths.mtl\nmtllib ../outside.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                      "usemtl up\nf 1 2 3\nusemtl abs\nf 1 2 3\nusemtl drive\nf 1 2 3\nusemtl ok\nf 1 2 3\n";
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_obj_read_mem(obj, strlen(obj), tmpdir, NULL, &m, &e), ST_OK);
    assert_string_equal(m->mats[m->tri_mat[0]].map_kd, "");
    assert_string_equal(m->mats[m->tri_mat[1]].map_kd, "");
    assert_string_equal(m->mats[m->tri_mat[2]].map_kd, "");
    assert_non_null(strstr(m->mats[m->tri_mat[3]].map_kd, "/sub/a..b.png"));
    st_mesh_free(m);
}

static void obj_with_backslash_texture_path_imports_as_an_atlas(void **state)
{
    (void)state;
    char sub[512], tex[512], objp[512], mtlp[512];
    tmp_path(sub, sizeof sub, "tex");
    mkdir(sub, 0700);
    tmp_path(tex, sizeof tex, "tex/checker.png");
    uint8_t px[8 * 4 * 3];
    for (int i = 0; i < 8 * 4 * 3; i++)
        px[i] = (uint8_t)(i * 5);
    st_error e;
    assert_int_equal(st_image_write(tex, 8, 4, 3, ST_DT_U8, px, &e), ST_OK);
    tmp_path(objp, sizeof objp, "quad.obj");
    tmp_path(mtlp, sizeof mtlp, "quad.mtl");
    const char *obj = "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
                      "usemtl q\nf 1/1 2/2 3/3\n";
    const char *mtl = "newmtl q\nmap_Kd .\\tex\\checker.png\n";
    write_file(objp, obj, strlen(obj));
    write_file(mtlp, mtl, strlen(mtl));
    st_set *s = NULL;
    assert_int_equal(st_import_file(objp, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.kind, ST_KIND_ATLAS);
    assert_int_equal(s->faces[0].w, 8);   /* non-power-of-two atlas sizes are fine */
    assert_int_equal(s->faces[0].h, 4);
    const st_atlas *a = st_atlas_get(s);
    assert_non_null(a);
    assert_int_equal(a->mesh->ntri, 1);
    assert_memory_equal(st_face_level(s, 0, 0), px, sizeof px);
    st_set_free(s);
}

static void draco_duck_pairs_with_its_texture(void **state)
{
    (void)state;
    char drc[1024], png[1024];
    if (st_test_data_path(drc, sizeof drc, "drc/converted/Duck.drc") ||
        st_test_data_path(png, sizeof png, "meshes/duck/DuckCM.png"))
        skip();
    st_import_opts o;
    st_import_opts_init(&o);
    o.texture_path = png;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(drc, &o, &s, &e), ST_OK);
    const st_atlas *a = st_atlas_get(s);
    assert_non_null(a);
    assert_int_equal(a->mesh->seams->nseams, 166);
    /* the same with an already-imported texture set */
    st_set *t = NULL;
    assert_int_equal(st_import_file(png, NULL, &t, &e), ST_OK);
    st_import_opts_init(&o);
    o.texture = t;
    st_set *s2 = NULL;
    assert_int_equal(st_import_file(drc, &o, &s2, &e), ST_OK);
    assert_memory_equal(s2->texels, s->texels, s->texel_bytes);
    /* an environment map is no atlas texture, as a file as well as a set (the daemon's
     * texture= refuses a cube set; seamtex-render --inproc drew the strip as an atlas) */
    const char *envs[] = {"env/StageEnvCube.exr", "env/StageEnvLatLong.exr"};
    for (int i = 0; i < 2; i++) {
        char env[1024];
        if (st_test_data_path(env, sizeof env, envs[i]))
            continue;
        st_import_opts_init(&o);
        o.texture_path = env;
        st_set *s3 = NULL;
        assert_int_equal(st_import_file(drc, &o, &s3, &e), ST_EINVAL);
        assert_null(s3);
        printf("# %s\n", e.msg);
        assert_non_null(strstr(e.msg, i ? "envmap=latlong" : "envmap=cube"));
    }
    st_set_free(t);
    st_set_free(s2);
    st_set_free(s);
}

/* A 22-byte Draco edgebreaker header that declares 2^28 faces: refused from the header, before
 * Draco sizes its corner table from it (it allocated gigabytes; found by fuzz_draco). */
static void draco_header_declaring_too_many_faces_is_refused_before_decoding(void **state)
{
    (void)state;
    static const uint8_t drc[] = {'D', 'R', 'A', 'C', 'O', 2, 2, 1 /* mesh */, 1 /* edgebreaker */,
                                  0, 0, /* flags */ 0 /* traversal */, 3 /* vertices */,
                                  0x80, 0x80, 0x80, 0x80, 0x01 /* 2^28 faces */, 0 /* attr data */,
                                  0 /* symbols */, 0 /* split symbols */, 0};
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_draco_read_mem(drc, sizeof drc, NULL, &m, &e), ST_ETOOBIG);
    assert_null(m);
    assert_non_null(strstr(e.msg, "268435456 faces"));
    /* under small caps, a modest declared count is refused too */
    st_mesh_caps caps = {1000, 1000, 1u << 20, 0};
    static const uint8_t small[] = {'D', 'R', 'A', 'C', 'O', 2, 2, 1, 0 /* sequential */, 0, 0,
                                    0xd1, 0x0f /* 2001 faces */, 3 /* points */, 0};
    assert_int_equal(st_draco_read_mem(small, sizeof small, &caps, &m, &e), ST_ETOOBIG);
}

/* st_exr_read_mem (an OpenEXR memory stream) reads what st_exr_read reads from the file. */
static void exr_from_memory_matches_exr_from_the_file(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "mem.exr");
    enum { W = 9, H = 5 };
    static float px[W * H * 3];
    for (int i = 0; i < W * H * 3; i++)
        px[i] = (float)i / 7.0f;
    st_error e;
    assert_int_equal(st_image_write(path, W, H, 3, ST_DT_F32, px, &e), ST_OK);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    static uint8_t buf[1 << 16];
    size_t len = fread(buf, 1, sizeof buf, f);
    fclose(f);
    st_image a, b;
    assert_int_equal(st_exr_read(path, NULL, &a, &e), ST_OK);
    assert_int_equal(st_exr_read_mem(buf, len, "mem.exr", NULL, &b, &e), ST_OK);
    assert_int_equal(a.w, b.w);
    assert_int_equal(a.h, b.h);
    assert_int_equal(a.nchan, b.nchan);
    assert_int_equal(a.dtype, b.dtype);
    assert_memory_equal(a.data, b.data, (size_t)W * H * 3 * sizeof(float));
    st_image_free(&a);
    st_image_free(&b);
    /* cut short: refused, as the file is */
    assert_int_equal(st_exr_read_mem(buf, len / 2, "cut.exr", NULL, &b, &e), ST_EFORMAT);
    assert_null(b.data);
}

/* A failed image read leaves the caller's st_image empty, whatever it held (found by
 * fuzz_image: OIIO's error paths returned with the struct untouched). */
static void failed_image_reads_leave_the_image_empty(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "not_an_image.png");
    write_file(path, "\x89PNG\r\n\x1a\n garbage", 17);
    st_image img;
    st_error e;
    memset(&img, 0xa5, sizeof img);
    assert_int_not_equal(st_image_read(path, NULL, &img, &e), ST_OK);
    assert_null(img.data);
    memset(&img, 0xa5, sizeof img);
    assert_int_not_equal(st_image_read_any(path, NULL, &img, &e), ST_OK);
    assert_null(img.data);
    st_image_free(&img);
}

static void obj_nan_uv_and_out_of_range_indices_are_refused_naming_the_line(void **state)
{
    (void)state;
    const char *bad[] = {
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan 0\nf 1/1 2/1 3/1\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 inf\nf 1/1 2/1 3/1\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
        "v 0 0 0\nv 1 0 0\nf -5 1 2\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
        "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n",
        "# nothing\n",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        st_mesh *m = NULL;
        st_error e;
        st_error_clear(&e);
        int rc = st_obj_read_mem(bad[i], strlen(bad[i]), NULL, NULL, &m, &e);
        print_message("bad obj %zu: %s %s\n", i, st_strerror(rc), e.msg);
        assert_int_equal(rc, ST_EFORMAT);
        assert_null(m);
        if (i < 9)
            assert_non_null(strstr(e.msg, "line"));
    }
}

static void obj_over_the_caps_is_refused(void **state)
{
    (void)state;
    const char *obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n";
    st_mesh_caps c = {1, 0, 0, 0};
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_obj_read_mem(obj, strlen(obj), NULL, &c, &m, &e), ST_ETOOBIG);
    st_mesh_caps c2 = {0, 3, 0, 0};
    assert_int_equal(st_obj_read_mem(obj, strlen(obj), NULL, &c2, &m, &e), ST_ETOOBIG);
    assert_null(m);
}

/* The mesh stays with its set, so its memory (about ST_MESH_BYTES_PER_TRI a triangle) counts
 * against the import's byte cap: a mesh of 300 triangles under a cap that allows 100 is
 * TOO_LARGE naming the cap, before any texture is looked for; under a cap that allows them it
 * reads (and then wants its texture). Without the rule the mesh was read whatever the cap. */
static void mesh_triangles_count_against_the_byte_cap(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "tris300.obj");
    char *obj = malloc(64 * 310);
    assert_non_null(obj);
    size_t n = (size_t)sprintf(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n");
    for (int i = 0; i < 300; i++)
        n += (size_t)sprintf(obj + n, "f 1/1 2/2 3/3\n");
    write_file(path, obj, n);
    free(obj);
    st_import_opts o;
    st_import_opts_init(&o);
    o.max_bytes = 100 * ST_MESH_BYTES_PER_TRI;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(path, &o, &s, &e), ST_ETOOBIG);
    assert_null(s);
    printf("# %s\n", e.msg);
    assert_non_null(strstr(e.msg, "allows 100 triangles"));
    o.max_bytes = 400 * ST_MESH_BYTES_PER_TRI;
    assert_int_equal(st_import_file(path, &o, &s, &e), ST_EINVAL); /* read; no texture */
    assert_non_null(strstr(e.msg, "texture"));
    remove(path);
}

/* MTL map statements as other tools write them (mesh27): the spec's options are skipped by
 * their argument counts and the rest of the line is the name, spaces included (taking the last
 * token read "map_Kd my tex.png" as "tex.png": another file, or none); names are relative to
 * the .mtl's folder, which mtllib may put in a subfolder. */
static void mtl_map_names_keep_spaces_skip_options_and_follow_the_mtl_folder(void **state)
{
    (void)state;
    char sub[512], mp[512];
    tmp_path(sub, sizeof sub, "mats");
    mkdir(sub, 0700);
    tmp_path(mp, sizeof mp, "mats/spaces.mtl");
    const char *mtl = "newmtl a\nmap_Kd my tex.png\n"
                      "newmtl b\r\n\tmap_Kd -s 1 1 1 -o 0 0 -bm 0.5 -clamp on Diffuse Map.png \r\n"
                      "newmtl c\nmap_Kd -blendu off -mm 0 1 .\\Sub Dir\\wood.png\n"
                      "newmtl d\nmap_Kd -s 2 1.png\n";
    write_file(mp, mtl, strlen(mtl));
    const char *obj = "mtllib mats/spaces.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                      "usemtl a\nf 1 2 3\nusemtl b\nf 1 2 3\nusemtl c\nf 1 2 3\nusemtl d\nf 1 2 3\n";
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_obj_read_mem(obj, strlen(obj), tmpdir, NULL, &m, &e), ST_OK);
    const char *want[] = {"mats/my tex.png", "mats/Diffuse Map.png", "mats/Sub Dir/wood.png",
                          "mats/1.png"};
    for (int i = 0; i < 4; i++) {
        char w[600];
        snprintf(w, sizeof w, "%s/%s", tmpdir, want[i]);
        assert_string_equal(m->mats[m->tri_mat[i]].map_kd, w);
    }
    st_mesh_free(m);
}

/* A material name longer than the 127 bytes kept is looked up by those 127 bytes (mesh27: each
 * usemtl of it made a new material without the MTL's map_Kd, and 4097 of them refused the
 * file as "more than 4096 materials"). */
static void long_material_names_stay_one_material(void **state)
{
    (void)state;
    char name[201];
    memset(name, 'M', 200);
    name[200] = 0;
    char mtl[400], mp[512];
    snprintf(mtl, sizeof mtl, "newmtl %s\nmap_Kd long.png\n", name);
    tmp_path(mp, sizeof mp, "long.mtl");
    write_file(mp, mtl, strlen(mtl));
    enum { N = 5000 };
    size_t cap = 64 + (size_t)N * 260;
    char *obj = malloc(cap);
    assert_non_null(obj);
    size_t len = (size_t)snprintf(obj, cap, "mtllib long.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for (int i = 0; i < N; i++)
        len += (size_t)snprintf(obj + len, cap - len, "usemtl %s\nf 1 2 3\n", name);
    st_mesh *m = NULL;
    st_error e;
    int rc = st_obj_read_mem(obj, len, tmpdir, NULL, &m, &e);
    if (rc)
        print_message("long names: %s\n", e.msg);
    assert_int_equal(rc, ST_OK);
    assert_int_equal(m->ntri, N);
    assert_int_equal(m->nmat, 2);   /* "default" and the long one */
    char w[600];
    snprintf(w, sizeof w, "%s/long.png", tmpdir);
    assert_string_equal(m->mats[m->tri_mat[N - 1]].map_kd, w);
    st_mesh_free(m);
    free(obj);
}

/* vn indices are range-checked like v and vt ones; a token that is not a number is named (a
 * comment after a statement is one); numbers with many digits are read. */
static void obj_vn_indices_junk_tokens_and_long_numbers(void **state)
{
    (void)state;
    st_mesh *m = NULL;
    st_error e;
    const char *vn = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n";
    assert_int_equal(st_obj_read_mem(vn, strlen(vn), NULL, NULL, &m, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "line 5: vn index 2 out of range"));
    assert_null(m);
    const char *vnrel = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//-1 2//-2 3//-1\n";
    assert_int_equal(st_obj_read_mem(vnrel, strlen(vnrel), NULL, NULL, &m, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "relative vn index -2"));
    const char *ok = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 1 0 0\nf 1//1 2//2 3//-1\n";
    assert_int_equal(st_obj_read_mem(ok, strlen(ok), NULL, NULL, &m, &e), ST_OK);
    st_mesh_free(m);
    const char *cm = "v 0 0 0 # origin\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    assert_int_equal(st_obj_read_mem(cm, strlen(cm), NULL, NULL, &m, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "line 1: vertex: '#' is not a number"));
    const char *vt = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5 abc\nf 1/1 2/1 3/1\n";
    assert_int_equal(st_obj_read_mem(vt, strlen(vt), NULL, NULL, &m, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "line 4: vt: 'abc' is not a number"));
    char longn[200];
    snprintf(longn, sizeof longn, "v 0.%s 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
             "11111111111111111111111111111111111111111111111111111111111111111111111111111111");
    assert_int_equal(st_obj_read_mem(longn, strlen(longn), NULL, NULL, &m, &e), ST_OK);
    assert_float_equal(m->pos[0], 0.11111111f, 1e-7);
    st_mesh_free(m);
}

/* A PNG whose header claims w x h (valid CRCs, no pixel data). */
static void huge_png(uint32_t w, uint32_t h)
{
    uint8_t png[8 + 25 + 12 + 12];
    memcpy(png, "\x89PNG\r\n\x1a\n", 8);
    uint8_t *ih = png + 8;
    ih[0] = 0; ih[1] = 0; ih[2] = 0; ih[3] = 13;
    memcpy(ih + 4, "IHDR", 4);
    uint8_t *d = ih + 8;
    d[0] = (uint8_t)(w >> 24); d[1] = (uint8_t)(w >> 16); d[2] = (uint8_t)(w >> 8); d[3] = (uint8_t)w;
    d[4] = (uint8_t)(h >> 24); d[5] = (uint8_t)(h >> 16); d[6] = (uint8_t)(h >> 8); d[7] = (uint8_t)h;
    d[8] = 8; d[9] = 2; d[10] = 0; d[11] = 0; d[12] = 0;
    uint32_t crc = (uint32_t)crc32(0, ih + 4, 17);
    ih[21] = (uint8_t)(crc >> 24); ih[22] = (uint8_t)(crc >> 16); ih[23] = (uint8_t)(crc >> 8); ih[24] = (uint8_t)crc;
    uint8_t *id = ih + 25; /* an empty IDAT, so that the header is read to the end */
    memcpy(id, "\0\0\0\0IDAT", 8);
    crc = (uint32_t)crc32(0, id + 4, 4);
    id[8] = (uint8_t)(crc >> 24); id[9] = (uint8_t)(crc >> 16); id[10] = (uint8_t)(crc >> 8); id[11] = (uint8_t)crc;
    uint8_t *ie = id + 12;
    memcpy(ie, "\0\0\0\0IEND", 8);
    crc = (uint32_t)crc32(0, ie + 4, 4);
    ie[8] = (uint8_t)(crc >> 24); ie[9] = (uint8_t)(crc >> 16); ie[10] = (uint8_t)(crc >> 8); ie[11] = (uint8_t)crc;
    char p[512];
    tmp_path(p, sizeof p, "huge.png");
    write_file(p, png, sizeof png);
    st_set *s = NULL;
    st_error e;
    int rc = st_import_file(p, NULL, &s, &e);
    print_message("huge png: %s %s\n", st_strerror(rc), e.msg);
    assert_int_equal(rc, ST_ETOOBIG);
    assert_null(s);
}

static void huge_png_dimensions_are_refused_before_allocation(void **state)
{
    (void)state;
    huge_png(100000, 100000); /* over the per-axis cap */
    huge_png(30000, 30000);   /* within it, but 2.7 GB of texels is over the byte cap */
}

static void exr_with_a_huge_data_window_is_refused(void **state)
{
    (void)state;
    /* write a small EXR, then patch its dataWindow to 0..99999 x 0..99999 */
    enum { W = 8, H = 8 };
    uint16_t px[W * H * 3];
    memset(px, 0, sizeof px);
    char p[512];
    tmp_path(p, sizeof p, "huge.exr");
    st_error e;
    assert_int_equal(st_image_write(p, W, H, 3, ST_DT_HALF, px, &e), ST_OK);
    size_t len;
    uint8_t *b = read_file(p, &len);
    const char key[] = "dataWindow\0box2i\0";
    uint8_t *hit = NULL;
    for (size_t i = 0; i + sizeof key + 20 < len && !hit; i++)
        if (!memcmp(b + i, key, sizeof key - 1))
            hit = b + i + sizeof key - 1 + 4; /* past the attribute size */
    assert_non_null(hit);
    int32_t box[4] = {0, 0, 99999, 99999};
    memcpy(hit, box, sizeof box); /* little-endian host, as the file */
    write_file(p, b, len);
    free(b);
    st_image img;
    int rc = st_exr_read(p, NULL, &img, &e);
    print_message("huge exr: %s %s\n", st_strerror(rc), e.msg);
    assert_true(rc == ST_ETOOBIG || rc == ST_EFORMAT);
    st_set *s = NULL;
    assert_true(st_import_file(p, NULL, &s, &e) < 0);
    assert_null(s);
}

static void caps_on_dimension_and_bytes_are_enforced(void **state)
{
    (void)state;
    char png[1024], exr[1024];
    if (st_test_data_path(png, sizeof png, "meshes/duck/DuckCM.png") ||
        st_test_data_path(exr, sizeof exr, "env/StageEnvCube.exr"))
        skip();
    st_import_opts o;
    st_import_opts_init(&o);
    o.max_dim = 256;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(png, &o, &s, &e), ST_ETOOBIG);
    assert_int_equal(st_import_file(exr, &o, &s, &e), ST_ETOOBIG); /* 256 x 1536 */
    st_import_opts_init(&o);
    o.max_bytes = 4096;
    assert_int_equal(st_import_file(png, &o, &s, &e), ST_ETOOBIG);
    assert_null(s);
}

static void truncated_files_are_refused_cleanly(void **state)
{
    (void)state;
    const char *rel[] = {"meshes/duck/DuckCM.png", "cube/humus-6face/+x.jpg", "images/StillLife.jpg",
                         "env/StageEnvCube.exr", "env/forest.exr", "drc/converted/Duck.drc",
                         "ptx/wdas-ptex-samples/envcube/envcube.ptx", "env/converted/forest.hdr"};
    for (size_t i = 0; i < sizeof rel / sizeof rel[0]; i++) {
        char path[1024];
        if (st_test_data_path(path, sizeof path, rel[i]))
            skip();
        size_t len;
        uint8_t *b = read_file(path, &len);
        const char *ext = strrchr(rel[i], '.');
        size_t cuts[] = {1, 7, 40, len / 3, len / 2, len - 9};
        for (size_t k = 0; k < sizeof cuts / sizeof cuts[0]; k++) {
            char p[512], name[64];
            snprintf(name, sizeof name, "trunc%zu_%zu%s", i, k, ext);
            tmp_path(p, sizeof p, name);
            write_file(p, b, cuts[k]);
            st_set *s = NULL;
            st_error e;
            st_error_clear(&e);
            int rc = st_import_file(p, NULL, &s, &e);
            /* every format refuses a cut file: JPEG's decoder would fill the tail with grey,
             * which the importer must see through the reader's error state */
            if (rc == ST_OK)
                print_message("%s cut at %zu bytes was accepted\n", rel[i], cuts[k]);
            assert_true(rc < 0);
            assert_null(s);
            assert_true(strlen(e.msg) > 0);
            unlink(p);
        }
        free(b);
    }
}

static void exr_luminance_chroma_images_are_refused_not_made_grey(void **state)
{
    (void)state;
    enum { W = 8, H = 4 };
    char p[512];
    st_error e;
    st_image img;
    const char *n[3] = {"BY", "RY", "Y"};
    const float v[3] = {0.25f, -0.125f, 0.5f};
    tmp_path(p, sizeof p, "yc.exr");
    write_exr_channels(p, W, H, 3, n, v);
    st_error_clear(&e);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "luminance/chroma"));
    st_set *s = NULL;
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "luminance/chroma"));
    assert_null(s);
    /* a file with Y alone is a grey image and reads as one channel */
    const char *ny[1] = {"Y"};
    tmp_path(p, sizeof p, "y.exr");
    write_exr_channels(p, W, H, 1, ny, v + 2);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 1);
    st_image_free(&img);
}

/* img27: a Y + A file is a grey image with alpha (it came in as its A channel alone, grey),
 * and Y, RY, BY, A is refused as luminance/chroma (the A let it through as grey). */
static void exr_grey_with_alpha_keeps_both_and_chroma_with_alpha_is_refused(void **state)
{
    (void)state;
    enum { W = 8, H = 4 };
    char p[512];
    st_error e;
    st_image img;
    const char *ya[2] = {"Y", "A"};
    const float v[4] = {0.5f, 0.25f, -0.125f, 0.75f};
    tmp_path(p, sizeof p, "ya.exr");
    write_exr_channels(p, W, H, 2, ya, v);
    st_error_clear(&e);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 2);
    assert_int_equal(img.alpha_chan, 1);
    const uint16_t *t = img.data;
    for (int x = 0; x < W; x++) {
        assert_true(st_half_to_float(t[2 * x]) == st_half_to_float(st_float_to_half(0.5f + x / 64.0f)));
        assert_true(st_half_to_float(t[2 * x + 1]) == st_half_to_float(st_float_to_half(0.25f + x / 64.0f)));
    }
    st_image_free(&img);
    /* the same in a layer: mask.Y + mask.A */
    const char *lya[2] = {"mask.Y", "mask.A"};
    tmp_path(p, sizeof p, "layer_ya.exr");
    write_exr_channels(p, W, H, 2, lya, v);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 2);
    assert_int_equal(img.alpha_chan, 1);
    st_image_free(&img);
    /* alpha alone is still one channel */
    const char *a1[1] = {"A"};
    tmp_path(p, sizeof p, "a.exr");
    write_exr_channels(p, W, H, 1, a1, v + 1);
    assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_OK);
    assert_int_equal(img.nchan, 1);
    assert_int_equal(img.alpha_chan, -1);
    st_image_free(&img);
    const char *yca[4] = {"Y", "RY", "BY", "A"};
    tmp_path(p, sizeof p, "yca.exr");
    write_exr_channels(p, W, H, 4, yca, v);
    st_set *s = NULL;
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "luminance/chroma"));
    assert_null(s);
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

/* An uncompressed ripmap EXR, assembled by the file format's rules (OpenEXR file layout): w x
 * h, one half channel Y, 1 x 1 tiles, ROUND_DOWN; texel (x, y) of level (lx, ly) holds
 * x + 10 y + 100 lx + 1000 ly (all exact in half). Single-part, or with multipart a
 * multi-part file (version flag bit 12) whose part 0 is that ripmap and part 1 a 1 x 1
 * scanline image: each header names its part, type and chunkCount, an empty header ends the
 * list, the two offset tables follow in part order, every chunk starts with its part number,
 * and part 1's chunk comes first in the file (so the last bytes are the ripmap's smallest rip
 * level). Returns its size. */
static size_t ripmap_exr(uint8_t *b, int w, int h, int multipart)
{
    size_t n = 0;
#define ATTR(name, type, size)                                                                   \
    do {                                                                                         \
        memcpy(b + n, name, strlen(name) + 1);                                                   \
        n += strlen(name) + 1;                                                                   \
        memcpy(b + n, type, strlen(type) + 1);                                                   \
        n += strlen(type) + 1;                                                                   \
        put32(b + n, size);                                                                      \
        n += 4;                                                                                  \
    } while (0)
#define STRATTR(name, value)                                                                     \
    do {                                                                                         \
        ATTR(name, "string", (uint32_t)strlen(value));                                           \
        memcpy(b + n, value, strlen(value));                                                     \
        n += strlen(value);                                                                      \
    } while (0)
    int nlx = 1, nly = 1;
    while ((w >> nlx) >= 1) nlx++;
    while ((h >> nly) >= 1) nly++;
    size_t nchunks = 0;
    for (int ly = 0; ly < nly; ly++)
        for (int lx = 0; lx < nlx; lx++)
            nchunks += (size_t)(w >> lx) * (size_t)(h >> ly);
    put32(b, 20000630u);
    put32(b + 4, multipart ? 2u | 0x1000u : 2u | 0x200u); /* version 2, multi-part or tiled */
    n = 8;
    float one = 1.0f, zero = 0.0f;
    for (int part = 0; part < (multipart ? 2 : 1); part++) {
        ATTR("channels", "chlist", 2 + 16 + 1);
        memcpy(b + n, "Y", 2);
        n += 2;
        put32(b + n, 1); /* half */
        memset(b + n + 4, 0, 4);
        put32(b + n + 8, 1);
        put32(b + n + 12, 1);
        n += 16;
        b[n++] = 0;
        ATTR("compression", "compression", 1);
        b[n++] = 0;
        int dw = part ? 1 : w, dh = part ? 1 : h; /* part 1: 1 x 1 */
        ATTR("dataWindow", "box2i", 16);
        put32(b + n, 0); put32(b + n + 4, 0); put32(b + n + 8, (uint32_t)dw - 1); put32(b + n + 12, (uint32_t)dh - 1);
        n += 16;
        ATTR("displayWindow", "box2i", 16);
        put32(b + n, 0); put32(b + n + 4, 0); put32(b + n + 8, (uint32_t)w - 1); put32(b + n + 12, (uint32_t)h - 1);
        n += 16;
        ATTR("lineOrder", "lineOrder", 1);
        b[n++] = 0;
        ATTR("pixelAspectRatio", "float", 4);
        memcpy(b + n, &one, 4);
        n += 4;
        ATTR("screenWindowCenter", "v2f", 8);
        memcpy(b + n, &zero, 4);
        memcpy(b + n + 4, &zero, 4);
        n += 8;
        ATTR("screenWindowWidth", "float", 4);
        memcpy(b + n, &one, 4);
        n += 4;
        if (part == 0) {
            ATTR("tiles", "tiledesc", 9);
            put32(b + n, 1);
            put32(b + n + 4, 1);
            b[n + 8] = 2; /* RIPMAP_LEVELS, ROUND_DOWN */
            n += 9;
        }
        if (multipart) {
            ATTR("chunkCount", "int", 4);
            put32(b + n, part ? 1u : (uint32_t)nchunks);
            n += 4;
            STRATTR("name", part ? "flat" : "rip");
            STRATTR("type", part ? "scanlineimage" : "tiledimage");
        }
        b[n++] = 0; /* end of header */
    }
    if (multipart)
        b[n++] = 0; /* the empty header: end of the list */
#undef STRATTR
#undef ATTR
    size_t table = n, pos = n + 8 * nchunks + (multipart ? 8 : 0), k = 0;
    if (multipart) {
        /* part 1's table and its one chunk: part 1, y 0, 2 bytes, a half 7 */
        uint64_t off = pos;
        memcpy(b + table + 8 * nchunks, &off, 8); /* little-endian host */
        put32(b + pos, 1);
        put32(b + pos + 4, 0);
        put32(b + pos + 8, 2);
        uint16_t hv = st_float_to_half(7.0f);
        memcpy(b + pos + 12, &hv, 2);
        pos += 14;
    }
    for (int ly = 0; ly < nly; ly++)
        for (int lx = 0; lx < nlx; lx++)
            for (int y = 0; y < h >> ly; y++)
                for (int x = 0; x < w >> lx; x++, k++) {
                    uint64_t off = pos;
                    memcpy(b + table + 8 * k, &off, 8);
                    if (multipart) {
                        put32(b + pos, 0); /* part 0 */
                        pos += 4;
                    }
                    put32(b + pos, (uint32_t)x);
                    put32(b + pos + 4, (uint32_t)y);
                    put32(b + pos + 8, (uint32_t)lx);
                    put32(b + pos + 12, (uint32_t)ly);
                    put32(b + pos + 16, 2);
                    uint16_t hv = st_float_to_half((float)(x + 10 * y + 100 * lx + 1000 * ly));
                    memcpy(b + pos + 20, &hv, 2);
                    pos += 22;
                }
    return pos;
}

/* The W x H ripmap file b (len bytes; ripmap_exr) read as its level 0 (texel (x, y) =
 * x + 10 y, half) from the file at p, from memory, and imported as a one-face set. */
static void ripmap_reads_level_0(const uint8_t *b, size_t len, const char *p, int W, int H)
{
    write_file(p, b, len);
    st_error e;
    st_error_clear(&e);
    st_image img;
    int rc = st_exr_read(p, NULL, &img, &e);
    if (rc)
        print_message("%s: %s\n", p, e.msg);
    assert_int_equal(rc, ST_OK);
    assert_int_equal(img.w, W);
    assert_int_equal(img.h, H);
    assert_int_equal(img.nchan, 1);
    assert_int_equal(img.dtype, ST_DT_HALF);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            assert_true(st_half_to_float(((uint16_t *)img.data)[y * W + x]) == (float)(x + 10 * y));
    st_image_free(&img);
    assert_int_equal(st_exr_read_mem(b, len, p, NULL, &img, &e), ST_OK);
    st_image_free(&img);
    st_set *s = NULL;
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.nfaces, 1);
    st_set_free(s);
}

/* img27: OpenEXR 3.1.5's C API maps the tiles of rip levels (x, y > 0) to the wrong chunks, so
 * the truncation check refused every valid ripmap file; the check now reads those chunks from
 * the file's offset table, and a ripmap cut short is still refused. */
static void exr_ripmap_imports_level_0_and_a_cut_ripmap_is_refused(void **state)
{
    (void)state;
    enum { W = 4, H = 2 };
    static uint8_t b[8192];
    size_t len = ripmap_exr(b, W, H, 0);
    char p[512];
    tmp_path(p, sizeof p, "ripmap.exr");
    ripmap_reads_level_0(b, len, p, W, H);
    st_error e;
    st_error_clear(&e);
    st_image img;
    /* cut inside the last rip level (1 texel: level (2, 1)), and inside the table */
    size_t cuts[3] = {len - 1, len - 22, len / 2};
    for (int k = 0; k < 3; k++) {
        write_file(p, b, cuts[k]);
        assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_EFORMAT);
        assert_null(img.data);
        assert_int_equal(st_exr_read_mem(b, cuts[k], "cut", NULL, &img, &e), ST_EFORMAT);
    }
}

/* img27's Left: a multi-part file whose part 0 is a ripmap was still refused (the offset-table
 * check knew single-part files only, and the library's mapping of the rip levels is wrong in
 * a multi-part file too). Now part 0's chunks are found through the multi-part layout; a cut
 * inside the ripmap, or a part 0 offset that leads to another part's chunk, is refused. */
static void exr_multipart_ripmap_imports_part_0_and_a_cut_one_is_refused(void **state)
{
    (void)state;
    enum { W = 4, H = 2 };
    static uint8_t b[8192];
    size_t len = ripmap_exr(b, W, H, 1);
    char p[512];
    tmp_path(p, sizeof p, "ripmap_mp.exr");
    ripmap_reads_level_0(b, len, p, W, H);
    st_error e;
    st_error_clear(&e);
    st_image img;
    /* cut inside the last rip level (1 texel: level (2, 1)), a whole tile short, and inside
     * the tables */
    size_t cuts[3] = {len - 1, len - 26, len / 2};
    for (int k = 0; k < 3; k++) {
        write_file(p, b, cuts[k]);
        assert_int_equal(st_exr_read(p, NULL, &img, &e), ST_EFORMAT);
        assert_null(img.data);
        assert_int_equal(st_exr_read_mem(b, cuts[k], "cut", NULL, &img, &e), ST_EFORMAT);
    }
    /* the last rip tile's offset pointed at part 1's chunk: not part 0's, refused */
    int nlx = 3, nly = 2;
    size_t nchunks = 0;
    for (int ly = 0; ly < nly; ly++)
        for (int lx = 0; lx < nlx; lx++)
            nchunks += (size_t)(W >> lx) * (size_t)(H >> ly);
    uint64_t part1_off, last;
    size_t table = len - 14 - 26 * nchunks - 8 * (nchunks + 1); /* part 0's table */
    memcpy(&part1_off, b + table + 8 * nchunks, 8);
    memcpy(&last, b + table + 8 * (nchunks - 1), 8);
    assert_int_equal(last, len - 26); /* the table is where it is thought to be */
    memcpy(b + table + 8 * (nchunks - 1), &part1_off, 8);
    assert_int_equal(st_exr_read_mem(b, len, "wrong part", NULL, &img, &e), ST_EFORMAT);
    assert_null(img.data);
}

/* A little-endian uncompressed TIFF, 1 sample of SampleFormat INT (2), 16 bits, w x 1; with
 * omit_bps its BitsPerSample tag is left out (1 bit by the TIFF default). */
static size_t int16_tiff(uint8_t *b, const int16_t *v, int w, int omit_bps)
{
    memcpy(b, "II*\0", 4);
    put32(b + 4, 8);
    uint8_t *d = b + 8;
    enum { NTAG = 10 };
    int ntag = omit_bps ? NTAG - 1 : NTAG;
    d[0] = (uint8_t)ntag;
    d[1] = 0;
    size_t data = 8 + 2 + 12 * (size_t)ntag + 4;
    static const uint16_t tags[NTAG][2] = {{256, 3}, {257, 3}, {258, 3}, {259, 3}, {262, 3},
                                           {273, 4}, {277, 3}, {278, 3}, {279, 4}, {339, 3}};
    uint32_t vals[NTAG] = {(uint32_t)w, 1, 16, 1, 1, (uint32_t)data, 1, 1, (uint32_t)(2 * w), 2};
    for (int k = 0, o = 0; k < NTAG; k++) {
        if (omit_bps && tags[k][0] == 258)
            continue;
        uint8_t *t = d + 2 + 12 * o++;
        t[0] = (uint8_t)tags[k][0];
        t[1] = (uint8_t)(tags[k][0] >> 8);
        t[2] = (uint8_t)tags[k][1];
        t[3] = 0;
        put32(t + 4, 1);
        put32(t + 8, vals[k]);
    }
    put32(d + 2 + 12 * ntag, 0);
    memcpy(b + data, v, 2 * (size_t)w);
    return data + 2 * (size_t)w;
}

/* Writes int16_tiff of the 4 values v (omit_bps as there) to the temporary file `file` (its
 * path into p) and reads it with st_image_read; returns what that returns. */
static int read_int16_tiff(const int16_t *v, int omit_bps, const char *file, char *p, size_t cap,
                           st_image *img, st_error *e)
{
    uint8_t b[512];
    size_t len = int16_tiff(b, v, 4, omit_bps);
    tmp_path(p, cap, file);
    write_file(p, b, len);
    st_error_clear(e);
    return st_image_read(p, NULL, img, e);
}

/* img27: signed 16-bit TIFF data came in as u16 with every negative value clamped to 0; it is
 * float now (OpenImageIO's -1..1 normalisation), signs kept. */
static void signed_16_bit_tiff_keeps_its_negative_values(void **state)
{
    (void)state;
    const int16_t v[4] = {-32767, -16384, 0, 32767};
    char p[512];
    st_error e;
    st_image img;
    int rc = read_int16_tiff(v, 0, "int16.tif", p, sizeof p, &img, &e);
    if (rc)
        print_message("int16 tiff: %s\n", e.msg);
    assert_int_equal(rc, ST_OK);
    assert_int_equal(img.w, 4);
    assert_int_equal(img.nchan, 1);
    assert_int_equal(img.dtype, ST_DT_F32);
    const float *f = img.data;
    for (int k = 0; k < 4; k++)
        assert_float_equal(f[k], v[k] / 32767.0, 1e-4);
    st_image_free(&img);
}

/* img27: a TIFF without BitsPerSample is 1-bit by the TIFF default (Pillow writes 1-bit images
 * so); OpenImageIO 2.4 reads it as 8-bit past the end of the strip and makes texels up without
 * an error. It is refused with a reason. */
static void tiff_without_bits_per_sample_is_refused_not_made_up(void **state)
{
    (void)state;
    const int16_t v[4] = {-32767, -16384, 0, 32767};
    char p[512];
    st_error e;
    st_image img;
    assert_int_equal(read_int16_tiff(v, 1, "nobps.tif", p, sizeof p, &img, &e), ST_EUNSUPPORTED);
    assert_null(img.data);
    assert_non_null(strstr(e.msg, "BitsPerSample"));
    st_set *s = NULL;
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_EUNSUPPORTED);
    assert_null(s);
}

/* img27: the set's premultiplied flag says how alpha is stored: an EXR's colour is
 * premultiplied (OpenEXR's convention), a PNG's is straight; texels stay as stored. */
static void premultiplied_flag_follows_the_file(void **state)
{
    (void)state;
    enum { W = 8, H = 4 };
    char p[512];
    st_error e;
    st_error_clear(&e);
    const char *rgba[4] = {"R", "G", "B", "A"};
    const float v[4] = {0.25f, 0.125f, 0.0625f, 0.5f};
    st_set *s = NULL;
    tmp_path(p, sizeof p, "pm_rgba.exr");
    write_exr_channels(p, W, H, 4, rgba, v);
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.alpha_chan, 3);
    assert_int_equal(s->info.premultiplied, 1);
    st_set_free(s);
    tmp_path(p, sizeof p, "pm_rgb.exr");
    write_exr_channels(p, W, H, 3, rgba, v);
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.premultiplied, 0);
    st_set_free(s);
    uint8_t px[W * H * 4];
    for (size_t i = 0; i < sizeof px; i++)
        px[i] = (uint8_t)(i * 7);
    tmp_path(p, sizeof p, "pm_rgba.png");
    assert_int_equal(st_image_write(p, W, H, 4, ST_DT_U8, px, &e), ST_OK);
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.alpha_chan, 3);
    assert_int_equal(s->info.premultiplied, 0);
    assert_memory_equal(st_face_level(s, 0, 0), px, sizeof px); /* as stored, not premultiplied */
    st_set_free(s);
}

/* A little-endian uncompressed 8-bit TIFF, w x h, spp samples per pixel, PhotometricInterpretation
 * photometric (1 grey, 2 RGB), ExtraSamples `extra` (0 unspecified, 1 associated alpha, 2
 * unassociated alpha) or no ExtraSamples tag when extra < 0; texels px (w * h * spp bytes). */
static size_t u8_tiff(uint8_t *b, int w, int h, int spp, int photometric, int extra,
                      const uint8_t *px)
{
    memcpy(b, "II*\0", 4);
    put32(b + 4, 8);
    int ntag = extra < 0 ? 9 : 10;
    uint8_t *d = b + 8;
    d[0] = (uint8_t)ntag;
    d[1] = 0;
    size_t bps = 8 + 2 + 12 * (size_t)ntag + 4; /* BitsPerSample array, then the strip */
    size_t data = bps + 2 * (size_t)spp;
    const uint16_t tags[10] = {256, 257, 258, 259, 262, 273, 277, 278, 279, 338};
    const uint16_t types[10] = {3, 3, 3, 3, 3, 4, 3, 3, 4, 3};
    const uint32_t counts[10] = {1, 1, (uint32_t)spp, 1, 1, 1, 1, 1, 1, 1};
    uint32_t vals[10] = {(uint32_t)w, (uint32_t)h, (uint32_t)bps, 1, (uint32_t)photometric,
                         (uint32_t)data, (uint32_t)spp, (uint32_t)h,
                         (uint32_t)(w * h * spp), (uint32_t)(extra < 0 ? 0 : extra)};
    if (spp <= 2)
        vals[2] = spp == 1 ? 8 : 8u | 8u << 16; /* fits the tag: inline */
    for (int k = 0; k < ntag; k++) {
        uint8_t *t = d + 2 + 12 * k;
        t[0] = (uint8_t)tags[k];
        t[1] = (uint8_t)(tags[k] >> 8);
        t[2] = (uint8_t)types[k];
        t[3] = 0;
        put32(t + 4, counts[k]);
        put32(t + 8, vals[k]);
    }
    put32(d + 2 + 12 * ntag, 0);
    for (int c = 0; c < spp; c++) {
        b[bps + 2 * c] = 8;
        b[bps + 2 * c + 1] = 0;
    }
    memcpy(b + data, px, (size_t)(w * h * spp));
    return data + (size_t)(w * h * spp);
}

/* Imports p (case k of a table) and fails, naming the case and the reason, unless it imports. */
static st_set *import_case_ok(const char *p, size_t k)
{
    st_error e;
    st_error_clear(&e);
    st_set *s = NULL;
    int rc = st_import_file(p, NULL, &s, &e);
    if (rc)
        print_message("case %zu: %s\n", k, e.msg);
    assert_int_equal(rc, ST_OK);
    return s;
}

/* imp34: the last channel of a 2- or 4-channel image was taken as alpha whenever OpenImageIO
 * reported none: a 2-channel TIFF (R, G: a normal or flow map, as oiiotool writes it) or an
 * RGB TIFF with an unspecified extra sample came in with alpha_chan 1 / 3 and premultiplied 1,
 * and COMPRESS then punched transparent BC1 texels wherever that channel was under 0.5. The
 * alpha is what the file says (ExtraSamples 1 or 2), texels as stored either way. */
static void tiff_channels_are_alpha_only_when_the_file_says_so(void **state)
{
    (void)state;
    enum { W = 3, H = 2 };
    static const struct {
        int spp, photometric, extra, alpha, premultiplied;
    } cases[] = {
        {2, 1, -1, -1, 0}, /* R, G */
        {2, 1, 0, -1, 0},  /* grey + an unspecified extra sample */
        {4, 2, 0, -1, 0},  /* RGB + an unspecified extra sample */
        {2, 1, 1, 1, 1},   /* grey + associated alpha */
        {4, 2, 2, 3, 0},   /* RGB + unassociated alpha */
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        uint8_t px[W * H * 4], b[1024];
        for (size_t i = 0; i < sizeof px; i++)
            px[i] = (uint8_t)(i * 37 + 5);
        size_t len = u8_tiff(b, W, H, cases[k].spp, cases[k].photometric, cases[k].extra, px);
        char p[512];
        tmp_path(p, sizeof p, "alpha.tif");
        write_file(p, b, len);
        st_set *s = import_case_ok(p, k);
        if (s->info.alpha_chan != cases[k].alpha)
            print_message("case %zu: alpha_chan %d, the file says %d\n", k, s->info.alpha_chan,
                          cases[k].alpha);
        assert_int_equal(s->info.nchan, cases[k].spp);
        assert_int_equal(s->info.alpha_chan, cases[k].alpha);
        assert_int_equal(s->info.premultiplied, cases[k].premultiplied);
        assert_memory_equal(st_face_level(s, 0, 0), px, (size_t)(W * H * cases[k].spp));
        st_set_free(s);
    }
}

/* imp34: an EXR whose channels are X, Y, Z (a position or normal map, CIE XYZ; also in a layer:
 * N.X, N.Y, N.Z) came in as its Y channel alone, a grey image of one component, because a Y
 * with no R, G, B is read as luminance. A Y beside an X is a vector's: X, Y, Z in that order;
 * a Y beside only a Z (depth) and an A is still grey + alpha. */
static void exr_xyz_channels_are_a_vector_not_luminance(void **state)
{
    (void)state;
    enum { W = 4, H = 2 };
    static const struct {
        const char *names[3];
        int nch, want_nchan, want_alpha;
        int order[3]; /* the file channel (index into names) of each set channel */
    } cases[] = {
        {{"X", "Y", "Z"}, 3, 3, -1, {0, 1, 2}},
        {{"N.Z", "N.Y", "N.X"}, 3, 3, -1, {2, 1, 0}},
        {{"Y", "X", NULL}, 2, 2, -1, {1, 0, -1}},
        {{"Z", "A", "Y"}, 3, 2, 1, {2, 1, -1}}, /* luminance, alpha; depth left out */
    };
    const float v[3] = {0.25f, 0.5f, 0.75f};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char p[512];
        tmp_path(p, sizeof p, "xyz.exr");
        write_exr_channels(p, W, H, cases[k].nch, cases[k].names, v);
        st_set *s = import_case_ok(p, k);
        if (s->info.nchan != cases[k].want_nchan)
            print_message("case %zu: %u channels, want %d\n", k, s->info.nchan,
                          cases[k].want_nchan);
        assert_int_equal(s->info.nchan, cases[k].want_nchan);
        assert_int_equal(s->info.alpha_chan, cases[k].want_alpha);
        const uint8_t *t = st_face_level(s, 0, 0);
        size_t ts = st_texel_size(s);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                for (int c = 0; c < cases[k].want_nchan; c++)
                    assert_float_equal(st_channel_get(s->info.dtype, t + (size_t)(y * W + x) * ts, (unsigned)c),
                                       v[cases[k].order[c]] + (float)x / 64.0f, 1e-3);
        st_set_free(s);
    }
}

/* A deep scanline EXR of w x 2 (one half channel R, 1..w samples per pixel), through the C API. */
static void write_deep_exr(const char *path, int w)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_context_t ctx = NULL;
    int part = 0;
    assert_int_equal(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init), EXR_ERR_SUCCESS);
    assert_int_equal(exr_add_part(ctx, "deep", EXR_STORAGE_DEEP_SCANLINE, &part), EXR_ERR_SUCCESS);
    assert_int_equal(exr_initialize_required_attr_simple(ctx, part, w, 2, EXR_COMPRESSION_NONE),
                     EXR_ERR_SUCCESS);
    assert_int_equal(exr_add_channel(ctx, part, "R", EXR_PIXEL_HALF, EXR_PERCEPTUALLY_LOGARITHMIC,
                                     1, 1), EXR_ERR_SUCCESS);
    assert_int_equal(exr_write_header(ctx), EXR_ERR_SUCCESS);
    int32_t counts[16];
    uint16_t vals[16 * 17 / 2];
    assert_true(w <= 16);
    for (int x = 0, n = 0; x < w; x++) /* cumulative sample counts */
        counts[x] = n += x + 1;
    for (int i = 0; i < counts[w - 1]; i++)
        vals[i] = st_float_to_half((float)i / 16.0f);
    for (int y = 0; y < 2; y++) {
        exr_chunk_info_t ci;
        assert_int_equal(exr_write_scanline_chunk_info(ctx, part, y, &ci), EXR_ERR_SUCCESS);
        size_t vb = 2 * (size_t)counts[w - 1];
        assert_int_equal(exr_write_deep_scanline_chunk(ctx, part, y, vals, vb, vb, counts,
                                                       4 * (size_t)w), EXR_ERR_SUCCESS);
    }
    assert_int_equal(exr_finish(&ctx), EXR_ERR_SUCCESS);
}

/* An EXR of R, G at full resolution and B sampled every 2 x 2 pixels (w, h even). */
static void write_subsampled_exr(const char *path, int w, int h)
{
    static const char *const names[3] = {"R", "G", "B"};
    static const float values[3] = {0.25f, 0.5f, 0.75f};
    static const int samp[3] = {1, 1, 2};
    write_exr_sampled(path, w, h, 3, names, values, samp);
}

/* imp34: a deep EXR was refused with OpenImageIO's "called OpenEXRInput::read_native_scanlines
 * without an open file" (FORMAT): the C API's "deep" refusal (UNSUPPORTED) sent the file on to
 * OIIO's reader, the fallback meant for DWAA/DWAB, whose failure replaced the reason. Now the
 * C API's reason and code stay, OIIO's is added; a subsampled colour channel is named the same
 * way. A subsampled channel that is not read (R, G + a subsampled Z) is no reason to refuse. */
static void exr_deep_and_subsampled_files_are_refused_with_their_reason(void **state)
{
    (void)state;
    char p[512];
    st_error e;
    st_set *s = NULL;
    tmp_path(p, sizeof p, "deep.exr");
    write_deep_exr(p, 4);
    st_error_clear(&e);
    int rc = st_import_file(p, NULL, &s, &e);
    print_message("deep: %s\n", e.msg);
    assert_int_equal(rc, ST_EUNSUPPORTED);
    assert_null(s);
    assert_non_null(strstr(e.msg, "deep EXR"));
    st_image img;
    st_error_clear(&e);
    assert_int_equal(st_image_read_any(p, NULL, &img, &e), ST_EUNSUPPORTED);
    assert_null(img.data);
    assert_non_null(strstr(e.msg, "deep EXR"));

    tmp_path(p, sizeof p, "sub.exr");
    write_subsampled_exr(p, 8, 4);
    st_error_clear(&e);
    rc = st_import_file(p, NULL, &s, &e);
    print_message("subsampled: %s\n", e.msg);
    assert_int_equal(rc, ST_EUNSUPPORTED);
    assert_null(s);
    assert_non_null(strstr(e.msg, "channel B is subsampled"));
}

/* imp34: OpenImageIO's messages may hold line breaks (libpng: "PNG read error: Not enough
 * image data\nPNG library error"), which went into the daemon's one-line log records and the
 * protocol's message as they were. They are one line now. */
static void image_reader_messages_are_one_line(void **state)
{
    (void)state;
    /* a 64 x 64 grey PNG whose IDAT holds 10 rows: its chunks reach IEND, its data does not */
    uint8_t raw[65 * 10], z[256], b[512];
    memset(raw, 0, sizeof raw);
    uLongf zl = sizeof z;
    assert_int_equal(compress(z, &zl, raw, sizeof raw), Z_OK);
    size_t n = 0;
    memcpy(b, "\x89PNG\r\n\x1a\n", 8);
    n = 8;
    const uint8_t ihdr[13] = {0, 0, 0, 64, 0, 0, 0, 64, 8, 0, 0, 0, 0};
    const struct { const char *type; const uint8_t *d; size_t len; } ch[3] = {
        {"IHDR", ihdr, sizeof ihdr}, {"IDAT", z, zl}, {"IEND", NULL, 0}};
    for (int k = 0; k < 3; k++) {
        uint8_t *c = b + n;
        c[0] = (uint8_t)(ch[k].len >> 24);
        c[1] = (uint8_t)(ch[k].len >> 16);
        c[2] = (uint8_t)(ch[k].len >> 8);
        c[3] = (uint8_t)ch[k].len;
        memcpy(c + 4, ch[k].type, 4);
        if (ch[k].len)
            memcpy(c + 8, ch[k].d, ch[k].len);
        uint32_t crc = (uint32_t)crc32(0, c + 4, (uInt)(4 + ch[k].len));
        c[8 + ch[k].len] = (uint8_t)(crc >> 24);
        c[9 + ch[k].len] = (uint8_t)(crc >> 16);
        c[10 + ch[k].len] = (uint8_t)(crc >> 8);
        c[11 + ch[k].len] = (uint8_t)crc;
        n += 12 + ch[k].len;
    }
    char p[512];
    tmp_path(p, sizeof p, "short.png");
    write_file(p, b, n);
    st_error e;
    st_error_clear(&e);
    st_set *s = NULL;
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_EFORMAT);
    print_message("short IDAT: %s\n", e.msg);
    for (const char *c = e.msg; *c; c++)
        assert_true((unsigned char)*c >= 0x20);
}

/* Imports path with o->cube = cube (and cube_lenient); returns the code, the set freed. */
static int import_cube_opt(const char *path, int cube, int lenient, int *kind, st_error *e)
{
    st_import_opts o;
    st_import_opts_init(&o);
    o.cube = (uint8_t)cube;
    o.cube_lenient = (uint8_t)lenient;
    st_set *s = NULL;
    st_error_clear(e);
    int rc = st_import_file(path, &o, &s, e);
    *kind = s ? s->info.kind : -1;
    st_set_free(s);
    return rc;
}

/* imp34: an OpenEXR cube map (envmap=cube: a vertical strip) imported with cube=latlong was
 * resampled as if its strip were a lat-long panorama, a wrong cube with OK (cube=cross_h /
 * strip_h likewise where the aspect fitted); and a tagged cube of a shape no layout takes was
 * refused with no option but became a plain atlas with cube=auto. The file's tag now decides:
 * strip_v, auto and none read the strip (or refuse it), the other layouts are refused. */
static void exr_cube_maps_take_no_other_layout(void **state)
{
    (void)state;
    uint16_t px[4 * 24 * 3];
    for (size_t i = 0; i < sizeof px / sizeof px[0]; i++)
        px[i] = st_float_to_half((float)(i % 97) / 97.0f);
    char ok[512], bad[512];
    tmp_path(ok, sizeof ok, "cube_tag.exr");
    tmp_path(bad, sizeof bad, "cube_tag_bad.exr");
    st_error e;
    st_image img = {.w = 4, .h = 24, .nchan = 3, .dtype = ST_DT_HALF, .alpha_chan = -1,
                    .colorspace = ST_CS_LINEAR, .envmap = ST_ENVMAP_CUBE, .nlevels_file = 1,
                    .data = px};
    assert_int_equal(st_image_write_img(ok, &img, &e), ST_OK);
    img.h = 20; /* 4 x 20: no cube layout */
    assert_int_equal(st_image_write_img(bad, &img, &e), ST_OK);
    int kind;
    assert_int_equal(import_cube_opt(ok, ST_IMPORT_CUBE_NONE, 0, &kind, &e), ST_OK);
    assert_int_equal(kind, ST_KIND_CUBE);
    assert_int_equal(import_cube_opt(ok, ST_IMPORT_CUBE_AUTO, 0, &kind, &e), ST_OK);
    assert_int_equal(kind, ST_KIND_CUBE);
    assert_int_equal(import_cube_opt(ok, ST_IMPORT_CUBE_STRIP_V, 0, &kind, &e), ST_OK);
    assert_int_equal(kind, ST_KIND_CUBE);
    int rc = import_cube_opt(ok, ST_IMPORT_CUBE_LATLONG, 0, &kind, &e);
    if (rc == ST_OK)
        print_message("cube=latlong on an envmap=cube file: OK, kind %d\n", kind);
    assert_int_equal(rc, ST_EINVAL);
    assert_non_null(strstr(e.msg, "envmap=cube"));
    /* a set recorded with that option before the check still rebuilds as it was */
    assert_int_equal(import_cube_opt(ok, ST_IMPORT_CUBE_LATLONG, 1, &kind, &e), ST_OK);
    assert_int_equal(import_cube_opt(bad, ST_IMPORT_CUBE_NONE, 0, &kind, &e), ST_EINVAL);
    rc = import_cube_opt(bad, ST_IMPORT_CUBE_AUTO, 0, &kind, &e);
    if (rc == ST_OK)
        print_message("cube=auto on a 4x20 envmap=cube file: OK, kind %d\n", kind);
    assert_int_equal(rc, ST_EINVAL);
}

/* Peak resident size of this process in KB (VmHWM; -1 when it cannot be read). */
static long vm_hwm_kb(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    long kb = -1;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "VmHWM: %ld kB", &kb) == 1)
            break;
    if (f)
        fclose(f);
    return kb;
}

/* Runs this binary again as a child that only imports path (main: ST_IMPORT_CHILD) and
 * returns the child's own peak resident size in KB, which it writes to a file (wait4's
 * ru_maxrss would count the parent's memory: a spawned child's high-water mark starts from
 * the address space it was spawned from); *status its wait status. */
static long import_child_peak_kb(const char *path, int *status)
{
    extern char **environ;
    char out[512];
    tmp_path(out, sizeof out, "import_child_hwm.txt");
    unlink(out);
    char *const argv[] = {(char *)"test_import", NULL};
    pid_t pid;
    assert_int_equal(setenv("ST_IMPORT_CHILD", path, 1), 0);
    assert_int_equal(setenv("ST_IMPORT_CHILD_OUT", out, 1), 0);
    int rc = posix_spawn(&pid, "/proc/self/exe", NULL, NULL, argv, environ);
    unsetenv("ST_IMPORT_CHILD");
    unsetenv("ST_IMPORT_CHILD_OUT");
    assert_int_equal(rc, 0);
    int st = 0;
    assert_int_equal(waitpid(pid, &st, 0), pid);
    if (status)
        *status = st;
    FILE *f = fopen(out, "r");
    long kb = -1;
    assert_non_null(f);
    assert_int_equal(fscanf(f, "%ld", &kb), 1);
    fclose(f);
    assert_true(kb > 0);
    return kb;
}

/* imp34: a 200-byte TIFF declaring a 16000 x 16000 grey image (256 MB decoded, under the caps)
 * with one 100-byte strip is refused, but OpenImageIO's read_image went on through all 16000
 * rows, filling the whole buffer and collecting a message per row (a 20000^2 RGB one: 12 s,
 * 1.4 GB; the daemon's set cap is 8 GiB). The read is banded now and stops at the first band
 * that fails: the import's peak memory stays far below the declared size. Measured in a fresh
 * child (this binary again, posix_spawn: OpenImageIO's threads make a bare fork unsafe) by its
 * peak resident size from wait4, against a child that imports nothing. */
static void a_small_file_declaring_a_huge_image_is_refused_without_decoding_it(void **state)
{
    (void)state;
    enum { W = 16000, H = 16000 };
    uint8_t b[512];
    memset(b, 0, sizeof b);
    memcpy(b, "II*\0", 4);
    put32(b + 4, 8);
    b[8] = 9;
    static const uint16_t tags[9][2] = {{256, 4}, {257, 4}, {258, 3}, {259, 3}, {262, 3},
                                        {273, 4}, {277, 3}, {278, 4}, {279, 4}};
    const uint32_t data = 8 + 2 + 12 * 9 + 4;
    const uint32_t vals[9] = {W, H, 8, 1, 1, data, 1, H, (uint32_t)W * H};
    for (int k = 0; k < 9; k++) {
        uint8_t *t = b + 10 + 12 * k;
        t[0] = (uint8_t)tags[k][0];
        t[1] = (uint8_t)(tags[k][0] >> 8);
        t[2] = (uint8_t)tags[k][1];
        put32(t + 4, 1);
        if (tags[k][1] == 3) {
            t[8] = (uint8_t)vals[k];
            t[9] = (uint8_t)(vals[k] >> 8);
        } else {
            put32(t + 8, vals[k]);
        }
    }
    char p[512];
    tmp_path(p, sizeof p, "huge_decl.tif");
    write_file(p, b, data + 100);
    long base_kb = import_child_peak_kb("/nonexistent/seamtex-import-child.tif", NULL);
    int status = 0;
    long peak_kb = import_child_peak_kb(p, &status);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0); /* refused as truncated (ST_EFORMAT) */
    long grew_kb = peak_kb - base_kb;
    print_message("peak %ld KB in the child, %ld KB in a child importing nothing: %ld KB for a "
                  "%d MB image\n", peak_kb, base_kb, grew_kb, W / 1000 * H / 1000);
#ifndef __SANITIZE_ADDRESS__ /* AddressSanitizer's allocator and shadow change the figures */
    assert_true(grew_kb < 96 * 1024);
#endif
}

static void upload_options_are_parsed_strictly(void **state)
{
    (void)state;
    st_import_opts o;
    char tex[256];
    st_error e;
    st_import_opts_init(&o);
    assert_int_equal(st_import_opts_parse("", &o, tex, sizeof tex, &e), ST_OK);
    assert_int_equal(st_import_opts_parse("cube=latlong:512 colorspace=linear texture=duck-tex",
                                          &o, tex, sizeof tex, &e), ST_OK);
    assert_int_equal(o.cube, ST_IMPORT_CUBE_LATLONG);
    assert_int_equal(o.face_size, 512);
    assert_int_equal(o.colorspace, ST_IMPORT_CS_LINEAR);
    assert_string_equal(tex, "duck-tex");
    const char *bad[] = {"cube=latlong:abc", "cube=latlong:", "cube=latlong:300", "cube=latlong:0",
                         "cube=latlong:+64", "cube=latlong:064", "cube=latlong:65536",
                         "cube=cross_h:64", "cube=sphere", "colorspace=rgb", "colorspace=",
                         "texture=", "zzz=1", "cube", " cube=auto", "cube=auto ",
                         "cube=auto  colorspace=srgb", "cube=auto cube=none"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        st_import_opts before = o;
        st_error_clear(&e);
        assert_int_equal(st_import_opts_parse(bad[i], &o, tex, sizeof tex, &e), ST_EINVAL);
        assert_true(strlen(e.msg) > 0);
        assert_memory_equal(&before, &o, sizeof o); /* unchanged on failure */
    }
}

static void ptex_env_cube_is_recognised_by_its_layout_not_its_name(void **state)
{
    (void)state;
    char src[1024];
    if (st_test_data_path(src, sizeof src, "ptx/wdas-ptex-samples/envcube/envcube.ptx"))
        skip();
    size_t len;
    void *b = read_file(src, &len);
    char p[512];
    tmp_path(p, sizeof p, "source-17.ptx"); /* as the daemon stores an upload */
    write_file(p, b, len);
    free(b);
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_OK);
    assert_int_equal(s->info.kind, ST_KIND_CUBE);
    st_set_free(s);
}

/* A BC1 DDS file (what COMPRESS stores and FETCH exports) imports through the dispatcher as
 * the same BC1 set; a DDS of another format and a truncated one are refused. */
static void bc1_dds_imports_as_the_same_bc1_set(void **state)
{
    (void)state;
    char src[512], p[512];
    if (st_test_data_path(src, sizeof src, "ptex-ref/cube8_k6_u8_rot.ptx"))
        skip();
    st_set *s = NULL, *b = NULL, *r = NULL;
    st_error e;
    assert_int_equal(st_import_file(src, NULL, &s, &e), ST_OK);
    st_bc1_opts o;
    st_bc1_opts_default(&o);
    o.level = ST_BC1_FAST;
    o.threads = 1;
    assert_int_equal(st_bc1_compress_set(s, &o, NULL, NULL, NULL, &b, &e), ST_OK);
    tmp_path(p, sizeof p, "cube8.dds");
    assert_int_equal(st_dds_write_file(b, p, &e), ST_OK);
    size_t len = 0;
    unsigned char *bytes = read_file(p, &len);
    assert_int_equal(st_import_detect(bytes, len, "noext"), ST_FMT_DDS);
    assert_int_equal(st_import_file(p, NULL, &r, &e), ST_OK);
    assert_int_equal(r->info.kind, ST_KIND_BC1);
    assert_int_equal(r->info.nfaces, b->info.nfaces);
    assert_int_equal(r->texel_bytes, b->texel_bytes);
    assert_memory_equal(r->texels, b->texels, b->texel_bytes);
    st_set_free(r);
    r = NULL;
    /* asked to be a cube: refused with a message, not silently ignored */
    st_import_opts io;
    st_import_opts_init(&io);
    io.cube = ST_IMPORT_CUBE_STRIP_V;
    assert_int_equal(st_import_file(p, &io, &r, &e), ST_EINVAL);
    assert_null(r);
    /* truncated: a clear error, nothing returned */
    write_file(p, bytes, len / 2);
    assert_true(st_import_file(p, NULL, &r, &e) < 0);
    assert_null(r);
    /* a DXT5 header is not BC1 */
    bytes[84] = 'D', bytes[85] = 'X', bytes[86] = 'T', bytes[87] = '5';
    write_file(p, bytes, len);
    assert_true(st_import_file(p, NULL, &r, &e) < 0);
    assert_null(r);
    free(bytes);
    st_set_free(b);
    st_set_free(s);
}

static void detection_uses_magic_before_extension(void **state)
{
    (void)state;
    assert_int_equal(st_import_detect("Ptex\1", 5, "x.png"), ST_FMT_PTEX);
    assert_int_equal(st_import_detect("\x76\x2f\x31\x01", 4, "x.png"), ST_FMT_EXR);
    assert_int_equal(st_import_detect("DRACO\2\2", 7, "x.obj"), ST_FMT_DRACO);
    assert_int_equal(st_import_detect("\x89PNG\r\n\x1a\n", 8, "x.exr"), ST_FMT_IMAGE);
    assert_int_equal(st_import_detect("# a\nv 1 2 3\n", 12, "noext"), ST_FMT_OBJ);
    assert_int_equal(st_import_detect("xx", 2, "a.penv"), ST_FMT_PTEX);
    assert_int_equal(st_import_detect("xx", 2, "a.TIF"), ST_FMT_IMAGE);
    assert_int_equal(st_import_detect("xx", 2, "a.bin"), ST_FMT_AUTO);
    assert_int_equal(st_import_detect("DDS \x7c", 5, "x.png"), ST_FMT_DDS);
    assert_int_equal(st_import_detect("xx", 2, "a.DDS"), ST_FMT_DDS);
    char p[512];
    tmp_path(p, sizeof p, "junk.bin");
    write_file(p, "hello world", 11);
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_EFORMAT);
    tmp_path(p, sizeof p, "missing.png");
    assert_int_equal(st_import_file(p, NULL, &s, &e), ST_ENOTFOUND);
}

int main(void)
{
    const char *child = getenv("ST_IMPORT_CHILD"); /* import_child_peak_kb's child */
    if (child) {
        st_error e;
        st_set *s = NULL;
        int rc = st_import_file(child, NULL, &s, &e);
        st_set_free(s);
        const char *out = getenv("ST_IMPORT_CHILD_OUT");
        FILE *f = out ? fopen(out, "w") : NULL;
        if (!f || fprintf(f, "%ld\n", vm_hwm_kb()) < 0 || fclose(f))
            return 2;
        return rc == ST_EFORMAT ? 0 : 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(shared_assets_import_or_fail_as_expected),
        cmocka_unit_test(colour_space_is_stated_and_can_be_overridden),
        cmocka_unit_test(bc1_dds_imports_as_the_same_bc1_set),
        cmocka_unit_test(exr_channels_come_in_rgba_order_from_the_c_api),
        cmocka_unit_test(exr_takes_rgba_by_name_from_extra_channels_and_layers),
        cmocka_unit_test(exr_c_api_matches_openimageio_on_the_orientation_maps),
        cmocka_unit_test(precision_is_kept_for_16_bit_and_float),
        cmocka_unit_test(png_writer_round_trips_8_bit_and_refuses_dds),
        cmocka_unit_test(obj_reader_handles_polygons_negative_indices_groups_and_materials),
        cmocka_unit_test(mtl_paths_outside_the_mesh_folder_are_not_followed),
        cmocka_unit_test(obj_with_backslash_texture_path_imports_as_an_atlas),
        cmocka_unit_test(draco_duck_pairs_with_its_texture),
        cmocka_unit_test(draco_header_declaring_too_many_faces_is_refused_before_decoding),
        cmocka_unit_test(exr_from_memory_matches_exr_from_the_file),
        cmocka_unit_test(failed_image_reads_leave_the_image_empty),
        cmocka_unit_test(obj_nan_uv_and_out_of_range_indices_are_refused_naming_the_line),
        cmocka_unit_test(obj_over_the_caps_is_refused),
        cmocka_unit_test(mesh_triangles_count_against_the_byte_cap),
        cmocka_unit_test(mtl_map_names_keep_spaces_skip_options_and_follow_the_mtl_folder),
        cmocka_unit_test(long_material_names_stay_one_material),
        cmocka_unit_test(obj_vn_indices_junk_tokens_and_long_numbers),
        cmocka_unit_test(huge_png_dimensions_are_refused_before_allocation),
        cmocka_unit_test(exr_with_a_huge_data_window_is_refused),
        cmocka_unit_test(caps_on_dimension_and_bytes_are_enforced),
        cmocka_unit_test(truncated_files_are_refused_cleanly),
        cmocka_unit_test(exr_luminance_chroma_images_are_refused_not_made_grey),
        cmocka_unit_test(exr_grey_with_alpha_keeps_both_and_chroma_with_alpha_is_refused),
        cmocka_unit_test(exr_ripmap_imports_level_0_and_a_cut_ripmap_is_refused),
        cmocka_unit_test(exr_multipart_ripmap_imports_part_0_and_a_cut_one_is_refused),
        cmocka_unit_test(signed_16_bit_tiff_keeps_its_negative_values),
        cmocka_unit_test(tiff_without_bits_per_sample_is_refused_not_made_up),
        cmocka_unit_test(premultiplied_flag_follows_the_file),
        cmocka_unit_test(tiff_channels_are_alpha_only_when_the_file_says_so),
        cmocka_unit_test(exr_xyz_channels_are_a_vector_not_luminance),
        cmocka_unit_test(exr_deep_and_subsampled_files_are_refused_with_their_reason),
        cmocka_unit_test(image_reader_messages_are_one_line),
        cmocka_unit_test(exr_cube_maps_take_no_other_layout),
        cmocka_unit_test(a_small_file_declaring_a_huge_image_is_refused_without_decoding_it),
        cmocka_unit_test(ptex_env_cube_is_recognised_by_its_layout_not_its_name),
        cmocka_unit_test(detection_uses_magic_before_extension),
        cmocka_unit_test(upload_options_are_parsed_strictly),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
