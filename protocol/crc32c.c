/* protocol/crc32c.c - stp_crc32c, the wire protocol's CRC-32C (upload and fetch checksums).
 *
 * The one implementation is util/crc32c.c (shared with the store's native set files). protocol/
 * includes libc headers only, so the util prototype is repeated here; every program that links
 * libseamtex_proto.a links libseamtex_util.a too (libseamtex.a bundles both).
 */
#include "proto.h"

uint32_t stu_crc32c(uint32_t crc, const void *p, size_t n);

uint32_t stp_crc32c(uint32_t crc, const void *p, size_t n)
{
    return stu_crc32c(crc, p, n);
}
