/* tests/bench/native_lib.c - the generated library, the daemon and the query stream that
 * bench_native's restart and out-of-core parts share (native_lib.h). Bench-only code. */
#include "native_lib.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "datadir.h"
#include "import.h"
#include "../common/testdata.h"

double nl_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

int nl_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double nl_median(double *v, int n)
{
    if (n <= 0)
        return 0;
    qsort(v, (size_t)n, sizeof *v, nl_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void nl_read_load(char *buf, size_t cap)
{
    buf[0] = 0;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (!fgets(buf, (int)cap, f))
            buf[0] = 0;
        fclose(f);
    }
    char *nl = strchr(buf, '\n');
    if (nl)
        *nl = 0;
}

nl_source nl_sources[] = {
    {"ptex-ref/cube8_k7varrot_f32.ptx", "ptx", 0, 0},
    {"ptx/wdas-ptex-samples/holeycube/holeycube.ptx", "ptx", 0, 0},
    {"ptx/wdas-ptex-2009/cube/text/cube.ptx", "ptx", 0, 0},
    {"ptex-ref/cube8_k6_u8.ptx", "ptx", 0, 0},
    {"images/brick.png", "png", 0, 0},
    {"meshes/duck/DuckCM.png", "png", 0, 0},
};
const size_t nl_nsources = sizeof nl_sources / sizeof nl_sources[0];

int nl_copy_file(const char *from, const char *to)
{
    size_t n;
    void *b = st_test_read_file(from, &n);
    if (!b)
        return -1;
    int fd = open(to, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    int ok = fd >= 0 && write(fd, b, n) == (ssize_t)n;
    if (fd >= 0)
        close(fd);
    free(b);
    return ok ? 0 : -1;
}

int nl_make_library(const char *dir, double mb, nl_set **out)
{
    char p[900], q[1200];
    uint64_t total = 0, want = (uint64_t)(mb * 1048576.0);
    int have = 0;
    *out = NULL;
    for (size_t i = 0; i < nl_nsources; i++) {
        if (st_test_data_path(p, sizeof p, nl_sources[i].rel) != 0 || access(p, R_OK) != 0)
            continue;
        st_import_opts o;
        st_import_opts_init(&o);
        st_set *s = NULL;
        st_error e;
        if (st_import_file(p, &o, &s, &e) != 0)
            continue;
        nl_sources[i].texel_bytes = s->texel_bytes;
        nl_sources[i].nfaces = s->info.nfaces;
        st_set_free(s);
        have++;
    }
    if (!have)
        return 0;
    snprintf(p, sizeof p, "%s/sets", dir);
    mkdir(dir, 0700);
    mkdir(p, 0700);
    int n = 0, cap = 0;
    nl_set *sets = NULL;
    for (size_t k = 0; total < want; k++) {
        int si = (int)(k % nl_nsources);
        nl_source *sr = &nl_sources[si];
        if (!sr->texel_bytes)
            continue;
        if (n == cap) {
            cap = cap ? cap * 2 : 64;
            nl_set *ns = realloc(sets, (size_t)cap * sizeof *sets);
            if (!ns) {
                free(sets);
                return -1;
            }
            sets = ns;
        }
        nl_set *ls = &sets[n];
        snprintf(ls->name, sizeof ls->name, "lib%05d", n);
        ls->nfaces = sr->nfaces;
        ls->src = si;
        ls->texel_bytes = sr->texel_bytes;
        snprintf(p, sizeof p, "%s/sets/%s", dir, ls->name);
        mkdir(p, 0700);
        char srcname[64];
        snprintf(srcname, sizeof srcname, "source-%05d.%s", n, sr->ext);
        snprintf(q, sizeof q, "%s/%s", p, srcname);
        char from[1024];
        st_test_data_path(from, sizeof from, sr->rel);
        uint64_t bytes;
        uint32_t crc;
        st_error e;
        if (nl_copy_file(from, q) != 0 || st_file_crc(q, &bytes, &crc, &e) != 0) {
            free(sets);
            return -1;
        }
        snprintf(q, sizeof q, "%s/manifest", p);
        FILE *f = fopen(q, "w");
        if (!f) {
            free(sets);
            return -1;
        }
        fprintf(f, "seamtex-set 1\nname %s\nsource %s\nformat %s\nbytes %llu\ncrc32 %08x\n"
                "options\nend\n", ls->name, srcname, sr->ext, (unsigned long long)bytes, crc);
        fclose(f);
        total += sr->texel_bytes;
        n++;
    }
    *out = sets;
    printf("library: %d sets, %.0f MB of texels, in %s\n", n, (double)total / 1048576.0, dir);
    return n;
}

int nl_link_subset(const char *dir, const nl_set *sets, int n, double mb, const char *sub)
{
    char p[1200], q[1200];
    snprintf(p, sizeof p, "%s/sets", sub);
    if ((mkdir(sub, 0700) != 0 && errno != EEXIST) || (mkdir(p, 0700) != 0 && errno != EEXIST))
        return -1;
    uint64_t total = 0, want = mb > 0 ? (uint64_t)(mb * 1048576.0) : UINT64_MAX;
    int k = 0;
    for (; k < n && total < want; k++) {
        snprintf(p, sizeof p, "%s/sets/%s", sub, sets[k].name);
        mkdir(p, 0700);
        snprintf(p, sizeof p, "%s/sets/%s", dir, sets[k].name);
        DIR *d = opendir(p);
        if (!d)
            return -1;
        struct dirent *de;
        while ((de = readdir(d))) {
            if (de->d_name[0] == '.')
                continue;
            snprintf(p, sizeof p, "%s/sets/%s/%s", dir, sets[k].name, de->d_name);
            snprintf(q, sizeof q, "%s/sets/%s/%s", sub, sets[k].name, de->d_name);
            struct stat st;
            if (stat(p, &st) == 0 && S_ISREG(st.st_mode) && link(p, q) != 0) {
                closedir(d);
                return -1;
            }
        }
        closedir(d);
        total += sets[k].texel_bytes;
    }
    return k;
}

int nl_daemon_start(nl_daemon *d, const char *dir, const char *const *extra)
{
    const char *bdir = getenv("SEAMTEX_BUILD");
    char exe[1024];
    snprintf(exe, sizeof exe, "%s/seamtexd", bdir && *bdir ? bdir : "build");
    snprintf(d->portfile, sizeof d->portfile, "%s.port", dir);
    snprintf(d->logfile, sizeof d->logfile, "%s.log", dir);
    unlink(d->portfile);
    const char *argv[32];
    int ac = 0;
    argv[ac++] = exe;
    argv[ac++] = "--listen";
    argv[ac++] = "127.0.0.1:0";
    argv[ac++] = "--data-dir";
    argv[ac++] = dir;
    argv[ac++] = "--port-file";
    argv[ac++] = d->portfile;
    argv[ac++] = "--no-default-set";
    argv[ac++] = "--max-sets";
    argv[ac++] = "100000";
    for (int i = 0; extra && extra[i] && ac < 30; i++)
        argv[ac++] = extra[i];
    argv[ac] = NULL;
    d->pid = fork();
    if (d->pid == 0) {
        int fd = open(d->logfile, O_WRONLY | O_CREAT | O_APPEND, 0600);
        dup2(fd, 2);
        execv(exe, (char *const *)argv);
        _exit(127);
    }
    return d->pid > 0 ? 0 : -1;
}

stc_conn *nl_daemon_connect(nl_daemon *d, double timeout_s)
{
    double t0 = nl_now_s();
    while (nl_now_s() - t0 < timeout_s) {
        FILE *f = fopen(d->portfile, "r");
        /* the port file is written when the daemon serves */
        if (f) {
            int port = 0;
            if (fscanf(f, "%d", &port) == 1 && port > 0) {
                fclose(f);
                d->port = port;
                int err;
                stc_conn *c = stc_connect("127.0.0.1", (unsigned)port, 60000, &err);
                if (c)
                    return c;
            } else {
                fclose(f);
            }
        }
        int st;
        if (waitpid(d->pid, &st, WNOHANG) == d->pid)
            return NULL;
        usleep(2000);
    }
    return NULL;
}

void nl_daemon_stop(nl_daemon *d)
{
    kill(d->pid, SIGTERM);
    int st;
    waitpid(d->pid, &st, 0);
}

uint64_t nl_stat(stc_conn *c, const char *key)
{
    const stc_stat *s;
    size_t n;
    if (stc_stats(c, &s, &n) != 0)
        return UINT64_MAX;
    for (size_t i = 0; i < n; i++)
        if (!strcmp(s[i].key, key))
            return s[i].u;
    return UINT64_MAX;
}

uint64_t nl_proc_rss(pid_t pid)
{
    char p[64], line[256];
    snprintf(p, sizeof p, "/proc/%d/status", (int)pid);
    FILE *f = fopen(p, "r");
    uint64_t kb = 0;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "VmRSS: %llu", (unsigned long long *)&kb) == 1)
            break;
    if (f)
        fclose(f);
    return kb * 1024;
}

int nl_zipf_init(nl_zipf *z, int n)
{
    z->n = n;
    z->sum = 0;
    z->cdf = malloc((size_t)(n > 0 ? n : 1) * sizeof *z->cdf);
    if (!z->cdf)
        return -1;
    for (int i = 0; i < n; i++)
        z->cdf[i] = (z->sum += 1.0 / (double)(i + 1));   /* Zipf(1.0) */
    return 0;
}

void nl_zipf_free(nl_zipf *z)
{
    free(z->cdf);
    z->cdf = NULL;
}

static uint32_t lcg(uint32_t *r)
{
    *r = *r * 1664525u + 1013904223u;
    return *r;
}

void nl_next_batch(const nl_zipf *z, const nl_set *sets, uint32_t *rng, nl_batch *b)
{
    double x = (double)(lcg(rng) >> 8) / 16777216.0 * z->sum;
    int lo = 0, hi = z->n - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (z->cdf[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    /* popularity rank != name order: spread the popular ones over the library */
    b->set = (int)(((uint64_t)lo * 2654435761u) % (uint64_t)z->n);
    uint32_t nf = sets[b->set].nfaces;
    for (int i = 0; i < NL_BATCH; i++) {
        b->face[i] = (lcg(rng) >> 8) % nf;
        b->u[i] = (float)(lcg(rng) >> 8) / 16777216.0f;
        b->v[i] = (float)(lcg(rng) >> 8) / 16777216.0f;
        b->d[i] = (float)((*rng >> 4) & 15) * 0.003f;
    }
}
