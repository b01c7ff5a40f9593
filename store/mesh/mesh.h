/* store/mesh/mesh.h - triangle meshes with texture coordinates, and their UV seams.
 *
 * Owns: the in-memory mesh (st_mesh), its readers (obj.c: Wavefront OBJ + MTL; draco.cpp:
 * Draco .drc through the Draco library), position welding, and seam / boundary /
 * non-manifold edge detection (seams.c). Does not own: textures (image.h, atlas.h), the
 * texture set (set.h), seam masking for BC1 (seammask.h uses the seam list from here).
 *
 * Conventions:
 *   - Polygons are fan-triangulated on import (corner 0, i, i+1); tri_face keeps the index of
 *     the source polygon.
 *   - Texture coordinates are stored in the SET's texture space: u to the right, v DOWN from
 *     the image's top row (texel row j covers v in [j/h, (j+1)/h]). OBJ and Draco files (OBJ
 *     convention, v up) are flipped on import: v = 1 - v_file. So a mesh uv can be passed to
 *     st_sample_batch on the atlas face without conversion. UVs outside [0,1] are kept.
 *   - A triangle corner without a texture coordinate has tri_uv == ST_MESH_NO_UV (OBJ faces
 *     written "f 1 2 3" or "f 1//1 ..."); such triangles count in ntri_nouv.
 *   - Welding: corners whose positions are bit-identical floats (after -0 -> +0) get the same
 *     weld id (tri_weld); Draco splits positions where UVs split, OBJ files usually do not.
 *   - Triangle edge k of triangle t runs from corner k to corner (k+1)%3.
 *
 * Seams (st_mesh_find_seams, welded positions): a mesh edge is an unordered pair of distinct
 * weld ids used by a triangle side (a degenerate triangle, two corners welded together, still
 * contributes its two non-zero-length sides). These rules reproduce the figures of the
 * shared data README (duck 166 seams; spider 172 seams, 72 boundary, 16 non-manifold, 91
 * charts; cesium milk truck 479 seams, 376 charts).
 *   - boundary edge:     used by exactly one triangle side;
 *   - non-manifold edge: used by three or more triangle sides;
 *   - seam edge:         used by exactly two triangles whose texture coordinates along it
 *                        differ (compared by value: duplicated vt entries, and -0 against +0,
 *                        are not seams).
 *                        Both triangles must have UVs: an edge between a triangle with UVs and
 *                        one without is counted in nuv_border, not as a seam.
 *   - charts:            connected components of triangles across manifold non-seam edges
 *                        between two UV'd triangles; a triangle without UVs, or one whose
 *                        every edge is a seam / boundary / non-manifold, is a chart alone.
 * For each seam the two UV segments are stored in the same order along the 3D edge (both
 * from weld id pos[0] to pos[1]) with the UV-space winding of each triangle, so a consumer
 * knows whether one side is mirrored.
 *
 * Ownership: readers return a mesh the caller frees with st_mesh_free (NULL accepted), which
 * also frees an attached seam list. Nothing here keeps global state.
 */
#ifndef ST_MESH_H
#define ST_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"

#define ST_MESH_NO_UV        UINT32_MAX
#define ST_MESH_MAX_TRIS     (1u << 26)   /* default cap on triangles */
/* What a triangle of an imported mesh costs in memory, reader and seams together (measured
 * about 130 bytes, docs/import.md): an import's byte cap allows max_bytes / this many. */
#define ST_MESH_BYTES_PER_TRI 128u
#define ST_MESH_MAX_VERTS    (1u << 26)   /* default cap on positions / uvs */
#define ST_MESH_MAX_MATERIALS 4096

typedef struct st_material {
    char name[128];
    char map_kd[512];      /* map_Kd as resolved to a path (backslashes turned into '/',
                              relative to the .mtl's folder); "" when none, or when the file
                              names an absolute path or one with ".." (not followed) */
} st_material;

/* One side of a seam: a triangle edge and the UV segment along it. */
typedef struct st_seam_edge {
    uint32_t pos[2];       /* weld ids of the edge, pos[0] < pos[1] */
    uint32_t tri[2];       /* the two triangles */
    uint8_t  edge[2];      /* edge index 0..2 of the edge in tri[k] */
    int8_t   winding[2];   /* sign of tri[k]'s signed area in UV space: +1, -1, 0 degenerate */
    uint8_t  mirrored;     /* 1 when winding[0] != winding[1] (one chart is flipped) */
    float    uv[2][2][2];  /* uv[k][end][axis]: tri[k]'s texture coordinate at pos[end] */
} st_seam_edge;

/* A boundary or non-manifold edge. */
typedef struct st_mesh_edge {
    uint32_t pos[2];       /* weld ids, pos[0] < pos[1] */
    uint32_t tri;          /* the (first) triangle using it */
    uint8_t  edge;         /* its edge index in tri */
    uint32_t count;        /* triangle sides using the edge (1 boundary, >= 3 non-manifold) */
} st_mesh_edge;

typedef struct st_seams {
    st_seam_edge *seams;        uint32_t nseams;
    st_mesh_edge *boundary;     uint32_t nboundary;
    st_mesh_edge *nonmanifold;  uint32_t nnonmanifold;
    uint32_t nedges;            /* distinct edges */
    uint32_t ncharts;           /* see above */
    uint32_t *tri_chart;        /* ntri entries: chart id 0..ncharts-1 */
    uint32_t ndegenerate;       /* triangles with two corners on one weld id */
    uint32_t nuv_border;        /* manifold edges between a UV'd and a UV-less triangle */
} st_seams;

typedef struct st_mesh {
    uint32_t  npos, nuv, ntri;
    float    *pos;              /* npos * 3 */
    float    *uv;               /* nuv * 2, texture space (see above) */
    uint32_t *tri_pos;          /* ntri * 3 indices into pos */
    uint32_t *tri_uv;           /* ntri * 3 indices into uv, or ST_MESH_NO_UV */
    uint32_t *tri_weld;         /* ntri * 3 weld ids (filled by st_mesh_weld) */
    uint32_t  nweld;            /* distinct weld ids (0 before st_mesh_weld) */
    uint16_t *tri_mat;          /* ntri material ids (index into mats; 0 when none) */
    uint32_t *tri_face;         /* ntri: index of the source polygon */
    uint32_t  nfaces_src;       /* polygons in the source file */
    uint32_t  ntri_nouv;        /* triangles with at least one corner without a uv */
    st_material *mats;          /* nmat entries (at least one, "default") */
    uint32_t  nmat;
    st_seams *seams;            /* NULL until st_mesh_find_seams; owned by the mesh */
} st_mesh;

typedef struct st_mesh_caps {
    uint32_t max_tris;          /* 0 = ST_MESH_MAX_TRIS */
    uint32_t max_verts;         /* 0 = ST_MESH_MAX_VERTS */
    size_t   max_bytes;         /* cap on the input file, 0 = 1 GiB */
    uint8_t  no_side_files;     /* 1: open no file the input names (an OBJ's mtllib): for input
                                   from outside, whose folder may hold other users' files */
} st_mesh_caps;


/* Fills tri_weld / nweld (idempotent). */
int st_mesh_weld(st_mesh *m, st_error *e);

/* Welds when needed, then finds seams, boundary and non-manifold edges and charts, and
 * attaches them to m->seams (replacing an older list). */
int st_mesh_find_seams(st_mesh *m, st_error *e);

/* ST_ENOUV with a clear message when the mesh has no texture coordinates at all. */
int st_mesh_require_uv(const st_mesh *m, st_error *e);

/* Allocates an empty mesh with room for the given counts (all arrays allocated, zeroed;
 * one "default" material). Used by readers and tests. */
int st_mesh_alloc(uint32_t npos, uint32_t nuv, uint32_t ntri, st_mesh **out, st_error *e);

/* Bytes the mesh and its seam list hold in memory. */
size_t st_mesh_memory(const st_mesh *m);

void st_mesh_free(st_mesh *m);
void st_seams_free(st_seams *s);

#endif
