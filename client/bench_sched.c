/* client/bench_sched.c - uniform and Poisson arrival schedules (bench_sched.h).
 *
 * Owns: the arrival arithmetic and the small generator (splitmix64 seeding, xorshift64*).
 * Does not own: clocks, sockets.
 */
#include "bench_sched.h"

#include <math.h>

uint64_t stc_rng_seed(uint64_t seed)
{
    uint64_t z = seed + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return z ? z : 0x2545F4914F6CDD1Dull;
}

uint64_t stc_rng_next(uint64_t *state)
{
    uint64_t x = *state;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *state = x;
    return x * 0x2545F4914F6CDD1Dull;
}

double stc_rng_unit(uint64_t *state)
{
    return (double)(stc_rng_next(state) >> 11) * (1.0 / 9007199254740992.0);
}

/* Exponential gap of mean `mean`: -mean * ln(1 - U), U in [0,1) so the log is finite. */
static double exp_gap(stc_sched *s, double mean)
{
    return -mean * log1p(-stc_rng_unit(&s->rng));
}

void stc_sched_init(stc_sched *s, stc_arrival kind, double rate, uint64_t start_ns,
                    double phase, uint64_t seed)
{
    s->kind = (uint8_t)kind;
    s->interval_ns = rate > 0.0 ? 1e9 / rate : 1e18;
    s->rng = stc_rng_seed(seed);
    if (phase < 0.0 || !(phase < 1.0))
        phase = 0.0;
    if (kind == STC_ARRIVAL_POISSON)
        s->next_ns = (double)start_ns + exp_gap(s, s->interval_ns);
    else
        s->next_ns = (double)start_ns + phase * s->interval_ns;
}

uint64_t stc_sched_next(stc_sched *s)
{
    uint64_t t = (uint64_t)s->next_ns;
    if (s->kind == STC_ARRIVAL_POISSON)
        s->next_ns += exp_gap(s, s->interval_ns);
    else
        s->next_ns += s->interval_ns;
    return t;
}
