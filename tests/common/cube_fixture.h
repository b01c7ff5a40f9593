/* tests/common/cube_fixture.h - cube texture sets for tests and benchmarks (sampler, Ptex
 * filter, BC1, server tests may reuse them).
 *
 * Owns: a smooth analytic 3D function to bake, cube and subdivided-cube sets built through
 * quadmesh.h (kept together with their mesh so a test can get the 3D point of any (face, u, v)),
 * and small lookups (the faces around a vertex). Does not own: the builder (store/quadmesh.c).
 */
#ifndef CUBE_FIXTURE_H
#define CUBE_FIXTURE_H

#include <stdint.h>

#include "quadmesh.h"
#include "sample.h"

/* Smooth function of the 3D point, nchan channels in about 0.05..0.95; its gradient is
 * below 1 per unit of length. */
void cf_smooth(const float P[3], unsigned nchan, float *out);
/* st_quad_bake_fn that bakes cf_smooth (user: pointer to the unsigned channel count, or NULL
 * for 4 channels). */
void cf_bake_smooth(void *user, uint32_t face, float u, float v, const float P[3], float *out);

typedef struct cf_cube {
    st_quadmesh mesh;  /* owned */
    st_set     *set;   /* owned */
    unsigned    n;     /* subdivisions per side */
} cf_cube;

/* A cube subdivided n x n per side, baked from cf_smooth. rot_seed != 0 rotates the quads'
 * frames. Face sizes: 2^lo when lo == hi, else drawn per face and axis in 2^lo..2^hi (seed
 * res_seed). Returns 0 or an ST_E* code. */
int cf_cube_build(cf_cube *c, unsigned n, uint32_t rot_seed, uint8_t lo, uint8_t hi,
                  uint32_t res_seed, st_dtype dtype, unsigned nchan);
void cf_cube_free(cf_cube *c);

/* 3D point of (u, v) on quad f (bilinear blend of its corners, as baked). */
void cf_point(const st_quadmesh *m, uint32_t f, float u, float v, float P[3]);

/* Faces (and the corner of each) whose corner lies on vertex `vert`; returns how many
 * (at most max). */
unsigned cf_faces_at_vertex(const st_quadmesh *m, uint32_t vert, uint32_t *faces,
                            unsigned *corners, unsigned max);

/* One query with zero footprint. */
st_query cf_q(uint32_t face, float u, float v);

/* Samples one query; returns its status, fills out (nchan floats) and *cov. */
int cf_sample1(const st_set *s, unsigned mode, unsigned filter, const st_query *q, float *out,
               float *cov);

/* Deterministic uniform random float in [0, 1) from a 32-bit state. */
float cf_rand(uint32_t *state);

#endif
