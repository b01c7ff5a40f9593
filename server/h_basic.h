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

int sts_h_hello(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_ping(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_list(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_info(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_sample(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_sample_dir(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_stats(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);

#endif
