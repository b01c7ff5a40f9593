/* client/libcalls.c - libseamtex's request calls: the blocking calls (ping, list, info, sample,
 * sample_dir, delete, stats, compress, jobs), the pipelined stc_append_* and the decoders of
 * pipelined replies.
 *
 * Owns: turning API arguments into protocol bodies and replies into stc_* results stored in
 * the connection. Does not own: the socket, waiting, pending-request bookkeeping (libconn.c),
 * uploads and downloads (libxfer.c).
 */
#include "libseamtex_int.h"

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* stc_query and stp_query (and the direction queries) are the same fields in the same order:
 * the encoder reads the caller's arrays as they are, nothing is copied first. */
#define SAME_FIELD(a, b, f) (offsetof(a, f) == offsetof(b, f))
_Static_assert(sizeof(stc_query) == sizeof(stp_query) && SAME_FIELD(stc_query, stp_query, face) &&
               SAME_FIELD(stc_query, stp_query, u) && SAME_FIELD(stc_query, stp_query, v) &&
               SAME_FIELD(stc_query, stp_query, dudx) && SAME_FIELD(stc_query, stp_query, dvdx) &&
               SAME_FIELD(stc_query, stp_query, dudy) && SAME_FIELD(stc_query, stp_query, dvdy),
               "query layout");
_Static_assert(sizeof(stc_dir_query) == sizeof(stp_dir_query) &&
               SAME_FIELD(stc_dir_query, stp_dir_query, dir) &&
               SAME_FIELD(stc_dir_query, stp_dir_query, ddx) &&
               SAME_FIELD(stc_dir_query, stp_dir_query, ddy), "dir query layout");
#undef SAME_FIELD
_Static_assert((int)STC_OUT_UNORM16 == (int)STP_OUT_UNORM16 && (int)STC_WANT_STATUS == (int)STP_SF_STATUS, "enums");
_Static_assert(STC_ESHUTDOWN == -(STC_SERVER_BASE + STP_S_SHUTDOWN), "status numbering");
_Static_assert((int)STC_CAP_AUTH == (int)STP_CAP_AUTH && (int)STC_CAP_FETCH == (int)STP_CAP_FETCH &&
               (int)STC_CAP_OUT_OF_ORDER == (int)STP_CAP_OUT_OF_ORDER &&
               (int)STC_CAP_SAMPLE_DIR == (int)STP_CAP_SAMPLE_DIR, "capability bits");

#define APPEND_FLUSH_AT (1u << 20)   /* an append sends (without waiting) past this much queued */
#define APPEND_HARD_CAP (64u << 20)  /* an append waits for room past this much queued */

/* ---- request plumbing ---------------------------------------------------------------------- */

/* Reserves a request id and its pending slot (before encoding, so a failure to track it never
 * leaves an untracked frame in the output). */
static int start(stc_conn *c, uint8_t op, int pipelined, uint32_t *id)
{
    *id = stc__next_reqid(c);
    return stc__pend_add(c, *id, op, pipelined);
}

static int encoded(stc_conn *c, int st)
{
    if (st == 0)
        return 0;
    stc__pend_drop_last(c);
    return stc__enc_error(c, st);
}

/* Sends the encoded request and waits for its reply; 0 with an OK reply in *f. */
static int finish(stc_conn *c, uint32_t id, stc_frame *f)
{
    int64_t dl = stc__deadline(c->timeout_ms);
    int rc = stc__flush(c, dl);
    if (stc__gave_up(rc)) {
        stc__pend_abandon(c, id);
        return rc;
    }
    if (rc)
        return rc;
    rc = stc__wait(c, id, 0, dl, f);
    if (rc)
        return rc;
    if (f->h.status)
        return stc__status_error(c, f);
    return 0;
}

static int bad_reply(stc_conn *c, const char *why)
{
    return stc__break(c, STC_EPROTO, "malformed reply: %s", why ? why : "?");
}

int stc__check_name(stc_conn *c, const char *name)
{
    if (!stp_name_valid_cstr(name))
        return stc__fail(c, STC_EINVAL, "'%s' is not a valid set name (1..255 of A-Z a-z 0-9 . _ -, "
                         "not starting with '.')", name ? name : "(null)");
    return 0;
}

static uint32_t tmo(const stc_conn *c)
{
    return (uint32_t)c->timeout_ms;
}

/* ---- ping, delete, list, stats ------------------------------------------------------------- */

int stc_ping(stc_conn *c)
{
    stc_frame f;
    uint32_t id;
    int rc = stc__begin_blocking(c);
    if (rc || (rc = start(c, STP_OP_PING, 0, &id)) != 0)
        return rc;
    if ((rc = encoded(c, stp_enc_empty(&c->out, STP_OP_PING, 0, id, tmo(c)))) != 0)
        return rc;
    if ((rc = finish(c, id, &f)) != 0)
        return rc;
    if (f.h.body_len != 0)
        return bad_reply(c, "PING echo of an empty payload is not empty");
    return 0;
}

int stc_delete(stc_conn *c, const char *set)
{
    stc_frame f;
    uint32_t id;
    int rc = stc__begin_blocking(c);
    if (rc || (rc = stc__check_name(c, set)) != 0 || (rc = start(c, STP_OP_DELETE, 0, &id)) != 0)
        return rc;
    if ((rc = encoded(c, stp_enc_name_req(&c->out, STP_OP_DELETE, id, tmo(c), set))) != 0)
        return rc;
    if ((rc = finish(c, id, &f)) != 0)
        return rc;
    if (f.h.body_len != 0)
        return bad_reply(c, "DELETE reply is not empty");
    return 0;
}

/* Appends a NUL-terminated string to c->names. */
static int names_add(stc_conn *c, const char *s)
{
    size_t n = strlen(s) + 1;
    if (stc__grow((void **)&c->names, &c->names_cap, c->names_len + n) != 0)
        return stc__fail(c, STC_ENOMEM, "out of memory");
    memcpy(c->names + c->names_len, s, n);
    c->names_len += n;
    return 0;
}

int stc_list(stc_conn *c, const stc_set_entry **sets, size_t *n)
{
    size_t count = 0;
    uint32_t first = 0;
    int rc = stc__begin_blocking(c);
    if (rc)
        return rc;
    if (!sets || !n)
        return stc__fail(c, STC_EINVAL, "sets or n is NULL");
    c->names_len = 0;
    for (;;) {
        stc_frame f;
        stp_list_req rq = { first, 0 };
        stp_list_reply rp;
        stp_list_entry e;
        const char *why = NULL;
        size_t pos = 0;
        uint32_t id;

        if ((rc = start(c, STP_OP_LIST, 0, &id)) != 0)
            return rc;
        if ((rc = encoded(c, stp_enc_list_req(&c->out, id, tmo(c), &rq))) != 0)
            return rc;
        if ((rc = finish(c, id, &f)) != 0)
            return rc;
        if (stp_dec_list_reply(f.body, f.h.body_len, &rp, &why) != 0)
            return bad_reply(c, why);
        if (stc__grow((void **)&c->sets, &c->sets_cap,
                      (count + rp.count) * sizeof *c->sets) != 0)
            return stc__fail(c, STC_ENOMEM, "out of memory");
        while (stp_list_next(&rp, &pos, &e)) {
            stc_set_entry *s = &c->sets[count++];
            if ((rc = names_add(c, e.name)) != 0)
                return rc;
            s->name = NULL;
            s->kind = e.kind;
            s->nchan = e.nchan;
            s->dtype = e.dtype;
            s->nfaces = e.nfaces;
            s->memory = e.memory;
        }
        /* The reply is consumed before the next page is asked for. */
        stc__begin(c);
        first += rp.count;
        if (rp.count == 0 || first >= rp.total)
            break;
    }
    /* Names were appended in entry order; point at them now that the block stopped moving. */
    for (size_t i = 0, off = 0; i < count; i++) {
        c->sets[i].name = c->names + off;
        off += strlen(c->names + off) + 1;
    }
    *sets = c->sets;
    *n = count;
    return 0;
}

int stc_stats(stc_conn *c, const stc_stat **stats, size_t *n)
{
    stc_frame f;
    stp_stats_reply rp;
    stp_stat s;
    const char *why = NULL;
    size_t pos = 0, count = 0;
    uint32_t id;
    int rc = stc__begin_blocking(c);
    if (rc)
        return rc;
    if (!stats || !n)
        return stc__fail(c, STC_EINVAL, "stats or n is NULL");
    if ((rc = start(c, STP_OP_STATS, 0, &id)) != 0)
        return rc;
    if ((rc = encoded(c, stp_enc_empty(&c->out, STP_OP_STATS, 0, id, tmo(c)))) != 0)
        return rc;
    if ((rc = finish(c, id, &f)) != 0)
        return rc;
    if (stp_dec_stats_reply(f.body, f.h.body_len, &rp, &why) != 0)
        return bad_reply(c, why);
    if (stc__grow((void **)&c->stats, &c->stats_cap, (size_t)rp.count * sizeof *c->stats) != 0)
        return stc__fail(c, STC_ENOMEM, "out of memory");
    c->names_len = 0;
    while (stp_stats_next(&rp, &pos, &s)) {
        stc_stat *o = &c->stats[count++];
        if ((rc = names_add(c, s.key)) != 0)
            return rc;
        o->is_float = s.type == STP_STAT_F64;
        o->u = o->is_float ? 0 : s.v.u;
        o->f = o->is_float ? s.v.f : (double)s.v.u;
    }
    for (size_t i = 0, off = 0; i < count; i++) {
        c->stats[i].key = c->names + off;
        off += strlen(c->names + off) + 1;
    }
    *stats = c->stats;
    *n = count;
    return 0;
}

const stc_stat *stc_stat_find(const stc_stat *stats, size_t n, const char *key)
{
    for (size_t i = 0; stats && key && i < n; i++)
        if (strcmp(stats[i].key, key) == 0)
            return &stats[i];
    return NULL;
}

/* ---- info ------------------------------------------------------------------------------------- */

static int info_from_body(stc_conn *c, const uint8_t *body, size_t len, stc_info *o)
{
    stp_info_reply rp;
    const char *why = NULL;
    if (stp_dec_info_reply(body, len, &rp, &why) != 0)
        return bad_reply(c, why);
    memset(o, 0, sizeof *o);
    o->nfaces = rp.nfaces;
    o->nchan = rp.nchan;
    o->dtype = rp.dtype;
    o->kind = rp.kind;
    o->colorspace = rp.colorspace;
    o->premultiplied = rp.premultiplied;
    o->border_u = rp.border_u;
    o->border_v = rp.border_v;
    o->meshtype = rp.meshtype;
    o->edgefilter = rp.edgefilter;
    o->alpha_chan = rp.alpha_chan;
    o->memory = rp.memory;
    o->texel_bytes = rp.texel_bytes;
    o->min_w = rp.min_w;
    o->max_w = rp.max_w;
    o->min_h = rp.min_h;
    o->max_h = rp.max_h;
    o->nconstant = rp.nconstant;
    o->nsubfaces = rp.nsubfaces;
    o->boundary_edges = rp.boundary_edges;
    o->irregular_corners = rp.irregular_corners;
    o->max_valence = rp.max_valence;
    o->nmeta = rp.nmeta;
    o->face_first = rp.face_first;
    o->nrec = rp.nrec;
    if (rp.nrec) {
        if (stc__grow((void **)&c->faces, &c->faces_cap, (size_t)rp.nrec * sizeof *c->faces))
            return stc__fail(c, STC_ENOMEM, "out of memory");
        for (uint32_t i = 0; i < rp.nrec; i++) {
            stp_face_rec fr;
            stp_info_face(&rp, i, &fr);
            c->faces[i].w = fr.w;
            c->faces[i].h = fr.h;
            memcpy(c->faces[i].adjface, fr.adjface, sizeof fr.adjface);
            memcpy(c->faces[i].adjedge, fr.adjedge, sizeof fr.adjedge);
            c->faces[i].flags = fr.flags;
            c->faces[i].nlevels = fr.nlevels;
        }
        o->faces = c->faces;
    }
    return 0;
}

static int enc_info(stc_conn *c, uint32_t id, const char *set, uint32_t first, uint32_t count)
{
    stp_info_req rq;
    memset(&rq, 0, sizeof rq);
    snprintf(rq.name, sizeof rq.name, "%s", set);
    rq.face_first = first;
    rq.face_count = count;
    return encoded(c, stp_enc_info_req(&c->out, id, tmo(c), &rq));
}

int stc_info_get(stc_conn *c, const char *set, uint32_t face_first, uint32_t face_count,
                 stc_info *out)
{
    stc_frame f;
    uint32_t id;
    int rc = stc__begin_blocking(c);
    if (rc || (rc = stc__check_name(c, set)) != 0)
        return rc;
    if (!out)
        return stc__fail(c, STC_EINVAL, "out is NULL");
    if ((rc = start(c, STP_OP_INFO, 0, &id)) != 0 ||
        (rc = enc_info(c, id, set, face_first, face_count)) != 0 ||
        (rc = finish(c, id, &f)) != 0)
        return rc;
    return info_from_body(c, f.body, f.h.body_len, out);
}

int stc_reply_info(stc_conn *c, const stc_reply *r, stc_info *out)
{
    if (!c || !r || !out)
        return STC_EINVAL;
    if (r->status)
        return r->status;
    if (r->opcode != STP_OP_INFO)
        return stc__fail(c, STC_EINVAL, "not an INFO reply");
    return info_from_body(c, r->body, r->body_len, out);
}

/* ---- sampling ----------------------------------------------------------------------------- */

int stc__fill_params(stc_conn *c, const char *set, const stc_sample_opts *o, size_t n,
                     stp_sample_params *p)
{
    int rc = stc__check_name(c, set);
    if (rc)
        return rc;
    if (!o)
        return stc__fail(c, STC_EINVAL, "sample options are NULL");
    if (n > UINT32_MAX)
        return stc__fail(c, STC_EINVAL, "batch of %zu queries is too large", n);
    if (o->mode > 255 || o->filter > 255 || o->zero_rule > 255 || o->max_aniso > 255 ||
        o->outfmt > 255 || o->want > 255 || o->footprint > 255)
        return stc__fail(c, STC_EINVAL, "a sample option is out of range");
    memset(p, 0, sizeof *p);
    snprintf(p->name, sizeof p->name, "%s", set);
    p->mode = (uint8_t)o->mode;
    p->filter = (uint8_t)o->filter;
    p->zero_rule = (uint8_t)o->zero_rule;
    p->max_aniso = (uint8_t)o->max_aniso;
    p->outfmt = (uint8_t)o->outfmt;
    p->flags = (uint8_t)o->want;
    p->footprint = (uint8_t)o->footprint;
    p->sharpness = o->sharpness;
    p->width = o->width;
    p->blur = o->blur;
    return 0;
}

static int enc_sample(stc_conn *c, uint32_t id, int dir, const char *set,
                      const stc_sample_opts *o, const void *q, size_t n)
{
    stp_sample_req rq;
    int rc;
    memset(&rq, 0, sizeof rq);
    if ((rc = stc__fill_params(c, set, o, n, &rq.p)) != 0) {
        stc__pend_drop_last(c);
        return rc;
    }
    if (n && !q) {
        stc__pend_drop_last(c);
        return stc__fail(c, STC_EINVAL, "queries are NULL");
    }
    rq.count = (uint32_t)n;
    /* the caller's array is encoded as it is (the same layout: checked at the top) */
    if (!dir)
        rq.queries = (const stp_query *)q;
    else
        rq.dqueries = (const stp_dir_query *)q;
    /* with a region attached (libshm.c) the queries go there and the frame stays small */
    if ((rc = stc__shm_place(c, dir ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE, &rq)) < 0) {
        stc__pend_drop_last(c);
        return rc;
    }
    if (!dir)
        return encoded(c, stp_enc_sample_req(&c->out, id, tmo(c), &rq));
    return encoded(c, stp_enc_sample_dir_req(&c->out, id, tmo(c), &rq));
}

/* Decodes a SAMPLE reply into the connection's result arrays at query offset `at` of a result
 * of `total` queries (at = 0, total = count for a single reply). The arrays are sized for
 * `total` when at == 0; later parts must agree on nchan and outfmt. */
static int sample_decode_at(stc_conn *c, const uint8_t *body, size_t len, size_t at,
                            size_t total, stc_sample_result *res)
{
    stp_sample_reply rp;
    const char *why = NULL;
    size_t esz, nval;
    if (stp_dec_sample_reply(body, len, &rp, &why) != 0)
        return bad_reply(c, why);
    if (at == 0) {
        memset(res, 0, sizeof *res);
        res->nchan = rp.nchan;
        res->outfmt = rp.outfmt;
        esz = rp.outfmt == STP_OUT_F16 ? sizeof(float) : stp_outfmt_size(rp.outfmt);
        if (stc__grow(&c->vals, &c->vals_cap, total * rp.nchan * esz) != 0 ||
            stc__grow((void **)&c->cov, &c->cov_cap, total * sizeof(float)) != 0 ||
            stc__grow((void **)&c->qst, &c->qst_cap, total) != 0)
            return stc__fail(c, STC_ENOMEM, "out of memory for %zu results", total);
        res->values = c->vals;
        res->coverage = rp.raw_coverage ? c->cov : NULL;
        res->status = rp.raw_status ? c->qst : NULL;
    } else if (rp.nchan != res->nchan || rp.outfmt != res->outfmt ||
               !rp.raw_coverage != !res->coverage || !rp.raw_status != !res->status) {
        return bad_reply(c, "parts of one batch disagree on channels or format");
    }
    if (at + rp.count > total)
        return bad_reply(c, "SAMPLE reply carries more queries than were asked");
    esz = rp.outfmt == STP_OUT_F16 ? sizeof(float) : stp_outfmt_size(rp.outfmt);
    nval = (size_t)rp.count * rp.nchan;
    uint8_t *dst = (uint8_t *)c->vals + at * rp.nchan * esz;
    if (rp.outfmt == STP_OUT_F32 || rp.outfmt == STP_OUT_F16)
        stp_sample_values_f32(&rp, (float *)(void *)dst);
    else if (rp.outfmt == STP_OUT_UNORM8)
        memcpy(dst, rp.raw_values, nval);
    else
        stp_sample_values_u16(&rp, (uint16_t *)(void *)dst);
    if (rp.raw_coverage)
        stp_sample_coverage(&rp, c->cov + at);
    if (rp.raw_status && rp.count)
        memcpy(c->qst + at, rp.raw_status, rp.count);
    res->count = (uint32_t)(at + rp.count);
    res->nbad += rp.nbad;
    return 0;
}

/* A reply (in the shared region, or the socket's reply held in the receive buffer until the
 * next call) whose arrays are already what the caller gets (little-endian host, not f16,
 * aligned): the result points at them where they lie, valid until the next call as every
 * result. 1 when done. */
static int sample_in_place(const stp_sample_reply *rp, stc_sample_result *res)
{
    size_t esz = stp_outfmt_size(rp->outfmt);
    if (__BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__ || rp->outfmt == STP_OUT_F16 ||
        ((uintptr_t)rp->raw_values % esz) != 0 ||
        (rp->raw_coverage && ((uintptr_t)rp->raw_coverage % _Alignof(float)) != 0))
        return 0;
    memset(res, 0, sizeof *res);
    res->count = rp->count;
    res->nchan = rp->nchan;
    res->outfmt = rp->outfmt;
    res->nbad = rp->nbad;
    res->values = rp->raw_values;
    res->coverage = (const float *)(const void *)rp->raw_coverage;
    res->status = rp->raw_status;
    return 1;
}

static int sample_from_body(stc_conn *c, const uint8_t *body, size_t len, stc_sample_result *res)
{
    stp_sample_reply rp;
    const char *why = NULL;
    /* peek at the count to size the arrays */
    if (stp_dec_sample_reply(body, len, &rp, &why) != 0)
        return bad_reply(c, why);
    /* a reply in the region (held until the next call, libshm.c) or in the receive buffer
     * (held until the next call, libconn.c) is read where it lies */
    if ((stc__shm_holds(c, body, len) || stc__in_holds(c, body, len)) &&
        sample_in_place(&rp, res))
        return 0;
    return sample_decode_at(c, body, len, 0, rp.count, res);
}

/* A batch larger than the server's max_batch is split into parts of max_batch queries, sent
 * pipelined (a window bounded by max_inflight; one at a time when the server may reorder
 * replies) and reassembled in order, so callers need not know the server's limit. */
static int sample_blocking(stc_conn *c, int dir, const char *set, const stc_sample_opts *o,
                           const void *q, size_t n, stc_sample_result *res)
{
    size_t per, nparts, sent = 0, got = 0, qsize = dir ? sizeof(stc_dir_query)
                                                          : sizeof(stc_query);
    uint32_t *ids;
    int rc = stc__begin_blocking(c), window;
    if (rc)
        return rc;
    if (!res)
        return stc__fail(c, STC_EINVAL, "result is NULL");
    /* the result's count is 32 bits; a bigger n also made (n + per - 1) wrap, so that n near
     * SIZE_MAX came out as 0 parts: 0 returned with nothing sampled and res left unset */
    if (n > UINT32_MAX)
        return stc__fail(c, STC_EINVAL, "batch of %zu queries: at most 2^32-1 in one call", n);
    per = c->server.max_batch ? c->server.max_batch : n;
    if (per == 0)
        per = 1;
    nparts = n <= per ? 1 : (n + per - 1) / per;
    window = (c->server.caps & STP_CAP_OUT_OF_ORDER) ? 1
             : c->server.max_inflight > 16 ? 16 : (int)c->server.max_inflight;
    if (window < 1)
        window = 1;
    ids = malloc(nparts * sizeof *ids);
    if (!ids)
        return stc__fail(c, STC_ENOMEM, "out of memory");
    while (got < nparts) {
        stc_frame f;
        int64_t dl;
        while (sent < nparts && sent - got < (size_t)window) {
            size_t first = sent * per, cnt = n - first < per ? n - first : per;
            if ((rc = start(c, dir ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE, 0, &ids[sent])) != 0 ||
                (rc = enc_sample(c, ids[sent], dir, set, o,
                                 q ? (const uint8_t *)q + first * qsize : NULL, cnt)) != 0)
                goto fail;
            sent++;
        }
        dl = stc__deadline(c->timeout_ms);
        if ((rc = stc__flush(c, dl)) != 0 || (rc = stc__wait(c, ids[got], 0, dl, &f)) != 0) {
            if (stc__gave_up(rc))
                stc__pend_abandon(c, ids[got]);
            goto fail;
        }
        got++;
        if (f.h.status) {
            rc = stc__status_error(c, &f);
            goto fail;
        }
        size_t first = (got - 1) * per, cnt = n - first < per ? n - first : per;
        if (nparts == 1)                  /* one reply: where it lies when it can be */
            rc = sample_from_body(c, f.body, f.h.body_len, res);
        else
            rc = sample_decode_at(c, f.body, f.h.body_len, first, n, res);
        if (rc != 0)
            goto fail;
        if (res->count != first + cnt) {
            rc = bad_reply(c, "SAMPLE reply count differs from the request's");
            goto fail;
        }
    }
    free(ids);
    return 0;
fail:
    for (size_t i = got; i < sent; i++)
        stc__pend_abandon(c, ids[i]);
    free(ids);
    return rc;
}

int stc_sample(stc_conn *c, const char *set, const stc_sample_opts *o, const stc_query *q,
               size_t n, stc_sample_result *res)
{
    return sample_blocking(c, 0, set, o, q, n, res);
}

int stc_sample_dir(stc_conn *c, const char *set, const stc_sample_opts *o,
                   const stc_dir_query *q, size_t n, stc_sample_result *res)
{
    return sample_blocking(c, 1, set, o, q, n, res);
}

int stc_reply_sample(stc_conn *c, const stc_reply *r, stc_sample_result *res)
{
    if (!c || !r || !res)
        return STC_EINVAL;
    if (r->status)
        return r->status;
    if (r->opcode != STP_OP_SAMPLE && r->opcode != STP_OP_SAMPLE_DIR)
        return stc__fail(c, STC_EINVAL, "not a SAMPLE reply");
    return sample_from_body(c, r->body, r->body_len, res);
}

/* ---- jobs ------------------------------------------------------------------------------------- */

int stc_compress(stc_conn *c, const char *set, const char *target, unsigned level,
                 unsigned flags, uint64_t *job_id)
{
    stp_compress_req rq;
    stc_frame f;
    const char *why = NULL;
    uint32_t id;
    int rc = stc__begin_blocking(c);
    if (rc || (rc = stc__check_name(c, set)) != 0 || (rc = stc__check_name(c, target)) != 0)
        return rc;
    if (level > 9 || flags > 3 || !job_id)
        return stc__fail(c, STC_EINVAL, "level over 9, unknown flags or job_id NULL");
    memset(&rq, 0, sizeof rq);
    snprintf(rq.name, sizeof rq.name, "%s", set);
    snprintf(rq.target, sizeof rq.target, "%s", target);
    rq.level = (uint8_t)level;
    rq.flags = (uint8_t)flags;
    if ((rc = start(c, STP_OP_COMPRESS, 0, &id)) != 0 ||
        (rc = encoded(c, stp_enc_compress_req(&c->out, id, tmo(c), &rq))) != 0 ||
        (rc = finish(c, id, &f)) != 0)
        return rc;
    if (stp_dec_id_reply(f.body, f.h.body_len, job_id, &why) != 0)
        return bad_reply(c, why);
    return 0;
}

static int job_call(stc_conn *c, uint8_t op, uint64_t job_id, stc_job *out)
{
    stp_job_status js;
    stc_frame f;
    const char *why = NULL;
    uint32_t id;
    int rc = stc__begin_blocking(c);
    if (rc)
        return rc;
    if ((rc = start(c, op, 0, &id)) != 0 ||
        (rc = encoded(c, stp_enc_id_req(&c->out, op, id, tmo(c), job_id))) != 0 ||
        (rc = finish(c, id, &f)) != 0)
        return rc;
    if (stp_dec_job_status(f.body, f.h.body_len, &js, &why) != 0)
        return bad_reply(c, why);
    if (out) {
        out->id = js.job_id;
        out->state = js.state;
        out->progress = js.progress;
        out->result = js.result ? -(STC_SERVER_BASE + (int)js.result) : 0;
        snprintf(out->message, sizeof out->message, "%s", js.message);
    }
    return 0;
}

int stc_job_status(stc_conn *c, uint64_t job_id, stc_job *out)
{
    if (!out)
        return c ? stc__fail(c, STC_EINVAL, "out is NULL") : STC_EINVAL;
    return job_call(c, STP_OP_JOB_STATUS, job_id, out);
}

int stc_job_cancel(stc_conn *c, uint64_t job_id, stc_job *out)
{
    return job_call(c, STP_OP_JOB_CANCEL, job_id, out);
}

int stc_job_wait(stc_conn *c, uint64_t job_id, int wait_ms, stc_job *out)
{
    stc_job tmp, *j = out ? out : &tmp;
    /* wait_ms 0: one poll (stc__deadline takes 0 as "none", which made it wait for ever) */
    int64_t dl = wait_ms < 0 ? -1 : stc__now_ms() + wait_ms;
    long sleep_ms = 5;
    for (;;) {
        int rc = stc_job_status(c, job_id, j);
        if (rc)
            return rc;
        if (j->state == STC_JOB_DONE)
            return 0;
        if (j->state == STC_JOB_FAILED)
            return stc__fail(c, j->result ? j->result : STC_EINTERNAL, "job %llu failed: %s",
                             (unsigned long long)job_id, j->message);
        if (j->state == STC_JOB_CANCELED)
            return stc__fail(c, STC_ESERVERCANCELED, "job %llu was cancelled",
                             (unsigned long long)job_id);
        if (dl >= 0 && stc__now_ms() >= dl)
            return stc__fail(c, STC_ETIMEDOUT, "job %llu still running after %d ms",
                             (unsigned long long)job_id, wait_ms);
        struct timespec ts = { 0, sleep_ms * 1000000L };
        /* the pause between polls is a wait too: the hook after a signal (EINTR) or, with
         * an interval, after each pause (at most 100 ms) */
        int eintr = nanosleep(&ts, NULL) != 0;
        if ((eintr || c->intr.every_ms > 0) && stc__interrupted(&c->intr))
            return stc__fail(c, STC_EINTERRUPTED, "interrupted waiting for job %llu",
                             (unsigned long long)job_id);
        if (sleep_ms < 100)
            sleep_ms *= 2;
    }
}

/* ---- pipelined appends -------------------------------------------------------------------- */

/* Before queuing: past APPEND_HARD_CAP of unsent bytes (a peer that does not read) wait up to
 * the request timeout for room, and refuse (nothing queued) if there is none. */
static int make_room(stc_conn *c)
{
    if (stp_buf_avail(&c->out) < APPEND_HARD_CAP)
        return 0;
    int rc = stc__flush(c, stc__deadline(c->timeout_ms));
    if (rc == STC_ETIMEDOUT && stp_buf_avail(&c->out) >= APPEND_HARD_CAP)
        return stc__fail(c, STC_ETIMEDOUT, "%zu bytes of requests are queued and the server "
                         "is not reading them; nothing was appended", stp_buf_avail(&c->out));
    return rc == STC_ETIMEDOUT ? 0 : rc;
}

/* After queuing: past APPEND_FLUSH_AT send what the socket takes now, without waiting. */
static int appended(stc_conn *c)
{
    if (stp_buf_avail(&c->out) >= APPEND_FLUSH_AT) {
        int rc = stc__flush(c, stc__now_ms());
        if (rc && rc != STC_ETIMEDOUT)
            return rc;
        c->msg[0] = 0;              /* a slow peer is not an error for an append */
    }
    return 0;
}

int stc_append_ping(stc_conn *c, const void *payload, size_t len, uint32_t *reqid)
{
    uint32_t id;
    int rc = stc__begin(c);
    if (rc)
        return rc;
    if (!reqid || (len && !payload))
        return stc__fail(c, STC_EINVAL, "reqid or payload is NULL");
    if ((rc = make_room(c)) != 0 || (rc = start(c, STP_OP_PING, 1, &id)) != 0 ||
        (rc = encoded(c, stp_enc_raw(&c->out, STP_OP_PING, 0, id, 0, tmo(c), payload, len))) != 0)
        return rc;
    *reqid = id;
    return appended(c);
}

static int append_sample(stc_conn *c, int dir, const char *set, const stc_sample_opts *o,
                         const void *q, size_t n, uint32_t *reqid)
{
    uint32_t id;
    int rc = stc__begin(c);
    if (rc)
        return rc;
    if (!reqid)
        return stc__fail(c, STC_EINVAL, "reqid is NULL");
    if ((rc = make_room(c)) != 0 ||
        (rc = start(c, dir ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE, 1, &id)) != 0 ||
        (rc = enc_sample(c, id, dir, set, o, q, n)) != 0)
        return rc;
    *reqid = id;
    return appended(c);
}

int stc_append_sample(stc_conn *c, const char *set, const stc_sample_opts *o,
                      const stc_query *q, size_t n, uint32_t *reqid)
{
    return append_sample(c, 0, set, o, q, n, reqid);
}

int stc_append_sample_dir(stc_conn *c, const char *set, const stc_sample_opts *o,
                          const stc_dir_query *q, size_t n, uint32_t *reqid)
{
    return append_sample(c, 1, set, o, q, n, reqid);
}

/* Encodes the open reservation (stc_shm_reserve) as the request `id`. */
static int enc_reserved(stc_conn *c, uint32_t id)
{
    stp_sample_req rq;
    int dir = c->shm_resv.dir;
    stc__shm_take_reserved(c, &rq);
    if (!dir)
        return encoded(c, stp_enc_sample_req(&c->out, id, tmo(c), &rq));
    return encoded(c, stp_enc_sample_dir_req(&c->out, id, tmo(c), &rq));
}

int stc_shm_append(stc_conn *c, uint32_t *reqid)
{
    uint32_t id;
    if (!c)
        return STC_EINVAL;
    if (!c->shm_resv.open)
        return stc__fail(c, STC_ESTATE, "no open reservation (stc_shm_reserve)");
    int rc = stc__begin(c);
    if (!rc && !reqid)
        rc = stc__fail(c, STC_EINVAL, "reqid is NULL");
    if (rc || (rc = make_room(c)) != 0 ||
        (rc = start(c, c->shm_resv.dir ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE, 1, &id)) != 0) {
        stc_shm_cancel(c);           /* used up, as the header promises */
        return rc;
    }
    if ((rc = enc_reserved(c, id)) != 0)
        return rc;
    *reqid = id;
    return appended(c);
}

int stc_shm_sample(stc_conn *c, stc_sample_result *res)
{
    stc_frame f;
    uint32_t id;
    if (!c)
        return STC_EINVAL;
    if (!c->shm_resv.open)
        return stc__fail(c, STC_ESTATE, "no open reservation (stc_shm_reserve)");
    int rc = stc__begin_blocking(c);
    if (!rc && !res)
        rc = stc__fail(c, STC_EINVAL, "result is NULL");
    if (rc || (rc = start(c, c->shm_resv.dir ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE, 0, &id)) != 0) {
        stc_shm_cancel(c);
        return rc;
    }
    if ((rc = enc_reserved(c, id)) != 0 || (rc = finish(c, id, &f)) != 0)
        return rc;
    return sample_from_body(c, f.body, f.h.body_len, res);
}

int stc_append_info(stc_conn *c, const char *set, uint32_t *reqid)
{
    uint32_t id;
    int rc = stc__begin(c);
    if (rc || (rc = stc__check_name(c, set)) != 0)
        return rc;
    if (!reqid)
        return stc__fail(c, STC_EINVAL, "reqid is NULL");
    if ((rc = make_room(c)) != 0 || (rc = start(c, STP_OP_INFO, 1, &id)) != 0 ||
        (rc = enc_info(c, id, set, 0, 0)) != 0)
        return rc;
    *reqid = id;
    return appended(c);
}

int stc_append_stats(stc_conn *c, uint32_t *reqid)
{
    return stc_append_raw(c, STP_OP_STATS, NULL, 0, reqid);
}

int stc_append_raw(stc_conn *c, unsigned opcode, const void *body, size_t len, uint32_t *reqid)
{
    uint32_t id;
    int rc = stc__begin(c);
    if (rc)
        return rc;
    if (!reqid || opcode > 255 || (len && !body))
        return stc__fail(c, STC_EINVAL, "reqid NULL, opcode over 255 or body NULL");
    if ((rc = make_room(c)) != 0 || (rc = start(c, (uint8_t)opcode, 1, &id)) != 0 ||
        (rc = encoded(c, stp_enc_raw(&c->out, (uint8_t)opcode, 0, id, 0, tmo(c), body, len))) != 0)
        return rc;
    *reqid = id;
    return appended(c);
}
