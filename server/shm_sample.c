/* server/shm_sample.c - a SAMPLE / SAMPLE_DIR whose queries and reply are in the connection's
 * shared region (PROTOCOL.md 4.12; shm.h), sampled in place.
 *
 * Owns: sts_shm_sample: the range checks, the reply's size check, and the chunked loop that
 * copies SHM_CHUNK queries at a time out of the region into the sampling thread's stack (the
 * only read of those bytes), widens them there, samples them and writes their values,
 * coverage and statuses straight into the reply room (f32 values and coverage by the sampler
 * itself when the room is aligned; other formats through stp_enc_sample_values). A batch big
 * enough to split runs its parts on helper workers (sts_sample_parts), each part with its own
 * stack chunk, writing its own disjoint slice of the room. Does not own: the region and its
 * descriptors (shm.c), the checks and accounting every SAMPLE shares (h_basic.c:
 * sts_sample_prepare / sts_sample_finish), the encodings (protocol/).
 *
 * Why this is safe with a client that rewrites the region at any time: every query byte is
 * read from the region exactly once, into private memory, and only that copy is looked at;
 * nothing the server wrote into the region is read back; every address is inside
 * [query_off, +Q x count) or [reply_off, +reply length), both checked against the mapping
 * with stp_shm_range_ok (no addition that can wrap). When the two ranges overlap (allowed by
 * 4.12; earlier clients put the reply where the queries were) a write could land on queries
 * not yet read, so the queries are first copied whole into the thread's private buffer
 * (sts_shm_scratch) and sampled from there (shm_overlap_copies).
 */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "h_basic.h"
#include "io.h"
#include "server.h"
#include "shm.h"

/* Queries per chunk: 128 x 36 bytes of queries and ~5 KiB of widened queries plus 2.6 KiB of
 * results stay in L1/L2 between the copy, the sampler and the encode. */
#define SHM_CHUNK 128

typedef struct shm_job {
    const st_set         *s;
    const st_sample_opts *o;
    const stp_sample_req *rq;
    uint8_t               opcode;
    const uint8_t        *qsrc;    /* count x qsize bytes: in the region, or a private copy */
    size_t                qsize;
    unsigned              nchan;
    size_t                esz;     /* bytes per value in the reply's outfmt */
    uint8_t              *vals;    /* the reply's values, coverage, statuses in the region */
    uint8_t              *cov;     /* NULL: not asked for */
    uint8_t              *st;      /* NULL: not asked for */
    int                   direct;  /* f32 values and coverage written by the sampler in place */
} shm_job;

/* One chunk [at, at + k): copy, widen, sample, write. The bad queries or an ST_E* code. */
static int shm_chunk(const shm_job *j, size_t at, uint32_t k)
{
    union {
        st_query      q[SHM_CHUNK];
        st_cube_query cq[SHM_CHUNK];
    } w;
    uint8_t raw[SHM_CHUNK * STP_DIR_QUERY_SIZE];
    float vals[SHM_CHUNK * 4], cov[SHM_CHUNK];
    uint8_t st[SHM_CHUNK];
    const uint8_t *src = j->qsrc + at * j->qsize;
    size_t qbytes = (size_t)k * j->qsize;
    int dir = j->opcode == STP_OP_SAMPLE_DIR;
    /* the one read of these bytes; the f32 layout is st_query's on little-endian hosts, so
     * sts_sample_decode's copy is that read */
    if (!dir && !(j->rq->p.flags & STP_SF_COMPACT_MASK) && sizeof(st_query) == STP_QUERY_SIZE &&
        __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__) {
        sts_sample_decode(j->opcode, j->rq, src, k, w.q, NULL);
    } else {
        memcpy(raw, src, qbytes);
        sts_sample_decode(j->opcode, j->rq, raw, k, dir ? NULL : w.q, dir ? w.cq : NULL);
    }
    float *out = j->direct ? (float *)(void *)(j->vals + at * j->nchan * 4) : vals;
    float *cv = !j->cov ? NULL : j->direct ? (float *)(void *)(j->cov + at * 4) : cov;
    uint8_t *sp = j->st ? j->st + at : st;
    int rc = dir ? st_cube_sample_dir(j->s, j->o, ST_CUBE_LOOKUP_PLAIN, w.cq, k, out, cv, sp)
                 : st_sample_batch(j->s, j->o, w.q, k, out, cv, sp);
    if (rc < 0 || j->direct)
        return rc;
    stp_enc_sample_values(j->vals + at * j->nchan * j->esz, vals, (size_t)k * j->nchan,
                          j->rq->p.outfmt);
    if (j->cov)
        stp_enc_sample_values(j->cov + at * 4, cov, k, STP_OUT_F32);
    return rc;
}

/* sts_part_fn: a part of the batch, in chunks. */
static int shm_part(void *arg, size_t first, size_t count)
{
    const shm_job *j = arg;
    int bad = 0;
    for (size_t i = 0; i < count; i += SHM_CHUNK) {
        uint32_t k = count - i < SHM_CHUNK ? (uint32_t)(count - i) : SHM_CHUNK;
        int rc = shm_chunk(j, first + i, k);
        if (rc < 0)
            return rc;
        bad += rc;
    }
    return bad;
}

/* The thread's private buffer for the queries of an overlapping request; NULL: no memory. */
static uint8_t *private_queries(sts_ctx *c, uint64_t qbytes)
{
    sts_scratch *sc = c->scratch;
    if (!sc->shm)
        sc->shm = calloc(1, sizeof *sc->shm);
    sts_shm_scratch *ps = sc->shm;
    if (ps && qbytes > ps->qcap) {
        uint8_t *q = realloc(ps->q, (size_t)qbytes);
        if (!q)
            return NULL;
        ps->q = q;
        ps->qcap = (size_t)qbytes;
    }
    return ps ? ps->q : NULL;
}

int sts_shm_sample(sts_ctx *c, const stp_header *h, stp_sample_req *rq, stp_buf *out)
{
    const sts_shm_conn *s = c->conn->shm;
    char msg[256];
    if (!s || !s->map) {
        sts_reply_error(out, h, STP_S_INVALID, c->conn->unix_sock
                        ? "SAMPLE: flag SHM without a region: send SHM_ATTACH first"
                        : "SAMPLE: flag SHM needs a Unix-domain connection and SHM_ATTACH");
        return 0;
    }
    uint64_t qbytes = stp_sample_query_bytes(h->opcode, rq->p.flags, rq->count);
    const stp_shm_ref *r = &rq->shm;
    if (!stp_shm_range_ok(s->size, r->query_off, qbytes)) {
        snprintf(msg, sizeof msg, "SAMPLE: queries at [%" PRIu64 ", +%" PRIu64 ") are outside "
                 "the region of %" PRIu64 " bytes", r->query_off, qbytes, s->size);
        sts_reply_error(out, h, STP_S_INVALID, msg);
        return 0;
    }
    if (!stp_shm_range_ok(s->size, r->reply_off, r->reply_cap)) {
        snprintf(msg, sizeof msg, "SAMPLE: reply room at [%" PRIu64 ", +%" PRIu64 ") is outside "
                 "the region of %" PRIu64 " bytes", r->reply_off, r->reply_cap, s->size);
        sts_reply_error(out, h, STP_S_INVALID, msg);
        return 0;
    }
    sts_sample_prep pp;
    int prc = sts_sample_prepare(c, h, rq, out, &pp);
    if (prc)
        return prc == 2 ? STS_DEFER : 0;
    uint32_t n = rq->count;
    unsigned nchan = pp.s->info.nchan;
    /* the sampler's refusal of the options comes before the reply's size, as on the socket
     * path (which samples first); a call with no queries checks them and samples nothing */
    if (n) {
        float none[4];
        int rc = st_sample_batch(pp.s, &pp.o, NULL, 0, none, NULL, NULL);
        if (rc < 0) {
            sts_sample_finish(c, h, rq, &pp, rc, out);
            return 0;
        }
    }
    uint64_t len = stp_sample_reply_bytes(n, nchan, rq->p.outfmt, rq->p.flags);
    if (len > r->reply_cap) {
        st_setref_release(pp.ref);
        STS_STAT_ADD(c->srv, shm_too_small, 1);
        snprintf(msg, sizeof msg, "SAMPLE: the reply needs %" PRIu64 " bytes; reply_cap is %"
                 PRIu64, len, r->reply_cap);
        sts_reply_error(out, h, STP_S_TOO_LARGE, msg);
        return 0;
    }
    shm_job j = {pp.s, &pp.o, rq, h->opcode, s->map + r->query_off,
                 stp_query_size(rq->p.flags), nchan, stp_outfmt_size(rq->p.outfmt),
                 NULL, NULL, NULL, 0};
    if (h->opcode == STP_OP_SAMPLE_DIR)
        j.qsize = STP_DIR_QUERY_SIZE;
    /* both ranges lie inside the region (checked above): no sum below can wrap */
    if (n && r->query_off < r->reply_off + len && r->reply_off < r->query_off + qbytes) {
        uint8_t *q = private_queries(c, qbytes);
        if (!q) {
            st_setref_release(pp.ref);
            sts_reply_error(out, h, STP_S_NOMEM, "out of memory for the batch");
            return 0;
        }
        memcpy(q, s->map + r->query_off, (size_t)qbytes);
        j.qsrc = q;
        STS_STAT_ADD(c->srv, shm_overlap_copies, 1);
    }
    uint8_t *body = s->map + r->reply_off;
    size_t vbytes = (size_t)n * nchan * j.esz;
    int want_cov = (rq->p.flags & STP_SF_COVERAGE) != 0;
    j.vals = body + 12;
    j.cov = want_cov ? j.vals + vbytes : NULL;
    j.st = (rq->p.flags & STP_SF_STATUS) ? j.vals + vbytes + (want_cov ? (size_t)n * 4 : 0)
                                         : NULL;
    j.direct = rq->p.outfmt == STP_OUT_F32 && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ &&
               ((uintptr_t)j.vals % _Alignof(float)) == 0;
    int rc = sts_sample_parts(c, n, shm_part, &j);
    if (sts_sample_finish(c, h, rq, &pp, rc, out))
        return 0;   /* the room's contents are unspecified after an error reply (4.12) */
    stp_wr32(body, n);
    body[4] = (uint8_t)nchan;
    body[5] = rq->p.outfmt;
    body[6] = rq->p.flags & STP_SF_REPLY_MASK;
    body[7] = 0;
    stp_wr32(body + 8, (uint32_t)rc);
    STS_STAT_ADD(c->srv, shm_requests, 1);
    stp_shm_reply rp = { r->reply_off, len };
    stp_enc_shm_reply(out, h->opcode, h->reqid, &rp);
    return 0;
}
