// Huge-page memory for the model database's tables (memory.hpp).
#include <binpose/memory.hpp>

#include <cstdlib>
#include <new>
#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace binpose {

void* allocateHugePages(std::size_t bytes) {
  void* p = std::aligned_alloc(HugePageAllocator<char>::kHuge, bytes);
  if (p == nullptr) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  madvise(p, bytes, MADV_HUGEPAGE);  // advice only: ignored where huge pages are off
#endif
  return p;
}

void freeHugePages(void* p) { std::free(p); }

}  // namespace binpose
