/* render/rmesh.c - the meshes seamtex-render draws: OBJ files read into triangles carrying the
 * texture face and uv of each corner, with smooth vertex normals.
 *
 * Owns: a small OBJ reader (v, vt, f; everything else skipped) and the conversion to rm_mesh.
 * It is the renderer's own: the renderer is a libseamtex client and links no store code on its
 * network path (the store's reader, store/import/obj.c, fan-triangulates and welds for atlas
 * sets, which is not what drawing a Ptex quad mesh needs). Does not own: textures.
 */
#include "render.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RM_MAX_ITEMS (1u << 24)
#define RM_MAX_CORNERS 64

typedef struct fbuf {
    float   *p;
    uint32_t n, cap;   /* in elements */
} fbuf;
typedef struct ubuf {
    uint32_t *p;
    uint32_t  n, cap;
} ubuf;

/* Makes room for one more element of elem bytes in *p (n used, *cap allocated). */
static int room(void **p, uint32_t n, uint32_t *cap, size_t elem)
{
    if (n < *cap)
        return 0;
    uint32_t nc = *cap ? *cap * 2 : 1024;
    void *np = realloc(*p, (size_t)nc * elem);
    if (!np)
        return -1;
    *p = np;
    *cap = nc;
    return 0;
}

static int fpush(fbuf *b, float v)
{
    if (room((void **)&b->p, b->n, &b->cap, sizeof *b->p) != 0)
        return -1;
    b->p[b->n++] = v;
    return 0;
}

static int upush(ubuf *b, uint32_t v)
{
    if (room((void **)&b->p, b->n, &b->cap, sizeof *b->p) != 0)
        return -1;
    b->p[b->n++] = v;
    return 0;
}

/* Resolves an OBJ index (1-based, or negative from the end) against count; -1 when invalid. */
static long obj_index(long i, uint32_t count)
{
    if (i > 0 && (unsigned long)i <= count)
        return i - 1;
    if (i < 0 && (unsigned long)(-i) <= count)
        return (long)count + i;
    return -1;
}

void rm_free(rm_mesh *m)
{
    if (!m)
        return;
    free(m->pos);
    free(m->nrm);
    free(m->tri);
    free(m->uv);
    free(m->face);
    free(m);
}

/* Bounding box and area-weighted vertex normals from the triangles. */
static void finish(rm_mesh *m)
{
    for (int k = 0; k < 3; k++) {
        m->bmin[k] = INFINITY;
        m->bmax[k] = -INFINITY;
    }
    for (uint32_t i = 0; i < m->nverts; i++)
        for (int k = 0; k < 3; k++) {
            float v = m->pos[3 * i + k];
            if (v < m->bmin[k])
                m->bmin[k] = v;
            if (v > m->bmax[k])
                m->bmax[k] = v;
        }
    memset(m->nrm, 0, (size_t)m->nverts * 3 * sizeof *m->nrm);
    for (uint32_t t = 0; t < m->ntris; t++) {
        const float *a = m->pos + 3 * m->tri[3 * t], *b = m->pos + 3 * m->tri[3 * t + 1],
                    *c = m->pos + 3 * m->tri[3 * t + 2];
        float e1[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
        float e2[3] = { c[0] - a[0], c[1] - a[1], c[2] - a[2] };
        float n[3] = { e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                       e1[0] * e2[1] - e1[1] * e2[0] };
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++)
                m->nrm[3 * m->tri[3 * t + k] + j] += n[j];
    }
    for (uint32_t i = 0; i < m->nverts; i++) {
        float *n = m->nrm + 3 * i;
        float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (l > 0)
            for (int j = 0; j < 3; j++)
                n[j] /= l;
    }
}

static rm_mesh *alloc_mesh(uint32_t nverts, uint32_t ntris)
{
    rm_mesh *m = calloc(1, sizeof *m);
    if (!m)
        return NULL;
    m->nverts = nverts;
    m->ntris = ntris;
    m->pos = malloc((size_t)nverts * 3 * sizeof *m->pos);
    m->nrm = malloc((size_t)nverts * 3 * sizeof *m->nrm);
    m->tri = malloc((size_t)ntris * 3 * sizeof *m->tri);
    m->uv = malloc((size_t)ntris * 6 * sizeof *m->uv);
    m->face = malloc((size_t)ntris * sizeof *m->face);
    if (!m->pos || !m->nrm || !m->tri || !m->uv || !m->face) {
        rm_free(m);
        return NULL;
    }
    return m;
}

static const float QUAD_UV[4][2] = { { 0, 0 }, { 1, 0 }, { 1, 1 }, { 0, 1 } };

rm_mesh *rm_from_quads(const float *pos, uint32_t nverts, const uint32_t *quads, uint32_t nquads,
                       char *msg, size_t ml)
{
    if (!pos || !quads || nverts == 0 || nquads == 0 || nverts > RM_MAX_ITEMS ||
        nquads > RM_MAX_ITEMS) {
        rt_say(msg, ml, "a quad mesh needs 1..%u vertices and quads", RM_MAX_ITEMS);
        return NULL;
    }
    for (size_t i = 0; i < (size_t)nquads * 4; i++)
        if (quads[i] >= nverts) {
            rt_say(msg, ml, "quad %zu: vertex %u out of range (%u vertices)", i / 4, quads[i],
                   nverts);
            return NULL;
        }
    rm_mesh *m = alloc_mesh(nverts, 2 * nquads);
    if (!m) {
        rt_say(msg, ml, "out of memory for %u quads", nquads);
        return NULL;
    }
    memcpy(m->pos, pos, (size_t)nverts * 3 * sizeof *pos);
    static const int split[2][3] = { { 0, 1, 2 }, { 0, 2, 3 } };
    for (uint32_t q = 0; q < nquads; q++)
        for (int h = 0; h < 2; h++) {
            uint32_t t = 2 * q + h;
            for (int k = 0; k < 3; k++) {
                int c = split[h][k];
                m->tri[3 * t + k] = quads[4 * q + c];
                m->uv[6 * t + 2 * k] = QUAD_UV[c][0];
                m->uv[6 * t + 2 * k + 1] = QUAD_UV[c][1];
            }
            m->face[t] = q;
        }
    m->nfaces = nquads;
    finish(m);
    return m;
}

typedef struct obj_data {
    fbuf v, vt;
    ubuf fv, fvt, fstart;   /* corners (vertex, uv or UINT32_MAX) and each face's first corner */
} obj_data;

static void obj_free(obj_data *d)
{
    free(d->v.p);
    free(d->vt.p);
    free(d->fv.p);
    free(d->fvt.p);
    free(d->fstart.p);
}

static int parse_floats(const char *s, int n, float *out)
{
    for (int i = 0; i < n; i++) {
        char *end;
        errno = 0;
        double x = strtod(s, &end);
        if (end == s || errno == ERANGE || !isfinite(x) || fabs(x) > 1e30)
            return -1;
        out[i] = (float)x;
        s = end;
    }
    return 0;
}

/* One "f" line: corners "v", "v/vt", "v//vn", "v/vt/vn". */
static int parse_face(obj_data *d, const char *s, unsigned line, char *msg, size_t ml)
{
    unsigned nc = 0;
    if (upush(&d->fstart, d->fv.n) != 0)
        goto oom;
    while (*s) {
        while (*s == ' ' || *s == '\t' || *s == '\r')
            s++;
        if (!*s || *s == '\n' || *s == '#')
            break;
        char *end;
        long vi = strtol(s, &end, 10);
        if (end == s)
            goto bad;
        long vti = 0;
        s = end;
        if (*s == '/') {
            s++;
            if (*s != '/') {
                vti = strtol(s, &end, 10);
                if (end == s)
                    goto bad;
                s = end;
            }
            if (*s == '/') {
                s++;
                strtol(s, &end, 10);
                s = end;
            }
        }
        long v = obj_index(vi, d->v.n / 3);
        if (v < 0) {
            rt_say(msg, ml, "line %u: vertex index %ld out of range (%u vertices so far)", line, vi,
                d->v.n / 3);
            return -1;
        }
        long t = -1;
        if (vti != 0) {
            t = obj_index(vti, d->vt.n / 2);
            if (t < 0) {
                rt_say(msg, ml, "line %u: texture index %ld out of range", line, vti);
                return -1;
            }
        }
        if (++nc > RM_MAX_CORNERS) {
            rt_say(msg, ml, "line %u: a face with more than %d corners", line, RM_MAX_CORNERS);
            return -1;
        }
        if (upush(&d->fv, (uint32_t)v) != 0 || upush(&d->fvt, t < 0 ? UINT32_MAX : (uint32_t)t))
            goto oom;
        if (d->fv.n > RM_MAX_ITEMS) {
            rt_say(msg, ml, "line %u: more than %u face corners", line, RM_MAX_ITEMS);
            return -1;
        }
    }
    if (nc < 3) {
        rt_say(msg, ml, "line %u: a face with %u corners", line, nc);
        return -1;
    }
    return 0;
bad:
    rt_say(msg, ml, "line %u: a face corner that is not a number", line);
    return -1;
oom:
    rt_say(msg, ml, "out of memory at line %u", line);
    return -1;
}

static int obj_read(FILE *f, obj_data *d, char *msg, size_t ml)
{
    char buf[4096];
    unsigned line = 0;
    while (fgets(buf, sizeof buf, f)) {
        line++;
        size_t len = strlen(buf);
        if (len == sizeof buf - 1 && buf[len - 1] != '\n') {
            rt_say(msg, ml, "line %u: longer than %zu bytes", line, sizeof buf - 2);
            return -1;
        }
        const char *s = buf;
        while (*s == ' ' || *s == '\t')
            s++;
        float x[3];
        if (s[0] == 'v' && (s[1] == ' ' || s[1] == '\t')) {
            if (parse_floats(s + 2, 3, x) != 0) {
                rt_say(msg, ml, "line %u: a vertex needs three finite numbers", line);
                return -1;
            }
            if (d->v.n / 3 >= RM_MAX_ITEMS) {
                rt_say(msg, ml, "line %u: more than %u vertices", line, RM_MAX_ITEMS);
                return -1;
            }
            for (int k = 0; k < 3; k++)
                if (fpush(&d->v, x[k]) != 0)
                    goto oom;
        } else if (s[0] == 'v' && s[1] == 't' && (s[2] == ' ' || s[2] == '\t')) {
            if (parse_floats(s + 3, 2, x) != 0) {
                rt_say(msg, ml, "line %u: a texture coordinate needs two finite numbers", line);
                return -1;
            }
            if (d->vt.n / 2 >= RM_MAX_ITEMS) {
                rt_say(msg, ml, "line %u: more than %u texture coordinates", line, RM_MAX_ITEMS);
                return -1;
            }
            if (fpush(&d->vt, x[0]) != 0 || fpush(&d->vt, x[1]) != 0)
                goto oom;
        } else if (s[0] == 'f' && (s[1] == ' ' || s[1] == '\t')) {
            if (parse_face(d, s + 2, line, msg, ml) != 0)
                return -1;
        }
    }
    if (ferror(f)) {
        rt_say(msg, ml, "read error: %s", strerror(errno));
        return -1;
    }
    return 0;
oom:
    rt_say(msg, ml, "out of memory at line %u", line);
    return -1;
}

rm_mesh *rm_load_obj(const char *path, int kind, char *msg, size_t ml)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        rt_say(msg, ml, "%s: %s", path, strerror(errno));
        return NULL;
    }
    obj_data d;
    memset(&d, 0, sizeof d);
    char m2[256];
    int rc = obj_read(f, &d, m2, sizeof m2);
    fclose(f);
    rm_mesh *m = NULL;
    uint32_t nf = d.fstart.n;
    if (rc != 0) {
        rt_say(msg, ml, "%s: %s", path, m2);
        goto out;
    }
    if (nf == 0 || d.v.n == 0) {
        rt_say(msg, ml, "%s: no faces", path);
        goto out;
    }
    if (kind == RM_PTEX) {
        for (uint32_t i = 0; i < nf; i++) {
            uint32_t n = (i + 1 < nf ? d.fstart.p[i + 1] : d.fv.n) - d.fstart.p[i];
            if (n != 4) {
                rt_say(msg, ml, "%s: face %u has %u corners: a Ptex mesh drawn by seamtex-render "
                    "must be all quads (its faces are the texture's faces)", path, i, n);
                goto out;
            }
        }
        m = rm_from_quads(d.v.p, d.v.n / 3, d.fv.p, nf, m2, sizeof m2);
        if (!m)
            rt_say(msg, ml, "%s: %s", path, m2);
        goto out;
    }
    /* atlas: fan triangles, uv from vt (v flipped into the set's texture space) */
    uint64_t ntris = (uint64_t)d.fv.n - 2ull * nf;
    m = alloc_mesh(d.v.n / 3, (uint32_t)ntris);
    if (!m) {
        rt_say(msg, ml, "%s: out of memory", path);
        goto out;
    }
    memcpy(m->pos, d.v.p, (size_t)d.v.n * sizeof *d.v.p);
    uint32_t t = 0;
    for (uint32_t i = 0; i < nf; i++) {
        uint32_t first = d.fstart.p[i];
        uint32_t n = (i + 1 < nf ? d.fstart.p[i + 1] : d.fv.n) - first;
        for (uint32_t k = 0; k < n; k++)
            if (d.fvt.p[first + k] == UINT32_MAX) {
                rt_say(msg, ml, "%s: face %u has a corner without a texture coordinate (an atlas "
                    "mesh needs vt on every corner)", path, i);
                rm_free(m);
                m = NULL;
                goto out;
            }
        for (uint32_t k = 1; k + 1 < n; k++, t++) {
            uint32_t c[3] = { first, first + k, first + k + 1 };
            for (int j = 0; j < 3; j++) {
                m->tri[3 * t + j] = d.fv.p[c[j]];
                m->uv[6 * t + 2 * j] = d.vt.p[2 * d.fvt.p[c[j]]];
                m->uv[6 * t + 2 * j + 1] = 1.0f - d.vt.p[2 * d.fvt.p[c[j]] + 1];
            }
            m->face[t] = 0;
        }
    }
    m->nfaces = 1;
    m->atlas = 1;
    finish(m);
out:
    obj_free(&d);
    return m;
}
