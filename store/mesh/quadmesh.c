/* store/mesh/quadmesh.c - quad mesh -> per-face texture set: adjacency from shared edges, sizes,
 * baking from a callback, and the cube generators. See quadmesh.h for the conventions.
 *
 * The edge map is an open-addressing hash table of undirected edges (key: the two vertex
 * indices, smaller first), sized to a power of two at least twice the number of quad edges,
 * allocated once per call. Every size from outside is checked before it is multiplied.
 */
#include "quadmesh.h"

#include <stdlib.h>
#include <string.h>

uint32_t st_quad_hash(uint32_t a, uint32_t b)
{
    uint32_t h = a * 0x9e3779b1u ^ (b + 0x7f4a7c15u + (a << 6) + (a >> 2));
    h ^= h >> 16;
    h *= 0x85ebca6bu;
    h ^= h >> 13;
    h *= 0xc2b2ae35u;
    h ^= h >> 16;
    return h;
}

typedef struct edge_slot {
    uint64_t key;    /* (lo << 32 | hi) + 1; 0 = empty */
    uint32_t fe;     /* first user: face * 4 + edge */
    uint32_t count;  /* quads using the edge */
} edge_slot;

static uint64_t mix64(uint64_t k)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdull;
    k ^= k >> 33;
    return k;
}

int st_quadmesh_adjacency(const st_quadmesh *m, st_face_desc *fd, st_error *e)
{
    if (!m || !fd || !m->quads)
        return st_fail(e, ST_EINVAL, "quad mesh: no quads");
    uint32_t nq = m->nquads;
    if (nq < 1 || nq > ST_MAX_FACES)
        return st_fail(e, ST_ETOOBIG, "quad mesh: %u quads not in 1..%u", nq, ST_MAX_FACES);
    for (uint32_t f = 0; f < nq; f++) {
        const uint32_t *q = &m->quads[4 * (size_t)f];
        for (int k = 0; k < 4; k++) {
            if (q[k] >= m->nverts)
                return st_fail(e, ST_EINVAL, "quad %u: vertex %u out of range (%u vertices)", f,
                               q[k], m->nverts);
            for (int j = 0; j < k; j++)
                if (q[j] == q[k])
                    return st_fail(e, ST_EINVAL, "quad %u: vertex %u repeated", f, q[k]);
        }
        for (int k = 0; k < 4; k++) {
            fd[f].adjface[k] = -1;
            fd[f].adjedge[k] = 0;
        }
    }
    size_t cap = 16;
    while (cap < 8 * (size_t)nq)
        cap <<= 1;
    edge_slot *tab = calloc(cap, sizeof *tab);
    if (!tab)
        return st_fail(e, ST_ENOMEM, "quad mesh: out of memory for the edge map");
    int rc = ST_OK;
    for (uint32_t f = 0; f < nq && rc == ST_OK; f++) {
        const uint32_t *q = &m->quads[4 * (size_t)f];
        for (unsigned k = 0; k < 4; k++) {
            uint32_t a = q[k], b = q[(k + 1) & 3];
            uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
            uint64_t key = (((uint64_t)lo << 32) | hi) + 1;
            size_t i = (size_t)mix64(key) & (cap - 1);
            while (tab[i].key && tab[i].key != key)
                i = (i + 1) & (cap - 1);
            edge_slot *sl = &tab[i];
            if (!sl->key) {
                sl->key = key;
                sl->fe = f * 4 + k;
                sl->count = 1;
                continue;
            }
            uint32_t g = sl->fe / 4, ge = sl->fe % 4;
            if (sl->count >= 2) {
                uint32_t h = (uint32_t)fd[g].adjface[ge];
                rc = st_fail(e, ST_EADJ,
                             "edge %u-%u is shared by more than two faces (%u, %u, %u): "
                             "non-manifold", a, b, g, h, f);
                break;
            }
            if (g == f) {
                rc = st_fail(e, ST_EADJ, "quad %u uses edge %u-%u twice", f, a, b);
                break;
            }
            if (m->quads[4 * (size_t)g + ge] == a) {
                rc = st_fail(e, ST_EADJ,
                             "edge %u-%u is traversed in the same direction by faces %u and %u "
                             "(inconsistent orientation)", a, b, g, f);
                break;
            }
            sl->count = 2;
            fd[f].adjface[k] = (int32_t)g;
            fd[f].adjedge[k] = (int8_t)ge;
            fd[g].adjface[ge] = (int32_t)f;
            fd[g].adjedge[ge] = (int8_t)k;
        }
    }
    free(tab);
    return rc;
}

int st_quadmesh_build(const st_quadmesh *m, const st_quadmesh_opts *o, st_set **out,
                      st_error *e)
{
    *out = NULL;
    if (!m || !o)
        return st_fail(e, ST_EINVAL, "quad mesh build: missing mesh or options");
    if (!m->pos && o->bake)
        return st_fail(e, ST_EINVAL, "quad mesh build: baking needs vertex positions");
    if (m->nquads < 1 || m->nquads > ST_MAX_FACES)
        return st_fail(e, ST_ETOOBIG, "quad mesh: %u quads not in 1..%u", m->nquads,
                       ST_MAX_FACES);
    st_face_desc *fd = calloc(m->nquads, sizeof *fd);
    if (!fd)
        return st_fail(e, ST_ENOMEM, "out of memory for %u face descriptions", m->nquads);
    int rc = st_quadmesh_adjacency(m, fd, e);
    for (uint32_t f = 0; rc == ST_OK && f < m->nquads; f++) {
        uint8_t ul = o->ulog2, vl = o->vlog2;
        if (o->res)
            o->res(o->user, f, &ul, &vl);
        if (ul > ST_MAX_LOG2 || vl > ST_MAX_LOG2)
            rc = st_fail(e, ST_ETOOBIG, "face %u: log2 size %u x %u over %u", f, ul, vl,
                         ST_MAX_LOG2);
        fd[f].w = 1u << ul;
        fd[f].h = 1u << vl;
    }
    st_set *s = NULL;
    if (rc == ST_OK) {
        st_set_info in = {.nfaces = m->nquads, .nchan = o->nchan, .dtype = o->dtype,
                          .alpha_chan = (int8_t)(o->has_alpha ? o->nchan - 1 : -1),
                          .kind = ST_KIND_PERFACE};
        rc = st_set_create(&in, fd, o->max_bytes, &s, e);
    }
    free(fd);
    if (rc != ST_OK)
        return rc;
    if (o->bake) {
        size_t ts = st_texel_size(s);
        for (uint32_t f = 0; f < m->nquads; f++) {
            const st_face *F = &s->faces[f];
            const uint32_t *q = &m->quads[4 * (size_t)f];
            const float *c0 = &m->pos[3 * (size_t)q[0]], *c1 = &m->pos[3 * (size_t)q[1]];
            const float *c2 = &m->pos[3 * (size_t)q[2]], *c3 = &m->pos[3 * (size_t)q[3]];
            uint8_t *t = st_face_level(s, f, 0);
            for (uint32_t j = 0; j < F->h; j++) {
                float v = ((float)j + 0.5f) / (float)F->h;
                for (uint32_t i = 0; i < F->w; i++) {
                    float u = ((float)i + 0.5f) / (float)F->w, P[3];
                    float w0 = (1 - u) * (1 - v), w1 = u * (1 - v), w2 = u * v, w3 = (1 - u) * v;
                    for (int k = 0; k < 3; k++)
                        P[k] = w0 * c0[k] + w1 * c1[k] + w2 * c2[k] + w3 * c3[k];
                    float val[ST_MAX_CHANNELS] = {0};
                    o->bake(o->user, f, u, v, P, val);
                    uint8_t *p = t + ((size_t)j * F->w + i) * ts;
                    for (unsigned c = 0; c < s->info.nchan; c++)
                        st_channel_put(s->info.dtype, p, c, val[c]);
                }
            }
        }
        st_set_build_mips(s, UINT32_MAX);
    }
    *out = s;
    return ST_OK;
}

/* The six sides: normal axis, sign, then the lattice axes of U and V with U x V outward. */
static const int8_t cube_sides[6][4] = {
    {0, +1, 1, 2}, /* +X: U = +Y, V = +Z */
    {0, -1, 2, 1}, /* -X: U = +Z, V = +Y */
    {1, +1, 2, 0}, /* +Y: U = +Z, V = +X */
    {1, -1, 0, 2}, /* -Y: U = +X, V = +Z */
    {2, +1, 0, 1}, /* +Z: U = +X, V = +Y */
    {2, -1, 1, 0}, /* -Z: U = +Y, V = +X */
};

int st_quadmesh_cube(uint32_t n, uint32_t rot_seed, st_quadmesh *out, st_error *e)
{
    memset(out, 0, sizeof *out);
    if (n < 1 || n > 1024)
        return st_fail(e, ST_EINVAL, "cube subdivision %u not in 1..1024", n);
    size_t n1 = (size_t)n + 1, lat = n1 * n1 * n1;
    size_t nq = 6 * (size_t)n * n, nv = lat - (n > 1 ? (n1 - 2) * (n1 - 2) * (n1 - 2) : 0);
    int32_t *idx = malloc(lat * sizeof *idx);
    out->pos = malloc(nv * 3 * sizeof *out->pos);
    out->quads = malloc(nq * 4 * sizeof *out->quads);
    if (!idx || !out->pos || !out->quads) {
        free(idx);
        st_quadmesh_free(out);
        return st_fail(e, ST_ENOMEM, "out of memory for a cube of %zu quads", nq);
    }
    for (size_t i = 0; i < lat; i++)
        idx[i] = -1;
    uint32_t vcount = 0, qcount = 0;
    for (int sd = 0; sd < 6; sd++) {
        const int8_t *S = cube_sides[sd];
        for (uint32_t b = 0; b < n; b++)
            for (uint32_t a = 0; a < n; a++) {
                static const uint32_t du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
                uint32_t vq[4];
                for (int k = 0; k < 4; k++) {
                    uint32_t c[3];
                    c[S[0]] = S[1] > 0 ? n : 0;
                    c[S[2]] = a + du[k];
                    c[S[3]] = b + dv[k];
                    size_t li = ((size_t)c[0] * n1 + c[1]) * n1 + c[2];
                    if (idx[li] < 0) {
                        idx[li] = (int32_t)vcount;
                        for (int ax = 0; ax < 3; ax++)
                            out->pos[3 * (size_t)vcount + ax] = -1.0f + 2.0f * (float)c[ax] / (float)n;
                        vcount++;
                    }
                    vq[k] = (uint32_t)idx[li];
                }
                unsigned r = rot_seed ? st_quad_hash(rot_seed, qcount) >> 30 : 0;
                for (int k = 0; k < 4; k++)
                    out->quads[4 * (size_t)qcount + k] = vq[(k + r) & 3];
                qcount++;
            }
    }
    free(idx);
    out->nverts = vcount;
    out->nquads = qcount;
    return ST_OK;
}

void st_quadmesh_free(st_quadmesh *m)
{
    if (!m)
        return;
    free(m->pos);
    free(m->quads);
    memset(m, 0, sizeof *m);
}

void st_quad_res_random(void *user, uint32_t face, uint8_t *ulog2, uint8_t *vlog2)
{
    const st_quad_res_range *r = user;
    unsigned span = r->hi >= r->lo ? (unsigned)(r->hi - r->lo) + 1 : 1;
    *ulog2 = (uint8_t)(r->lo + st_quad_hash(r->seed, 2 * face) % span);
    *vlog2 = (uint8_t)(r->lo + st_quad_hash(r->seed, 2 * face + 1) % span);
}
