/* reseal.h: a libFuzzer custom mutator for pmtk files, so that the checks behind the
 * checksum (values, the KD-tree, materials, image sizes) are reached. A pmtk file ends in
 * the XXH3-64 of every byte before it (docs/formats.md); a mutated input almost never
 * matches its trailer, and the reader stops there. This mutator lets libFuzzer mutate all
 * but the last 8 bytes and then writes the right checksum into them, so every input it
 * makes is a file a stage would accept as far as the checksum goes, and a crash file is one
 * any stage can be given as it is (tests/stage/formats.sh replays them).
 * Included by one fuzz target each; defines the two libFuzzer hooks for mutation. */
#ifndef PM_FUZZ_RESEAL_H
#define PM_FUZZ_RESEAL_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <xxhash.h>

size_t LLVMFuzzerMutate(uint8_t *data, size_t size, size_t max_size);
size_t LLVMFuzzerCustomMutator(uint8_t *data, size_t size, size_t max_size, unsigned int seed);
size_t LLVMFuzzerCustomCrossOver(const uint8_t *d1, size_t s1, const uint8_t *d2, size_t s2, uint8_t *out,
                                 size_t max_out, unsigned int seed);

/* Writes the checksum of data[0, size - 8) into its last 8 bytes (little-endian, as the
 * writer does on the little-endian machines pmtk runs on). */
static size_t fuzz_reseal(uint8_t *data, size_t size)
{
    if (size < 8)
        return size;
    uint64_t sum = XXH3_64bits(data, size - 8);
    memcpy(data + size - 8, &sum, 8);
    return size;
}

size_t LLVMFuzzerCustomMutator(uint8_t *data, size_t size, size_t max_size, unsigned int seed)
{
    (void)seed;
    if (max_size < 8 || size < 8)
        return LLVMFuzzerMutate(data, size, max_size); /* too short to be a file: plain mutation */
    size_t body = LLVMFuzzerMutate(data, size - 8, max_size - 8);
    return fuzz_reseal(data, body + 8);
}

/* Crossing two files over: the bodies spliced at a random point, then resealed. */
size_t LLVMFuzzerCustomCrossOver(const uint8_t *d1, size_t s1, const uint8_t *d2, size_t s2, uint8_t *out,
                                 size_t max_out, unsigned int seed)
{
    size_t b1 = s1 >= 8 ? s1 - 8 : s1, b2 = s2 >= 8 ? s2 - 8 : s2;
    if (max_out < 8)
        return 0;
    size_t cut1 = b1 ? seed % (b1 + 1) : 0, cut2 = b2 ? (seed / 7u) % (b2 + 1) : 0;
    size_t n = 0;
    for (size_t i = 0; i < cut1 && n < max_out - 8; i++)
        out[n++] = d1[i];
    for (size_t i = cut2; i < b2 && n < max_out - 8; i++)
        out[n++] = d2[i];
    return fuzz_reseal(out, n + 8);
}

#endif
