/* SPDX-License-Identifier: MIT */
/* What every benchmark program times with: the monotonic clock and the
 * median of repeated runs. Header-only: each bench is one program. */
#ifndef LODKIT_BENCH_COMMON_H
#define LODKIT_BENCH_COMMON_H

#include <stdlib.h>
#include <time.h>

/* Seconds on the monotonic clock (wall time). */
static inline double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static inline int compare_doubles(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Median of `count` values (sorts them). */
static inline double median(double *values, size_t count)
{
    qsort(values, count, sizeof *values, compare_doubles);
    return count % 2 ? values[count / 2] : 0.5 * (values[count / 2 - 1] + values[count / 2]);
}

#endif
