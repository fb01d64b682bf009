/* gather_isa.c: gather_kernel.h instantiated for each SIMD width, each compiled for its
 * own instruction set (GCC target pragmas; under clang, which ignores them, the same target
 * applied to every function of the section by `#pragma clang attribute`), so one binary runs
 * the widest the CPU has and falls back to narrower ones (common/base/cpu.h decides which may run).
 *
 * Lane masks are plain bit sets (bit l = lane l) everywhere outside the arithmetic, as in
 * the paper's pseudocode; each ISA turns compare results into bits (movemask, or the
 * AVX-512 mask registers) and bits back into vector masks where shading needs them. */
#include <immintrin.h>
#include <string.h>

#include "photonmap/gather_impl.h"

/* ---------------------------------------------------------------- scalar, W = 1 */
#define W 1
#define V float
#define VSET1(x) (x)
#define VLOAD(p) ((p)[0])
#define VSTORE(p, v) ((p)[0] = (v))
#define VADD(a, b) ((a) + (b))
#define VSUB(a, b) ((a) - (b))
#define VMUL(a, b) ((a) * (b))
#define VFMA(a, b, c) ((a) * (b) + (c))
#define BLE(a, b) ((uint32_t)((a) <= (b)))
#define BLT(a, b) ((uint32_t)((a) < (b)))
#define BGE(a, b) ((uint32_t)((a) >= (b)))
#define VMASKED(bits, v) ((bits) ? (v) : 0.0f)
#define FLUSH(ar, ag, ab, dacc) (dacc[0][0] += (ar), dacc[1][0] += (ag), dacc[2][0] += (ab))
#define ISA_NAME scalar
#include "photonmap/gather_isa_inst.h"

/* ---------------------------------------------------------------- SSE4.1, W = 4 */
#ifdef __clang__
#pragma clang attribute push(__attribute__((target("sse4.1"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("sse4.1")
#endif
static const uint32_t lane_bits4[4] = {1, 2, 4, 8};
static inline __m128 mask4(uint32_t bits)
{
    __m128i b = _mm_set1_epi32((int)bits), l = _mm_loadu_si128((const __m128i *)lane_bits4);
    return _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(b, l), l));
}
static inline void flush4(__m128 ar, __m128 ag, __m128 ab, double dacc[3][4])
{
    _Alignas(16) float t[3][4];
    _mm_store_ps(t[0], ar), _mm_store_ps(t[1], ag), _mm_store_ps(t[2], ab);
    for (int k = 0; k < 3; k++)
        for (int l = 0; l < 4; l++)
            dacc[k][l] += t[k][l];
}
typedef float vf4 __attribute__((vector_size(16)));
typedef int vi4 __attribute__((vector_size(16)));
#define VF vf4
#define VI vi4
#define VSQRTF(x) ((VF)_mm_sqrt_ps((__m128)(x)))
#define W 4
#define V __m128
#define VSET1(x) _mm_set1_ps(x)
#define VLOAD(p) _mm_load_ps(p)
#define VSTORE(p, v) _mm_store_ps(p, v)
#define VADD(a, b) _mm_add_ps(a, b)
#define VSUB(a, b) _mm_sub_ps(a, b)
#define VMUL(a, b) _mm_mul_ps(a, b)
#define VFMA(a, b, c) _mm_add_ps(_mm_mul_ps(a, b), c)
#define BLE(a, b) ((uint32_t)_mm_movemask_ps(_mm_cmple_ps(a, b)))
#define BLT(a, b) ((uint32_t)_mm_movemask_ps(_mm_cmplt_ps(a, b)))
#define BGE(a, b) ((uint32_t)_mm_movemask_ps(_mm_cmpge_ps(a, b)))
#define VMASKED(bits, v) _mm_and_ps(mask4(bits), v)
#define FLUSH(ar, ag, ab, dacc) flush4(ar, ag, ab, dacc)
#define ISA_NAME sse4
#include "photonmap/gather_isa_inst.h"
#ifdef __clang__
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

/* ---------------------------------------------------------------- AVX2 + FMA, W = 8 */
#ifdef __clang__
#pragma clang attribute push(__attribute__((target("avx2,fma"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2,fma")
#endif
static const uint32_t lane_bits8[8] = {1, 2, 4, 8, 16, 32, 64, 128};
static inline __m256 mask8(uint32_t bits)
{
    __m256i b = _mm256_set1_epi32((int)bits), l = _mm256_loadu_si256((const __m256i *)lane_bits8);
    return _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(b, l), l));
}
static inline void flush8(__m256 ar, __m256 ag, __m256 ab, double dacc[3][8])
{
    __m256 v[3] = {ar, ag, ab};
    for (int k = 0; k < 3; k++) {
        __m256d lo = _mm256_cvtps_pd(_mm256_castps256_ps128(v[k])),
                hi = _mm256_cvtps_pd(_mm256_extractf128_ps(v[k], 1));
        _mm256_storeu_pd(&dacc[k][0], _mm256_add_pd(_mm256_loadu_pd(&dacc[k][0]), lo));
        _mm256_storeu_pd(&dacc[k][4], _mm256_add_pd(_mm256_loadu_pd(&dacc[k][4]), hi));
    }
}
typedef float vf8 __attribute__((vector_size(32)));
typedef int vi8 __attribute__((vector_size(32)));
#define VF vf8
#define VI vi8
#define VSQRTF(x) ((VF)_mm256_sqrt_ps((__m256)(x)))
#define W 8
#define V __m256
#define VSET1(x) _mm256_set1_ps(x)
#define VLOAD(p) _mm256_load_ps(p)
#define VSTORE(p, v) _mm256_store_ps(p, v)
#define VADD(a, b) _mm256_add_ps(a, b)
#define VSUB(a, b) _mm256_sub_ps(a, b)
#define VMUL(a, b) _mm256_mul_ps(a, b)
#define VFMA(a, b, c) _mm256_fmadd_ps(a, b, c)
#define BLE(a, b) ((uint32_t)_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)))
#define BLT(a, b) ((uint32_t)_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LT_OQ)))
#define BGE(a, b) ((uint32_t)_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_GE_OQ)))
#define VMASKED(bits, v) _mm256_and_ps(mask8(bits), v)
#define FLUSH(ar, ag, ab, dacc) flush8(ar, ag, ab, dacc)
#define ISA_NAME avx2
#include "photonmap/gather_isa_inst.h"
#ifdef __clang__
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

/* ---------------------------------------------------------------- AVX-512, W = 16 */
#ifdef __clang__
#pragma clang attribute push(__attribute__((target("avx512f"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx512f")
#endif
static inline void flush16(__m512 ar, __m512 ag, __m512 ab, double dacc[3][16])
{
    __m512 v[3] = {ar, ag, ab};
    for (int k = 0; k < 3; k++) {
        __m512d lo = _mm512_cvtps_pd(_mm512_castps512_ps256(v[k]));
        __m512d hi = _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v[k]), 1)));
        _mm512_storeu_pd(&dacc[k][0], _mm512_add_pd(_mm512_loadu_pd(&dacc[k][0]), lo));
        _mm512_storeu_pd(&dacc[k][8], _mm512_add_pd(_mm512_loadu_pd(&dacc[k][8]), hi));
    }
}
typedef float vf16 __attribute__((vector_size(64)));
typedef int vi16 __attribute__((vector_size(64)));
#define VF vf16
#define VI vi16
#define VSQRTF(x) ((VF)_mm512_sqrt_ps((__m512)(x)))
#define W 16
#define V __m512
#define VSET1(x) _mm512_set1_ps(x)
#define VLOAD(p) _mm512_load_ps(p)
#define VSTORE(p, v) _mm512_store_ps(p, v)
#define VADD(a, b) _mm512_add_ps(a, b)
#define VSUB(a, b) _mm512_sub_ps(a, b)
#define VMUL(a, b) _mm512_mul_ps(a, b)
#define VFMA(a, b, c) _mm512_fmadd_ps(a, b, c)
#define BLE(a, b) ((uint32_t)_mm512_cmp_ps_mask(a, b, _CMP_LE_OQ))
#define BLT(a, b) ((uint32_t)_mm512_cmp_ps_mask(a, b, _CMP_LT_OQ))
#define BGE(a, b) ((uint32_t)_mm512_cmp_ps_mask(a, b, _CMP_GE_OQ))
#define VMASKED(bits, v) _mm512_maskz_mov_ps((__mmask16)(bits), v)
#define FLUSH(ar, ag, ab, dacc) flush16(ar, ag, ab, dacc)
#define ISA_NAME avx512
#include "photonmap/gather_isa_inst.h"
#ifdef __clang__
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

gather_fn_t gather_kernel_for(pm_isa_t isa, int widths)
{
    static const gather_fn_t fns[PM_ISA_COUNT][3] = {
        [PM_ISA_SCALAR] = {gather_packets_scalar_fixed, gather_packets_scalar_var, gather_packets_scalar_perq},
        [PM_ISA_SSE4] = {gather_packets_sse4_fixed, gather_packets_sse4_var, gather_packets_sse4_perq},
        [PM_ISA_AVX2] = {gather_packets_avx2_fixed, gather_packets_avx2_var, gather_packets_avx2_perq},
        [PM_ISA_AVX512] = {gather_packets_avx512_fixed, gather_packets_avx512_var, gather_packets_avx512_perq}};
    return fns[(unsigned)isa < PM_ISA_COUNT ? isa : PM_ISA_SCALAR][widths >= 0 && widths <= 2 ? widths : 0];
}
