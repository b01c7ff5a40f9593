/* server/log.h - leveled logging to stderr for the daemon.
 *
 * Owns: the log line format ("2026-11-23T03:10:00.123Z INFO  message"), the level filter.
 * Does not own: where stderr goes (systemd's journal, a test's log file).
 * The level lives in an sts_log object owned by the server and may change at any time
 * (SIGHUP): it is read and written with relaxed atomics. One write(2) per line, so lines
 * from several threads never interleave.
 */
#ifndef STS_LOG_H
#define STS_LOG_H

enum sts_level { STS_ERROR = 0, STS_WARN = 1, STS_INFO = 2, STS_DEBUG = 3 };

typedef struct sts_log {
    int level;  /* atomic; lines above it are dropped */
} sts_log;

/* Parses "error", "warn", "info", "debug"; -1 when unknown. */
int sts_level_parse(const char *s);
const char *sts_level_name(int level);

void sts_log_set_level(sts_log *lg, int level);
int sts_log_enabled(const sts_log *lg, int level);

void sts_logf(const sts_log *lg, int level, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

#endif
