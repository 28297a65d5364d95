#pragma once
// Internal: what the AVX2 kernels of the feature keys and the votes share. They are compiled for
// AVX2 function by function (the build's baseline is x86-64-v2) and run where the CPU has it.
#if defined(__x86_64__)
#include <immintrin.h>

/// A helper inlined into AVX2 kernels (GCC inlines across targets only when both match).
#define BINPOSE_AVX2_INLINE __attribute__((target("avx2"), always_inline)) inline
#endif

namespace binpose::detail {

/// True when this CPU runs AVX2 code (asked once).
inline bool haveAvx2() {
#if defined(__x86_64__)
  static const bool avx2 = __builtin_cpu_supports("avx2");
  return avx2;
#else
  return false;
#endif
}

}  // namespace binpose::detail
