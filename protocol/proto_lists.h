/* protocol/proto_lists.h - every enumerated list of the wire protocol, written once.
 *
 * Owns: the opcodes (with their "mutating" flag), the reply statuses (with the name the client
 * library gives each as an error code), the per-query statuses, the sampling modes, filters,
 * zero-coverage rules and output formats, the FETCH file formats, the set kinds and texel types, as X-macros. Every
 * other place derives from these lists: the enums and name <-> value functions of proto.h,
 * the daemon's dispatch table and store-code checks (server/), the client library's error
 * codes (checked against STP_STATUSES in client/libconn.c), the CLI's names.
 * Does not own: layouts (proto.h), what a request does (server/), PROTOCOL.md (the normative
 * text, which shows the same lists as tables).
 *
 * Self-contained: no includes, only macros. The values are wire values: never renumber.
 * To add an entry, add one X(...) line; the compiler then asks for what else it needs (a
 * dispatch row, a client error name, a store value to agree with).
 */
#ifndef STP_PROTO_LISTS_H
#define STP_PROTO_LISTS_H

/* Opcodes: X(NAME, lower_name, code, mutating). lower_name names the daemon's handler
 * (sts_h_<lower_name>); mutating requests need the token when the server has one. */
#define STP_OPCODES(X)                                   \
    X(HELLO,         hello,         0x01, 0)             \
    X(PING,          ping,          0x02, 0)             \
    X(LIST,          list,          0x03, 0)             \
    X(INFO,          info,          0x04, 0)             \
    X(SAMPLE,        sample,        0x05, 0)             \
    X(SAMPLE_DIR,    sample_dir,    0x06, 0)             \
    X(STATS,         stats,         0x07, 0)             \
    X(UPLOAD_BEGIN,  upload_begin,  0x10, 1)             \
    X(UPLOAD_CHUNK,  upload_chunk,  0x11, 1)             \
    X(UPLOAD_COMMIT, upload_commit, 0x12, 1)             \
    X(UPLOAD_ABORT,  upload_abort,  0x13, 1)             \
    X(UPLOAD_STATUS, upload_status, 0x14, 0)             \
    X(DELETE,        delete,        0x15, 1)             \
    X(COMPRESS,      compress,      0x20, 1)             \
    X(JOB_STATUS,    job_status,    0x21, 0)             \
    X(JOB_CANCEL,    job_cancel,    0x22, 1)             \
    X(FETCH_OPEN,    fetch_open,    0x23, 0)             \
    X(FETCH_READ,    fetch_read,    0x24, 0)             \
    X(FETCH_CLOSE,   fetch_close,   0x25, 0)             \
    X(CLUSTER,       cluster,       0x30, 0)             \
    X(REPLICA_PUBLISH, replica_publish, 0x31, 1)         \
    X(SHM_ATTACH,    shm_attach,    0x08, 0)

/* Reply statuses: X(NAME, value, client_error). Values are dense from 0. client_error is the
 * suffix of the client library's code for it (STC_<client_error> in client/seamtex.h, equal
 * to -(STC_SERVER_BASE + value)); OK has none (STC_OK). */
#define STP_STATUSES(X)                                  \
    X(OK,             0,  OK)                            \
    X(BAD_REQUEST,    1,  EBADREQUEST)                   \
    X(UNKNOWN_OPCODE, 2,  EUNKNOWNOP)                    \
    X(BAD_VERSION,    3,  EBADVERSION)                   \
    X(TOO_LARGE,      4,  ETOOLARGE)                     \
    X(NOT_FOUND,      5,  ENOTFOUND)                     \
    X(EXISTS,         6,  EEXISTS)                       \
    X(UNSUPPORTED,    7,  EUNSUPPORTED)                  \
    X(PERM,           8,  EPERM)                         \
    X(BUSY,           9,  EBUSY)                         \
    X(TIMEOUT,        10, ESERVERTIMEOUT)                \
    X(INTERNAL,       11, EINTERNAL)                     \
    X(CORRUPT,        12, ECORRUPT)                      \
    X(INVALID,        13, EINVALID)                      \
    X(FORMAT,         14, EFORMAT)                       \
    X(NOMEM,          15, ESERVERNOMEM)                  \
    X(IO,             16, ESERVERIO)                     \
    X(CANCELED,       17, ESERVERCANCELED)               \
    X(ADJ,            18, EADJ)                          \
    X(NOUV,           19, ENOUV)                         \
    X(SHUTDOWN,       20, ESHUTDOWN)                     \
    X(MOVED,          21, EMOVED)                        \
    X(UNAVAILABLE,    22, EUNAVAILABLE)

/* Per-query statuses of a SAMPLE reply (u8 each): X(NAME, value). Same numbers as
 * store/sample.h enum st_qstatus (ST_Q_<NAME>; checked in server/h_basic.c). */
#define STP_QSTATUSES(X)                                 \
    X(OK,            0)                                  \
    X(BAD_FACE,      1)                                  \
    X(NONFINITE,     2)                                  \
    X(BAD_FOOTPRINT, 3)                                  \
    X(ZERO_COVERAGE, 4)

/* Sampling modes: X(NAME, "name", value); store/sample.h st_mode (ST_MODE_<NAME>). */
#define STP_MODES(X)                                     \
    X(DISCARD,  "discard",  0)                           \
    X(TRAVERSE, "traverse", 1)                           \
    X(CLAMP,    "clamp",    2)

/* Filters: X(NAME, "name", value); store/sample.h st_filter (ST_FILTER_<NAME>). */
#define STP_FILTERS(X)                                   \
    X(POINT,           "point",           0)             \
    X(BILINEAR,        "bilinear",        1)             \
    X(TRILINEAR,       "trilinear",       2)             \
    X(ANISO,           "aniso",           3)             \
    X(PTEX_POINT,      "ptex-point",      8)             \
    X(PTEX_BILINEAR,   "ptex-bilinear",   9)             \
    X(PTEX_BOX,        "ptex-box",        10)            \
    X(PTEX_GAUSSIAN,   "ptex-gaussian",   11)            \
    X(PTEX_BICUBIC,    "ptex-bicubic",    12)            \
    X(PTEX_BSPLINE,    "ptex-bspline",    13)            \
    X(PTEX_CATMULLROM, "ptex-catmullrom", 14)            \
    X(PTEX_MITCHELL,   "ptex-mitchell",   15)

/* What Discard does when every tap falls outside: X(NAME, "name", value); store/sample.h
 * st_zero_rule (ST_ZERO_<NAME>). */
#define STP_ZERO_RULES(X)                                \
    X(NAN,   "nan",   0)                                 \
    X(CLAMP, "clamp", 1)

/* Value formats of a SAMPLE reply: X(NAME, "name", value, bytes per value). */
#define STP_OUTFMTS(X)                                   \
    X(F32,     "f32",     0, 4)                          \
    X(UNORM8,  "unorm8",  1, 1)                          \
    X(UNORM16, "unorm16", 2, 2)                          \
    X(F16,     "f16",     3, 2)

/* File formats of FETCH_OPEN: X(NAME, "name", value); the name is also the file extension
 * (the client picks the format from it). Same numbers as store/import/export.h
 * st_export_format (ST_EXPORT_<NAME>; checked in server/h_jobs.c). Which format fits which set
 * kind is the store's table (export.h, PROTOCOL.md 4.10). */
#define STP_FETCH_FORMATS(X)                             \
    X(PTX, "ptx", 0)                                     \
    X(DDS, "dds", 1)                                     \
    X(EXR, "exr", 2)                                     \
    X(PNG, "png", 3)                                     \
    X(OBJ, "obj", 4)

/* Set kinds (LIST, INFO, UPLOAD_COMMIT): X(NAME, "name", value); store/set.h st_kind. */
#define STP_KINDS(X)                                     \
    X(PERFACE, "perface", 0)                             \
    X(CUBE,    "cube",    1)                             \
    X(ATLAS,   "atlas",   2)                             \
    X(BC1,     "bc1",     3)

/* Texel types (LIST, INFO, UPLOAD_COMMIT): X(NAME, "name", value); store/set.h st_dtype
 * (ST_DT_<NAME>). */
#define STP_DTYPES(X)                                    \
    X(U8,   "u8",   0)                                   \
    X(U16,  "u16",  1)                                   \
    X(HALF, "half", 2)                                   \
    X(F32,  "f32",  3)

#endif
