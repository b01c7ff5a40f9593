// tests/bench/ptexcmp/harness.h - the two Ptex harnesses' shared bits (ptexq.cpp,
// ptexopen.cpp): a clock in seconds and the median of a set of runs.
#ifndef PTEXCMP_HARNESS_H
#define PTEXCMP_HARNESS_H

#include <algorithm>
#include <time.h>
#include <vector>

inline double harness_clock(clockid_t c)
{
    struct timespec ts;
    clock_gettime(c, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

inline double harness_median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

#endif
