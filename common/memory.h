/* memory.h: allocation for the large arrays of photons, nodes and queries.
 *
 * 64-byte aligned (cache lines, AVX-512 loads), and arrays of 4 MiB or more are placed on
 * 2 MiB boundaries with transparent huge pages requested: first-touch page faults were
 * half the time of reading a million-record file, and the gather's random accesses into
 * the photon map miss the TLB far less on huge pages. Free with free(). */
#ifndef PM_MEMORY_H
#define PM_MEMORY_H

#include <stddef.h>

/* NULL when out of memory (or bytes == 0 and the C library says so). */
void *pm_alloc_aligned(size_t bytes);

#endif
