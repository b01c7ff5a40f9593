/* tests/common/daemon_fixture.c - see daemon_fixture.h. */
#include "daemon_fixture.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "testdata.h"
#include "wait.h"

extern char **environ;

/* Daemons started and not yet reaped: a test that fails an assertion jumps out without its
 * cleanup, so at exit every daemon still listed is killed (no orphan keeps running). */
#define MAX_LIVE 64
static pid_t live[MAX_LIVE];
static int atexit_set;

static void kill_leftovers(void)
{
    for (int i = 0; i < MAX_LIVE; i++)
        if (live[i] > 0) {
            kill(live[i], SIGKILL);
            waitpid(live[i], NULL, 0);
            live[i] = 0;
        }
}

static void track(pid_t pid, int add)
{
    if (add && !atexit_set) {
        atexit(kill_leftovers);
        atexit_set = 1;
    }
    for (int i = 0; i < MAX_LIVE; i++) {
        if (add && live[i] == 0) {
            live[i] = pid;
            return;
        }
        if (!add && live[i] == pid) {
            live[i] = 0;
            return;
        }
    }
}

int st_daemon_init(st_daemon *d)
{
    memset(d, 0, sizeof *d);
    const char *tmp = getenv("TMPDIR");
    if (!tmp || !*tmp)
        tmp = "/tmp";
    snprintf(d->dir, sizeof d->dir, "%s/seamtexd-test-XXXXXX", tmp);
    if (!mkdtemp(d->dir)) {
        fprintf(stderr, "daemon_fixture: mkdtemp %s: %s\n", d->dir, strerror(errno));
        return -1;
    }
    snprintf(d->datadir, sizeof d->datadir, "%s/data", d->dir);
    snprintf(d->log, sizeof d->log, "%s/daemon.log", d->dir);
    snprintf(d->host, sizeof d->host, "127.0.0.1");
    return 0;
}

int st_daemon_connect(const st_daemon *d)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    struct sockaddr_in sa;
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_port = htons((uint16_t)d->port);
    inet_pton(AF_INET, d->host, &sa.sin_addr);
    if (connect(fd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        close(fd);
        return -1;
    }
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    return fd;
}

int st_daemon_log_count(const st_daemon *d, const char *needle)
{
    FILE *f = fopen(d->log, "r");
    if (!f)
        return -1;
    char line[1024];
    int n = 0;
    while (fgets(line, sizeof line, f))
        n += strstr(line, needle) != NULL;
    fclose(f);
    return n;
}

void st_daemon_dump_log(const st_daemon *d, int lines)
{
    FILE *f = fopen(d->log, "r");
    if (!f)
        return;
    /* keep the last `lines` lines in a ring */
    char ring[64][512];
    int n = 0;
    if (lines > 64)
        lines = 64;
    while (fgets(ring[n % lines], sizeof ring[0], f))
        n++;
    fclose(f);
    int start = n > lines ? n - lines : 0;
    fprintf(stderr, "---- last lines of %s ----\n", d->log);
    for (int i = start; i < n; i++)
        fputs(ring[i % lines], stderr);
    fprintf(stderr, "----\n");
}

/* Waiting for a start: the daemon exited (status kept), or its port file names a port that
 * accepts a connection. */
typedef struct start_cond {
    st_daemon *d;
    pid_t pid;
    const char *portfile;
    int exited;
} start_cond;

static int started(void *arg)
{
    start_cond *sc = arg;
    st_daemon *d = sc->d;
    int status;
    if (waitpid(sc->pid, &status, WNOHANG) == sc->pid) {
        track(sc->pid, 0);
        d->pid = 0;
        d->exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        sc->exited = 1;
        return 1;
    }
    FILE *f = fopen(sc->portfile, "r");
    if (f) {
        int port = 0;
        if (fscanf(f, "%d", &port) == 1 && port > 0)
            d->port = port;
        fclose(f);
    }
    if (d->port > 0) {
        int fd = st_daemon_connect(d);
        if (fd >= 0) {
            close(fd);
            return 1;
        }
    }
    return 0;
}

int st_daemon_start(st_daemon *d, const char *const *extra)
{
    if (d->pid > 0)
        return -1;
    const char *bdir = getenv("SEAMTEX_BUILD");
    char exe[512], portfile[320];
    snprintf(exe, sizeof exe, "%s/seamtexd", bdir && *bdir ? bdir : "build");
    snprintf(portfile, sizeof portfile, "%s/port", d->dir);
    unlink(portfile);
    if (access(exe, X_OK) != 0) {
        fprintf(stderr, "daemon_fixture: %s is not there (SEAMTEX_BUILD=%s)\n", exe,
                bdir ? bdir : "(unset)");
        return -1;
    }
    const char *argv[64];
    int ac = 0;
    argv[ac++] = exe;
    argv[ac++] = "--listen";
    argv[ac++] = "127.0.0.1:0";
    argv[ac++] = "--data-dir";
    argv[ac++] = d->datadir;
    argv[ac++] = "--port-file";
    argv[ac++] = portfile;
    for (int i = 0; extra && extra[i] && ac < 62; i++)
        argv[ac++] = extra[i];
    argv[ac] = NULL;

    struct stat lst;
    d->log_mark = stat(d->log, &lst) == 0 ? (long)lst.st_size : 0;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    const char *through = getenv("SEAMTEX_DAEMON_LOG");
    if (!(through && *through == '1'))
        posix_spawn_file_actions_addopen(&fa, 2, d->log, O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    pid_t pid;
    int rc = posix_spawn(&pid, exe, &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
        fprintf(stderr, "daemon_fixture: posix_spawn %s: %s\n", exe, strerror(rc));
        return -1;
    }
    d->pid = pid;
    track(pid, 1);
    d->port = 0;
    start_cond sc = {d, pid, portfile, 0};
    /* SEAMTEX_START_MS: how long a start may take (default 30 s; make tsan sets more, since a
     * ThreadSanitizer daemon on a loaded machine starts far slower) */
    const char *sm = getenv("SEAMTEX_START_MS");
    int start_ms = sm && atoi(sm) > 0 ? atoi(sm) : 30000;
    if (st_wait_until(started, &sc, start_ms) == 0) {
        if (sc.exited) {
            fprintf(stderr, "daemon_fixture: seamtexd exited at start (status %d)\n",
                    d->exit_status);
            st_daemon_dump_log(d, 20);
            return -1;
        }
        return 0;
    }
    fprintf(stderr, "daemon_fixture: seamtexd did not answer within 30 s\n");
    st_daemon_dump_log(d, 20);
    st_daemon_kill(d);
    return -1;
}

/* Waiting for the daemon to exit: 1 once reaped (or lost: waitpid failed). */
typedef struct reap_cond {
    st_daemon *d;
    int lost;
} reap_cond;

static int reaped(void *arg)
{
    reap_cond *rc = arg;
    st_daemon *d = rc->d;
    int status;
    pid_t r = waitpid(d->pid, &status, WNOHANG);
    if (r == d->pid) {
        track(d->pid, 0);
        d->exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        d->pid = 0;
        return 1;
    }
    if (r < 0 && errno != EINTR) {
        track(d->pid, 0);
        d->pid = 0;
        rc->lost = 1;
        return 1;
    }
    return 0;
}

/* The exit status, -1 when it was lost, -2 when the daemon still runs after timeout_ms. */
static int reap(st_daemon *d, int timeout_ms)
{
    reap_cond rc = {d, 0};
    if (st_wait_until(reaped, &rc, timeout_ms) != 0)
        return -2;
    return rc.lost ? -1 : d->exit_status;
}

/* Runs argv (PATH search) with stdin /dev/null and stdout onto stderr, waits; its status or
 * -1 (posix_spawn, never fork: the test binaries link OpenImageIO). */
static int spawn_wait(const char *const *argv)
{
    pid_t g;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&fa, 2, 1);
    int rc = posix_spawnp(&g, argv[0], &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0)
        return -1;
    int st = 0;
    while (waitpid(g, &st, 0) < 0)
        if (errno != EINTR)
            return -1;
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Every thread's stack of a daemon that does not exit, to stderr, before it is killed: gdb's
 * (bounded by timeout(1): attaching to a process in uninterruptible sleep can block), else
 * each thread's name, wchan and kernel stack from /proc. */
static void dump_stacks(pid_t pid)
{
    char spid[16], cmd[256];
    snprintf(spid, sizeof spid, "%d", (int)pid);
    const char *gdb[] = {"timeout", "60", "gdb", "-nx", "-batch", "-p", spid,
                         "-ex", "thread apply all bt", NULL};
    if (access("/usr/bin/gdb", X_OK) == 0 && spawn_wait(gdb) == 0)
        return;
    snprintf(cmd, sizeof cmd, "for t in /proc/%d/task/*; do echo \"$t $(cat $t/comm) "
             "$(cat $t/wchan)\"; cat $t/stack; done", (int)pid);
    const char *sh[] = {"sh", "-c", cmd, NULL};
    spawn_wait(sh);
}

/* 1 when this run of the daemon (its log from log_mark on) logged "stopped", text or JSON */
static int logged_stopped(const st_daemon *d)
{
    FILE *f = fopen(d->log, "r");
    if (!f)
        return 0;
    char line[1024];
    int found = 0;
    if (fseek(f, d->log_mark, SEEK_SET) == 0)
        while (!found && fgets(line, sizeof line, f))
            found = strstr(line, "Z INFO  stopped: ") || strstr(line, "\"event\":\"stopped\"");
    fclose(f);
    return found;
}

long st_proc_status_field(pid_t pid, const char *key)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    size_t kl = strlen(key);
    long v = -1;
    while (f && fgets(line, sizeof line, f))
        if (strncmp(line, key, kl) == 0 && line[kl] == ':')
            v = atol(line + kl + 1);
    if (f)
        fclose(f);
    return v;
}

/* the pid tracing this process (LeakSanitizer's stop-the-world), 0 when none */
static long tracer_of(pid_t pid)
{
    long t = st_proc_status_field(pid, "TracerPid");
    return t < 0 ? 0 : t;
}

int st_daemon_stop(st_daemon *d, int timeout_ms)
{
    if (d->pid <= 0)
        return -1;
    kill(d->pid, SIGTERM);
    int rc = reap(d, timeout_ms);
    if (rc == -2 && logged_stopped(d)) {
        long tracer = tracer_of(d->pid);
        const char *em = getenv("SEAMTEX_EXIT_MS");
        int exit_ms = em && atoi(em) > 0 ? atoi(em) : 120000;
        char why[96] = "not traced";
        if (tracer)
            snprintf(why, sizeof why, "traced by %ld: LeakSanitizer's leak check", tracer);
        fprintf(stderr, "daemon_fixture: seamtexd logged 'stopped' but had not exited after %d "
                "ms (%s); giving its exit %d ms more\n", timeout_ms, why, exit_ms);
        int64_t t0 = st_now_ms();
        rc = reap(d, exit_ms);
        if (rc != -2)
            fprintf(stderr, "daemon_fixture: seamtexd exited %lld ms after that\n",
                    (long long)(st_now_ms() - t0));
        timeout_ms += exit_ms;
    }
    if (rc == -2) {
        fprintf(stderr, "daemon_fixture: seamtexd ignored SIGTERM for %d ms, killing\n",
                timeout_ms);
        st_daemon_dump_log(d, 20);
        dump_stacks(d->pid);
        st_daemon_kill(d);
        return -1;
    }
    return rc;
}

void st_daemon_kill(st_daemon *d)
{
    if (d->pid <= 0)
        return;
    kill(d->pid, SIGKILL);
    reap(d, 10000);
}

int st_daemon_signal(st_daemon *d, int sig)
{
    if (d->pid <= 0 || kill(d->pid, sig) != 0)
        return -1;
    return sig == SIGSTOP ? st_wait_stopped(d->pid, 10000) : 0;
}

void st_daemon_cleanup(st_daemon *d)
{
    if (d->pid > 0)
        st_daemon_stop(d, 10000);
    if (d->dir[0] && !getenv("SEAMTEX_KEEP_TMP"))
        st_test_rmtree(d->dir);
    d->dir[0] = 0;
}

int st_daemon_up(st_daemon *d, const char *const *extra)
{
    return st_daemon_init(d) == 0 && st_daemon_start(d, extra) == 0 ? 0 : -1;
}

int st_daemon_down(st_daemon *d, int timeout_ms)
{
    int rc = st_daemon_stop(d, timeout_ms);
    st_daemon_cleanup(d);
    return rc == 0 ? 0 : -1;
}

st_daemon ST_GROUP;
const char *const *st_group_args;

int st_group_setup(void **state)
{
    (void)state;
    return st_daemon_up(&ST_GROUP, st_group_args);
}

int st_group_teardown(void **state)
{
    (void)state;
    return st_daemon_down(&ST_GROUP, 15000);
}

int st_daemon_data_path(char *out, size_t cap, const char *rel)
{
    const char *root = getenv("SEAMTEX_DATA");
    if (!root || !*root)
        root = "../shared/data";
    snprintf(out, cap, "%s/%s", root, rel);
    return access(out, R_OK) == 0 ? 0 : -1;
}
