/* server/h_basic.h - handlers of the read-only requests (h_basic.c): HELLO, PING, LIST, INFO,
 * STATS, SAMPLE, SAMPLE_DIR.
 *
 * Owns: nothing shared; these are entries of the dispatch table (dispatch.c). Each follows
 * sts_handler_fn (dispatch.h): appends exactly one reply frame to `out`, which the caller
 * owns.
 */
#ifndef STS_H_BASIC_H
#define STS_H_BASIC_H

#include "cube.h"
#include "dispatch.h"
#include "registry.h"
#include "workers.h"

STS_HANDLER(sts_h_hello);
STS_HANDLER(sts_h_ping);
STS_HANDLER(sts_h_list);
STS_HANDLER(sts_h_info);
STS_HANDLER(sts_h_sample);
STS_HANDLER(sts_h_sample_dir);
STS_HANDLER(sts_h_stats);

/* Samples a decoded SAMPLE / SAMPLE_DIR request (h->opcode tells which) whose queries are at
 * rq->raw and appends the reply (or an error) to out. Returns 0, or STS_DEFER (see
 * sts_sample_prepare). */
int sts_sample_run(sts_ctx *c, const stp_header *h, const stp_sample_req *rq, stp_buf *out);

/* ---- the steps of sts_sample_run, shared with the shared-memory form (shm_sample.c) ---- */

/* A request that passed the checks before sampling: its set (held) and sampler options. */
typedef struct sts_sample_prep {
    st_setref     *ref;      /* released by sts_sample_finish */
    const st_set  *s;
    st_sample_opts o;
    int            cold;     /* the set was released by the memory budget (budget.c) */
    int64_t        t0;
} sts_sample_prep;
/* The checks before sampling, in the order of PROTOCOL.md 4.4: options (INVALID), the set
 * (NOT_FOUND), a cube for SAMPLE_DIR (UNSUPPORTED). 0 with *pp filled (the caller then calls
 * sts_sample_finish), 1 when an error reply was appended to out (nothing held), 2 (only on an
 * I/O thread, c->on_io) when the batch would first build the set's lazy chart data or Ptex
 * table: nothing appended or held, the caller returns STS_DEFER (dispatch.h). */
int sts_sample_prepare(sts_ctx *c, const stp_header *h, const stp_sample_req *rq, stp_buf *out,
                       sts_sample_prep *pp);
/* After sampling rq->count queries with result rc (bad queries, or a negative ST_E* code from
 * the sampler): counts them, or appends the sampler's error reply to out; releases the set.
 * Returns 1 when it appended an error reply, else 0. */
int sts_sample_finish(sts_ctx *c, const stp_header *h, const stp_sample_req *rq,
                      sts_sample_prep *pp, int rc, stp_buf *out);
/* Runs fn(arg, first, count) over [0, n): on this thread, split with idle workers from
 * split-batch queries on (workers.c). The sum of the parts' results, or the first error. */
int sts_sample_parts(sts_ctx *c, size_t n, sts_part_fn fn, void *arg);
/* Widens k wire queries at raw (in rq's layout: opcode, flags bits 2-3, footprint) into q
 * (SAMPLE) or cq (SAMPLE_DIR), caller-owned, k entries. Uses each byte of raw once (the
 * vector widening of 14-byte queries loads the 2 bytes between two queries with both, and
 * keeps them from one load only). */
void sts_sample_decode(uint8_t opcode, const stp_sample_req *rq, const uint8_t *raw, uint32_t k,
                       st_query *q, st_cube_query *cq);

/* The STATS entries, in the order STATS sends them (PROTOCOL.md 4.7): fills at most cap
 * entries of s and returns how many. What STATS encodes and /metrics renders (metrics_text.c),
 * so the two always show the same counters. Any thread. */
size_t sts_stats_collect(sts_server *srv, stp_stat *s, size_t cap);
/* The most entries sts_stats_collect writes. */
size_t sts_stats_max_keys(const sts_server *srv);
/* "queries_<mode>_<filter>" ('-' as '_') for wire values mode, filter; -1 for unnamed ones. */
int sts_queries_key(unsigned mode, unsigned filter, char *key, size_t cap);

#endif
