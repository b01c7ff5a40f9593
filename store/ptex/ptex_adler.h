/* store/ptex/ptex_adler.h - Adler-32 (RFC 1950), the check value of every zlib stream in a
 * .ptx. The reader inflates raw deflate data and checks the stream's Adler-32 with this,
 * because zlib's own (scalar, one byte at a time) took a quarter of a Ptex import.
 *
 * Owns: the checksum only. Same results as zlib's adler32() for every input (tested).
 * Threading: pure function.
 */
#ifndef ST_PTEX_ADLER_H
#define ST_PTEX_ADLER_H

#include <stddef.h>
#include <stdint.h>

/* The Adler-32 of p[0..n) continued from adler (1 for a new stream). */
uint32_t st_ptx_adler32(uint32_t adler, const uint8_t *p, size_t n);

#endif
