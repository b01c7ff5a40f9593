/* store/import/mesh_io.h - reading meshes from files: OBJ (obj.c, no library) and Draco
 * (draco.cpp, the only user of the Draco library).
 *
 * Owns: the two readers. Does not own: the mesh type, welding and seams (mesh/mesh.h).
 *
 * Ownership: a reader returns a mesh the caller frees with st_mesh_free.
 */
#ifndef ST_MESH_IO_H
#define ST_MESH_IO_H

#include "mesh.h"

/* Reads an OBJ from memory. base_dir (may be NULL) is where mtllib files are looked for;
 * a missing .mtl is not an error (materials keep their names, no texture). Negative
 * indices, polygons, v/vt/vn forms, groups, usemtl, comments and line continuations are
 * handled; an index out of range, a NaN or infinite coordinate, a face with fewer than 3
 * corners or a size over the caps is ST_EFORMAT / ST_ETOOBIG naming the line. */
int st_obj_read_mem(const char *buf, size_t len, const char *base_dir,
                    const st_mesh_caps *caps, st_mesh **out, st_error *e);
int st_obj_read_file(const char *path, const st_mesh_caps *caps, st_mesh **out, st_error *e);

/* Reads a Draco .drc mesh (legacy and current bitstreams, edgebreaker and sequential) with its
 * TEX_COORD attribute when present (none: nuv = 0, every corner ST_MESH_NO_UV). A point cloud
 * is ST_EUNSUPPORTED. */
int st_draco_read_mem(const void *buf, size_t len, const st_mesh_caps *caps, st_mesh **out,
                      st_error *e);
int st_draco_read_file(const char *path, const st_mesh_caps *caps, st_mesh **out, st_error *e);

#endif
