/* tests/common/ptx_fixture.h - .ptx files made in memory, to upload in server tests without
 * the shared data.
 *
 * Owns: the built-in default set written as .ptx (optionally with face 0 repainted, so that
 * uploads of different content differ), and a small uniform set (four 32x32 RGBA8 faces
 * without neighbours: every face one size, so its BC1 form fits a DDS file). Does not own:
 * the writer (store/ptex.h) or the default set (store/defaultset.h).
 */
#ifndef ST_PTX_FIXTURE_H
#define ST_PTX_FIXTURE_H

#include <stddef.h>
#include <stdint.h>

#include "set.h"

/* The default set as a .ptx in memory (malloc'ed; *len its size), with face 0 painted from
 * `tint` when tint >= 0. NULL on failure (the reason on stderr). */
void *st_fixture_default_ptx(size_t *len, int tint);

/* Four 32x32 RGBA8 faces without neighbours as a .ptx in memory (malloc'ed), or NULL. */
void *st_fixture_uniform_ptx(size_t *len);

/* Corrupts, in place, the first block of level 1 (a stored reduction) of a .ptx held in
 * memory: a byte of its deflate data (what 0) or the last byte of its Adler-32 (what 1). The
 * file still imports (the Ptex reader defers the reductions); its levels past level 0 then
 * fail to inflate. -1 when the file has no zipped level-1 block (or is malformed). */
int st_fixture_corrupt_reduction(uint8_t *ptx, size_t len, int what);

/* An empty (zeroed) set of four n x n RGBA8 faces with no neighbours, for tests to fill;
 * NULL on failure. The caller frees it with st_set_free. */
st_set *st_fixture_rgba8_faces(uint32_t n);

#endif
