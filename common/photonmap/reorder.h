/* reorder.h: records written in the order of a permutation, for hilbert-sort: the permutation
 * comes from pm_reorder_points (hilbert.h), the records are copied, never changed. */
#ifndef PM_REORDER_H
#define PM_REORDER_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "formats/formats.h"

/* Records per chunk of pm_reorder_write: 3.5 MB at 54 bytes. */
#define PM_REORDER_CHUNK 65536

/* Copies records perm[0..n) of src (rs bytes each) into dst, packed: record perm[i] goes to
 * place i. */
void pm_reorder_gather(unsigned char *dst, const unsigned char *src, const uint32_t *perm, uint64_t n, size_t rs);

/* Writes the n records of rs bytes at recs to w in perm's order, in chunks of
 * PM_REORDER_CHUNK records gathered into buf[0] and buf[1] (PM_REORDER_CHUNK * rs bytes
 * each): one thread writes a chunk (checksum and write; the records are ones a reader has
 * checked, so they are not checked again) while another gathers the next, so the gather's
 * cache misses (the input is in any order) hide behind the writer. A failed write, on
 * whichever thread it ran, is this thread's error on return. Does not commit w. */
pm_result_t pm_reorder_write(pm_writer_t *w, const unsigned char *recs, size_t rs, uint64_t n, const uint32_t *perm,
                             unsigned char *buf[2]);

#endif
