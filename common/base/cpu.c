/* cpu.c: CPUID-based ISA detection (see cpu.h). */
#include "base/cpu.h"

#include <cpuid.h>
#include <pmmintrin.h>
#include <string.h>
#include <xmmintrin.h>

int pm_cpu_supports(pm_isa_t isa)
{
    /* gcc's __builtin_cpu_supports checks both the CPU bits and that the OS saves
     * the wide registers (XCR0), so a "yes" here is safe to execute. */
    __builtin_cpu_init();
    switch (isa) {
    case PM_ISA_SCALAR: return 1;
    case PM_ISA_SSE4: return __builtin_cpu_supports("sse4.1") && __builtin_cpu_supports("sse4.2");
    case PM_ISA_AVX2: return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case PM_ISA_AVX512:
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
               __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw");
    default: return 0;
    }
}

pm_isa_t pm_cpu_best_isa(void)
{
    for (int i = PM_ISA_COUNT - 1; i > 0; i--)
        if (pm_cpu_supports((pm_isa_t)i))
            return (pm_isa_t)i;
    return PM_ISA_SCALAR;
}

static const char *const isa_names[PM_ISA_COUNT] = {"scalar", "sse4", "avx2", "avx512"};
static const int isa_widths[PM_ISA_COUNT] = {1, 4, 8, 16};

const char *pm_isa_name(pm_isa_t isa) { return isa < PM_ISA_COUNT ? isa_names[isa] : "unknown"; }
int pm_isa_width(pm_isa_t isa) { return isa < PM_ISA_COUNT ? isa_widths[isa] : 0; }

pm_result_t pm_isa_parse(const char *name, pm_isa_t *isa_out)
{
    if (strcmp(name, "auto") == 0) {
        *isa_out = pm_cpu_best_isa();
        return PM_OK;
    }
    for (int i = 0; i < PM_ISA_COUNT; i++) {
        if (strcmp(name, isa_names[i]) != 0)
            continue;
        if (!pm_cpu_supports((pm_isa_t)i))
            return pm_error_set(PM_ERR_USAGE, "isa '%s' is not supported by this cpu (best: %s)", name,
                                isa_names[pm_cpu_best_isa()]);
        *isa_out = (pm_isa_t)i;
        return PM_OK;
    }
    return pm_error_set(PM_ERR_USAGE, "unknown isa '%s' (auto|scalar|sse4|avx2|avx512)", name);
}

const char *pm_cpu_model(void)
{
    static char brand[49];
    if (brand[0])
        return brand;
    unsigned regs[12], max = __get_cpuid_max(0x80000000u, NULL);
    if (max < 0x80000004u) {
        strcpy(brand, "unknown");
        return brand;
    }
    for (unsigned i = 0; i < 3; i++)
        __get_cpuid(0x80000002u + i, &regs[4 * i], &regs[4 * i + 1], &regs[4 * i + 2], &regs[4 * i + 3]);
    memcpy(brand, regs, 48);
    brand[48] = '\0';
    /* Trim the padding some vendors put around the name. */
    char *s = brand;
    while (*s == ' ')
        s++;
    memmove(brand, s, strlen(s) + 1);
    for (size_t n = strlen(brand); n && brand[n - 1] == ' '; n--)
        brand[n - 1] = '\0';
    return brand;
}

void pm_cpu_set_ftz_daz(void)
{
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}
