/* store/core/err.h - the store's error convention, used by every module under store/.
 *
 * A function that can fail returns 0 (ST_OK) or a negative ST_E* code, and when the caller
 * passes a non-NULL st_error it also gets a message that names what was wrong (the face, the
 * edge, the byte offset, the field). st_error is caller-owned, fixed size, never allocated.
 * Asserts are for invariants only, never for input.
 */
#ifndef ST_ERR_H
#define ST_ERR_H

#include <stddef.h>

enum {
    ST_OK           =   0,
    ST_EINVAL       =  -1,  /* an argument or a query is invalid (NaN, out of range) */
    ST_ENOMEM       =  -2,  /* an allocation failed */
    ST_EIO          =  -3,  /* a read, write, fsync or rename failed */
    ST_EFORMAT      =  -4,  /* a file or buffer is malformed, truncated or inconsistent */
    ST_ETOOBIG      =  -5,  /* a size is over a cap (dimensions, face count, bytes) */
    ST_EADJ         =  -6,  /* adjacency is broken (asymmetric, out of range, non-manifold) */
    ST_ENOTFOUND    =  -7,  /* no such set, face, file or job */
    ST_EUNSUPPORTED =  -8,  /* a valid input that seamtex does not handle (said why) */
    ST_EEXIST       =  -9,  /* already exists */
    ST_ECORRUPT     = -10,  /* a checksum did not match */
    ST_ENOUV        = -11,  /* a mesh has no texture coordinates where they are needed */
    ST_ECANCELED    = -12,  /* a job was cancelled */
    ST_EBUSY        = -13,  /* a resource is in use or a limit of concurrent work is reached */
    ST_EPERM        = -14,  /* not allowed (missing or wrong token, bad name) */
    ST_ETIMEDOUT    = -15,  /* a deadline passed */
    ST_ECODE_MIN    = -15
};

#define ST_ERRMSG_LEN 256

typedef struct st_error {
    int  code;                   /* last ST_E* code, 0 when none */
    char msg[ST_ERRMSG_LEN];     /* NUL-terminated description */
} st_error;

/* Short stable name of a code ("EINVAL", ...); "E?" for an unknown code. */
const char *st_strerror(int code);

/* Records code and a printf-style message in e (when e is not NULL); returns code so that
 * callers can write `return st_fail(e, ST_EFORMAT, "face %u: ...", f);`. */
int st_fail(st_error *e, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Resets e to "no error" (NULL is accepted). */
void st_error_clear(st_error *e);

/* Overflow-checked size arithmetic: return 0 and store the result, or -1 on overflow. */
static inline int st_mul_size(size_t a, size_t b, size_t *out)
{
    return __builtin_mul_overflow(a, b, out) ? -1 : 0;
}
static inline int st_add_size(size_t a, size_t b, size_t *out)
{
    return __builtin_add_overflow(a, b, out) ? -1 : 0;
}

#endif
