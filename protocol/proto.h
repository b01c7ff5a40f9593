/* protocol/proto.h - the seamtex wire protocol, compiled into the daemon and the client alike.
 *
 * Owns: the frame header, the enums of opcodes, statuses and value lists (generated from
 * proto_lists.h, where each list is written once) with their name functions, capability bits,
 * every body layout (as typed structs with encode/decode functions), the pure incremental
 * header parser, CRC32C, and the little-endian byte helpers. PROTOCOL.md is the normative
 * description; this header and proto.c implement exactly that document.
 * Does not own: sockets, timeouts, dispatch (server/), connection state (client/), sampling
 * and store error codes (store/; nothing in protocol/ includes a header from outside it), the
 * set-name rule (stp_name.h, included here). Nothing here does I/O; the parser never
 * allocates; the only allocation is the growth of an stp_buf (realloc).
 *
 * Byte order: every multi-byte field is little-endian and is read and written byte by byte
 * (no struct is ever cast onto the wire). Floats are IEEE-754 binary32 bit patterns; NaN and
 * infinities are data as far as the protocol is concerned.
 *
 * Frames: a fixed 24-byte header (layout frozen for every protocol version, so a receiver can
 * always find the body length and skip a body it does not understand) followed by body_len
 * bytes:
 *
 *   offset size field
 *     0     4   magic "STX1" (bytes 53 54 58 31; u32 0x31585453)
 *     4     1   version (STP_VERSION)
 *     5     1   opcode (enum stp_opcode; a reply repeats the request's opcode)
 *     6     2   flags (STP_F_REPLY in replies; other bits 0 when sent, ignored when read)
 *     8     4   request id, chosen by the client, echoed in the reply
 *    12     2   status (enum stp_status; 0 in requests)
 *    14     2   reserved, 0
 *    16     4   body length in bytes
 *    20     4   timeout_ms: in requests the client's deadline hint (0 = none); 0 in replies
 *
 * Encoders append complete frames to an stp_buf (growable, caller-owned). Decoders take a body
 * (pointer + length, after the header was parsed) and fill a caller-owned struct; pointers in
 * a decoded struct point INTO the body (zero copy) and are valid as long as the body is.
 * Fixed-size strings in decoded structs are copied and NUL-terminated. Every count inside a
 * body is checked against the body length before it is trusted: a decoder never reads past
 * `len`, and a body with bytes left over after its last field is refused.
 *
 * Threading: every function is reentrant; no globals.
 */
#ifndef STP_PROTO_H
#define STP_PROTO_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "proto_lists.h"
#include "stp_name.h"

/* ---- frame header ------------------------------------------------------------------------ */

#define STP_MAGIC          0x31585453u   /* "STX1" as bytes on the wire */
#define STP_VERSION        1
#define STP_HEADER_SIZE    24
#define STP_F_REPLY        0x0001u

#define STP_DEFAULT_MAX_BODY   (64u << 20)  /* 64 MiB: a receiver's default body cap */
#define STP_DEFAULT_MAX_BATCH  (1u << 20)   /* queries per SAMPLE / SAMPLE_DIR request */
#define STP_DEFAULT_MAX_CHUNK  (4u << 20)   /* UPLOAD_CHUNK / FETCH_READ payload */
#define STP_MAX_TOKEN      255
#define STP_MAX_HINT       15    /* upload format hint ("ptx", "png", "exr", "obj", "drc") */
#define STP_MAX_OPTIONS    1023  /* upload options string */
#define STP_MAX_MSG        1023  /* error message / job message, bytes */
#define STP_MAX_STAT_KEY   63

typedef struct stp_header {
    uint8_t  version;
    uint8_t  opcode;
    uint16_t flags;
    uint32_t reqid;
    uint16_t status;
    uint32_t body_len;
    uint32_t timeout_ms;
} stp_header;

/* Results of stp_parse_header. */
enum {
    STP_NEED_MORE = 0,   /* fewer than 24 bytes so far and nothing wrong with them yet */
    STP_OK        = 1,   /* header complete and acceptable; *out filled */
    STP_BAD       = -1   /* see *reason; *out is filled whenever the 24 bytes are there */
};

/* Reasons for STP_BAD. Only STP_R_BAD_MAGIC is fatal (the stream cannot be resynchronised:
 * close it). For the others the header is well-formed: the receiver answers with
 * stp_reason_status(reason) and skips out->body_len bytes without storing them. */
enum stp_reason {
    STP_R_NONE        = 0,
    STP_R_BAD_MAGIC   = 1,   /* fatal */
    STP_R_BAD_VERSION = 2,   /* -> STP_S_BAD_VERSION, skip body */
    STP_R_TOO_LARGE   = 3    /* body_len > max_body -> STP_S_TOO_LARGE, skip body */
};

/* Pure incremental parser: looks at the first min(len, 24) bytes of buf. Detects a bad magic
 * as soon as its first wrong byte is there. No allocation, no I/O, no state. */
int stp_parse_header(const uint8_t *buf, size_t len, size_t max_body, stp_header *out,
                     int *reason);
/* Writes the 24 header bytes. */
void stp_write_header(uint8_t out[STP_HEADER_SIZE], const stp_header *h);
int stp_reason_fatal(int reason);
int stp_reason_status(int reason);          /* stp_status to answer with */
const char *stp_reason_name(int reason);

/* ---- opcodes ------------------------------------------------------------------------------ */

/* STP_OP_HELLO = 0x01, ... from STP_OPCODES (proto_lists.h). */
enum stp_opcode {
#define STP_X_(NAME, lower, code, mut) STP_OP_##NAME = code,
    STP_OPCODES(STP_X_)
#undef STP_X_
    STP_OP_MAX_ = 0xff    /* opcodes are one byte: tables indexed by opcode have 256 rows */
};

/* "HELLO", ...; NULL for an opcode this version does not define. */
const char *stp_opcode_name(unsigned op);
/* 1 when op changes the store (UPLOAD_*, DELETE, COMPRESS, JOB_CANCEL): such requests need
 * the token when the server has one. */
int stp_opcode_mutating(unsigned op);

/* ---- statuses ----------------------------------------------------------------------------- */

/* STP_S_OK = 0, STP_S_BAD_REQUEST = 1, ... from STP_STATUSES (proto_lists.h); PROTOCOL.md
 * section 3 says what each means. STP_S_COUNT_ is one past the last. */
enum stp_status {
#define STP_X_(NAME, value, client) STP_S_##NAME = value,
    STP_STATUSES(STP_X_)
#undef STP_X_
    STP_S_COUNT_
};

/* "OK", "BAD_REQUEST", ...; "?" for an unknown status. */
const char *stp_status_name(unsigned status);

/* ---- value lists: per-query statuses, modes, filters, zero rules, formats, kinds, types ----
 * Wire values from proto_lists.h. Each list has a name function (NULL for a value the list
 * does not have, except stp_qstatus_name: "?") and a parse function (-1 for an unknown name). */

enum stp_qstatus {
#define STP_X_(NAME, value) STP_Q_##NAME = value,
    STP_QSTATUSES(STP_X_)
#undef STP_X_
};
enum stp_mode {
#define STP_X_(NAME, str, value) STP_MODE_##NAME = value,
    STP_MODES(STP_X_)
#undef STP_X_
};
enum stp_filter {
#define STP_X_(NAME, str, value) STP_FILTER_##NAME = value,
    STP_FILTERS(STP_X_)
#undef STP_X_
};
enum stp_zero_rule {
#define STP_X_(NAME, str, value) STP_ZERO_##NAME = value,
    STP_ZERO_RULES(STP_X_)
#undef STP_X_
};
enum stp_outfmt {
#define STP_X_(NAME, str, value, size) STP_OUT_##NAME = value,
    STP_OUTFMTS(STP_X_)
#undef STP_X_
};
enum stp_fetch_format {
#define STP_X_(NAME, str, value) STP_FETCH_##NAME = value,
    STP_FETCH_FORMATS(STP_X_)
#undef STP_X_
};
enum stp_kind {
#define STP_X_(NAME, str, value) STP_KIND_##NAME = value,
    STP_KINDS(STP_X_)
#undef STP_X_
};
enum stp_dtype {
#define STP_X_(NAME, str, value) STP_DT_##NAME = value,
    STP_DTYPES(STP_X_)
#undef STP_X_
};

const char *stp_qstatus_name(unsigned qstatus);     /* "OK", "BAD_FACE", ...; "?" */
const char *stp_mode_name(unsigned mode);           /* "discard", "traverse", "clamp" */
int stp_mode_parse(const char *name);
/* "point", ..., "ptex-point", ...; parse also takes '_' for '-' ("ptex_bilinear"). */
const char *stp_filter_name(unsigned filter);
int stp_filter_parse(const char *name);
const char *stp_zero_rule_name(unsigned rule);      /* "nan", "clamp" */
int stp_zero_rule_parse(const char *name);
const char *stp_outfmt_name(unsigned fmt);          /* "f32", "unorm8", "unorm16" */
int stp_outfmt_parse(const char *name);
/* Bytes per value of an stp_outfmt (4, 1, 2); 0 for an unknown format. */
size_t stp_outfmt_size(unsigned fmt);
/* FETCH formats: "ptx", "dds", "exr", "png", "obj" (also their file extensions); NULL when
 * unknown. parse takes a name or an extension, any case; -1 when unknown. */
const char *stp_fetch_format_name(unsigned fmt);
int stp_fetch_format_parse(const char *name);
const char *stp_kind_name(unsigned kind);           /* "perface", "cube", "atlas", "bc1" */
const char *stp_dtype_name(unsigned dtype);         /* "u8", "u16", "half", "f32" */

/* ---- set names -----------------------------------------------------------------------------
 * The one rule for set names (PROTOCOL.md 1): 1..STP_MAX_NAME bytes, each in
 * [A-Za-z0-9._-], the first not '.'. So a name is always a plain file name: never "", "."
 * or "..", never hidden, no '/', no NUL, ASCII only. stp_name.h holds the implementation
 * (header-only, so that store/registry.c applies the same rule without linking protocol/). */

/* ---- capabilities (HELLO) ------------------------------------------------------------------- */

enum stp_caps {
    STP_CAP_PIPELINE      = 1u << 0,  /* several requests in flight on one connection */
    STP_CAP_OUT_OF_ORDER  = 1u << 1,  /* replies may come in another order than requests */
    STP_CAP_SAMPLE_DIR    = 1u << 2,
    STP_CAP_UPLOAD_RESUME = 1u << 3,  /* uploads survive a dropped connection */
    STP_CAP_COMPRESS      = 1u << 4,
    STP_CAP_FETCH         = 1u << 5,
    STP_CAP_PTEX_FILTERS  = 1u << 6,
    STP_CAP_AUTH          = 1u << 7,  /* the server has a token (mutations need it) */
    STP_CAP_COMPACT       = 1u << 8,  /* SAMPLE flags UV16 / FACE16 and outfmt f16 (4.4) */
    STP_CAP_SHM           = 1u << 9,  /* Unix connections: SHM_ATTACH and SAMPLE flag SHM (4.12) */
    STP_CAP_LERP          = 1u << 10  /* SAMPLE flag LERP, bit 5: Ptex's lerp option (4.4) */
};

/* ---- byte helpers --------------------------------------------------------------------------- */

static inline void stp_wr16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8);
}
static inline void stp_wr32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}
static inline void stp_wr64(uint8_t *p, uint64_t v)
{
    stp_wr32(p, (uint32_t)v); stp_wr32(p + 4, (uint32_t)(v >> 32));
}
static inline uint16_t stp_rd16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}
static inline uint32_t stp_rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t stp_rd64(const uint8_t *p)
{
    return (uint64_t)stp_rd32(p) | (uint64_t)stp_rd32(p + 4) << 32;
}
static inline uint32_t stp_f2u(float f)  { uint32_t u; memcpy(&u, &f, 4); return u; }
static inline float    stp_u2f(uint32_t u) { float f; memcpy(&f, &u, 4); return f; }
static inline uint64_t stp_d2u(double d) { uint64_t u; memcpy(&u, &d, 8); return u; }
static inline double   stp_u2d(uint64_t u) { double d; memcpy(&d, &u, 8); return d; }

/* ---- output buffer -------------------------------------------------------------------------- */

/* A growable byte buffer. Owned by the caller; stp_buf_free releases it. A failed growth makes
 * `err` sticky (STP_S_NOMEM); later puts do nothing and stp_frame_end reports it. */
typedef struct stp_buf {
    uint8_t *data;
    size_t   len, cap;
    size_t   start;       /* bytes already consumed from the front (see stp_buf_consume) */
    int      err;
} stp_buf;

void stp_buf_init(stp_buf *b);
void stp_buf_free(stp_buf *b);
/* Makes room for `extra` more bytes after len; 0 or -1 (err set). */
int  stp_buf_reserve(stp_buf *b, size_t extra);
/* Drops n bytes from the front (cheap: advances `start`, compacts lazily). */
void stp_buf_consume(stp_buf *b, size_t n);
static inline const uint8_t *stp_buf_head(const stp_buf *b)
{
    return b->data ? b->data + b->start : b->data;   /* no arithmetic on NULL */
}
static inline size_t stp_buf_avail(const stp_buf *b) { return b->len - b->start; }
void stp_buf_clear(stp_buf *b);

void stp_put_u8(stp_buf *b, uint8_t v);
void stp_put_u16(stp_buf *b, uint16_t v);
void stp_put_u32(stp_buf *b, uint32_t v);
void stp_put_u64(stp_buf *b, uint64_t v);
void stp_put_f32(stp_buf *b, float v);
void stp_put_bytes(stp_buf *b, const void *p, size_t n);
/* str16: u16 length + bytes (no NUL). s may be NULL (length 0); cut at 65535 bytes. */
void stp_put_str(stp_buf *b, const char *s);

/* Starts a frame: appends a header with body length 0 and returns its offset from the head
 * of b (stp_buf_head), which stays valid while the frame is written. */
size_t stp_frame_begin(stp_buf *b, uint8_t opcode, uint16_t flags, uint32_t reqid,
                       uint16_t status, uint32_t timeout_ms);
/* Patches the body length of the frame that starts at `at`; 0, or STP_S_NOMEM after a failed
 * growth, or STP_S_TOO_LARGE when the body exceeds 4 GiB - 1 (the frame is then removed). */
int stp_frame_end(stp_buf *b, size_t at);

/* ---- body reader ------------------------------------------------------------------------------ */

/* A cursor over a body. Reads past the end return 0 and set `bad`; decoders check `bad` once.
 * `nul`: bad was set by a NUL byte inside a string (a str16 holds none), not by a short body,
 * so the decoder's message can say which (STP_WHY_NUL). */
typedef struct stp_rd {
    const uint8_t *p;
    size_t len, off;
    int bad, nul;
} stp_rd;
#define STP_WHY_NUL "a string holds a NUL byte (str16 strings carry none)"

static inline void stp_rd_init(stp_rd *r, const void *p, size_t len)
{
    r->p = (const uint8_t *)p; r->len = len; r->off = 0; r->bad = 0; r->nul = 0;
}
static inline size_t stp_rd_left(const stp_rd *r) { return r->len - r->off; }
static inline const uint8_t *stp_rd_take(stp_rd *r, size_t n)
{
    if (r->bad || n > r->len - r->off) { r->bad = 1; return NULL; }
    const uint8_t *q = r->p ? r->p + r->off : r->p;   /* no arithmetic on NULL */
    r->off += n;
    return q;
}
static inline uint8_t  stp_get_u8(stp_rd *r)  { const uint8_t *q = stp_rd_take(r, 1); return q ? q[0] : 0; }
static inline uint16_t stp_get_u16(stp_rd *r) { const uint8_t *q = stp_rd_take(r, 2); return q ? stp_rd16(q) : 0; }
static inline uint32_t stp_get_u32(stp_rd *r) { const uint8_t *q = stp_rd_take(r, 4); return q ? stp_rd32(q) : 0; }
static inline uint64_t stp_get_u64(stp_rd *r) { const uint8_t *q = stp_rd_take(r, 8); return q ? stp_rd64(q) : 0; }
static inline float    stp_get_f32(stp_rd *r) { return stp_u2f(stp_get_u32(r)); }
/* Reads a str16 into dst (cap bytes including the NUL). Too long for cap, or an embedded NUL
 * byte, sets bad. */
void stp_get_str(stp_rd *r, char *dst, size_t cap);

/* ---- bodies ------------------------------------------------------------------------------------
 * Each decoder returns 0 or a status to answer with (STP_S_BAD_REQUEST for a malformed body,
 * STP_S_TOO_LARGE for a count over a cap, STP_S_INVALID for a value out of range) and, when
 * `why` is not NULL, sets *why to a constant string naming the faulty field.
 * Each encoder appends one complete frame to b and returns 0 or a status (STP_S_NOMEM,
 * STP_S_INVALID for an argument that could not be encoded). Request encoders take the request
 * id and the timeout hint; reply encoders the request id of the request they answer. */

/* Error reply (any opcode, status != OK): body = message bytes, UTF-8, no NUL, <= STP_MAX_MSG
 * (longer messages are cut). */
int stp_enc_error(stp_buf *b, uint8_t opcode, uint32_t reqid, uint16_t status, const char *msg);
int stp_enc_errorf(stp_buf *b, uint8_t opcode, uint32_t reqid, uint16_t status,
                   const char *fmt, ...) __attribute__((format(printf, 5, 6)));
/* Copies the message (cut to cap-1 bytes, NULs replaced by '?') into msg; never fails. */
void stp_dec_error(const uint8_t *body, size_t len, char *msg, size_t cap);

/* Empty-body frame (PING without payload, LIST/STATS requests with no field, replies with no
 * field). */
int stp_enc_empty(stp_buf *b, uint8_t opcode, uint16_t flags, uint32_t reqid, uint32_t timeout_ms);
/* A frame whose body is the given bytes (PING payload and its echo, raw frames in tests). */
int stp_enc_raw(stp_buf *b, uint8_t opcode, uint16_t flags, uint32_t reqid, uint16_t status,
                uint32_t timeout_ms, const void *body, size_t len);
/* A body that must be empty. */
int stp_dec_empty(const uint8_t *body, size_t len, const char **why);

/* -- HELLO -- */
typedef struct stp_hello_req {
    uint8_t  min_version, max_version;   /* versions the client speaks */
    uint32_t caps;                        /* stp_caps the client wants */
    char     token[STP_MAX_TOKEN + 1];    /* "" = none */
    char     client_name[STP_MAX_NAME + 1];
} stp_hello_req;
typedef struct stp_hello_reply {
    uint8_t  version;                     /* chosen for this connection */
    uint32_t caps;                        /* stp_caps the server offers */
    uint32_t max_body, max_batch, max_chunk;
    uint32_t max_inflight;                /* requests the server reads ahead per connection */
    uint8_t  authenticated;               /* 1 when the token was accepted */
    char     server_name[STP_MAX_NAME + 1];
} stp_hello_reply;
int stp_enc_hello_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_hello_req *r);
int stp_dec_hello_req(const uint8_t *body, size_t len, stp_hello_req *r, const char **why);
int stp_enc_hello_reply(stp_buf *b, uint32_t reqid, const stp_hello_reply *r);
int stp_dec_hello_reply(const uint8_t *body, size_t len, stp_hello_reply *r, const char **why);

/* -- LIST -- request: u32 first, u32 max (0 = as many as fit); reply: entries */
typedef struct stp_list_req {
    uint32_t first, max;
} stp_list_req;
typedef struct stp_list_entry {
    char     name[STP_MAX_NAME + 1];
    uint8_t  kind, nchan, dtype;
    uint32_t nfaces;
    uint64_t memory;
} stp_list_entry;
typedef struct stp_list_reply {
    uint32_t total;                       /* sets in the store */
    uint32_t count;                       /* entries in this reply */
    const stp_list_entry *entries;        /* encode: count entries */
    const uint8_t *raw;                   /* decode: the entries, use stp_list_next */
    size_t raw_len;
} stp_list_reply;
int stp_enc_list_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_list_req *r);
int stp_dec_list_req(const uint8_t *body, size_t len, stp_list_req *r, const char **why);
int stp_enc_list_reply(stp_buf *b, uint32_t reqid, const stp_list_reply *r);
int stp_dec_list_reply(const uint8_t *body, size_t len, stp_list_reply *r, const char **why);
/* Iterates the entries of a decoded reply (already validated): *pos starts at 0; returns 1
 * and fills e, or 0 at the end. */
int stp_list_next(const stp_list_reply *r, size_t *pos, stp_list_entry *e);

/* -- INFO -- request: set name, first face, face count (0 = no per-face records) */
typedef struct stp_info_req {
    char     name[STP_MAX_NAME + 1];
    uint32_t face_first, face_count;
} stp_info_req;
#define STP_FACE_REC_SIZE 32
typedef struct stp_face_rec {
    uint32_t w, h;
    int32_t  adjface[4];
    uint8_t  adjedge[4];
    uint8_t  flags, nlevels;
} stp_face_rec;
typedef struct stp_info_reply {
    uint32_t nfaces;
    uint8_t  nchan, dtype;
    int8_t   alpha_chan;
    uint8_t  kind, colorspace, premultiplied, border_u, border_v, meshtype;
    uint8_t  edgefilter;                  /* Ptex edge filter mode: 0 none, 1 tanvec */
    uint64_t memory;                      /* bytes held in memory by the set */
    uint64_t texel_bytes;
    uint32_t min_w, max_w, min_h, max_h;  /* level-0 resolutions over all faces */
    uint32_t nconstant, nsubfaces;
    uint32_t boundary_edges;              /* edges with no neighbour */
    uint32_t irregular_corners;           /* interior corners whose vertex valence != 4 */
    uint32_t max_valence;
    uint32_t nmeta;
    uint32_t face_first, nrec;            /* per-face records that follow */
    const stp_face_rec *faces;            /* encode: nrec records */
    const uint8_t *raw;                   /* decode: use stp_info_face */
} stp_info_reply;
int stp_enc_info_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_info_req *r);
int stp_dec_info_req(const uint8_t *body, size_t len, stp_info_req *r, const char **why);
int stp_enc_info_reply(stp_buf *b, uint32_t reqid, const stp_info_reply *r);
int stp_dec_info_reply(const uint8_t *body, size_t len, stp_info_reply *r, const char **why);
void stp_info_face(const stp_info_reply *r, uint32_t i, stp_face_rec *out);  /* i < nrec */

/* -- SAMPLE / SAMPLE_DIR -- */
enum stp_sample_flags {
    STP_SF_COVERAGE = 1,   /* reply carries one f32 coverage per query */
    STP_SF_STATUS   = 2,   /* reply carries one u8 status (stp_qstatus) per query */
    STP_SF_UV16     = 4,   /* SAMPLE request: u, v as u16 x 2^-16, derivatives as binary16 */
    STP_SF_FACE16   = 8,   /* SAMPLE request: face as u16 */
    STP_SF_SHM      = 16,  /* SAMPLE / SAMPLE_DIR request: queries and reply in the
                              connection's shared region (PROTOCOL.md 4.12; stp_shm_ref) */
    STP_SF_LERP     = 32   /* SAMPLE request: Ptex's lerp option (the gaussian and bicubic
                              family blend toward the next lower resolution); not echoed */
};
#define STP_SF_REPLY_MASK   (STP_SF_COVERAGE | STP_SF_STATUS)   /* what a reply echoes */
#define STP_SF_COMPACT_MASK (STP_SF_UV16 | STP_SF_FACE16)       /* query layout (SAMPLE) */
enum stp_footprint {
    STP_FP_DERIV = 0,      /* ddx, ddy are the direction's screen derivatives */
    STP_FP_CONE  = 1       /* ddx[0] is the full cone angle in radians; the rest must be 0 */
};
#define STP_QUERY_SIZE     28   /* u32 face, f32 u, v, dudx, dvdx, dudy, dvdy */
/* Bytes of one SAMPLE query with these request flags: 28, 26 (FACE16), 16 (UV16), 14 (both). */
static inline size_t stp_query_size(unsigned flags)
{
    return (size_t)((flags & STP_SF_FACE16) ? 2 : 4) + ((flags & STP_SF_UV16) ? 12 : 24);
}
#define STP_DIR_QUERY_SIZE 36   /* f32 dir[3], ddx[3], ddy[3] */

typedef struct stp_query {
    uint32_t face;
    float u, v, dudx, dvdx, dudy, dvdy;
} stp_query;
typedef struct stp_dir_query {
    float dir[3], ddx[3], ddy[3];
} stp_dir_query;

/* Common sampling parameters; mode, filter and zero_rule are stp_mode, stp_filter (including
 * the Ptex family 8..15) and stp_zero_rule, whose numbers are the sampler's (checked by the
 * daemon at compile time). */
typedef struct stp_sample_params {
    char     name[STP_MAX_NAME + 1];
    uint8_t  mode, filter, zero_rule, max_aniso;
    uint8_t  outfmt;                      /* stp_outfmt */
    uint8_t  flags;                       /* stp_sample_flags */
    uint8_t  footprint;                   /* SAMPLE_DIR only: stp_footprint */
    float    sharpness, width, blur;
} stp_sample_params;
/* Where a shared-memory request's queries are and where its reply goes (flag STP_SF_SHM),
 * byte offsets into the connection's region (PROTOCOL.md 4.12). */
typedef struct stp_shm_ref {
    uint64_t query_off;                   /* count * query size bytes of queries */
    uint64_t reply_off, reply_cap;        /* room for the 4.6 reply body */
} stp_shm_ref;
#define STP_SHM_REF_SIZE 24
typedef struct stp_sample_req {
    stp_sample_params p;
    uint32_t count;
    stp_shm_ref shm;                      /* with STP_SF_SHM: instead of queries in the body */
    const stp_query *queries;             /* encode: count queries (SAMPLE) */
    const stp_dir_query *dqueries;        /* encode: count queries (SAMPLE_DIR) */
    const uint8_t *raw;                   /* decode: the packed queries, use stp_sample_query
                                             / stp_sample_dir_query */
} stp_sample_req;
typedef struct stp_sample_reply {
    uint32_t count;
    uint8_t  nchan;                       /* 1..4 */
    uint8_t  outfmt, flags;
    uint32_t nbad;                        /* queries whose status is not OK */
    const float   *values;                /* encode: count * nchan floats (converted to outfmt:
                                             unorm = round(clamp(v,0,1) * max), NaN -> 0) */
    const float   *coverage;              /* encode: count floats when STP_SF_COVERAGE */
    const uint8_t *status;                /* encode: count bytes when STP_SF_STATUS */
    const uint8_t *raw_values;            /* decode: count * nchan * size(outfmt) bytes, LE */
    const uint8_t *raw_coverage;          /* decode: count * 4 bytes, LE f32, or NULL */
    const uint8_t *raw_status;            /* decode: count bytes, or NULL (points into body) */
} stp_sample_reply;

int stp_enc_sample_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_sample_req *r);
int stp_dec_sample_req(const uint8_t *body, size_t len, uint32_t max_batch, stp_sample_req *r,
                       const char **why);
int stp_enc_sample_dir_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                           const stp_sample_req *r);
int stp_dec_sample_dir_req(const uint8_t *body, size_t len, uint32_t max_batch,
                           stp_sample_req *r, const char **why);
/* The count field of a SAMPLE / SAMPLE_DIR body without decoding it (0 when the body is too
 * short to hold one): how big a batch is, for scheduling, before the decoder checks it. */
uint32_t stp_sample_peek_count(const uint8_t *body, size_t len);
/* Query i (< count) of a decoded request, whatever its layout (flags UV16 / FACE16: the
 * compact values widened exactly, PROTOCOL.md 4.4.1). NaN and infinite values are passed
 * through. */
void stp_sample_query(const stp_sample_req *r, uint32_t i, stp_query *q);
/* Queries [first, first + n) of a decoded SAMPLE request, as stp_sample_query. */
void stp_sample_queries(const stp_sample_req *r, uint32_t first, uint32_t n, stp_query *out);
/* The same queries in the f32 layout of 4.4 (28 bytes each: u32 face, 6 x f32, little-endian)
 * at out, any alignment: the form the daemon samples (the store's query layout on a
 * little-endian host), without a copy through stp_query. */
void stp_sample_queries_f32(const stp_sample_req *r, uint32_t first, uint32_t n, uint8_t *out);
/* The compact forms of PROTOCOL.md 4.4.1, encode and decode, exact: */
uint16_t stp_f32_to_f16(float f);       /* binary16, round to nearest even; NaN -> 0x7E00|sign */
float    stp_f16_to_f32(uint16_t h);    /* exact widening (NaN payload kept) */
void     stp_f16_encode(const float *v, size_t n, uint8_t *out);  /* n values, LE binary16 */
void     stp_f16_decode(const uint8_t *p, size_t n, float *out);  /* n LE binary16, widened */
uint16_t stp_f32_to_unit16(float u);    /* nearest integer to u x 65536, ties to even, clamped
                                           to 0..65535; NaN -> 0 */
static inline float stp_unit16_to_f32(uint16_t q) { return (float)q * (1.0f / 65536.0f); }
/* The query a compact encoding delivers for q (what the server samples): q rounded through
 * the layout of `flags` and widened again; face & 0xFFFF with FACE16. */
void stp_query_round(const stp_query *q, unsigned flags, stp_query *out);
void stp_sample_dir_query(const stp_sample_req *r, uint32_t i, stp_dir_query *q);
/* The same reply layout serves SAMPLE and SAMPLE_DIR (pass the opcode). */
int stp_enc_sample_reply(stp_buf *b, uint8_t opcode, uint32_t reqid, const stp_sample_reply *r);
/* n values in outfmt's wire form (4.6: f32, unorm8, unorm16, f16; little-endian) at dst, which
 * holds n x stp_outfmt_size(outfmt) bytes; outfmt must be one of the four. The encoder of the
 * reply's values and coverage (coverage: STP_OUT_F32), for a reply built in place. */
void stp_enc_sample_values(uint8_t *dst, const float *v, size_t n, uint8_t outfmt);
int stp_dec_sample_reply(const uint8_t *body, size_t len, stp_sample_reply *r, const char **why);
/* Converts the values of a decoded reply: to floats (unorm / max, f16 widened exactly) or
 * to the raw unsigned integers (for unorm formats; f32 and f16 replies refuse with -1). out
 * holds count * nchan. */
void stp_sample_values_f32(const stp_sample_reply *r, float *out);
int  stp_sample_values_u16(const stp_sample_reply *r, uint16_t *out);
void stp_sample_coverage(const stp_sample_reply *r, float *out);   /* needs raw_coverage */

/* -- STATS -- request: empty; reply: key/value list */
enum { STP_STAT_U64 = 0, STP_STAT_F64 = 1 };
typedef struct stp_stat {
    char    key[STP_MAX_STAT_KEY + 1];
    uint8_t type;
    union { uint64_t u; double f; } v;
} stp_stat;
typedef struct stp_stats_reply {
    uint32_t count;
    const stp_stat *stats;                /* encode */
    const uint8_t *raw;                   /* decode: use stp_stats_next */
    size_t raw_len;
} stp_stats_reply;
int stp_enc_stats_reply(stp_buf *b, uint32_t reqid, const stp_stats_reply *r);
int stp_dec_stats_reply(const uint8_t *body, size_t len, stp_stats_reply *r, const char **why);
int stp_stats_next(const stp_stats_reply *r, size_t *pos, stp_stat *s);

/* -- requests whose body is one name (DELETE) or one u64 id (UPLOAD_COMMIT / ABORT / STATUS,
 *    JOB_STATUS, JOB_CANCEL, FETCH_CLOSE) -- */
int stp_enc_name_req(stp_buf *b, uint8_t opcode, uint32_t reqid, uint32_t timeout_ms,
                     const char *name);
int stp_dec_name_req(const uint8_t *body, size_t len, char name[STP_MAX_NAME + 1],
                     const char **why);
int stp_enc_id_req(stp_buf *b, uint8_t opcode, uint32_t reqid, uint32_t timeout_ms, uint64_t id);
/* REPLICA_PUBLISH (4.11): the set's name and the CRC-32 (zlib) of the staged source. The body
 * alone (no frame) for stc_append_raw; the decoder checks the name rule. */
int stp_put_replica_publish(stp_buf *b, const char *name, uint32_t crc32);
int stp_dec_replica_publish(const uint8_t *body, size_t len, char name[STP_MAX_NAME + 1],
                            uint32_t *crc32, const char **why);
int stp_dec_id_req(const uint8_t *body, size_t len, uint64_t *id, const char **why);

/* -- UPLOAD -- */
enum stp_upload_flags {
    STP_UF_REPLACE = 1,   /* replace an existing set of that name on commit */
    STP_UF_RESUME  = 2,   /* reattach to an unfinished upload of the same name, size and crc */
    STP_UF_REPLICA = 4,   /* node-to-node copy inside a cluster (docs/cluster.md): REPLACE
                             implied, no catalogue claim, no further copies */
    STP_UF_STAGE   = 8    /* with REPLICA: the copy of a write not recorded yet; the receiver
                             stages it at COMMIT (not published) until REPLICA_PUBLISH or its
                             repair pass finds the write recorded */
};
typedef struct stp_upload_begin {
    char     name[STP_MAX_NAME + 1];      /* the set to create */
    char     hint[STP_MAX_HINT + 1];      /* file type: "ptx", "png", "exr", "obj", "drc"...,
                                             "" = detect from contents */
    uint64_t total_size;                  /* bytes the file has */
    uint32_t crc32c;                      /* of the whole file (stp_crc32c) */
    uint32_t flags;                       /* stp_upload_flags */
    char     options[STP_MAX_OPTIONS + 1];/* "key=value key=value": texture=<set>,
                                             cube=latlong:512, ... */
} stp_upload_begin;
typedef struct stp_upload_begin_reply {
    uint64_t upload_id;
    uint64_t received;                    /* bytes the server already has (resume), else 0 */
    uint32_t max_chunk;
} stp_upload_begin_reply;
typedef struct stp_upload_chunk {
    uint64_t upload_id, offset;
    uint32_t len;
    const uint8_t *data;                  /* encode: len bytes; decode: points into the body */
} stp_upload_chunk;
/* UPLOAD_CHUNK reply and UPLOAD_STATUS reply: u64 received, u64 total */
typedef struct stp_upload_progress {
    uint64_t received, total;
} stp_upload_progress;
/* UPLOAD_COMMIT reply: what was created */
typedef struct stp_upload_done {
    char     name[STP_MAX_NAME + 1];
    uint8_t  kind, nchan, dtype;
    uint32_t nfaces;
    uint64_t memory;
} stp_upload_done;
int stp_enc_upload_begin(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                         const stp_upload_begin *r);
int stp_dec_upload_begin(const uint8_t *body, size_t len, stp_upload_begin *r, const char **why);
int stp_enc_upload_begin_reply(stp_buf *b, uint32_t reqid, const stp_upload_begin_reply *r);
int stp_dec_upload_begin_reply(const uint8_t *body, size_t len, stp_upload_begin_reply *r,
                               const char **why);
int stp_enc_upload_chunk(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                         const stp_upload_chunk *r);
int stp_dec_upload_chunk(const uint8_t *body, size_t len, stp_upload_chunk *r, const char **why);
int stp_enc_upload_progress(stp_buf *b, uint8_t opcode, uint32_t reqid,
                            const stp_upload_progress *r);
int stp_dec_upload_progress(const uint8_t *body, size_t len, stp_upload_progress *r,
                            const char **why);
int stp_enc_upload_done(stp_buf *b, uint32_t reqid, const stp_upload_done *r);
int stp_dec_upload_done(const uint8_t *body, size_t len, stp_upload_done *r, const char **why);

/* -- COMPRESS and jobs -- */
enum stp_compress_flags { STP_CF_SEAM_AWARE = 1, STP_CF_REPLACE = 2 };
typedef struct stp_compress_req {
    char    name[STP_MAX_NAME + 1];       /* source set */
    char    target[STP_MAX_NAME + 1];     /* set to create */
    uint8_t level;                        /* 0 fastest .. 9 best */
    uint8_t flags;                        /* stp_compress_flags */
} stp_compress_req;
enum stp_job_state {
    STP_JOB_QUEUED = 0, STP_JOB_RUNNING = 1, STP_JOB_DONE = 2, STP_JOB_FAILED = 3,
    STP_JOB_CANCELED = 4
};
/* COMPRESS reply: u64 job id (stp_enc_id_reply). JOB_STATUS and JOB_CANCEL replies: */
typedef struct stp_job_status {
    uint64_t job_id;
    uint8_t  state;                       /* stp_job_state */
    float    progress;                    /* 0..1 */
    uint16_t result;                      /* stp_status of a finished job */
    char     message[STP_MAX_MSG + 1];
} stp_job_status;
int stp_enc_compress_req(stp_buf *b, uint32_t reqid, uint32_t timeout_ms,
                         const stp_compress_req *r);
int stp_dec_compress_req(const uint8_t *body, size_t len, stp_compress_req *r, const char **why);
int stp_enc_id_reply(stp_buf *b, uint8_t opcode, uint32_t reqid, uint64_t id);
int stp_dec_id_reply(const uint8_t *body, size_t len, uint64_t *id, const char **why);
int stp_enc_job_status(stp_buf *b, uint8_t opcode, uint32_t reqid, const stp_job_status *r);
int stp_dec_job_status(const uint8_t *body, size_t len, stp_job_status *r, const char **why);

/* -- FETCH (download a set as a file) -- */
typedef struct stp_fetch_open {
    char    name[STP_MAX_NAME + 1];
    uint8_t format;                       /* stp_fetch_format */
} stp_fetch_open;
typedef struct stp_fetch_open_reply {
    uint64_t fetch_id;
    uint64_t total_size;
    uint32_t crc32c;                      /* of the whole file */
    uint32_t max_chunk;
} stp_fetch_open_reply;
typedef struct stp_fetch_read {
    uint64_t fetch_id, offset;
    uint32_t max_len;
} stp_fetch_read;
typedef struct stp_fetch_data {
    uint64_t offset;
    uint32_t len;
    const uint8_t *data;                  /* encode: len bytes; decode: into the body */
} stp_fetch_data;
int stp_enc_fetch_open(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_fetch_open *r);
int stp_dec_fetch_open(const uint8_t *body, size_t len, stp_fetch_open *r, const char **why);
int stp_enc_fetch_open_reply(stp_buf *b, uint32_t reqid, const stp_fetch_open_reply *r);
int stp_dec_fetch_open_reply(const uint8_t *body, size_t len, stp_fetch_open_reply *r,
                             const char **why);
int stp_enc_fetch_read(stp_buf *b, uint32_t reqid, uint32_t timeout_ms, const stp_fetch_read *r);
int stp_dec_fetch_read(const uint8_t *body, size_t len, stp_fetch_read *r, const char **why);
int stp_enc_fetch_data(stp_buf *b, uint32_t reqid, const stp_fetch_data *r);
int stp_dec_fetch_data(const uint8_t *body, size_t len, stp_fetch_data *r, const char **why);

/* -- shared-memory sampling (PROTOCOL.md 4.12; protocol/shm.c) --
 * SHM_ATTACH request: u64 region size (stp_enc_id_req / stp_dec_id_req), the memfd passed as
 * SCM_RIGHTS ancillary data with the frame's first byte; OK reply: u64 region size
 * (stp_enc_id_reply). A SAMPLE / SAMPLE_DIR request with STP_SF_SHM carries an stp_shm_ref
 * instead of its queries (stp_enc_sample_req / _dir_req write it, the decoders fill r->shm
 * and leave r->raw NULL); its OK reply is an stp_shm_reply. */
typedef struct stp_shm_reply {
    uint64_t offset;                      /* where the 4.6 reply body starts in the region */
    uint64_t length;                      /* its bytes */
} stp_shm_reply;
#define STP_SHM_REPLY_SIZE 16
int stp_enc_shm_reply(stp_buf *b, uint8_t opcode, uint32_t reqid, const stp_shm_reply *r);
int stp_dec_shm_reply(const uint8_t *body, size_t len, stp_shm_reply *r, const char **why);
/* 1 when [off, off + len) lies inside a region of `size` bytes (no overflow possible). */
static inline int stp_shm_range_ok(uint64_t size, uint64_t off, uint64_t len)
{
    return off <= size && len <= size - off;
}
/* Writes the count queries of r (r->queries for SAMPLE in the layout of r->p.flags,
 * r->dqueries for SAMPLE_DIR) to out, stp_sample_query_bytes of them: what the frame encoders
 * put in a body, for a client that puts them into its region instead. */
void stp_put_queries(uint8_t opcode, const stp_sample_req *r, uint8_t *out);
/* Bytes of the queries of a request: count x (28, 26, 16 or 14 by the flags; 36 for
 * SAMPLE_DIR). */
uint64_t stp_sample_query_bytes(uint8_t opcode, uint8_t flags, uint32_t count);
/* Bytes of the 4.6 reply body for count queries of nchan channels (nchan 4 = the most any
 * set has) in outfmt, with the reply flags of `flags`; 0 for an unknown outfmt. */
uint64_t stp_sample_reply_bytes(uint32_t count, unsigned nchan, uint8_t outfmt, uint8_t flags);

/* ---- CRC32C (Castagnoli, reflected, init and final xor 0xFFFFFFFF) ----------------------------
 * Incremental: crc = stp_crc32c(0, a, n); crc = stp_crc32c(crc, b, m). crc32c("123456789") is
 * 0xE3069283. Uses the SSE4.2 instruction when the CPU has it. */
uint32_t stp_crc32c(uint32_t crc, const void *p, size_t n);

#endif
