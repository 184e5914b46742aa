// The APGD kernel built for AVX-512F and VL, on 256-bit vectors, without FMA.
#define CES_KERNEL_ISA 2
#include "dynamics/kernel.inl"
