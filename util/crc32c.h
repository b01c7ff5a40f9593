/* util/crc32c.h - CRC-32C (Castagnoli, reflected polynomial 0x82F63B78, init and final xor
 * 0xFFFFFFFF), libc only.
 *
 * Owns: the one CRC-32C implementation of seamtex (util/crc32c.c): the wire protocol's
 * stp_crc32c forwards to it, the store's native set files checksum their sections with it.
 * Incremental: crc = stu_crc32c(0, a, n); crc = stu_crc32c(crc, b, m). crc32c("123456789") is
 * 0xE3069283. Uses the SSE4.2 instruction when the CPU has it, else slice-by-8.
 */
#ifndef STU_CRC32C_H
#define STU_CRC32C_H

#include <stddef.h>
#include <stdint.h>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "util/crc32c.c reads words little-endian"
#endif

uint32_t stu_crc32c(uint32_t crc, const void *p, size_t n);

/* The table path alone (the unit test checks that both paths agree). */
uint32_t stu_crc32c_sw(uint32_t crc, const void *p, size_t n);

#endif
