/* store/import/import.c - the import dispatcher: detects a file's format and turns it into a set.
 *
 * Owns: st_import_opts_init, st_import_opts_parse (the upload options grammar), st_import_detect, st_import_file, st_import_format_name.
 * Does not own: the readers (ptex_read.c, exr.c, image_oiio.cpp, obj.c, draco.cpp), cube
 * conversions (cube_convert.c), atlas building (atlas.c). The rules are in import.h.
 *
 * Order of checks for a file: it must exist and be no larger than the byte cap; the magic
 * decides the format (the extension only when no magic matches: OBJ is text); then the
 * reader checks its own header against the caps before allocating texels.
 */
#include "import.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "atlas.h"
#include "bc1.h"
#include "cube.h"
#include "exr.h"
#include "image.h"
#include "mesh.h"
#include "ptex.h"
#include "image_io.h"
#include "mesh_io.h"

#define DEFAULT_MAX_FILE ((size_t)2 << 30)

void st_import_opts_init(st_import_opts *o)
{
    memset(o, 0, sizeof *o);
}

const char *st_import_format_name(int fmt)
{
    switch (fmt) {
    case ST_FMT_PTEX: return "ptex";
    case ST_FMT_EXR: return "exr";
    case ST_FMT_IMAGE: return "image";
    case ST_FMT_OBJ: return "obj";
    case ST_FMT_DRACO: return "draco";
    case ST_FMT_DDS: return "dds";
    default: return "auto";
    }
}

static const char *ext_of(const char *name)
{
    if (!name)
        return "";
    const char *dot = strrchr(name, '.'), *slash = strrchr(name, '/');
    return dot && (!slash || dot > slash) ? dot + 1 : "";
}

/* OBJ has no magic: the first statement of the text must be an OBJ keyword. */
static int looks_like_obj(const unsigned char *h, size_t len)
{
    size_t i = 0;
    while (i < len) {
        while (i < len && (h[i] == ' ' || h[i] == '\t' || h[i] == '\r' || h[i] == '\n'))
            i++;
        if (i >= len)
            return 0;
        if (h[i] == '#') {
            while (i < len && h[i] != '\n')
                i++;
            continue;
        }
        static const char *kw[] = {"v ", "vt ", "vn ", "vp ", "f ", "o ", "g ", "s ", "mtllib ",
                                   "usemtl ", "v\t", "f\t"};
        for (size_t k = 0; k < sizeof kw / sizeof kw[0]; k++) {
            size_t l = strlen(kw[k]);
            if (len - i >= l && !memcmp(h + i, kw[k], l))
                return 1;
        }
        return 0;
    }
    return 0;
}

static const struct { const char *name; uint8_t v; } CUBE_KINDS[] = {
    {"none", ST_IMPORT_CUBE_NONE},       {"auto", ST_IMPORT_CUBE_AUTO},
    {"strip_v", ST_IMPORT_CUBE_STRIP_V}, {"strip_h", ST_IMPORT_CUBE_STRIP_H},
    {"cross_h", ST_IMPORT_CUBE_CROSS_H}, {"cross_v", ST_IMPORT_CUBE_CROSS_V},
    {"latlong", ST_IMPORT_CUBE_LATLONG}, {"ptex", ST_IMPORT_CUBE_PTEX}};

/* A decimal power of two 1..ST_MAX_DIM: digits only, no sign, no leading zero. */
static int parse_face_size(const char *p, size_t n, uint32_t *out)
{
    if (n == 0 || n > 5 || p[0] == '0')
        return -1;
    uint32_t v = 0;
    for (size_t i = 0; i < n; i++) {
        if (p[i] < '0' || p[i] > '9')
            return -1;
        v = v * 10 + (uint32_t)(p[i] - '0');
    }
    if (v > ST_MAX_DIM || (v & (v - 1)))
        return -1;
    *out = v;
    return 0;
}

int st_import_opts_parse(const char *text, st_import_opts *o, char *texture, size_t cap,
                         st_error *e)
{
    st_import_opts r = *o;
    int seen_cube = 0, seen_cs = 0, seen_tex = 0;
    if (cap)
        texture[0] = 0;
    const char *p = text ? text : "";
    if (*p == ' ')
        return st_fail(e, ST_EINVAL, "options: a leading space");
    while (*p) {
        const char *end = strchr(p, ' ');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        if (n == 0)
            return st_fail(e, ST_EINVAL, "options: two spaces in a row");
        if (end && !end[1])
            return st_fail(e, ST_EINVAL, "options: a trailing space");
        const char *eq = memchr(p, '=', n);
        if (!eq)
            return st_fail(e, ST_EINVAL, "option '%.*s' is not key=value", (int)(n > 64 ? 64 : n), p);
        size_t kl = (size_t)(eq - p), vl = n - kl - 1;
        const char *v = eq + 1;
        if (kl == 4 && !memcmp(p, "cube", 4)) {
            if (seen_cube++)
                return st_fail(e, ST_EINVAL, "option cube given twice");
            const char *colon = memchr(v, ':', vl);
            size_t knl = colon ? (size_t)(colon - v) : vl;
            int found = -1;
            for (size_t i = 0; i < sizeof CUBE_KINDS / sizeof CUBE_KINDS[0]; i++)
                if (strlen(CUBE_KINDS[i].name) == knl && !memcmp(CUBE_KINDS[i].name, v, knl))
                    found = CUBE_KINDS[i].v;
            if (found < 0)
                return st_fail(e, ST_EINVAL, "cube=%.*s: not one of none auto strip_v strip_h "
                               "cross_h cross_v latlong ptex", (int)(knl > 32 ? 32 : knl), v);
            r.cube = (uint8_t)found;
            r.face_size = 0;
            if (colon) {
                if (found != ST_IMPORT_CUBE_LATLONG)
                    return st_fail(e, ST_EINVAL, "cube=%.*s: only latlong takes a face size",
                                   (int)(vl > 40 ? 40 : vl), v);
                if (parse_face_size(colon + 1, vl - knl - 1, &r.face_size))
                    return st_fail(e, ST_EINVAL, "cube=%.*s: the face size must be a power of "
                                   "two from 1 to %u", (int)(vl > 40 ? 40 : vl), v, ST_MAX_DIM);
            }
        } else if (kl == 10 && !memcmp(p, "colorspace", 10)) {
            if (seen_cs++)
                return st_fail(e, ST_EINVAL, "option colorspace given twice");
            if (vl == 4 && !memcmp(v, "auto", 4))
                r.colorspace = ST_IMPORT_CS_AUTO;
            else if (vl == 4 && !memcmp(v, "srgb", 4))
                r.colorspace = ST_IMPORT_CS_SRGB;
            else if (vl == 6 && !memcmp(v, "linear", 6))
                r.colorspace = ST_IMPORT_CS_LINEAR;
            else
                return st_fail(e, ST_EINVAL, "colorspace=%.*s: not one of auto srgb linear",
                               (int)(vl > 32 ? 32 : vl), v);
        } else if (kl == 7 && !memcmp(p, "texture", 7)) {
            if (seen_tex++)
                return st_fail(e, ST_EINVAL, "option texture given twice");
            if (vl == 0 || vl > 255 || vl >= cap)
                return st_fail(e, ST_EINVAL, "texture=: a set name of 1 to 255 bytes");
            memcpy(texture, v, vl);
            texture[vl] = 0;
        } else {
            return st_fail(e, ST_EINVAL, "unknown option '%.*s' (texture, cube, colorspace)",
                           (int)(kl > 32 ? 32 : kl), p);
        }
        p += n;
        if (*p == ' ')
            p++;
    }
    *o = r;
    return ST_OK;
}

int st_import_detect(const void *head, size_t len, const char *name)
{
    const unsigned char *h = head;
    if (len >= 4 && !memcmp(h, "Ptex", 4))
        return ST_FMT_PTEX;
    if (st_exr_is_magic(h, len))
        return ST_FMT_EXR;
    if (len >= 5 && !memcmp(h, "DRACO", 5))
        return ST_FMT_DRACO;
    if (len >= 4 && !memcmp(h, "DDS ", 4))
        return ST_FMT_DDS;
    if ((len >= 8 && !memcmp(h, "\x89PNG\r\n\x1a\n", 8)) || (len >= 3 && !memcmp(h, "\xff\xd8\xff", 3)) ||
        (len >= 4 && (!memcmp(h, "II*\0", 4) || !memcmp(h, "MM\0*", 4))) ||
        (len >= 2 && !memcmp(h, "#?", 2)) || (len >= 2 && !memcmp(h, "BM", 2)) ||
        (len >= 4 && !memcmp(h, "8BPS", 4)) || (len >= 4 && !memcmp(h, "GIF8", 4)))
        return ST_FMT_IMAGE;
    const char *x = ext_of(name);
    if (!strcasecmp(x, "ptx") || !strcasecmp(x, "penv"))
        return ST_FMT_PTEX;
    if (!strcasecmp(x, "exr"))
        return ST_FMT_EXR;
    if (!strcasecmp(x, "drc"))
        return ST_FMT_DRACO;
    if (!strcasecmp(x, "dds"))
        return ST_FMT_DDS;
    if (!strcasecmp(x, "obj") || looks_like_obj(h, len))
        return ST_FMT_OBJ;
    static const char *img[] = {"png", "jpg", "jpeg", "tif", "tiff", "hdr", "tga", "bmp", "psd",
                                "gif", "webp", "pnm", "ppm", "pgm", "tx", "sgi", "rgbe", "dpx"};
    for (size_t k = 0; k < sizeof img / sizeof img[0]; k++)
        if (!strcasecmp(x, img[k]))
            return ST_FMT_IMAGE;
    return ST_FMT_AUTO;
}

static void apply_cs(st_set *s, const st_import_opts *o)
{
    if (o->colorspace == ST_IMPORT_CS_LINEAR)
        s->info.colorspace = ST_CS_LINEAR;
    else if (o->colorspace == ST_IMPORT_CS_SRGB)
        s->info.colorspace = ST_CS_SRGB;
}

static int add_format_meta(st_set *s, int fmt, st_error *e)
{
    const char *n = st_import_format_name(fmt);
    return st_set_meta_add(s, "seamtex:source_format", 0, n, (uint32_t)strlen(n) + 1, e);
}

static int import_six(const char *pattern, const st_import_opts *o, st_image_caps *caps,
                      st_set **out, st_error *e)
{
    static const char *def[6] = {"+x", "-x", "+y", "-y", "+z", "-z"};
    const char *pc = strstr(pattern, "%s");
    if (!pc || strstr(pc + 2, "%"))
        return st_fail(e, ST_EINVAL, "six-face import needs a path pattern with one %%s");
    st_image faces[6];
    memset(faces, 0, sizeof faces);
    int rc = ST_OK;
    for (int f = 0; f < 6 && rc == ST_OK; f++) {
        char path[4096];
        const char *nm = o->face_names[f] ? o->face_names[f] : def[f];
        int n = snprintf(path, sizeof path, "%.*s%s%s", (int)(pc - pattern), pattern, nm, pc + 2);
        if (n < 0 || (size_t)n >= sizeof path) {
            rc = st_fail(e, ST_EINVAL, "face path too long");
            break;
        }
        rc = st_image_read_any(path, caps, &faces[f], e);
    }
    if (rc == ST_OK)
        rc = st_cube_from_faces(faces, (st_cube_faces_conv)o->six_conv, o->max_bytes, out, e);
    for (int f = 0; f < 6; f++)
        st_image_free(&faces[f]);
    return rc;
}

static const char *cube_kind_name(unsigned v)
{
    for (size_t i = 0; i < sizeof CUBE_KINDS / sizeof CUBE_KINDS[0]; i++)
        if (CUBE_KINDS[i].v == v)
            return CUBE_KINDS[i].name;
    return v == ST_IMPORT_CUBE_SIX ? "six" : "?";
}

/* A cube conversion the file's format cannot take is refused, never ignored (PROTOCOL.md 4.8:
 * a client that asked for a cube map must not get another kind of set with OK). Images take
 * the layouts (image_to_set), a Ptex file `ptex` (6 faces, checked once read), a mesh none;
 * `none` and `auto` fit every format but a BC1 DDS (`none` only: its own case below).
 * cube_lenient skips the check: images and DDS files were refused before session 32 already,
 * so only Ptex files and meshes can have been recorded with a kind they cannot take. */
static int cube_option_fits(int fmt, const st_import_opts *o, const char *path, st_error *e)
{
    if (o->cube == ST_IMPORT_CUBE_NONE || o->cube == ST_IMPORT_CUBE_AUTO || o->cube_lenient)
        return ST_OK;
    if (fmt == ST_FMT_PTEX && o->cube == ST_IMPORT_CUBE_PTEX)
        return ST_OK;
    if (fmt == ST_FMT_PTEX)
        return st_fail(e, ST_EINVAL, "%s: cube=%s applies to images; a Ptex file takes "
                       "cube=ptex (a 6-face file), auto or none", path, cube_kind_name(o->cube));
    if (fmt == ST_FMT_OBJ || fmt == ST_FMT_DRACO)
        return st_fail(e, ST_EINVAL, "%s: cube=%s does not apply to a mesh (an atlas set; "
                       "only cube=none or auto)", path, cube_kind_name(o->cube));
    return ST_OK;
}

static int is_env_ptex(const st_set *s, const char *path, const st_import_opts *o)
{
    if (s->info.nfaces != 6)
        return 0;
    if (o->cube == ST_IMPORT_CUBE_PTEX || !strcasecmp(ext_of(path), "penv"))
        return 1;
    /* a .ptx with exactly the env-cube adjacency is one (a textured 6-quad cube model has its
     * own face order, e.g. ptex-ref/cube1_k6_u8.ptx) */
    return st_cube_is_ptex_env_layout(s);
}

static int image_to_set(st_image *img, const st_import_opts *o, st_set **out, st_error *e)
{
    int layout = -1;
    switch (o->cube) {
    case ST_IMPORT_CUBE_STRIP_V: layout = ST_CUBE_STRIP_V; break;
    case ST_IMPORT_CUBE_STRIP_H: layout = ST_CUBE_STRIP_H; break;
    case ST_IMPORT_CUBE_CROSS_H: layout = ST_CUBE_CROSS_H; break;
    case ST_IMPORT_CUBE_CROSS_V: layout = ST_CUBE_CROSS_V; break;
    case ST_IMPORT_CUBE_LATLONG: layout = ST_CUBE_LATLONG; break;
    case ST_IMPORT_CUBE_AUTO:
        /* an OpenEXR cube map is its vertical strip (or refused), never an atlas by its aspect */
        layout = img->envmap == ST_ENVMAP_CUBE ? ST_CUBE_STRIP_V : st_cube_guess_layout(img);
        if (layout == ST_CUBE_LATLONG && img->envmap != ST_ENVMAP_LATLONG)
            layout = -1; /* a 2:1 photo stays an image unless it says it is an environment */
        break;
    default:
        if (img->envmap == ST_ENVMAP_CUBE)
            layout = ST_CUBE_STRIP_V; /* OpenEXR envmap=cube is a vertical strip */
        break;
    }
    /* an OpenEXR cube map says what it is: read as a lat-long image, a horizontal strip or a
     * cross its vertical strip would make a wrong cube without a word (cube_lenient: as before,
     * for sets recorded with that option) */
    if (img->envmap == ST_ENVMAP_CUBE && layout >= 0 && layout != ST_CUBE_STRIP_V &&
        !o->cube_lenient)
        return st_fail(e, ST_EINVAL, "the file is an OpenEXR cube map (envmap=cube, a vertical "
                       "strip); cube=%s does not apply to it", cube_kind_name(o->cube));
    if (layout >= 0)
        return st_cube_from_image(img, (st_cube_layout)layout, o->face_size, o->max_bytes, out, e);
    if (o->cube != ST_IMPORT_CUBE_NONE && o->cube != ST_IMPORT_CUBE_AUTO)
        return st_fail(e, ST_EINVAL, "cube=%s does not apply to an image (it takes strip_v, "
                       "strip_h, cross_h, cross_v, latlong, auto or none)",
                       cube_kind_name(o->cube));
    return st_atlas_from_image(img, NULL, o->max_bytes, out, e);
}

static int copy_atlas_texture(const st_set *t, st_set **out, st_error *e)
{
    if (t->info.kind != ST_KIND_ATLAS || t->info.nfaces != 1)
        return st_fail(e, ST_EINVAL, "the texture to pair a mesh with must be an atlas set");
    st_face_desc fd;
    memset(&fd, 0, sizeof fd);
    fd.w = t->faces[0].w;
    fd.h = t->faces[0].h;
    for (int k = 0; k < 4; k++)
        fd.adjface[k] = -1;
    int rc = st_set_levels(t, e); /* every level is copied (set.h) */
    if (rc || (rc = st_set_create(&t->info, &fd, 0, out, e)))
        return rc;
    memcpy((*out)->texels, t->texels, t->texel_bytes);
    return ST_OK;
}

static int mesh_to_set(const char *path, int fmt, const st_import_opts *o, st_image_caps *caps,
                       st_set **out, st_error *e)
{
    st_mesh_caps mc = {0, 0, o->max_bytes, o->no_side_files};
    /* the mesh stays with the set: its memory counts against the same cap as the texels */
    if (o->max_bytes && o->max_bytes / ST_MESH_BYTES_PER_TRI < ST_MESH_MAX_TRIS)
        mc.max_tris = (uint32_t)(o->max_bytes / ST_MESH_BYTES_PER_TRI);
    st_mesh *m = NULL;
    int rc = fmt == ST_FMT_OBJ ? st_obj_read_file(path, &mc, &m, e)
                               : st_draco_read_file(path, &mc, &m, e);
    if (rc == ST_ETOOBIG && mc.max_tris) {
        char m0[sizeof e->msg];
        snprintf(m0, sizeof m0, "%s", e->msg);
        return st_fail(e, ST_ETOOBIG, "%s (a byte cap of %zu allows %u triangles, about %u bytes "
                       "each)", m0, o->max_bytes, mc.max_tris, ST_MESH_BYTES_PER_TRI);
    }
    if (rc)
        return rc;
    if ((rc = st_mesh_require_uv(m, e)) != ST_OK) {
        st_mesh_free(m);
        return rc;
    }
    if (o->texture) {
        rc = copy_atlas_texture(o->texture, out, e);
        if (rc == ST_OK) {
            st_atlas *a = st_atlas_new();
            if (!a) {
                st_mesh_free(m);
                return st_fail(e, ST_ENOMEM, "out of memory for the atlas");
            }
            st_set_ext x;
            st_atlas_ext(a, &x);
            st_set_ext_attach(*out, &x);
            rc = st_atlas_attach_mesh(*out, m, e);
        } else {
            st_mesh_free(m);
        }
        if (rc) {
            st_set_free(*out);
            *out = NULL;
        }
        return rc;
    }
    const char *tex = o->texture_path;
    for (uint32_t i = 0; !tex && i < m->nmat; i++)
        if (m->mats[i].map_kd[0]) {
            struct stat sb;
            if (!stat(m->mats[i].map_kd, &sb))
                tex = m->mats[i].map_kd;
        }
    if (!tex) {
        st_mesh_free(m);
        return st_fail(e, ST_EINVAL, "%s: a mesh needs a texture (%s)", path,
                       o->no_side_files ? "none given; the files an OBJ names (mtllib, map_Kd) "
                                          "are not opened here"
                                        : "none given and no map_Kd found");
    }
    st_image img;
    if ((rc = st_image_read_any(tex, caps, &img, e)) != ST_OK) {
        st_mesh_free(m);
        return rc;
    }
    if (img.envmap != ST_ENVMAP_NONE) {
        /* a file that imports as a cube map on its own is one here too: as the daemon's
         * texture= refuses a cube set, so does a texture file */
        rc = st_fail(e, ST_EINVAL, "%s: the texture to pair a mesh with must be an atlas image, "
                     "not an environment map (envmap=%s)", tex,
                     img.envmap == ST_ENVMAP_CUBE ? "cube" : "latlong");
        st_image_free(&img);
        st_mesh_free(m); /* after the message: tex may be one of its materials' names */
        return rc;
    }
    rc = st_atlas_from_image(&img, m, o->max_bytes, out, e);
    if (rc == ST_OK) {
        st_atlas *a = st_set_ext_get(*out, ST_EXT_ATLAS);
        size_t tl = strlen(tex), cap = sizeof a->texture_name;
        const char *t = tl >= cap ? tex + tl - (cap - 1) : tex; /* keep the file name end */
        memcpy(a->texture_name, t, strlen(t) + 1);
    }
    st_image_free(&img);
    return rc;
}

int st_import_file(const char *path, const st_import_opts *opts, st_set **out, st_error *e)
{
    *out = NULL;
    st_import_opts def;
    if (!opts) {
        st_import_opts_init(&def);
        opts = &def;
    }
    if (!path)
        return st_fail(e, ST_EINVAL, "no path");
    st_image_caps caps = {opts->max_dim, opts->max_bytes};
    if (opts->cube == ST_IMPORT_CUBE_SIX)
        return import_six(path, opts, &caps, out, e);
    struct stat sb;
    if (stat(path, &sb))
        return st_fail(e, ST_ENOTFOUND, "%s: no such file", path);
    if (!S_ISREG(sb.st_mode))
        return st_fail(e, ST_EINVAL, "%s: not a regular file", path);
    size_t maxf = opts->max_bytes ? opts->max_bytes : DEFAULT_MAX_FILE;
    if ((uint64_t)sb.st_size > maxf)
        return st_fail(e, ST_ETOOBIG, "%s: %lld bytes is over the %zu byte cap", path,
                       (long long)sb.st_size, maxf);
    unsigned char head[256];
    size_t hn = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return st_fail(e, ST_EIO, "%s: cannot open", path);
    hn = fread(head, 1, sizeof head, f);
    fclose(f);
    if (hn == 0)
        return st_fail(e, ST_EFORMAT, "%s: empty file", path);
    int fmt = opts->format ? opts->format : st_import_detect(head, hn, path);
    int rc = cube_option_fits(fmt, opts, path, e);
    if (rc)
        return rc;
    switch (fmt) {
    case ST_FMT_PTEX: {
        st_set *p = NULL;
        rc = st_ptex_read_file(path, opts->max_bytes, &p, e);
        if (rc)
            return rc;
        if (opts->cube == ST_IMPORT_CUBE_PTEX && p->info.nfaces != 6 && !opts->cube_lenient) {
            rc = st_fail(e, ST_EINVAL, "%s: cube=ptex needs a 6-face Ptex file; this one has "
                         "%u faces", path, p->info.nfaces);
            st_set_free(p);
            return rc;
        }
        /* Ptex has no colour space: a set seamtex wrote as sRGB says so in its metadata */
        const st_meta_entry *cs = st_set_meta_find(p, ST_META_COLORSPACE);
        if (cs && cs->type == 0 && cs->count == 5 && !memcmp(cs->data, "srgb", 5))
            p->info.colorspace = ST_CS_SRGB;
        if (is_env_ptex(p, path, opts)) {
            /* level 0 only is read; the stored reductions are still checked as before */
            rc = st_set_levels(p, e);
            if (rc == ST_OK)
                rc = st_cube_from_ptex_env(p, opts->max_bytes, out, e);
            if (rc == ST_OK)
                (*out)->info.colorspace = p->info.colorspace;
            st_set_free(p);
        } else {
            *out = p;
        }
        break;
    }
    case ST_FMT_EXR:
    case ST_FMT_IMAGE: {
        st_image img;
        /* EXR: the C API, then OIIO for what the 3.1 C API lacks (DWAA/DWAB; image_io.h) */
        rc = fmt == ST_FMT_EXR ? st_image_read_any(path, &caps, &img, e)
                               : st_image_read(path, &caps, &img, e);
        if (rc)
            return rc;
        rc = image_to_set(&img, opts, out, e);
        st_image_free(&img);
        break;
    }
    case ST_FMT_OBJ:
    case ST_FMT_DRACO:
        rc = mesh_to_set(path, fmt, opts, &caps, out, e);
        break;
    case ST_FMT_DDS:
        if (opts->cube != ST_IMPORT_CUBE_NONE)
            return st_fail(e, ST_EINVAL, "%s: cube conversions do not apply to a BC1 DDS file", path);
        rc = st_dds_read_file(path, opts->max_bytes, out, e);
        break;
    default:
        return st_fail(e, ST_EFORMAT, "%s: unknown format (no known magic or extension)", path);
    }
    if (rc) {
        st_set_free(*out);
        *out = NULL;
        return rc;
    }
    apply_cs(*out, opts);
    if ((rc = add_format_meta(*out, fmt, e)) != ST_OK) {
        st_set_free(*out);
        *out = NULL;
    }
    return rc;
}
