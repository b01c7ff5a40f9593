/* tests/common/unix_daemon.c - seamtexd on a Unix socket for integration tests, and running
 * programs with posix_spawn (unix_daemon.h).
 */
#include "unix_daemon.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "wait.h"

extern char **environ;

const char *st_build_dir(void)
{
    const char *b = getenv("SEAMTEX_BUILD");
    return b && *b ? b : "build";
}

/* Runs argv with stderr to errpath; returns the exit status (128 + signal), -1 when it could
 * not start. */
int st_run(const char *const *argv, const char *errpath, pid_t *bg)
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, errpath, O_WRONLY | O_CREAT | O_APPEND, 0644);
    pid_t pid;
    int rc = posix_spawnp(&pid, argv[0], &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0)
        return -1;
    if (bg) {
        *bg = pid;
        return 0;
    }
    int st;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
        ;
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

static int port_written(void *arg)
{
    st_unix_daemon *u = arg;
    struct stat st;
    int status;
    if (waitpid(u->pid, &status, WNOHANG) == u->pid) {
        u->pid = -(WIFEXITED(status) ? WEXITSTATUS(status) : 128);
        return 1;
    }
    return stat(u->port, &st) == 0 && st.st_size > 0;
}

int st_unix_start_args(st_unix_daemon *u, const char *mode, const char *const *extra)
{
    char exe[512];
    snprintf(exe, sizeof exe, "%s/seamtexd", st_build_dir());
    unlink(u->port);
    const char *argv[32] = {exe, "--listen", u->addr, "--unix-mode", mode, "--port-file",
                            u->port, "--data-dir", u->d.datadir};
    size_t n = 9;
    for (size_t i = 0; extra && extra[i] && n + 1 < sizeof argv / sizeof argv[0]; i++)
        argv[n++] = extra[i];
    argv[n] = NULL;
    if (st_run(argv, u->d.log, &u->pid) != 0)
        return -1;
    if (st_wait_until(port_written, u, 30000) != 0)
        return -1;
    return u->pid < 0 ? -u->pid : 0;
}

int st_unix_start(st_unix_daemon *u, const char *mode)
{
    return st_unix_start_args(u, mode, NULL);
}

int st_unix_stop(st_unix_daemon *u)
{
    if (u->pid <= 0)
        return -1;
    kill(u->pid, SIGTERM);
    int st;
    while (waitpid(u->pid, &st, 0) < 0 && errno == EINTR)
        ;
    u->pid = 0;
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

int st_unix_setup(void **state)
{
    st_unix_daemon *u = calloc(1, sizeof *u);
    if (!u || st_daemon_init(&u->d) != 0)
        return -1;
    chmod(u->d.dir, 0755);   /* so that only the socket's own mode decides who gets in */
    snprintf(u->sock, sizeof u->sock, "%.250s/s.sock", u->d.dir);
    snprintf(u->addr, sizeof u->addr, "unix:%s", u->sock);
    snprintf(u->port, sizeof u->port, "%.250s/port", u->d.dir);
    *state = u;
    return 0;
}

int st_unix_teardown(void **state)
{
    st_unix_daemon *u = *state;
    if (u->pid > 0) {
        kill(u->pid, SIGKILL);
        waitpid(u->pid, NULL, 0);
    }
    st_daemon_cleanup(&u->d);
    free(u);
    return 0;
}

int st_unix_log_has(const st_unix_daemon *u, const char *text)
{
    FILE *f = fopen(u->d.log, "r");
    char line[1024];
    int found = 0;
    while (f && fgets(line, sizeof line, f))
        found |= strstr(line, text) != NULL;
    if (f)
        fclose(f);
    return found;
}
