/* store/mesh/mesh.c - st_mesh allocation, freeing, position welding and the "needs UVs" check.
 *
 * Owns: st_mesh_alloc, st_mesh_free, st_seams_free, st_mesh_weld, st_mesh_require_uv.
 * Does not own: file readers (obj.c, draco.cpp), seam detection (seams.c).
 *
 * Welding is by exact float bits (with -0 folded to +0) through an open-addressing hash of
 * the position, O(npos) expected; positions that are NaN never reach here (readers refuse
 * them).
 */
#include "mesh.h"

#include <stdlib.h>
#include <string.h>

int st_mesh_alloc(uint32_t npos, uint32_t nuv, uint32_t ntri, st_mesh **out, st_error *e)
{
    *out = NULL;
    if (npos > ST_MESH_MAX_VERTS || nuv > ST_MESH_MAX_VERTS || ntri > ST_MESH_MAX_TRIS)
        return st_fail(e, ST_ETOOBIG, "mesh of %u positions, %u uvs, %u triangles is over the caps",
                       npos, nuv, ntri);
    st_mesh *m = calloc(1, sizeof *m);
    if (!m)
        return st_fail(e, ST_ENOMEM, "out of memory for a mesh");
    m->npos = npos;
    m->nuv = nuv;
    m->ntri = ntri;
    m->pos = calloc((size_t)npos * 3 + 1, sizeof(float));
    m->uv = calloc((size_t)nuv * 2 + 1, sizeof(float));
    m->tri_pos = calloc((size_t)ntri * 3 + 1, sizeof(uint32_t));
    m->tri_uv = calloc((size_t)ntri * 3 + 1, sizeof(uint32_t));
    m->tri_weld = calloc((size_t)ntri * 3 + 1, sizeof(uint32_t));
    m->tri_mat = calloc((size_t)ntri + 1, sizeof(uint16_t));
    m->tri_face = calloc((size_t)ntri + 1, sizeof(uint32_t));
    m->mats = calloc(1, sizeof *m->mats);
    if (!m->pos || !m->uv || !m->tri_pos || !m->tri_uv || !m->tri_weld || !m->tri_mat ||
        !m->tri_face || !m->mats) {
        st_mesh_free(m);
        return st_fail(e, ST_ENOMEM, "out of memory for a mesh of %u triangles", ntri);
    }
    m->nmat = 1;
    strcpy(m->mats[0].name, "default");
    *out = m;
    return ST_OK;
}

void st_seams_free(st_seams *s)
{
    if (!s)
        return;
    free(s->seams);
    free(s->boundary);
    free(s->nonmanifold);
    free(s->tri_chart);
    free(s);
}

void st_mesh_free(st_mesh *m)
{
    if (!m)
        return;
    st_seams_free(m->seams);
    free(m->pos);
    free(m->uv);
    free(m->tri_pos);
    free(m->tri_uv);
    free(m->tri_weld);
    free(m->tri_mat);
    free(m->tri_face);
    free(m->mats);
    free(m);
}

static uint32_t fbits(float f)
{
    uint32_t b;
    if (f == 0.0f)
        f = 0.0f; /* -0 -> +0 */
    memcpy(&b, &f, 4);
    return b;
}

static uint64_t pos_hash(const float *p)
{
    uint64_t h = 1469598103934665603ull;
    for (int k = 0; k < 3; k++) {
        h ^= fbits(p[k]);
        h *= 1099511628211ull;
        h ^= h >> 29;
    }
    return h;
}

int st_mesh_weld(st_mesh *m, st_error *e)
{
    if (m->nweld)
        return ST_OK;
    /* weld id per position index, then per corner */
    uint32_t *pid = malloc(((size_t)m->npos + 1) * sizeof *pid);
    size_t cap = 16;
    while (cap < (size_t)m->npos * 2)
        cap <<= 1;
    uint32_t *tab = malloc(cap * sizeof *tab);   /* position index + 1, 0 = empty */
    if (!pid || !tab) {
        free(pid);
        free(tab);
        return st_fail(e, ST_ENOMEM, "out of memory welding %u positions", m->npos);
    }
    memset(tab, 0, cap * sizeof *tab);
    uint32_t nw = 0;
    for (uint32_t i = 0; i < m->npos; i++) {
        const float *p = &m->pos[(size_t)i * 3];
        size_t h = (size_t)pos_hash(p) & (cap - 1);
        for (;;) {
            if (!tab[h]) {
                tab[h] = i + 1;
                pid[i] = nw++;
                break;
            }
            const float *q = &m->pos[(size_t)(tab[h] - 1) * 3];
            if (fbits(p[0]) == fbits(q[0]) && fbits(p[1]) == fbits(q[1]) &&
                fbits(p[2]) == fbits(q[2])) {
                pid[i] = pid[tab[h] - 1];
                break;
            }
            h = (h + 1) & (cap - 1);
        }
    }
    for (size_t c = 0; c < (size_t)m->ntri * 3; c++)
        m->tri_weld[c] = pid[m->tri_pos[c]];
    m->nweld = nw ? nw : 1;
    free(pid);
    free(tab);
    return ST_OK;
}

int st_mesh_require_uv(const st_mesh *m, st_error *e)
{
    if (!m || m->nuv == 0 || m->ntri_nouv >= m->ntri)
        return st_fail(e, ST_ENOUV,
                       "the mesh has no texture coordinates (%u triangles, none with UVs): an "
                       "atlas needs a UV-mapped mesh",
                       m ? m->ntri : 0);
    return ST_OK;
}

size_t st_mesh_memory(const st_mesh *m)
{
    if (!m)
        return 0;
    size_t t = m->ntri;
    size_t b = sizeof *m + (size_t)m->npos * 3 * sizeof(float) + (size_t)m->nuv * 2 * sizeof(float) +
               t * 3 * sizeof(uint32_t) * (m->tri_weld ? 3 : 2) + t * sizeof(uint16_t) +
               (m->tri_face ? t * sizeof(uint32_t) : 0) + (size_t)m->nmat * sizeof(st_material);
    const st_seams *s = m->seams;
    if (s)
        b += sizeof *s + (size_t)s->nseams * sizeof *s->seams +
             ((size_t)s->nboundary + s->nnonmanifold) * sizeof(st_mesh_edge) +
             (s->tri_chart ? t * sizeof(uint32_t) : 0);
    return b;
}
