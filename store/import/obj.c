/* store/import/obj.c - Wavefront OBJ (and its MTL) reader into st_mesh.
 *
 * Owns: st_obj_read_mem, st_obj_read_file. Does not own: seams (seams.c), textures.
 *
 * Handled: v (x y z [w], or x y z r g b: the first three kept), vt (u [v [w]]), vn (counted, not
 * kept: faces' vn indices are range-checked), f with i, i/j, i/j/k, i//k corners
 * and negative (relative) indices, polygons (fan-triangulated), g / o / s (ignored), usemtl,
 * mtllib (several names on a line; .mtl newmtl and map_Kd with the spec's options, names
 * with spaces and Windows '\' paths, relative to the .mtl's folder), comments (whole lines:
 * "v 1 2 3 # x" is refused naming the token), CRLF line ends and backslash line continuation.
 * Numbers are C's strtof (so hex floats are accepted). Material names are kept to 127 bytes
 * (names equal in their first 127 bytes are one material). mtllib and map_Kd paths
 * are only followed when relative and inside the OBJ's folder (no "..", not absolute), and
 * never with caps->no_side_files (the daemon's uploads).
 *
 * Hostile input: counts are capped (caps) as they grow, every index is range-checked (at the
 * end, so faces may name vertices defined later), NaN / infinite coordinates are refused, and
 * the error names the line.
 */
#include "mesh.h"
#include "mesh_io.h"
#include "fileio.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct vec {
    void  *p;
    size_t n, cap, esz;
} vec;

static int vec_push(vec *v, const void *x, size_t limit)
{
    if (v->n >= limit)
        return -1;
    if (v->n == v->cap) {
        size_t nc = v->cap ? v->cap * 2 : 256;
        if (nc > limit)
            nc = limit;
        void *q = realloc(v->p, nc * v->esz);
        if (!q)
            return -2;
        v->p = q;
        v->cap = nc;
    }
    memcpy((char *)v->p + v->n * v->esz, x, v->esz);
    v->n++;
    return 0;
}

typedef struct corner {
    int64_t p, t;      /* resolved 0-based indices (t = -1 none); checked at the end */
} corner;

typedef struct tri_rec {
    corner   c[3];
    uint32_t mat, face, line;
} tri_rec;

typedef struct parser {
    const char *base_dir;
    uint32_t    max_tris, max_verts;
    vec pos, uv, tris, mats;   /* float[3], float[2], tri_rec, st_material */
    uint32_t cur_mat;
    uint32_t nfaces;
    uint64_t nvn;              /* vn statements: normals are not kept, their indices checked */
    int64_t  max_n;            /* largest 0-based vn index a face names (-1 none) ... */
    uint32_t max_n_line;       /* ... and its line; checked at the end like v and vt */
    st_error *e;
} parser;

static const char *skip_ws(const char *s, const char *end)
{
    while (s < end && isspace((unsigned char)*s)) /* the same notion as the token loops */
        s++;
    return s;
}

/* Parses up to n floats; returns how many were read, -1 on a non-finite value, -2 on a token
 * that is not a number (*bad, *badlen: the token, for the message). Tokens up to 255
 * characters are read (a 64-character cap refused numbers written with many digits as
 * "needs 3 numbers"). */
static int parse_floats(const char *s, const char *end, float *out, int n, const char **bad,
                        int *badlen)
{
    char buf[256];
    int k = 0;
    while (k < n) {
        s = skip_ws(s, end);
        if (s >= end)
            break;
        const char *t = s;
        while (t < end && !isspace((unsigned char)*t))
            t++;
        size_t len = (size_t)(t - s);
        *bad = s;
        *badlen = len > 40 ? 40 : (int)len;
        if (len >= sizeof buf)
            return -2;
        memcpy(buf, s, len);
        buf[len] = 0;
        char *ep;
        errno = 0;
        float f = strtof(buf, &ep);
        if (ep == buf || *ep)
            return -2;
        if (!isfinite(f))
            return -1;
        out[k++] = f;
        s = t;
    }
    return k;
}

/* Material names are kept to their first 127 bytes, and looked up the same way: a longer
 * name compared at full length never matched its stored copy, so each usemtl of it made a
 * new material without the MTL's map_Kd (and 4097 of them refused the file). */
static int find_mat(parser *P, const char *name, size_t len)
{
    st_material *m = P->mats.p;
    if (len >= sizeof m[0].name)
        len = sizeof m[0].name - 1;
    for (size_t i = 0; i < P->mats.n; i++)
        if (strlen(m[i].name) == len && !memcmp(m[i].name, name, len))
            return (int)i;
    st_material nm;
    memset(&nm, 0, sizeof nm);
    memcpy(nm.name, name, len);
    if (vec_push(&P->mats, &nm, ST_MESH_MAX_MATERIALS))
        return -1;
    return (int)P->mats.n - 1;
}

/* A relative path that stays inside its folder: not absolute, no ".." component, no drive
 * letter. Files named by an uploaded OBJ or MTL are only looked for beside it. */
static int safe_rel(const char *p)
{
    if (!*p || p[0] == '/' || (isalpha((unsigned char)p[0]) && p[1] == ':'))
        return 0;
    for (const char *c = p; *c;) {
        const char *slash = strchr(c, '/');
        size_t l = slash ? (size_t)(slash - c) : strlen(c);
        if (l == 2 && c[0] == '.' && c[1] == '.')
            return 0;
        c += l + (slash ? 1 : 0);
    }
    return 1;
}

/* The options of an MTL map statement (the MTL spec) and how many arguments each takes;
 * -o, -s and -t take one to three numbers (-3). */
static const struct { const char *opt; int nargs; } MAP_OPTS[] = {
    {"-blendu", 1}, {"-blendv", 1}, {"-boost", 1}, {"-cc", 1},     {"-clamp", 1}, {"-mm", 2},
    {"-o", -3},     {"-s", -3},     {"-t", -3},    {"-texres", 1}, {"-bm", 1},    {"-imfchan", 1},
    {"-type", 1}};

static const char *next_tok(const char *s, const char *end, const char **te)
{
    s = skip_ws(s, end);
    const char *t = s;
    while (t < end && !isspace((unsigned char)*t))
        t++;
    *te = t;
    return s;
}

static int is_number(const char *s, const char *te)
{
    char buf[64];
    size_t l = (size_t)(te - s);
    if (l == 0 || l >= sizeof buf)
        return 0;
    memcpy(buf, s, l);
    buf[l] = 0;
    char *ep;
    (void)strtod(buf, &ep);
    return ep != buf && !*ep;
}

/* Resolves an MTL map path: the options skipped by the spec's argument counts, and the rest
 * of the line is the file name (spaces kept: "map_Kd my tex.png" names "my tex.png"; taking
 * the last token named "tex.png"), '\' -> '/', "./" dropped, made relative to the .mtl's
 * folder (dir). */
static void resolve_map(const char *dir, const char *s, const char *end, char *out, size_t cap)
{
    while (end > s && isspace((unsigned char)end[-1]))
        end--;
    const char *te, *t = next_tok(s, end, &te);
    for (;;) {
        int nargs = 0;
        for (size_t i = 0; i < sizeof MAP_OPTS / sizeof MAP_OPTS[0]; i++)
            if (strlen(MAP_OPTS[i].opt) == (size_t)(te - t) &&
                !memcmp(t, MAP_OPTS[i].opt, (size_t)(te - t)))
                nargs = MAP_OPTS[i].nargs;
        if (!nargs)
            break;
        t = next_tok(te, end, &te);
        if (nargs > 0) {
            for (int k = 0; k < nargs && t < end; k++)
                t = next_tok(te, end, &te);
        } else {
            /* one to three numbers, never the last token (the file name) */
            for (int k = 0; k < -nargs && te < end && is_number(t, te); k++)
                t = next_tok(te, end, &te);
        }
    }
    char name[512];
    size_t len = t < end ? (size_t)(end - t) : 0;
    if (len >= sizeof name) {
        out[0] = 0; /* too long: no texture rather than a wrong one */
        return;
    }
    memcpy(name, t, len);
    name[len] = 0;
    for (char *c = name; *c; c++)
        if (*c == '\\')
            *c = '/';
    const char *n = name;
    while (n[0] == '.' && n[1] == '/')
        n += 2;
    if (!safe_rel(n)) {
        out[0] = 0; /* absolute or climbing out of the mesh's folder: not followed */
        return;
    }
    int r = !dir || !*dir ? snprintf(out, cap, "%s", n) : snprintf(out, cap, "%s/%s", dir, n);
    if (r < 0 || (size_t)r >= cap)
        out[0] = 0; /* too long: no texture rather than a wrong one */
}

static void read_mtl(parser *P, const char *file, size_t flen)
{
    if (!P->base_dir)
        return;
    char name[512], path[1024];
    if (flen >= sizeof name)
        return;
    memcpy(name, file, flen);
    name[flen] = 0;
    for (char *c = name; *c; c++)
        if (*c == '\\')
            *c = '/';
    if (!safe_rel(name))
        return;
    int r = snprintf(path, sizeof path, "%s/%s", P->base_dir, name);
    if (r < 0 || (size_t)r >= sizeof path)
        return;
    FILE *f = fopen(path, "rb");
    if (!f)
        return; /* a missing .mtl is not an error */
    char mtldir[1024];   /* map_Kd names are relative to the .mtl's folder */
    snprintf(mtldir, sizeof mtldir, "%s", path);
    *strrchr(mtldir, '/') = 0;
    char line[1024];
    int cur = -1;
    while (fgets(line, sizeof line, f)) {
        const char *s = skip_ws(line, line + strlen(line));
        const char *end = line + strlen(line);
        while (end > s && (end[-1] == '\n' || end[-1] == '\r'))
            end--;
        if (!strncmp(s, "newmtl", 6) && isspace((unsigned char)s[6])) {
            const char *nm = skip_ws(s + 6, end);
            const char *ne = end;
            while (ne > nm && isspace((unsigned char)ne[-1]))
                ne--;
            cur = find_mat(P, nm, (size_t)(ne - nm));
        } else if (cur >= 0 && !strncmp(s, "map_Kd", 6) && isspace((unsigned char)s[6])) {
            st_material *m = &((st_material *)P->mats.p)[cur];
            resolve_map(mtldir, s + 6, end, m->map_kd, sizeof m->map_kd);
        }
    }
    fclose(f);
}

static int parse_face(parser *P, const char *s, const char *end, uint32_t line)
{
    int n = 0;
    corner first = {0, 0}, prev = {0, 0};
    int64_t np = (int64_t)P->pos.n, nt = (int64_t)P->uv.n, nn = (int64_t)P->nvn;
    for (;;) {
        s = skip_ws(s, end);
        if (s >= end)
            break;
        corner c = {0, -1};
        int64_t idx[3] = {0, 0, 0};
        int have[3] = {0, 0, 0};
        for (int part = 0; part < 3; part++) {
            int neg = 0;
            if (s < end && *s == '-') {
                neg = 1;
                s++;
            }
            int64_t v = 0;
            int digits = 0;
            while (s < end && isdigit((unsigned char)*s)) {
                if (v > 1000000000000LL)
                    return st_fail(P->e, ST_EFORMAT, "line %u: index too large", line);
                v = v * 10 + (*s - '0');
                s++;
                digits++;
            }
            if (digits) {
                if (v == 0)
                    return st_fail(P->e, ST_EFORMAT, "line %u: index 0 (OBJ indices start at 1)", line);
                idx[part] = neg ? -v : v;
                have[part] = 1;
            } else if (neg) {
                return st_fail(P->e, ST_EFORMAT, "line %u: '-' without a number", line);
            }
            if (s < end && *s == '/') {
                s++;
                continue;
            }
            break;
        }
        if (s < end && !isspace((unsigned char)*s))
            return st_fail(P->e, ST_EFORMAT, "line %u: bad face corner near '%c'", line, *s);
        if (!have[0])
            return st_fail(P->e, ST_EFORMAT, "line %u: face corner without a position", line);
        c.p = idx[0] < 0 ? np + idx[0] : idx[0] - 1;
        if (c.p < 0)
            return st_fail(P->e, ST_EFORMAT, "line %u: relative index %lld before the first vertex",
                           line, (long long)idx[0]);
        if (have[1]) {
            c.t = idx[1] < 0 ? nt + idx[1] : idx[1] - 1;
            if (c.t < 0)
                return st_fail(P->e, ST_EFORMAT, "line %u: relative vt index %lld before the first vt",
                               line, (long long)idx[1]);
        }
        if (have[2]) {
            int64_t cn = idx[2] < 0 ? nn + idx[2] : idx[2] - 1;
            if (cn < 0)
                return st_fail(P->e, ST_EFORMAT, "line %u: relative vn index %lld before the first vn",
                               line, (long long)idx[2]);
            if (cn > P->max_n) {
                P->max_n = cn;
                P->max_n_line = line;
            }
        }
        if (n == 0)
            first = c;
        if (n >= 2) {
            tri_rec t;
            t.c[0] = first;
            t.c[1] = prev;
            t.c[2] = c;
            t.mat = P->cur_mat;
            t.face = P->nfaces;
            t.line = line;
            int r = vec_push(&P->tris, &t, P->max_tris);
            if (r == -1)
                return st_fail(P->e, ST_ETOOBIG, "line %u: more than %u triangles", line, P->max_tris);
            if (r)
                return st_fail(P->e, ST_ENOMEM, "out of memory for triangles");
        }
        prev = c;
        n++;
    }
    if (n < 3)
        return st_fail(P->e, ST_EFORMAT, "line %u: face with %d corners (at least 3 needed)", line, n);
    P->nfaces++;
    return ST_OK;
}

static int parse_line(parser *P, const char *s, const char *end, uint32_t line)
{
    s = skip_ws(s, end);
    if (s >= end || *s == '#')
        return ST_OK;
    const char *kw = s;
    while (s < end && !isspace((unsigned char)*s))
        s++;
    size_t kl = (size_t)(s - kw);
    if (kl == 1 && kw[0] == 'v') {
        float p[4];
        const char *bad = "";
        int bl = 0;
        int k = parse_floats(s, end, p, 4, &bad, &bl);
        if (k == -1)
            return st_fail(P->e, ST_EFORMAT, "line %u: vertex with a NaN or infinite coordinate", line);
        if (k == -2)
            return st_fail(P->e, ST_EFORMAT, "line %u: vertex: '%.*s' is not a number (no comments "
                           "after a statement)", line, bl, bad);
        if (k < 3)
            return st_fail(P->e, ST_EFORMAT, "line %u: vertex needs 3 numbers", line);
        int r = vec_push(&P->pos, p, P->max_verts);
        if (r == -1)
            return st_fail(P->e, ST_ETOOBIG, "line %u: more than %u vertices", line, P->max_verts);
        return r ? st_fail(P->e, ST_ENOMEM, "out of memory for vertices") : ST_OK;
    }
    if (kl == 2 && kw[0] == 'v' && kw[1] == 't') {
        float t[3] = {0, 0, 0};
        const char *bad = "";
        int bl = 0;
        int k = parse_floats(s, end, t, 3, &bad, &bl);
        if (k == -1)
            return st_fail(P->e, ST_EFORMAT, "line %u: texture coordinate is NaN or infinite", line);
        if (k == -2)
            return st_fail(P->e, ST_EFORMAT, "line %u: vt: '%.*s' is not a number (no comments "
                           "after a statement)", line, bl, bad);
        if (k < 1)
            return st_fail(P->e, ST_EFORMAT, "line %u: vt needs at least one number", line);
        if (fabsf(t[0]) > 1e6f || fabsf(t[1]) > 1e6f)
            return st_fail(P->e, ST_EFORMAT, "line %u: texture coordinate beyond +-1e6", line);
        float uv[2] = {t[0], 1.0f - t[1]}; /* OBJ v is up; texture space v is down */
        int r = vec_push(&P->uv, uv, P->max_verts);
        if (r == -1)
            return st_fail(P->e, ST_ETOOBIG, "line %u: more than %u texture coordinates", line,
                           P->max_verts);
        return r ? st_fail(P->e, ST_ENOMEM, "out of memory for texture coordinates") : ST_OK;
    }
    if (kl == 1 && kw[0] == 'f')
        return parse_face(P, s, end, line);
    if (kl == 2 && kw[0] == 'v' && kw[1] == 'n') {
        P->nvn++; /* normals are not kept; faces' vn indices are range-checked against them */
        return ST_OK;
    }
    if (kl == 6 && !memcmp(kw, "usemtl", 6)) {
        const char *nm = skip_ws(s, end);
        const char *ne = end;
        while (ne > nm && isspace((unsigned char)ne[-1]))
            ne--;
        int m = find_mat(P, nm, (size_t)(ne - nm));
        if (m < 0)
            return st_fail(P->e, ST_ETOOBIG, "line %u: more than %u materials", line,
                           ST_MESH_MAX_MATERIALS);
        P->cur_mat = (uint32_t)m;
        return ST_OK;
    }
    if (kl == 6 && !memcmp(kw, "mtllib", 6)) {
        for (;;) {
            s = skip_ws(s, end);
            if (s >= end)
                break;
            const char *t = s;
            while (t < end && !isspace((unsigned char)*t))
                t++;
            read_mtl(P, s, (size_t)(t - s));
            s = t;
        }
        return ST_OK;
    }
    return ST_OK; /* vp, g, o, s, l, p and unknown statements are ignored */
}

static int build_mesh(parser *P, st_mesh **out)
{
    if (P->max_n >= (int64_t)P->nvn)
        return st_fail(P->e, ST_EFORMAT, "line %u: vn index %lld out of range (%llu vn)",
                       P->max_n_line, (long long)P->max_n + 1, (unsigned long long)P->nvn);
    size_t nt = P->tris.n;
    st_mesh *m;
    int rc = st_mesh_alloc((uint32_t)P->pos.n, (uint32_t)P->uv.n, (uint32_t)nt, &m, P->e);
    if (rc)
        return rc;
    if (P->pos.n)
        memcpy(m->pos, P->pos.p, P->pos.n * 3 * sizeof(float));
    if (P->uv.n)
        memcpy(m->uv, P->uv.p, P->uv.n * 2 * sizeof(float));
    const tri_rec *t = P->tris.p;
    for (size_t i = 0; i < nt; i++) {
        int nouv = 0;
        for (int k = 0; k < 3; k++) {
            const corner *c = &t[i].c[k];
            if (c->p >= (int64_t)P->pos.n) {
                st_mesh_free(m);
                return st_fail(P->e, ST_EFORMAT, "line %u: vertex index %lld out of range (%zu vertices)",
                               t[i].line, (long long)c->p + 1, P->pos.n);
            }
            if (c->t >= (int64_t)P->uv.n) {
                st_mesh_free(m);
                return st_fail(P->e, ST_EFORMAT, "line %u: vt index %lld out of range (%zu vt)",
                               t[i].line, (long long)c->t + 1, P->uv.n);
            }
            m->tri_pos[i * 3 + k] = (uint32_t)c->p;
            m->tri_uv[i * 3 + k] = c->t < 0 ? ST_MESH_NO_UV : (uint32_t)c->t;
            if (c->t < 0)
                nouv = 1;
        }
        m->tri_mat[i] = (uint16_t)t[i].mat;
        m->tri_face[i] = t[i].face;
        m->ntri_nouv += (uint32_t)nouv;
    }
    m->nfaces_src = P->nfaces;
    if (P->mats.n) {
        st_material *mm = malloc(P->mats.n * sizeof *mm);
        if (!mm) {
            st_mesh_free(m);
            return st_fail(P->e, ST_ENOMEM, "out of memory for materials");
        }
        memcpy(mm, P->mats.p, P->mats.n * sizeof *mm);
        free(m->mats);
        m->mats = mm;
        m->nmat = (uint32_t)P->mats.n;
    }
    *out = m;
    return ST_OK;
}

int st_obj_read_mem(const char *buf, size_t len, const char *base_dir, const st_mesh_caps *caps,
                    st_mesh **out, st_error *e)
{
    *out = NULL;
    parser P;
    memset(&P, 0, sizeof P);
    P.base_dir = base_dir;
    P.max_tris = caps && caps->max_tris ? caps->max_tris : ST_MESH_MAX_TRIS;
    P.max_verts = caps && caps->max_verts ? caps->max_verts : ST_MESH_MAX_VERTS;
    P.pos.esz = 3 * sizeof(float);
    P.uv.esz = 2 * sizeof(float);
    P.tris.esz = sizeof(tri_rec);
    P.mats.esz = sizeof(st_material);
    P.e = e;
    P.max_n = -1;
    /* material 0 = "default" for faces before any usemtl */
    find_mat(&P, "default", 7);
    int rc = ST_OK;
    const char *s = buf, *end = buf + len;
    uint32_t line = 1;
    char *joined = NULL;
    size_t jcap = 0;
    while (s < end && rc == ST_OK) {
        const char *nl = memchr(s, '\n', (size_t)(end - s));
        const char *le = nl ? nl : end;
        uint32_t start_line = line;
        /* backslash continuation: join physical lines */
        const char *ce = le;
        while (ce > s && (ce[-1] == '\r'))
            ce--;
        if (ce > s && ce[-1] == '\\' && nl) {
            size_t jl = 0;
            const char *q = s;
            for (;;) {
                const char *qn = memchr(q, '\n', (size_t)(end - q));
                const char *qe = qn ? qn : end;
                const char *qc = qe;
                while (qc > q && qc[-1] == '\r')
                    qc--;
                int cont = qc > q && qc[-1] == '\\' && qn;
                size_t part = (size_t)(qc - q) - (cont ? 1 : 0);
                if (jl + part + 2 > jcap) {
                    size_t nc = (jl + part + 2) * 2;
                    char *nj = realloc(joined, nc);
                    if (!nj) {
                        rc = st_fail(e, ST_ENOMEM, "out of memory joining lines");
                        break;
                    }
                    joined = nj;
                    jcap = nc;
                }
                memcpy(joined + jl, q, part);
                jl += part;
                joined[jl++] = ' ';
                line++;
                q = qn ? qn + 1 : end;
                if (!cont)
                    break;
            }
            if (rc)
                break;
            rc = parse_line(&P, joined, joined + jl, start_line);
            s = q;
            continue;
        }
        rc = parse_line(&P, s, le, line);
        line++;
        s = nl ? nl + 1 : end;
    }
    free(joined);
    if (rc == ST_OK) {
        if (P.tris.n == 0)
            rc = st_fail(e, ST_EFORMAT, "no faces in the OBJ (%zu vertices)", P.pos.n);
        else
            rc = build_mesh(&P, out);
    }
    free(P.pos.p);
    free(P.uv.p);
    free(P.tris.p);
    free(P.mats.p);
    return rc;
}

int st_obj_read_file(const char *path, const st_mesh_caps *caps, st_mesh **out, st_error *e)
{
    *out = NULL;
    size_t maxb = caps && caps->max_bytes ? caps->max_bytes : ((size_t)1 << 30);
    void *data;
    size_t sz;
    int frc = st_file_read(path, maxb, &data, &sz, e);
    if (frc)
        return frc;
    char *buf = data;
    char dir[1024];
    const char *slash = strrchr(path, '/');
    if (slash) {
        size_t dl = (size_t)(slash - path);
        if (dl >= sizeof dir)
            dl = sizeof dir - 1;
        memcpy(dir, path, dl);
        dir[dl] = 0;
    } else {
        strcpy(dir, ".");
    }
    int rc = st_obj_read_mem(buf, sz, caps && caps->no_side_files ? NULL : dir, caps, out, e);
    free(buf);
    return rc;
}
