/* hash.c: XXH3 wrappers (see hash.h). */
#include "base/hash.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <xxhash.h>
#if defined(__x86_64__)
/* libxxhash's run-time dispatch: XXH3 in AVX2 or AVX-512 where the CPU has them (4x the
 * SSE2 default here), the same hash. */
#include <xxh_x86dispatch.h>
#endif

uint64_t pm_hash_bytes(const void *data, size_t n) { return XXH3_64bits(data, n); }

pm_result_t pm_hash_file(const char *path, uint64_t *hash_out)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return pm_error_set(pm_result_of_errno(errno), "cannot open '%s': %s", path, strerror(errno));
    XXH3_state_t *st = XXH3_createState();
    unsigned char *buf = malloc(1 << 16);
    if (!st || !buf) {
        fclose(f);
        XXH3_freeState(st);
        free(buf);
        return pm_error_set(PM_ERR_NOMEM, "out of memory hashing '%s'", path);
    }
    XXH3_64bits_reset(st);
    size_t n;
    while ((n = fread(buf, 1, 1 << 16, f)) > 0)
        XXH3_64bits_update(st, buf, n);
    int err = ferror(f);
    fclose(f);
    *hash_out = XXH3_64bits_digest(st);
    XXH3_freeState(st);
    free(buf);
    if (err)
        return pm_error_set(PM_ERR_IO, "cannot read '%s'", path);
    return PM_OK;
}
