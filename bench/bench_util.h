/* bench_util.h - what every benchmark needs: a monotonic clock and sorting
 * samples for medians and percentiles. */
#ifndef SC_BENCH_UTIL_H
#define SC_BENCH_UTIL_H

#include <stdlib.h>
#include <time.h>

static inline double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static inline int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* splitmix64 on *state: a uniform double in [-1, 1), the same sequence on
 * every machine (seeded queries). */
static inline double bench_rnd(unsigned long long *state)
{
    unsigned long long z = (*state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return 2.0 * (double)((z ^ (z >> 31)) >> 11) * 0x1.0p-53 - 1.0;
}

#endif /* SC_BENCH_UTIL_H */
