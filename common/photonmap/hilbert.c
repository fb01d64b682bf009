/* hilbert.c: the order of hilbert-sort (see hilbert.h): points to cells of a 2^21 grid over
 * their bounding cube, cells to 63-bit Morton codes (the octant at every level, no state),
 * then an MSD radix sort of 64-bit words (the point's index and, above it, the Morton digits
 * of as many levels as fit) that descends the octree one to four levels per pass and stops
 * in cells of `leaf` points or fewer. The curve enters per pass: a cell in
 * orientation s maps the Morton digits of its next k levels to curve digits (and the child's
 * orientation) with one look-up in a table made from the L-system, so that no per-point chain
 * of look-ups through 21 levels is needed.
 *
 * Why this shape: sorting one 8-byte word per point moves 8 bytes per point per pass instead
 * of a 40 to 56-byte record (or a 12-byte code and index), and the records are gathered once
 * by the caller; the root's counts are made with the words, and a last pass whose children
 * are all leaves puts the indices straight into the permutation; the first passes (large cells, memory-bound) run on
 * every thread, the cells below them are independent and shared out dynamically. Every pass is a stable counting
 * scatter, whose result does not depend on how the input was split among threads, so the permutation is the same for
 * any thread count. */
#include "photonmap/hilbert.h"

#include <inttypes.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <xmmintrin.h>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "base/memory.h"
#include "base/timer.h"

/* Derived by tests/unit/test_hilbert.c from the symmetries of the cube (rotations only):
 * state 0 visits the octants in Gray-code order, entering at corner (0,0,0) and leaving at
 * (0,0,1); each child's orientation is the rotation that makes its entry corner the previous
 * child's exit corner. Twelve orientations are reachable. */
const uint8_t pm_hilbert_order[PM_HILBERT_STATES][8] = {
    {0, 1, 3, 2, 6, 7, 5, 4}, {0, 2, 6, 4, 5, 7, 3, 1}, {0, 4, 5, 1, 3, 7, 6, 2}, {5, 1, 0, 4, 6, 2, 3, 7},
    {3, 2, 0, 1, 5, 4, 6, 7}, {6, 2, 3, 7, 5, 1, 0, 4}, {5, 7, 3, 1, 0, 2, 6, 4}, {6, 4, 0, 2, 3, 1, 5, 7},
    {5, 4, 6, 7, 3, 2, 0, 1}, {3, 7, 6, 2, 0, 4, 5, 1}, {3, 1, 5, 7, 6, 4, 0, 2}, {6, 7, 5, 4, 0, 1, 3, 2},
};
const uint8_t pm_hilbert_child[PM_HILBERT_STATES][8] = {
    {1, 2, 0, 3, 4, 5, 5, 6},  {2, 0, 1, 4, 7, 8, 8, 9},  {0, 1, 2, 7, 3, 10, 10, 11}, {8, 6, 3, 10, 2, 7, 7, 4},
    {10, 9, 4, 5, 0, 3, 3, 7}, {11, 7, 5, 1, 9, 6, 6, 0}, {3, 8, 6, 11, 10, 0, 0, 5},  {5, 11, 7, 8, 1, 4, 4, 3},
    {6, 3, 8, 2, 11, 9, 9, 1}, {4, 10, 9, 6, 5, 1, 1, 8}, {9, 4, 10, 0, 6, 11, 11, 2}, {7, 5, 11, 9, 8, 2, 2, 10},
};

const char *const pm_order_names[] = {"none", "morton", "hilbert", NULL};

#define LEVELS PM_HILBERT_LEVELS
#define CELLS (1u << LEVELS) /* cells per axis at the deepest level */
#define MAX_PASS_LEVELS 4    /* levels per radix pass: 4096 buckets, 16 KiB of counts */
#define MAX_BUCKETS (1u << (3 * MAX_PASS_LEVELS))
#define PAR_MIN_POINTS 65536 /* cells at least this large (and a large share) get a parallel pass */

/* Per-pass tables: for a pass of k levels (1..4) over a cell in state s, entry
 * [s * 8^k + m] of t[k] maps the cell's next k Morton digits m (3 bits per level, the top
 * level first) to its k curve digits (low 12 bits) and the state of the cell they lead to
 * (bits 12 to 15). 12 states x 4096 x 2 bytes = 96 KiB for k = 4. */
typedef struct {
    uint16_t *t[MAX_PASS_LEVELS + 1];
} digit_tables_t;

static void digit_tables_free(digit_tables_t *d)
{
    for (unsigned k = 1; k <= MAX_PASS_LEVELS; k++)
        free(d->t[k]);
}

static pm_result_t digit_tables_build(pm_order_t order, digit_tables_t *d)
{
    uint8_t rank[PM_HILBERT_STATES][8];
    for (unsigned s = 0; s < PM_HILBERT_STATES; s++)
        for (unsigned r = 0; r < 8; r++)
            rank[s][pm_hilbert_order[s][r]] = (uint8_t)r;
    memset(d, 0, sizeof *d);
    for (unsigned k = 1; k <= MAX_PASS_LEVELS; k++) {
        unsigned nb = 1u << (3 * k);
        d->t[k] = malloc((size_t)PM_HILBERT_STATES * nb * sizeof *d->t[k]);
        if (!d->t[k]) {
            digit_tables_free(d);
            return pm_error_set(PM_ERR_NOMEM, "out of memory for the curve tables");
        }
        for (unsigned s0 = 0; s0 < PM_HILBERT_STATES; s0++)
            for (unsigned m = 0; m < nb; m++) {
                unsigned s = s0, digits = 0;
                for (int j = (int)k - 1; j >= 0; j--) {
                    unsigned o = (m >> (3 * j)) & 7, r = order == PM_ORDER_HILBERT ? rank[s][o] : o;
                    digits = digits << 3 | r;
                    s = order == PM_ORDER_HILBERT ? pm_hilbert_child[s][r] : 0;
                }
                d->t[k][(size_t)s0 * nb + m] = (uint16_t)(digits | s << 12);
            }
    }
    return PM_OK;
}

static inline uint32_t cell_of(float x, double lo, double scale)
{
    double c = ((double)x - lo) * scale;
    c = c > 0.0 ? c : 0.0; /* clamped without branches (maxsd, minsd): c is never NaN */
    c = c < (double)(CELLS - 1) ? c : (double)(CELLS - 1);
    return (uint32_t)c;
}

/* The 21 bits of v spread to every third bit (bit i to bit 3i). */
static inline uint64_t spread3(uint32_t v)
{
    uint64_t x = v & (CELLS - 1);
    x = (x | x << 32) & 0x001f00000000ffffull;
    x = (x | x << 16) & 0x001f0000ff0000ffull;
    x = (x | x << 8) & 0x100f00f00f00f00full;
    x = (x | x << 4) & 0x10c30c30c30c30c3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
}

/* The Morton code: at every level, from the top, the octant x | y << 1 | z << 2. */
static inline uint64_t morton_of(uint32_t x, uint32_t y, uint32_t z)
{
    return spread3(x) | spread3(y) << 1 | spread3(z) << 2;
}

/* Position i: copied out, since records of 42 or 54 bytes leave it unaligned for a float. */
static inline void point(const void *pos, size_t stride, uint64_t i, float p[3])
{
    memcpy(p, (const unsigned char *)pos + i * stride, 3 * sizeof(float));
}

uint64_t pm_reorder_key(pm_order_t order, const float xyz[3], const double lo[3], double scale)
{
    uint64_t m = morton_of(cell_of(xyz[0], lo[0], scale), cell_of(xyz[1], lo[1], scale), cell_of(xyz[2], lo[2], scale));
    if (order != PM_ORDER_HILBERT)
        return m;
    uint8_t rank[PM_HILBERT_STATES][8];
    for (unsigned s = 0; s < PM_HILBERT_STATES; s++)
        for (unsigned r = 0; r < 8; r++)
            rank[s][pm_hilbert_order[s][r]] = (uint8_t)r;
    uint64_t key = 0;
    unsigned s = 0;
    for (int l = LEVELS - 1; l >= 0; l--) {
        unsigned r = rank[s][(m >> (3 * l)) & 7];
        key = key << 3 | r;
        s = pm_hilbert_child[s][r];
    }
    return key;
}

void pm_reorder_cube(const void *pos, size_t stride, uint64_t n, double lo_out[3], double *scale_out)
{
    /* Worker threads take the caller's floating-point mode (FTZ/DAZ), so that a subnormal
     * coordinate compares the same on every thread and the cube does not depend on --threads. */
    unsigned csr = _mm_getcsr();
    float mn0 = 0, mn1 = 0, mn2 = 0, mx0 = 0, mx1 = 0, mx2 = 0;
    if (n) {
        float p[3];
        point(pos, stride, 0, p);
        mn0 = mx0 = p[0], mn1 = mx1 = p[1], mn2 = mx2 = p[2];
    }
#pragma omp parallel reduction(min : mn0, mn1, mn2) reduction(max : mx0, mx1, mx2) if (n > 100000)
    {
        _mm_setcsr(csr);
#pragma omp for schedule(static)
        for (uint64_t i = 0; i < n; i++) {
            float p[3];
            point(pos, stride, i, p);
            mn0 = p[0] < mn0 ? p[0] : mn0, mx0 = p[0] > mx0 ? p[0] : mx0;
            mn1 = p[1] < mn1 ? p[1] : mn1, mx1 = p[1] > mx1 ? p[1] : mx1;
            mn2 = p[2] < mn2 ? p[2] : mn2, mx2 = p[2] > mx2 ? p[2] : mx2;
        }
    }
    /* In double: the side of a cube from -3e38 to 3e38 overflows a float, not a double. */
    double side = (double)mx0 - mn0;
    if ((double)mx1 - mn1 > side)
        side = (double)mx1 - mn1;
    if ((double)mx2 - mn2 > side)
        side = (double)mx2 - mn2;
    lo_out[0] = mn0, lo_out[1] = mn1, lo_out[2] = mn2;
    *scale_out = side > 0.0 ? (double)CELLS / side : 0.0;
}

uint64_t pm_reorder_auto_leaf(uint64_t n, uint64_t cache_bytes)
{
    /* The model of docs/programs/hilbert-sort.md: the gather's cost is flat for leaves up to
     * its packet width W and grows beyond; the sort's cost grows with the octree levels it
     * descends, about log8(n / leaf), each level a pass over the points' 12-byte (key,
     * index) pairs, cheap while they fit in the cache. */
    const uint64_t W = 16; /* queries per gather packet: 16 float lanes of AVX-512 */
    if (n <= W)
        return n ? n : 1;
    if (n * 12 <= cache_bytes) /* every level is an in-cache pass: the full order costs little */
        return 1;
    /* Levels the default leaf W needs, then the smallest leaf reached with no more levels. */
    unsigned d = 0;
    uint64_t cells = 1;
    while (d < LEVELS && n > W * cells)
        d++, cells *= 8;
    uint64_t leaf = (n + cells - 1) / cells;
    return leaf < 1 ? 1 : leaf > W ? W : leaf;
}

/* ---- the radix sort ---- */

/* A point is one 64-bit word: its index in the low `ib` bits and, above them, the Morton
 * digits of `cap` consecutive levels of its cell (a window starting at level `base`, its
 * top level in the highest digit). A pass moves 8 bytes per point, one array, instead of an
 * 8-byte code and a 4-byte index in two. 10 million points take 24 index bits and leave 13
 * levels, more than leaves of 16 need unless points cluster; a cell that goes deeper than
 * its window has its words rewritten from the positions with the next levels (refill). */
typedef struct {
    uint64_t *w[2]; /* words, in one of two buffers; a pass moves a cell to the other */
    uint32_t *perm; /* the caller's permutation, where every leaf ends up */
    uint64_t leaf;
    unsigned ib, cap; /* index bits; levels of Morton digits a word holds */
    uint64_t imask;   /* the index bits */
    digit_tables_t tab;
    const void *pos; /* the points, for refills */
    size_t stride;
    double lo[3], scale;
} sorter_t;

typedef struct {
    uint64_t leaves;
    unsigned depth;
} tally_t;

/* Work left after the parallel passes: a cell to sort, or a leaf to put in place. */
typedef struct {
    uint64_t b, m;   /* the range [b, b + m) */
    uint8_t level;   /* its depth in the octree */
    uint8_t base;    /* the first level its words hold */
    uint8_t state;   /* its orientation */
    uint8_t buf;     /* which buffer holds it */
    uint8_t is_leaf; /* 1: a leaf, 2: a leaf whose indices must be put back in input order */
} work_t;

typedef struct {
    work_t *w;
    size_t n, cap;
} worklist_t;

static int by_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* The digits of levels [base, base + cap) of a 63-bit Morton code (levels past the last
 * are 0), in the low 3 * cap bits. */
static inline uint64_t window(uint64_t morton, unsigned base, unsigned cap)
{
    int sh = 3 * ((int)LEVELS - (int)(base + cap));
    uint64_t v = sh >= 0 ? morton >> sh : morton << -sh;
    return v & ((1ull << (3 * cap)) - 1);
}

static inline uint64_t point_morton(const sorter_t *s, uint64_t i)
{
    float p[3];
    point(s->pos, s->stride, i, p);
    return morton_of(cell_of(p[0], s->lo[0], s->scale), cell_of(p[1], s->lo[1], s->scale),
                     cell_of(p[2], s->lo[2], s->scale));
}

/* The cell [b, b + m) of buffer buf descends below its words' window: rewrite them with
 * the digits of levels [level, level + cap). Rare: only clustered points get here. */
static void refill(const sorter_t *s, int buf, uint64_t b, uint64_t m, unsigned level)
{
    uint64_t *w = s->w[buf] + b;
    for (uint64_t j = 0; j < m; j++) {
        uint64_t i = w[j] & s->imask;
        w[j] = window(point_morton(s, i), level, s->cap) << s->ib | i;
    }
}

/* Levels for the next pass over a cell of m points at `level`: as many (up to 4) as keep the
 * average child above the leaf size, so that few leaves fall inside a pass. */
static unsigned pass_levels(uint64_t m, uint64_t leaf, unsigned level)
{
    unsigned k = 1;
    while (k < MAX_PASS_LEVELS && level + k < LEVELS && (m >> (3 * (k + 1))) >= leaf)
        k++;
    return k;
}

/* The pass over a cell of m points at `level` whose words hold levels from *base: its
 * levels k, within the window (refilling the cell when the window is used up). */
static unsigned plan_pass(const sorter_t *s, int buf, uint64_t b, uint64_t m, unsigned level, unsigned *base)
{
    unsigned k = pass_levels(m, s->leaf, level);
    if (level + k > *base + s->cap) {
        if (level == *base + s->cap) {
            refill(s, buf, b, m, level);
            *base = level;
        } else {
            k = *base + s->cap - level;
        }
    }
    return k;
}

/* The shift that brings the digits of levels [level, level + k) to the bottom of a word. */
static inline unsigned pass_shift(const sorter_t *s, unsigned level, unsigned base, unsigned k)
{
    return s->ib + 3 * (s->cap - (level - base) - k);
}

/* A leaf: its points keep their input order. Points that share a cell of the last pass
 * already are (every pass is stable); a leaf found at a level inside a multi-level pass was
 * also ordered by the levels below it, and is sorted back by index (resort). */
static void leaf_done(const sorter_t *s, int buf, uint64_t b, uint64_t m, unsigned level, int resort, tally_t *t)
{
    uint32_t *dst = s->perm + b;
    const uint64_t *w = s->w[buf] + b;
    for (uint64_t i = 0; i < m; i++)
        dst[i] = (uint32_t)(w[i] & s->imask);
    if (resort) {
        if (m <= 32) {
            for (uint64_t i = 1; i < m; i++) {
                uint32_t v = dst[i];
                uint64_t j = i;
                for (; j > 0 && dst[j - 1] > v; j--)
                    dst[j] = dst[j - 1];
                dst[j] = v;
            }
        } else {
            qsort(dst, m, sizeof *dst, by_u32);
        }
    }
    t->leaves++;
    if (level > t->depth)
        t->depth = level;
}

/* One pass: the bucket (curve digits of k levels) of a word, in a cell of state s. */
#define BUCKET(tab, word) ((tab)[((word) >> shift) & (nb - 1)] & (nb - 1))

static void sort_cell(const sorter_t *s, int buf, uint64_t b, uint64_t m, unsigned level, unsigned base, unsigned state,
                      uint32_t *scratch, tally_t *t);

/* Walks the cells of one pass, from the pass's first level (j = 1) to its last (j = k), over
 * the bucket ends `end` (relative to b): empty cells are skipped, small ones are leaves, the
 * rest are sorted (now) or queued (list != NULL: the parallel top). tab is the pass's table
 * row, which gives each bucket's state. */
static void visit(const sorter_t *s, int buf, uint64_t b, const uint32_t *end, unsigned k, unsigned level,
                  unsigned base, const uint16_t *tab, unsigned j, unsigned first, uint32_t *scratch, tally_t *t,
                  worklist_t *list, int *oom)
{
    unsigned span = 1u << (3 * (k - j)), nb = 1u << (3 * k), shift = pass_shift(s, level, base, k);
    uint64_t lo = first ? end[first - 1] : 0, hi = end[first + span - 1], m = hi - lo;
    if (m == 0)
        return;
    if (m <= s->leaf || j == k) {
        int leaf = m <= s->leaf;
        unsigned child = leaf ? 0 : tab[(s->w[buf][b + lo] >> shift) & (nb - 1)] >> 12;
        if (!list) {
            if (leaf)
                leaf_done(s, buf, b + lo, m, level + j, j < k, t);
            else
                sort_cell(s, buf, b + lo, m, level + k, base, child, scratch, t);
            return;
        }
        if (list->n == list->cap) {
            size_t cap = list->cap ? 2 * list->cap : 4096;
            work_t *w = realloc(list->w, cap * sizeof *w);
            if (!w) {
                *oom = 1;
                return;
            }
            list->w = w, list->cap = cap;
        }
        list->w[list->n++] = (work_t){b + lo,
                                      m,
                                      (uint8_t)(leaf ? level + j : level + k),
                                      (uint8_t)base,
                                      (uint8_t)child,
                                      (uint8_t)buf,
                                      (uint8_t)(leaf ? (j < k ? 2 : 1) : 0)};
        return;
    }
    for (unsigned c = 0; c < 8; c++)
        visit(s, buf, b, end, k, level, base, tab, j + 1, first + c * (span / 8), scratch, t, list, oom);
}

/* Sorts the cell [b, b + m) at `level` in orientation `state`, held in buffer buf, on this
 * thread. scratch holds LEVELS x (MAX_BUCKETS + 1) counts: one row per level, so that the
 * recursion (which only goes deeper) never reuses a row still in use. */
static void sort_cell(const sorter_t *s, int buf, uint64_t b, uint64_t m, unsigned level, unsigned base, unsigned state,
                      uint32_t *scratch, tally_t *t)
{
    for (;;) {
        if (m <= s->leaf || level >= LEVELS) {
            leaf_done(s, buf, b, m, level, 0, t);
            return;
        }
        unsigned k = plan_pass(s, buf, b, m, level, &base), nb = 1u << (3 * k);
        unsigned shift = pass_shift(s, level, base, k);
        const uint16_t *tab = s->tab.t[k] + (size_t)state * nb;
        uint32_t *cnt = scratch + (size_t)level * (MAX_BUCKETS + 1);
        const uint64_t *ws = s->w[buf] + b;
        memset(cnt, 0, nb * sizeof *cnt);
        for (uint64_t i = 0; i < m; i++)
            cnt[BUCKET(tab, ws[i])]++;
        if (cnt[BUCKET(tab, ws[0])] == m) { /* one child holds them all: no move */
            state = tab[(ws[0] >> shift) & (nb - 1)] >> 12;
            level += k;
            continue;
        }
        uint32_t sum = 0, most = 0, filled = 0;
        for (unsigned x = 0; x < nb; x++) {
            uint32_t c = cnt[x];
            cnt[x] = sum;
            sum += c;
            most = c > most ? c : most;
            filled += c > 0;
        }
        if (k == 1 && most <= s->leaf) {
            /* Every child is a leaf: its indices go straight to their places, in input
             * order (the pass is stable), with no copy through the other buffer. */
            uint32_t *dst = s->perm + b;
            for (uint64_t i = 0; i < m; i++)
                dst[cnt[BUCKET(tab, ws[i])]++] = (uint32_t)(ws[i] & s->imask);
            t->leaves += filled;
            if (level + 1 > t->depth)
                t->depth = level + 1;
            return;
        }
        uint64_t *wd = s->w[!buf] + b;
        for (uint64_t i = 0; i < m; i++)
            wd[cnt[BUCKET(tab, ws[i])]++] = ws[i];
        /* cnt[x] is now the end of bucket x */
        for (unsigned c = 0; c < 8; c++)
            visit(s, !buf, b, cnt, k, level, base, tab, 1, c * (nb / 8), scratch, t, NULL, NULL);
        return;
    }
}

/* A pass over a large cell on every thread: counts over nthreads contiguous slices, then a
 * stable scatter (slice i before slice i+1 within every bucket: the same result as one
 * thread). Children still large get another parallel pass; the rest are queued. counted:
 * the first pass's counts are already in hist (made with the words, at the root). */
static pm_result_t par_cell(const sorter_t *s, int buf, uint64_t b, uint64_t m, unsigned level, unsigned base,
                            unsigned state, uint64_t big, uint32_t *hist, int nthreads, int counted, worklist_t *list,
                            tally_t *t)
{
    for (;; counted = 0) {
        if (m <= s->leaf || level >= LEVELS) {
            leaf_done(s, buf, b, m, level, 0, t);
            return PM_OK;
        }
        unsigned k = plan_pass(s, buf, b, m, level, &base), nb = 1u << (3 * k);
        unsigned shift = pass_shift(s, level, base, k);
        const uint16_t *tab = s->tab.t[k] + (size_t)state * nb;
        const int used = nthreads; /* slices, whatever the team size */
        if (!counted) {
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
            for (int th = 0; th < used; th++) {
                uint64_t i0 = b + m * (uint64_t)th / (uint64_t)used, i1 = b + m * (uint64_t)(th + 1) / (uint64_t)used;
                uint32_t *h = hist + (size_t)th * MAX_BUCKETS;
                const uint64_t *ws = s->w[buf];
                memset(h, 0, nb * sizeof *h);
                for (uint64_t i = i0; i < i1; i++)
                    h[BUCKET(tab, ws[i])]++;
            }
        }
        /* Bucket starts per slice: bucket by bucket, slice by slice. */
        uint32_t sum = 0;
        for (unsigned x = 0; x < nb; x++)
            for (int th = 0; th < used; th++) {
                uint32_t c = hist[(size_t)th * MAX_BUCKETS + x];
                hist[(size_t)th * MAX_BUCKETS + x] = sum;
                sum += c;
            }
        /* One child holds every point: go a pass deeper without moving anything. Slice 0's
         * starts are the buckets' starts. */
        uint64_t word0 = s->w[buf][b];
        unsigned first = BUCKET(tab, word0);
        uint64_t stop = first + 1 < nb ? hist[first + 1] : m;
        if (stop - hist[first] == m) {
            state = tab[(word0 >> shift) & (nb - 1)] >> 12;
            level += k;
            continue;
        }
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
        for (int th = 0; th < used; th++) {
            uint64_t i0 = b + m * (uint64_t)th / (uint64_t)used, i1 = b + m * (uint64_t)(th + 1) / (uint64_t)used;
            uint32_t *h = hist + (size_t)th * MAX_BUCKETS;
            const uint64_t *ws = s->w[buf];
            uint64_t *wd = s->w[!buf] + b;
            for (uint64_t i = i0; i < i1; i++)
                wd[h[BUCKET(tab, ws[i])]++] = ws[i];
        }
        /* The last slice's cursors are the bucket ends. */
        uint32_t *end = malloc((size_t)nb * sizeof *end);
        if (!end)
            return pm_error_set(PM_ERR_NOMEM, "out of memory sorting %" PRIu64 " points", m);
        memcpy(end, hist + (size_t)(used - 1) * MAX_BUCKETS, (size_t)nb * sizeof *end);
        size_t first_new = list->n;
        int oom = 0;
        for (unsigned c = 0; c < 8 && !oom; c++)
            visit(s, !buf, b, end, k, level, base, tab, 1, c * (nb / 8), NULL, t, list, &oom);
        free(end);
        if (oom)
            return pm_error_set(PM_ERR_NOMEM, "out of memory sorting %" PRIu64 " points", m);
        /* Large children: another parallel pass each, in place of their queue entry. */
        for (size_t i = first_new; i < list->n; i++) {
            work_t w = list->w[i];
            if (w.is_leaf || w.m < big)
                continue;
            list->w[i].m = 0; /* done here */
            pm_result_t r = par_cell(s, w.buf, w.b, w.m, w.level, w.base, w.state, big, hist, nthreads, 0, list, t);
            if (r != PM_OK)
                return r;
        }
        return PM_OK;
    }
}

/* The words of points [i0, i1) into w[0], and the counts of the root's first pass (k
 * levels, table row tab, digits at `shift`) into h. SPREAD3 makes a Morton code of three
 * cell coordinates. */
#define KEYGEN_LOOP(MORTON)                                                                                            \
    for (uint64_t i = i0; i < i1; i++) {                                                                               \
        float p[3];                                                                                                    \
        point(s->pos, s->stride, i, p);                                                                                \
        uint64_t mc = MORTON(cell_of(p[0], s->lo[0], s->scale), cell_of(p[1], s->lo[1], s->scale),                     \
                             cell_of(p[2], s->lo[2], s->scale));                                                       \
        uint64_t word = (mc >> sh) << s->ib | i;                                                                       \
        w[i] = word;                                                                                                   \
        h[BUCKET(tab, word)]++;                                                                                        \
    }

static void keygen(const sorter_t *s, uint64_t i0, uint64_t i1, uint32_t *h, const uint16_t *tab, unsigned shift,
                   unsigned nb)
{
    uint64_t *w = s->w[0];
    unsigned sh = 3 * (LEVELS - s->cap);
    KEYGEN_LOOP(morton_of)
}

#if defined(__x86_64__)
__attribute__((target("bmi2"))) static inline uint64_t morton_pdep(uint32_t x, uint32_t y, uint32_t z)
{
    return _pdep_u64(x, 0x1249249249249249ull) | _pdep_u64(y, 0x2492492492492492ull) |
           _pdep_u64(z, 0x4924924924924924ull);
}

/* The same with BMI2's bit deposit: one instruction per axis instead of ten. */
__attribute__((target("bmi2"))) static void keygen_bmi2(const sorter_t *s, uint64_t i0, uint64_t i1, uint32_t *h,
                                                        const uint16_t *tab, unsigned shift, unsigned nb)
{
    uint64_t *w = s->w[0];
    unsigned sh = 3 * (LEVELS - s->cap);
    KEYGEN_LOOP(morton_pdep)
}
#endif

pm_result_t pm_reorder_points(const void *pos, size_t stride, uint64_t n, pm_order_t order, uint64_t leaf,
                              uint32_t *perm_out, pm_reorder_info_t *info_out)
{
    pm_reorder_info_t info = {0};
    if (leaf < 1 || n > UINT32_MAX || stride < 3 * sizeof(float))
        return pm_error_set(PM_ERR_INTERNAL, "reorder: leaf %" PRIu64 ", %" PRIu64 " points, stride %zu", leaf, n,
                            stride);
    double t0 = pm_time_wall();
    if (order == PM_ORDER_NONE || n <= leaf) {
        for (uint64_t i = 0; i < n; i++)
            perm_out[i] = (uint32_t)i;
        info.leaves = n > 0;
        if (info_out)
            *info_out = info;
        return PM_OK;
    }
    unsigned csr = _mm_getcsr();
    int nthreads = omp_get_max_threads();
    sorter_t s = {.leaf = leaf, .perm = perm_out, .pos = pos, .stride = stride};
    s.ib = 64 - (unsigned)__builtin_clzll(n - 1); /* n >= 2 here */
    s.cap = (64 - s.ib) / 3 < LEVELS ? (64 - s.ib) / 3 : LEVELS;
    s.imask = (1ull << s.ib) - 1;
    s.w[0] = pm_alloc_aligned(n * sizeof(uint64_t));
    s.w[1] = pm_alloc_aligned(n * sizeof(uint64_t));
    uint32_t *hist = malloc((size_t)nthreads * MAX_BUCKETS * sizeof *hist);
    uint32_t *scratch = malloc((size_t)nthreads * LEVELS * (MAX_BUCKETS + 1) * sizeof *scratch);
    worklist_t list = {0};
    pm_result_t res = digit_tables_build(order, &s.tab);
    if (res != PM_OK)
        goto done;
    if (!s.w[0] || !s.w[1] || !hist || !scratch) {
        res =
            pm_error_set(PM_ERR_NOMEM, "out of memory for the keys of %" PRIu64 " points (%.0f MB)", n, n * 16.0 / 1e6);
        goto done;
    }
    pm_reorder_cube(pos, stride, n, s.lo, &s.scale);
    /* The words, and with them the counts of the root's first pass, on the slices par_cell
     * uses for it. */
    unsigned base = 0, k0 = pass_levels(n, leaf, 0), nb0 = 1u << (3 * k0), shift0 = pass_shift(&s, 0, 0, k0);
    const uint16_t *tab0 = s.tab.t[k0];
#if defined(__x86_64__)
    int bmi2 = __builtin_cpu_supports("bmi2");
#endif
    const int used = nthreads;
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
    for (int th = 0; th < used; th++) {
        _mm_setcsr(csr);
        uint64_t i0 = n * (uint64_t)th / (uint64_t)used, i1 = n * (uint64_t)(th + 1) / (uint64_t)used;
        uint32_t *h = hist + (size_t)th * MAX_BUCKETS;
        memset(h, 0, nb0 * sizeof *h);
#if defined(__x86_64__)
        if (bmi2)
            keygen_bmi2(&s, i0, i1, h, tab0, shift0, nb0);
        else
#endif
            keygen(&s, i0, i1, h, tab0, shift0, nb0);
    }
    double t1 = pm_time_wall();
    info.keys_s = t1 - t0;

    tally_t top = {0};
    uint64_t big = n / (uint64_t)(2 * nthreads);
    if (big < PAR_MIN_POINTS)
        big = PAR_MIN_POINTS;
    res = par_cell(&s, 0, 0, n, 0, base, 0, big, hist, nthreads, 1, &list, &top);
    if (res != PM_OK)
        goto done;
    uint64_t leaves = top.leaves;
    unsigned depth = top.depth;
#pragma omp parallel num_threads(nthreads) reduction(+ : leaves) reduction(max : depth)
    {
        _mm_setcsr(csr); /* refills quantize positions as the words were made */
        tally_t t = {0};
        uint32_t *mine = scratch + (size_t)omp_get_thread_num() * LEVELS * (MAX_BUCKETS + 1);
#pragma omp for schedule(dynamic, 1)
        for (size_t i = 0; i < list.n; i++) {
            work_t w = list.w[i];
            if (w.m == 0)
                continue;
            if (w.is_leaf)
                leaf_done(&s, w.buf, w.b, w.m, w.level, w.is_leaf == 2, &t);
            else
                sort_cell(&s, w.buf, w.b, w.m, w.level, w.base, w.state, mine, &t);
        }
        leaves += t.leaves;
        depth = t.depth > depth ? t.depth : depth;
    }
    info.leaves = leaves;
    info.depth = depth;
    info.sort_s = pm_time_wall() - t1;
done:
    digit_tables_free(&s.tab);
    free(list.w);
    free(scratch);
    free(hist);
    pm_free_aligned(s.w[1]);
    pm_free_aligned(s.w[0]);
    if (res == PM_OK && info_out)
        *info_out = info;
    return res;
}
