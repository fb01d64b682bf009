/* gather_isa_inst.h: instantiates gather_kernel.h for one ISA, fixed, per-photon and
 * per-query widths (gather_packets_ISA_fixed, _var, _perq), then clears that ISA's macros so the
 * next one can define its own. Included by gather_isa.c with ISA_NAME and the vector
 * macros of gather_kernel.h defined. */
#define GATHER_CAT3(a, b, c) a##b##c
#define GATHER_NAME(x, isa, var) GATHER_CAT3(x##_, isa, var)

#define VAR 0
#define FN(x) GATHER_NAME(x, ISA_NAME, _fixed)
#include "photonmap/gather_kernel.h"
#undef VAR
#undef FN
#define VAR 1
#define FN(x) GATHER_NAME(x, ISA_NAME, _var)
#include "photonmap/gather_kernel.h"
#undef VAR
#undef FN
#define VAR 2
#define FN(x) GATHER_NAME(x, ISA_NAME, _perq)
#include "photonmap/gather_kernel.h"
#undef VAR
#undef FN

#undef GATHER_CAT3
#undef GATHER_NAME
#undef ISA_NAME
#undef W
#undef V
#undef VSET1
#undef VLOAD
#undef VSTORE
#undef VADD
#undef VSUB
#undef VMUL
#undef VFMA
#undef BLE
#undef BLT
#undef BGE
#undef VMASKED
#undef FLUSH
#undef VF
#undef VI
#undef VSQRTF
