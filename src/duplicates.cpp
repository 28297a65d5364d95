// Duplicate suppression: each scan point explains one object.
#include "duplicates.hpp"

#include <algorithm>

namespace binpose {

std::vector<Hypothesis> distinctObjects(std::vector<Hypothesis> hypotheses, std::size_t scan_size, const ModelShape& shape) {
  std::stable_sort(hypotheses.begin(), hypotheses.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.detection.score > b.detection.score; });
  std::vector<char> claimed(scan_size, 0);
  std::vector<Hypothesis> kept;
  for (Hypothesis& h : hypotheses) {
    std::size_t taken = 0;
    for (const auto i : h.support) taken += claimed[i];
    if (4 * taken > h.support.size()) continue;  // a quarter explained already: not a new object
    // Another pose of an object already found (a near-symmetric flip, say) shares some of its
    // support; a pose that shares almost none (under a twentieth) explains other points: a
    // neighbour, however close (thin caps stacked rim to rim overlap in that measure).
    if (20 * taken >= h.support.size() &&
        std::any_of(kept.begin(), kept.end(), [&](const Hypothesis& k) { return shape.mostlyOverlaps(h.detection.pose, k.detection.pose); }))
      continue;
    for (const auto i : h.support) claimed[i] = 1;
    kept.push_back(std::move(h));
  }
  return kept;
}

std::vector<Detection> suppressDuplicates(std::vector<Hypothesis> hypotheses, std::size_t scan_size, const ModelShape& shape) {
  std::vector<Detection> kept;
  for (Hypothesis& h : distinctObjects(std::move(hypotheses), scan_size, shape)) kept.push_back(h.detection);
  return kept;
}

}  // namespace binpose
