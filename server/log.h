/* server/log.h - leveled logging to stderr for the daemon, as text or JSON lines.
 *
 * Owns: the log line formats, the level filter. Text (the default):
 *     2026-11-23T03:10:00.123Z INFO  message
 * JSON (--log-format json), one object per line:
 *     {"time":"2026-11-23T03:10:00.123Z","level":"info","message":"...",<fields>}
 * where time is RFC 3339 UTC with milliseconds, level one of error warn info debug, and the
 * fields are the structured ones the call passed (sts_logkv): strings as JSON strings, numbers
 * as JSON integers; every string escaped by stu_json_str (control characters, quotes, invalid
 * UTF-8 replaced by U+FFFD), so each line is one valid JSON object. Field keys never repeat
 * "time", "level" or "message". Text lines do not show the fields: the message already says
 * what they hold.
 * Does not own: where stderr goes (systemd's journal, a test's log file).
 * The level lives in an sts_log object owned by the server and may change at any time
 * (SIGHUP): it is read and written with relaxed atomics; the format is set once at start.
 * One write(2) per line, so lines from several threads never interleave. A message is cut at
 * 1023 bytes.
 */
#ifndef STS_LOG_H
#define STS_LOG_H

#include <stddef.h>
#include <stdint.h>

enum sts_level { STS_ERROR = 0, STS_WARN = 1, STS_INFO = 2, STS_DEBUG = 3 };
enum sts_log_format { STS_LOG_TEXT = 0, STS_LOG_JSON = 1 };

typedef struct sts_log {
    int level;   /* atomic; lines above it are dropped */
    int format;  /* sts_log_format, set before any thread logs */
} sts_log;

/* One structured field: a string (is_int 0; NULL is written as null) or an integer.
 * Borrowed for the call. */
typedef struct sts_logfield {
    const char *key;
    const char *s;
    int64_t     i;
    int         is_int;
} sts_logfield;

#define STS_FS(k, v) ((sts_logfield){(k), (v), 0, 0})
#define STS_FI(k, v) ((sts_logfield){(k), NULL, (int64_t)(v), 1})
/* The two arguments sts_logkv takes for a list of fields: STS_FIELDS(STS_FS(..), STS_FI(..)) */
#define STS_FIELDS(...) (const sts_logfield[]){__VA_ARGS__}, \
    sizeof((const sts_logfield[]){__VA_ARGS__}) / sizeof(sts_logfield)

/* Parses "error", "warn", "info", "debug"; -1 when unknown. */
int sts_level_parse(const char *s);
const char *sts_level_name(int level);
/* Parses "text", "json"; -1 when unknown. */
int sts_log_format_parse(const char *s);
const char *sts_log_format_name(int format);

void sts_log_set_level(sts_log *lg, int level);
int sts_log_enabled(const sts_log *lg, int level);

void sts_logf(const sts_log *lg, int level, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* A line with structured fields (shown in JSON lines only). */
void sts_logkv(const sts_log *lg, int level, const sts_logfield *f, size_t nf, const char *fmt,
               ...) __attribute__((format(printf, 5, 6)));

/* Formats one line (text or JSON, newline included) into out; returns its length (< cap).
 * time_s / time_ns: the wall clock. What sts_logkv writes; exposed for the unit test. */
size_t sts_log_format_line(int format, int level, int64_t time_s, long time_ns,
                           const sts_logfield *f, size_t nf, const char *msg, char *out,
                           size_t cap);

#endif
