/* memory.c: aligned allocation with populated large mappings (see memory.h).
 *
 * Every block starts with a 64-byte header that says how it was made, so that one free
 * function serves both kinds and a pointer that did not come from here is caught. */
#include "memory.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/mman.h>

#define PM_MAP_MIN ((size_t)1 << 20) /* bytes: from here on, a populated mapping */
#define PM_PAGE ((size_t)4096)
#define PM_HEADER 64u
#define PM_MAGIC_HEAP 0x70bd6d656d686561ull /* "pmtk heap" in spirit */
#define PM_MAGIC_MAP 0x70bd6d656d6d6170ull

typedef struct {
    uint64_t magic;
    size_t length; /* of the mapping, bytes */
} block_header_t;

void *pm_alloc_aligned(size_t bytes)
{
    if (bytes > SIZE_MAX - PM_HEADER - PM_PAGE)
        return NULL;
    size_t total = bytes + PM_HEADER;
    unsigned char *base;
    block_header_t h;
    if (total >= PM_MAP_MIN) {
        size_t len = (total + PM_PAGE - 1) & ~(PM_PAGE - 1);
        void *m = mmap(NULL, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_POPULATE, -1, 0);
        if (m == MAP_FAILED)
            return NULL;
        base = m;
        h = (block_header_t){PM_MAGIC_MAP, len};
    } else {
        base = aligned_alloc(64, (total + 63) & ~(size_t)63);
        if (!base)
            return NULL;
        h = (block_header_t){PM_MAGIC_HEAP, 0};
    }
    *(block_header_t *)base = h;
    return base + PM_HEADER;
}

void pm_free_aligned(void *p)
{
    if (!p)
        return;
    unsigned char *base = (unsigned char *)p - PM_HEADER;
    block_header_t h = *(block_header_t *)base;
    if (h.magic == PM_MAGIC_MAP) {
        munmap(base, h.length);
    } else if (h.magic == PM_MAGIC_HEAP) {
        free(base);
    } else {
        fprintf(stderr, "pmtk: internal error: pm_free_aligned(%p) of a block it did not allocate\n", p);
        abort();
    }
}
