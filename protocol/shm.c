/* protocol/shm.c - the shared-memory extension of SAMPLE (PROTOCOL.md 4.12): the OK reply of
 * a shared-memory request (where its reply body lies in the region) and the sizes a client and
 * the server compute for the queries and the reply.
 *
 * Owns: stp_enc_shm_reply / stp_dec_shm_reply, stp_sample_query_bytes,
 * stp_sample_reply_bytes. Does not own: the SAMPLE request's shared-memory form (bodies.c,
 * with the other SAMPLE fields), the region itself, file descriptors and mappings (server/shm.c,
 * client/libshm.c): nothing here does I/O.
 */
#include "proto.h"

int stp_enc_shm_reply(stp_buf *b, uint8_t opcode, uint32_t reqid, const stp_shm_reply *r)
{
    size_t at = stp_frame_begin(b, opcode, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, r->offset);
    stp_put_u64(b, r->length);
    return stp_frame_end(b, at);
}

int stp_dec_shm_reply(const uint8_t *body, size_t len, stp_shm_reply *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->offset = stp_get_u64(&rd);
    r->length = stp_get_u64(&rd);
    if (rd.bad || stp_rd_left(&rd) != 0) {
        if (why)
            *why = "shared-memory SAMPLE reply: not 16 bytes";
        return STP_S_BAD_REQUEST;
    }
    return 0;
}

uint64_t stp_sample_query_bytes(uint8_t opcode, uint8_t flags, uint32_t count)
{
    uint64_t q = opcode == STP_OP_SAMPLE_DIR ? STP_DIR_QUERY_SIZE : stp_query_size(flags);
    return q * count;
}

uint64_t stp_sample_reply_bytes(uint32_t count, unsigned nchan, uint8_t outfmt, uint8_t flags)
{
    uint64_t s = stp_outfmt_size(outfmt);
    if (!s)
        return 0;
    uint64_t per = (uint64_t)nchan * s + ((flags & STP_SF_COVERAGE) ? 4 : 0) +
                   ((flags & STP_SF_STATUS) ? 1 : 0);
    return 12 + per * count;
}
