/* tests/common/daemon_fixture.h - start and stop a real seamtexd for integration tests and
 * benchmarks.
 *
 * Owns: spawning $SEAMTEX_BUILD/seamtexd (default ./build/seamtexd) with posix_spawn (never
 * fork: the test binaries link OpenImageIO), on 127.0.0.1 port 0 with a fresh temp data dir,
 * learning the port from --port-file, waiting until it accepts connections, stopping it with
 * SIGTERM (graceful) or SIGKILL (crash tests). Does not own: the protocol (use libseamtex).
 *
 * Daemons still running when the test process exits (a failed assertion skips the test's
 * cleanup) are killed by an atexit handler.
 *
 * The daemon's stderr goes to <tmpdir>/daemon.log (set SEAMTEX_DAEMON_LOG=1 to let it through
 * to the test's stderr instead); on a failed start the log's tail is printed.
 */
#ifndef ST_DAEMON_FIXTURE_H
#define ST_DAEMON_FIXTURE_H

#include <sys/types.h>

typedef struct st_daemon {
    pid_t pid;             /* 0 when not running */
    int   port;            /* the TCP port it listens on */
    char  host[32];        /* "127.0.0.1" */
    char  dir[256];        /* temp dir holding data/, port file and log */
    char  datadir[300];    /* the data dir passed with --data-dir */
    char  log[300];        /* the daemon's stderr */
    int   exit_status;     /* after stop: exit code, or 128 + signal */
    long  log_mark;        /* size of the log when this run started (its lines follow) */
} st_daemon;

/* Creates a temp dir (mkdtemp under $TMPDIR or /tmp) and fills d; nothing is started. */
int st_daemon_init(st_daemon *d);

/* Starts seamtexd with --listen 127.0.0.1:0 --data-dir <datadir> --port-file ... plus extra
 * (a NULL-terminated argv tail, may be NULL), and waits up to 30 s until the port answers.
 * Can be called again after a stop or kill (same data dir: restart tests). 0 or -1. */
int st_daemon_start(st_daemon *d, const char *const *extra);

/* SIGTERM, then waits up to timeout_ms for the process to exit. The daemon's own stop ends
 * with the log line "stopped" (every thread joined); what follows is the process's exit
 * (library destructors and, in sanitizer builds, LeakSanitizer's leak check, which stops the
 * process with ptrace and scans all its memory: seconds to tens of seconds on a loaded
 * machine, docs/testing.md). So when the time is up but this run logged "stopped", the exit
 * gets SEAMTEX_EXIT_MS more (default 120 s; the normal build's exit takes well under 1 s),
 * with a note on stderr saying whether the process is being traced (the leak check). Past
 * that: every thread's stack on stderr (gdb, else /proc), SIGKILL, -1. Returns the exit
 * status (see exit_status), or -1 when the daemon was not running. */
int st_daemon_stop(st_daemon *d, int timeout_ms);

/* SIGKILL and reap. */
void st_daemon_kill(st_daemon *d);

/* Sends a signal (SIGHUP for reload tests). For SIGSTOP it returns once every thread of the
 * daemon has stopped (st_wait_stopped, 10 s): -1 when that did not happen. */
int st_daemon_signal(st_daemon *d, int sig);

/* Stops the daemon if running and removes the temp dir. */
void st_daemon_cleanup(st_daemon *d);

/* init + start in one call (for group setups); 0 or -1. */
int st_daemon_up(st_daemon *d, const char *const *extra);

/* stop (waiting up to timeout_ms) + cleanup; 0 when the daemon exited with status 0. */
int st_daemon_down(st_daemon *d, int timeout_ms);

/* Connects a blocking TCP socket to the daemon; fd or -1. */
int st_daemon_connect(const st_daemon *d);

/* A numeric field of /proc/<pid>/status ("VmRSS", "VmHWM" in kB, "TracerPid"); -1 when it
 * cannot be read. */
long st_proc_status_field(pid_t pid, const char *key);

/* Prints the last lines of the daemon's log to stderr (for failure messages). */
void st_daemon_dump_log(const st_daemon *d, int lines);

/* How many lines of the daemon's log contain needle; -1 when the log cannot be read. */
int st_daemon_log_count(const st_daemon *d, const char *needle);

/* One daemon shared by a cmocka group: st_group_setup starts ST_GROUP with the arguments in
 * st_group_args (NULL-terminated; NULL for none), st_group_teardown stops it and fails the
 * group unless it exited 0. Pass them to cmocka_run_group_tests. */
extern st_daemon ST_GROUP;
extern const char *const *st_group_args;
int st_group_setup(void **state);
int st_group_teardown(void **state);

/* Writes the path of a file in the shared data folder (SEAMTEX_DATA, default ../shared/data)
 * into out; returns 0 when it exists, -1 otherwise. */
int st_daemon_data_path(char *out, size_t cap, const char *rel);

#endif
