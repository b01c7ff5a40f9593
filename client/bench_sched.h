/* client/bench_sched.h - open-loop arrival schedules for seamtex-bench: the intended send
 * time of every request on one connection, uniform (fixed interval) or Poisson (exponential
 * gaps), from a seeded generator so that a run can be repeated.
 *
 * Owns: the arrival process and its random numbers. Does not own: clocks or sockets; times are
 * plain nanoseconds on whatever clock the caller uses (CLOCK_MONOTONIC in the load tester).
 *
 * Why intended times: a request is due at its intended time whether or not the connection is
 * ready, and latency is measured from that time, so a server that stalls pays for every
 * request it delayed (coordinated omission corrected).
 */
#ifndef STC_BENCH_SCHED_H
#define STC_BENCH_SCHED_H

#include <stdint.h>

typedef enum stc_arrival {
    STC_ARRIVAL_UNIFORM = 0,
    STC_ARRIVAL_POISSON = 1
} stc_arrival;

typedef struct stc_sched {
    uint8_t  kind;         /* stc_arrival */
    double   interval_ns;  /* mean gap between two intended sends */
    double   next_ns;      /* intended time of the next request (double: no drift) */
    uint64_t rng;          /* xorshift64* state, never 0 */
} stc_sched;

/* Sets up a schedule of `rate` requests per second starting at start_ns. Uniform schedules
 * begin at start_ns + phase * interval (phase in [0,1), to stagger connections); Poisson ones
 * at start_ns plus a first exponential gap. rate must be > 0. */
void stc_sched_init(stc_sched *s, stc_arrival kind, double rate, uint64_t start_ns,
                    double phase, uint64_t seed);

/* Intended time of the next request, without consuming it. */
static inline uint64_t stc_sched_peek(const stc_sched *s)
{
    return (uint64_t)s->next_ns;
}

/* Returns the intended time of the next request and moves on to the one after. */
uint64_t stc_sched_next(stc_sched *s);

/* The generator, exposed for the load tester's query mix: uniform 64-bit and [0,1) double. */
uint64_t stc_rng_next(uint64_t *state);
double stc_rng_unit(uint64_t *state);
/* Seeds a state from any 64-bit value (splitmix64, never 0). */
uint64_t stc_rng_seed(uint64_t seed);

#endif
