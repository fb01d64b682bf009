/* memory.h: allocation for the large arrays of photons, nodes and queries.
 *
 * 64-byte aligned (cache lines, AVX-512 loads). Arrays of 1 MiB or more are mappings whose
 * pages are populated up front: on the machines this project runs on, touching fresh memory
 * page by page ran at 0.3 GB/s. Arrays of 4 MiB or more also start on a 2 MiB boundary and
 * ask for transparent huge pages (MADV_HUGEPAGE, then MADV_POPULATE_WRITE): on these
 * virtual machines even a populated 4 KiB page costs about 1.4 us at its first write (the
 * hypervisor fills its shadow page table lazily), so 512 MB of 4 KiB pages cost 0.07 s to
 * populate and 0.2 s more at first use, while 2 MiB pages populate at about 20 GB/s and are
 * then at full speed. The catch: huge pages come from free 2 MiB blocks, which the guest
 * reports to the hypervisor after 2 s idle (free page reporting), and a reported block
 * costs a host fault per 4 KiB on first touch: "cold", 512 MB populate in 0.6-0.8 s on one
 * thread, so arrays of 64 MiB or more are populated on every thread (0.35-0.45 s on two),
 * against 0.26 s for 4 KiB pages, cold or warm. Back-to-back runs (a pipeline, a
 * benchmark) find them warm. Where the kernel gives no huge pages this is the 4 KiB
 * behaviour. A block's contents are undefined, as malloc's are (a reused mapping holds what
 * it held): clear what must start at zero. Free with pm_free_aligned, never with free(). */
#ifndef PM_MEMORY_H
#define PM_MEMORY_H

#include <stddef.h>

/* NULL when out of memory. bytes may be 0 (a valid pointer to free later). */
void *pm_alloc_aligned(size_t bytes);
/* Frees what pm_alloc_aligned returned; NULL is a no-op. */
void pm_free_aligned(void *p);
/* Keeps up to max_bytes of freed mappings (1 MiB and larger) for later requests, for a stage
 * that takes a stream of documents and allocates the same arrays for each (0, the default:
 * every freed mapping is unmapped at once, and no process holds more than it uses). A request
 * larger than every kept mapping grows the largest kept one of 2 MiB pages: its pages move to
 * the new mapping, and only the rest is fresh, so that documents that grow (a TIME budget's
 * passes) fault in their largest arrays once. */
void pm_memory_reuse(size_t max_bytes);
/* What a stage taking a stream keeps: more than the arrays of one frame of the interactive
 * session (docs/pipelines.md, pipelines/frames), bytes. */
#define PM_MEMORY_STREAM_REUSE ((size_t)1 << 30)

#endif
