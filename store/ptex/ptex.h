/* store/ptex/ptex.h - Ptex (.ptx) files: read into a texture set, write a set back out.
 *
 * Owns: the .ptx reader (ptex_read.c) and writer (ptex_write.c); the on-disk layout is in
 * ptex_format.h. Does not own: the set layout (set.h), filtering (ptexfilter.h, sample.h).
 *
 * Reading: Ptex file version 1 (any minor version, with or without the extended header),
 * quad meshes including subfaces of non-quad faces, and triangle meshes (info.meshtype
 * ST_MESH_TRIANGLE: square faces, three edges, Ptex's packed triangle layout, core/trilevel.h),
 * u8/u16/half/float, 1..4 channels (files with more channels are refused: the set holds at
 * most ST_MAX_CHANNELS), constant, zipped, diff-zipped and tiled face data, stored reductions,
 * small and large metadata, edit records.
 * The file's stored reductions replace the set's box reductions where the file has them
 * (level L of the set = Ptex reduction level L, both axes halved); the levels Ptex does not
 * store (past min(ulog2, vlog2) for a non-square face; below the stored reductions of a
 * triangle face) are filled the way the Ptex reader fills them on demand. Metadata becomes
 * set->meta (Ptex types kept).
 *
 * Hostile input: every header field is checked against the buffer length and the set caps
 * before anything is allocated; zlib streams must inflate to exactly the declared size. The
 * error message names the field, face or byte offset at fault.
 *
 * Ownership: *out is a new set the caller frees with st_set_free. The input buffer is only
 * read during the call (the set keeps a copy of what it still needs). No globals; safe to
 * call from several threads.
 */
#ifndef ST_PTEX_H
#define ST_PTEX_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"

/* Reads a .ptx held in memory. max_bytes caps the set's texel arena (0 = the default cap of
 * st_set_create); inflated sizes are also capped by it.
 *
 * Levels past level 0 are deferred (as Ptex reads them on demand): level 0, the faces,
 * adjacency and metadata are complete on return; the stored reductions are checked (every
 * size, offset, zip-ratio bound and zlib header) but kept zipped (st_ptex_read_file keeps its
 * file buffer; st_ptex_read_mem copies the level data from level 1 on), and inflated - with
 * the unstored levels filled - by the first st_set_levels
 * (set.h), which every reader of those levels calls (samplers, Ptex filters, the writers).
 * So a corrupt deflate body or Adler-32 of a stored reduction is found there: that call and
 * every later one return ST_EFORMAT with the message the import would have given. A caller
 * that wants the whole file checked at once calls st_set_levels right after (the daemon does)
 * or uses the _eager readers, which inflate everything in the one pass. */
int st_ptex_read_mem(const void *buf, size_t len, size_t max_bytes, st_set **out, st_error *e);

/* Reads a .ptx file (the whole file is read into memory first; files over 4 GiB are refused). */
int st_ptex_read_file(const char *path, size_t max_bytes, st_set **out, st_error *e);

/* The same, every level made before returning (the set needs no st_set_levels). */
int st_ptex_read_mem_eager(const void *buf, size_t len, size_t max_bytes, st_set **out,
                           st_error *e);
int st_ptex_read_file_eager(const char *path, size_t max_bytes, st_set **out, st_error *e);

/* Writes a per-face set as a Ptex v1.4 file: extended header, zipped face info and constant
 * data, level 0 plus the stored reductions in Ptex's rfaceid order, zipped (u8/u16:
 * diff-zipped) planar blocks, faces larger than Ptex's tile size tiled, small and large
 * metadata (a key the set holds more than once is written once, with its last value; the
 * importer's "seamtex:source_format" is not written), so that write(read(write(s))) ==
 * write(s) byte for byte.
 * The writer stores the set's own levels as the reductions, so reading the file back gives
 * the same set bit for bit. *buf is malloc'ed, the caller frees it. */
int st_ptex_write_mem(const st_set *s, void **buf, size_t *len, st_error *e);

/* The same into a file (written to path.tmp, fsynced, renamed). */
int st_ptex_write_file(const st_set *s, const char *path, st_error *e);

#endif
