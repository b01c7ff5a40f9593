/* server/opstats.h - per-opcode request counters and latency histograms for STATS
 * (opstats.c).
 *
 * Owns: for each opcode, the replies given (one per dispatched request), the non-OK ones,
 * and a power-of-two histogram of the time from "request parsed" (sts_dispatch entered) to
 * "reply queued" (appended to the connection's output inline, or ready on a worker before it
 * goes back to the I/O thread). Frames refused before dispatch (bad version, over a size
 * cap, over max-memory) are not requests here; they have their frames_* counters.
 * Does not own: the other STATS keys (h_basic.c), the dispatch decision (dispatch.c).
 *
 * Cost: two clock reads and two or three relaxed atomic adds per request; counters are shared
 * by every thread (like the other STATS counters) and read without a lock, so a STATS taken
 * under load may see a request in its histogram whose error is not counted yet.
 */
#ifndef STS_OPSTATS_H
#define STS_OPSTATS_H

#include <stddef.h>
#include <stdint.h>

#include "proto.h"

/* Bucket 0: under 1 us; bucket b (1..STS_LAT_BUCKETS-2): [2^(b-1), 2^b) us; the last bucket:
 * 2^(STS_LAT_BUCKETS-2) us (67 s) and more. */
#define STS_LAT_BUCKETS 28

typedef struct sts_opstat {
    uint64_t errors;                 /* replies whose status is not OK */
    uint64_t sum_us;                 /* their latencies added up (microseconds) */
    uint64_t lat[STS_LAT_BUCKETS];   /* replies by latency; their sum is the request count */
} sts_opstat;

typedef struct sts_opstats {
    sts_opstat op[256];              /* by opcode (only named opcodes are reported) */
} sts_opstats;

/* Counts one reply of `opcode` for a request parsed at start_us (sts_now_us). The reply is the frame that
 * ends `out`, which held avail_before unsent bytes before it was appended (stp_buf_avail;
 * not a position: appending may move the pending bytes); its status decides whether it is
 * an error. Nothing appended: counted, not as an error. */
void sts_opstats_record(sts_opstats *s, unsigned opcode, int64_t start_us, const stp_buf *out,
                        size_t avail_before);

/* One opcode's counters as they are now: lat[STS_LAT_BUCKETS] (its sum is the request count,
 * returned), errors, sum of latencies in microseconds. What STATS and /metrics both read. */
uint64_t sts_opstats_read(const sts_opstats *s, unsigned opcode, uint64_t *lat,
                          uint64_t *errors, uint64_t *sum_us);
/* The upper bound in microseconds of bucket b (b < STS_LAT_BUCKETS - 1; the last has none). */
uint64_t sts_opstats_bucket_hi_us(unsigned b);

/* The most STATS entries sts_opstats_report writes. */
size_t sts_opstats_max_keys(void);
/* Writes the keys for every named opcode into out (at most cap entries; see PROTOCOL.md 4.7):
 * op_<name>_requests, op_<name>_errors, and for an opcode with requests op_<name>_p50_us,
 * op_<name>_p99_us, op_<name>_sum_us and its non-empty buckets op_<name>_lat_<lo>_<hi>us
 * (op_<name>_lat_over_<lo>us for the last). Returns the entries written. */
size_t sts_opstats_report(const sts_opstats *s, stp_stat *out, size_t cap);

#endif
