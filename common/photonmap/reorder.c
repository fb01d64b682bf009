/* reorder.c: writing records in a permutation's order (reorder.h), hilbert-sort's output: a
 * gather of whole records by index, overlapped with the writer. */
#include "photonmap/reorder.h"

#include <string.h>

#define PREFETCH_AHEAD 16 /* records: enough misses in flight to cover DRAM latency */

/* pm_reorder_gather with a bound on prefetching: perm holds `total` indices from perm[0] on.
 * Fixed sizes for the four layouts of the queries format, so that the compiler moves them
 * as whole words. */
static void gather(unsigned char *dst, const unsigned char *src, const uint32_t *perm, uint64_t n, uint64_t total,
                   size_t rs)
{
#define GATHER_FIXED(SIZE)                                                                                             \
    case SIZE:                                                                                                         \
        for (uint64_t i = 0; i < n; i++) {                                                                             \
            if (i + PREFETCH_AHEAD < total)                                                                            \
                __builtin_prefetch(src + (size_t)perm[i + PREFETCH_AHEAD] * (SIZE));                                   \
            memcpy(dst + i * (SIZE), src + (size_t)perm[i] * (SIZE), (SIZE));                                          \
        }                                                                                                              \
        return;
    switch (rs) {
        GATHER_FIXED(40)
        GATHER_FIXED(42)
        GATHER_FIXED(52)
        GATHER_FIXED(54)
    default:
        for (uint64_t i = 0; i < n; i++)
            memcpy(dst + i * rs, src + (size_t)perm[i] * rs, rs);
    }
#undef GATHER_FIXED
}

void pm_reorder_gather(unsigned char *dst, const unsigned char *src, const uint32_t *perm, uint64_t n, size_t rs)
{
    gather(dst, src, perm, n, n, rs);
}

/* Gathers chunk c (of PM_REORDER_CHUNK records) into buf; returns its record count. */
static uint64_t gather_chunk(unsigned char *buf, const unsigned char *recs, const uint32_t *perm, uint64_t n,
                             uint64_t c, size_t rs)
{
    uint64_t first = c * PM_REORDER_CHUNK, m = n - first < PM_REORDER_CHUNK ? n - first : PM_REORDER_CHUNK;
    gather(buf, recs, perm + first, m, n - first, rs);
    return m;
}

/* Chunk c is written while chunk c + 1 is gathered. */
pm_result_t pm_reorder_write(pm_writer_t *w, const unsigned char *recs, size_t rs, uint64_t n, const uint32_t *perm,
                             unsigned char *buf[2])
{
    uint64_t chunks = (n + PM_REORDER_CHUNK - 1) / PM_REORDER_CHUNK, m = 0;
    /* The write may run on a worker thread, whose error message would die with it. */
    pm_error_slot_t err;
    pm_error_slot_init(&err);
    if (chunks)
        m = gather_chunk(buf[0], recs, perm, n, 0, rs);
    for (uint64_t c = 0; c < chunks && err.code == PM_OK; c++) {
        uint64_t next_m = 0;
#pragma omp parallel sections num_threads(2)
        {
#pragma omp section
            pm_error_slot_record(&err, c, pm_writer_write_checked(w, buf[c & 1], m));
#pragma omp section
            if (c + 1 < chunks)
                next_m = gather_chunk(buf[(c + 1) & 1], recs, perm, n, c + 1, rs);
        }
        m = next_m;
    }
    return pm_error_slot_raise(&err);
}
