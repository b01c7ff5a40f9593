/* server/log.c - leveled logging to stderr as text or JSON lines (see log.h). */
#include "log.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "json_str.h"

static const char *const names[] = {"error", "warn", "info", "debug"};
static const char *const formats[] = {"text", "json"};

int sts_level_parse(const char *s)
{
    for (int i = 0; i < 4; i++)
        if (!strcmp(s, names[i]))
            return i;
    if (!strcmp(s, "warning"))
        return STS_WARN;
    return -1;
}

const char *sts_level_name(int level)
{
    return level >= 0 && level < 4 ? names[level] : "?";
}

int sts_log_format_parse(const char *s)
{
    for (int i = 0; i < 2; i++)
        if (!strcmp(s, formats[i]))
            return i;
    return -1;
}

const char *sts_log_format_name(int format)
{
    return format >= 0 && format < 2 ? formats[format] : "?";
}

void sts_log_set_level(sts_log *lg, int level)
{
    __atomic_store_n(&lg->level, level, __ATOMIC_RELAXED);
}

int sts_log_enabled(const sts_log *lg, int level)
{
    return level <= __atomic_load_n(&lg->level, __ATOMIC_RELAXED);
}

/* Appends printf output at *n when it fits whole below cap - 1 (room for the newline);
 * 0, or -1 with nothing appended. */
static int add(char *out, size_t cap, size_t *n, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static int add(char *out, size_t cap, size_t *n, const char *fmt, ...)
{
    if (*n + 2 >= cap)
        return -1;
    va_list ap;
    va_start(ap, fmt);
    int m = vsnprintf(out + *n, cap - 1 - *n, fmt, ap);
    va_end(ap);
    if (m < 0 || (size_t)m >= cap - 1 - *n) {
        out[*n] = 0;
        return -1;
    }
    *n += (size_t)m;
    return 0;
}

/* Appends a JSON string literal when it fits whole; 0 or -1. */
static int add_json(char *out, size_t cap, size_t *n, const char *s)
{
    if (*n + 2 >= cap)
        return -1;
    size_t need = stu_json_str(out + *n, cap - 1 - *n, s, strlen(s));
    if (need >= cap - 1 - *n) {
        out[*n] = 0;
        return -1;
    }
    *n += need;
    return 0;
}

size_t sts_log_format_line(int format, int level, int64_t time_s, long time_ns,
                           const sts_logfield *f, size_t nf, const char *msg, char *out,
                           size_t cap)
{
    static const char *const tags[] = {"ERROR", "WARN ", "INFO ", "DEBUG"};
    int lv = level < 0 ? 0 : level > 3 ? 3 : level;
    char ts[96];
    time_t t = (time_t)time_s;
    struct tm tm;
    gmtime_r(&t, &tm);
    snprintf(ts, sizeof ts, "%04d-%02d-%02dT%02d:%02d:%02d.%03ldZ", tm.tm_year + 1900,
             tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, time_ns / 1000000);
    size_t n = 0;
    if (format != STS_LOG_JSON) {
        /* a message too long for the line is cut */
        int m = snprintf(out, cap - 1, "%s %s %s", ts, tags[lv], msg);
        n = m < 0 ? 0 : (size_t)m < cap - 1 ? (size_t)m : cap - 2;
    } else {
        cap--;   /* keeps room for the closing brace */
        if (add(out, cap, &n, "{\"time\":\"%s\",\"level\":\"%s\",\"message\":", ts,
                names[lv]) != 0)
            n = 0;   /* cap too small for any line: the caller's buffer is at least 256 */
        else if (add_json(out, cap, &n, msg) != 0)
            add(out, cap, &n, "\"(message too long for the log line)\"");
        for (size_t i = 0; i < nf && n; i++) {
            size_t back = n;
            int bad = add(out, cap, &n, ",") || add_json(out, cap, &n, f[i].key) ||
                      add(out, cap, &n, ":");
            if (!bad) {
                if (f[i].is_int)
                    bad = add(out, cap, &n, "%lld", (long long)f[i].i);
                else if (!f[i].s)
                    bad = add(out, cap, &n, "null");
                else
                    bad = add_json(out, cap, &n, f[i].s);
            }
            if (bad) {
                n = back;   /* a field that does not fit whole is left out, with the rest */
                break;
            }
        }
        if (n)
            out[n++] = '}';
    }
    out[n++] = '\n';
    out[n] = 0;
    return n;
}

static void vlog(const sts_log *lg, int level, const sts_logfield *f, size_t nf, const char *fmt,
                 va_list ap)
{
    char msg[1024], line[8192];
    vsnprintf(msg, sizeof msg, fmt, ap);
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    size_t len = sts_log_format_line(lg->format, level, (int64_t)ts.tv_sec, ts.tv_nsec, f, nf,
                                     msg, line, sizeof line);
    ssize_t w = write(2, line, len);
    (void)w;
}

void sts_logf(const sts_log *lg, int level, const char *fmt, ...)
{
    if (!sts_log_enabled(lg, level))
        return;
    va_list ap;
    va_start(ap, fmt);
    vlog(lg, level, NULL, 0, fmt, ap);
    va_end(ap);
}

void sts_logkv(const sts_log *lg, int level, const sts_logfield *f, size_t nf, const char *fmt,
               ...)
{
    if (!sts_log_enabled(lg, level))
        return;
    va_list ap;
    va_start(ap, fmt);
    vlog(lg, level, f, nf, fmt, ap);
    va_end(ap);
}
