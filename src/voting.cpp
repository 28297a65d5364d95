// Accumulator voting and fourth-spread selection (thesis 4.3-4.4).
#include <binpose/voting.hpp>

#include <binpose/geometry.hpp>
#include <binpose/symmetry.hpp>

#include "simd.hpp"
#include "vote_kernels.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <numeric>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

namespace binpose {

using namespace kernels;  // the votes' SIMD kernels (vote_kernels.hpp)

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

namespace {

/// Eq. 11: the value above which one of a data set with fourths `f` is an upper outlier,
/// x_u + 3 xi_s.
double outlierLimit(const Fourths& f) { return f.upper + 3.0 * f.spread(); }

/// Eq. 10-11 on the histogram of an accumulator's non-zero counts into `cut`.
void cutAt(std::span<const std::uint32_t> histogram, VoteCut& cut) {
  cut.fourths = fourthsOfHistogram(histogram);
  cut.limit = outlierLimit(cut.fourths);
}

}  // namespace

void upperOutliers(std::span<const std::uint32_t> values, std::vector<std::uint32_t>& histogram,
                   std::vector<std::size_t>& out) {
  out.clear();
  if (values.empty()) return;
  const std::uint32_t top = *std::max_element(values.begin(), values.end());
  histogram.assign(std::size_t{top} + 1, 0);
  for (const auto v : values) ++histogram[v];
  const double limit = outlierLimit(fourthsOfHistogram(histogram));
  if (!(top > limit)) return;  // eq. 11: no upper outlier, no candidate
  for (std::size_t i = 0; i < values.size(); ++i)
    if (values[i] > limit) out.push_back(i);
}

namespace {

/// Orders indices by more votes first (value(i)), then by index.
template <typename Value>
auto moreVotes(Value value) {
  return [value](std::size_t a, std::size_t b) { return value(a) != value(b) ? value(a) > value(b) : a < b; };
}

/// Eq. 12 on the upper outliers `picked` (ascending indices, value(i) their votes): with keep <= 1
/// the maximum (ties all kept), else the `keep` with most votes, ties by index, best first.
template <typename Value>
void keepBest(std::vector<std::size_t>& picked, int keep, Value value) {
  if (picked.empty()) return;
  if (keep <= 1) {
    std::uint32_t top = 0;
    for (const auto i : picked) top = std::max<std::uint32_t>(top, value(i));
    std::erase_if(picked, [&](std::size_t i) { return value(i) != top; });
    return;
  }
  const auto cut = picked.begin() + std::min<std::ptrdiff_t>(keep, static_cast<std::ptrdiff_t>(picked.size()));
  std::partial_sort(picked.begin(), cut, picked.end(), moreVotes(value));
  picked.erase(cut, picked.end());
}

}  // namespace

std::vector<std::size_t> selectCandidates(std::span<const std::uint32_t> values, int keep) {
  std::vector<std::uint32_t> histogram;
  std::vector<std::size_t> picked;
  upperOutliers(values, histogram, picked);
  keepBest(picked, keep, [values](std::size_t i) { return values[i]; });
  return picked;
}

VoteCut upperOutlierCut(std::span<const std::uint16_t> votes, std::vector<std::uint8_t>& bytes,
                        std::vector<std::uint32_t>& histogram) {
  // Eq. 10-11 need only the fourths of the non-zero votes, which lie in the histogram's lower
  // part. With AVX2, the votes as bytes (when the top is under 256) are counted from the bottom,
  // eight values a pass, until the histogram holds the upper fourth's last position: on IPD
  // obj 8's 4000 points 2.1 passes on average (1 to 6), each a few logic operations on 32
  // bytes at a time, instead of a scalar increment per model point.
  VoteCut cut;
  bool counted = false;
#if defined(__x86_64__)
  if (votes.size() % 128 == 0 && detail::haveAvx2()) {
    bytes.resize(votes.size());
    cut.top = packVotes(votes, bytes.data());
    counted = cut.top > 0 && lowHistogram(bytes, cut.top, histogram);
  } else {
    cut.top = largestVote(votes);
  }
#else
  cut.top = largestVote(votes);
#endif
  if (cut.top == 0) return cut;
  if (!counted) fullHistogram(votes, cut.top, histogram);
  cutAt(histogram, cut);
  return cut;
}

template <class Count>
void Voter::countDense(std::vector<Count>& counters) {
  // Bitsets rather than id lists for the lists of a 48th of the model points and more: with n_M
  // = 4000, a list costs about 64 logic operations on 256-bit words and the points' counts
  // about 1.5 operations a point, against about 1 ns a point listed (IPD obj 8's points each
  // had 41 such lists, 31000 points in all, from a 32nd). A 48th measured faster than a 32nd
  // or a 16th on the bench bins, and no slower than a 64th.
  if (!dense_lists_.empty()) addBitsets(counters.data(), dense_lists_, counters.size() / 256);
  dense_lists_.clear();
}

Voter::Voter(const ModelDatabase& db, int keep, float spacing, const Orbits* orbits, MildOutliers mild)
    : db_(db), keep_(keep), spacing_(spacing), mild_(mild),
      orbits_(orbits != nullptr && !orbits->cyclic ? orbits : nullptr),
      classes_(orbits != nullptr && orbits->cyclic ? orbits : nullptr) {
  if (orbits != nullptr && orbits->of.size() != db.model().points.size())
    throw Error(fmt::format("orbits of {} points for a model of {}", orbits->of.size(), db.model().points.size()));
  counters_ = orbits_ != nullptr ? orbits_->count : db.model().points.size();
  votes_.assign(256 * ((counters_ + 255) / 256), 0);
  bitsets_ = orbits_ == nullptr && detail::haveAvx2();
  if (detail::haveAvx2()) narrow_.assign(votes_.size(), 0);
}

void Voter::useBitsets(bool on) { bitsets_ = on && orbits_ == nullptr && detail::haveAvx2(); }

void Voter::groupKeys() {
  // Open addressing on a table of at least twice as many slots as keys, each slot the key's
  // place in distinct_ (kEmpty: none); used slots are emptied again at the end. The votes are
  // sums, so the keys' order does not matter, only that equal keys are counted together
  // (std::sort did this before, 2-3% of the detection's time).
  constexpr std::uint32_t kEmpty = ~std::uint32_t{0};
  distinct_.clear();
  const std::size_t size = std::bit_ceil(std::max<std::size_t>(64, 2 * keys_.size()));
  if (slots_.size() < size) slots_.assign(size, kEmpty);
  const std::size_t mask = slots_.size() - 1;
  const int shift = 32 - std::countr_zero(slots_.size());
  for (const std::uint32_t key : keys_) {
    std::size_t h = (key * 0x9E3779B1u) >> shift;  // Fibonacci hashing: the product's top bits
    while (slots_[h] != kEmpty && distinct_[slots_[h]].key != key) h = (h + 1) & mask;
    if (slots_[h] == kEmpty) {
      slots_[h] = static_cast<std::uint32_t>(distinct_.size());
      distinct_.push_back({key, 1, static_cast<std::uint32_t>(h)});
    } else {
      ++distinct_[slots_[h]].count;
    }
  }
  for (const Distinct& d : distinct_) slots_[d.slot] = kEmpty;
}

void Voter::votePoint(const Points& points, const Points& normals, std::uint32_t k,
                      std::span<const std::uint32_t> partners, std::vector<Correspondence>& out) {
  const KeySpace& keys = db_.keySpace();
  // L_k (eq. 9): the model points under the key of every feature (ss_k -> ss_o). Features of the
  // same key (pairs on one plane, say) are counted together: the same sums, fewer increments.
  keys_.clear();
  featureKeys(points[k], normals[k], points, normals, partners, k, keys, keys_);
  groupKeys();
  lists_.clear();
  std::uint64_t added = 0;  // the votes the lists add, all told: no count is larger
  // The keys' table entries are fetched kKeysAhead keys before they are read.
  constexpr std::size_t kKeysAhead = 16;
  for (std::size_t a = 0; a < std::min(kKeysAhead, distinct_.size()); ++a) db_.prefetch(distinct_[a].key);
  for (std::size_t a = 0; a < distinct_.size(); ++a) {
    if (a + kKeysAhead < distinct_.size()) db_.prefetch(distinct_[a + kKeysAhead].key);
    const std::uint32_t key = distinct_[a].key;
    const auto ids = db_.lookup(key);
    if (ids.empty()) continue;
    const auto times = static_cast<std::uint16_t>(distinct_[a].count);
    added += times;
    // The lists lie far apart in the table (which does not fit in the cache): each one's lines
    // are fetched as soon as it is known, some 60 keys before the lists are counted.
    if (orbits_ != nullptr) {
      lists_.push_back({orbits_->lookup(key), times});  // the orbits of those points
      prefetchIds(lists_.back().ids);
      continue;
    }
    // A long list as its bitset, once per vote it adds (rarely more than once).
    const auto bits = bitsets_ && times <= kMostBitsetRepeats ? db_.denseBits(key) : std::span<const std::uint64_t>{};
    if (bits.empty()) {
      lists_.push_back({ids, times});
      prefetchIds(ids);
      continue;
    }
    for (std::size_t at = 0; at < std::min(bits.size(), 8 * kBitsetLinesAhead); at += 8) __builtin_prefetch(bits.data() + at);
    dense_lists_.insert(dense_lists_.end(), times, bits.data());
  }
  // When the lists add up to at most 255 votes (a point with fewer partners than that, each
  // feature adding one), no count passes 255: the counts go into bytes, half the accumulator
  // to add the bitsets into, scan and clear, and no packing for the histogram.
  const bool narrow = !narrow_.empty() && added <= 255;
  const auto tally = [&](auto& counters) {
    for (const List& list : lists_) countList(counters.data(), list.ids, list.times);
    countDense(counters);
    select(k, narrow, out);
    std::fill_n(counters.begin(), counters_, 0);  // the padding stays zero
  };
  if (narrow) tally(narrow_);
  else tally(votes_);
}

void Voter::select(std::uint32_t k, bool narrow, std::vector<Correspondence>& out) {
  // A_k is the model points with a vote (eq. 9-10): its histogram is the accumulator's without
  // the zeros (the padding's zeros included in the scans).
#if defined(__x86_64__)
  if (narrow) {
    VoteCut cut;
    cut.top = largestByte(narrow_);
    if (cut.top == 0) return;
    lowHistogram(narrow_, cut.top, histogram_);  // the top is under 256: always counted
    cutAt(histogram_, cut);
    const int keep = cutFor(cut);
    if (keep == 0) return;  // eq. 11: no upper outlier, no candidate
    bytesAbove(narrow_, static_cast<std::uint8_t>(cut.limit), outliers_);  // v > limit <=> v > floor(limit)
    keepCandidates(k, cut, keep, [this](std::size_t m) { return std::uint32_t{narrow_[m]}; }, out);
    return;
  }
#endif
  (void)narrow;
  VoteCut cut = upperOutlierCut(votes_, bytes_, histogram_);
  const int keep = cutFor(cut);
  if (keep == 0) return;  // eq. 11: no upper outlier, no candidate (nor any vote)
  // Votes are whole: v > limit <=> v > floor(limit).
  votesAbove(std::span<const std::uint16_t>(votes_.data(), counters_), static_cast<std::uint16_t>(cut.limit), outliers_);
  keepCandidates(k, cut, keep, [this](std::size_t m) { return std::uint32_t{votes_[m]}; }, out);
}

int Voter::cutFor(VoteCut& cut) const {
  if (cut.top > cut.limit) return keep_;
  if (mild_.keep <= 0 || cut.top == 0) return 0;
  cut.limit = cut.fourths.upper + mild_.spreads * cut.fourths.spread();
  return cut.top > cut.limit ? std::min(keep_, mild_.keep) : 0;
}

template <class Value>
void Voter::keepCandidates(std::uint32_t k, VoteCut cut, int keep, Value value, std::vector<Correspondence>& out) {
  const std::uint16_t top = cut.top;
  const auto above = static_cast<std::uint16_t>(cut.limit);
  // A body of revolution's accumulator is over its orbits: each one's first point stands for it.
  // A part of cyclic symmetry's over its points: each stands for its class, by the class member.
  const auto model_point = [this](std::size_t m) {
    return static_cast<std::uint32_t>(orbits_ != nullptr ? orbits_->member[m] : classes_ != nullptr ? classes_->member[classes_->of[m]] : m);
  };
  if (keep <= 1 || spacing_ <= 0) {
    keepBest(outliers_, keep, value);
    for (const std::size_t m : outliers_) out.push_back({k, model_point(m)});
    return;
  }
  // The upper outliers best first (counted into order, or sorted a batch at a time: usually the
  // first batch holds all that are kept); each kept unless a better one kept lies within spacing_.
  // Distances between model points (class members: a class's images are one candidate), or
  // between orbits in the axis's half-plane.
  const auto where = [this](std::uint32_t m) -> Vec3 {
    return orbits_ != nullptr ? orbits_->inPlane(orbits_->of[m]) : db_.model().points[m];
  };
  const std::size_t first = out.size();
  const auto better = moreVotes(value);
  const std::size_t batch = 4 * static_cast<std::size_t>(keep);
  // Votes are whole and lie in (above, top]: when that range is short, sortByCell's counting
  // sort over top - votes (most first; outliers_ holds ascending indices, and the sort keeps
  // their order) gives moreVotes's order at once, where partial_sort's comparisons took a fifth
  // of select().
  const std::size_t range = std::size_t{top} - above;
  std::size_t sorted = 0;
  if (range <= 2 * outliers_.size() + 64) {
    rank_.resize(outliers_.size());
    for (std::size_t r = 0; r < outliers_.size(); ++r) rank_[r] = top - value(outliers_[r]);
    sortByCell(rank_, range, bucket_, order_);
    by_votes_.resize(outliers_.size());
    for (std::size_t r = 0; r < order_.size(); ++r) by_votes_[r] = outliers_[order_[r]];
    outliers_.swap(by_votes_);
    sorted = outliers_.size();
  }
  for (std::size_t r = 0; r < outliers_.size(); ++r) {
    if (r == sorted) {
      sorted = std::min(outliers_.size(), sorted + batch);
      std::partial_sort(outliers_.begin() + static_cast<std::ptrdiff_t>(r),
                        outliers_.begin() + static_cast<std::ptrdiff_t>(sorted), outliers_.end(), better);
    }
    const Vec3 m = where(model_point(outliers_[r]));
    bool near = false;
    for (std::size_t c = first; c < out.size() && !near; ++c) near = (where(out[c].model) - m).squaredNorm() < spacing_ * spacing_;
    if (near) continue;
    out.push_back({k, model_point(outliers_[r])});
    if (out.size() - first >= static_cast<std::size_t>(keep)) break;
  }
}

void Voter::vote(const Points& points, const Points& normals, std::span<const std::uint32_t> group,
                 std::vector<Correspondence>& out) {
  if (group.size() >= 65535) throw Error(fmt::format("sub-group of {} points is too large to vote", group.size()));
  for (const std::uint32_t k : group) votePoint(points, normals, k, group, out);
}

ParallelVoter::ParallelVoter(const ModelDatabase& db, int keep, float spacing, const Orbits* orbits, MildOutliers mild)
    : voters_([&db, keep, spacing, orbits, mild] { return Voter(db, keep, spacing, orbits, mild); }) {}

void ParallelVoter::vote(const Points& points, const Points& normals, std::span<const std::uint32_t> group,
                         std::vector<Correspondence>& out) {
  if (group.size() >= 65535) throw Error(fmt::format("sub-group of {} points is too large to vote", group.size()));
  constexpr std::size_t kChunk = 16;  // points per task; each task's pairs kept apart, joined in order
  const std::size_t chunks = (group.size() + kChunk - 1) / kChunk;
  if (parts_.size() < chunks) parts_.resize(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    Voter& voter = voters_.local();
    parts_[c].clear();
    for (std::size_t i = c * kChunk; i < std::min(group.size(), (c + 1) * kChunk); ++i)
      voter.votePoint(points, normals, group[i], group, parts_[c]);
  });
  for (std::size_t c = 0; c < chunks; ++c) out.insert(out.end(), parts_[c].begin(), parts_[c].end());
}

struct NeighbourhoodVoter::Local {
  Voter voter;
  std::vector<std::uint32_t> found;
  std::vector<std::uint32_t> partners;
  std::vector<Correspondence> out;
};

NeighbourhoodVoter::NeighbourhoodVoter(const ModelDatabase& db, const Points& points, const Points& normals, float radius,
                                       int keep, std::span<const std::uint32_t> partners, float spacing,
                                       const Orbits* orbits, MildOutliers mild)
    : points_(points), normals_(normals), radius_(radius), voted_(points.size(), 0), candidates_(points.size()) {
  if (partners.empty()) {
    partners_.resize(points.size());
    std::iota(partners_.begin(), partners_.end(), 0u);
  } else {
    partners_.assign(partners.begin(), partners.end());
  }
  for (const auto o : partners_) partner_points_.push_back(points[o]);
  grid_ = std::make_unique<PointGrid>(partner_points_, 0.5f * radius);
  // Each thread's copy of this one (its own accumulator and buffers).
  locals_ = std::make_unique<tbb::enumerable_thread_specific<Local>>(Local{Voter(db, keep, spacing, orbits, mild), {}, {}, {}});
}

NeighbourhoodVoter::~NeighbourhoodVoter() = default;

void NeighbourhoodVoter::vote(std::span<const std::uint32_t> voters) {
  pending_.clear();
  for (const auto k : voters)
    if (!voted_[k]) {
      voted_[k] = 1;
      pending_.push_back(k);
    }
  // Four points a task at least: a batch of sub-groups has about 70 new voters of some 15 us
  // each, and tasks of 16 left the other core idle at the end. On ipd8-16 (two threads, 36
  // batches) the votes' wall time less their busy time per thread: 0.76-0.90 ms, against
  // 1.15-1.41 ms with 16.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pending_.size(), 4), [&](const tbb::blocked_range<std::size_t>& range) {
    Local& l = locals_->local();
    for (std::size_t v = range.begin(); v < range.end(); ++v) {
      const std::uint32_t k = pending_[v];
      grid_->within(points_[k], radius_, l.found);
      if (l.found.size() >= 65535)
        throw Error(fmt::format("{} points within {} mm of a point: too many to vote", l.found.size(), radius_));
      l.partners.clear();
      for (const auto o : l.found) l.partners.push_back(partners_[o]);
      l.out.clear();
      l.voter.votePoint(points_, normals_, k, l.partners, l.out);
      candidates_[k].reserve(l.out.size());  // one allocation
      for (const Correspondence& c : l.out) candidates_[k].push_back(c.model);
    }
  });
}

std::vector<std::vector<std::uint32_t>> voteNeighbourhoods(const ModelDatabase& db, const Points& points,
                                                           const Points& normals, float radius, int keep,
                                                           std::span<const std::uint32_t> voters,
                                                           std::span<const std::uint32_t> partners) {
  NeighbourhoodVoter voter(db, points, normals, radius, keep, partners);
  std::vector<std::uint32_t> all;
  if (voters.empty()) {
    all.resize(points.size());
    std::iota(all.begin(), all.end(), 0u);
    voters = all;
  }
  voter.vote(voters);
  return voter.release();
}

}  // namespace binpose
