/* tests/common/pfpaths.h - the Ptex filters' fast paths against their general path, for the
 * tests that prove a fast path bit for bit (test_ptexfilter_walk, _iso, _const, _nonb,
 * _lean3); the files they read: pffiles.h.
 *
 * Owns nothing: reads the set and the queries the caller owns; its output buffers are its
 * own, allocated per call.
 */
#ifndef ST_TEST_PFPATHS_H
#define ST_TEST_PFPATHS_H

#include <stddef.h>

#include "sample.h"
#include "set.h"

/* The Ptex filters with a kernel (bilinear, box and the width-4 family), for the tests that
 * try them all. */
enum { ST_PF_NKERNEL_FILTERS = 7 };
extern const unsigned st_pf_kernel_filters[ST_PF_NKERNEL_FILTERS];

/* Samples the n queries q with st_ptexfilter_batch (every fast path allowed) and with
 * pf_batch_path(PF_PATH_GENERAL), for each of the nf filters and each mode (Discard,
 * Traverse, Clamp; sharpness 0.3): the failure counts, every output value, coverage and
 * status must be the same bits, and the values and statuses again when st_ptexfilter_batch
 * is asked for no coverage. Returns the queries compared (n x nf x 3), or -1 after
 * printing the first difference to stderr, labelled with what. */
long st_pf_paths_agree(const st_set *s, const st_query *q, size_t n, const char *what,
                       const unsigned *filters, size_t nf);

struct pf_klanes;
/* The 8-query lanes a fast path serves: for each block of 8 of the n queries q, the kernel
 * lanes of filter ft (pf_kernel_lanes_select, the options' width 1 and blur 0) set the block
 * up, then serve(k, arg) returns the lanes it serves (a mask within k's lanes). Returns the
 * lanes served in all, -1 without AVX2 lanes or the set's resolution table. */
long st_pf_lanes_served(const st_set *s, const st_query *q, size_t n, unsigned ft,
                        unsigned (*serve)(const struct pf_klanes *k, void *arg), void *arg);

#endif
