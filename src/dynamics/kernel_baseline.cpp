// The APGD kernel built for baseline x86-64 (SSE2): every x86-64 CPU.
#define CES_KERNEL_ISA 0
#include "dynamics/kernel.inl"
