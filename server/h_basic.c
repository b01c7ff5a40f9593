/* server/h_basic.c - handlers for the read-only requests: HELLO, PING, LIST, INFO, STATS,
 * SAMPLE, SAMPLE_DIR.
 *
 * Owns: decoding their bodies (through protocol/), reading the registry, sampling into the
 * thread's scratch, encoding replies. Does not own: uploads, jobs (h_upload.c, h_jobs.c),
 * the per-opcode counters STATS reports (opstats.c).
 * Every handler appends exactly one frame to `out`.
 */
#include <stdio.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "atlas.h"
#include "cube.h"
#include "cluster_node.h"
#include "dispatch.h"
#include "h_basic.h"
#include "io.h"
#include "opstats.h"
#include "ptexres.h"
#include "server.h"
#include "shm.h"
#include "workers.h"

/* Looks a set up by a name the decoder has already held to the name rule (protocol/stp_name.h:
 * a bad name was answered INVALID before the handler ran), as a read may use it (in a cluster
 * only a copy the catalogue confirmed: sts_get_served); replies NOT_FOUND or MOVED itself and
 * returns NULL. */
static st_setref *get_set(sts_ctx *c, const stp_header *h, const char *name, stp_buf *out)
{
    st_error e;
    st_error_clear(&e);
    st_setref *ref = NULL;
    if (sts_get_served(c->srv, name, &ref, &e) != 0) {
        sts_reply_not_here(c->srv, out, h, name, e.msg);
        return NULL;
    }
    return ref;
}

int sts_h_hello(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_hello_req rq;
    const char *why = NULL;
    int st = stp_dec_hello_req(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    if (rq.min_version > STP_VERSION || rq.max_version < STP_VERSION) {
        char msg[96];
        snprintf(msg, sizeof msg, "server speaks version %d; client speaks %u..%u", STP_VERSION,
                 rq.min_version, rq.max_version);
        sts_reply_error(out, h, STP_S_BAD_VERSION, msg);
        return 0;
    }
    c->conn->authed = sts_token_check(c->srv, rq.token);
    stp_hello_reply r;
    memset(&r, 0, sizeof r);
    r.version = STP_VERSION;
    r.caps = STP_CAP_PIPELINE | STP_CAP_SAMPLE_DIR | STP_CAP_COMPRESS | STP_CAP_FETCH |
             STP_CAP_PTEX_FILTERS | STP_CAP_COMPACT | STP_CAP_LERP;
    if (STS_LIVE(c->srv, upload_keep))
        r.caps |= STP_CAP_UPLOAD_RESUME;
    if (!sts_token_allows(c->srv, 0))
        r.caps |= STP_CAP_AUTH;
    if (c->conn->unix_sock && STS_LIVE(c->srv, shm_max))
        r.caps |= STP_CAP_SHM;       /* shm.c: offered on Unix connections only */
    uint64_t mf = STS_LIVE(c->srv, max_frame);
    r.max_body = mf > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)mf;
    r.max_batch = STS_LIVE(c->srv, max_batch);
    r.max_chunk = STP_DEFAULT_MAX_CHUNK;
    r.max_inflight = 256;
    r.authenticated = c->conn->authed != 0 && !sts_token_allows(c->srv, 0);
    snprintf(r.server_name, sizeof r.server_name, "seamtexd 0.1");
    stp_enc_hello_reply(out, h->reqid, &r);
    return 0;
}

int sts_h_ping(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    (void)c;
    stp_enc_raw(out, h->opcode, STP_F_REPLY, h->reqid, STP_S_OK, 0, body, h->body_len);
    return 0;
}

int sts_h_list(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_list_req rq;
    const char *why = NULL;
    int st = stp_dec_list_req(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    size_t total = st_registry_count(c->srv->reg);
    st_setref **refs = malloc((total ? total : 1) * sizeof *refs);
    if (!refs) {
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    size_t n = st_registry_snapshot(c->srv->reg, refs, total);
    if (c->srv->cluster) {   /* in a cluster, the copies reads may use (sts_cluster_serves) */
        size_t k = 0;
        for (size_t i = 0; i < n; i++) {
            if (sts_cluster_serves(c->srv->cluster, refs[i]))
                refs[k++] = refs[i];
            else
                st_setref_release(refs[i]);
        }
        n = k;
    }
    size_t first = rq.first < n ? rq.first : n;
    size_t count = n - first;
    size_t cap = rq.max ? rq.max : 65536;
    if (cap > 65536)
        cap = 65536;
    if (count > cap)
        count = cap;
    stp_list_entry *ents = calloc(count ? count : 1, sizeof *ents);
    if (!ents) {
        for (size_t i = 0; i < n; i++)
            st_setref_release(refs[i]);
        free(refs);
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    for (size_t i = 0; i < count; i++) {
        const st_setref *r = refs[first + i];
        snprintf(ents[i].name, sizeof ents[i].name, "%s", r->name);
        ents[i].kind = r->set->info.kind;
        ents[i].nchan = r->set->info.nchan;
        ents[i].dtype = r->set->info.dtype;
        ents[i].nfaces = r->set->info.nfaces;
        ents[i].memory = st_set_memory(r->set);
    }
    stp_list_reply rep;
    memset(&rep, 0, sizeof rep);
    rep.total = (uint32_t)n;
    rep.count = (uint32_t)count;
    rep.entries = ents;
    stp_enc_list_reply(out, h->reqid, &rep);
    free(ents);
    for (size_t i = 0; i < n; i++)
        st_setref_release(refs[i]);
    free(refs);
    return 0;
}

int sts_h_info(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_info_req rq;
    const char *why = NULL;
    int st = stp_dec_info_req(body, h->body_len, &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    st_setref *ref = get_set(c, h, rq.name, out);
    if (!ref)
        return 0;
    const st_set *s = ref->set;
    stp_info_reply r;
    memset(&r, 0, sizeof r);
    r.nfaces = s->info.nfaces;
    r.nchan = s->info.nchan;
    r.dtype = s->info.dtype;
    r.alpha_chan = s->info.alpha_chan;
    r.kind = s->info.kind;
    r.colorspace = s->info.colorspace;
    r.premultiplied = s->info.premultiplied;
    r.border_u = s->info.border_u;
    r.border_v = s->info.border_v;
    r.meshtype = s->info.meshtype;
    r.edgefilter = s->info.edgefilter;
    r.memory = st_set_memory(s);
    r.texel_bytes = s->texel_bytes;
    r.min_w = r.min_h = s->info.nfaces ? UINT32_MAX : 0;
    r.nmeta = s->nmeta;
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        const st_face *fc = &s->faces[f];
        if (fc->w < r.min_w) r.min_w = fc->w;
        if (fc->w > r.max_w) r.max_w = fc->w;
        if (fc->h < r.min_h) r.min_h = fc->h;
        if (fc->h > r.max_h) r.max_h = fc->h;
        if (fc->flags & ST_FACE_CONSTANT) r.nconstant++;
        if (fc->flags & ST_FACE_SUBFACE) r.nsubfaces++;
        /* a triangle has three edges and corners; its regular interior vertex has valence 6 */
        int tri = s->info.meshtype == ST_MESH_TRIANGLE;
        for (int e = 0; e < (tri ? 3 : 4); e++) {
            if (fc->adjface[e] < 0)
                r.boundary_edges++;
            unsigned v = fc->valence[e];
            unsigned val = v & ~ST_VALENCE_BOUNDARY;
            if (val > r.max_valence)
                r.max_valence = val;
            if (!(v & ST_VALENCE_BOUNDARY) && val != (tri ? 6u : 4u))
                r.irregular_corners++;
        }
    }
    uint32_t first = rq.face_first < s->info.nfaces ? rq.face_first : s->info.nfaces;
    uint32_t nrec = rq.face_count;
    if (nrec > s->info.nfaces - first)
        nrec = s->info.nfaces - first;
    uint64_t room = (STS_LIVE(c->srv, max_frame) - 128) / STP_FACE_REC_SIZE;
    if (nrec > room)
        nrec = (uint32_t)room;
    if (nrec > (1u << 20))
        nrec = 1u << 20;
    stp_face_rec *recs = NULL;
    if (nrec) {
        recs = calloc(nrec, sizeof *recs);
        if (!recs) {
            st_setref_release(ref);
            sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
            return 0;
        }
        for (uint32_t i = 0; i < nrec; i++) {
            const st_face *fc = &s->faces[first + i];
            recs[i].w = fc->w;
            recs[i].h = fc->h;
            for (int e = 0; e < 4; e++) {
                recs[i].adjface[e] = fc->adjface[e];
                recs[i].adjedge[e] = fc->adjedge[e];
            }
            recs[i].flags = fc->flags;
            recs[i].nlevels = fc->nlevels;
        }
    }
    r.face_first = first;
    r.nrec = nrec;
    r.faces = recs;
    stp_enc_info_reply(out, h->reqid, &r);
    free(recs);
    st_setref_release(ref);
    return 0;
}

#define WIRE_IS_ST_QUERY                                                                  \
    (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ && sizeof(st_query) == STP_QUERY_SIZE &&      \
     offsetof(st_query, u) == 4 && offsetof(st_query, dudx) == 12 &&                         \
     offsetof(st_query, dvdy) == 24)

/* The wire's modes, filters, zero rules and per-query statuses (protocol/proto_lists.h) are
 * handed to the sampler and back as they are, and set kinds and texel types are sent as the
 * store has them: each wire value must be the store's value of the same name (store/sample.h,
 * store/set.h). */
#define SAME(a, b, what) _Static_assert((int)(a) == (int)(b), what);
#define SAME_MODE(NAME, str, v)   SAME(STP_MODE_##NAME, ST_MODE_##NAME, "mode " str)
#define SAME_FILTER(NAME, str, v) SAME(STP_FILTER_##NAME, ST_FILTER_##NAME, "filter " str)
#define SAME_ZERO(NAME, str, v)   SAME(STP_ZERO_##NAME, ST_ZERO_##NAME, "zero rule " str)
#define SAME_QSTATUS(NAME, v)     SAME(STP_Q_##NAME, ST_Q_##NAME, "query status " #NAME)
#define SAME_KIND(NAME, str, v)   SAME(STP_KIND_##NAME, ST_KIND_##NAME, "kind " str)
#define SAME_DTYPE(NAME, str, v)  SAME(STP_DT_##NAME, ST_DT_##NAME, "dtype " str)
STP_MODES(SAME_MODE)
STP_FILTERS(SAME_FILTER)
STP_ZERO_RULES(SAME_ZERO)
STP_QSTATUSES(SAME_QSTATUS)
STP_KINDS(SAME_KIND)
STP_DTYPES(SAME_DTYPE)
#undef SAME_MODE
#undef SAME_FILTER
#undef SAME_ZERO
#undef SAME_QSTATUS
#undef SAME_KIND
#undef SAME_DTYPE
#undef SAME

/* Request parameters -> sampler options; -1 for a mode, filter or zero rule the protocol does
 * not define (the sampler then never sees it), or for a sharpness, width or blur out of its
 * range (PROTOCOL.md 4.4: sharpness 0..1, width and blur 0..1e4, NaN never), whatever the
 * filter: only the Ptex filters use them, but a value no filter could take is refused for
 * every filter, so a client's bad value does not wait for a filter change to surface. */
/* The request's parameters into o; NULL, or the reason naming the first bad one in PROTOCOL.md
 * 4.4's order (the decoder has checked name, outfmt, max_aniso, flags and footprint). */
static const char *fill_opts(const stp_sample_params *p, st_sample_opts *o)
{
    memset(o, 0, sizeof *o);
    o->mode = p->mode;
    o->filter = p->filter;
    o->zero_rule = p->zero_rule;
    o->max_aniso = p->max_aniso;
    o->sharpness = p->sharpness;
    o->width = p->width;
    o->blur = p->blur;
    o->lerp = (p->flags & STP_SF_LERP) != 0; /* Ptex's lerp (SAMPLE flag bit 5) */
    if (!stp_mode_name(p->mode))
        return "unknown mode (0 discard, 1 traverse, 2 clamp)";
    if (!stp_filter_name(p->filter))
        return "unknown filter (0-3, 8-15)";
    if (!stp_zero_rule_name(p->zero_rule))
        return "unknown zero_rule (0 nan, 1 clamp)";
    if (p->max_aniso > 16 || !stp_outfmt_size(p->outfmt)) /* the decoder refused these first */
        return "unknown outfmt, or max_aniso over 16";
    /* written so that NaN fails every test */
    if (!(p->sharpness >= 0.0f && p->sharpness <= 1.0f))
        return "sharpness out of range (0..1)";
    if (!(p->width >= 0.0f && p->width <= ST_MAX_DERIV))
        return "width out of range (0..10000)";
    if (!(p->blur >= 0.0f && p->blur <= ST_MAX_DERIV))
        return "blur out of range (0..10000)";
    return NULL;
}

/* Queries per part of a split batch (sts_pool_parallel): ~20 us of bilinear sampling, so a
 * helper that wakes late still finds parts to take, and the caller waits at most one part. */
#define PART_GRAIN 256

typedef struct part_arg {
    const st_set         *s;
    const st_sample_opts *o;
    const st_query       *q;    /* SAMPLE */
    const st_cube_query  *cq;   /* SAMPLE_DIR */
    float                *out, *cov;
    uint8_t              *status;
    unsigned              nchan;
    const stp_sample_req *rq;   /* SAMPLE: the request, for part_sample_chunks */
} part_arg;

static int part_sample(void *arg, size_t first, size_t count)
{
    const part_arg *a = arg;
    return st_sample_batch(a->s, a->o, a->q + first, count, a->out + first * a->nchan,
                           a->cov ? a->cov + first : NULL, a->status + first);
}

/* Queries widened at a time by part_sample_chunks: 128 x 28 bytes on the stack stay in L1
 * between the copy and the sampler (shm_sample.c's chunk is the same size). */
#define PART_CHUNK 128

/* Queries that cannot be sampled where they lie (compact ones, PROTOCOL.md 4.4.1, or f32 ones
 * at an unaligned address: with a set name of 7 bytes the queries start at an odd offset of
 * the frame): widened PART_CHUNK at a time from the request into the stack and sampled from
 * there, on the thread that samples the part. Each query byte is read once and no
 * batch-sized copy (28 bytes a query, 114 KiB at 4096) goes through the caches. */
static int part_sample_chunks(void *arg, size_t first, size_t count)
{
    const part_arg *a = arg;
    size_t qs = stp_query_size(a->rq->p.flags);
    st_query q[PART_CHUNK];
    int bad = 0;
    for (size_t i = first; i < first + count; i += PART_CHUNK) {
        uint32_t k = first + count - i < PART_CHUNK ? (uint32_t)(first + count - i) : PART_CHUNK;
        sts_sample_decode(STP_OP_SAMPLE, a->rq, a->rq->raw + i * qs, k, q, NULL);
        int rc = st_sample_batch(a->s, a->o, q, k, a->out + i * a->nchan,
                                 a->cov ? a->cov + i : NULL, a->status + i);
        if (rc < 0)
            return rc;
        bad += rc;
    }
    return bad;
}

static int part_sample_dir(void *arg, size_t first, size_t count)
{
    const part_arg *a = arg;
    return st_cube_sample_dir(a->s, a->o, ST_CUBE_LOOKUP_PLAIN, a->cq + first, count,
                              a->out + first * a->nchan, a->cov ? a->cov + first : NULL,
                              a->status + first);
}

/* Samples the batch on this thread, split with idle workers when it has split-batch queries
 * or more (0 = never split). */
int sts_sample_parts(sts_ctx *c, size_t n, sts_part_fn fn, void *arg)
{
    uint32_t split = STS_LIVE(c->srv, split_batch);
    if (n == 0)
        return 0;
    if (split && n >= split) {
        /* on an I/O thread (its own scratch) the pool tracks it as that thread's batches */
        const sts_io *io = c->conn ? c->conn->io : NULL;
        int slot = io && c->scratch == &io->scratch ? io->index : -1;
        return sts_pool_parallel(&c->srv->pool, slot, n, PART_GRAIN, fn, arg);
    }
    return fn(arg, 0, n);
}

/* f32 replies on a little-endian host: the reply's values (and coverage, status) are laid
 * out exactly as the sampler writes them, so the frame is started in `out` and the batch is
 * sampled straight into it: no intermediate array, no encode pass. Returns 1 when the reply
 * is complete in `out` (*rc = bad queries), 0 when it could not be done here (no room,
 * unaligned room, or the sampler refused the options: *rc < 0), with `out` as it was. */
static int sample_into_reply(sts_ctx *c, const stp_header *h, const stp_sample_req *rq,
                             uint32_t n, sts_part_fn fn, part_arg *a, stp_buf *out, int *rc)
{
    int want_cov = (rq->p.flags & STP_SF_COVERAGE) != 0;
    int want_st = (rq->p.flags & STP_SF_STATUS) != 0;
    size_t vbytes = (size_t)n * a->nchan * 4;   /* n <= max-batch (2^32 - 1) and nchan <= 4 */
    size_t cbytes = want_cov ? (size_t)n * 4 : 0;
    size_t bytes = vbytes + cbytes + (want_st ? n : 0);
    size_t at = stp_frame_begin(out, h->opcode, STP_F_REPLY, h->reqid, 0, 0);
    stp_put_u32(out, n);
    stp_put_u8(out, (uint8_t)a->nchan);
    stp_put_u8(out, rq->p.outfmt);
    stp_put_u8(out, rq->p.flags & STP_SF_REPLY_MASK);
    stp_put_u8(out, 0);
    size_t nbad_at = out->len - out->start;   /* head-relative: survives compaction */
    stp_put_u32(out, 0);
    *rc = 0;
    if (!out->err && stp_buf_reserve(out, bytes) == 0 &&
        ((uintptr_t)(out->data + out->len) % _Alignof(float)) == 0) {
        uint8_t *dst = out->data + out->len;
        a->out = (float *)(void *)dst;
        a->cov = want_cov ? (float *)(void *)(dst + vbytes) : NULL;
        if (want_st)
            a->status = dst + vbytes + cbytes;
        *rc = sts_sample_parts(c, n, fn, a);
        if (*rc >= 0) {
            out->len += bytes;
            stp_wr32(out->data + out->start + nbad_at, (uint32_t)*rc);
            if (stp_frame_end(out, at) == 0)
                return 1;
            sts_reply_error(out, h, STP_S_TOO_LARGE, "reply could not be encoded (too large?)");
            return 1;
        }
    }
    /* drop the partial frame: the buffer holds whole frames only */
    out->len = out->start + at;
    out->err = 0;
    a->out = c->scratch->out;
    a->cov = want_cov ? c->scratch->cov : NULL;
    a->status = c->scratch->status;
    return 0;
}

/* Counts the queries of an answered batch: in all, by mode and filter, and the bad ones. */
static void count_queries(sts_server *srv, const stp_sample_params *p, uint32_t n, uint64_t bad)
{
    STS_STAT_ADD(srv, queries, n);
    STS_STAT_ADD(srv, query_errors, bad);
    if (p->mode < STS_QMODES && p->filter < STS_QFILTERS)
        STS_STAT_ADD(srv, queries_by[p->mode][p->filter], n);
}

void sts_sample_decode(uint8_t opcode, const stp_sample_req *rq, const uint8_t *raw, uint32_t k,
                       st_query *q, st_cube_query *cq)
{
    stp_sample_req r = *rq;
    r.raw = raw;
    r.count = k;
    if (opcode == STP_OP_SAMPLE_DIR) {
        for (uint32_t i = 0; i < k; i++) {
            stp_dir_query d;
            stp_sample_dir_query(&r, i, &d);
            memcpy(cq[i].dir, d.dir, sizeof d.dir);
            if (rq->p.footprint == STP_FP_CONE) {
                cq[i].cone = d.ddx[0];
                memset(cq[i].ddx, 0, sizeof cq[i].ddx);
                memset(cq[i].ddy, 0, sizeof cq[i].ddy);
            } else {
                cq[i].cone = 0;
                memcpy(cq[i].ddx, d.ddx, sizeof d.ddx);
                memcpy(cq[i].ddy, d.ddy, sizeof d.ddy);
            }
        }
        return;
    }
    if (!(rq->p.flags & STP_SF_COMPACT_MASK) && WIRE_IS_ST_QUERY) {
        if (k)    /* with k == 0 both pointers may be NULL: memcpy must not see them */
            memcpy(q, raw, (size_t)k * STP_QUERY_SIZE);
        return;
    }
    if (WIRE_IS_ST_QUERY) {
        /* compact queries widened straight into st_query's layout (the f32 wire form) */
        stp_sample_queries_f32(&r, 0, k, (uint8_t *)(void *)q);
        return;
    }
    stp_query tmp[64];
    for (uint32_t i = 0; i < k;) {
        uint32_t m = k - i < 64 ? k - i : 64;
        stp_sample_queries(&r, i, m, tmp);
        for (uint32_t j = 0; j < m; j++) {
            st_query *d = &q[i + j];
            d->face = tmp[j].face;
            d->u = tmp[j].u;
            d->v = tmp[j].v;
            d->dudx = tmp[j].dudx;
            d->dvdx = tmp[j].dvdx;
            d->dudy = tmp[j].dudy;
            d->dvdy = tmp[j].dvdy;
        }
        i += m;
    }
}

/* 1 when sampling s with o would first build data the set builds lazily and a memory-budget
 * release may drop (tens to hundreds of milliseconds for a large set): an atlas's chart data
 * for chart Discard / Traverse (kinds/atlas.h), a Ptex table for a Ptex filter (ptexres.h).
 * A hint read without a lock: a release right after it only means the build runs here. */
static int builds_first(const st_set *s, const st_sample_opts *o)
{
    if ((o->mode == ST_MODE_DISCARD || o->mode == ST_MODE_TRAVERSE) &&
        s->info.kind == ST_KIND_ATLAS && s->ext.charts_pin && !st_atlas_charts_built_bytes(s))
        return 1;
    return o->filter >= ST_FILTER_PTEX_POINT && st_ptexres_get(s) &&
           !st_ptexres_built_bytes(s);
}

int sts_sample_prepare(sts_ctx *c, const stp_header *h, const stp_sample_req *rq, stp_buf *out,
                       sts_sample_prep *pp)
{
    memset(pp, 0, sizeof *pp);
    const char *bad = fill_opts(&rq->p, &pp->o);
    if (bad) {
        sts_reply_bad(out, h, STP_S_INVALID, bad);
        return 1;
    }
    pp->ref = get_set(c, h, rq->p.name, out);
    if (!pp->ref)
        return 1;
    pp->s = pp->ref->set;
    if (c->on_io && builds_first(pp->s, &pp->o)) {
        st_setref_release(pp->ref);   /* a worker takes the request from the start */
        pp->ref = NULL;
        return 2;
    }
    pp->cold = sts_budget_touch(c->srv, pp->ref->set);  /* a released set faults back in */
    pp->t0 = pp->cold ? sts_now_us() : 0;
    if (h->opcode == STP_OP_SAMPLE_DIR && !st_cube_is_cube(pp->s)) {
        st_setref_release(pp->ref);
        pp->ref = NULL;
        sts_reply_error(out, h, STP_S_UNSUPPORTED, "SAMPLE_DIR needs a cube-map set");
        return 1;
    }
    return 0;
}

int sts_sample_finish(sts_ctx *c, const stp_header *h, const stp_sample_req *rq,
                      sts_sample_prep *pp, int rc, stp_buf *out)
{
    const st_set *s = pp->s;
    if (pp->cold)
        sts_budget_cold_done(c->srv, pp->t0, rq->count);
    if (rc >= 0)
        count_queries(c->srv, &rq->p, rq->count, (uint64_t)rc);
    else
        sts_reply_st(out, h, rc, rc != ST_EUNSUPPORTED ? "invalid sampling options"
                                 : s->info.meshtype == ST_MESH_TRIANGLE
                                     ? "a triangle-mesh set samples with point (0) and the "
                                       "Ptex filters (8-15); bilinear, trilinear and aniso "
                                       "are not defined on triangle faces"
                                 : s->info.kind == ST_KIND_BC1
                                     ? "the Ptex filters need an uncompressed per-face set; BC1 "
                                       "sets sample with point, bilinear, trilinear and aniso"
                                     : "the Ptex filters need a per-face set");
    st_setref_release(pp->ref);
    pp->ref = NULL;
    return rc < 0;
}

/* Samples and replies; shared by SAMPLE and SAMPLE_DIR (h->opcode tells which). */
int sts_sample_run(sts_ctx *c, const stp_header *h, const stp_sample_req *rq, stp_buf *out)
{
    sts_sample_prep pp;
    int prc = sts_sample_prepare(c, h, rq, out, &pp);
    if (prc)
        return prc == 2 ? STS_DEFER : 0;
    const st_set *s = pp.s;
    uint32_t n = rq->count;
    if (sts_scratch_reserve(c->scratch, n ? n : 1, h->opcode == STP_OP_SAMPLE_DIR) != 0) {
        st_setref_release(pp.ref);
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory for the batch");
        return 0;
    }
    sts_scratch *sc = c->scratch;
    float *cov = (rq->p.flags & STP_SF_COVERAGE) ? sc->cov : NULL;
    part_arg a = {s, &pp.o, sc->q, sc->cq, sc->out, cov, sc->status, s->info.nchan, NULL};
    sts_part_fn fn;
    if (h->opcode == STP_OP_SAMPLE) {
        /* the wire query (u32 face, 6 x f32, little-endian, packed) is st_query's layout on
         * a little-endian host: sampled where it lies in the input buffer when aligned, else
         * (and compact queries, PROTOCOL.md 4.4.1) widened a chunk at a time in each part,
         * so a split batch decodes in parallel too */
        a.rq = rq;
        fn = part_sample_chunks;
        if (WIRE_IS_ST_QUERY && !(rq->p.flags & STP_SF_COMPACT_MASK) && n &&
            ((uintptr_t)rq->raw % _Alignof(st_query)) == 0) {
            a.q = (const st_query *)(const void *)rq->raw;
            fn = part_sample;
        }
    } else {
        sts_sample_decode(h->opcode, rq, rq->raw, n, NULL, sc->cq);
        fn = part_sample_dir;
    }
    int rc = 0, replied = 0;
    if (n && rq->p.outfmt == STP_OUT_F32 && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__)
        replied = sample_into_reply(c, h, rq, n, fn, &a, out, &rc);
    if (!replied && rc >= 0)
        rc = sts_sample_parts(c, n, fn, &a);
    if (sts_sample_finish(c, h, rq, &pp, rc, out) || replied)
        return 0;
    stp_sample_reply r;
    memset(&r, 0, sizeof r);
    r.count = n;
    r.nchan = s->info.nchan;
    r.outfmt = rq->p.outfmt;
    r.flags = rq->p.flags & STP_SF_REPLY_MASK;
    r.nbad = (uint32_t)rc;
    r.values = sc->out;
    r.coverage = cov;
    r.status = sc->status;
    int e = stp_enc_sample_reply(out, h->opcode, h->reqid, &r);
    if (e)
        sts_reply_error(out, h, e, "reply could not be encoded (too large?)");
    return 0;
}

int sts_h_sample(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_sample_req rq;
    const char *why = NULL;
    int st = stp_dec_sample_req(body, h->body_len, STS_LIVE(c->srv, max_batch), &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    if (rq.p.flags & STP_SF_SHM)
        return sts_shm_sample(c, h, &rq, out);
    return sts_sample_run(c, h, &rq, out);
}

int sts_h_sample_dir(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    stp_sample_req rq;
    const char *why = NULL;
    int st = stp_dec_sample_dir_req(body, h->body_len, STS_LIVE(c->srv, max_batch), &rq, &why);
    if (st)
        return sts_reply_bad(out, h, st, why);
    if (rq.p.flags & STP_SF_SHM)
        return sts_shm_sample(c, h, &rq, out);
    return sts_sample_run(c, h, &rq, out);
}

/* ---- STATS ------------------------------------------------------------------------------------ */

#define U(k, val) do { if (n < cap) { snprintf(s[n].key, sizeof s[n].key, "%s", k); \
    s[n].type = STP_STAT_U64; s[n].v.u = (val); n++; } } while (0)
#define L(f) __atomic_load_n(&srv->stats.f, __ATOMIC_RELAXED)

size_t sts_stats_max_keys(const sts_server *srv)
{
    /* with the budget's keys (budget.c), the cluster's (cluster_node.c), the query counts
     * by mode and filter and three per I/O thread */
    return 224 + STS_SHM_STAT_KEYS + 3 * (size_t)srv->nio + STS_QMODES * STS_QFILTERS + sts_opstats_max_keys();
}

size_t sts_stats_collect(sts_server *srv, stp_stat *s, size_t cap)
{
    size_t n = 0;
    U("uptime_ms", (uint64_t)(sts_now_ms() - srv->started_ms));
    U("conns_current", __atomic_load_n(&srv->nconns, __ATOMIC_RELAXED));
    U("conns_accepted", L(conns_accepted));
    U("conns_rejected", L(conns_rejected));
    U("conns_closed", L(conns_closed));
    U("conns_idle_closed", L(conns_idle_closed));
    U("requests", L(requests));
    U("replies_error", L(replies_error));
    U("bytes_in", L(bytes_in));
    U("bytes_out", L(bytes_out));
    U("reads", L(reads));
    U("writes", L(writes));
    U("frames_bad_magic", L(frames_bad_magic));
    U("frames_bad_version", L(frames_bad_version));
    U("frames_too_large", L(frames_too_large));
    U("frames_unknown_opcode", L(frames_unknown_op));
    U("bad_requests", L(bad_requests));
    U("perm_denied", L(perm_denied));
    U("mem_rejected", L(mem_rejected));
    U("deadline_expired", L(deadline_expired));
    U("backpressure_pauses", L(backpressure_pauses));
    U("worker_tasks", L(worker_tasks));
    U("inline_tasks", L(inline_tasks));
    U("queries", L(queries));
    U("query_errors", L(query_errors));
    U("uploads_begun", L(uploads_begun));
    U("uploads_committed", L(uploads_committed));
    U("uploads_failed", L(uploads_failed));
    U("uploads_resumed", L(uploads_resumed));
    U("uploads_expired", L(uploads_expired));
    U("native_write_failed", L(native_write_failed));
    U("upload_bytes", L(upload_bytes));
    U("deletes", L(deletes));
    U("jobs_started", L(jobs_started));
    U("jobs_done", L(jobs_done));
    U("jobs_failed", L(jobs_failed));
    U("jobs_canceled", L(jobs_canceled));
    U("fetches", L(fetches));
    U("fetches_refused", L(fetches_refused));
    U("fetch_memory", __atomic_load_n(&srv->fetch_mem, __ATOMIC_RELAXED));
    U("conns_request_timeout", L(conns_request_timeout));
    U("conns_evicted", L(conns_evicted));
    U("buffer_memory", __atomic_load_n(&srv->mem_used, __ATOMIC_RELAXED));
    U("sets", st_registry_count(srv->reg));
    U("set_memory", st_registry_memory(srv->reg));
    U("io_threads", srv->nio);
    for (uint32_t i = 0; i < srv->nio; i++) {   /* how the acceptor spread connections (io.c) */
        char key[32];
        snprintf(key, sizeof key, "io%u_conns", i);
        U(key, __atomic_load_n(&srv->io[i].nconns, __ATOMIC_RELAXED));
        snprintf(key, sizeof key, "io%u_accepted", i);
        U(key, __atomic_load_n(&srv->io[i].accepted, __ATOMIC_RELAXED));
        if (srv->io[i].cpu >= 0) {   /* pin-io (server.c) */
            snprintf(key, sizeof key, "io%u_cpu", i);
            U(key, (uint64_t)srv->io[i].cpu);
        }
    }
    U("workers", srv->pool.nthreads);
    U("worker_queue", __atomic_load_n(&srv->pool.queued, __ATOMIC_RELAXED));
    U("split_batches", __atomic_load_n(&srv->pool.split_batches, __ATOMIC_RELAXED));
    U("parts_helped", __atomic_load_n(&srv->pool.parts_helped, __ATOMIC_RELAXED));
    U("helpers_yielded", __atomic_load_n(&srv->pool.helpers_yielded, __ATOMIC_RELAXED));
    n += sts_budget_stats(srv, s + n, cap - n);
    n += sts_shm_stats(srv, s + n, cap - n);
    U("max_conns", STS_LIVE(srv, max_conns));
    U("max_frame", STS_LIVE(srv, max_frame));
    U("metrics_port", (uint64_t)srv->metrics.port);
    U("metrics_scrapes", __atomic_load_n(&srv->metrics.scrapes, __ATOMIC_RELAXED));
    U("metrics_refused", __atomic_load_n(&srv->metrics.refused, __ATOMIC_RELAXED));
    for (unsigned m = 0; m < STS_QMODES; m++)
        for (unsigned f = 0; f < STS_QFILTERS; f++) {
            uint64_t v = __atomic_load_n(&srv->stats.queries_by[m][f], __ATOMIC_RELAXED);
            char key[STP_MAX_STAT_KEY + 1];
            if (!v || sts_queries_key(m, f, key, sizeof key) != 0)
                continue;
            U(key, v);
        }
    for (unsigned op = 0; op < 256; op++) {
        uint64_t v = __atomic_load_n(&srv->stats.by_op[op], __ATOMIC_RELAXED);
        const char *name = stp_opcode_name(op);
        if (!name)
            continue;
        char key[STP_MAX_STAT_KEY + 1];
        snprintf(key, sizeof key, "req_%s", name);
        for (char *p = key; *p; p++)
            if (*p >= 'A' && *p <= 'Z')
                *p = (char)(*p - 'A' + 'a');
        U(key, v);
    }
    n += sts_opstats_report(&srv->opstats, s + n, cap - n);
    if (srv->cluster)
        n += sts_cluster_stats(srv->cluster, s + n, cap - n);
    return n;
}

int sts_queries_key(unsigned mode, unsigned filter, char *key, size_t cap)
{
    const char *m = stp_mode_name(mode), *f = stp_filter_name(filter);
    if (!m || !f)
        return -1;
    snprintf(key, cap, "queries_%s_%s", m, f);
    for (char *p = key; *p; p++)
        if (*p == '-')
            *p = '_';
    return 0;
}

int sts_h_stats(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    const char *why = NULL;
    if (h->body_len && stp_dec_empty(body, h->body_len, &why))
        return sts_reply_bad(out, h, STP_S_BAD_REQUEST, why);
    size_t cap = sts_stats_max_keys(c->srv);
    stp_stat *s = malloc(cap * sizeof *s);
    if (!s) {
        sts_reply_error(out, h, STP_S_NOMEM, "out of memory");
        return 0;
    }
    size_t n = sts_stats_collect(c->srv, s, cap);
    stp_stats_reply r;
    memset(&r, 0, sizeof r);
    r.count = (uint32_t)n;
    r.stats = s;
    stp_enc_stats_reply(out, h->reqid, &r);
    free(s);
    return 0;
}
