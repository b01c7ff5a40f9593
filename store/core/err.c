/* store/core/err.c - names of the store's error codes and the st_error helpers (see err.h). */
#include "err.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

static const char *const names[] = {
    "OK", "EINVAL", "ENOMEM", "EIO", "EFORMAT", "ETOOBIG", "EADJ", "ENOTFOUND",
    "EUNSUPPORTED", "EEXIST", "ECORRUPT", "ENOUV", "ECANCELED", "EBUSY", "EPERM", "ETIMEDOUT",
};

const char *st_strerror(int code)
{
    if (code > 0 || code < ST_ECODE_MIN)
        return "E?";
    return names[-code];
}

int st_fail(st_error *e, int code, const char *fmt, ...)
{
    if (e) {
        va_list ap;
        va_start(ap, fmt);
        e->code = code;
        vsnprintf(e->msg, sizeof e->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}

void st_error_clear(st_error *e)
{
    if (e) {
        e->code = 0;
        e->msg[0] = '\0';
    }
}
