// The APGD kernel built for AVX2, without FMA.
#define CES_KERNEL_ISA 1
#include "dynamics/kernel.inl"
