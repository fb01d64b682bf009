/* memory.h: allocation for the large arrays of photons, nodes and queries.
 *
 * 64-byte aligned (cache lines, AVX-512 loads). Arrays of 1 MiB or more are mapped with
 * their pages populated up front (mmap MAP_POPULATE): on the machines this project runs
 * on, touching fresh memory page by page ran at 0.3 GB/s, a third of the time of reading a
 * million-record file, while populating a whole mapping at once runs at about 5 GB/s
 * (tests/bench measures both). Huge pages are requested for them too, where the kernel
 * gives them. Free with pm_free_aligned, never with free(). */
#ifndef PM_MEMORY_H
#define PM_MEMORY_H

#include <stddef.h>

/* NULL when out of memory. bytes may be 0 (a valid pointer to free later). */
void *pm_alloc_aligned(size_t bytes);
/* Frees what pm_alloc_aligned returned; NULL is a no-op. */
void pm_free_aligned(void *p);

#endif
