/* threads.h: thread counts for OpenMP parallel loops.
 *
 * Determinism rule of the project: a parallel loop's result for item i depends only
 * on i and the inputs (counter-based RNG keyed by i, outputs written to slot i), never
 * on which thread ran it, so files are bit-identical for any --threads. */
#ifndef PM_THREADS_H
#define PM_THREADS_H

#include <stdint.h>

/* Cores available to this process. */
int pm_threads_available(void);

/* Resolves a --threads value (0 = all cores) and makes it the OpenMP default;
 * returns the count in force. */
int pm_threads_use(int64_t requested);

#endif
