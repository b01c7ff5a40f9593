/* store/mesh/seams.c - UV seams, boundary and non-manifold edges, and charts of a triangle mesh.
 *
 * Owns: st_mesh_find_seams. Does not own: welding (mesh.c), using the seams (seammask.c,
 * atlas.c). The rules (what counts as a seam, a boundary, a chart) are in mesh.h.
 *
 * Method: every triangle side becomes a record (edge key = the two weld ids, smaller first);
 * the records are sorted by key, so the sides of one edge are adjacent; each run of equal
 * keys is one edge, classified by its length (1 boundary, 2 manifold, 3+ non-manifold).
 * Charts are the union-find components of triangles over manifold non-seam edges between
 * two UV'd triangles (so a UV-less or degenerate triangle is a chart of its own).
 * O(n log n) in the number of triangles, two allocations of 3 * ntri records.
 */
#include "mesh.h"

#include <stdlib.h>
#include <string.h>

typedef struct side {
    uint64_t key;     /* lo << 32 | hi */
    uint32_t tri;
    uint8_t  edge;
} side;

static int side_cmp(const void *a, const void *b)
{
    const side *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    if (x->tri != y->tri)
        return x->tri < y->tri ? -1 : 1;
    return (int)x->edge - (int)y->edge;
}

static uint32_t uf_find(uint32_t *p, uint32_t x)
{
    while (p[x] != x) {
        p[x] = p[p[x]];
        x = p[x];
    }
    return x;
}

static int tri_has_uv(const st_mesh *m, uint32_t t)
{
    const uint32_t *u = &m->tri_uv[(size_t)t * 3];
    return u[0] != ST_MESH_NO_UV && u[1] != ST_MESH_NO_UV && u[2] != ST_MESH_NO_UV;
}

static int8_t uv_winding(const st_mesh *m, uint32_t t)
{
    if (!tri_has_uv(m, t))
        return 0;
    const uint32_t *u = &m->tri_uv[(size_t)t * 3];
    const float *a = &m->uv[(size_t)u[0] * 2], *b = &m->uv[(size_t)u[1] * 2],
                *c = &m->uv[(size_t)u[2] * 2];
    double area = ((double)b[0] - a[0]) * ((double)c[1] - a[1]) -
                  ((double)b[1] - a[1]) * ((double)c[0] - a[0]);
    return area > 0 ? 1 : area < 0 ? -1 : 0;
}

/* The texture coordinates of side (tri, edge) at weld ids lo and hi. */
static void side_uv(const st_mesh *m, uint32_t t, unsigned k, uint32_t lo, float out[2][2])
{
    unsigned c0 = k, c1 = (k + 1) % 3;
    if (m->tri_weld[(size_t)t * 3 + c0] != lo) {
        unsigned x = c0;
        c0 = c1;
        c1 = x;
    }
    const float *a = &m->uv[(size_t)m->tri_uv[(size_t)t * 3 + c0] * 2];
    const float *b = &m->uv[(size_t)m->tri_uv[(size_t)t * 3 + c1] * 2];
    out[0][0] = a[0];
    out[0][1] = a[1];
    out[1][0] = b[0];
    out[1][1] = b[1];
}

/* The two UV segments are equal by value (so -0 and +0 are the same coordinate; a bitwise
 * compare made an edge between vt 0 0 and vt -0 0 a seam). UVs are finite (readers refuse
 * NaN), so == is an equivalence here. */
static int same_segment(float a[2][2], float b[2][2])
{
    return a[0][0] == b[0][0] && a[0][1] == b[0][1] && a[1][0] == b[1][0] && a[1][1] == b[1][1];
}

static int push_edge(st_mesh_edge **arr, uint32_t *n, uint32_t *cap, const st_mesh_edge *x)
{
    if (*n == *cap) {
        uint32_t nc = *cap ? *cap * 2 : 64;
        st_mesh_edge *q = realloc(*arr, (size_t)nc * sizeof *q);
        if (!q)
            return -1;
        *arr = q;
        *cap = nc;
    }
    (*arr)[(*n)++] = *x;
    return 0;
}

int st_mesh_find_seams(st_mesh *m, st_error *e)
{
    int rc = st_mesh_weld(m, e);
    if (rc)
        return rc;
    st_seams *S = calloc(1, sizeof *S);
    side *sd = malloc(((size_t)m->ntri * 3 + 1) * sizeof *sd);
    uint32_t *parent = malloc(((size_t)m->ntri + 1) * sizeof *parent);
    if (!S || !sd || !parent) {
        free(sd);
        free(parent);
        st_seams_free(S);
        return st_fail(e, ST_ENOMEM, "out of memory for the edges of %u triangles", m->ntri);
    }
    S->tri_chart = malloc(((size_t)m->ntri + 1) * sizeof *S->tri_chart);
    if (!S->tri_chart) {
        free(sd);
        free(parent);
        st_seams_free(S);
        return st_fail(e, ST_ENOMEM, "out of memory for charts");
    }
    size_t ns = 0;
    for (uint32_t t = 0; t < m->ntri; t++) {
        parent[t] = t;
        const uint32_t *w = &m->tri_weld[(size_t)t * 3];
        if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2])
            S->ndegenerate++; /* its non-zero-length sides still count */
        for (unsigned k = 0; k < 3; k++) {
            uint32_t a = w[k], b = w[(k + 1) % 3];
            if (a == b)
                continue;
            uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
            sd[ns].key = (uint64_t)lo << 32 | hi;
            sd[ns].tri = t;
            sd[ns].edge = (uint8_t)k;
            ns++;
        }
    }
    qsort(sd, ns, sizeof *sd, side_cmp);
    uint32_t cap_seam = 0, cap_b = 0, cap_nm = 0;
    for (size_t i = 0; i < ns && rc == ST_OK;) {
        size_t j = i + 1;
        while (j < ns && sd[j].key == sd[i].key)
            j++;
        uint32_t cnt = (uint32_t)(j - i);
        uint32_t lo = (uint32_t)(sd[i].key >> 32), hi = (uint32_t)sd[i].key;
        S->nedges++;
        st_mesh_edge me = {{lo, hi}, sd[i].tri, sd[i].edge, cnt};
        if (cnt == 1) {
            if (push_edge(&S->boundary, &S->nboundary, &cap_b, &me))
                rc = st_fail(e, ST_ENOMEM, "out of memory for boundary edges");
        } else if (cnt >= 3) {
            if (push_edge(&S->nonmanifold, &S->nnonmanifold, &cap_nm, &me))
                rc = st_fail(e, ST_ENOMEM, "out of memory for non-manifold edges");
        } else {
            uint32_t t0 = sd[i].tri, t1 = sd[i + 1].tri;
            int h0 = tri_has_uv(m, t0), h1 = tri_has_uv(m, t1);
            st_seam_edge se;
            memset(&se, 0, sizeof se);
            int seam = 0;
            if (h0 && h1) {
                side_uv(m, t0, sd[i].edge, lo, se.uv[0]);
                side_uv(m, t1, sd[i + 1].edge, lo, se.uv[1]);
                seam = !same_segment(se.uv[0], se.uv[1]);
                if (!seam)
                    parent[uf_find(parent, t0)] = uf_find(parent, t1);
            } else if (h0 || h1) {
                S->nuv_border++;
            }
            if (seam) {
                se.pos[0] = lo;
                se.pos[1] = hi;
                se.tri[0] = t0;
                se.tri[1] = t1;
                se.edge[0] = sd[i].edge;
                se.edge[1] = sd[i + 1].edge;
                se.winding[0] = uv_winding(m, t0);
                se.winding[1] = uv_winding(m, t1);
                se.mirrored = se.winding[0] != se.winding[1];
                if (S->nseams == cap_seam) {
                    uint32_t nc = cap_seam ? cap_seam * 2 : 64;
                    st_seam_edge *q = realloc(S->seams, (size_t)nc * sizeof *q);
                    if (!q) {
                        rc = st_fail(e, ST_ENOMEM, "out of memory for seams");
                        break;
                    }
                    S->seams = q;
                    cap_seam = nc;
                }
                S->seams[S->nseams++] = se;
            }
        }
        i = j;
    }
    free(sd);
    if (rc) {
        free(parent);
        st_seams_free(S);
        return rc;
    }
    /* charts: number the union-find roots of UV'd, non-degenerate triangles */
    for (uint32_t t = 0; t < m->ntri; t++)
        S->tri_chart[t] = UINT32_MAX;
    uint32_t *root_id = malloc(((size_t)m->ntri + 1) * sizeof *root_id);
    if (!root_id) {
        free(parent);
        st_seams_free(S);
        return st_fail(e, ST_ENOMEM, "out of memory for charts");
    }
    for (uint32_t t = 0; t < m->ntri; t++)
        root_id[t] = UINT32_MAX;
    for (uint32_t t = 0; t < m->ntri; t++) {
        uint32_t r = uf_find(parent, t);
        if (root_id[r] == UINT32_MAX)
            root_id[r] = S->ncharts++;
        S->tri_chart[t] = root_id[r];
    }
    free(root_id);
    free(parent);
    st_seams_free(m->seams);
    m->seams = S;
    return ST_OK;
}
