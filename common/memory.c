/* memory.c: aligned, huge-page-friendly allocation (see memory.h). */
#include "memory.h"

#include <stdlib.h>
#include <sys/mman.h>

#define PM_HUGE_PAGE ((size_t)2 << 20)   /* bytes: x86-64 transparent huge page */
#define PM_HUGE_MIN ((size_t)4 << 20)    /* bytes: below this, huge pages do not pay */

void *pm_alloc_aligned(size_t bytes)
{
    size_t align = bytes >= PM_HUGE_MIN ? PM_HUGE_PAGE : 64;
    size_t rounded = (bytes + align - 1) & ~(align - 1);
    if (rounded < bytes)
        return NULL; /* overflow */
    void *p = aligned_alloc(align, rounded ? rounded : align);
#ifdef MADV_HUGEPAGE
    if (p && align == PM_HUGE_PAGE)
        madvise(p, rounded, MADV_HUGEPAGE); /* a hint; failure only costs speed */
#endif
    return p;
}
