#pragma once
// Internal: the k nearest seen so far, as PointGrid's neighbour searches keep them
// (PixelNeighbours keeps them in the same order as keys, so that both give the same answer).
#include <cstddef>
#include <cstdint>

namespace binpose::detail {

/// The k best (squared distance, index) pairs seen, best first (equal distances by index): an
/// insertion into a short array (k is k_normals, 6 or 8, for normals; 2 for a spacing).
struct NearestK {
  std::size_t k, count = 0;
  std::uint32_t* idx;
  float* d2;
  void offer(float d, std::uint32_t i) {
    if (count == k && (d > d2[k - 1] || (d == d2[k - 1] && i > idx[k - 1]))) return;
    std::size_t at = count < k ? count++ : k - 1;
    while (at > 0 && (d < d2[at - 1] || (d == d2[at - 1] && i < idx[at - 1]))) {
      d2[at] = d2[at - 1];
      idx[at] = idx[at - 1];
      --at;
    }
    d2[at] = d;
    idx[at] = i;
  }
};

}  // namespace binpose::detail
