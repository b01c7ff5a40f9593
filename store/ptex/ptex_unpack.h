/* store/ptex/ptex_unpack.h - turning an inflated Ptex block into set texels: undoing the
 * difference coding and interleaving planar channels into rows.
 *
 * A Ptex block stores its channels planar (all of channel 0 in rows of u, then channel 1...);
 * a diff-zipped one (u8/u16) stores x[i] - x[i-1] (mod 2^n) in one run over the whole planar
 * block. The set holds texels interleaved. Owns these two steps only (ptex_read.c inflates
 * and places blocks). SSE2 (part of every x86-64 CPU) for the common shapes, plain C for the
 * rest; results are the same bytes either way (moves and integer adds only).
 * Threading: pure functions on caller memory.
 */
#ifndef ST_PTEX_UNPACK_H
#define ST_PTEX_UNPACK_H

#include <stddef.h>
#include <stdint.h>

/* Undoes the difference coding of bytes bytes at p in place: u8 (csize 1) or u16 (csize 2,
 * p 2-byte aligned); other sizes are left alone. */
void st_ptx_undiff(size_t csize, uint8_t *p, size_t bytes);

/* Planar src (nc planes of w x h channels of csize bytes, rows of u) -> dst rows of w texels
 * of nc channels, rows stride bytes apart. dst and src aligned to csize. */
void st_ptx_planar_to_rows(size_t csize, unsigned nc, const uint8_t *src, uint32_t w,
                           uint32_t h, uint8_t *dst, size_t stride);

#endif
