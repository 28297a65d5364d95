#pragma once
// Memory for large tables read at random (the model database): on 2 MiB pages where the kernel
// allows it, so that the table's lookups miss the TLB far less often.
#include <cstddef>
#include <memory>
#include <vector>

namespace binpose {

/// `bytes` (a multiple of 2 MiB) aligned to 2 MiB and advised to the kernel as huge pages;
/// throws std::bad_alloc. Freed by freeHugePages.
void* allocateHugePages(std::size_t bytes);
void freeHugePages(void* p);

/// std::allocator, but an allocation of 2 MiB or more is aligned to 2 MiB and advised to the
/// kernel as huge pages (madvise MADV_HUGEPAGE; transparent huge pages set to "madvise" or
/// "always"). Without them it is ordinary memory.
template <typename T>
struct HugePageAllocator {
  using value_type = T;
  static constexpr std::size_t kHuge = std::size_t{2} << 20;
  HugePageAllocator() = default;
  template <typename U>
  HugePageAllocator(const HugePageAllocator<U>&) {}  // NOLINT: converting, as std::allocator's

  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHuge) return std::allocator<T>().allocate(n);
    return static_cast<T*>(allocateHugePages((bytes + kHuge - 1) / kHuge * kHuge));
  }
  void deallocate(T* p, std::size_t n) {
    if (n * sizeof(T) < kHuge) std::allocator<T>().deallocate(p, n);
    else freeHugePages(p);
  }
  template <typename U>
  bool operator==(const HugePageAllocator<U>&) const { return true; }
};

/// A vector whose large buffers lie on huge pages.
template <typename T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

}  // namespace binpose
