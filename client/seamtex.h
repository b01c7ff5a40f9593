/* client/seamtex.h - libseamtex, the client library of the seamtex texture service.
 *
 * Owns: connections to seamtexd, blocking calls for every request of the protocol, a
 * pipelined append / flush / get-reply API, timeouts, error reporting.
 * Does not own: the wire format (protocol/proto.h, PROTOCOL.md), printing, process exit: the
 * library never prints and never exits; every failure is a return code plus a message.
 *
 * Self-contained: this header needs only <stddef.h> and <stdint.h>. Link with -lseamtex
 * (pkg-config seamtex), which needs libseamtex_proto.a's objects (bundled into libseamtex.a).
 *
 * THREADING: a connection is used by one thread at a time (one connection per thread, or
 * your own lock around it). Different connections are independent; the library has no
 * global state. Writes use MSG_NOSIGNAL, so a closed peer never raises SIGPIPE.
 * FORK: a connection belongs to the process that opened it. In a child after fork(2) every
 * call on an inherited connection returns STC_ESTATE (the socket, the shared-memory region
 * and the request ids would be shared with the parent: replies could go to the wrong
 * process); stc_close on the child's copy is allowed and leaves the parent's connection alone.
 *
 * OWNERSHIP: stc_connect returns a connection the caller frees with stc_close (NULL accepted).
 * Everything a call hands back through a pointer into the library (lists, stats, sample
 * results, replies, info face records, stc_errmsg) is OWNED BY THE CONNECTION and valid until
 * the next call on that connection (any stc_* call taking it, except stc_errmsg, stc_error,
 * stc_server_info, stc_pending and the stc_reply_* decoders, which may be applied to the reply
 * stc_get_reply just returned). Copy what you keep. Buffers the caller passes in stay the
 * caller's; the library does not keep pointers to them after the call returns.
 *
 * ERRORS: functions return 0 (STC_OK) or a negative code:
 *   - local codes STC_EINVAL .. STC_EINTERRUPTED;
 *   - server statuses, -(STC_SERVER_BASE + status), e.g. STC_ENOTFOUND: the server refused
 *     this request; the connection stays usable; stc_errmsg gives the server's message.
 * A broken connection (I/O error, peer closed, protocol violation, out of memory while
 * reading, a server-initiated BUSY / SHUTDOWN) is STICKY: that error is returned by every
 * later call (stc_error tells it); close the connection and open a new one.
 * A timeout (STC_ETIMEDOUT) is NOT sticky: the request stays outstanding, its late reply is
 * recognised by its request id and discarded, and the connection can be used at once.
 * An interrupt (STC_EINTERRUPTED: the hook of stc_set_interrupt said stop) is handled exactly
 * as a timeout is, with no deadline needed (Ctrl-C for a caller without a timeout).
 */
#ifndef SEAMTEX_H
#define SEAMTEX_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define STC_SERVER_BASE 100

/* The local codes, written once: X(NAME, value) gives STC_<NAME> below and its name in
 * stc_strerror ("EINVAL"). */
#define STC_LOCAL_ERRORS(X)                                                               \
    X(EINVAL,    -1)   /* a bad argument (NULL, a name that is not valid, n too big) */    \
    X(ENOMEM,    -2)                                                                     \
    X(ECONNECT,  -3)   /* name resolution or connect() failed */                         \
    X(EIO,       -4)   /* send/recv failed (sticky) */                                   \
    X(ECLOSED,   -5)   /* the server closed the connection (sticky) */                   \
    X(EPROTO,    -6)   /* the server broke the protocol (sticky) */                      \
    X(ETIMEDOUT, -7)   /* a connect or request timeout (not sticky) */                   \
    X(EFILE,     -8)   /* a local file could not be read or written */                   \
    X(ECHECKSUM, -9)   /* downloaded data did not match its checksum */                  \
    X(ESTATE,    -10)  /* a call that is not allowed now (e.g. a blocking call while     \
                          pipelined replies are unread, get_reply with nothing pending) */ \
    X(ECANCELED, -11)  /* an upload/fetch progress callback asked to stop */             \
    X(EINTERRUPTED, -12) /* the interrupt hook (stc_set_interrupt) asked to stop a wait    \
                          (not sticky: as ETIMEDOUT, the request is abandoned) */

enum stc_err {
    STC_OK        = 0,
#define STC_X_(NAME, value) STC_##NAME = value,
    STC_LOCAL_ERRORS(STC_X_)
#undef STC_X_
    /* server statuses (protocol/proto.h enum stp_status), negated and offset; written out
     * here so that this header stands alone, checked against protocol/proto_lists.h
     * STP_STATUSES at compile time (client/libconn.c) */
    STC_EBADREQUEST    = -(STC_SERVER_BASE + 1),
    STC_EUNKNOWNOP     = -(STC_SERVER_BASE + 2),
    STC_EBADVERSION    = -(STC_SERVER_BASE + 3),
    STC_ETOOLARGE      = -(STC_SERVER_BASE + 4),
    STC_ENOTFOUND      = -(STC_SERVER_BASE + 5),
    STC_EEXISTS        = -(STC_SERVER_BASE + 6),
    STC_EUNSUPPORTED   = -(STC_SERVER_BASE + 7),
    STC_EPERM          = -(STC_SERVER_BASE + 8),
    STC_EBUSY          = -(STC_SERVER_BASE + 9),
    STC_ESERVERTIMEOUT = -(STC_SERVER_BASE + 10),
    STC_EINTERNAL      = -(STC_SERVER_BASE + 11),
    STC_ECORRUPT       = -(STC_SERVER_BASE + 12),
    STC_EINVALID       = -(STC_SERVER_BASE + 13),
    STC_EFORMAT        = -(STC_SERVER_BASE + 14),
    STC_ESERVERNOMEM   = -(STC_SERVER_BASE + 15),
    STC_ESERVERIO      = -(STC_SERVER_BASE + 16),
    STC_ESERVERCANCELED= -(STC_SERVER_BASE + 17),
    STC_EADJ           = -(STC_SERVER_BASE + 18),
    STC_ENOUV          = -(STC_SERVER_BASE + 19),
    STC_ESHUTDOWN      = -(STC_SERVER_BASE + 20),
    STC_EMOVED         = -(STC_SERVER_BASE + 21),   /* cluster: ask the node in the message */
    STC_EUNAVAILABLE   = -(STC_SERVER_BASE + 22)    /* cluster: etcd unreachable or write
                                                       quorum not reached; retry later */
};

/* 1 when code is a server status (the connection is fine); its stp_status number. */
static inline int stc_is_server_error(int code) { return code <= -STC_SERVER_BASE; }
static inline int stc_server_status(int code) { return code <= -STC_SERVER_BASE ? -code - STC_SERVER_BASE : 0; }
/* Stable short name of a code: "OK", "EIO", "NOT_FOUND", ...; "?" for any code that is
 * none of these (local or server range alike). */
const char *stc_strerror(int code);

typedef struct stc_conn stc_conn;

/* The interrupt hook (stc_set_interrupt, stc_opts.interrupt): fn(user) is called on the
 * calling thread while a call waits for the server (a connect, a reply, room to send, a
 * transfer's next chunk, stc_job_wait's pause between polls): when a signal interrupts the
 * wait (poll(2) or nanosleep(2) fails with EINTR) and, when every_ms > 0, after every every_ms
 * of waiting. It is never called while data flows without waiting, so a call that does not
 * wait costs nothing more. Returning non-zero stops the call: it returns STC_EINTERRUPTED,
 * which is NOT sticky and leaves the connection as STC_ETIMEDOUT does (the request abandoned,
 * its late reply recognised by its request id and dropped; an upload or fetch sends
 * UPLOAD_ABORT / FETCH_CLOSE without waiting for its reply; a connect or HELLO that is
 * interrupted closes the connection, as a connect timeout does). A call the hook stopped
 * never returns 0: it returns STC_EINTERRUPTED (or the sticky error of a connection that
 * broke meanwhile), even when it would have finished otherwise.
 * The hook must not call stc_* on the same connection. (Name resolution, getaddrinfo(3) of a
 * host name, cannot be interrupted.) */
typedef int (*stc_interrupt_fn)(void *user);

/* ---- connecting ----------------------------------------------------------------------------- */

typedef struct stc_opts {
    int         connect_timeout_ms;   /* 0 = 5000; < 0 = wait as long as the OS does */
    int         request_timeout_ms;   /* default per-request timeout; 0 = none */
    const char *token;                /* sent in HELLO; needed for mutating requests when the
                                         server has one; NULL = none */
    const char *client_name;          /* informational, NULL = "libseamtex" */
    int         no_hello;             /* 1: skip the HELLO exchange (protocol v1 defaults) */
    uint32_t    max_body;             /* cap on reply bodies the client accepts; 0 = 256 MiB */
    stc_interrupt_fn interrupt;       /* the interrupt hook for connecting and HELLO, then the
                                         connection's (stc_set_interrupt); NULL = none */
    void       *interrupt_user;
    int         interrupt_every_ms;
} stc_opts;

/* Connects (TCP; host is a name or address, IPv4 or IPv6; or a Unix socket: host
 * "unix:/path", port ignored), then sends HELLO unless opts->no_hello. opts may be NULL (defaults). On failure returns NULL, stores the code in
 * *err and a message in errmsg (errmsg_len bytes, may be NULL / 0). A connect timeout (the
 * connect or the wait for HELLO's reply) is STC_ETIMEDOUT; the connection is closed, so no late
 * reply is waited for. */
stc_conn *stc_connect_opts(const char *host, unsigned port, const stc_opts *opts, int *err,
                           char *errmsg, size_t errmsg_len);
/* Shorthand: defaults except the connect timeout. */
stc_conn *stc_connect(const char *host, unsigned port, int timeout_ms, int *err);
void stc_close(stc_conn *c);

/* The message of the last failed call on c ("" after a success); owned by c. */
const char *stc_errmsg(const stc_conn *c);
/* The sticky error of c (0 while the connection is healthy). */
int stc_error(const stc_conn *c);
/* Per-request timeout for later calls; 0 (or negative) = none. */
void stc_set_timeout(stc_conn *c, int timeout_ms);
/* Sets (fn NULL: removes) the interrupt hook of c (stc_interrupt_fn above); every_ms <= 0:
 * called only when a signal interrupts a wait. */
void stc_set_interrupt(stc_conn *c, stc_interrupt_fn fn, void *user, int every_ms);

/* Capability bits of stc_server.caps (PROTOCOL.md 4.1). */
enum {
    STC_CAP_PIPELINE      = 1u << 0,
    STC_CAP_OUT_OF_ORDER  = 1u << 1,   /* replies may come in another order than requests */
    STC_CAP_SAMPLE_DIR    = 1u << 2,
    STC_CAP_UPLOAD_RESUME = 1u << 3,
    STC_CAP_COMPRESS      = 1u << 4,
    STC_CAP_FETCH         = 1u << 5,
    STC_CAP_PTEX_FILTERS  = 1u << 6,
    STC_CAP_AUTH          = 1u << 7,   /* the server has a token: mutations need it */
    STC_CAP_COMPACT       = 1u << 8,   /* compact SAMPLE queries, f16 replies */
    STC_CAP_SHM           = 1u << 9,   /* shared-memory sampling (stc_shm_attach) */
    STC_CAP_LERP          = 1u << 10   /* STC_WANT_LERP (Ptex's lerp option) */
};
typedef struct stc_server {
    unsigned version;                 /* protocol version in use */
    uint32_t caps;                    /* STC_CAP_* bits */
    uint32_t max_body, max_batch, max_chunk, max_inflight;
    int      authenticated;
    char     name[256];
} stc_server;
/* What HELLO told (protocol defaults when no_hello). Owned by c. */
const stc_server *stc_server_info(const stc_conn *c);

/* Shared-memory sampling (PROTOCOL.md 4.12) on a connection to "unix:/path" whose server
 * offers STC_CAP_SHM: creates a memfd of `bytes` (0 = 64 MiB) sealed against shrinking and
 * growing, maps it and attaches it to c (SHM_ATTACH, the descriptor passed over the socket).
 * From then on stc_sample, stc_sample_dir, stc_append_sample and stc_append_sample_dir write
 * each request's queries into the region, the server samples them in place and writes the
 * reply into a room of its own beside them, and results are read where they lie (values and
 * coverage point into the region, except f16 and unaligned ones, which are copied; valid
 * until the next call on c, as every result); only small frames cross the socket. Results
 * are bit for bit those of the socket path. A request whose queries plus reply (counted with
 * 4 channels) do not fit in the free part of the region goes over the socket as before. Returns 0; STC_EINVAL on a TCP connection; STC_EUNSUPPORTED when
 * the server does not offer it; STC_ESTATE when a region is attached already or pipelined
 * replies are unread; a server error (TOO_LARGE: over its shm-max) or STC_ENOMEM otherwise.
 * The region belongs to c and is unmapped by stc_close. */
int stc_shm_attach(stc_conn *c, size_t bytes);
/* The bytes one request of n queries (dir 0: SAMPLE, 1: SAMPLE_DIR; any layout) with replies
 * in outfmt (enum stc_outfmt) takes in the region: its queries and its reply room, each rounded
 * up to the region's span alignment. A region of k times this holds k such requests at once
 * (one more than the requests in flight, for the reply last read in place). 0 when n is 0 or
 * over 2^32 - 1, or outfmt is not an STC_OUT_* value. */
size_t stc_shm_request_bytes(int dir, size_t n, unsigned outfmt);
/* Requests sent through the region and over the socket since the connection opened. */
void stc_shm_counts(const stc_conn *c, uint64_t *via_shm, uint64_t *via_socket);


/* ---- blocking calls -------------------------------------------------------------------------
 * Each sends one request and waits for its reply (per-request timeout). They return
 * STC_ESTATE while pipelined requests are outstanding (read their replies first). */

int stc_ping(stc_conn *c);

typedef struct stc_set_entry {
    const char *name;
    unsigned    kind, nchan, dtype;   /* set kind (0 perface, 1 cube, 2 atlas, 3 bc1), channel
                                         count, texel type (0 u8, 1 u16, 2 half, 3 f32) */
    uint32_t    nfaces;
    uint64_t    memory;
} stc_set_entry;
/* All sets (pages through LIST as needed). *sets (n entries) is owned by c. */
int stc_list(stc_conn *c, const stc_set_entry **sets, size_t *n);

typedef struct stc_face {
    uint32_t w, h;
    int32_t  adjface[4];
    uint8_t  adjedge[4];
    uint8_t  flags, nlevels;
} stc_face;
typedef struct stc_info {
    uint32_t nfaces;
    unsigned nchan, dtype, kind, colorspace, premultiplied, border_u, border_v, meshtype;
    int      alpha_chan;
    unsigned edgefilter;              /* Ptex edge filter mode: 0 none, 1 tanvec */
    uint64_t memory, texel_bytes;
    uint32_t min_w, max_w, min_h, max_h;
    uint32_t nconstant, nsubfaces, boundary_edges, irregular_corners, max_valence, nmeta;
    uint32_t face_first, nrec;        /* per-face records asked for */
    const stc_face *faces;            /* nrec records, owned by c */
} stc_info;
/* Facts about one set; face_count > 0 also asks for per-face records from face_first: those
 * that exist, at most face_count and at most 2^20 a call (the server's cap), out->nrec of them. */
int stc_info_get(stc_conn *c, const char *set, uint32_t face_first, uint32_t face_count,
                 stc_info *out);

/* Sampling. mode / filter / zero_rule use the protocol's numbering (PROTOCOL.md 4.4,
 * protocol/proto_lists.h): mode 0 discard, 1 traverse, 2 clamp; filter 0 point, 1 bilinear,
 * 2 trilinear, 3 aniso, 8..15 Ptex family; zero_rule 0 nan, 1 clamp. */
enum { STC_OUT_F32 = 0, STC_OUT_UNORM8 = 1, STC_OUT_UNORM16 = 2,
       STC_OUT_F16 = 3 };             /* f16: half the bytes on the wire; delivered as float */
/* COVERAGE, STATUS: ask for them in the result. UV16, FACE16 (stc_sample only; servers whose
 * HELLO offers STP_CAP_COMPACT, bit 8): send the queries compact, PROTOCOL.md 4.4.1: u, v
 * rounded to multiples of 2^-16 in [0, 1 - 2^-16], derivatives to binary16; faces as u16
 * (face & 0xFFFF: only for sets of at most 65536 faces). The server samples the rounded
 * queries, exactly as if they had been sent as f32. */
enum { STC_WANT_COVERAGE = 1, STC_WANT_STATUS = 2, STC_WANT_UV16 = 4, STC_WANT_FACE16 = 8 };
/* LERP (stc_sample only; in want, although no part of the result: the SAMPLE flag bit 5):
 * Ptex's lerp filter option, the gaussian and bicubic-family kernels blended toward the next
 * lower resolution as PtexFilter::Options::lerp does; other filters ignore it. A server
 * whose caps lack STC_CAP_LERP answers INVALID (bit 5 is reserved there). */
enum { STC_WANT_LERP = 32 };
typedef struct stc_sample_opts {
    unsigned mode, filter, zero_rule, max_aniso;
    unsigned outfmt;                  /* STC_OUT_* */
    unsigned want;                    /* STC_WANT_* */
    unsigned footprint;               /* direction sampling: 0 derivatives, 1 cone */
    float    sharpness, width, blur;
} stc_sample_opts;
typedef struct stc_query {            /* PROTOCOL.md 4.4: face, point and footprint */
    uint32_t face;
    float u, v, dudx, dvdx, dudy, dvdy;
} stc_query;
typedef struct stc_dir_query {        /* direction sampling of cube maps */
    float dir[3], ddx[3], ddy[3];     /* cone: ddx[0] = full angle in radians, rest 0 */
} stc_dir_query;
typedef struct stc_sample_result {
    uint32_t count;
    unsigned nchan, outfmt;
    uint32_t nbad;                    /* queries whose status is not OK */
    const void    *values;            /* count*nchan of float (F32, F16) / uint8_t /
                                         uint16_t (outfmt), native byte order, owned by c */
    const float   *coverage;          /* count, or NULL when not asked for */
    const uint8_t *status;            /* count per-query status bytes (PROTOCOL.md 4.6: 0 OK,
                                         1 BAD_FACE, 2 NONFINITE, 3 BAD_FOOTPRINT,
                                         4 ZERO_COVERAGE), or NULL when not asked for */
} stc_sample_result;
/* A batch over the server's max_batch is split into pipelined parts and reassembled, so n is
 * not limited by the server, only by memory and by res->count: at most 2^32-1 (UINT32_MAX)
 * queries a call, more is STC_EINVAL. */
int stc_sample(stc_conn *c, const char *set, const stc_sample_opts *o, const stc_query *q,
               size_t n, stc_sample_result *res);
int stc_sample_dir(stc_conn *c, const char *set, const stc_sample_opts *o,
                   const stc_dir_query *q, size_t n, stc_sample_result *res);

/* Uploads. progress(user, sent, total) is called after each acknowledged chunk; returning
 * non-zero aborts the upload (UPLOAD_ABORT is sent) and the call returns STC_ECANCELED; on a
 * connection with an interrupt hook (stc_set_interrupt) the abort's reply is then not waited
 * for (sent as far as the socket takes it, the rest with the next call, its reply dropped:
 * as after an interrupt), so a stop returns at once from a hung server too; the same for a
 * fetch's FETCH_CLOSE.
 * On any failure after UPLOAD_BEGIN the library sends UPLOAD_ABORT when the connection is
 * still usable, so the server never keeps a half-made set (after a timeout its reply is
 * waited for 1000 ms at most: an upload with timeout T returns within about T + 1 s from a
 * server that stops answering; the same for a fetch's FETCH_CLOSE). When the connection breaks
 * instead, a server with STC_CAP_UPLOAD_RESUME keeps the partial upload for a while
 * (seamtexd: upload-keep, default 600 s): calling again on a new connection with
 * STC_UPLOAD_RESUME and the same file, name, hint and options continues from the bytes the
 * server has (result.resumed_from); when it has nothing to resume, the upload starts at 0.
 * The whole file's CRC32C is checked at commit either way. */
typedef int (*stc_progress_fn)(void *user, uint64_t done, uint64_t total);
enum { STC_UPLOAD_REPLACE = 1, STC_UPLOAD_RESUME = 2,
       STC_UPLOAD_REPLICA = 4,  /* node-to-node copy in a cluster (seamtexd uses it) */
       STC_UPLOAD_STAGE = 8     /* with REPLICA: staged until published (seamtexd uses it) */ };
typedef struct stc_upload_opts {
    const char     *hint;             /* "ptx", "png", ... (at most 15 bytes, else STC_EINVAL);
                                         NULL = from the file extension */
    const char     *options;          /* "texture=<set> cube=latlong:512" (at most 1023 bytes);
                                         NULL = none */
    unsigned        flags;            /* STC_UPLOAD_* (another bit: STC_EINVAL) */
    uint32_t        chunk;            /* bytes per chunk; 0 = min(1 MiB, server max_chunk) */
    stc_progress_fn progress;
    void           *user;
} stc_upload_opts;
typedef struct stc_upload_result {
    char     name[256];
    unsigned kind, nchan, dtype;
    uint32_t nfaces;
    uint64_t memory;
    uint32_t crc32c;                  /* of what was sent */
    uint64_t resumed_from;            /* bytes the server already had (STC_UPLOAD_RESUME) */
} stc_upload_result;
int stc_upload_file(stc_conn *c, const char *path, const char *set, const stc_upload_opts *o,
                    stc_upload_result *out);
int stc_upload_buffer(stc_conn *c, const void *data, size_t len, const char *set,
                      const stc_upload_opts *o, stc_upload_result *out);

int stc_delete(stc_conn *c, const char *set);

typedef struct stc_stat {
    const char *key;
    int         is_float;
    uint64_t    u;                    /* when !is_float */
    double      f;                    /* when is_float */
} stc_stat;
/* Server counters; *stats (n entries) owned by c. */
int stc_stats(stc_conn *c, const stc_stat **stats, size_t *n);
/* Looks a key up in the last stc_stats result; NULL when absent. */
const stc_stat *stc_stat_find(const stc_stat *stats, size_t n, const char *key);

enum { STC_COMPRESS_SEAM_AWARE = 1, STC_COMPRESS_REPLACE = 2 };
enum { STC_JOB_QUEUED = 0, STC_JOB_RUNNING = 1, STC_JOB_DONE = 2, STC_JOB_FAILED = 3,
       STC_JOB_CANCELED = 4 };
typedef struct stc_job {
    uint64_t id;
    unsigned state;                   /* STC_JOB_* */
    float    progress;                /* 0..1 */
    int      result;                  /* 0 or an stc_err server code of a finished job */
    char     message[1024];
} stc_job;
int stc_compress(stc_conn *c, const char *set, const char *target, unsigned level,
                 unsigned flags, uint64_t *job_id);
int stc_job_status(stc_conn *c, uint64_t job_id, stc_job *out);
int stc_job_cancel(stc_conn *c, uint64_t job_id, stc_job *out);   /* out may be NULL */
/* Polls until the job is DONE/FAILED/CANCELED or wait_ms passes (STC_ETIMEDOUT; < 0 =
 * forever; each poll is a request under the request timeout). Returns 0 when DONE, the job's
 * result code when FAILED (STC_EINTERNAL when it gives none), STC_ESERVERCANCELED when
 * CANCELED. */
int stc_job_wait(stc_conn *c, uint64_t job_id, int wait_ms, stc_job *out);

/* FETCH formats (PROTOCOL.md 4.10: which fits which set kind). STC_FETCH_AUTO picks the
 * format from the path's extension (.ptx .dds .exr .png .obj, any case), as an upload picks
 * its hint; any other extension fetches .ptx. */
enum {
    STC_FETCH_PTX = 0, STC_FETCH_DDS = 1, STC_FETCH_EXR = 2, STC_FETCH_PNG = 3,
    STC_FETCH_OBJ = 4,
    STC_FETCH_AUTO = 255
};
/* The format for a file name's extension, -1 when it names none. */
int stc_fetch_format_for_path(const char *path);
/* Downloads a set as a file (written to path + ".part", checked against the server's
 * CRC32C, then renamed onto path). A format that does not fit the set is EUNSUPPORTED, the
 * server's message naming the formats that do. */
int stc_fetch_file(stc_conn *c, const char *set, unsigned format, const char *path,
                   stc_progress_fn progress, void *user);

/* ---- pipelined API ----------------------------------------------------------------------------
 * stc_append_* encode a request into the connection's output buffer and return its request
 * id in *reqid. An append never waits while little is queued: past 1 MiB it sends what the
 * socket takes at once; past 64 MiB unsent (a server that does not read) it waits up to the
 * request timeout for room and otherwise returns STC_ETIMEDOUT with nothing appended.
 * stc_flush sends everything queued (per-request timeout; on timeout the unsent rest stays
 * queued). stc_get_reply waits for the next reply of an appended request, in the order the
 * server sends them (match by reqid): up to timeout_ms when > 0; when 0 it only returns a reply
 * that has already arrived (else STC_ETIMEDOUT at once); when < 0 it uses the connection's
 * request timeout. A get_reply timeout leaves the request outstanding. The reply, and what stc_reply_* decode from it, are owned by c until the next call.
 * A reply with a non-OK status has status != 0 and its message in errmsg. */
typedef struct stc_reply {
    uint32_t       reqid;
    unsigned       opcode;
    int            status;            /* 0, or an stc_err server code */
    const char    *errmsg;            /* "" when status == 0 */
    const uint8_t *body;              /* raw body (PROTOCOL.md layout) */
    size_t         body_len;
} stc_reply;

int stc_append_ping(stc_conn *c, const void *payload, size_t len, uint32_t *reqid);
int stc_append_sample(stc_conn *c, const char *set, const stc_sample_opts *o,
                      const stc_query *q, size_t n, uint32_t *reqid);
int stc_append_sample_dir(stc_conn *c, const char *set, const stc_sample_opts *o,
                          const stc_dir_query *q, size_t n, uint32_t *reqid);
int stc_append_info(stc_conn *c, const char *set, uint32_t *reqid);
int stc_append_stats(stc_conn *c, uint32_t *reqid);
/* Any request with a body already encoded (PROTOCOL.md layout), e.g. for tests. */
int stc_append_raw(stc_conn *c, unsigned opcode, const void *body, size_t len, uint32_t *reqid);
int stc_flush(stc_conn *c);
int stc_get_reply(stc_conn *c, int timeout_ms, stc_reply *r);
/* Requests appended and not yet answered (abandoned ones after a timeout excluded). */
size_t stc_pending(const stc_conn *c);
/* Gives up on every outstanding pipelined request: their replies will be read and dropped
 * when they come, and blocking calls are allowed again at once. Returns how many. */
size_t stc_discard_pending(stc_conn *c);
/* Decoders for replies from stc_get_reply (results owned by c). */
int stc_reply_sample(stc_conn *c, const stc_reply *r, stc_sample_result *res);
int stc_reply_info(stc_conn *c, const stc_reply *r, stc_info *out);

/* ---- zero-copy shared-memory sampling (PROTOCOL.md 4.12; after stc_shm_attach) ----
 * The caller writes its queries straight into the region.
 * stc_shm_reserve takes room in the region for a SAMPLE (dir 0) or SAMPLE_DIR (dir 1) of n
 * queries of set `set` with options o (n at most the server's max_batch) and sets *queries to
 * where the n queries go: packed, little-endian, in the wire layout of PROTOCOL.md 4.4 /
 * 4.4.1 / 4.5 that o->want selects (28 bytes: u32 face, then u, v, dudx, dvdx, dudy, dvdy as
 * f32; with UV16 / FACE16 the compact forms; 36 bytes per direction query). On a
 * little-endian host the f32 layouts are exactly stc_query[n] and stc_dir_query[n], and
 * *queries is aligned for them (64 bytes). Returns 0; STC_ESTATE with no region, while a
 * reservation is open, or when the free part of the region cannot hold the queries and the
 * reply (read the replies of pipelined requests to free it); STC_EINVAL for bad options.
 * One reservation at a time: until it is sent or cancelled, other SAMPLE calls on c go over
 * the socket. stc_shm_append sends it pipelined (the reply through stc_get_reply and
 * stc_reply_sample); stc_shm_sample sends it and waits (the blocking rules apply). The
 * queries must be complete before that call and left alone until the reply is read; the
 * reservation is used up by the call whether it succeeds or fails. The result is read in
 * place in the region (f16 values are widened into c's memory) and stays valid until the
 * next call on c. stc_shm_cancel gives an unsent reservation back (none open: no-op). */
int stc_shm_reserve(stc_conn *c, const char *set, const stc_sample_opts *o, int dir, size_t n,
                    void **queries);
int stc_shm_append(stc_conn *c, uint32_t *reqid);
int stc_shm_sample(stc_conn *c, stc_sample_result *res);
void stc_shm_cancel(stc_conn *c);

#ifdef __cplusplus
}
#endif
#endif
