/* tests/unit/test_ptexfilter_gen.c - the Ptex filters' fast paths against their general path,
 * bit for bit, on sets GENERATED at random (fixed seeds): shapes and contents that the shared
 * .ptx files (test_ptexfilter_paths, _walk, _iso, _const, _nonb, _lean3, test_ptextri_outputs)
 * do not have (session 25).
 *
 * Sets: polygon meshes turned into Ptex faces the way Ptex does it (a quad is one face, an
 * n-gon n subfaces around its centre, ST_FACE_SUBFACE, a main face's edge pointing to the
 * subface on its first half, one-sided), adjacency from the shared edges, every face's edge
 * numbering rotated at random (adjedge != the opposite edge): grids with holes and
 * boundaries, a grid with some quads cut into triangles and some pairs merged into hexagons
 * (main face <-> subface edges and corners), cylinders, tori, cubes (valence-3 corners),
 * the cube refined once, closed bipyramids refined into quads (valence 5..11 corners, closed),
 * a bipyramid of triangles (subfaces only), open fans of 5..12 quads (valence >= 5 at a
 * boundary-free vertex inside an open mesh); per-face resolutions with ulog2 and vlog2
 * independent in 0..8 (1x1, 1xN, Nx1), one resolution for the whole set or another per face
 * (neighbours of very different resolutions); u8, u16, half and f32 with 1..4 channels;
 * contents smooth, noise, steps, uniform, extreme (0, the max, large and tiny floats,
 * subnormal floats and halfs), constant faces (some sharing one value, so that the reader
 * marks neighbourhoods constant); Ptex border modes (clamp, black, periodic) at random.
 * Triangle meshes (ST_MESH_TRIANGLE): triangulated grids with holes, tetrahedra (valence 3),
 * bipyramids (valence 3..9, closed), triangulated tori.
 * Every set is written with st_ptex_write_mem and read back with st_ptex_read_mem, so the
 * reader makes its reductions and derived flags as for a file.
 *
 * Queries (per set): random; a third within two texels of an edge or corner; some on texel
 * centres; a few on or past the face's bounds; 40% in runs that keep the face and footprint
 * of the query before (the 8-query lanes' coherent blocks; on triangles, the kernel shape
 * the filter reuses, a quarter of them with one derivative changed); footprints 0.25 to 32
 * texels (the exact powers of two and in between), isotropic, anisotropic, with cross terms;
 * a few with a zero footprint. Quad sets: every Ptex filter (point, bilinear, box, gaussian,
 * bicubic, bspline, catmullrom, mitchell), Discard, Traverse and Clamp, default width and
 * blur and (kernel filters) width 1.5 blur 0.02: pf_batch_path with PF_PATH_BEST, PF_PATH_QUERY and
 * PF_PATH_LANES4 against PF_PATH_GENERAL (every query through eval): outputs, coverage,
 * status and return value the same bytes. Triangle sets: st_ptextri_batch and
 * st_ptextri_batch_baseline against st_ptextri_batch_general (point, gaussian, bicubic with
 * width 1.5 and blur 0.01, gaussian with the clamp zero rule, box; three modes; with and
 * without the coverage array).
 *
 * Faults planted in the 2 x 2 path's subface declines (across_small, corner_small) fail this
 * test and no test on the shared files (docs/ptex-log.md, "gen25").
 *
 * GEN_SETS=N (environment) runs N sets of each kind instead of the default, GEN_SEED=S
 * another seed: for longer hunts by hand; GEN_VERBOSE=1 prints what each set holds. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "ptextri.h"
#include "sample.h"
#include "set.h"

enum { NQ = 1500, MAXP = 1024, MAXI = 8192, TEXEL_BUDGET = 1 << 20 };

static uint32_t rng;
static float rndf(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}
static uint32_t rndu(uint32_t n) /* 0 .. n-1 */
{
    return (uint32_t)(rndf() * (float)n) % n;
}

/* ---- polygon meshes ---------------------------------------------------------------------- */

typedef struct mesh {
    int np, nv, ni;
    int start[MAXP + 1]; /* polygon p: idx[start[p] .. start[p + 1]) */
    int idx[MAXI];
} mesh;

static void mesh_clear(mesh *m)
{
    m->np = m->nv = m->ni = 0;
    m->start[0] = 0;
}
static void poly(mesh *m, int n, const int *v)
{
    assert_true(m->np < MAXP && m->ni + n <= MAXI);
    for (int i = 0; i < n; i++)
        m->idx[m->ni++] = v[i];
    m->start[++m->np] = m->ni;
}
static void quad4(mesh *m, int a, int b, int c, int d)
{
    int v[4] = {a, b, c, d};
    poly(m, 4, v);
}
static void tri3(mesh *m, int a, int b, int c)
{
    int v[3] = {a, b, c};
    poly(m, 3, v);
}

/* A small open-addressing map from a 64-bit key to an int. */
typedef struct hmap {
    uint64_t *k;
    int *v;
    size_t cap;
} hmap;
static void hm_init(hmap *h, size_t n)
{
    h->cap = 64;
    while (h->cap < 2 * n + 16)
        h->cap <<= 1;
    h->k = malloc(h->cap * sizeof *h->k);
    h->v = malloc(h->cap * sizeof *h->v);
    assert_true(h->k && h->v);
    memset(h->k, 0xff, h->cap * sizeof *h->k);
}
static void hm_free(hmap *h)
{
    free(h->k);
    free(h->v);
}
static int *hm_slot(hmap *h, uint64_t key, int insert)
{
    size_t i = (size_t)((key * 0x9e3779b97f4a7c15ull) >> 20) & (h->cap - 1);
    while (h->k[i] != UINT64_MAX) {
        if (h->k[i] == key)
            return &h->v[i];
        i = (i + 1) & (h->cap - 1);
    }
    if (!insert)
        return NULL;
    h->k[i] = key;
    return &h->v[i];
}
static uint64_t dkey(int a, int b)
{
    return (uint64_t)(uint32_t)a << 32 | (uint32_t)b;
}
static uint64_t ukey(int a, int b)
{
    return a < b ? dkey(a, b) : dkey(b, a);
}

/* Edge midpoints and polygon centres made while splitting: new vertex ids from base on, the
 * endpoints of each (-1 for a centre). */
typedef struct mids {
    hmap h;
    int base, n, *ea, *eb;
} mids;
static void mids_init(mids *d, int base, int cap)
{
    hm_init(&d->h, (size_t)cap);
    d->base = base;
    d->n = 0;
    d->ea = malloc(sizeof(int) * (size_t)cap);
    d->eb = malloc(sizeof(int) * (size_t)cap);
    assert_true(d->ea && d->eb);
}
static void mids_free(mids *d)
{
    hm_free(&d->h);
    free(d->ea);
    free(d->eb);
}
static int mid_new(mids *d, int a, int b)
{
    d->ea[d->n] = a;
    d->eb[d->n] = b;
    return d->base + d->n++;
}
static int mid_of(mids *d, int a, int b)
{
    int *p = hm_slot(&d->h, ukey(a, b), 0);
    if (p)
        return *p;
    int id = mid_new(d, a, b);
    *hm_slot(&d->h, ukey(a, b), 1) = id;
    return id;
}

/* Every polygon of n sides into n quads (corner, edge midpoint, centre, edge midpoint): the
 * refinement step of Catmull-Clark, topology only. */
static void refine(mesh *m)
{
    static mesh r;
    mesh_clear(&r);
    mids d;
    mids_init(&d, m->nv, 2 * m->ni + m->np + 16);
    for (int p = 0; p < m->np; p++) {
        int n = m->start[p + 1] - m->start[p];
        const int *v = &m->idx[m->start[p]];
        int c = mid_new(&d, -1, -1);
        for (int i = 0; i < n; i++)
            quad4(&r, v[i], mid_of(&d, v[i], v[(i + 1) % n]), c,
                  mid_of(&d, v[(i + n - 1) % n], v[i]));
    }
    r.nv = m->nv + d.n;
    mids_free(&d);
    memcpy(m, &r, sizeof r);
}

/* W x H quads; wrap: periodic in u (cylinder) and v (torus); holes: the share of quads left
 * out; tris / hexes: the share of quads cut into two triangles / merged with their right
 * neighbour into a hexagon. */
static void grid(mesh *m, int W, int H, int wrapu, int wrapv, float holes, float tris,
                 float hexes)
{
    mesh_clear(m);
    int VW = wrapu ? W : W + 1, VH = wrapv ? H : H + 1;
    m->nv = VW * VH;
#define VID(i, j) (((i) % VW) + ((j) % VH) * VW)
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            float r = rndf();
            int a = VID(i, j), b = VID(i + 1, j), c = VID(i + 1, j + 1), d = VID(i, j + 1);
            if (r < holes)
                continue;
            if (r < holes + tris) {
                if (rndf() < 0.5f) {
                    tri3(m, a, b, c);
                    tri3(m, a, c, d);
                } else {
                    tri3(m, a, b, d);
                    tri3(m, b, c, d);
                }
            } else if (r < holes + tris + hexes && i + 1 < W) {
                int v[6] = {a, b, VID(i + 2, j), VID(i + 2, j + 1), c, d};
                poly(m, 6, v);
                i++;
            } else {
                quad4(m, a, b, c, d);
            }
        }
#undef VID
}

static void cube(mesh *m)
{
    mesh_clear(m);
    m->nv = 8;
    quad4(m, 0, 2, 3, 1);
    quad4(m, 4, 5, 7, 6);
    quad4(m, 0, 1, 5, 4);
    quad4(m, 2, 6, 7, 3);
    quad4(m, 0, 4, 6, 2);
    quad4(m, 1, 3, 7, 5);
}

/* k triangles around each of two apexes (closed; valence k at the apexes). */
static void bipyramid(mesh *m, int k)
{
    mesh_clear(m);
    m->nv = 2 + k;
    for (int i = 0; i < k; i++) {
        tri3(m, 0, 2 + i, 2 + (i + 1) % k);
        tri3(m, 1, 2 + (i + 1) % k, 2 + i);
    }
}

static void tetrahedron(mesh *m)
{
    mesh_clear(m);
    m->nv = 4;
    tri3(m, 0, 1, 2);
    tri3(m, 0, 3, 1);
    tri3(m, 0, 2, 3);
    tri3(m, 1, 3, 2);
}

/* k quads around one vertex (valence k inside, an open boundary around). */
static void fan(mesh *m, int k)
{
    mesh_clear(m);
    m->nv = 1 + 2 * k;
    for (int i = 0; i < k; i++)
        quad4(m, 0, 1 + i, 1 + k + i, 1 + (i + 1) % k);
}

/* ---- sets ------------------------------------------------------------------------------- */

typedef struct spec {
    unsigned dtype, nchan;
    int resmode;     /* 0: one resolution for the set, 1: each face its own, 2: one with
                        outliers */
    int maxlog;      /* largest log2 */
    float pconst;    /* share of constant faces */
    int tri;         /* triangle mesh */
} spec;

/* The resolution log2 of one axis. */
static int rand_log(int maxlog)
{
    float r = rndf();
    if (r < 0.15f)
        return 0;
    if (r < 0.3f)
        return 1 + (int)rndu(2);
    return (int)rndu((uint32_t)maxlog + 1);
}

/* The value of texel (x, y) of a face of content kind `kind`; raw bits for the extremes. */
static void put_value(const st_set *s, uint8_t *p, unsigned c, int kind, float x, float y,
                      const float *par, float scale)
{
    unsigned dt = s->info.dtype;
    float v;
    switch (kind) {
    case 0: /* smooth */
        v = 0.5f + 0.45f * sinf(par[0] * x + par[1] * y + (float)c * 1.3f + par[2]);
        break;
    case 1: /* noise */
        v = rndf();
        break;
    case 2: /* steps */
        v = (((int)(x * par[3]) + (int)(y * par[3])) & 1) ? par[4] : par[5];
        break;
    case 3: /* uniform, not flagged */
        v = par[4 + (c & 1)];
        break;
    default: { /* extremes, raw */
        static const uint8_t u8[] = {0, 255, 1, 254, 0, 255};
        static const uint16_t u16[] = {0, 65535, 1, 65534, 0, 65535};
        static const uint16_t hf[] = {0x0000, 0x8000, 0x0001, 0x03ff, 0x0400, 0x7bff, 0xfbff,
                                      0x3c00, 0x8001, 0x0200};
        static const float f32[] = {0.0f, -0.0f, 1e30f, -1e30f, 1e-30f, 1e-40f, 3e38f, -2e38f,
                                    1.0f, 1e-44f};
        switch (dt) {
        case ST_DT_U8: ((uint8_t *)p)[c] = u8[rndu(6)]; break;
        case ST_DT_U16: ((uint16_t *)p)[c] = u16[rndu(6)]; break;
        case ST_DT_HALF: ((uint16_t *)p)[c] = hf[rndu(10)]; break;
        default: ((float *)p)[c] = f32[rndu(10)]; break;
        }
        return;
    }
    }
    if (dt == ST_DT_HALF || dt == ST_DT_F32)
        v = (v - 0.25f) * scale;
    st_channel_put(dt, p, c, v);
}

/* Fills level 0 of every face of s (constant faces: their one texel, a value shared by many
 * of them), makes its levels, writes it as a .ptx and reads that back; frees s. */
static st_set *fill_write_read(st_set *s)
{
    size_t ts = st_texel_size(s);
    float scale = (float[]){1.0f, 300.0f, 1e-4f, 2e-6f}[rndu(4)];
    float shared[2] = {rndf(), rndf()};
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        uint8_t *t = st_face_level(s, f, 0);
        float par[6] = {1.0f + 30.0f * rndf(), 1.0f + 30.0f * rndf(), 6.0f * rndf(),
                        1.0f + 8.0f * rndf(), rndf(), rndf()};
        if (F->flags & ST_FACE_CONSTANT) {
            float v0 = rndf() < 0.7f ? shared[f & 1 && rndf() < 0.3f] : rndf();
            for (unsigned c = 0; c < s->info.nchan; c++)
                st_channel_put(s->info.dtype, t, c,
                               (v0 - 0.25f) * (s->info.dtype >= ST_DT_HALF ? scale : 1.0f));
            continue;
        }
        float r = rndf();
        int kind = r < 0.35f ? 0 : r < 0.6f ? 1 : r < 0.75f ? 2 : r < 0.85f ? 3 : 4;
        for (uint32_t y = 0; y < F->h; y++)
            for (uint32_t x = 0; x < F->w; x++) {
                uint8_t *p = t + ((size_t)y * F->w + x) * ts;
                for (unsigned c = 0; c < s->info.nchan; c++)
                    put_value(s, p, c, kind, ((float)x + 0.5f) / (float)F->w,
                              ((float)y + 0.5f) / (float)F->h, par, scale);
            }
    }
    st_set_build_mips(s, UINT32_MAX);
    void *buf = NULL;
    size_t len = 0;
    st_error e = {0};
    int rc = st_ptex_write_mem(s, &buf, &len, &e);
    if (rc)
        print_message("write: %s\n", e.msg);
    assert_int_equal(rc, 0);
    st_set_free(s);
    st_set *r2 = NULL;
    rc = st_ptex_read_mem(buf, len, 0, &r2, &e);
    if (rc)
        print_message("read: %s\n", e.msg);
    assert_int_equal(rc, 0);
    free(buf);
    assert_int_equal(st_ptexfilter_prepare(r2, &e), 0);
    return r2;
}

/* The set of info and fd (fd freed here), filled, written and read back (fill_write_read). */
static st_set *create_write_read(const st_set_info *info, st_face_desc *fd)
{
    st_set *s = NULL;
    st_error e = {0};
    int rc = st_set_create(info, fd, 0, &s, &e);
    if (rc)
        print_message("create: %s\n", e.msg);
    assert_int_equal(rc, 0);
    free(fd);
    return fill_write_read(s);
}


/* A quad set from the polygons of m (see the file header), each face's edges rotated at
 * random when rot. */
static st_set *quad_set(const mesh *m, const spec *sp, int rot)
{
    int nf = 0;
    for (int p = 0; p < m->np; p++) {
        int n = m->start[p + 1] - m->start[p];
        nf += n == 4 ? 1 : n;
    }
    int(*C)[4] = calloc((size_t)nf, sizeof *C);
    uint8_t *sub = calloc((size_t)nf, 1);
    st_face_desc *fd = calloc((size_t)nf, sizeof *fd);
    assert_true(C && sub && fd);
    mids d;
    mids_init(&d, m->nv, 2 * m->ni + m->np + 16);
    int f = 0;
    for (int p = 0; p < m->np; p++) {
        int n = m->start[p + 1] - m->start[p];
        const int *v = &m->idx[m->start[p]];
        if (n == 4) {
            memcpy(C[f++], v, sizeof C[0]);
            continue;
        }
        int cen = mid_new(&d, -1, -1);
        for (int i = 0; i < n; i++, f++) {
            C[f][0] = v[i];
            C[f][1] = mid_of(&d, v[i], v[(i + 1) % n]);
            C[f][2] = cen;
            C[f][3] = mid_of(&d, v[(i + n - 1) % n], v[i]);
            sub[f] = 1;
        }
    }
    hmap edges;
    hm_init(&edges, (size_t)nf * 4);
    for (f = 0; f < nf; f++) {
        if (rot) {
            int r = (int)rndu(4), c0[4];
            memcpy(c0, C[f], sizeof c0);
            for (int k = 0; k < 4; k++)
                C[f][k] = c0[(k + r) & 3];
        }
        for (int e = 0; e < 4; e++) { /* each directed edge once: a manifold mesh */
            assert_null(hm_slot(&edges, dkey(C[f][e], C[f][(e + 1) & 3]), 0));
            *hm_slot(&edges, dkey(C[f][e], C[f][(e + 1) & 3]), 1) = f * 4 + e;
        }
    }
    int nv0 = m->nv;
    for (f = 0; f < nf; f++)
        for (int e = 0; e < 4; e++) {
            int a = C[f][e], b = C[f][(e + 1) & 3], *hit = hm_slot(&edges, dkey(b, a), 0);
            fd[f].adjface[e] = -1;
            if (!hit && !sub[f]) { /* a main face's edge split on the other side */
                int *mid = hm_slot(&d.h, ukey(a, b), 0);
                hit = mid ? hm_slot(&edges, dkey(*mid, a), 0) : NULL;
                if (hit && !sub[*hit >> 2])
                    hit = NULL;
            } else if (!hit) { /* a subface's half edge against a main face's whole edge */
                int x = -1;
                if (b >= nv0 && d.ea[b - nv0] >= 0 && (d.ea[b - nv0] == a || d.eb[b - nv0] == a)) {
                    x = d.ea[b - nv0] == a ? d.eb[b - nv0] : d.ea[b - nv0];
                    hit = hm_slot(&edges, dkey(x, a), 0);
                } else if (a >= nv0 && d.ea[a - nv0] >= 0 &&
                           (d.ea[a - nv0] == b || d.eb[a - nv0] == b)) {
                    x = d.ea[a - nv0] == b ? d.eb[a - nv0] : d.ea[a - nv0];
                    hit = hm_slot(&edges, dkey(b, x), 0);
                }
                if (hit && sub[*hit >> 2])
                    hit = NULL;
            }
            if (hit) {
                fd[f].adjface[e] = *hit >> 2;
                fd[f].adjedge[e] = (int8_t)(*hit & 3);
            }
        }
    hm_free(&edges);
    mids_free(&d);
    /* resolutions */
    int ul0 = rand_log(sp->maxlog), vl0 = rand_log(sp->maxlog);
    size_t texels = 0;
    for (f = 0; f < nf; f++) {
        int ul = ul0, vl = vl0;
        if (sp->resmode == 1 || (sp->resmode == 2 && rndf() < 0.2f)) {
            ul = rand_log(sp->maxlog);
            vl = rndf() < 0.3f ? ul : rand_log(sp->maxlog);
        }
        while (texels + ((size_t)1 << (ul + vl)) > TEXEL_BUDGET / 2 && ul + vl > 0)
            *(ul > vl ? &ul : &vl) -= 1;
        texels += (size_t)1 << (ul + vl);
        fd[f].w = 1u << ul;
        fd[f].h = 1u << vl;
        fd[f].flags = (uint8_t)((sub[f] ? ST_FACE_SUBFACE : 0) |
                                (rndf() < sp->pconst ? ST_FACE_CONSTANT : 0));
    }
    st_set_info info = {.nfaces = (uint32_t)nf, .nchan = (uint8_t)sp->nchan,
                        .dtype = (uint8_t)sp->dtype, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE, .meshtype = ST_MESH_QUAD,
                        .border_u = (uint8_t)rndu(3), .border_v = (uint8_t)rndu(3)};
    free(C);
    free(sub);
    return create_write_read(&info, fd);
}

/* A triangle set from the triangles of m, each face's edges rotated at random when rot. */
static st_set *tri_set(const mesh *m, const spec *sp, int rot)
{
    int nf = m->np;
    int(*C)[3] = calloc((size_t)nf, sizeof *C);
    st_face_desc *fd = calloc((size_t)nf, sizeof *fd);
    assert_true(C && fd);
    hmap edges;
    hm_init(&edges, (size_t)nf * 3);
    for (int f = 0; f < nf; f++) {
        assert_int_equal(m->start[f + 1] - m->start[f], 3);
        int r = rot ? (int)rndu(3) : 0;
        for (int k = 0; k < 3; k++)
            C[f][k] = m->idx[m->start[f] + (k + r) % 3];
        for (int e = 0; e < 3; e++) {
            assert_null(hm_slot(&edges, dkey(C[f][e], C[f][(e + 1) % 3]), 0));
            *hm_slot(&edges, dkey(C[f][e], C[f][(e + 1) % 3]), 1) = f * 4 + e;
        }
    }
    int l0 = rand_log(sp->maxlog);
    size_t texels = 0;
    for (int f = 0; f < nf; f++) {
        for (int e = 0; e < 3; e++) {
            int *hit = hm_slot(&edges, dkey(C[f][(e + 1) % 3], C[f][e]), 0);
            fd[f].adjface[e] = hit ? *hit >> 2 : -1;
            fd[f].adjedge[e] = hit ? (int8_t)(*hit & 3) : 0;
        }
        fd[f].adjface[3] = -1;
        int l = sp->resmode == 1 || (sp->resmode == 2 && rndf() < 0.2f) ? rand_log(sp->maxlog) : l0;
        while (texels + ((size_t)1 << (2 * l)) > TEXEL_BUDGET / 2 && l > 0)
            l--;
        texels += (size_t)1 << (2 * l);
        fd[f].w = fd[f].h = 1u << l;
        fd[f].flags = rndf() < sp->pconst ? ST_FACE_CONSTANT : 0;
    }
    hm_free(&edges);
    st_set_info info = {.nfaces = (uint32_t)nf, .nchan = (uint8_t)sp->nchan,
                        .dtype = (uint8_t)sp->dtype, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE, .meshtype = ST_MESH_TRIANGLE,
                        .border_u = (uint8_t)rndu(3), .border_v = (uint8_t)rndu(3)};
    free(C);
    return create_write_read(&info, fd);
}

/* ---- queries ----------------------------------------------------------------------------- */

static const float fps[] = {0.25f, 0.5f, 1.0f, 2.0f, 4.0f, 7.0f, 16.0f, 32.0f};

/* A footprint in texels: an exact one of fps or one in between, 0.25 .. 32. */
static float rand_fp(void)
{
    return rndf() < 0.5f ? fps[rndu(8)] : exp2f(-2.0f + 7.0f * rndf());
}

/* The derivatives of a footprint of fu x fv texels on a w x h face, rotated a third of the
 * time (cross terms); a few zero. */
static void set_fp(st_query *q, float fu, float fv, float w, float h)
{
    float r = rndf();
    if (r < 0.02f)
        return; /* zero footprint */
    if (r < 0.35f) {
        float a = 6.2831853f * rndf(), c = cosf(a), sn = sinf(a);
        q->dudx = c * fu / w;
        q->dvdx = sn * fv / h;
        q->dudy = -sn * fu / w;
        q->dvdy = c * fv / h;
    } else {
        q->dudx = fu / w;
        q->dvdy = fv / h;
    }
}

static void quad_queries(const st_set *s, st_query *q, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        int run = i > 0 && rndf() < 0.4f; /* the face and footprint of the query before */
        uint32_t f = run ? q[i - 1].face : rndu(s->info.nfaces);
        const st_face *F = &s->faces[f];
        float W = (float)F->w, H = (float)F->h, u = rndf(), v = rndf();
        float r = rndf();
        if (r < 0.34f) { /* within 2 texels of an edge, or of a corner */
            float du = rndf() * 2.0f / W, dv = rndf() * 2.0f / H;
            if (rndf() < 0.5f)
                u = rndf() < 0.5f ? du : 1.0f - du;
            else
                v = rndf() < 0.5f ? dv : 1.0f - dv;
            if (rndf() < 0.5f) {
                u = rndf() < 0.5f ? du : 1.0f - du;
                v = rndf() < 0.5f ? dv : 1.0f - dv;
            }
        } else if (r < 0.5f) { /* texel centres */
            u = ((float)rndu(F->w) + 0.5f) / W;
            v = ((float)rndu(F->h) + 0.5f) / H;
        } else if (r < 0.54f) { /* on or past the bounds */
            float b[] = {0.0f, 1.0f, 0.99999994f, -0.02f, 1.03f};
            if (rndf() < 0.5f)
                u = b[rndu(5)];
            else
                v = b[rndu(5)];
        }
        if (u >= 1.0f && r < 0.5f)
            u = 0.99999994f;
        if (v >= 1.0f && r < 0.5f)
            v = 0.99999994f;
        st_query prev = i > 0 ? q[i - 1] : (st_query){0};
        q[i] = (st_query){.face = f, .u = u, .v = v};
        float fu = rand_fp(), fv = rndf() < 0.5f ? fu : rand_fp();
        set_fp(&q[i], fu, fv, W, H);
        if (run)
            q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = prev.dudx, .dvdx = prev.dvdx,
                              .dudy = prev.dudy, .dvdy = prev.dvdy};
    }
}

static void tri_queries(const st_set *s, st_query *q, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        int run = i > 0 && rndf() < 0.4f; /* the face and footprint of the query before */
        uint32_t f = run ? q[i - 1].face : rndu(s->info.nfaces);
        float R = (float)s->faces[f].w;
        float u = rndf(), v = rndf(), r = rndf();
        if (u + v > 1.0f) {
            u = 1.0f - u;
            v = 1.0f - v;
        }
        if (r < 0.34f) { /* within 2 texels of an edge or a corner */
            float d = 2.0f * rndf() / R;
            int side = (int)rndu(7);
            if (side == 0 || side == 3)
                v = d;
            if (side == 1 || side == 3)
                u = d;
            if (side == 2 || side == 4) {
                float t = 0.5f * (u + v - 1.0f + d);
                u -= t;
                v -= t;
            }
            if (side == 5)
                u = 1.0f - d, v = 0.5f * d;
            if (side == 6)
                v = 1.0f - d, u = 0.5f * d;
        } else if (r < 0.45f) { /* small triangle centroids */
            float i0 = (float)rndu(s->faces[f].w), j0 = (float)rndu(s->faces[f].w);
            if (i0 + j0 > R - 1.0f) {
                i0 = R - 1.0f - i0;
                j0 = R - 1.0f - j0;
            }
            float k = rndf() < 0.5f ? 1.0f / 3.0f : 2.0f / 3.0f;
            if (i0 + j0 > R - 2.0f)
                k = 1.0f / 3.0f;
            u = (i0 + k) / R;
            v = (j0 + k) / R;
        } else if (r < 0.55f) { /* past the triangle */
            u = -0.1f + 1.2f * u;
            v = -0.1f + 1.2f * v;
        }
        st_query prev = i > 0 ? q[i - 1] : (st_query){0};
        q[i] = (st_query){.face = f, .u = u, .v = v};
        float fu = rand_fp(), fv = rndf() < 0.5f ? fu : rand_fp();
        set_fp(&q[i], fu, fv, R, R);
        if (run) /* the same footprint, or one derivative changed */
            q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = prev.dudx, .dvdx = prev.dvdx,
                              .dudy = prev.dudy, .dvdy = prev.dvdy};
        if (run && rndf() < 0.25f)
            (&q[i].dudx)[rndu(4)] = q[i].dudx * 0.5f + 0.25f / R;
    }
}

/* ---- comparisons ------------------------------------------------------------------------- */

static float o1[NQ * 4], o2[NQ * 4], c1[NQ], c2[NQ];
static uint8_t s1[NQ], s2[NQ];

/* 0 when the two runs gave the same bytes, else prints the first difference and returns 1. */
static int differ(const char *what, const st_set *s, const st_sample_opts *o, const st_query *q,
                  size_t n, int r1, int r2, int cov)
{
    unsigned nc = s->info.nchan;
    if (r1 != r2) {
        print_message("%s mode %u filter %u: %d failed queries, the general path %d\n", what,
                      o->mode, o->filter, r1, r2);
        return 1;
    }
    for (size_t i = 0; i < n; i++)
        if (memcmp(&o1[i * nc], &o2[i * nc], nc * sizeof(float)) ||
            (cov && memcmp(&c1[i], &c2[i], sizeof(float))) || s1[i] != s2[i]) {
            const st_face *F = &s->faces[q[i].face < s->info.nfaces ? q[i].face : 0];
            print_message("%s mode %u filter %u width %g blur %g query %zu (face %u %ux%u flags "
                          "%u u %.9g v %.9g d %.9g %.9g %.9g %.9g): %.9g %.9g cov %.9g status %u "
                          "!= general %.9g %.9g cov %.9g status %u\n",
                          what, o->mode, o->filter, (double)o->width, (double)o->blur, i,
                          q[i].face, F->w, F->h, F->flags, (double)q[i].u, (double)q[i].v,
                          (double)q[i].dudx, (double)q[i].dvdx, (double)q[i].dudy,
                          (double)q[i].dvdy, (double)o1[i * nc], (double)o1[i * nc + nc - 1],
                          (double)c1[i], s1[i], (double)o2[i * nc], (double)o2[i * nc + nc - 1],
                          (double)c2[i], s2[i]);
            return 1;
        }
    return 0;
}

static const unsigned quad_filters[] = {
    ST_FILTER_PTEX_POINT,  ST_FILTER_PTEX_BILINEAR, ST_FILTER_PTEX_BOX,
    ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_BSPLINE,
    ST_FILTER_PTEX_CATMULLROM, ST_FILTER_PTEX_MITCHELL};

/* The quad set's queries through every filter, mode, option and path against the general
 * path; returns the number of groups that differ (each printed), *runs the groups run. */
static int quad_compare(const char *what, const st_set *s, const st_query *q, size_t n,
                        long *runs)
{
    static const int paths[] = {PF_PATH_BEST, PF_PATH_QUERY, PF_PATH_LANES4};
    int bad = 0;
    for (unsigned m = ST_MODE_DISCARD; m <= ST_MODE_CLAMP; m++)
        for (size_t fi = 0; fi < sizeof quad_filters / sizeof quad_filters[0]; fi++)
            for (int ov = 0; ov < (fi >= 2 ? 2 : 1); ov++) {
                st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)quad_filters[fi],
                                    .sharpness = 0.3f, .width = ov ? 1.5f : 0.0f,
                                    .blur = ov ? 0.02f : 0.0f};
                memset(o2, 0xa5, sizeof(float) * n * s->info.nchan);
                int r2 = pf_batch_path(s, &o, q, n, o2, c2, s2, PF_PATH_GENERAL);
                for (int p = 0; p < 3; p++) {
                    memset(o1, 0x5a, sizeof(float) * n * s->info.nchan);
                    int r1 = pf_batch_path(s, &o, q, n, o1, c1, s1, paths[p]);
                    char w[256];
                    snprintf(w, sizeof w, "%.200s path %d", what, paths[p]);
                    bad += differ(w, s, &o, q, n, r1, r2, 1);
                    (*runs)++;
                }
            }
    return bad;
}

static int tri_compare(const char *what, const st_set *s, const st_query *q, size_t n,
                       long *runs)
{
    static const uint8_t filt[] = {ST_FILTER_PTEX_POINT, ST_FILTER_PTEX_GAUSSIAN,
                                   ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_GAUSSIAN,
                                   ST_FILTER_PTEX_BOX};
    int bad = 0;
    for (int g = 0; g < 5; g++)
        for (uint8_t m = 0; m < 3; m++)
            for (int wc = 0; wc < 2; wc++) {
                st_sample_opts o = {.filter = filt[g], .mode = m, .sharpness = 0.3f,
                                    .width = g == 2 ? 1.5f : 0.0f, .blur = g == 2 ? 0.01f : 0.0f,
                                    .zero_rule = g == 3 ? ST_ZERO_CLAMP : ST_ZERO_NAN};
                memset(o2, 0xa5, sizeof(float) * n * s->info.nchan);
                memset(c2, 0, sizeof(float) * n);
                int r2 = st_ptextri_batch_general(s, &o, q, n, o2, wc ? c2 : NULL, s2);
                for (int base = 0; base < 2; base++) {
                    memset(o1, 0x5a, sizeof(float) * n * s->info.nchan);
                    memset(c1, 0, sizeof(float) * n);
                    int r1 = (base ? st_ptextri_batch_baseline : st_ptextri_batch)(
                        s, &o, q, n, o1, wc ? c1 : NULL, s1);
                    char w[256];
                    snprintf(w, sizeof w, "%.200s %s coverage %d", what,
                             base ? "baseline" : "lean", wc);
                    bad += differ(w, s, &o, q, n, r1, r2, wc);
                    (*runs)++;
                }
            }
    return bad;
}

/* ---- the tests --------------------------------------------------------------------------- */

/* With GEN_VERBOSE set: what set what holds (faces by kind, the largest and smallest, corner
 * valences, neighbours across edges) and the statuses of its queries under the gaussian. */
static void describe(const char *what, const st_set *s, const st_query *q, size_t n)
{
    if (!getenv("GEN_VERBOSE"))
        return;
    unsigned sub = 0, cons = 0, bound = 0, nb = 0, val[16] = {0}, ne = s->info.meshtype ? 3 : 4;
    uint32_t wmax = 0, wmin = UINT32_MAX, thin = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        sub += (F->flags & ST_FACE_SUBFACE) != 0;
        cons += (F->flags & ST_FACE_CONSTANT) != 0;
        thin += F->w != F->h;
        wmax = F->w * F->h > wmax ? F->w * F->h : wmax;
        wmin = F->w * F->h < wmin ? F->w * F->h : wmin;
        for (unsigned e = 0; e < ne; e++) {
            bound += F->adjface[e] < 0;
            nb += F->adjface[e] >= 0;
            val[F->valence[e] & 15]++;
        }
    }
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_GAUSSIAN};
    int failed = st_ptexfilter_batch(s, &o, q, n, o1, c1, s1);
    print_message("%s: %u subfaces, %u constant, %u not square, texels %u..%u, %u edges "
                  "shared, %u on a boundary, valences 3:%u 4:%u 5:%u 6+:%u, %d of %zu queries "
                  "failed\n", what, sub, cons, thin, wmin, wmax, nb, bound, val[3], val[4],
                  val[5], val[6] + val[7] + val[8] + val[9] + val[10] + val[11] + val[12],
                  failed, n);
}

static int env_int(const char *name, int dflt)
{
    const char *v = getenv(name);
    return v && *v ? atoi(v) : dflt;
}

static spec rand_spec(int tri)
{
    static const unsigned dts[] = {ST_DT_U8, ST_DT_U16, ST_DT_HALF, ST_DT_F32};
    spec sp = {.dtype = dts[rndu(4)], .nchan = 1 + rndu(4), .resmode = (int)rndu(3),
               .maxlog = 8, .pconst = rndf() < 0.5f ? 0.0f : 0.3f * rndf(), .tri = tri};
    return sp;
}

/* The shape of quad set number i: one of the meshes of the file header. */
static const char *quad_mesh(mesh *m, int i)
{
    switch (i % 11) {
    case 0: grid(m, 3 + (int)rndu(6), 2 + (int)rndu(6), 0, 0, 0.15f, 0.0f, 0.0f);
        return "grid with holes";
    case 1: grid(m, 3 + (int)rndu(5), 2 + (int)rndu(5), 0, 0, 0.05f, 0.2f, 0.15f);
        return "grid with triangles and hexagons (subfaces)";
    case 2: grid(m, 3 + (int)rndu(5), 1 + (int)rndu(4), 1, 0, 0.0f, 0.0f, 0.0f);
        return "cylinder";
    case 3: grid(m, 3 + (int)rndu(4), 3 + (int)rndu(4), 1, 1, 0.0f, 0.0f, 0.0f);
        return "torus";
    case 4: cube(m);
        return "cube";
    case 5: cube(m);
        refine(m);
        return "cube refined";
    case 6: bipyramid(m, 5 + (int)rndu(7));
        refine(m);
        return "bipyramid refined (valence 5..11)";
    case 7: bipyramid(m, 3 + (int)rndu(4));
        return "bipyramid of subfaces";
    case 8: fan(m, 5 + (int)rndu(8));
        return "fan (valence 5..12)";
    case 9: grid(m, 3 + (int)rndu(4), 3 + (int)rndu(4), 1, 1, 0.1f, 0.15f, 0.1f);
        return "torus with holes, triangles and hexagons";
    default: tetrahedron(m);
        refine(m);
        return "tetrahedron refined";
    }
}

static const char *tri_mesh(mesh *m, int i)
{
    switch (i % 5) {
    case 0: { /* triangulated grid with holes */
        grid(m, 2 + (int)rndu(5), 2 + (int)rndu(5), 0, 0, 0.1f, 1.0f, 0.0f);
        return "triangulated grid with holes";
    }
    case 1: tetrahedron(m);
        return "tetrahedron";
    case 2: bipyramid(m, 4 + (int)rndu(6));
        return "bipyramid (valence 4..9)";
    case 3: grid(m, 3 + (int)rndu(3), 3 + (int)rndu(3), 1, 1, 0.0f, 1.0f, 0.0f);
        return "triangulated torus";
    default: bipyramid(m, 3);
        return "triangular bipyramid";
    }
}

static void quad_sets_fast_paths_match_the_general_path(void **state)
{
    (void)state;
    static mesh m;
    static st_query q[NQ];
    int nsets = env_int("GEN_SETS", 66), bad = 0;
    long runs = 0;
    for (int i = 0; i < nsets; i++) {
        rng = (uint32_t)env_int("GEN_SEED", 2512) * 7919u + (uint32_t)i * 104729u;
        const char *shape = quad_mesh(&m, i);
        spec sp = rand_spec(0);
        st_set *s = quad_set(&m, &sp, i % 4 != 3);
        quad_queries(s, q, NQ);
        char what[200];
        snprintf(what, sizeof what, "quad set %d (%s, %u faces, dtype %u, %u channels, "
                 "resolutions %d)", i, shape, s->info.nfaces, sp.dtype, sp.nchan, sp.resmode);
        describe(what, s, q, NQ);
        int b = quad_compare(what, s, q, NQ, &runs);
        bad += b;
        st_set_free(s);
    }
    print_message("%d generated quad sets, %ld groups of %d queries compared, %d differ\n",
                  nsets, runs, NQ, bad);
    assert_int_equal(bad, 0);
}

static void triangle_sets_lean_sweeps_match_the_general_sweeps(void **state)
{
    (void)state;
    static mesh m;
    static st_query q[NQ];
    int nsets = env_int("GEN_SETS", 30), bad = 0;
    long runs = 0;
    for (int i = 0; i < nsets; i++) {
        rng = (uint32_t)env_int("GEN_SEED", 2512) * 6007u + (uint32_t)i * 15485863u + 1u;
        const char *shape = tri_mesh(&m, i);
        spec sp = rand_spec(1);
        st_set *s = tri_set(&m, &sp, 1);
        tri_queries(s, q, NQ);
        char what[200];
        snprintf(what, sizeof what, "triangle set %d (%s, %u faces, dtype %u, %u channels, "
                 "resolutions %d)", i, shape, s->info.nfaces, sp.dtype, sp.nchan, sp.resmode);
        describe(what, s, q, NQ);
        bad += tri_compare(what, s, q, NQ, &runs);
        st_set_free(s);
    }
    print_message("%d generated triangle sets, %ld groups of %d queries compared, %d differ\n",
                  nsets, runs, NQ, bad);
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(quad_sets_fast_paths_match_the_general_path),
        cmocka_unit_test(triangle_sets_lean_sweeps_match_the_general_sweeps),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
