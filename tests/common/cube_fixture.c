/* tests/common/cube_fixture.c - see cube_fixture.h. */
#include "cube_fixture.h"

#include <math.h>
#include <string.h>

void cf_smooth(const float P[3], unsigned nchan, float *out)
{
    double x = P[0], y = P[1], z = P[2];
    for (unsigned c = 0; c < nchan; c++)
        out[c] = (float)(0.5 + 0.25 * sin(1.1 * x + 0.7 * y - 0.5 * z + c) +
                         0.18 * cos(0.6 * x - 1.3 * y + 0.9 * z + 0.5 * c));
}

void cf_bake_smooth(void *user, uint32_t face, float u, float v, const float P[3], float *out)
{
    (void)face;
    (void)u;
    (void)v;
    cf_smooth(P, user ? *(const unsigned *)user : 4, out);
}

/* The build's one `user` serves both callbacks: channel count first, then the size range. */
typedef struct cf_user {
    unsigned nchan;
    st_quad_res_range range;
} cf_user;

static void cf_res(void *user, uint32_t face, uint8_t *ul, uint8_t *vl)
{
    st_quad_res_random(&((cf_user *)user)->range, face, ul, vl);
}

int cf_cube_build(cf_cube *c, unsigned n, uint32_t rot_seed, uint8_t lo, uint8_t hi,
                  uint32_t res_seed, st_dtype dtype, unsigned nchan)
{
    memset(c, 0, sizeof *c);
    c->n = n;
    int rc = st_quadmesh_cube(n, rot_seed, &c->mesh, NULL);
    if (rc)
        return rc;
    cf_user user = {.nchan = nchan, .range = {.seed = res_seed, .lo = lo, .hi = hi}};
    st_quadmesh_opts o = {.nchan = (uint8_t)nchan, .dtype = (uint8_t)dtype, .ulog2 = lo,
                          .vlog2 = lo, .res = lo != hi ? cf_res : NULL,
                          .bake = cf_bake_smooth, .user = &user};
    rc = st_quadmesh_build(&c->mesh, &o, &c->set, NULL);
    if (rc)
        cf_cube_free(c);
    return rc;
}

void cf_cube_free(cf_cube *c)
{
    st_quadmesh_free(&c->mesh);
    st_set_free(c->set);
    c->set = NULL;
}

void cf_point(const st_quadmesh *m, uint32_t f, float u, float v, float P[3])
{
    const uint32_t *q = &m->quads[4 * (size_t)f];
    float w[4] = {(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v};
    for (int k = 0; k < 3; k++) {
        P[k] = 0;
        for (int j = 0; j < 4; j++)
            P[k] += w[j] * m->pos[3 * (size_t)q[j] + k];
    }
}

unsigned cf_faces_at_vertex(const st_quadmesh *m, uint32_t vert, uint32_t *faces,
                            unsigned *corners, unsigned max)
{
    unsigned n = 0;
    for (uint32_t f = 0; f < m->nquads; f++)
        for (unsigned k = 0; k < 4; k++)
            if (m->quads[4 * (size_t)f + k] == vert && n < max) {
                faces[n] = f;
                corners[n] = k;
                n++;
            }
    return n;
}

st_query cf_q(uint32_t face, float u, float v)
{
    st_query q = {.face = face, .u = u, .v = v};
    return q;
}

int cf_sample1(const st_set *s, unsigned mode, unsigned filter, const st_query *q, float *out,
               float *cov)
{
    st_sample_opts o = {.mode = (uint8_t)mode, .filter = (uint8_t)filter};
    uint8_t st = 0;
    float c = 0;
    int rc = st_sample_batch(s, &o, q, 1, out, &c, &st);
    if (cov)
        *cov = c;
    return rc < 0 ? rc : st;
}

float cf_rand(uint32_t *state)
{
    *state = *state * 1664525u + 1013904223u;
    return (float)(*state >> 8) * (1.0f / 16777216.0f);
}
