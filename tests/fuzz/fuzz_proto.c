/* tests/fuzz/fuzz_proto.c - libFuzzer target for the wire protocol: arbitrary bytes go through
 * the incremental header parser as a stream of frames, and every body goes through every
 * decoder (requests and replies, the CLUSTER reply of protocol/stp_cluster.h too), including the iterators and converters that run on a
 * decoded body. Checks that need no oracle: no crash, no read outside the input (ASan), the
 * parser's answer does not change when more bytes arrive (a prefix may only say NEED_MORE or
 * the same BAD), a decoded count always fits the body it came from (in each SAMPLE query
 * layout, PROTOCOL.md 4.4.1) and agrees with stp_sample_peek_count, and a decoded compact
 * query is a fixed point of its rounding; a shared-memory SAMPLE (PROTOCOL.md 4.12) carries no
 * query bytes and its reply is exactly 16 bytes.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "stp_cluster.h"

#define CHECK(c) do { if (!(c)) __builtin_trap(); } while (0)

static void all_decoders(const uint8_t *b, size_t n)
{
    const char *why;
    union {
        stp_hello_req hq; stp_hello_reply hr; stp_list_req lq; stp_list_reply lr;
        stp_info_req iq; stp_info_reply ir; stp_sample_req sq; stp_sample_reply sr;
        stp_stats_reply st; stp_upload_begin ub; stp_upload_begin_reply ubr;
        stp_upload_chunk uc; stp_upload_progress up; stp_upload_done ud;
        stp_compress_req cq; stp_job_status js; stp_fetch_open fo; stp_fetch_open_reply fr;
        stp_fetch_read rd; stp_fetch_data fd; stp_cluster_reply cl;
    } u;
    char name[STP_MAX_NAME + 1], msg[64];
    uint64_t id;

    (void)stp_dec_empty(b, n, &why);
    (void)stp_dec_hello_req(b, n, &u.hq, &why);
    (void)stp_dec_hello_reply(b, n, &u.hr, &why);
    (void)stp_dec_list_req(b, n, &u.lq, &why);
    if (stp_dec_list_reply(b, n, &u.lr, &why) == 0) {
        size_t pos = 0, k = 0;
        stp_list_entry e;
        while (stp_list_next(&u.lr, &pos, &e))
            k++;
        CHECK(k == u.lr.count);
    }
    (void)stp_dec_info_req(b, n, &u.iq, &why);
    if (stp_dec_info_reply(b, n, &u.ir, &why) == 0) {
        stp_face_rec f;
        CHECK((uint64_t)u.ir.nrec * STP_FACE_REC_SIZE + 80 == n);
        for (uint32_t i = 0; i < u.ir.nrec; i++)
            stp_info_face(&u.ir, i, &f);
    }
    for (int dir = 0; dir < 2; dir++) {
        int s = dir ? stp_dec_sample_dir_req(b, n, 1u << 20, &u.sq, &why)
                    : stp_dec_sample_req(b, n, 1u << 20, &u.sq, &why);
        if (s == 0 && (u.sq.p.flags & STP_SF_SHM)) {
            /* shared-memory form (4.12): offsets instead of queries, no query in the body */
            CHECK(u.sq.count <= (1u << 20) && u.sq.raw == NULL && n >= STP_SHM_REF_SIZE + 26);
            CHECK(stp_sample_peek_count(b, n) == u.sq.count);
        } else if (s == 0) {
            stp_query q;
            stp_dir_query dq;
            CHECK(u.sq.count <= (1u << 20));
            CHECK((uint64_t)u.sq.count * (dir ? STP_DIR_QUERY_SIZE : stp_query_size(u.sq.p.flags)) <= n);
            CHECK(stp_sample_peek_count(b, n) == u.sq.count);
            for (uint32_t i = 0; i < u.sq.count; i++) {
                if (dir) {
                    stp_sample_dir_query(&u.sq, i, &dq);
                } else {
                    /* a decoded compact query is already rounded: rounding it through its
                     * own layout again changes nothing (NaN payloads aside) */
                    stp_query r;
                    stp_sample_query(&u.sq, i, &q);
                    stp_query_round(&q, u.sq.p.flags, &r);
                    CHECK(r.face == q.face);
                    const float *a = &q.u, *c = &r.u;
                    for (int k = 0; k < 6; k++)
                        CHECK(a[k] != a[k] ? c[k] != c[k] : memcmp(&a[k], &c[k], 4) == 0);
                }
            }
        }
    }
    stp_shm_reply shr;
    if (stp_dec_shm_reply(b, n, &shr, &why) == 0)
        CHECK(n == STP_SHM_REPLY_SIZE);
    if (stp_dec_sample_reply(b, n, &u.sr, &why) == 0) {
        size_t nv = (size_t)u.sr.count * u.sr.nchan;
        CHECK(nv * stp_outfmt_size(u.sr.outfmt) <= n);
        float *out = malloc((nv ? nv : 1) * sizeof(float));
        float *cov = malloc((u.sr.count ? u.sr.count : 1) * sizeof(float));
        uint16_t *u16 = malloc((nv ? nv : 1) * sizeof(uint16_t));
        if (out && cov && u16) {
            stp_sample_values_f32(&u.sr, out);
            (void)stp_sample_values_u16(&u.sr, u16);
            stp_sample_coverage(&u.sr, cov);
        }
        free(out);
        free(cov);
        free(u16);
    }
    if (stp_dec_stats_reply(b, n, &u.st, &why) == 0) {
        size_t pos = 0, k = 0;
        stp_stat s;
        while (stp_stats_next(&u.st, &pos, &s))
            k++;
        CHECK(k == u.st.count);
    }
    (void)stp_dec_upload_begin(b, n, &u.ub, &why);
    (void)stp_dec_upload_begin_reply(b, n, &u.ubr, &why);
    if (stp_dec_upload_chunk(b, n, &u.uc, &why) == 0)
        CHECK((size_t)u.uc.len + 20 == n);
    (void)stp_dec_upload_progress(b, n, &u.up, &why);
    (void)stp_dec_upload_done(b, n, &u.ud, &why);
    (void)stp_dec_compress_req(b, n, &u.cq, &why);
    (void)stp_dec_job_status(b, n, &u.js, &why);
    (void)stp_dec_fetch_open(b, n, &u.fo, &why);
    (void)stp_dec_fetch_open_reply(b, n, &u.fr, &why);
    (void)stp_dec_fetch_read(b, n, &u.rd, &why);
    if (stp_dec_fetch_data(b, n, &u.fd, &why) == 0)
        CHECK((size_t)u.fd.len + 12 == n);
    if (stp_dec_cluster_reply(b, n, &u.cl, &why) == 0) {
        /* every entry the decoder accepted is walked again, inside the body */
        size_t pos = 0, k = 0;
        stp_cluster_node e;
        while (stp_cluster_next(&u.cl, &pos, &e)) {
            CHECK(e.id + e.id_len <= (const char *)b + n && e.addr + e.addr_len <= (const char *)b + n);
            k++;
        }
        CHECK(k == u.cl.count);
    }
    (void)stp_dec_name_req(b, n, name, &why);
    (void)stp_dec_id_req(b, n, &id, &why);
    stp_dec_error(b, n, msg, sizeof msg);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* Copy so that ASan knows the exact end of the input buffer. */
    uint8_t *buf = malloc(size ? size : 1);
    size_t off = 0;
    if (!buf)
        return 0;
    memcpy(buf, data, size);

    all_decoders(buf, size);

    /* The input as a stream of frames with a small cap, as a server would read it. */
    while (off < size) {
        stp_header h, h2;
        int reason = 0, reason2 = 0;
        int r = stp_parse_header(buf + off, size - off, 4096, &h, &reason);
        /* Incremental consistency: any shorter view says NEED_MORE or the same BAD. */
        for (size_t k = 0; k < STP_HEADER_SIZE && k < size - off; k++) {
            int r2 = stp_parse_header(buf + off, k, 4096, &h2, &reason2);
            CHECK(r2 == STP_NEED_MORE || (r2 == STP_BAD && r == STP_BAD &&
                                          reason2 == STP_R_BAD_MAGIC && reason == reason2));
        }
        if (r == STP_NEED_MORE)
            break;
        if (r == STP_BAD && stp_reason_fatal(reason))
            break;
        off += STP_HEADER_SIZE;
        if (r == STP_BAD) {               /* skip the body, as a receiver must */
            CHECK(reason == STP_R_BAD_VERSION || reason == STP_R_TOO_LARGE);
            off += size - off < h.body_len ? size - off : h.body_len;
            continue;
        }
        CHECK(h.body_len <= 4096);
        if (h.body_len > size - off)
            break;
        /* Exact-size copy of the body so an overread of one byte is caught. */
        uint8_t *body = malloc(h.body_len ? h.body_len : 1);
        if (!body)
            break;
        memcpy(body, buf + off, h.body_len);
        all_decoders(body, h.body_len);
        free(body);
        off += h.body_len;
    }
    free(buf);
    return 0;
}
