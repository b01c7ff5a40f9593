/* tests/common/unix_daemon.h - seamtexd on a Unix socket for integration tests (the daemon
 * fixture, daemon_fixture.h, serves TCP only), and running programs with posix_spawn.
 *
 * Owns: spawning $SEAMTEX_BUILD/seamtexd with --listen unix:<tmpdir>/s.sock, waiting for its
 * port file, stopping it; a cmocka setup / teardown pair that gives each test its own temp
 * dir. Used by test_server_wire.c (the listener) and test_server_shm.c (shared memory).
 */
#ifndef ST_UNIX_DAEMON_H
#define ST_UNIX_DAEMON_H

#include <sys/types.h>

#include "daemon_fixture.h"

typedef struct st_unix_daemon {
    st_daemon d;            /* for its temp dir and log */
    char      sock[300], addr[310], port[300];
    pid_t     pid;
} st_unix_daemon;

/* $SEAMTEX_BUILD, default "build". */
const char *st_build_dir(void);
/* Runs argv with stdin/stdout on /dev/null and stderr appended to errpath; with bg, returns 0
 * at once with the pid in *bg, else the exit status (128 + signal). -1 when it could not
 * start. */
int st_run(const char *const *argv, const char *errpath, pid_t *bg);
/* Starts seamtexd on unix:<dir>/s.sock with --unix-mode mode (and the NULL-terminated extra
 * flags, may be NULL). Returns 0 once it serves, or the daemon's exit status when it refused
 * to start (> 0), -1 when it could not be run. */
int st_unix_start(st_unix_daemon *u, const char *mode);
int st_unix_start_args(st_unix_daemon *u, const char *mode, const char *const *extra);
/* SIGTERM and wait: the exit status, -1 when not running. */
int st_unix_stop(st_unix_daemon *u);
/* cmocka per-test setup (a fresh temp dir, nothing started) and teardown (kill, clean). */
int st_unix_setup(void **state);
int st_unix_teardown(void **state);
/* 1 when the daemon's log holds text. */
int st_unix_log_has(const st_unix_daemon *u, const char *text);

#endif
