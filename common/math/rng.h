/* rng.h: a counter-based random number generator (Philox4x32-10, Salmon et al. 2011).
 *
 * Counter-based so that determinism does not depend on threads: the stream of item i
 * (photon i, pixel i) is keyed by (seed, i) alone, and any thread can produce it.
 * Each stream yields 2^64 blocks of four 32-bit words. */
#ifndef PM_RNG_H
#define PM_RNG_H

#include <stdint.h>

typedef struct {
    uint32_t key[2]; /* the seed */
    uint32_t ctr[4]; /* ctr[0..1]: block within the stream, ctr[2..3]: the stream id */
    uint32_t buf[4]; /* the current block */
    unsigned used;   /* words of buf already handed out */
} pm_rng_t;

/* One Philox4x32-10 block: out = bijection of ctr under key. */
static inline void pm_philox4x32_10(const uint32_t ctr[4], const uint32_t key[2], uint32_t out[4])
{
    uint32_t c0 = ctr[0], c1 = ctr[1], c2 = ctr[2], c3 = ctr[3], k0 = key[0], k1 = key[1];
    for (int round = 0; round < 10; round++) {
        uint64_t p0 = (uint64_t)0xD2511F53u * c0, p1 = (uint64_t)0xCD9E8D57u * c2;
        uint32_t n0 = (uint32_t)(p1 >> 32) ^ c1 ^ k0, n1 = (uint32_t)p1;
        uint32_t n2 = (uint32_t)(p0 >> 32) ^ c3 ^ k1, n3 = (uint32_t)p0;
        c0 = n0, c1 = n1, c2 = n2, c3 = n3;
        k0 += 0x9E3779B9u; /* the Weyl sequence: golden ratio and sqrt(3) - 1 */
        k1 += 0xBB67AE85u;
    }
    out[0] = c0, out[1] = c1, out[2] = c2, out[3] = c3;
}

/* The stream `stream` of generator `seed`. */
static inline void pm_rng_init(pm_rng_t *r, uint64_t seed, uint64_t stream)
{
    r->key[0] = (uint32_t)seed;
    r->key[1] = (uint32_t)(seed >> 32);
    r->ctr[0] = r->ctr[1] = 0;
    r->ctr[2] = (uint32_t)stream;
    r->ctr[3] = (uint32_t)(stream >> 32);
    r->used = 4;
}

static inline uint32_t pm_rng_u32(pm_rng_t *r)
{
    if (r->used == 4) {
        pm_philox4x32_10(r->ctr, r->key, r->buf);
        if (++r->ctr[0] == 0)
            ++r->ctr[1];
        r->used = 0;
    }
    return r->buf[r->used++];
}

/* Uniform in [0, 1): the top 24 bits, so every value is an exact float below 1. */
static inline float pm_rng_float(pm_rng_t *r) { return (float)(pm_rng_u32(r) >> 8) * 0x1p-24f; }

/* Uniform in [0, 1) with 53 bits, for choices that need more resolution than a float. */
static inline double pm_rng_double(pm_rng_t *r)
{
    uint64_t hi = pm_rng_u32(r) >> 5, lo = pm_rng_u32(r) >> 6;
    return (double)((hi << 26) | lo) * 0x1p-53;
}

#endif
