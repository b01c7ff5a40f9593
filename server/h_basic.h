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

#endif
