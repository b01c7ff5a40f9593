/* store/import/export.c - sets out as standard files (see export.h for the table). */
#include "export.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "atlas.h"
#include "bc1.h"
#include "cube.h"
#include "fileio.h"
#include "image_io.h"
#include "ptex.h"

static const char *const NAMES[ST_EXPORT_COUNT] = {"ptx", "dds", "exr", "png", "obj"};

const char *st_export_format_name(int format)
{
    return format >= 0 && format < ST_EXPORT_COUNT ? NAMES[format] : NULL;
}

unsigned st_export_formats(const st_set *s)
{
    if (!s)
        return 0;
    int flt = s->info.dtype == ST_DT_HALF || s->info.dtype == ST_DT_F32;
    switch (s->info.kind) {
    case ST_KIND_PERFACE:
        return 1u << ST_EXPORT_PTX;
    case ST_KIND_CUBE:
        return 1u << ST_EXPORT_PTX | (flt ? 1u << ST_EXPORT_EXR : 0);
    case ST_KIND_ATLAS: {
        const st_atlas *a = st_atlas_get(s);
        return (flt ? 1u << ST_EXPORT_EXR : 1u << ST_EXPORT_PNG) |
               (a && a->mesh ? 1u << ST_EXPORT_OBJ : 0);
    }
    case ST_KIND_BC1:
        return 1u << ST_EXPORT_DDS;
    default:
        return 0;
    }
}

/* A growing text buffer for the OBJ writer. */
typedef struct tbuf { char *p; size_t len, cap; int oom; } tbuf;

static void tprintf(tbuf *b, const char *fmt, ...)
{
    if (b->oom)
        return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(b->p ? b->p + b->len : NULL, b->p ? b->cap - b->len : 0, fmt, ap);
        va_end(ap);
        if (n < 0) {
            b->oom = 1;
            return;
        }
        if (b->p && (size_t)n < b->cap - b->len) {
            b->len += (size_t)n;
            return;
        }
        size_t cap = b->cap ? b->cap * 2 : 65536;
        while (cap - b->len <= (size_t)n)
            cap *= 2;
        char *q = realloc(b->p, cap);
        if (!q) {
            b->oom = 1;
            return;
        }
        b->p = q;
        b->cap = cap;
    }
}

/* The atlas mesh as OBJ: positions, texture coordinates flipped back to OBJ's v-up, one
 * triangle per line (a triangle with a corner lacking a uv is written without vt). Floats
 * with 9 significant digits read back to the same value. */
static int mesh_obj(const st_mesh *m, void **buf, size_t *len, st_error *e)
{
    tbuf b = {0};
    tprintf(&b, "# seamtex atlas mesh: %u positions, %u uvs, %u triangles\n", m->npos, m->nuv,
            m->ntri);
    for (uint32_t i = 0; i < m->npos; i++)
        tprintf(&b, "v %.9g %.9g %.9g\n", m->pos[3 * i], m->pos[3 * i + 1], m->pos[3 * i + 2]);
    for (uint32_t i = 0; i < m->nuv; i++)
        tprintf(&b, "vt %.9g %.9g\n", m->uv[2 * i], 1.0f - m->uv[2 * i + 1]);
    for (uint32_t t = 0; t < m->ntri; t++) {
        const uint32_t *p = m->tri_pos + 3 * t, *u = m->tri_uv + 3 * t;
        if (u[0] == ST_MESH_NO_UV || u[1] == ST_MESH_NO_UV || u[2] == ST_MESH_NO_UV)
            tprintf(&b, "f %u %u %u\n", p[0] + 1, p[1] + 1, p[2] + 1);
        else
            tprintf(&b, "f %u/%u %u/%u %u/%u\n", p[0] + 1, u[0] + 1, p[1] + 1, u[1] + 1,
                    p[2] + 1, u[2] + 1);
    }
    if (b.oom) {
        free(b.p);
        return st_fail(e, ST_ENOMEM, "out of memory writing the mesh");
    }
    *buf = b.p;
    *len = b.len;
    return ST_OK;
}

/* Writes img through OpenImageIO to a temp file in tmpdir and reads it back. */
static int image_mem(const st_image *img, const char *ext, const char *tmpdir, void **buf,
                     size_t *len, st_error *e)
{
    char path[4096];
    const char *dir = tmpdir && *tmpdir ? tmpdir : getenv("TMPDIR");
    if (!dir || !*dir)
        dir = "/tmp";
    if ((size_t)snprintf(path, sizeof path, "%s/seamtex-export-XXXXXX.%s", dir, ext) >= sizeof path)
        return st_fail(e, ST_EINVAL, "temp folder path too long");
    int fd = mkstemps(path, (int)strlen(ext) + 1);
    if (fd < 0)
        return st_fail(e, ST_EIO, "cannot create a temp file for the export: %s", strerror(errno));
    close(fd);
    int rc = st_image_write_img(path, img, e);
    /* OpenImageIO 2.4 reports success for a file its writes could not fill (a full disk left
     * a 0-byte PNG, served as the set): the file must read back as this image before it is
     * handed out. */
    if (rc == ST_OK) {
        st_image back;
        st_error be;
        st_error_clear(&be);
        st_image_caps caps = {0, SIZE_MAX / 2};
        int brc = st_image_read_any(path, &caps, &back, &be);
        int same = brc == ST_OK && back.w == img->w && back.h == img->h;
        st_image_free(&back);
        if (!same) {
            struct statvfs vfs;
            int full = statvfs(dir, &vfs) == 0 && vfs.f_bavail == 0;
            rc = st_fail(e, ST_EIO, "the %s file written for the export does not read back "
                         "(%.200s)%s", ext, brc ? be.msg : "another size",
                         full ? ": No space left on device" : "");
        }
    }
    if (rc == ST_OK)
        rc = st_file_read(path, SIZE_MAX / 2, buf, len, e);
    unlink(path);
    return rc;
}

int st_export_mem(const st_set *s, int format, const char *tmpdir, void **buf, size_t *len,
                  st_error *e)
{
    *buf = NULL;
    *len = 0;
    unsigned fits = st_export_formats(s);
    if (format < 0 || format >= ST_EXPORT_COUNT || !(fits & (1u << format))) {
        char list[64] = "";
        for (int f = 0; f < ST_EXPORT_COUNT; f++)
            if (fits & (1u << f))
                snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s",
                         list[0] ? " " : "", NAMES[f]);
        return st_fail(e, ST_EUNSUPPORTED, "this set cannot be fetched as %s (it can be as: %s)",
                       st_export_format_name(format) ? st_export_format_name(format) : "that format",
                       list[0] ? list : "nothing");
    }
    switch (s->info.kind) {
    case ST_KIND_PERFACE:
        return st_ptex_write_mem(s, buf, len, e);
    case ST_KIND_BC1: {
        uint8_t *b = NULL;
        int rc = st_dds_write_mem(s, &b, len, e);
        *buf = b;
        return rc;
    }
    case ST_KIND_CUBE: {
        if (format == ST_EXPORT_PTX) {
            st_set *px = NULL;
            int rc = st_cube_to_ptex_env(s, 0, &px, e);
            if (rc == ST_OK)
                rc = st_ptex_write_mem(px, buf, len, e);
            st_set_free(px);
            return rc;
        }
        st_image img;
        int rc = st_cube_to_image(s, 0, ST_CUBE_STRIP_V, &img, e);
        if (rc)
            return rc;
        rc = image_mem(&img, "exr", tmpdir, buf, len, e);
        st_image_free(&img);
        return rc;
    }
    case ST_KIND_ATLAS: {
        if (format == ST_EXPORT_OBJ)
            return mesh_obj(st_atlas_get(s)->mesh, buf, len, e);
        const st_face *F = &s->faces[0];
        st_image img = {.w = F->w, .h = F->h, .nchan = s->info.nchan, .dtype = s->info.dtype,
                        .colorspace = s->info.colorspace, .alpha_chan = s->info.alpha_chan,
                        .premultiplied = s->info.premultiplied,
                        .envmap = ST_ENVMAP_NONE, .nlevels_file = 1,
                        .data = st_face_level(s, 0, 0)};
        if (F->flags & ST_FACE_CONSTANT)
            return st_fail(e, ST_EUNSUPPORTED, "a constant atlas face cannot be fetched as an image");
        return image_mem(&img, format == ST_EXPORT_EXR ? "exr" : "png", tmpdir, buf, len, e);
    }
    default:
        return st_fail(e, ST_EUNSUPPORTED, "unknown set kind %u", s->info.kind);
    }
}
