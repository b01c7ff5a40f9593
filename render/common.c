/* render/common.c - the two helpers every render/ file may use: the monotonic clock in
 * milliseconds and writing a formatted message into a caller's buffer (the renderer's error
 * convention: -1 plus a message).
 */
#include "render.h"

#include <stdarg.h>
#include <stdio.h>
#include <time.h>

double rt_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

void rt_say(char *msg, size_t ml, const char *fmt, ...)
{
    if (!msg || !ml)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, ml, fmt, ap);
    va_end(ap);
}
