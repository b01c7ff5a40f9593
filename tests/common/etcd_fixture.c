/* tests/common/etcd_fixture.c - a real etcd on loopback (etcd_fixture.h). */
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "etcd_fixture.h"
#include "wait.h"
#include "wire.h"

extern char **environ;

static int answers(void *arg)
{
    st_etcd *e = arg;
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons((uint16_t)e->client_port);
    int ok = fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0;
    if (fd >= 0)
        close(fd);
    return ok;
}

static int spawn(st_etcd *e, const char *bin);

static const char *etcd_bin(void)
{
    const char *bin = getenv("SEAMTEX_ETCD");
    return bin && *bin ? bin : "/usr/bin/etcd";
}

int st_etcd_start(st_etcd *e, const char *prefix)
{
    memset(e, 0, sizeof *e);
    const char *bin = etcd_bin();
    if (access(bin, X_OK) != 0) {
        fprintf(stderr, "etcd not found at %s (install etcd-server: deploy/install-deps.sh)\n", bin);
        return -1;
    }
    const char *tmp = getenv("TMPDIR");
    snprintf(e->dir, sizeof e->dir, "%s/seamtex-etcd-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(e->dir))
        return -1;
    e->client_port = st_wire_free_port();
    e->peer_port = st_wire_free_port();
    snprintf(e->url, sizeof e->url, "etcd://127.0.0.1:%d%s", e->client_port, prefix);
    return spawn(e, bin);
}

/* runs etcd on e's ports and dir and waits until it answers */
static int spawn(st_etcd *e, const char *bin)
{
    char data[300], cu[64], pu[64], ic[96], logp[300];
    snprintf(data, sizeof data, "%s/data", e->dir);
    snprintf(cu, sizeof cu, "http://127.0.0.1:%d", e->client_port);
    snprintf(pu, sizeof pu, "http://127.0.0.1:%d", e->peer_port);
    snprintf(ic, sizeof ic, "default=%s", pu);
    snprintf(logp, sizeof logp, "%s/etcd.log", e->dir);
    const char *argv[] = {bin, "--data-dir", data, "--listen-client-urls", cu,
                          "--advertise-client-urls", cu, "--listen-peer-urls", pu,
                          "--initial-advertise-peer-urls", pu, "--initial-cluster", ic, NULL};
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, logp, O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, logp, O_WRONLY | O_CREAT | O_APPEND, 0644);
    int rc = posix_spawn(&e->pid, bin, &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
        fprintf(stderr, "etcd: %s\n", strerror(rc));
        e->pid = 0;
        return -1;
    }
    if (st_wait_until(answers, e, 30000) != 0) {
        fprintf(stderr, "etcd did not answer on port %d (log %s)\n", e->client_port, logp);
        return -1;
    }
    st_sleep_ms(500);   /* a leader first */
    return 0;
}

/* kills etcd (a paused one too) and reaps it */
static void kill_etcd(st_etcd *e)
{
    kill(e->pid, SIGCONT);
    kill(e->pid, SIGKILL);
    waitpid(e->pid, NULL, 0);
    e->pid = 0;
}

/* kills etcd, runs the shell command fmt when not NULL (with e->dir for each %s, at most
 * three) and starts etcd again */
static int down_run_up(st_etcd *e, const char *fmt)
{
    if (e->pid <= 0)
        return -1;
    kill_etcd(e);
    if (fmt) {
        char cmd[1200];
        snprintf(cmd, sizeof cmd, fmt, e->dir, e->dir, e->dir);
        if (system(cmd) != 0)
            return -1;
    }
    return spawn(e, etcd_bin());
}

int st_etcd_restart(st_etcd *e, int wipe)
{
    return down_run_up(e, wipe ? "rm -rf '%s/data'" : NULL);
}

int st_etcd_save(st_etcd *e)
{
    return down_run_up(e, "rm -rf '%s/saved' && cp -a '%s/data' '%s/saved'");
}

int st_etcd_restore(st_etcd *e)
{
    return down_run_up(e, "rm -rf '%s/data' && cp -a '%s/saved' '%s/data'");
}

int st_etcd_pause(st_etcd *e, int paused)
{
    if (e->pid <= 0 || kill(e->pid, paused ? SIGSTOP : SIGCONT) != 0)
        return -1;
    return paused ? st_wait_stopped(e->pid, 10000) : 0;
}

void st_etcd_stop(st_etcd *e)
{
    if (e->pid > 0)
        kill_etcd(e);
    if (e->dir[0]) {
        char cmd[400];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", e->dir);
        if (system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", e->dir);
        e->dir[0] = 0;
    }
}
