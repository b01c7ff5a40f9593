/* protocol/bodies.c - encoders and decoders of every body layout in PROTOCOL.md section 4.
 *
 * Owns: the byte layout of request and reply bodies, and the checks a body can have without
 * knowing the server's state: every set name in a request is held to the rule of stp_name.h
 * (INVALID), output formats and flag bits to their lists. Does not own: the header
 * (proto.c), what a value means to the store (the server looks names up in its sets and
 * checks modes and filters against the sampler's), I/O.
 *
 * Decoders never read past `len`: every field goes through an stp_rd cursor, every count is
 * checked against the bytes left before it is used (multiplications overflow-checked), and
 * leftover bytes are refused. They point into the body for bulk arrays (zero copy).
 */
#include "codec_simd.h"

/* Ends a decode: the cursor must have stayed in bounds and used every byte. */
static int finish(const stp_rd *r, const char **why, const char *what)
{
    if (r->bad) {
        if (why)
            *why = r->nul ? STP_WHY_NUL : what;
        return STP_S_BAD_REQUEST;
    }
    if (stp_rd_left(r) != 0) {
        if (why)
            *why = "trailing bytes after the last field";
        return STP_S_BAD_REQUEST;
    }
    return 0;
}

static int fail(const char **why, const char *what, int status)
{
    if (why)
        *why = what;
    return status;
}

/* Reads a str16 set name (request decoders). A body that is cut short, or a NUL byte in the
 * string, sets r->bad (the decoder answers BAD_REQUEST, as for every str16); any other name
 * that breaks the rule of stp_name.h (longer than 255 bytes included) is not a malformed
 * body: *problem gets the stp_name_problem, name is left "", and the decoder answers INVALID
 * once the rest of the body has been found well-formed (name_fail). */
static void get_name(stp_rd *r, char name[STP_MAX_NAME + 1], int *problem)
{
    uint16_t n = stp_get_u16(r);
    const uint8_t *p = stp_rd_take(r, n);
    name[0] = 0;
    *problem = STP_NAME_OK;
    if (!p)
        return;
    if (memchr(p, 0, n)) {
        r->bad = r->nul = 1;
        return;
    }
    *problem = stp_name_check(p, n, NULL);
    if (*problem == STP_NAME_OK) {
        memcpy(name, p, n);
        name[n] = 0;
    }
}

static const char *const SET_NAME_WHY[] = STP_NAME_TEXTS("set");
static const char *const TARGET_NAME_WHY[] = STP_NAME_TEXTS("target");

static int name_fail(const char **why, const char *const texts[], int problem)
{
    return fail(why, texts[problem], STP_S_INVALID);
}

/* ---- HELLO ---------------------------------------------------------------------------------- */

int stp_enc_hello_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_hello_req *r)
{
    size_t at = stp_frame_begin(b, STP_OP_HELLO, 0, reqid, 0, timeout_ms);
    stp_put_u8(b, r->min_version);
    stp_put_u8(b, r->max_version);
    stp_put_u16(b, 0);
    stp_put_u32(b, r->caps);
    stp_put_str(b, r->token);
    stp_put_str(b, r->client_name);
    return stp_frame_end(b, at);
}

int stp_dec_hello_req(const uint8_t *body, size_t len, stp_hello_req *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->min_version = stp_get_u8(&rd);
    r->max_version = stp_get_u8(&rd);
    (void)stp_get_u16(&rd);
    r->caps = stp_get_u32(&rd);
    stp_get_str(&rd, r->token, sizeof r->token);
    stp_get_str(&rd, r->client_name, sizeof r->client_name);
    int s = finish(&rd, why, "truncated body or bad token / client name");
    if (s)
        return s;
    if (r->min_version > r->max_version)
        return fail(why, "min_version > max_version", STP_S_INVALID);
    return 0;
}

int stp_enc_hello_reply(stp_buf *b, uint32_t reqid, const stp_hello_reply *r)
{
    size_t at = stp_frame_begin(b, STP_OP_HELLO, STP_F_REPLY, reqid, 0, 0);
    stp_put_u8(b, r->version);
    stp_put_u8(b, r->authenticated);
    stp_put_u16(b, 0);
    stp_put_u32(b, r->caps);
    stp_put_u32(b, r->max_body);
    stp_put_u32(b, r->max_batch);
    stp_put_u32(b, r->max_chunk);
    stp_put_u32(b, r->max_inflight);
    stp_put_str(b, r->server_name);
    return stp_frame_end(b, at);
}

int stp_dec_hello_reply(const uint8_t *body, size_t len, stp_hello_reply *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->version = stp_get_u8(&rd);
    r->authenticated = stp_get_u8(&rd);
    (void)stp_get_u16(&rd);
    r->caps = stp_get_u32(&rd);
    r->max_body = stp_get_u32(&rd);
    r->max_batch = stp_get_u32(&rd);
    r->max_chunk = stp_get_u32(&rd);
    r->max_inflight = stp_get_u32(&rd);
    stp_get_str(&rd, r->server_name, sizeof r->server_name);
    return finish(&rd, why, "HELLO reply: truncated body or bad server name");
}

/* ---- LIST ------------------------------------------------------------------------------------- */

int stp_enc_list_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_list_req *r)
{
    size_t at = stp_frame_begin(b, STP_OP_LIST, 0, reqid, 0, timeout_ms);
    stp_put_u32(b, r->first);
    stp_put_u32(b, r->max);
    return stp_frame_end(b, at);
}

int stp_dec_list_req(const uint8_t *body, size_t len, stp_list_req *r, const char **why)
{
    stp_rd rd;
    r->first = r->max = 0;
    if (len == 0)
        return 0;
    stp_rd_init(&rd, body, len);
    r->first = stp_get_u32(&rd);
    r->max = stp_get_u32(&rd);
    return finish(&rd, why, "body must be empty or 8 bytes");
}

static void put_list_entry(stp_buf *b, const stp_list_entry *e)
{
    stp_put_str(b, e->name);
    stp_put_u8(b, e->kind);
    stp_put_u8(b, e->nchan);
    stp_put_u8(b, e->dtype);
    stp_put_u8(b, 0);
    stp_put_u32(b, e->nfaces);
    stp_put_u64(b, e->memory);
}

static void get_list_entry(stp_rd *rd, stp_list_entry *e)
{
    stp_get_str(rd, e->name, sizeof e->name);
    e->kind = stp_get_u8(rd);
    e->nchan = stp_get_u8(rd);
    e->dtype = stp_get_u8(rd);
    (void)stp_get_u8(rd);
    e->nfaces = stp_get_u32(rd);
    e->memory = stp_get_u64(rd);
}

int stp_enc_list_reply(stp_buf *b, uint32_t reqid, const stp_list_reply *r)
{
    size_t at = stp_frame_begin(b, STP_OP_LIST, STP_F_REPLY, reqid, 0, 0);
    stp_put_u32(b, r->total);
    stp_put_u32(b, r->count);
    for (uint32_t i = 0; i < r->count; i++)
        put_list_entry(b, &r->entries[i]);
    return stp_frame_end(b, at);
}

int stp_dec_list_reply(const uint8_t *body, size_t len, stp_list_reply *r, const char **why)
{
    stp_rd rd;
    stp_list_entry e;
    stp_rd_init(&rd, body, len);
    r->total = stp_get_u32(&rd);
    r->count = stp_get_u32(&rd);
    r->entries = NULL;
    r->raw = NULL;
    r->raw_len = 0;
    if (rd.bad)
        return fail(why, "LIST reply: truncated", STP_S_BAD_REQUEST);
    /* Each entry takes at least 18 bytes: refuse a count the body cannot hold before looping. */
    if ((uint64_t)r->count * 18 > stp_rd_left(&rd))
        return fail(why, "LIST reply: count larger than the body", STP_S_BAD_REQUEST);
    r->raw = rd.p + rd.off;
    r->raw_len = stp_rd_left(&rd);
    for (uint32_t i = 0; i < r->count && !rd.bad; i++)
        get_list_entry(&rd, &e);
    return finish(&rd, why, "LIST reply: an entry is truncated or has a bad name");
}

int stp_list_next(const stp_list_reply *r, size_t *pos, stp_list_entry *e)
{
    stp_rd rd;
    if (!r->raw || *pos >= r->raw_len)
        return 0;
    stp_rd_init(&rd, r->raw, r->raw_len);
    rd.off = *pos;
    get_list_entry(&rd, e);
    if (rd.bad)
        return 0;
    *pos = rd.off;
    return 1;
}

/* ---- INFO ------------------------------------------------------------------------------------- */

int stp_enc_info_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_info_req *r)
{
    size_t at = stp_frame_begin(b, STP_OP_INFO, 0, reqid, 0, timeout_ms);
    stp_put_str(b, r->name);
    stp_put_u32(b, r->face_first);
    stp_put_u32(b, r->face_count);
    return stp_frame_end(b, at);
}

int stp_dec_info_req(const uint8_t *body, size_t len, stp_info_req *r, const char **why)
{
    stp_rd rd;
    int np;
    stp_rd_init(&rd, body, len);
    get_name(&rd, r->name, &np);
    r->face_first = stp_get_u32(&rd);
    r->face_count = stp_get_u32(&rd);
    int s = finish(&rd, why, "truncated body");
    return s ? s : np ? name_fail(why, SET_NAME_WHY, np) : 0;
}

int stp_enc_info_reply(stp_buf *b, uint32_t reqid, const stp_info_reply *r)
{
    size_t at = stp_frame_begin(b, STP_OP_INFO, STP_F_REPLY, reqid, 0, 0);
    stp_put_u32(b, r->nfaces);
    stp_put_u8(b, r->nchan);
    stp_put_u8(b, r->dtype);
    stp_put_u8(b, (uint8_t)r->alpha_chan);
    stp_put_u8(b, r->kind);
    stp_put_u8(b, r->colorspace);
    stp_put_u8(b, r->premultiplied);
    stp_put_u8(b, r->border_u);
    stp_put_u8(b, r->border_v);
    stp_put_u8(b, r->meshtype);
    stp_put_u8(b, r->edgefilter);
    stp_put_u16(b, 0);
    stp_put_u64(b, r->memory);
    stp_put_u64(b, r->texel_bytes);
    stp_put_u32(b, r->min_w);
    stp_put_u32(b, r->max_w);
    stp_put_u32(b, r->min_h);
    stp_put_u32(b, r->max_h);
    stp_put_u32(b, r->nconstant);
    stp_put_u32(b, r->nsubfaces);
    stp_put_u32(b, r->boundary_edges);
    stp_put_u32(b, r->irregular_corners);
    stp_put_u32(b, r->max_valence);
    stp_put_u32(b, r->nmeta);
    stp_put_u32(b, r->face_first);
    stp_put_u32(b, r->nrec);
    if (stp_buf_reserve(b, (size_t)r->nrec * STP_FACE_REC_SIZE) == 0)
        for (uint32_t i = 0; i < r->nrec; i++) {
            const stp_face_rec *f = &r->faces[i];
            uint8_t *p = b->data + b->len;
            stp_wr32(p, f->w);
            stp_wr32(p + 4, f->h);
            for (int e = 0; e < 4; e++)
                stp_wr32(p + 8 + 4 * e, (uint32_t)f->adjface[e]);
            memcpy(p + 24, f->adjedge, 4);
            p[28] = f->flags;
            p[29] = f->nlevels;
            stp_wr16(p + 30, 0);
            b->len += STP_FACE_REC_SIZE;
        }
    return stp_frame_end(b, at);
}

int stp_dec_info_reply(const uint8_t *body, size_t len, stp_info_reply *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->nfaces = stp_get_u32(&rd);
    r->nchan = stp_get_u8(&rd);
    r->dtype = stp_get_u8(&rd);
    r->alpha_chan = (int8_t)stp_get_u8(&rd);
    r->kind = stp_get_u8(&rd);
    r->colorspace = stp_get_u8(&rd);
    r->premultiplied = stp_get_u8(&rd);
    r->border_u = stp_get_u8(&rd);
    r->border_v = stp_get_u8(&rd);
    r->meshtype = stp_get_u8(&rd);
    r->edgefilter = stp_get_u8(&rd); /* reserved (0) from older servers: none */
    (void)stp_get_u16(&rd);
    r->memory = stp_get_u64(&rd);
    r->texel_bytes = stp_get_u64(&rd);
    r->min_w = stp_get_u32(&rd);
    r->max_w = stp_get_u32(&rd);
    r->min_h = stp_get_u32(&rd);
    r->max_h = stp_get_u32(&rd);
    r->nconstant = stp_get_u32(&rd);
    r->nsubfaces = stp_get_u32(&rd);
    r->boundary_edges = stp_get_u32(&rd);
    r->irregular_corners = stp_get_u32(&rd);
    r->max_valence = stp_get_u32(&rd);
    r->nmeta = stp_get_u32(&rd);
    r->face_first = stp_get_u32(&rd);
    r->nrec = stp_get_u32(&rd);
    r->faces = NULL;
    r->raw = NULL;
    if (rd.bad)
        return fail(why, "INFO reply: truncated", STP_S_BAD_REQUEST);
    if ((uint64_t)r->nrec * STP_FACE_REC_SIZE != stp_rd_left(&rd))
        return fail(why, "INFO reply: nrec does not match the body length", STP_S_BAD_REQUEST);
    r->raw = rd.p + rd.off;
    return 0;
}

void stp_info_face(const stp_info_reply *r, uint32_t i, stp_face_rec *f)
{
    const uint8_t *p = r->raw + (size_t)i * STP_FACE_REC_SIZE;
    f->w = stp_rd32(p);
    f->h = stp_rd32(p + 4);
    for (int e = 0; e < 4; e++)
        f->adjface[e] = (int32_t)stp_rd32(p + 8 + 4 * e);
    memcpy(f->adjedge, p + 24, 4);
    f->flags = p[28];
    f->nlevels = p[29];
}

/* ---- SAMPLE / SAMPLE_DIR ---------------------------------------------------------------------- */

static void put_params(stp_buf *b, const stp_sample_params *p, int dir)
{
    stp_put_str(b, p->name);
    stp_put_u8(b, p->mode);
    stp_put_u8(b, p->filter);
    stp_put_u8(b, p->zero_rule);
    stp_put_u8(b, p->max_aniso);
    stp_put_u8(b, p->outfmt);
    stp_put_u8(b, p->flags);
    stp_put_u8(b, dir ? p->footprint : 0);
    stp_put_u8(b, 0);
    stp_put_f32(b, p->sharpness);
    stp_put_f32(b, p->width);
    stp_put_f32(b, p->blur);
}

/* With STP_SF_SHM the queries are in the shared region: the body ends with where (4.12). */
static void put_shm_ref(stp_buf *b, const stp_shm_ref *s)
{
    stp_put_u64(b, s->query_off);
    stp_put_u64(b, s->reply_off);
    stp_put_u64(b, s->reply_cap);
}

void stp_put_queries(uint8_t opcode, const stp_sample_req *r, uint8_t *out)
{
    uint8_t *p = out;
    if (opcode == STP_OP_SAMPLE_DIR) {
        for (uint32_t i = 0; i < r->count; i++) {
            const stp_dir_query *q = &r->dqueries[i];
            for (int k = 0; k < 3; k++) {
                stp_wr32(p + 4 * k, stp_f2u(q->dir[k]));
                stp_wr32(p + 12 + 4 * k, stp_f2u(q->ddx[k]));
                stp_wr32(p + 24 + 4 * k, stp_f2u(q->ddy[k]));
            }
            p += STP_DIR_QUERY_SIZE;
        }
        return;
    }
    size_t qs = stp_query_size(r->p.flags);
    int face16 = (r->p.flags & STP_SF_FACE16) != 0;
    if (r->p.flags & STP_SF_UV16) {             /* compact.c, vectorised where the CPU can */
        stp_put_queries_uv16(r->queries, r->count, face16, out);
        return;
    }
    if (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ && !face16 && sizeof *r->queries == qs) {
        if (r->count)                           /* stp_query is the wire layout: one copy */
            memcpy(out, r->queries, (size_t)r->count * qs);
        return;
    }
    for (uint32_t i = 0; i < r->count; i++, p += qs) {
        const stp_query *q = &r->queries[i];
        uint8_t *f = p + (face16 ? 2 : 4);
        if (face16)
            stp_wr16(p, (uint16_t)q->face);
        else
            stp_wr32(p, q->face);
        stp_wr32(f, stp_f2u(q->u));
        stp_wr32(f + 4, stp_f2u(q->v));
        stp_wr32(f + 8, stp_f2u(q->dudx));
        stp_wr32(f + 12, stp_f2u(q->dvdx));
        stp_wr32(f + 16, stp_f2u(q->dudy));
        stp_wr32(f + 20, stp_f2u(q->dvdy));
    }
}

int stp_enc_sample_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_sample_req *r)
{
    size_t at = stp_frame_begin(b, STP_OP_SAMPLE, 0, reqid, 0, timeout_ms);
    size_t bytes, qs = stp_query_size(r->p.flags);
    put_params(b, &r->p, 0);
    stp_put_u32(b, r->count);
    if (r->p.flags & STP_SF_SHM)
        put_shm_ref(b, &r->shm);
    else if (__builtin_mul_overflow(r->count, qs, &bytes))
        b->err = STP_S_TOO_LARGE;
    else if (stp_buf_reserve(b, bytes) == 0) {
        stp_put_queries(STP_OP_SAMPLE, r, b->data + b->len);
        b->len += bytes;
    }
    return stp_frame_end(b, at);
}

int stp_enc_sample_dir_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                           const stp_sample_req *r)
{
    size_t at = stp_frame_begin(b, STP_OP_SAMPLE_DIR, 0, reqid, 0, timeout_ms);
    size_t bytes;
    put_params(b, &r->p, 1);
    stp_put_u32(b, r->count);
    if (r->p.flags & STP_SF_SHM)
        put_shm_ref(b, &r->shm);
    else if (__builtin_mul_overflow(r->count, STP_DIR_QUERY_SIZE, &bytes))
        b->err = STP_S_TOO_LARGE;
    else if (stp_buf_reserve(b, bytes) == 0) {
        stp_put_queries(STP_OP_SAMPLE_DIR, r, b->data + b->len);
        b->len += bytes;
    }
    return stp_frame_end(b, at);
}

static int dec_sample_common(const uint8_t *body, size_t len, uint32_t max_batch, int dir,
                             stp_sample_req *r, const char **why)
{
    stp_rd rd;
    size_t qsize;
    stp_sample_params *p = &r->p;
    int np;

    stp_rd_init(&rd, body, len);
    get_name(&rd, p->name, &np);
    p->mode = stp_get_u8(&rd);
    p->filter = stp_get_u8(&rd);
    p->zero_rule = stp_get_u8(&rd);
    p->max_aniso = stp_get_u8(&rd);
    p->outfmt = stp_get_u8(&rd);
    p->flags = stp_get_u8(&rd);
    p->footprint = stp_get_u8(&rd);
    (void)stp_get_u8(&rd);
    p->sharpness = stp_get_f32(&rd);
    p->width = stp_get_f32(&rd);
    p->blur = stp_get_f32(&rd);
    r->count = stp_get_u32(&rd);
    r->queries = NULL;
    r->dqueries = NULL;
    r->raw = NULL;
    if (rd.bad)
        return fail(why, rd.nul ? STP_WHY_NUL : "truncated parameters", STP_S_BAD_REQUEST);
    if (!dir)
        p->footprint = 0;
    /* the query layout follows the flags (SAMPLE_DIR has one layout: compact flags there are
     * INVALID below, once the length is found right for 36-byte queries) */
    qsize = dir ? STP_DIR_QUERY_SIZE : stp_query_size(p->flags);
    memset(&r->shm, 0, sizeof r->shm);
    if (p->flags & STP_SF_SHM) {
        /* the queries are in the shared region (4.12): exactly the three offsets follow */
        if (stp_rd_left(&rd) != STP_SHM_REF_SIZE)
            return fail(why, "a shared-memory request ends with 24 bytes of offsets",
                        STP_S_BAD_REQUEST);
        r->shm.query_off = stp_get_u64(&rd);
        r->shm.reply_off = stp_get_u64(&rd);
        r->shm.reply_cap = stp_get_u64(&rd);
    }
    /* The lying-length check: count must account for every remaining byte exactly. */
    else if ((uint64_t)r->count * qsize != stp_rd_left(&rd))
        return fail(why, "count does not match the body length", STP_S_BAD_REQUEST);
    if (r->count > max_batch)
        return fail(why, "count over the server's max_batch", STP_S_TOO_LARGE);
    if (np)
        return name_fail(why, SET_NAME_WHY, np);
    if (stp_outfmt_size(p->outfmt) == 0)
        return fail(why, "unknown output format", STP_S_INVALID);
    if (p->max_aniso > 16)
        return fail(why, "max_aniso over 16", STP_S_INVALID);
    if (p->flags & ~(STP_SF_REPLY_MASK | STP_SF_COMPACT_MASK | STP_SF_SHM | STP_SF_LERP))
        return fail(why, "unknown flag bits", STP_S_INVALID);
    if (dir && (p->flags & STP_SF_LERP))
        return fail(why, "the lerp flag (bit 5) is for SAMPLE only", STP_S_INVALID);
    if (dir && (p->flags & STP_SF_COMPACT_MASK))
        return fail(why, "the compact query flags (UV16, FACE16) are for SAMPLE only",
                    STP_S_INVALID);
    if (dir && p->footprint > STP_FP_CONE)
        return fail(why, "unknown footprint kind", STP_S_INVALID);
    r->raw = (p->flags & STP_SF_SHM) ? NULL : rd.p + rd.off;
    return 0;
}

int stp_dec_sample_req(const uint8_t *body, size_t len, uint32_t max_batch, stp_sample_req *r,
                       const char **why)
{
    return dec_sample_common(body, len, max_batch, 0, r, why);
}

int stp_dec_sample_dir_req(const uint8_t *body, size_t len, uint32_t max_batch,
                           stp_sample_req *r, const char **why)
{
    return dec_sample_common(body, len, max_batch, 1, r, why);
}

uint32_t stp_sample_peek_count(const uint8_t *body, size_t len)
{
    if (len < 2)
        return 0;
    size_t at = 2 + (size_t)stp_rd16(body) + 20;
    return len >= at + 4 ? stp_rd32(body + at) : 0;
}

void stp_sample_query(const stp_sample_req *r, uint32_t i, stp_query *q)
{
    stp_sample_queries(r, i, 1, q);
}

void stp_sample_dir_query(const stp_sample_req *r, uint32_t i, stp_dir_query *q)
{
    const uint8_t *p = r->raw + (size_t)i * STP_DIR_QUERY_SIZE;
    for (int k = 0; k < 3; k++) {
        q->dir[k] = stp_u2f(stp_rd32(p + 4 * k));
        q->ddx[k] = stp_u2f(stp_rd32(p + 12 + 4 * k));
        q->ddy[k] = stp_u2f(stp_rd32(p + 24 + 4 * k));
    }
}

/* The unorm rule of PROTOCOL.md 4.6, computed exactly: the integer nearest to
 * clamp(v, 0, 1) * max, ties (only v = 0.5 has one) rounded up; NaN gives 0. In binary64 the
 * product of a binary32 value (24 significant bits) and 255 or 65535 (8 or 16 bits) is exact,
 * and adding 0.5 to a value below 2^17 is exact too, so truncating x gives the exact result
 * (in binary32 the product would round first: 0.54705882f * 255 is 139.4999..., which
 * rounds to 139.5 in binary32 and would give 140). Written as selects so that the compiler
 * turns the loop into min/max instructions. */
static inline uint32_t to_unorm(float v, double max)
{
    double x = (double)v * max + 0.5;
    x = x > 0.0 ? x : 0.0;
    x = x < max ? x : max;
    return (uint32_t)x;
}

void stp_unorm8_encode_scalar(const float *v, size_t n, uint8_t *out)
{
    for (size_t i = 0; i < n; i++)
        out[i] = (uint8_t)to_unorm(v[i], 255.0);
}

void stp_unorm16_encode_scalar(const float *v, size_t n, uint8_t *out)
{
    for (size_t i = 0; i < n; i++)
        stp_wr16(out + 2 * i, (uint16_t)to_unorm(v[i], 65535.0));
}

/* unorm and f16 through codec_avx2.c when the CPU has AVX2 + F16C (the same bits) */
void stp_enc_sample_values(uint8_t *dst, const float *v, size_t n, uint8_t outfmt)
{
    int avx2 = outfmt != STP_OUT_F32 && stp_codec_have_avx2();
    switch (outfmt) {
    case STP_OUT_F32:
        for (size_t i = 0; i < n; i++)
            stp_wr32(dst + 4 * i, stp_f2u(v[i]));
        break;
    case STP_OUT_UNORM8:
        (avx2 ? stp_unorm8_encode_avx2 : stp_unorm8_encode_scalar)(v, n, dst);
        break;
    case STP_OUT_F16:
        (avx2 ? stp_f16_encode_avx2 : stp_f16_encode_scalar)(v, n, dst);
        break;
    default:
        (avx2 ? stp_unorm16_encode_avx2 : stp_unorm16_encode_scalar)(v, n, dst);
        break;
    }
}

int stp_enc_sample_reply(stp_buf *b, uint8_t opcode, uint32_t reqid, const stp_sample_reply *r)
{
    size_t at, nval, bytes, esz = stp_outfmt_size(r->outfmt);
    if (esz == 0 || r->nchan < 1 || r->nchan > 4)
        return STP_S_INVALID;
    at = stp_frame_begin(b, opcode, STP_F_REPLY, reqid, 0, 0);
    stp_put_u32(b, r->count);
    stp_put_u8(b, r->nchan);
    stp_put_u8(b, r->outfmt);
    stp_put_u8(b, r->flags & STP_SF_REPLY_MASK);
    stp_put_u8(b, 0);
    stp_put_u32(b, r->nbad);
    nval = (size_t)r->count * r->nchan;
    if (__builtin_mul_overflow(nval, esz, &bytes))
        b->err = STP_S_TOO_LARGE;
    else if (stp_buf_reserve(b, bytes) == 0) {
        stp_enc_sample_values(b->data + b->len, r->values, nval, r->outfmt);
        b->len += bytes;
    }
    if ((r->flags & STP_SF_COVERAGE) && stp_buf_reserve(b, (size_t)r->count * 4) == 0) {
        stp_enc_sample_values(b->data + b->len, r->coverage, r->count, STP_OUT_F32);
        b->len += (size_t)r->count * 4;
    }
    if (r->flags & STP_SF_STATUS)
        stp_put_bytes(b, r->status, r->count);
    return stp_frame_end(b, at);
}

int stp_dec_sample_reply(const uint8_t *body, size_t len, stp_sample_reply *r, const char **why)
{
    stp_rd rd;
    uint64_t need, esz;
    stp_rd_init(&rd, body, len);
    r->count = stp_get_u32(&rd);
    r->nchan = stp_get_u8(&rd);
    r->outfmt = stp_get_u8(&rd);
    r->flags = stp_get_u8(&rd);
    (void)stp_get_u8(&rd);
    r->nbad = stp_get_u32(&rd);
    r->values = r->coverage = NULL;
    r->status = NULL;
    r->raw_values = r->raw_coverage = r->raw_status = NULL;
    if (rd.bad)
        return fail(why, "SAMPLE reply: truncated", STP_S_BAD_REQUEST);
    esz = stp_outfmt_size(r->outfmt);
    if (esz == 0 || r->nchan < 1 || r->nchan > 4)
        return fail(why, "SAMPLE reply: bad outfmt or nchan", STP_S_BAD_REQUEST);
    if (r->flags & ~(STP_SF_COVERAGE | STP_SF_STATUS))
        return fail(why, "SAMPLE reply: unknown flags", STP_S_BAD_REQUEST);
    if (r->nbad > r->count)
        return fail(why, "SAMPLE reply: nbad > count", STP_S_BAD_REQUEST);
    /* the whole body's size less its 12-byte head (count < 2^32, nchan <= 4, esz <= 4: no
     * overflow) */
    need = stp_sample_reply_bytes(r->count, r->nchan, r->outfmt, r->flags) - 12;
    if (need != stp_rd_left(&rd))
        return fail(why, "SAMPLE reply: count does not match the body length", STP_S_BAD_REQUEST);
    r->raw_values = stp_rd_take(&rd, (size_t)r->count * r->nchan * esz);
    if (r->flags & STP_SF_COVERAGE)
        r->raw_coverage = stp_rd_take(&rd, (size_t)r->count * 4);
    if (r->flags & STP_SF_STATUS)
        r->raw_status = stp_rd_take(&rd, r->count);
    return finish(&rd, why, "SAMPLE reply: truncated");
}

void stp_sample_values_f32(const stp_sample_reply *r, float *out)
{
    size_t n = (size_t)r->count * r->nchan;
    const uint8_t *p = r->raw_values;
    switch (r->outfmt) {
    case STP_OUT_F32:
        for (size_t i = 0; i < n; i++)
            out[i] = stp_u2f(stp_rd32(p + 4 * i));
        break;
    case STP_OUT_UNORM8:
        for (size_t i = 0; i < n; i++)
            out[i] = p[i] * (1.0f / 255.0f);
        break;
    case STP_OUT_F16:
        stp_f16_decode(p, n, out);
        break;
    default:
        for (size_t i = 0; i < n; i++)
            out[i] = stp_rd16(p + 2 * i) * (1.0f / 65535.0f);
        break;
    }
}

int stp_sample_values_u16(const stp_sample_reply *r, uint16_t *out)
{
    size_t n = (size_t)r->count * r->nchan;
    const uint8_t *p = r->raw_values;
    if (r->outfmt == STP_OUT_UNORM8) {
        for (size_t i = 0; i < n; i++)
            out[i] = p[i];
        return 0;
    }
    if (r->outfmt == STP_OUT_UNORM16) {
        for (size_t i = 0; i < n; i++)
            out[i] = stp_rd16(p + 2 * i);
        return 0;
    }
    return -1;
}

void stp_sample_coverage(const stp_sample_reply *r, float *out)
{
    if (!r->raw_coverage)
        return;
    for (uint32_t i = 0; i < r->count; i++)
        out[i] = stp_u2f(stp_rd32(r->raw_coverage + 4 * (size_t)i));
}

/* ---- STATS -------------------------------------------------------------------------------------- */

static void get_stat(stp_rd *rd, stp_stat *s)
{
    uint64_t v;
    stp_get_str(rd, s->key, sizeof s->key);
    s->type = stp_get_u8(rd);
    v = stp_get_u64(rd);
    if (s->type == STP_STAT_F64)
        s->v.f = stp_u2d(v);
    else
        s->v.u = v;
}

int stp_enc_stats_reply(stp_buf *b, uint32_t reqid, const stp_stats_reply *r)
{
    size_t at = stp_frame_begin(b, STP_OP_STATS, STP_F_REPLY, reqid, 0, 0);
    stp_put_u32(b, r->count);
    for (uint32_t i = 0; i < r->count; i++) {
        const stp_stat *s = &r->stats[i];
        size_t n = strlen(s->key);
        if (n > STP_MAX_STAT_KEY)
            n = STP_MAX_STAT_KEY;
        stp_put_u16(b, (uint16_t)n);
        stp_put_bytes(b, s->key, n);
        stp_put_u8(b, s->type);
        stp_put_u64(b, s->type == STP_STAT_F64 ? stp_d2u(s->v.f) : s->v.u);
    }
    return stp_frame_end(b, at);
}

int stp_dec_stats_reply(const uint8_t *body, size_t len, stp_stats_reply *r, const char **why)
{
    stp_rd rd;
    stp_stat s;
    stp_rd_init(&rd, body, len);
    r->count = stp_get_u32(&rd);
    r->stats = NULL;
    r->raw = NULL;
    r->raw_len = 0;
    if (rd.bad)
        return fail(why, "STATS reply: truncated", STP_S_BAD_REQUEST);
    if ((uint64_t)r->count * 11 > stp_rd_left(&rd))
        return fail(why, "STATS reply: count larger than the body", STP_S_BAD_REQUEST);
    r->raw = rd.p + rd.off;
    r->raw_len = stp_rd_left(&rd);
    for (uint32_t i = 0; i < r->count && !rd.bad; i++) {
        get_stat(&rd, &s);
        if (!rd.bad && s.type > STP_STAT_F64)
            return fail(why, "STATS reply: unknown value type", STP_S_BAD_REQUEST);
    }
    return finish(&rd, why, "STATS reply: an entry is truncated or has a bad key");
}

int stp_stats_next(const stp_stats_reply *r, size_t *pos, stp_stat *s)
{
    stp_rd rd;
    if (!r->raw || *pos >= r->raw_len)
        return 0;
    stp_rd_init(&rd, r->raw, r->raw_len);
    rd.off = *pos;
    get_stat(&rd, s);
    if (rd.bad)
        return 0;
    *pos = rd.off;
    return 1;
}

/* ---- name / id bodies --------------------------------------------------------------------------- */

int stp_enc_name_req(stp_buf *b, uint8_t opcode, uint32_t reqid, uint32_t timeout_ms,
                     const char *name)
{
    size_t at = stp_frame_begin(b, opcode, 0, reqid, 0, timeout_ms);
    stp_put_str(b, name);
    return stp_frame_end(b, at);
}

int stp_dec_name_req(const uint8_t *body, size_t len, char name[STP_MAX_NAME + 1],
                     const char **why)
{
    stp_rd rd;
    int np;
    stp_rd_init(&rd, body, len);
    get_name(&rd, name, &np);
    int s = finish(&rd, why, "truncated body");
    return s ? s : np ? name_fail(why, SET_NAME_WHY, np) : 0;
}

int stp_put_replica_publish(stp_buf *b, const char *name, uint32_t crc32)
{
    stp_put_str(b, name);
    stp_put_u32(b, crc32);
    return b->err ? -1 : 0;
}

int stp_dec_replica_publish(const uint8_t *body, size_t len, char name[STP_MAX_NAME + 1],
                            uint32_t *crc32, const char **why)
{
    stp_rd rd;
    int np;
    stp_rd_init(&rd, body, len);
    get_name(&rd, name, &np);
    *crc32 = stp_get_u32(&rd);
    int s = finish(&rd, why, "body must be a name and a u32 crc32");
    return s ? s : np ? name_fail(why, SET_NAME_WHY, np) : 0;
}

int stp_enc_id_req(stp_buf *b, uint8_t opcode, uint32_t reqid, uint32_t timeout_ms, uint64_t id)
{
    size_t at = stp_frame_begin(b, opcode, 0, reqid, 0, timeout_ms);
    stp_put_u64(b, id);
    return stp_frame_end(b, at);
}

int stp_dec_id_req(const uint8_t *body, size_t len, uint64_t *id, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    *id = stp_get_u64(&rd);
    return finish(&rd, why, "body must be one u64 id");
}

int stp_enc_id_reply(stp_buf *b, uint8_t opcode, uint32_t reqid, uint64_t id)
{
    size_t at = stp_frame_begin(b, opcode, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, id);
    return stp_frame_end(b, at);
}

int stp_dec_id_reply(const uint8_t *body, size_t len, uint64_t *id, const char **why)
{
    return stp_dec_id_req(body, len, id, why);
}

/* ---- UPLOAD ------------------------------------------------------------------------------------- */

int stp_enc_upload_begin(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                         const stp_upload_begin *r)
{
    size_t at = stp_frame_begin(b, STP_OP_UPLOAD_BEGIN, 0, reqid, 0, timeout_ms);
    stp_put_str(b, r->name);
    stp_put_str(b, r->hint);
    stp_put_u64(b, r->total_size);
    stp_put_u32(b, r->crc32c);
    stp_put_u32(b, r->flags);
    stp_put_str(b, r->options);
    return stp_frame_end(b, at);
}

int stp_dec_upload_begin(const uint8_t *body, size_t len, stp_upload_begin *r, const char **why)
{
    stp_rd rd;
    int np;
    stp_rd_init(&rd, body, len);
    get_name(&rd, r->name, &np);
    stp_get_str(&rd, r->hint, sizeof r->hint);
    r->total_size = stp_get_u64(&rd);
    r->crc32c = stp_get_u32(&rd);
    r->flags = stp_get_u32(&rd);
    stp_get_str(&rd, r->options, sizeof r->options);
    int s = finish(&rd, why, "truncated body or bad hint / options");
    if (s)
        return s;
    if (np)
        return name_fail(why, SET_NAME_WHY, np);
    if (r->flags & ~(uint32_t)(STP_UF_REPLACE | STP_UF_RESUME | STP_UF_REPLICA | STP_UF_STAGE))
        return fail(why, "unknown flag bits", STP_S_INVALID);
    if ((r->flags & STP_UF_STAGE) && !(r->flags & STP_UF_REPLICA))
        return fail(why, "flag STAGE needs REPLICA", STP_S_INVALID);
    return 0;
}

int stp_enc_upload_begin_reply(stp_buf *b, uint32_t reqid, const stp_upload_begin_reply *r)
{
    size_t at = stp_frame_begin(b, STP_OP_UPLOAD_BEGIN, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, r->upload_id);
    stp_put_u64(b, r->received);
    stp_put_u32(b, r->max_chunk);
    return stp_frame_end(b, at);
}

int stp_dec_upload_begin_reply(const uint8_t *body, size_t len, stp_upload_begin_reply *r,
                               const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->upload_id = stp_get_u64(&rd);
    r->received = stp_get_u64(&rd);
    r->max_chunk = stp_get_u32(&rd);
    return finish(&rd, why, "UPLOAD_BEGIN reply: must be 20 bytes");
}

int stp_enc_upload_chunk(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                         const stp_upload_chunk *r)
{
    size_t at = stp_frame_begin(b, STP_OP_UPLOAD_CHUNK, 0, reqid, 0, timeout_ms);
    stp_put_u64(b, r->upload_id);
    stp_put_u64(b, r->offset);
    stp_put_u32(b, r->len);
    stp_put_bytes(b, r->data, r->len);
    return stp_frame_end(b, at);
}

int stp_dec_upload_chunk(const uint8_t *body, size_t len, stp_upload_chunk *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->upload_id = stp_get_u64(&rd);
    r->offset = stp_get_u64(&rd);
    r->len = stp_get_u32(&rd);
    r->data = NULL;
    if (rd.bad)
        return fail(why, "truncated", STP_S_BAD_REQUEST);
    if ((size_t)r->len != stp_rd_left(&rd))
        return fail(why, "len does not match the body length", STP_S_BAD_REQUEST);
    r->data = stp_rd_take(&rd, r->len);
    if (r->offset > UINT64_MAX - r->len)
        return fail(why, "offset + len overflows", STP_S_INVALID);
    return 0;
}

int stp_enc_upload_progress(stp_buf *b, uint8_t opcode, uint32_t reqid,
                            const stp_upload_progress *r)
{
    size_t at = stp_frame_begin(b, opcode, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, r->received);
    stp_put_u64(b, r->total);
    return stp_frame_end(b, at);
}

int stp_dec_upload_progress(const uint8_t *body, size_t len, stp_upload_progress *r,
                            const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->received = stp_get_u64(&rd);
    r->total = stp_get_u64(&rd);
    int s = finish(&rd, why, "upload progress: must be 16 bytes");
    if (s == 0 && r->received > r->total)
        return fail(why, "upload progress: received > total", STP_S_BAD_REQUEST);
    return s;
}

int stp_enc_upload_done(stp_buf *b, uint32_t reqid, const stp_upload_done *r)
{
    size_t at = stp_frame_begin(b, STP_OP_UPLOAD_COMMIT, STP_F_REPLY, reqid, 0, 0);
    stp_put_str(b, r->name);
    stp_put_u8(b, r->kind);
    stp_put_u8(b, r->nchan);
    stp_put_u8(b, r->dtype);
    stp_put_u8(b, 0);
    stp_put_u32(b, r->nfaces);
    stp_put_u64(b, r->memory);
    return stp_frame_end(b, at);
}

int stp_dec_upload_done(const uint8_t *body, size_t len, stp_upload_done *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    stp_get_str(&rd, r->name, sizeof r->name);
    r->kind = stp_get_u8(&rd);
    r->nchan = stp_get_u8(&rd);
    r->dtype = stp_get_u8(&rd);
    (void)stp_get_u8(&rd);
    r->nfaces = stp_get_u32(&rd);
    r->memory = stp_get_u64(&rd);
    return finish(&rd, why, "UPLOAD_COMMIT reply: truncated or bad name");
}

/* ---- COMPRESS and jobs ---------------------------------------------------------------------------- */

int stp_enc_compress_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                         const stp_compress_req *r)
{
    size_t at = stp_frame_begin(b, STP_OP_COMPRESS, 0, reqid, 0, timeout_ms);
    stp_put_str(b, r->name);
    stp_put_str(b, r->target);
    stp_put_u8(b, r->level);
    stp_put_u8(b, r->flags);
    return stp_frame_end(b, at);
}

int stp_dec_compress_req(const uint8_t *body, size_t len, stp_compress_req *r, const char **why)
{
    stp_rd rd;
    int np, tp;
    stp_rd_init(&rd, body, len);
    get_name(&rd, r->name, &np);
    get_name(&rd, r->target, &tp);
    r->level = stp_get_u8(&rd);
    r->flags = stp_get_u8(&rd);
    int s = finish(&rd, why, "truncated body");
    if (s)
        return s;
    if (np)
        return name_fail(why, SET_NAME_WHY, np);
    if (tp)
        return name_fail(why, TARGET_NAME_WHY, tp);
    if (r->level > 9)
        return fail(why, "level over 9", STP_S_INVALID);
    if (r->flags & ~(STP_CF_SEAM_AWARE | STP_CF_REPLACE))
        return fail(why, "unknown flag bits", STP_S_INVALID);
    return 0;
}

int stp_enc_job_status(stp_buf *b, uint8_t opcode, uint32_t reqid, const stp_job_status *r)
{
    size_t at = stp_frame_begin(b, opcode, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, r->job_id);
    stp_put_u8(b, r->state);
    stp_put_u8(b, 0);
    stp_put_u16(b, r->result);
    stp_put_f32(b, r->progress);
    stp_put_str(b, r->message);
    return stp_frame_end(b, at);
}

int stp_dec_job_status(const uint8_t *body, size_t len, stp_job_status *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->job_id = stp_get_u64(&rd);
    r->state = stp_get_u8(&rd);
    (void)stp_get_u8(&rd);
    r->result = stp_get_u16(&rd);
    r->progress = stp_get_f32(&rd);
    stp_get_str(&rd, r->message, sizeof r->message);
    int s = finish(&rd, why, "job status: truncated or bad message");
    if (s == 0 && r->state > STP_JOB_CANCELED)
        return fail(why, "job status: unknown state", STP_S_BAD_REQUEST);
    return s;
}

/* ---- FETCH --------------------------------------------------------------------------------------- */

int stp_enc_fetch_open(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_fetch_open *r)
{
    size_t at = stp_frame_begin(b, STP_OP_FETCH_OPEN, 0, reqid, 0, timeout_ms);
    stp_put_str(b, r->name);
    stp_put_u8(b, r->format);
    return stp_frame_end(b, at);
}

int stp_dec_fetch_open(const uint8_t *body, size_t len, stp_fetch_open *r, const char **why)
{
    stp_rd rd;
    int np;
    stp_rd_init(&rd, body, len);
    get_name(&rd, r->name, &np);
    r->format = stp_get_u8(&rd);
    int s = finish(&rd, why, "truncated body");
    if (s == 0 && np)
        return name_fail(why, SET_NAME_WHY, np);
    if (s == 0 && !stp_fetch_format_name(r->format))
        return fail(why, "unknown format", STP_S_INVALID);
    return s;
}

int stp_enc_fetch_open_reply(stp_buf *b, uint32_t reqid, const stp_fetch_open_reply *r)
{
    size_t at = stp_frame_begin(b, STP_OP_FETCH_OPEN, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, r->fetch_id);
    stp_put_u64(b, r->total_size);
    stp_put_u32(b, r->crc32c);
    stp_put_u32(b, r->max_chunk);
    return stp_frame_end(b, at);
}

int stp_dec_fetch_open_reply(const uint8_t *body, size_t len, stp_fetch_open_reply *r,
                             const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->fetch_id = stp_get_u64(&rd);
    r->total_size = stp_get_u64(&rd);
    r->crc32c = stp_get_u32(&rd);
    r->max_chunk = stp_get_u32(&rd);
    return finish(&rd, why, "FETCH_OPEN reply: must be 24 bytes");
}

int stp_enc_fetch_read(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_fetch_read *r)
{
    size_t at = stp_frame_begin(b, STP_OP_FETCH_READ, 0, reqid, 0, timeout_ms);
    stp_put_u64(b, r->fetch_id);
    stp_put_u64(b, r->offset);
    stp_put_u32(b, r->max_len);
    return stp_frame_end(b, at);
}

int stp_dec_fetch_read(const uint8_t *body, size_t len, stp_fetch_read *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->fetch_id = stp_get_u64(&rd);
    r->offset = stp_get_u64(&rd);
    r->max_len = stp_get_u32(&rd);
    return finish(&rd, why, "FETCH_READ: must be 20 bytes");
}

int stp_enc_fetch_data(stp_buf *b, uint32_t reqid, const stp_fetch_data *r)
{
    size_t at = stp_frame_begin(b, STP_OP_FETCH_READ, STP_F_REPLY, reqid, 0, 0);
    stp_put_u64(b, r->offset);
    stp_put_u32(b, r->len);
    stp_put_bytes(b, r->data, r->len);
    return stp_frame_end(b, at);
}

int stp_dec_fetch_data(const uint8_t *body, size_t len, stp_fetch_data *r, const char **why)
{
    stp_rd rd;
    stp_rd_init(&rd, body, len);
    r->offset = stp_get_u64(&rd);
    r->len = stp_get_u32(&rd);
    r->data = NULL;
    if (rd.bad)
        return fail(why, "FETCH_READ reply: truncated", STP_S_BAD_REQUEST);
    if ((size_t)r->len != stp_rd_left(&rd))
        return fail(why, "FETCH_READ reply: len does not match the body length",
                    STP_S_BAD_REQUEST);
    r->data = stp_rd_take(&rd, r->len);
    return 0;
}
