/* memory.c: aligned allocation with populated large mappings (see memory.h).
 *
 * Every block starts with a 64-byte header that says how it was made, so that one free
 * function serves both kinds and a pointer that did not come from here is caught. A stage
 * that takes a stream of documents turns on a cache of freed mappings (pm_memory_reuse), which
 * hands them out again to a later request they fit: such a stage allocates the same arrays for
 * every document, and a fresh mapping costs a page fault and a page clearing per page, a
 * reused one nothing; a request larger than any it keeps grows the largest (grow_huge). */
#include "base/memory.h"

#include <errno.h>
#include <gnu/libc-version.h>
#include <omp.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/auxv.h>
#include <sys/mman.h>
#include <unistd.h>

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23 /* Linux 5.14; older kernels refuse it and the pages are touched instead */
#endif

#define PM_MAP_MIN ((size_t)1 << 20)  /* bytes: from here on, a populated mapping */
#define PM_HUGE_MIN ((size_t)4 << 20) /* bytes: from here on, 2 MiB pages are asked for */
#define PM_PAR_MIN ((size_t)64 << 20) /* bytes: from here on, populated on every thread */
#define PM_PAGE ((size_t)4096)
#define PM_HUGE ((size_t)2 << 20)
#define PM_HEADER 64u
#define PM_MAGIC_HEAP 0x70bd6d656d686561ull /* "pmtk heap" in spirit */
#define PM_MAGIC_MAP 0x70bd6d656d6d6170ull
#define PM_MAGIC_HUGE 0x70bd6d656d687567ull /* a mapping of whole 2 MiB pages on a 2 MiB boundary */

typedef struct {
    uint64_t magic;
    size_t length; /* of the mapping, bytes */
} block_header_t;

/* The cache of freed mappings, oldest first; off (max 0) until pm_memory_reuse turns it on. A
 * request takes the smallest cached mapping at least its size; a freed mapping past the
 * cache's room pushes out the oldest. */
#define PM_CACHE_SLOTS 64
static struct {
    pthread_mutex_t lock;
    unsigned char *base[PM_CACHE_SLOTS];
    size_t length[PM_CACHE_SLOTS];
    unsigned char huge[PM_CACHE_SLOTS]; /* PM_MAGIC_HUGE's: whole 2 MiB pages on a 2 MiB boundary */
    size_t n, bytes, max;
} cache = {.lock = PTHREAD_MUTEX_INITIALIZER};

/* Takes entry i out of the cache (the lock held). */
static void cache_remove(size_t i)
{
    cache.bytes -= cache.length[i];
    cache.n--;
    memmove(&cache.base[i], &cache.base[i + 1], (cache.n - i) * sizeof cache.base[0]);
    memmove(&cache.length[i], &cache.length[i + 1], (cache.n - i) * sizeof cache.length[0]);
    memmove(&cache.huge[i], &cache.huge[i + 1], (cache.n - i) * sizeof cache.huge[0]);
}

void pm_memory_reuse(size_t max_bytes)
{
    pthread_mutex_lock(&cache.lock);
    cache.max = max_bytes;
    while (cache.n && cache.bytes > cache.max) {
        munmap(cache.base[0], cache.length[0]);
        cache_remove(0);
    }
    pthread_mutex_unlock(&cache.lock);
}

/* A cached mapping taken out of the cache, its length in *len_out and whether it is a huge one
 * in *huge_out; NULL if none. below 0: the smallest of at least len bytes. below 1: the largest
 * huge one shorter than len, for grow_huge. */
static unsigned char *cache_take(size_t len, int below, size_t *len_out, int *huge_out)
{
    pthread_mutex_lock(&cache.lock);
    size_t best = cache.n;
    for (size_t i = 0; i < cache.n; i++) {
        size_t l = cache.length[i];
        int fits = below ? l < len && cache.huge[i] : l >= len;
        if (fits && (best == cache.n || (below ? l > cache.length[best] : l < cache.length[best])))
            best = i;
    }
    unsigned char *b = NULL;
    if (best < cache.n) {
        b = cache.base[best];
        *len_out = cache.length[best];
        *huge_out = cache.huge[best];
        cache_remove(best);
    }
    pthread_mutex_unlock(&cache.lock);
    return b;
}

/* Keeps a freed mapping for a later request, pushing out the oldest to make room; 0 when it
 * does not go in (the cache off, or the mapping larger than all of it): the caller unmaps it. */
static int cache_put(unsigned char *base, size_t len, int huge)
{
    int kept = 0;
    pthread_mutex_lock(&cache.lock);
    if (len <= cache.max) {
        while (cache.n && (cache.n == PM_CACHE_SLOTS || cache.bytes + len > cache.max)) {
            munmap(cache.base[0], cache.length[0]);
            cache_remove(0);
        }
        cache.base[cache.n] = base;
        cache.length[cache.n] = len;
        cache.huge[cache.n] = (unsigned char)huge;
        cache.n++;
        cache.bytes += len;
        kept = 1;
    }
    pthread_mutex_unlock(&cache.lock);
    return kept;
}

/* A mapping of len bytes (a multiple of 2 MiB) that starts on a 2 MiB boundary, so that
 * the kernel can back all of it with huge pages; NULL when mmap fails. */
static unsigned char *map_huge(size_t len)
{
    unsigned char *m = mmap(NULL, len + PM_HUGE, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (m == MAP_FAILED)
        return NULL;
    unsigned char *a = (unsigned char *)(((uintptr_t)m + PM_HUGE - 1) & ~(uintptr_t)(PM_HUGE - 1));
    if (a > m)
        munmap(m, (size_t)(a - m));
    if (a + len < m + len + PM_HUGE)
        munmap(a + len, (size_t)(m + len + PM_HUGE - (a + len)));
    return a;
}

/* Populates bytes [from, len) of the huge mapping at base (from and len multiples of 2 MiB):
 * 0, or -1 when out of memory (nothing then unmapped). */
static int populate_huge(unsigned char *base, size_t from, size_t len)
{
    /* Populated on every thread: pages the hypervisor has taken back (free page
     * reporting) cost it a fault each, about 1.2 s per GB on one thread, 0.8 on two. */
    size_t pieces = (len - from) / PM_HUGE;
    int nt = len - from >= PM_PAR_MIN ? omp_get_max_threads() : 1, err = 0;
#pragma omp parallel for num_threads(nt) schedule(static) reduction(| : err)
    for (int t = 0; t < nt; t++) {
        size_t p0 = pieces * (size_t)t / (size_t)nt, p1 = pieces * (size_t)(t + 1) / (size_t)nt;
        if (p1 > p0 && madvise(base + from + p0 * PM_HUGE, (p1 - p0) * PM_HUGE, MADV_POPULATE_WRITE) != 0)
            err |= errno == EINVAL ? 1 : 2;
    }
    if (err & 2)
        return -1; /* out of memory now, rather than a fault later */
    /* A kernel older than 5.14: touch a byte of every page, in order. */
    if (err)
        for (size_t o = from; o < len; o += PM_PAGE)
            ((volatile unsigned char *)base)[o] = 0;
    return 0;
}

/* A mapping of len bytes made from the cached huge one at old (old_len, shorter): mremap
 * grows it, in place when the addresses after it are free, else moving it (its page tables
 * move; the pages are neither copied nor cleared again), and only the rest is populated. A
 * stream whose documents grow (a TIME budget's passes: 1, 4, then 8 units) then pays the first
 * touch of its largest arrays once, not of every size on the way. One call, so that the
 * mapping stays one area however often it grows (older kernels do not move a range that spans
 * two). NULL when it could not (old unmapped): the caller maps afresh. */
static unsigned char *grow_huge(unsigned char *old, size_t old_len, size_t len)
{
    unsigned char *m = mremap(old, old_len, len, MREMAP_MAYMOVE);
    if (m == MAP_FAILED) {
        munmap(old, old_len); /* unchanged by a failed mremap */
        return NULL;
    }
    madvise(m, len, MADV_HUGEPAGE);
    if (populate_huge(m, old_len, len) != 0) {
        munmap(m, len);
        return NULL;
    }
    return m;
}

void *pm_alloc_aligned(size_t bytes)
{
    if (bytes > SIZE_MAX - PM_HEADER - PM_HUGE - PM_PAGE)
        return NULL;
    size_t total = bytes + PM_HEADER;
    size_t huge_len = (total + PM_HUGE - 1) & ~(PM_HUGE - 1);
    unsigned char *base;
    block_header_t h;
    size_t reused_len;
    int huge;
    if (total >= PM_MAP_MIN &&
        (base = cache_take(total >= PM_HUGE_MIN ? huge_len : (total + PM_PAGE - 1) & ~(PM_PAGE - 1), 0, &reused_len,
                           &huge)) != NULL) {
        h = (block_header_t){huge ? PM_MAGIC_HUGE : PM_MAGIC_MAP, reused_len};
    } else if (total >= PM_HUGE_MIN && (base = cache_take(huge_len, 1, &reused_len, &huge)) != NULL &&
               (base = grow_huge(base, reused_len, huge_len)) != NULL) {
        /* moved to where 2 MiB pages may not line up: kept and reused, not grown again */
        h = (block_header_t){(uintptr_t)base % PM_HUGE == 0 ? PM_MAGIC_HUGE : PM_MAGIC_MAP, huge_len};
    } else if (total >= PM_HUGE_MIN) {
        /* 2 MiB pages: the page tables (and, on the virtual machines this runs on, the
         * hypervisor's shadow of them) get 512 times fewer entries to fill. Populated here,
         * in one call, rather than one fault per page at first touch. */
        base = map_huge(huge_len);
        if (!base)
            return NULL;
        madvise(base, huge_len, MADV_HUGEPAGE); /* advice: where THP is off this is 4 KiB pages */
        if (populate_huge(base, 0, huge_len) != 0) {
            munmap(base, huge_len);
            return NULL;
        }
        h = (block_header_t){PM_MAGIC_HUGE, huge_len};
    } else if (total >= PM_MAP_MIN) {
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
    if (h.magic == PM_MAGIC_MAP || h.magic == PM_MAGIC_HUGE) {
        if (!cache_put(base, h.length, h.magic == PM_MAGIC_HUGE))
            munmap(base, h.length);
    } else if (h.magic == PM_MAGIC_HEAP) {
        free(base);
    } else {
        fprintf(stderr, "pmtk: internal error: pm_free_aligned(%p) of a block it did not allocate\n", p);
        abort();
    }
}

/* 1 when transparent huge pages are on for madvised memory (not "[never]"). */
static int thp_available(void)
{
    FILE *f = fopen("/sys/kernel/mm/transparent_hugepage/enabled", "r");
    if (!f)
        return 0;
    char line[128] = "";
    int ok = fgets(line, sizeof line, f) != NULL && strstr(line, "[never]") == NULL;
    fclose(f);
    return ok;
}

void pm_memory_huge_malloc(char **argv, double t0)
{
    const char *tun = getenv("GLIBC_TUNABLES"), *off = getenv("PMTK_HUGE_MALLOC");
    /* PMTK_START_S set: this image is the re-executed one (glibc drops GLIBC_TUNABLES for a
     * set-user-ID program, AT_SECURE, which would otherwise re-execute for ever) */
    if ((tun && strstr(tun, "glibc.malloc.hugetlb")) || (off && !strcmp(off, "0")) || getenv("PMTK_START_S") ||
        getauxval(AT_SECURE) || !argv || !argv[0])
        return;
    int major = 0, minor = 0;
    if (sscanf(gnu_get_libc_version(), "%d.%d", &major, &minor) != 2 || major * 1000 + minor < 2035 || !thp_available())
        return;
    char value[4096], start[64];
    /* and the heap grown 64 MiB at a time (glibc.malloc.top_pad, bytes), unless the user set
     * its step: grown by 128 KiB it reaches a 2 MiB boundary a page at a time, and those pages
     * fault in as 4 KiB ones. The guarded import of the sky-lit atrium's OBJ took 0.19 to 0.25 s
     * with huge pages alone, 0.14 to 0.15 s with the step (docs/accuracy.md). */
    int pad = !(tun && strstr(tun, "glibc.malloc.top_pad"));
    int n = snprintf(value, sizeof value, "%s%sglibc.malloc.hugetlb=1%s", tun ? tun : "", tun && tun[0] ? ":" : "",
                     pad ? ":glibc.malloc.top_pad=" PM_MEMORY_TOP_PAD : "");
    if (n < 0 || (size_t)n >= sizeof value)
        return;
    snprintf(start, sizeof start, "%.9f", t0);
    if (setenv("GLIBC_TUNABLES", value, 1) == 0 && setenv("PMTK_START_S", start, 1) == 0)
        execv("/proc/self/exe", argv);
    /* not re-executed (no /proc, no room for the variables): go on as this image, and leave
     * the environment as it was */
    if (tun)
        setenv("GLIBC_TUNABLES", tun, 1);
    else
        unsetenv("GLIBC_TUNABLES");
    unsetenv("PMTK_START_S");
}

double pm_memory_started(double now)
{
    const char *v = getenv("PMTK_START_S");
    char *end = NULL;
    double t = v ? strtod(v, &end) : 0.0;
    unsetenv("PMTK_START_S");
    /* a start in the future, or one more than a minute back, is not this program's */
    return v && end != v && *end == '\0' && t <= now && now - t < 60.0 ? t : now;
}
