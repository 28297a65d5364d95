#pragma once
// Sub-groups run side by side, a batch at a time, and their outcomes taken one after the other
// in the sub-groups' order: the detections are those of running them in turn (thesis 5.2.5-5.2.6),
// whatever the thread count.
#include "model_shape.hpp"
#include "subgroup_matcher.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace binpose {

/// What the sub-groups taken so far have established.
struct MatchState {
  explicit MatchState(std::size_t scene_points) : removed(scene_points, 0) {}
  std::vector<char> removed;           ///< scene points explained by a confident detection (5.2.6)
  std::vector<Pose> found;             ///< poses of the detections scoring at least explain_score (or removal_score)
  std::vector<Pose> tried;             ///< closed-form poses of the cliques verified (tried_share)
  std::vector<Hypothesis> hypotheses;  ///< the accepted detections, in the order found
  int confident = 0;                   ///< detections that removed their points
  bool enough = false;                 ///< max_instances confident detections reached
  std::size_t subgroups_run = 0, hypotheses_made = 0, refined = 0, refound = 0;  ///< as DetectionResult's

  /// Another pose of an object already found, or close to a clique pose already verified.
  [[nodiscard]] bool seen(const Pose& pose, const ModelShape& shape, float tried_share) const;
  /// A verified detection taken: a found object from explain_score, its scene points removed
  /// from removal_score (5.2.6), counted towards max_instances.
  void accept(Hypothesis h, const StageSettings& p, const ModelShape& shape, const Points& scene);
  /// Another pose of an object already found, within refound_share of the same-place tolerance.
  [[nodiscard]] bool refoundAt(const Pose& pose, const ModelShape& shape, float refound_share) const;
};

/// Time spent in the batches, ms, to be shared out among the stages (DetectionTiming).
struct ScheduleTimes {
  double local_vote_ms = 0;                         ///< the batches' local votes
  double work_ms = 0;                               ///< wall time of the sub-groups' work
  double vote_ms = 0, match_ms = 0, refine_ms = 0;  ///< the threads' time in each stage, summed

  /// Another run's times added (the points left's pass, left_points.hpp).
  ScheduleTimes& operator+=(const ScheduleTimes& o) {
    local_vote_ms += o.local_vote_ms;
    work_ms += o.work_ms;
    vote_ms += o.vote_ms;
    match_ms += o.match_ms;
    refine_ms += o.refine_ms;
    return *this;
  }
};

class GroupSchedule {
 public:
  GroupSchedule(const ModelDatabase& db, const StageSettings& p, const ModelShape& shape, const Matcher& matcher,
                const std::vector<std::vector<std::uint32_t>>& groups, NeighbourhoodVoter* local,
                const std::vector<char>& may_vote, MatchState& state);

  /// The sub-groups `order` (indices into the groups), a batch at a time; `all_voters`: the
  /// second pass, every point's candidates taken.
  void run(const std::vector<std::uint32_t>& order, bool all_voters);

  /// Each sub-group's first clique size in the first pass (0: none searched).
  [[nodiscard]] const std::vector<int>& largestCliques() const { return largest_clique_; }
  [[nodiscard]] const ScheduleTimes& times() const { return times_; }

 private:
  /// The batch's sub-groups voted, matched and their pending poses verified side by side.
  void runBatch(const std::vector<std::uint32_t>& order, std::size_t next, std::size_t end, bool all_voters);
  /// The batch's outcomes taken in order; a sub-group some of whose points were removed meanwhile runs again.
  void takeBatch(const std::vector<std::uint32_t>& order, std::size_t next, std::size_t end, bool all_voters);
  /// The slots of the batch whose pending pose is not near one an earlier slot found.
  void choosePosesToVerify(std::size_t count);
  /// One outcome taken: the counts, hypotheses and removals of running the sub-groups in turn.
  void take(GroupOutcome& o);
  /// The other clique's hypothesis in place of the first's when it scores more and neither is
  /// an object found or tried before, judged on the objects found by now (as when run in turn).
  void preferOther(GroupOutcome& o) const;

  const StageSettings& p_;
  const ModelShape& shape_;
  const Matcher& matcher_;
  const std::vector<std::vector<std::uint32_t>>& groups_;
  NeighbourhoodVoter* local_;
  const std::vector<char>& may_vote_;
  MatchState& state_;
  std::size_t threads_ = 1;
  std::vector<Slot> slots_;
  GroupOutcome earlier_;
  ParallelVoter parallel_;  ///< for the sub-groups run again on their own
  std::vector<std::uint32_t> voters_;
  std::vector<std::size_t> to_verify_;
  std::vector<int> largest_clique_;
  ScheduleTimes times_;
};

}  // namespace binpose
