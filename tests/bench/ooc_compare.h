/* tests/bench/ooc_compare.h - bench_native's out-of-core comparison (ooc_compare.c): one
 * library served under a memory budget by seamtexd (SAMPLE batches over loopback), by seamtex
 * in process (the daemon's registry and budget code, no sockets) and by OpenImageIO's
 * TextureSystem in process on the same textures as .tx files, with the same query stream and
 * thread count, alternating the three sides round by round. Bench-only code.
 */
#ifndef OOC_COMPARE_H
#define OOC_COMPARE_H

#include <stdint.h>
#include <stdio.h>

#include "native_lib.h"

#define OOC_MAX_ROUNDS 16
#define OOC_MAX_RES    1024
enum { OOC_DAEMON, OOC_INPROC, OOC_OIIO, OOC_NSIDES };

typedef struct ooc_cfg {
    const char   *dir;       /* the data dir served (native files written or not yet) */
    const char   *txcache;   /* .tx files made from each source, kept between runs */
    const char   *txdir;     /* one .tx copy per set (the caller deletes it) */
    const nl_set *sets;
    int           nsets;
    double        secs;      /* per side, over all rounds */
    int           rounds;    /* 1..OOC_MAX_ROUNDS */
    int           threads;   /* client threads / sampling threads per side */
    uint64_t      budget;    /* bytes; 0 = a quarter of the stored bytes */
    const char   *tx_compression;  /* maketx --compression (zip, none, ...); NULL = zip */
} ooc_cfg;

typedef struct ooc_side {
    const char *name;
    double   qps[OOC_MAX_ROUNDS];        /* per round */
    double   qps_median, p50_ms, p99_ms;
    uint64_t queries, failed;
    double   cold_share;                 /* seamtex: queries of batches to a released set */
    uint64_t releases, majflt;           /* seamtex */
    uint64_t tiles_created, bytes_read;  /* OIIO */
    int      nres;
    double   res_t[OOC_MAX_RES], res_mb[OOC_MAX_RES];   /* resident over time (s, MB) */
    double   rss_mb[OOC_MAX_RES];        /* daemon: VmRSS of the process */
    double   max_res_mb;
} ooc_side;

typedef struct ooc_res {
    int      sets;
    double   stored_mb, budget_mb, tx_disk_mb;
    char     tx_compression[16];
    int      rounds, threads;
    ooc_side side[OOC_NSIDES];
    double   ratio_daemon_oiio, ratio_inproc_oiio;   /* medians of per-round throughput ratios */
} ooc_res;

/* Runs the comparison; prints as it goes. 0, or -1 (printed) when a side cannot be set up. */
int ooc_compare(const ooc_cfg *c, ooc_res *r);
/* The result as one JSON object (no trailing newline). */
void ooc_json(FILE *f, const ooc_res *r);

#endif
