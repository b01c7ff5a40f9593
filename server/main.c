/* server/main.c - seamtexd's entry point: settings, signals, start, reload, stop.
 *
 * Owns: the process: flags and config file, the signal mask (SIGTERM, SIGINT and SIGHUP are
 * blocked in every thread and taken synchronously here with sigwaitinfo, so no handler and no
 * global flag are needed; SIGPIPE and SIGXFSZ are ignored), exit codes (0 clean stop, 1 start
 * failure, 2 bad usage). Runs in the foreground: it never forks (a Debian OpenImageIO quirk hangs in
 * exit() after fork, and service managers want the foreground anyway).
 */
#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "cluster_node.h"
#include "server.h"

int main(int argc, char **argv)
{
    sts_config cfg;
    sts_config_defaults(&cfg);
    char err[512];
    int rc = sts_config_from_args(&cfg, argc, argv, err, sizeof err);
    if (rc == 1)
        return 0;
    if (rc < 0 || sts_config_load_token(&cfg, err, sizeof err) != 0 ||
        sts_config_check(&cfg, err, sizeof err) != 0 ||
        sts_cluster_config_check(&cfg, NULL, 0, err, sizeof err) != 0) {
        fprintf(stderr, "seamtexd: %s\n", err);
        return 2;
    }

    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &set, NULL);  /* before any thread exists: all inherit it */
    signal(SIGPIPE, SIG_IGN);
    /* a file-size limit (ulimit -f, LimitFSIZE=) must fail the one write with EFBIG - an IO
     * reply, "File too large" - not kill the daemon with SIGXFSZ (dur28) */
    signal(SIGXFSZ, SIG_IGN);

    static sts_server srv;  /* large (per-opcode counters); lives for the whole process */
    if (sts_server_init(&srv, &cfg) != 0 || sts_server_start(&srv) != 0) {
        sts_logf(&srv.log, STS_ERROR, "seamtexd did not start");
        return 1;
    }
    for (;;) {
        siginfo_t si;
        int sig = sigwaitinfo(&set, &si);
        if (sig < 0)
            continue;
        if (sig == SIGHUP) {
            sts_config fresh;
            sts_config_defaults(&fresh);
            if (sts_config_from_args(&fresh, argc, argv, err, sizeof err) < 0 ||
                sts_config_load_token(&fresh, err, sizeof err) != 0 ||
                sts_config_check(&fresh, err, sizeof err) != 0) {
                sts_logf(&srv.log, STS_ERROR, "SIGHUP: config not reloaded: %s", err);
                continue;
            }
            sts_server_reload(&srv, &fresh);
            continue;
        }
        sts_logf(&srv.log, STS_INFO, "%s: finishing requests in flight, then stopping",
                 sig == SIGTERM ? "SIGTERM" : "SIGINT");
        break;
    }
    sts_server_stop(&srv, 10000);
    sts_server_free(&srv);
    return 0;
}
