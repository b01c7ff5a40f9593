/* tests/common/daemon_client.h - libseamtex connections and STATS counters of a test daemon
 * (daemon_fixture.h), for integration tests and benchmarks.
 *
 * Owns: connecting with the options tests use (20 s request timeout, optional token),
 * reading one STATS counter, and waiting until a counter reaches a value (wait.h) - the way a
 * test learns that the daemon has done something instead of sleeping; the random SAMPLE
 * queries over the default set that the wire tests share. Does not own: the
 * daemon's process (daemon_fixture.h) or raw frames (wire.h).
 */
#ifndef ST_DAEMON_CLIENT_H
#define ST_DAEMON_CLIENT_H

#include <stdint.h>

#include "daemon_fixture.h"
#include "seamtex.h"

/* A connection to d (token may be NULL); NULL on failure, with the reason on stderr. */
stc_conn *st_daemon_client(const st_daemon *d, const char *token);

/* The STATS counter `key` read through c, or UINT64_MAX when the call fails or the key is
 * not there. */
uint64_t st_conn_stat(stc_conn *c, const char *key);

/* The same over a connection of its own (opened and closed here: it counts in
 * conns_current while the STATS call runs). */
uint64_t st_daemon_stat(const st_daemon *d, const char *key);

typedef enum st_stat_cmp {
    ST_STAT_EQ,   /* counter == value */
    ST_STAT_GE,   /* counter >= value (and not UINT64_MAX) */
    ST_STAT_LE    /* counter <= value */
} st_stat_cmp;

/* Waits until counter `key` compares to value as cmp says, reading it through c (c NULL: a
 * fresh connection for every read). 0, or -1 on timeout (the last value read is printed). */
int st_wait_stat(const st_daemon *d, stc_conn *c, const char *key, st_stat_cmp cmp,
                 uint64_t value, int timeout_ms);

/* The tests' small deterministic generator (an LCG): the next 24-bit value of state *s. */
uint32_t st_rng_next(uint32_t *s);

/* n SAMPLE queries over the default set's 384 faces (malloc'd, the caller frees): uniform
 * (u, v), some on the edges, footprints from none to large, a few NaN derivatives and faces
 * past the end; the same seed gives the same queries. NULL when out of memory. */
stc_query *st_default_set_queries(size_t n, uint32_t seed);

/* A whole SAMPLE frame (reqid, st_wire_sample_body's parameters) of n of those queries for
 * raw-socket tests: malloc'd (the caller frees), its length in *len; NULL when out of memory. */
uint8_t *st_default_sample_frame(size_t n, uint32_t seed, uint32_t reqid, size_t *len);

#endif
