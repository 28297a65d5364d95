// Accumulator voting and fourth-spread selection (thesis 4.3-4.4).
#include <binpose/voting.hpp>

#include <algorithm>
#include <fmt/format.h>

namespace binpose {
namespace {

/// Value at sorted position `pos` of the histogram's data.
std::uint32_t valueAt(std::span<const std::uint32_t> histogram, std::uint64_t pos) {
  std::uint64_t seen = 0;
  for (std::size_t v = 0; v < histogram.size(); ++v) {
    seen += histogram[v];
    if (seen > pos) return static_cast<std::uint32_t>(v);
  }
  return static_cast<std::uint32_t>(histogram.size() - 1);
}

/// Median of sorted positions [begin, begin + count).
double medianOf(std::span<const std::uint32_t> histogram, std::uint64_t begin, std::uint64_t count) {
  const std::uint64_t mid = begin + count / 2;
  if (count % 2 == 1) return valueAt(histogram, mid);
  return 0.5 * (double(valueAt(histogram, mid - 1)) + double(valueAt(histogram, mid)));
}

}  // namespace

Fourths fourthsOfHistogram(std::span<const std::uint32_t> histogram) {
  std::uint64_t n = 0;
  for (const auto c : histogram) n += c;
  if (n == 0) throw Error("fourth spread of an empty data set");
  const std::uint64_t half = (n + 1) / 2;  // the median goes in both halves when n is odd
  return {medianOf(histogram, 0, half), medianOf(histogram, n - half, half)};
}

std::vector<std::size_t> selectCandidates(std::span<const std::uint32_t> values, int keep) {
  if (values.empty()) return {};
  const std::uint32_t top = *std::max_element(values.begin(), values.end());
  std::vector<std::uint32_t> histogram(std::size_t{top} + 1, 0);
  for (const auto v : values) ++histogram[v];
  const Fourths f = fourthsOfHistogram(histogram);
  if (!(top > f.upper + 3.0 * f.spread())) return {};  // eq. 11: no upper outlier, no candidate
  std::vector<std::size_t> picked;
  if (keep <= 1) {
    for (std::size_t i = 0; i < values.size(); ++i)
      if (values[i] == top) picked.push_back(i);  // eq. 12: the maximum (ties all kept)
    return picked;
  }
  const double limit = f.upper + 3.0 * f.spread();
  for (std::size_t i = 0; i < values.size(); ++i)
    if (values[i] > limit) picked.push_back(i);
  const auto cut = picked.begin() + std::min<std::ptrdiff_t>(keep, static_cast<std::ptrdiff_t>(picked.size()));
  std::partial_sort(picked.begin(), cut, picked.end(), [&](std::size_t a, std::size_t b) {
    return values[a] != values[b] ? values[a] > values[b] : a < b;
  });
  picked.erase(cut, picked.end());
  return picked;
}

Voter::Voter(const ModelDatabase& db, int keep) : db_(db), keep_(keep), votes_(db.model().points.size(), 0) {}

void Voter::vote(const Points& points, const Points& normals, std::span<const std::uint32_t> group,
                 std::vector<Correspondence>& out) {
  if (group.size() >= 65535) throw Error(fmt::format("sub-group of {} points is too large to vote", group.size()));
  const KeySpace& keys = db_.keySpace();
  std::vector<std::uint32_t> values;
  for (const std::uint32_t k : group) {
    // L_k (eq. 9): the model points under the key of every feature (ss_k -> ss_o).
    for (const std::uint32_t o : group) {
      PairFeature f;
      if (o == k || !computeFeature(points[k], normals[k], points[o], normals[o], f)) continue;
      for (const auto id : db_.lookup(keys.key(f))) {
        if (votes_[id]++ == 0) touched_.push_back(id);
      }
    }
    if (touched_.empty()) continue;
    // A_k over the distinct model points of L_k, then eq. 10-12.
    values.clear();
    for (const auto id : touched_) values.push_back(votes_[id]);
    for (const std::size_t i : selectCandidates(values, keep_)) out.push_back({k, touched_[i]});
    for (const auto id : touched_) votes_[id] = 0;
    touched_.clear();
  }
}

}  // namespace binpose
