/* tests/common/testhash.h - the byte hash and the small random stream of the tests that pin
 * outputs by hash (test_ptexfilter_edge, test_ptextri_outputs).
 *
 * Owns: st_test_fnv (64-bit FNV-1a, chainable: h starts at 0xcbf29ce484222325 or a previous
 * hash) and st_test_rndf (floats in [0, 1) from a 32-bit LCG whose state the caller keeps).
 * The pinned hashes (tests/unit/ptexfilter_edge_hashes.inc, ptextri_outputs_hashes.inc) were
 * made with exactly these: changing either changes every one of them. Header-only.
 */
#ifndef ST_TEST_TESTHASH_H
#define ST_TEST_TESTHASH_H

#include <stddef.h>
#include <stdint.h>

static inline uint64_t st_test_fnv(uint64_t h, const void *p, size_t n)
{
    const uint8_t *b = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 0x100000001b3ull;
    return h;
}

static inline float st_test_rndf(uint32_t *state)
{
    *state = *state * 1664525u + 1013904223u;
    return (float)(*state >> 8) / 16777216.0f;
}

#endif
