/* protocol/proto.c - frame header parsing and writing, the growable output buffer, the names
 * of opcodes, statuses and value lists.
 *
 * Owns: stp_parse_header (pure: no I/O, no allocation, no state kept between calls), stp_buf
 * and the stp_put_* writers (the one place protocol/ allocates: an stp_buf grows with
 * realloc), frame begin/end, error frames, the name <-> value functions generated from
 * proto_lists.h. Does not own: body layouts (bodies.c), CRC32C (crc32c.c), the set-name rule
 * (stp_name.h), store error codes (the daemon maps them), sockets (never).
 */
#include "proto.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

/* ---- header ---------------------------------------------------------------------------------- */

int stp_parse_header(const uint8_t *buf, size_t len, size_t max_body, stp_header *out,
                     int *reason)
{
    static const uint8_t magic[4] = { 0x53, 0x54, 0x58, 0x31 };
    int why = STP_R_NONE;
    size_t have = len < 4 ? len : 4;

    if (reason)
        *reason = STP_R_NONE;
    /* A wrong magic byte is fatal as soon as it is seen: no point waiting for the rest. */
    for (size_t i = 0; i < have; i++)
        if (buf[i] != magic[i]) {
            if (reason)
                *reason = STP_R_BAD_MAGIC;
            return STP_BAD;
        }
    if (len < STP_HEADER_SIZE)
        return STP_NEED_MORE;

    out->version    = buf[4];
    out->opcode     = buf[5];
    out->flags      = stp_rd16(buf + 6);
    out->reqid      = stp_rd32(buf + 8);
    out->status     = stp_rd16(buf + 12);
    out->body_len   = stp_rd32(buf + 16);
    out->timeout_ms = stp_rd32(buf + 20);

    if (out->version != STP_VERSION)
        why = STP_R_BAD_VERSION;
    else if ((size_t)out->body_len > max_body)
        why = STP_R_TOO_LARGE;
    if (why != STP_R_NONE) {
        if (reason)
            *reason = why;
        return STP_BAD;
    }
    return STP_OK;
}

void stp_write_header(uint8_t out[STP_HEADER_SIZE], const stp_header *h)
{
    out[0] = 0x53; out[1] = 0x54; out[2] = 0x58; out[3] = 0x31;
    out[4] = h->version;
    out[5] = h->opcode;
    stp_wr16(out + 6, h->flags);
    stp_wr32(out + 8, h->reqid);
    stp_wr16(out + 12, h->status);
    stp_wr16(out + 14, 0);
    stp_wr32(out + 16, h->body_len);
    stp_wr32(out + 20, h->timeout_ms);
}

int stp_reason_fatal(int reason)
{
    return reason == STP_R_BAD_MAGIC;
}

int stp_reason_status(int reason)
{
    switch (reason) {
    case STP_R_NONE:        return STP_S_OK;
    case STP_R_BAD_VERSION: return STP_S_BAD_VERSION;
    case STP_R_TOO_LARGE:   return STP_S_TOO_LARGE;
    default:                return STP_S_BAD_REQUEST;
    }
}

const char *stp_reason_name(int reason)
{
    switch (reason) {
    case STP_R_NONE:        return "none";
    case STP_R_BAD_MAGIC:   return "bad magic";
    case STP_R_BAD_VERSION: return "unsupported protocol version";
    case STP_R_TOO_LARGE:   return "body longer than the receiver's cap";
    default:                return "?";
    }
}

/* ---- names: every function below is generated from a list in proto_lists.h -------------- */

const char *stp_opcode_name(unsigned op)
{
    switch (op) {
#define X(NAME, lower, code, mut) case code: return #NAME;
    STP_OPCODES(X)
#undef X
    default: return NULL;
    }
}

int stp_opcode_mutating(unsigned op)
{
    switch (op) {
#define X(NAME, lower, code, mut) case code: return mut;
    STP_OPCODES(X)
#undef X
    default: return 0;
    }
}

const char *stp_status_name(unsigned status)
{
    static const char *const names[STP_S_COUNT_] = {
#define X(NAME, value, client) [value] = #NAME,
        STP_STATUSES(X)
#undef X
    };
    return status < STP_S_COUNT_ ? names[status] : "?";
}

const char *stp_qstatus_name(unsigned qstatus)
{
    switch (qstatus) {
#define X(NAME, value) case value: return #NAME;
    STP_QSTATUSES(X)
#undef X
    default: return "?";
    }
}

/* name <-> value for the lists whose entries are X(NAME, "name", value, ...). */
typedef struct named { const char *name; unsigned value; } named;

static const char *name_of(const named *t, size_t n, unsigned v)
{
    for (size_t i = 0; i < n; i++)
        if (t[i].value == v)
            return t[i].name;
    return NULL;
}

static int parse_of(const named *t, size_t n, const char *name)
{
    for (size_t i = 0; name && i < n; i++)
        if (!strcmp(t[i].name, name))
            return (int)t[i].value;
    return -1;
}

#define ROW(NAME, str, value, ...) {str, value},
static const named MODES[] = { STP_MODES(ROW) };
static const named FILTERS[] = { STP_FILTERS(ROW) };
static const named ZERO_RULES[] = { STP_ZERO_RULES(ROW) };
static const named OUTFMTS[] = { STP_OUTFMTS(ROW) };
static const named FETCH_FORMATS[] = { STP_FETCH_FORMATS(ROW) };
static const named KINDS[] = { STP_KINDS(ROW) };
static const named DTYPES[] = { STP_DTYPES(ROW) };
#undef ROW
#define N_(t) (sizeof t / sizeof t[0])

const char *stp_mode_name(unsigned mode)       { return name_of(MODES, N_(MODES), mode); }
int stp_mode_parse(const char *name)           { return parse_of(MODES, N_(MODES), name); }
const char *stp_filter_name(unsigned filter)   { return name_of(FILTERS, N_(FILTERS), filter); }
const char *stp_zero_rule_name(unsigned rule)  { return name_of(ZERO_RULES, N_(ZERO_RULES), rule); }
int stp_zero_rule_parse(const char *name)      { return parse_of(ZERO_RULES, N_(ZERO_RULES), name); }
const char *stp_outfmt_name(unsigned fmt)      { return name_of(OUTFMTS, N_(OUTFMTS), fmt); }
int stp_outfmt_parse(const char *name)         { return parse_of(OUTFMTS, N_(OUTFMTS), name); }
const char *stp_fetch_format_name(unsigned fmt)
{
    return name_of(FETCH_FORMATS, N_(FETCH_FORMATS), fmt);
}

int stp_fetch_format_parse(const char *name)
{
    char low[8];
    size_t n = name ? strlen(name) : 0;
    if (n == 0 || n >= sizeof low)
        return -1;
    for (size_t i = 0; i <= n; i++)
        low[i] = name[i] >= 'A' && name[i] <= 'Z' ? (char)(name[i] - 'A' + 'a') : name[i];
    return parse_of(FETCH_FORMATS, N_(FETCH_FORMATS), low);
}

const char *stp_kind_name(unsigned kind)       { return name_of(KINDS, N_(KINDS), kind); }
const char *stp_dtype_name(unsigned dtype)     { return name_of(DTYPES, N_(DTYPES), dtype); }

int stp_filter_parse(const char *name)
{
    int v = parse_of(FILTERS, N_(FILTERS), name);
    char buf[32];
    size_t n;
    if (v >= 0 || !name || (n = strlen(name)) >= sizeof buf)
        return v;
    /* also "ptex_bilinear" for "ptex-bilinear" */
    for (size_t i = 0; i <= n; i++)
        buf[i] = name[i] == '_' ? '-' : name[i];
    return parse_of(FILTERS, N_(FILTERS), buf);
}

size_t stp_outfmt_size(unsigned fmt)
{
    switch (fmt) {
#define X(NAME, str, value, size) case value: return size;
    STP_OUTFMTS(X)
#undef X
    default: return 0;
    }
}

/* ---- output buffer ----------------------------------------------------------------------------- */

void stp_buf_init(stp_buf *b)
{
    b->data = NULL;
    b->len = b->cap = b->start = 0;
    b->err = 0;
}

void stp_buf_free(stp_buf *b)
{
    if (!b)
        return;
    free(b->data);
    stp_buf_init(b);
}

void stp_buf_clear(stp_buf *b)
{
    b->len = b->start = 0;
    b->err = 0;
}

int stp_buf_reserve(stp_buf *b, size_t extra)
{
    size_t need, ncap;
    uint8_t *p;

    if (b->err)
        return -1;
    if (extra <= b->cap - b->len)
        return 0;
    /* Reclaim consumed space at the front before growing. */
    if (b->start) {
        memmove(b->data, b->data + b->start, b->len - b->start);
        b->len -= b->start;
        b->start = 0;
        if (extra <= b->cap - b->len)
            return 0;
    }
    if (__builtin_add_overflow(b->len, extra, &need)) {
        b->err = STP_S_NOMEM;
        return -1;
    }
    ncap = b->cap ? b->cap : 256;
    while (ncap < need) {
        if (ncap > SIZE_MAX / 2) {
            ncap = need;
            break;
        }
        ncap *= 2;
    }
    p = realloc(b->data, ncap);
    if (!p) {
        b->err = STP_S_NOMEM;
        return -1;
    }
    b->data = p;
    b->cap = ncap;
    return 0;
}

void stp_buf_consume(stp_buf *b, size_t n)
{
    size_t avail = b->len - b->start;
    if (n >= avail) {
        b->start = b->len = 0;
        return;
    }
    b->start += n;
}

void stp_put_bytes(stp_buf *b, const void *p, size_t n)
{
    if (n == 0 || stp_buf_reserve(b, n) != 0)
        return;
    memcpy(b->data + b->len, p, n);
    b->len += n;
}

void stp_put_u8(stp_buf *b, uint8_t v)
{
    if (stp_buf_reserve(b, 1) == 0)
        b->data[b->len++] = v;
}

void stp_put_u16(stp_buf *b, uint16_t v)
{
    if (stp_buf_reserve(b, 2) == 0) {
        stp_wr16(b->data + b->len, v);
        b->len += 2;
    }
}

void stp_put_u32(stp_buf *b, uint32_t v)
{
    if (stp_buf_reserve(b, 4) == 0) {
        stp_wr32(b->data + b->len, v);
        b->len += 4;
    }
}

void stp_put_u64(stp_buf *b, uint64_t v)
{
    if (stp_buf_reserve(b, 8) == 0) {
        stp_wr64(b->data + b->len, v);
        b->len += 8;
    }
}

void stp_put_f32(stp_buf *b, float v)
{
    stp_put_u32(b, stp_f2u(v));
}

void stp_put_str(stp_buf *b, const char *s)
{
    size_t n = s ? strlen(s) : 0;
    if (n > 0xffff)
        n = 0xffff;
    stp_put_u16(b, (uint16_t)n);
    stp_put_bytes(b, s, n);
}

size_t stp_frame_begin(stp_buf *b, uint8_t opcode, uint16_t flags, uint32_t reqid,
                       uint16_t status, uint32_t timeout_ms)
{
    size_t at = b->len - b->start;   /* head-relative: survives compaction */
    stp_header h = { STP_VERSION, opcode, flags, reqid, status, 0, timeout_ms };
    if (stp_buf_reserve(b, STP_HEADER_SIZE) == 0) {
        stp_write_header(b->data + b->len, &h);
        b->len += STP_HEADER_SIZE;
    }
    return at;
}

int stp_frame_end(stp_buf *b, size_t at)
{
    size_t body, pos = b->start + at;
    if (b->err) {
        int e = b->err;
        /* Drop the partial frame so the buffer still holds whole frames only. */
        if (pos <= b->len)
            b->len = pos;
        b->err = 0;
        return e;
    }
    body = b->len - pos - STP_HEADER_SIZE;
    if (body > UINT32_MAX) {
        b->len = pos;
        return STP_S_TOO_LARGE;
    }
    stp_wr32(b->data + pos + 16, (uint32_t)body);
    return 0;
}

/* ---- generic frames ------------------------------------------------------------------------ */

int stp_enc_error(stp_buf *b, uint8_t opcode, uint32_t reqid, uint16_t status, const char *msg)
{
    size_t n = msg ? strlen(msg) : 0;
    if (n > STP_MAX_MSG)
        n = STP_MAX_MSG;
    size_t at = stp_frame_begin(b, opcode, STP_F_REPLY, reqid, status, 0);
    stp_put_bytes(b, msg, n);
    return stp_frame_end(b, at);
}

int stp_enc_errorf(stp_buf *b, uint8_t opcode, uint32_t reqid, uint16_t status,
                   const char *fmt, ...)
{
    char msg[STP_MAX_MSG + 1];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return stp_enc_error(b, opcode, reqid, status, msg);
}

void stp_dec_error(const uint8_t *body, size_t len, char *msg, size_t cap)
{
    size_t n;
    if (!msg || cap == 0)
        return;
    n = len < cap - 1 ? len : cap - 1;
    for (size_t i = 0; i < n; i++)
        msg[i] = body[i] ? (char)body[i] : '?';
    msg[n] = 0;
}

int stp_enc_empty(stp_buf *b, uint8_t opcode, uint16_t flags, uint32_t reqid, uint32_t timeout_ms)
{
    size_t at = stp_frame_begin(b, opcode, flags, reqid, 0, timeout_ms);
    return stp_frame_end(b, at);
}

int stp_enc_raw(stp_buf *b, uint8_t opcode, uint16_t flags, uint32_t reqid, uint16_t status,
                uint32_t timeout_ms, const void *body, size_t len)
{
    size_t at = stp_frame_begin(b, opcode, flags, reqid, status, timeout_ms);
    stp_put_bytes(b, body, len);
    return stp_frame_end(b, at);
}

int stp_dec_empty(const uint8_t *body, size_t len, const char **why)
{
    (void)body;
    if (len != 0) {
        if (why)
            *why = "body must be empty";
        return STP_S_BAD_REQUEST;
    }
    return 0;
}

void stp_get_str(stp_rd *r, char *dst, size_t cap)
{
    uint16_t n = stp_get_u16(r);
    const uint8_t *p;
    dst[0] = 0;
    if (r->bad)
        return;
    if ((size_t)n >= cap) {
        r->bad = 1;
        return;
    }
    p = stp_rd_take(r, n);
    if (!p)
        return;
    if (memchr(p, 0, n)) {
        r->bad = r->nul = 1;
        return;
    }
    memcpy(dst, p, n);
    dst[n] = 0;
}
