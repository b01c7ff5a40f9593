/* store/mesh/quadmesh.h - building a per-face texture set from a quad mesh.
 *
 * Owns: adjacency from shared edges (hash map of undirected edges), the per-face resolution
 * choice, baking texels from a callback of the 3D position, and two generators (a cube and a
 * subdivided cube, with optional random frame rotation per face). Does not own: the set layout
 * (set.h), files (import*.c), sampling (sample*.c).
 *
 * Conventions: quad q's vertices quads[4q + k], k = 0..3, are its face corners 0..3, i.e. the
 * uv points (0,0), (1,0), (1,1), (0,1); they run counter-clockwise seen from the front, so edge
 * k goes from vertex k to vertex k+1 (Ptex edge k). Two quads sharing an edge must traverse it
 * in opposite directions. The 3D point of (u, v) is the bilinear blend of the four corners.
 *
 * Ownership: a generator fills a caller's st_quadmesh with arrays the caller frees with
 * st_quadmesh_free; a caller-built mesh (own arrays) is only read. st_quadmesh_build returns a
 * set owned by the caller (st_set_free).
 */
#ifndef ST_QUADMESH_H
#define ST_QUADMESH_H

#include <stddef.h>
#include <stdint.h>

#include "set.h"

typedef struct st_quadmesh {
    uint32_t  nverts, nquads;
    float    *pos;     /* nverts * 3 floats: x, y, z */
    uint32_t *quads;   /* nquads * 4 vertex indices */
} st_quadmesh;

/* Per-face resolution: writes log2 of the level-0 width and height (each 0..ST_MAX_LOG2). */
typedef void (*st_quad_res_fn)(void *user, uint32_t face, uint8_t *ulog2, uint8_t *vlog2);
/* Texel value at (u, v) of face `face`, whose 3D point is P: writes nchan floats to out
 * (stored with st_channel_put: u8/u16 expect 0..1). */
typedef void (*st_quad_bake_fn)(void *user, uint32_t face, float u, float v, const float P[3],
                                float *out);

typedef struct st_quadmesh_opts {
    uint8_t  nchan;        /* 1..4 */
    uint8_t  dtype;        /* st_dtype */
    uint8_t  has_alpha;    /* the last channel is alpha */
    uint8_t  ulog2, vlog2; /* every face's size when res is NULL */
    st_quad_res_fn  res;   /* per-face size, or NULL */
    st_quad_bake_fn bake;  /* texel values, or NULL (texels stay 0) */
    void    *user;         /* passed to res and bake */
    size_t   max_bytes;    /* texel arena cap, 0 = ST_DEFAULT_MAX_BYTES */
} st_quadmesh_opts;

/* Fills fd[q].adjface / adjedge for every quad (other fields untouched) from shared edges.
 * Errors (ST_EADJ, naming the two vertices and the faces): an edge used by more than two
 * quads (non-manifold), an edge traversed in the same direction by two quads (inconsistent
 * orientation). ST_EINVAL: a vertex index out of range or a quad with a repeated vertex.
 * ST_ETOOBIG: more than ST_MAX_FACES quads. */
int st_quadmesh_adjacency(const st_quadmesh *m, st_face_desc *fd, st_error *e);

/* Builds a per-face set: adjacency as above, sizes from o, texels baked at texel centres
 * (u = (i + 0.5) / w, v = (j + 0.5) / h), then the mip chains. */
int st_quadmesh_build(const st_quadmesh *m, const st_quadmesh_opts *o, st_set **out,
                      st_error *e);

/* A cube [-1,1]^3 whose six sides are each split into n x n quads (n = 1: the plain 6-quad
 * cube), 6 n^2 quads, (vertices shared, faces outward). With rot_seed != 0 every quad's
 * vertex order is rotated by a pseudo-random 0..3 steps drawn from rot_seed, so that its uv
 * frame turns and every edge rotation occurs. Deterministic. n in 1..1024. */
int st_quadmesh_cube(uint32_t n, uint32_t rot_seed, st_quadmesh *out, st_error *e);

/* Frees a generator's arrays and zeroes m (NULL accepted). */
void st_quadmesh_free(st_quadmesh *m);

/* A ready-made st_quad_res_fn: user points to an st_quad_res_range; each face gets ulog2 and
 * vlog2 drawn independently in lo..hi from a hash of (seed, face). Deterministic. */
typedef struct st_quad_res_range {
    uint32_t seed;
    uint8_t  lo, hi;
} st_quad_res_range;
void st_quad_res_random(void *user, uint32_t face, uint8_t *ulog2, uint8_t *vlog2);

/* The 32-bit mixing hash the generators use (exposed so tests draw the same numbers). */
uint32_t st_quad_hash(uint32_t a, uint32_t b);

#endif
