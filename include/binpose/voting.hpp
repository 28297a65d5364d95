#pragma once
// Voting for scene points' model points (thesis 4.3-4.4).
#include <binpose/point_grid.hpp>
#include <binpose/model_database.hpp>

#include <cstdint>
#include <climits>
#include <memory>
#include <span>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

namespace binpose {

struct Orbits;  // symmetry.hpp

/// A candidate correspondence pair CP = {s, m}: a scene point index and a model point index.
struct Correspondence {
  std::uint32_t scene;
  std::uint32_t model;
  friend bool operator==(const Correspondence&, const Correspondence&) = default;
};

/// Lower and upper fourths of a data set (Johnson 1997): the medians of its smaller and larger
/// halves, the median counted in both halves when the count is odd. spread() is xi_s (eq. 10).
struct Fourths {
  double lower = 0, upper = 0;
  [[nodiscard]] double spread() const { return upper - lower; }
};
/// Fourths of the values v with histogram[v] occurrences each (at least one value).
Fourths fourthsOfHistogram(std::span<const std::uint32_t> histogram);

/// Eq. 10-11 on accumulator values: the indices of the upper outliers (> x_u + 3 xi_s), in index
/// order, into `out` (cleared; nothing when there is no outlier). `histogram` is scratch, kept
/// by the caller so nothing is allocated per call.
void upperOutliers(std::span<const std::uint32_t> values, std::vector<std::uint32_t>& histogram,
                   std::vector<std::size_t>& out);

/// Eq. 10-11 on an accumulator: its largest count, and the value above which a count is an upper
/// outlier of the non-zero counts (x_u + 3 xi_s; unset when no count is above zero).
struct VoteCut {
  std::uint16_t top = 0;
  double limit = 0;
  Fourths fourths;  ///< of the non-zero counts (eq. 10; unset with the limit)
};
/// VoteCut of 16-bit counts (the zeros are not part of the data set). `bytes` and `histogram`
/// are scratch, kept by the caller so nothing is allocated per call. The same for any count;
/// a multiple of 128 counts is read faster where the CPU has AVX2.
VoteCut upperOutlierCut(std::span<const std::uint16_t> votes, std::vector<std::uint8_t>& bytes,
                        std::vector<std::uint32_t>& histogram);

/// Selection of eq. 11-12 on accumulator values: the indices whose value is an upper outlier
/// (> x_u + 3 xi_s) and equals the largest value; empty when there is no outlier.
/// With `keep` > 1 (beyond the thesis): the `keep` highest upper outliers instead of only the
/// maximum (ties at the cut by index), for parts whose symmetric points share their votes.
std::vector<std::size_t> selectCandidates(std::span<const std::uint32_t> values, int keep = 1);

/// Beyond the thesis: the candidates of a scene point whose votes hold no upper outlier (eq. 11:
/// none above x_u + 3 xi_s). On a large or smooth part every model point takes votes from a
/// point's many features, the counts spread wide, and the right model point is often among the
/// few most voted without standing 3 fourth-spreads clear; eq. 11 leaves such a point without
/// any candidate. With `keep` > 0 it keeps its `keep` most voted (at most the voter's keep)
/// above x_u + `spreads` xi_s instead. keep 0: none (the thesis).
struct MildOutliers {
  float spreads = 2.0f;
  int keep = 0;
};

/// Votes for the model points of every point of a sub-group (eq. 8-12). Holds the accumulator
/// between calls so nothing is allocated per scene point; one Voter per thread.
class Voter {
 public:
  /// `keep`: candidates per scene point (1: the thesis's maximum; see selectCandidates).
  /// `spacing`: with keep > 1, each candidate at least this far (mm) in the model from every
  /// better-voted one kept (0: none). Each feature adds one vote (eq. 9).
  /// `orbits` (a body of revolution; symmetry.hpp): votes go to orbits, by their lists, and each
  /// candidate orbit is given as its first model point (spacing then between orbits, in the
  /// axis's half-plane). It must outlive the voter.
  /// `mild`: a point without an upper outlier keeps its mild outliers (MildOutliers).
  explicit Voter(const ModelDatabase& db, int keep = 1, float spacing = 0.0f, const Orbits* orbits = nullptr,
                 MildOutliers mild = {});
  /// Appends to `out` the candidate pairs of each point of `group` (indices into points/normals),
  /// each point voting with the whole group (the thesis's sub-group voting).
  void vote(const Points& points, const Points& normals, std::span<const std::uint32_t> group,
            std::vector<Correspondence>& out);
  /// Long lists counted by their bitsets (on by default where the CPU has AVX2), or every list
  /// point by point (off): the same votes either way.
  void useBitsets(bool on);
  [[nodiscard]] bool usesBitsets() const { return bitsets_; }
  /// Appends to `out` the candidate pairs of scene point k voting with the features to `partners`.
  void votePoint(const Points& points, const Points& normals, std::uint32_t k, std::span<const std::uint32_t> partners,
                 std::vector<Correspondence>& out);

 private:
  /// Adds the long lists of dense_lists_ (bitsets, ModelDatabase::denseBits) into `counters`
  /// (votes_ or narrow_). AVX2 only.
  template <class Count>
  void countDense(std::vector<Count>& counters);
  /// Appends scene point k's candidates, the upper outliers of the accumulator (eq. 10-12):
  /// votes_, or narrow_ (`narrow`).
  void select(std::uint32_t k, bool narrow, std::vector<Correspondence>& out);
  /// select's rest, once outliers_ holds the upper outliers (ascending) of counts value(m) cut
  /// by `cut`: the `keep` best, spread by spacing_ (eq. 12).
  template <class Value>
  void keepCandidates(std::uint32_t k, VoteCut cut, int keep, Value value, std::vector<Correspondence>& out);
  /// The candidates kept at `cut` (eq. 11's limit set): keep_, or with no count above it and
  /// mild outliers on, the limit lowered to mild_.spreads and mild_.keep of them; 0: none.
  int cutFor(VoteCut& cut) const;

  const ModelDatabase& db_;
  int keep_;
  float spacing_;
  MildOutliers mild_;
  std::vector<std::uint32_t> keys_;       ///< the keys of one point's features
  struct Distinct {
    std::uint32_t key, count, slot;  ///< a key, how many of the features have it, its slot in slots_
  };
  std::vector<Distinct> distinct_;        ///< keys_'s distinct keys, in the order first seen
  std::vector<std::uint32_t> slots_;      ///< groupKeys's hash table (all empty between calls)
  /// Gathers keys_ into distinct_.
  void groupKeys();
  struct List {
    std::span<const ModelDatabase::PointId> ids;
    std::uint16_t times;  ///< votes it adds: features of the point with this key (times their weight)
  };
  std::vector<List> lists_;  ///< the model point lists of those keys (but the bitsets)
  /// A long list adding more votes than this is counted point by point, not by its bitset.
  static constexpr std::uint16_t kMostBitsetRepeats = 16;
  std::size_t counters_;                  ///< model points (or orbits)
  std::vector<std::uint16_t> votes_;      ///< A_k, one counter per model point (or orbit), zeros after to a 256 multiple
  /// The same as bytes, for a point whose lists add at most 255 votes in all (empty without AVX2).
  std::vector<std::uint8_t> narrow_;
  std::vector<const std::uint64_t*> dense_lists_;  ///< one point's long lists' bitsets, each as often as it adds
  bool bitsets_;                          ///< long lists counted by bitset (where the CPU has AVX2)
  std::vector<std::uint8_t> bytes_;       ///< the accumulator as bytes (upperOutlierCut's scratch)
  std::vector<std::uint32_t> histogram_;  ///< the accumulator's histogram (eight side by side)
  std::vector<std::size_t> outliers_;     ///< model points whose votes are upper outliers
  std::vector<std::size_t> by_votes_;     ///< the same, most votes first (select's counting sort)
  std::vector<std::uint32_t> rank_, bucket_, order_;  ///< select's counting sort: keys, offsets, order
  const Orbits* orbits_;                  ///< a body of revolution's (votes_ then per orbit)
  const Orbits* classes_;                 ///< a cyclic symmetry's: candidates are class members
};

/// Voter::vote with the points of a group shared among threads: the same pairs in the same
/// order whatever the thread count.
class ParallelVoter {
 public:
  explicit ParallelVoter(const ModelDatabase& db, int keep = 1, float spacing = 0.0f, const Orbits* orbits = nullptr,
                         MildOutliers mild = {});
  void vote(const Points& points, const Points& normals, std::span<const std::uint32_t> group,
            std::vector<Correspondence>& out);

 private:
  tbb::enumerable_thread_specific<Voter> voters_;
  std::vector<std::vector<Correspondence>> parts_;
};

/// Beyond the thesis: every scene point votes once, with the features to the points within
/// `radius` of it (instead of once per sub-group it belongs to, about 9 times with the thesis's
/// eta and r), and on demand: a point is voted for only when a sub-group first needs it, so the
/// points of objects found and removed before that never vote. A point's candidates do not
/// depend on when it votes, nor on the thread count.
class NeighbourhoodVoter {
 public:
  /// Only the points listed in `partners` are paired with the voters (all when empty). The
  /// points and normals must outlive the voter. `spacing`, `orbits`, `mild`: as Voter's.
  NeighbourhoodVoter(const ModelDatabase& db, const Points& points, const Points& normals, float radius, int keep,
                     std::span<const std::uint32_t> partners = {}, float spacing = 0.0f,
                     const Orbits* orbits = nullptr, MildOutliers mild = {});
  ~NeighbourhoodVoter();
  NeighbourhoodVoter(const NeighbourhoodVoter&) = delete;
  NeighbourhoodVoter& operator=(const NeighbourhoodVoter&) = delete;
  /// Votes for the points of `voters` that have not voted yet, in parallel.
  void vote(std::span<const std::uint32_t> voters);
  /// The candidate model points of point i (empty until it has voted, or without an outlier).
  [[nodiscard]] const std::vector<std::uint32_t>& candidates(std::uint32_t i) const { return candidates_[i]; }
  /// All points' candidates, handed over.
  std::vector<std::vector<std::uint32_t>> release() { return std::move(candidates_); }

 private:
  struct Local;
  const Points& points_;
  const Points& normals_;
  float radius_;
  std::vector<std::uint32_t> partners_;  ///< partner index -> point index
  Points partner_points_;
  std::unique_ptr<PointGrid> grid_;  ///< the partners, for the radius searches
  std::vector<char> voted_;
  std::vector<std::vector<std::uint32_t>> candidates_;
  std::unique_ptr<tbb::enumerable_thread_specific<Local>> locals_;
  std::vector<std::uint32_t> pending_;
};

/// NeighbourhoodVoter's candidates of the points listed in `voters` (all when empty); the
/// others' lists stay empty.
std::vector<std::vector<std::uint32_t>> voteNeighbourhoods(const ModelDatabase& db, const Points& points,
                                                           const Points& normals, float radius, int keep,
                                                           std::span<const std::uint32_t> voters = {},
                                                           std::span<const std::uint32_t> partners = {});

}  // namespace binpose
