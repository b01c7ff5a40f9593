/* tests/bench/native_lib.h - what bench_native's parts share (native_lib.c): clocks and
 * medians, the generated library of sets (a sources-only data dir built from the shared .ptx
 * files and images), starting seamtexd on it, and the query stream of the out-of-core runs.
 * Bench-only code: nothing here is part of seamtex.
 *
 * Ownership: nl_make_library returns a malloc'd array of sets (the caller frees it); a
 * daemon started with nl_daemon_start is stopped (SIGTERM, waited for) by nl_daemon_stop.
 */
#ifndef NATIVE_LIB_H
#define NATIVE_LIB_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "seamtex.h"

double nl_now_s(void);
/* Median of v[0..n) (sorts v). */
double nl_median(double *v, int n);
int nl_cmp_double(const void *a, const void *b);
/* The machine's load average ("1.00 2.00 3.00 ..."), written into buf. */
void nl_read_load(char *buf, size_t cap);

/* One source the library is built from (paths relative to SEAMTEX_DATA). */
typedef struct nl_source {
    const char *rel, *ext;
    uint64_t    texel_bytes;   /* of the imported set, 0 when the file is missing */
    uint32_t    nfaces;
} nl_source;
extern nl_source nl_sources[];
extern const size_t nl_nsources;

typedef struct nl_set {
    char     name[32];
    uint32_t nfaces;
    int      src;            /* index into nl_sources */
    uint64_t texel_bytes;
} nl_set;

/* Copies a file (whole, through memory). 0 or -1. */
int nl_copy_file(const char *from, const char *to);

/* A sources-only data dir of about mb MB of texels under dir (set k is a copy of source
 * k % nl_nsources, manifest written as the daemon writes it). Returns the number of sets
 * (0: no shared data), or -1 on an I/O error. */
int nl_make_library(const char *dir, double mb, nl_set **out);

/* A data dir at sub holding hard links to the first sets of the library at dir whose texels
 * add up to at least mb MB (all when mb <= 0 or past the end). Returns how many, -1 on
 * error. */
int nl_link_subset(const char *dir, const nl_set *sets, int n, double mb, const char *sub);

typedef struct nl_daemon {
    pid_t pid;
    int   port;
    char  portfile[1100], logfile[1100];
} nl_daemon;

/* Starts $SEAMTEX_BUILD/seamtexd on data dir dir (port 0; port and log files beside dir),
 * with extra arguments (NULL-terminated, may be NULL). */
int nl_daemon_start(nl_daemon *d, const char *dir, const char *const *extra);
/* Waits (up to timeout_s) until the daemon serves and connects to it; NULL when it died. */
stc_conn *nl_daemon_connect(nl_daemon *d, double timeout_s);
void nl_daemon_stop(nl_daemon *d);
/* A STATS figure by key, UINT64_MAX when missing. */
uint64_t nl_stat(stc_conn *c, const char *key);
/* Resident set size of process pid (VmRSS) in bytes, 0 when unknown. */
uint64_t nl_proc_rss(pid_t pid);

/* ---- the out-of-core query stream ---- */

#define NL_BATCH 256

/* One batch: a set drawn with Zipf(1.0) popularity, NL_BATCH queries on random faces at
 * random (u, v) with an isotropic footprint of 0..0.045 of a face (dudx = dvdy). */
typedef struct nl_batch {
    int      set;
    uint32_t face[NL_BATCH];
    float    u[NL_BATCH], v[NL_BATCH], d[NL_BATCH];
} nl_batch;

typedef struct nl_zipf {
    double *cdf;
    double  sum;
    int     n;
} nl_zipf;

int nl_zipf_init(nl_zipf *z, int n);
void nl_zipf_free(nl_zipf *z);
/* Draws the next batch from *rng (the same seed gives the same stream). */
void nl_next_batch(const nl_zipf *z, const nl_set *sets, uint32_t *rng, nl_batch *b);

#endif
