/* server/h_basic.h - handlers of the read-only requests (h_basic.c): HELLO, PING, LIST, INFO,
 * STATS, SAMPLE, SAMPLE_DIR.
 *
 * Owns: nothing shared; these are entries of the dispatch table (dispatch.c). Each follows
 * sts_handler_fn (dispatch.h): appends exactly one reply frame to `out`, which the caller
 * owns.
 */
#ifndef STS_H_BASIC_H
#define STS_H_BASIC_H

#include "dispatch.h"

STS_HANDLER(sts_h_hello);
STS_HANDLER(sts_h_ping);
STS_HANDLER(sts_h_list);
STS_HANDLER(sts_h_info);
STS_HANDLER(sts_h_sample);
STS_HANDLER(sts_h_sample_dir);
STS_HANDLER(sts_h_stats);

/* Samples a decoded SAMPLE / SAMPLE_DIR request (h->opcode tells which) whose queries are at
 * rq->raw and appends the reply (or an error) to out. Returns 0. Used by sts_h_sample and by
 * the shared-memory form (shm.c). */
int sts_sample_run(sts_ctx *c, const stp_header *h, const stp_sample_req *rq, stp_buf *out);

/* The STATS entries, in the order STATS sends them (PROTOCOL.md 4.7): fills at most cap
 * entries of s and returns how many. What STATS encodes and /metrics renders (metrics_text.c),
 * so the two always show the same counters. Any thread. */
size_t sts_stats_collect(sts_server *srv, stp_stat *s, size_t cap);
/* The most entries sts_stats_collect writes. */
size_t sts_stats_max_keys(const sts_server *srv);
/* "queries_<mode>_<filter>" ('-' as '_') for wire values mode, filter; -1 for unnamed ones. */
int sts_queries_key(unsigned mode, unsigned filter, char *key, size_t cap);

#endif
