/* cpu.h: instruction-set detection and the floating-point mode of every stage.
 *
 * SIMD kernels come in scalar, SSE4 (4 lanes), AVX2 (8) and AVX-512 (16) flavours;
 * pm_cpu_best_isa picks the widest this CPU and OS run, and --isa can force a
 * narrower one (never a wider one: that would fault). */
#ifndef PM_CPU_H
#define PM_CPU_H

#include "base/error.h"

typedef enum { PM_ISA_SCALAR = 0, PM_ISA_SSE4 = 1, PM_ISA_AVX2 = 2, PM_ISA_AVX512 = 3, PM_ISA_COUNT } pm_isa_t;

int pm_cpu_supports(pm_isa_t isa);     /* 1 when this CPU and OS can run isa */
pm_isa_t pm_cpu_best_isa(void);        /* the widest supported */
const char *pm_isa_name(pm_isa_t isa); /* "scalar", "sse4", "avx2", "avx512" */
int pm_isa_width(pm_isa_t isa);        /* lanes of 32-bit floats: 1, 4, 8, 16 */

/* Parses "auto" or an ISA name; fails (PM_ERR_USAGE) for an unknown name or one this
 * CPU cannot run, naming what it can. */
pm_result_t pm_isa_parse(const char *name, pm_isa_t *isa_out);

/* The CPU brand string ("Intel(R) Xeon(R) ..."), or "unknown". */
const char *pm_cpu_model(void);

/* Flush denormals to zero on this thread: subnormal photon powers carry no visible
 * energy and cost 100x in the hot loops. Every stage calls it at start. */
void pm_cpu_set_ftz_daz(void);

#endif
