/* server/server.c - the sts_server: creation (registry, data dir, default set, listening
 * socket), thread start, graceful stop, config reload, token and memory accounting.
 *
 * Owns: the server's lifetime. Does not own: signals (main.c), loading the data dir's sets
 * (startup.c), connections (io.c), requests (dispatch.c and the handlers), the tables the
 * server embeds (handles.c, workers.c, opstats.c).
 */
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <sys/eventfd.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "cluster_node.h"
#include "defaultset.h"
#include "fdio.h"
#include "h_jobs.h"
#include "io.h"
#include "server.h"
#include "unixaddr.h"
#include "startup.h"
#include "uploads.h"
#include "workers.h"

int64_t sts_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

int64_t sts_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

static int mem_fits(sts_server *srv, uint64_t n, uint64_t limit)
{
    uint64_t used = __atomic_load_n(&srv->mem_used, __ATOMIC_RELAXED) +
                    __atomic_load_n(&srv->fetch_mem, __ATOMIC_RELAXED);
    return used + n > limit ? -1 : 0;
}

int sts_mem_take(sts_server *srv, uint64_t n)
{
    return mem_fits(srv, n, STS_LIVE(srv, max_memory));
}

int sts_mem_take_ahead(sts_server *srv, uint64_t n)
{
    return mem_fits(srv, n, STS_LIVE(srv, max_memory) / 2);
}

uint32_t sts_token_check(sts_server *srv, const char *token)
{
    pthread_mutex_lock(&srv->cfg_mu);
    const char *want = srv->cfg.token;
    size_t a = strlen(want), b = strlen(token);
    unsigned diff = (unsigned)(a ^ b);
    for (size_t i = 0; i < b; i++)   /* time depends on the offered token's length only */
        diff |= (unsigned char)token[i] ^ (unsigned char)want[a ? i % a : 0];
    uint32_t gen = (a && !diff) ? srv->token_gen : 0;
    pthread_mutex_unlock(&srv->cfg_mu);
    return gen;
}

int sts_token_allows(sts_server *srv, uint32_t authed)
{
    pthread_mutex_lock(&srv->cfg_mu);
    int ok = !srv->cfg.token[0] || (authed && authed == srv->token_gen);
    pthread_mutex_unlock(&srv->cfg_mu);
    return ok;
}

/* ---- the temp folder without a data dir -----------------------------------------------------
 * Uploads in progress (up to max-uploads x max-upload bytes) and FETCH's image exports need a
 * temp file. With a data dir they go to its tmp/, emptied at every start. Without one they go
 * to a folder of this daemon's own, $TMPDIR/seamtexd.XXXXXX, removed at exit; a killed
 * daemon cannot remove it, so every start removes such folders that no live daemon holds:
 * each daemon holds flock(LOCK_EX) on its folder for its life, and a folder whose lock can be
 * taken belongs to a daemon that is gone. A folder is made under another name
 * (.seamtexd-new.XXXXXX), locked and only then renamed to its final name, so a daemon
 * starting meanwhile never sees a live daemon's folder unlocked. (Before, the temp files lay
 * in $TMPDIR itself and a SIGKILL left them there for good: pc35 measured 252 MiB from 63
 * uploads begun, kept across a restart.) */
#define OWN_TMP_PREFIX "seamtexd."

static void sweep_stale_tmpdirs(sts_server *srv, const char *base)
{
    DIR *dp = opendir(base);
    if (!dp)
        return;
    unsigned removed = 0;
    struct dirent *de;
    while ((de = readdir(dp))) {
        if (strncmp(de->d_name, OWN_TMP_PREFIX, strlen(OWN_TMP_PREFIX)) != 0)
            continue;
        int fd = openat(dirfd(dp), de->d_name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
        if (fd < 0)
            continue;
        struct stat st;
        if (fstat(fd, &st) == 0 && st.st_uid == geteuid() && flock(fd, LOCK_EX | LOCK_NB) == 0) {
            char p[sizeof srv->tmpdir + 300];
            snprintf(p, sizeof p, "%s/%s", base, de->d_name);
            if (stu_remove_tree(p) == 0)
                removed++;
            else
                sts_logf(&srv->log, STS_WARN, "cannot remove %s, the temp folder of a seamtexd "
                         "that is gone", p);
        }
        close(fd);
    }
    closedir(dp);
    if (removed)
        sts_logf(&srv->log, STS_INFO, "removed %u temp folder(s) of seamtexd processes that are "
                 "gone from %s (their uploads in progress)", removed, base);
}

static int private_tmpdir(sts_server *srv, const char *base)
{
    sweep_stale_tmpdirs(srv, base);
    char tmp[sizeof srv->tmpdir], fin[sizeof srv->tmpdir + 32];
    if ((size_t)snprintf(tmp, sizeof tmp, "%s/.seamtexd-new.XXXXXX", base) >= sizeof tmp - 20) {
        sts_logf(&srv->log, STS_ERROR, "temp folder %s: path too long", base);
        return -1;
    }
    int fd = -1;
    if (!mkdtemp(tmp) ||
        (fd = open(tmp, O_RDONLY | O_DIRECTORY | O_CLOEXEC)) < 0 || flock(fd, LOCK_EX) != 0) {
        sts_logf(&srv->log, STS_ERROR, "temp folder in %s: %s (set TMPDIR, or give --data-dir)",
                 base, strerror(errno));
        if (fd >= 0) {
            close(fd);
            rmdir(tmp);
        }
        return -1;
    }
    snprintf(fin, sizeof fin, "%s/" OWN_TMP_PREFIX "%s", base, strrchr(tmp, '.') + 1);
    if (renameat2(AT_FDCWD, tmp, AT_FDCWD, fin, RENAME_NOREPLACE) != 0) {
        sts_logf(&srv->log, STS_ERROR, "temp folder %s: %s", fin, strerror(errno));
        close(fd);
        rmdir(tmp);
        return -1;
    }
    memcpy(srv->tmpdir, fin, strlen(fin) + 1);   /* no longer than tmp: it fits */
    srv->tmpdir_fd = fd;
    return 0;
}

static void raise_nofile(sts_server *srv)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur < rl.rlim_max) {
        rlim_t old = rl.rlim_cur;
        rl.rlim_cur = rl.rlim_max;
        if (setrlimit(RLIMIT_NOFILE, &rl) == 0)
            sts_logf(&srv->log, STS_DEBUG, "open-file limit raised from %llu to %llu",
                     (unsigned long long)old, (unsigned long long)rl.rlim_max);
    }
    if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY &&
        rl.rlim_cur < (rlim_t)srv->cfg.max_conns + 64)
        sts_logf(&srv->log, STS_WARN, "open-file limit %llu is below max-conns %u + 64: "
                 "connections past it fail at accept", (unsigned long long)rl.rlim_cur,
                 srv->cfg.max_conns);
}

int sts_tcp_listen(sts_server *srv, const char *what, const char *host, int port, int backlog,
                   int *bound)
{
    struct addrinfo hints, *res = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    char ps[16];
    snprintf(ps, sizeof ps, "%d", port);
    int rc = getaddrinfo(host, ps, &hints, &res);
    if (rc != 0) {
        sts_logf(&srv->log, STS_ERROR, "%s %s:%d: %s", what, host, port, gai_strerror(rc));
        return -1;
    }
    int fd = -1;
    for (struct addrinfo *ai = res; ai; ai = ai->ai_next) {
        fd = socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
        if (fd < 0)
            continue;
        int one = 1;
        setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        if (bind(fd, ai->ai_addr, ai->ai_addrlen) == 0 && listen(fd, backlog) == 0)
            break;
        sts_logf(&srv->log, STS_ERROR, "%s %s:%d: %s", what, host, port, strerror(errno));
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd < 0)
        return -1;
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    getsockname(fd, (struct sockaddr *)&ss, &sl);
    *bound = ss.ss_family == AF_INET6 ? ntohs(((struct sockaddr_in6 *)&ss)->sin6_port)
                                      : ntohs(((struct sockaddr_in *)&ss)->sin_port);
    return fd;
}

static int open_listener(sts_server *srv)
{
    if (stu_is_unix_addr(srv->cfg.listen)) {
        unsigned mode = (unsigned)strtoul(srv->cfg.unix_mode, NULL, 8);  /* checked by config */
        srv->listen_fd = sts_unix_listen(&srv->ulisten, srv->cfg.listen, mode, &srv->log);
        srv->port = 0;
        return srv->listen_fd >= 0 ? 0 : -1;
    }
    char host[128];
    int port;
    sts_parse_listen(srv->cfg.listen, host, sizeof host, &port);
    srv->listen_fd = sts_tcp_listen(srv, "listen", host, port, 4096, &srv->port);
    return srv->listen_fd < 0 ? -1 : 0;
}

/* path made absolute against the working folder (not resolved: it may not exist yet). */
static void absolute(const char *path, char *out, size_t cap)
{
    char cwd[512];
    if (path[0] == '/' || !getcwd(cwd, sizeof cwd))
        snprintf(out, cap, "%s", path);
    else
        snprintf(out, cap, "%s/%s", cwd, path);
}

/* The data dir's commit warning: a set committed without its native file (the disk filled
 * after UPLOAD_COMMIT promised the room, a file-size limit, EIO). The set is served from
 * memory and the file rebuilt at the next start; the log and STATS say why it is missing. */
static void native_write_failed(void *arg, const char *name, const char *path, const char *why)
{
    sts_server *srv = arg;
    STS_STAT_ADD(srv, native_write_failed, 1);
    sts_logf(&srv->log, STS_WARN,
             "set '%s' committed without its native file %s: %s (served from memory, "
             "rebuilt at the next start)", name, path, why);
}

int sts_server_init(sts_server *srv, const sts_config *cfg)
{
    memset(srv, 0, sizeof *srv);
    srv->cfg = *cfg;
    srv->listen_fd = -1;
    srv->spare_fd = open("/dev/null", O_RDONLY | O_CLOEXEC);  /* io.c: accept_starved */
    srv->tmpdir_fd = -1;
    srv->token_gen = 1;
    srv->started_ms = sts_now_ms();
    sts_log_set_level(&srv->log, cfg->log_level);
    srv->log.format = cfg->log_format;
    srv->metrics.fd = srv->metrics.wakefd = -1;
    pthread_mutex_init(&srv->cfg_mu, NULL);
    pthread_mutex_init(&srv->commit_mu, NULL);
    pthread_mutex_init(&srv->accept_mu, NULL);
    sts_handles_init(&srv->uploads);
    sts_handles_init(&srv->fetches);
    raise_nofile(srv);
    srv->reg = st_registry_create();
    if (!srv->reg) {
        sts_logf(&srv->log, STS_ERROR, "out of memory");
        return -1;
    }
    st_error e;
    st_error_clear(&e);
    /* every folder the daemon writes to is absolute, so a path in a store message always
     * starts with '/' and sts_scrub_paths keeps it out of replies */
    char absdir[sizeof cfg->data_dir + 512];
    if (cfg->data_dir[0]) {
        absolute(cfg->data_dir, absdir, sizeof absdir);
        snprintf(srv->tmpdir, sizeof srv->tmpdir, "%s/tmp", absdir);
    } else {
        const char *t = getenv("TMPDIR");
        char base[sizeof srv->tmpdir];
        absolute(t && *t ? t : "/tmp", base, sizeof base);
        if (private_tmpdir(srv, base) != 0)
            return -1;
    }
    if (cfg->data_dir[0]) {
        if (st_datadir_open(absdir, &srv->dd, &e) != 0) {
            sts_logf(&srv->log, STS_ERROR, "data dir: %s", e.msg);
            return -1;
        }
        st_datadir_set_warn(srv->dd, native_write_failed, srv);
        if (sts_load_datadir(srv) < 0)
            return -1;
    } else {
        sts_logf(&srv->log, STS_WARN, "no --data-dir: uploaded sets live in memory only");
    }
    if (cfg->default_set) {
        st_setref *ref = NULL;
        if (st_registry_get(srv->reg, "default", &ref, NULL) == 0) {
            st_setref_release(ref);
            sts_logf(&srv->log, STS_INFO, "set 'default' comes from the data dir");
        } else {
            st_set *s = NULL;
            int64_t t0 = sts_now_ms();
            if (st_default_set(&s, &e) == 0 &&
                st_registry_put(srv->reg, "default", s, NULL, 0, NULL, &e) == 0)
                sts_logf(&srv->log, STS_INFO, "built-in set 'default' loaded (%u faces, %lld ms)",
                         s->info.nfaces, (long long)(sts_now_ms() - t0));
            else
                sts_logf(&srv->log, STS_WARN, "built-in set 'default' not loaded: %s", e.msg);
        }
    }
    if (open_listener(srv) != 0 || sts_metrics_open(srv) != 0)
        return -1;
    if (cfg->cluster[0] && sts_cluster_init(srv) != 0)
        return -1;
    return 0;
}

/* pin-io: I/O thread i starts pinned to the i-th CPU of the daemon's own affinity mask
 * (taskset, cgroup cpusets), wrapping around, so with io-threads equal to the cores each loop
 * keeps one core's caches; workers are not pinned (split-batch helpers go to whichever CPU
 * is idle). Records the CPU in io->cpu (STATS io<i>_cpu); on failure the thread runs
 * unpinned with a warning. */
static void pin_attr(sts_server *srv, pthread_attr_t *attr, uint32_t i)
{
    cpu_set_t mask;
    CPU_ZERO(&mask);
    int n = sched_getaffinity(0, sizeof mask, &mask) == 0 ? CPU_COUNT(&mask) : 0;
    if (n <= 0) {
        sts_logf(&srv->log, STS_WARN, "pin-io: cannot read the CPU mask: %s", strerror(errno));
        return;
    }
    int want = (int)(i % (uint32_t)n), cpu = -1;
    for (int k = 0, seen = 0; k < CPU_SETSIZE; k++)
        if (CPU_ISSET(k, &mask) && seen++ == want) {
            cpu = k;
            break;
        }
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(cpu, &one);
    int rc = pthread_attr_setaffinity_np(attr, sizeof one, &one);
    if (rc != 0) {
        sts_logf(&srv->log, STS_WARN, "pin-io: I/O thread %u stays unpinned: %s", i,
                 strerror(rc));
        return;
    }
    srv->io[i].cpu = cpu;
}

static int write_port_file(sts_server *srv)
{
    if (!srv->cfg.port_file[0])
        return 0;
    char tmp[1100];
    snprintf(tmp, sizeof tmp, "%s.tmp", srv->cfg.port_file);
    FILE *f = fopen(tmp, "we");
    if (!f) {
        sts_logf(&srv->log, STS_ERROR, "port-file %s: %s", tmp, strerror(errno));
        return -1;
    }
    fprintf(f, "%d\n", srv->port);
    fclose(f);
    if (rename(tmp, srv->cfg.port_file) != 0) {
        sts_logf(&srv->log, STS_ERROR, "port-file %s: %s", srv->cfg.port_file, strerror(errno));
        return -1;
    }
    return 0;
}

int sts_server_start(sts_server *srv)
{
    srv->nio = srv->cfg.io_threads;
    srv->io = calloc(srv->nio, sizeof *srv->io);
    if (!srv->io)
        return -1;
    if (sts_pool_start(srv, &srv->pool, srv->cfg.workers) != 0) {
        sts_logf(&srv->log, STS_ERROR, "cannot start workers");
        return -1;
    }
    if (sts_jobs_start(srv) != 0) {
        sts_logf(&srv->log, STS_ERROR, "cannot start the job thread");
        return -1;
    }
    if (sts_budget_start(srv) != 0) {
        sts_logf(&srv->log, STS_ERROR, "cannot start the memory budget thread");
        return -1;
    }
    if (srv->cfg.memory_budget)
        sts_logf(&srv->log, STS_INFO, "memory budget %llu bytes: cold sets are released past it",
                 (unsigned long long)srv->cfg.memory_budget);
    /* Every I/O thread's state exists before the first thread starts: thread 0 accepts and
     * hands connections to the others (its mutex, its adopt list, its eventfd), which may
     * not have started yet (ThreadSanitizer saw thread 0 lock io[1].mu while main was still
     * initialising it, and write to io[1].wakefd, then 0: stdin). */
    for (uint32_t i = 0; i < srv->nio; i++) {
        sts_io *io = &srv->io[i];
        io->srv = srv;
        io->index = (int)i;
        io->cpu = -1;
        io->ev = sts_ev_create();
        io->wakefd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
        pthread_mutex_init(&io->mu, NULL);
        if (!io->ev || io->wakefd < 0) {
            sts_logf(&srv->log, STS_ERROR, "cannot set up I/O thread %u", i);
            srv->nio = 0;   /* no thread to stop (the process exits) */
            return -1;
        }
    }
    for (uint32_t i = 0; i < srv->nio; i++) {
        pthread_attr_t attr;
        pthread_attr_init(&attr);
        if (srv->cfg.pin_io)
            pin_attr(srv, &attr, i);
        int rc = pthread_create(&srv->io[i].thread, &attr, sts_io_main, &srv->io[i]);
        pthread_attr_destroy(&attr);
        if (rc != 0) {
            sts_logf(&srv->log, STS_ERROR, "cannot start I/O thread %u", i);
            srv->nio = i;
            return -1;
        }
    }
    if (srv->cluster && sts_cluster_start(srv) != 0) {
        sts_logf(&srv->log, STS_ERROR, "cannot start the cluster node");
        return -1;
    }
    if (sts_metrics_start(srv) != 0 || write_port_file(srv) != 0)
        return -1;
    sts_logkv(&srv->log, STS_INFO,
              STS_FIELDS(STS_FS("event", "serving"), STS_FS("listen", srv->cfg.listen),
                         STS_FI("port", srv->port), STS_FI("io_threads", srv->nio),
                         STS_FI("workers", srv->cfg.workers),
                         STS_FI("sets", st_registry_count(srv->reg)),
                         STS_FI("metrics_port", srv->metrics.port)),
              "seamtexd serving on %s (port %d): %u I/O threads, %u workers, %zu sets, token %s",
              srv->cfg.listen, srv->port, srv->nio, srv->cfg.workers,
              st_registry_count(srv->reg), srv->cfg.token[0] ? "required for changes" : "off");
    return 0;
}

void sts_server_stop(sts_server *srv, int grace_ms)
{
    __atomic_store_n(&srv->stopping, 1, __ATOMIC_RELEASE);
    sts_metrics_stop(srv);
    for (uint32_t i = 0; i < srv->nio; i++)
        sts_io_wake(&srv->io[i]);
    /* wait for the I/O threads to drain; past the grace period close what is left */
    int64_t deadline = sts_now_ms() + grace_ms;
    for (;;) {
        uint32_t live = 0;
        for (uint32_t i = 0; i < srv->nio; i++)
            live += __atomic_load_n(&srv->io[i].nconns, __ATOMIC_RELAXED);
        if (!live)
            break;
        if (sts_now_ms() >= deadline) {
            /* peers that do not read their replies, or keep a request half-sent, do not hold
             * the stop: closed now (a request on a worker is still finished first) */
            sts_logf(&srv->log, STS_WARN, "stop: grace period over: closing %u connection%s "
                     "with replies unsent or a request unfinished", live, live == 1 ? "" : "s");
            break;
        }
        struct timespec ts = {0, 10 * 1000000L};
        nanosleep(&ts, NULL);
    }
    __atomic_store_n(&srv->stopping, 2, __ATOMIC_RELEASE);
    for (uint32_t i = 0; i < srv->nio; i++) {
        sts_io_wake(&srv->io[i]);
        pthread_join(srv->io[i].thread, NULL);
    }
    sts_cluster_stop(srv);   /* before the workers: a push may be running on one */
    sts_pool_stop(&srv->pool);
    sts_jobs_stop(srv);
    sts_budget_stop(srv);
    sts_logkv(&srv->log, STS_INFO,
              STS_FIELDS(STS_FS("event", "stopped"), STS_FI("connections", srv->stats.conns_accepted),
                         STS_FI("requests", srv->stats.requests),
                         STS_FI("errors", srv->stats.replies_error),
                         STS_FI("queries", srv->stats.queries)),
              "stopped: %llu connections, %llu requests (%llu errors), %llu queries served",
              (unsigned long long)srv->stats.conns_accepted,
              (unsigned long long)srv->stats.requests,
              (unsigned long long)srv->stats.replies_error,
              (unsigned long long)srv->stats.queries);
}

void sts_server_free(sts_server *srv)
{
    for (uint32_t i = 0; i < srv->nio; i++) {
        sts_io *io = &srv->io[i];
        sts_ev_free(io->ev);
        if (io->wakefd >= 0)
            close(io->wakefd);
        sts_scratch_free(&io->scratch);
        free(io->spare_in[0]);
        free(io->spare_in[1]);
        stp_buf_free(&io->spare_out);
        pthread_mutex_destroy(&io->mu);
    }
    free(srv->io);
    srv->io = NULL;
    if (srv->listen_fd >= 0)
        close(srv->listen_fd);
    if (srv->spare_fd >= 0)
        close(srv->spare_fd);
    sts_metrics_close(srv);
    sts_unix_unlink(&srv->ulisten);
    sts_cluster_free(srv);
    sts_uploads_free(srv);
    sts_handles_destroy(&srv->fetches);   /* emptied by sts_jobs_stop */
    st_registry_free(srv->reg);
    st_datadir_close(srv->dd);
    if (srv->tmpdir_fd >= 0) {   /* the own temp folder (private_tmpdir), uploads freed above */
        stu_remove_tree(srv->tmpdir);
        close(srv->tmpdir_fd);
        srv->tmpdir_fd = -1;
    }
    if (srv->cfg.port_file[0])
        unlink(srv->cfg.port_file);
}

#define SET_LIVE(field) __atomic_store_n(&srv->cfg.field, fresh->field, __ATOMIC_RELAXED)

void sts_server_reload(sts_server *srv, const sts_config *fresh)
{
    char diff[4096];
    int n = sts_config_diff(&srv->cfg, fresh, diff, sizeof diff);
    SET_LIVE(max_conns);
    SET_LIVE(idle_timeout);
    SET_LIVE(request_timeout);
    SET_LIVE(request_min_rate);
    SET_LIVE(conn_fetch_cap);
    SET_LIVE(max_frame);
    SET_LIVE(max_upload);
    SET_LIVE(deadline_ms);
    SET_LIVE(max_batch);
    SET_LIVE(heavy_batch);
    SET_LIVE(split_batch);
    SET_LIVE(shm_max);
    SET_LIVE(conn_out_cap);
    SET_LIVE(max_memory);
    SET_LIVE(max_sets);
    SET_LIVE(memory_budget);
    SET_LIVE(max_uploads);
    SET_LIVE(upload_keep);
    SET_LIVE(max_jobs);
    SET_LIVE(job_threads);
    SET_LIVE(max_set_bytes);
    SET_LIVE(log_level);
    sts_log_set_level(&srv->log, fresh->log_level);
    pthread_mutex_lock(&srv->cfg_mu);
    if (strcmp(srv->cfg.token, fresh->token) != 0) {
        memcpy(srv->cfg.token, fresh->token, sizeof srv->cfg.token);
        srv->token_gen++;  /* connections authenticated with the old token must HELLO again */
    }
    memcpy(srv->cfg.token_file, fresh->token_file, sizeof srv->cfg.token_file);
    pthread_mutex_unlock(&srv->cfg_mu);
    if (n)
        sts_logf(&srv->log, STS_INFO, "reloaded config: %s", diff);
    else
        sts_logf(&srv->log, STS_INFO, "reloaded config: nothing changed");
}
