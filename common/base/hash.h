/* hash.h: content hashes for provenance and caching (XXH3-64 from libxxhash).
 * Provenance compares hashes of inputs, never file dates. */
#ifndef PM_HASH_H
#define PM_HASH_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

/* XXH3-64 of a buffer. */
uint64_t pm_hash_bytes(const void *data, size_t n);

/* XXH3-64 of a whole file's bytes. */
pm_result_t pm_hash_file(const char *path, uint64_t *hash_out);

#endif
