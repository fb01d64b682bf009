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

/* Once per program, at the top of main: re-executes it (/proc/self/exe, the same arguments)
 * with glibc's malloc asked to back its heap and its mappings with transparent huge pages
 * (GLIBC_TUNABLES glibc.malloc.hugetlb=1, glibc 2.35 and later), which every program it starts
 * then inherits. On the virtual machines this runs on each fresh 4 KiB page costs a fault the
 * hypervisor serves slowly (first touch at 0.4 GB/s): loading a 6.8 MB OBJ through assimp took
 * 0.42 to 0.65 s, with huge pages 0.15 to 0.27 s, and a render's stages fault in less as they
 * grow (docs/accuracy.md). Returns, without re-executing, when GLIBC_TUNABLES already names
 * glibc.malloc.hugetlb (a user's choice, or this program's first run), when PMTK_HUGE_MALLOC is
 * 0, when the kernel has transparent huge pages off or glibc is older, or when the exec fails.
 * t0, the program's start (pm_time_wall), goes to the new image in PMTK_START_S. */
void pm_memory_huge_malloc(char **argv, double t0);
/* Bytes the re-executed program's heap grows by at a time (GLIBC_TUNABLES glibc.malloc.top_pad,
 * added beside glibc.malloc.hugetlb unless GLIBC_TUNABLES names it): 64 MiB. */
#define PM_MEMORY_TOP_PAD "67108864"
/* The program's start for a budget that counts from it: PMTK_START_S, which
 * pm_memory_huge_malloc set before it re-executed (and which is taken out of the environment
 * here, so that the programs this one starts do not read it), else now. */
double pm_memory_started(double now);

#endif
