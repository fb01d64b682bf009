/* check.c: the checks of every value a reader reads and a writer writes, against the
 * channel flags of the schema (finite, non-negative, positive, unit length) and then the
 * format's own record checks. An exact check in double words every message; a fast pass
 * (integer tests on float bits, vectorized by the compiler, on records or on a table's
 * columns) runs first and sends a chunk to the exact check only where a value might fail,
 * so that the checks run at the speed of the I/O. */
#include <inttypes.h>
#include <math.h>
#include <string.h>

#include "formats/pmfile_impl.h"

/* The exact check, value by value in double, and the source of every message: checks the
 * values of n raw records starting at record index first, against the channel flags of h's
 * schema, channel by channel; path names the file in messages. pmfile_check_records runs it only on
 * a chunk where its fast pass saw a value that may fail. */
pm_result_t pmfile_check_exact(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                               uint64_t first)
{
    const pm_schema_t *s = h->schema;
    size_t off = 0;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(h->channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        unsigned fl = c->flags;
        size_t csize = pmfile_channel_size(c);
        if ((c->type == PM_TYPE_F32 || c->type == PM_TYPE_F64) &&
            (fl & (PM_CH_FINITE | PM_CH_NONNEG | PM_CH_UNIT | PM_CH_POSITIVE))) {
            for (uint64_t i = 0; i < n; i++) {
                const unsigned char *p = rec + i * h->record_size + off;
                double len2 = 0.0;
                for (unsigned k = 0; k < c->components; k++) {
                    double v;
                    if (c->type == PM_TYPE_F32) {
                        float f;
                        memcpy(&f, p + 4 * k, 4);
                        v = f;
                    } else {
                        memcpy(&v, p + 8 * k, 8);
                    }
                    const char *why = NULL;
                    if (!isfinite(v))
                        why = "not finite";
                    else if ((fl & PM_CH_NONNEG) && v < 0.0)
                        why = "negative";
                    else if ((fl & PM_CH_POSITIVE) && !(v > 0.0))
                        why = "not positive";
                    if (why)
                        return pm_error_set(PM_ERR_INPUT,
                                            "bad value in %s '%s': record %" PRIu64 " channel '%s'[%u] is %g (%s)",
                                            s->title, path, first + i, c->name, k, v, why);
                    len2 += v * v;
                }
                if ((fl & PM_CH_UNIT) && fabs(len2 - 1.0) > 2e-3)
                    return pm_error_set(PM_ERR_INPUT,
                                        "bad value in %s '%s': record %" PRIu64 " channel '%s' has length %g, not 1",
                                        s->title, path, first + i, c->name, sqrt(len2));
            }
        }
        off += csize;
    }
    return s->validate_records ? s->validate_records(h, path, rec, n, first) : PM_OK;
}

/* ---- the fast pass of the value checks ----
 *
 * Every chunk a reader reads and a writer writes is checked, so this runs at the speed of
 * the I/O. It answers one question, "might any value of these records fail?", and is
 * conservative: it says yes for every value the exact check rejects, and perhaps for a few
 * it accepts (a negative subnormal, a unit vector within 1e-5 of the tolerance, a channel
 * with a check it does not model). Then the chunk goes through pmfile_check_exact, which
 * decides and words the message, so the accepted values and the messages are exactly the
 * exact check's.
 *
 * Records are AoS with any size and alignment (54-byte records put floats at odd offsets),
 * so each channel of a block of PM_CHECK_BLOCK records is first copied into one small
 * column per component (in L1), and the tests run as fixed-length loops over those columns
 * that the compiler vectorizes: integer tests on the bits for finite / >= 0 / > 0, float
 * arithmetic for unit length. */
#define PM_CHECK_BLOCK 256 /* records per block: 4 columns of 1 KiB */
#define PM_F32_EXP 0x7f800000u
#define PM_F32_ONE 0x3f800000u

typedef struct {
    uint32_t v[4][PM_CHECK_BLOCK] __attribute__((aligned(64))); /* component k of record i: bits of an f32 */
} check_block_t;

/* 1 when some value in the block might fail; the block holds PM_CHECK_BLOCK rows (the
 * rows past the last record are padded with values that pass every check but > 0 on a
 * unit vector's y and z). */
static uint32_t block_suspect(const check_block_t *b, unsigned comps, unsigned fl)
{
    uint32_t bad = 0;
    for (unsigned k = 0; k < comps; k++) {
        const uint32_t *v = b->v[k];
        /* Not finite: exponent all ones. (x & 0x7fffffff) + 2^23 reaches bit 31 exactly
         * when x's magnitude is at least that of infinity. */
        for (unsigned i = 0; i < PM_CHECK_BLOCK; i++)
            bad |= (v[i] & 0x7fffffffu) + 0x00800000u;
        if (fl & PM_CH_NONNEG) /* negative: the sign set on a nonzero magnitude (-0 passes) */
            for (unsigned i = 0; i < PM_CHECK_BLOCK; i++)
                bad |= (uint32_t)(v[i] > 0x80000000u) << 31;
        if (fl & PM_CH_POSITIVE) /* not a positive normal number (zero, subnormal, sign set) */
            for (unsigned i = 0; i < PM_CHECK_BLOCK; i++)
                bad |= (uint32_t)(v[i] - 0x00800000u > PM_F32_EXP - 1 - 0x00800000u) << 31;
    }
    if ((fl & PM_CH_UNIT) && comps == 3) {
        /* |x^2 + y^2 + z^2 - 1| <= 2e-3 in double; in float the sum is within 3 ulp (2e-7)
         * of it, so a float sum inside [1 - 2e-3 + 1e-5, 1 + 2e-3 - 1e-5] surely passes.
         * Outside it, or NaN, the exact check decides. */
        float acc = 0.0f;
        for (unsigned i = 0; i < PM_CHECK_BLOCK; i++) {
            float x, y, z;
            memcpy(&x, &b->v[0][i], 4);
            memcpy(&y, &b->v[1][i], 4);
            memcpy(&z, &b->v[2][i], 4);
            float d = x * x + y * y + z * z - 1.0f;
            /* d * d <= t * t also rejects NaN; acc stays 0 while every row passes */
            acc += d * d <= (2e-3f - 1e-5f) * (2e-3f - 1e-5f) ? 0.0f : 1.0f;
        }
        bad |= (uint32_t) !(acc == 0.0f) << 31;
    } else if (fl & PM_CH_UNIT) {
        bad |= 1u << 31; /* no such channel yet: let the exact check have it */
    }
    return bad >> 31;
}

/* Copies component k of channel bytes [off, off + 4 * comps) of records [i0, i0 + m) into
 * the block's columns, padding the rest. */
static void block_load(check_block_t *b, const unsigned char *rec, size_t rs, size_t off, unsigned comps, uint64_t m,
                       unsigned fl)
{
    const unsigned char *p = rec + off;
    if (comps == 3) {
        for (uint64_t i = 0; i < m; i++, p += rs) {
            memcpy(&b->v[0][i], p, 4);
            memcpy(&b->v[1][i], p + 4, 4);
            memcpy(&b->v[2][i], p + 8, 4);
        }
    } else {
        for (uint64_t i = 0; i < m; i++, p += rs)
            for (unsigned k = 0; k < comps; k++)
                memcpy(&b->v[k][i], p + 4 * k, 4);
    }
    for (unsigned k = 0; k < comps; k++) { /* pad: 1.0 on the first component, 0 (unit) or 1.0 */
        uint32_t pad = k == 0 || !(fl & PM_CH_UNIT) ? PM_F32_ONE : 0;
        for (uint64_t i = m; i < PM_CHECK_BLOCK; i++)
            b->v[k][i] = pad;
    }
}

/* 1 when some f64 value of the channel might fail (the same tests on 64-bit patterns). */
static int f64_suspect(const unsigned char *rec, size_t rs, size_t off, unsigned comps, uint64_t n, unsigned fl)
{
    if (fl & PM_CH_UNIT)
        return 1;
    uint64_t bad = 0;
    for (uint64_t i = 0; i < n; i++)
        for (unsigned k = 0; k < comps; k++) {
            uint64_t v;
            memcpy(&v, rec + i * rs + off + 8 * k, 8);
            bad |= (v & 0x7fffffffffffffffull) + 0x0010000000000000ull;
            if (fl & PM_CH_NONNEG)
                bad |= (uint64_t)(v > 0x8000000000000000ull) << 63;
            if (fl & PM_CH_POSITIVE)
                bad |= (uint64_t)(v - 0x0010000000000000ull > 0x7fefffffffffffffull - 0x0010000000000000ull) << 63;
        }
    return (int)(bad >> 63);
}

/* The fast pass over n raw records: 1 when some value might fail. */
int pmfile_records_suspect(const pm_header_t *h, const unsigned char *rec, uint64_t n)
{
    const pm_schema_t *s = h->schema;
    const unsigned checked = PM_CH_FINITE | PM_CH_NONNEG | PM_CH_UNIT | PM_CH_POSITIVE;
    size_t rs = h->record_size, off = 0;
    check_block_t blk;
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(h->channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        size_t at = off;
        off += pmfile_channel_size(c);
        if (!(c->flags & checked))
            continue;
        if (c->type == PM_TYPE_F64) {
            if (f64_suspect(rec, rs, at, c->components, n, c->flags))
                return 1;
        } else if (c->type == PM_TYPE_F32) {
            if (c->components > 4)
                return 1;
            for (uint64_t i = 0; i < n; i += PM_CHECK_BLOCK) {
                uint64_t m = n - i < PM_CHECK_BLOCK ? n - i : PM_CHECK_BLOCK;
                block_load(&blk, rec + i * rs, rs, at, c->components, m, c->flags);
                if (block_suspect(&blk, c->components, c->flags))
                    return 1;
            }
        }
    }
    return 0;
}

/* The fast pass over the nv values of PM_CHECK_BLOCK rows of an f32 column already in
 * memory (SoA: the components of a row side by side): no copy, one flat loop per test (nv
 * is a constant where it is inlined, so that the loops vectorize), and for a unit vector
 * one loop over the rows. */
static inline uint32_t column_block_suspect_n(const float *v, const unsigned nv, unsigned comps, unsigned fl)
{
    uint32_t bad = 0;
    for (unsigned i = 0; i < nv; i++) {
        uint32_t b;
        memcpy(&b, &v[i], 4);
        bad |= (b & 0x7fffffffu) + 0x00800000u;
    }
    if (fl & PM_CH_NONNEG)
        for (unsigned i = 0; i < nv; i++) {
            uint32_t b;
            memcpy(&b, &v[i], 4);
            bad |= (uint32_t)(b > 0x80000000u) << 31;
        }
    if (fl & PM_CH_POSITIVE)
        for (unsigned i = 0; i < nv; i++) {
            uint32_t b;
            memcpy(&b, &v[i], 4);
            bad |= (uint32_t)(b - 0x00800000u > PM_F32_EXP - 1 - 0x00800000u) << 31;
        }
    if ((fl & PM_CH_UNIT) && comps == 3) {
        float acc = 0.0f; /* as in block_suspect */
        for (unsigned i = 0; i < PM_CHECK_BLOCK; i++) {
            float d = v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2] - 1.0f;
            acc += d * d <= (2e-3f - 1e-5f) * (2e-3f - 1e-5f) ? 0.0f : 1.0f;
        }
        bad |= (uint32_t) !(acc == 0.0f) << 31;
    } else if (fl & PM_CH_UNIT) {
        bad |= 1u << 31;
    }
    return bad >> 31;
}

static uint32_t column_block_suspect(const float *v, unsigned comps, unsigned fl)
{
    switch (comps) { /* the component counts channels have, as constants */
    case 1: return column_block_suspect_n(v, PM_CHECK_BLOCK, 1, fl);
    case 3: return column_block_suspect_n(v, 3 * PM_CHECK_BLOCK, 3, fl);
    default: return column_block_suspect_n(v, comps * PM_CHECK_BLOCK, comps, fl);
    }
}

/* The fast pass over rows [at, at + n) of a table's columns: 1 when some value might
 * fail. The same answer pmfile_records_suspect gives for those rows as records, with no
 * transposition: the table already holds each channel apart. */
int pmfile_columns_suspect(const pm_table_t *t, uint64_t at, uint64_t n)
{
    const pm_schema_t *s = t->hdr.schema;
    const unsigned checked = PM_CH_FINITE | PM_CH_NONNEG | PM_CH_UNIT | PM_CH_POSITIVE;
    float tail[PM_CHECK_BLOCK * 4] __attribute__((aligned(64)));
    for (unsigned ci = 0; ci < s->nchannels; ci++) {
        if (!(t->hdr.channels & (1u << ci)))
            continue;
        const pm_channel_t *c = &s->channels[ci];
        if (!(c->flags & checked))
            continue;
        size_t cs = pmfile_channel_size(c);
        const unsigned char *col = (const unsigned char *)t->col[ci] + at * cs;
        if (c->type == PM_TYPE_F64) {
            if (f64_suspect(col, cs, 0, c->components, n, c->flags))
                return 1;
        } else if (c->type == PM_TYPE_F32) {
            if (c->components > 4)
                return 1;
            unsigned comps = c->components;
            uint64_t i = 0;
            for (; i + PM_CHECK_BLOCK <= n; i += PM_CHECK_BLOCK)
                if (column_block_suspect((const float *)(const void *)(col + i * cs), comps, c->flags))
                    return 1;
            if (i < n) { /* the last rows, padded as block_load pads */
                uint64_t m = n - i;
                memcpy(tail, col + i * cs, (size_t)m * cs);
                for (uint64_t r = m; r < PM_CHECK_BLOCK; r++)
                    for (unsigned k = 0; k < comps; k++)
                        tail[r * comps + k] = k == 0 || !(c->flags & PM_CH_UNIT) ? 1.0f : 0.0f;
                if (column_block_suspect(tail, comps, c->flags))
                    return 1;
            }
        }
    }
    return 0;
}

/* The checks of n raw records starting at record index first, once a fast pass has said
 * whether some value might fail: the exact check when it might, then (as the exact check
 * does at its end) the format's record checks. */
pm_result_t pmfile_check_after(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                               uint64_t first, int suspect)
{
    if (suspect)
        return pmfile_check_exact(h, path, rec, n, first);
    return h->schema->validate_records ? h->schema->validate_records(h, path, rec, n, first) : PM_OK;
}

/* Checks the values of n raw records starting at record index first: the fast pass, then
 * the exact check where it is needed. */
pm_result_t pmfile_check_records(const pm_header_t *h, const char *path, const unsigned char *rec, uint64_t n,
                                 uint64_t first)
{
    return pmfile_check_after(h, path, rec, n, first, pmfile_records_suspect(h, rec, n));
}
