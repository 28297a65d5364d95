// Beyond the thesis: the points both passes left unexplained vote again among themselves.
#include "left_points.hpp"

#include "local_votes.hpp"
#include "removal.hpp"
#include "stopwatch.hpp"

#include <algorithm>
#include <utility>

namespace binpose {
namespace {

/// A sub-group runs again when at least this share of its points is left: around the copies
/// found most sub-groups are mostly explained, and running them again costs a clique search
/// each for nothing. On the quiet fresh and depth-offset bins, half finds as many copies as
/// running every sub-group with C_n points left, at 0-6 ms more a bin against 3-20 ms
/// (docs/design.md, The points left vote again).
constexpr float kLeftShare = 0.5f;

/// The points removed, and those within sigma_dist of a detection scoring explain_score but
/// too little to remove its points (removal_score): the pass looks where nothing was found.
std::vector<char> explainedPoints(const Points& scene, const MatchState& state, const StageSettings& p, const ModelShape& shape) {
  std::vector<char> explained = state.removed;
  for (const Hypothesis& h : state.hypotheses)
    if (h.detection.score >= p.explain_score && h.detection.score < p.removal_score)
      removeExplained(scene, h.detection.pose, shape, p.sigma_dist, explained);
  return explained;
}

/// The sub-groups with at least `min_size` points left, and at least kLeftShare of theirs.
std::vector<std::uint32_t> groupsMostlyLeft(const std::vector<std::vector<std::uint32_t>>& groups,
                                            const std::vector<char>& explained, std::size_t min_size) {
  std::vector<std::uint32_t> order;
  for (std::uint32_t g = 0; g < groups.size(); ++g) {
    const auto left = static_cast<std::size_t>(
        std::count_if(groups[g].begin(), groups[g].end(), [&](std::uint32_t i) { return explained[i] == 0; }));
    if (left >= min_size && static_cast<float>(left) >= kLeftShare * static_cast<float>(groups[g].size())) order.push_back(g);
  }
  return order;
}

/// The detections the pass added from `first` (found poses from `first_found`) under `least`
/// dropped, as in the second pass (retry_min_score): a late look at crowded points finds more
/// of the right copies' neighbours' pieces than of the copies themselves below it.
void dropWeakAdded(MatchState& state, std::size_t first, std::size_t first_found, float least) {
  const auto weak = [&](const Hypothesis& h) { return h.detection.score < least; };
  const auto added = state.hypotheses.begin() + static_cast<std::ptrdiff_t>(first);
  const auto dropped = [&](const Pose& found) {  // a found pose is the very pose of its hypothesis
    return std::any_of(added, state.hypotheses.end(),
                       [&](const Hypothesis& h) { return weak(h) && h.detection.pose.matrix() == found.matrix(); });
  };
  state.found.erase(std::remove_if(state.found.begin() + static_cast<std::ptrdiff_t>(first_found), state.found.end(), dropped),
                    state.found.end());
  state.hypotheses.erase(std::remove_if(added, state.hypotheses.end(), weak), state.hypotheses.end());
}

}  // namespace

ScheduleTimes revoteLeftPoints(const ModelDatabase& db, const StageSettings& p, const ModelShape& shape,
                               const PartSymmetry& symmetry, const PreparedScene& scene, const Matcher& matcher,
                               const std::vector<std::vector<std::uint32_t>>& groups, const std::vector<char>& may_vote,
                               MatchState& state) {
  const auto t0 = Clock::now();
  const std::vector<char> explained = explainedPoints(scene.points, state, p, shape);
  const std::vector<std::uint32_t> order = groupsMostlyLeft(groups, explained, static_cast<std::size_t>(p.C_n));
  if (order.empty()) return {};
  const std::unique_ptr<NeighbourhoodVoter> voter = makeVoter(db, scene, p, symmetry, &explained);
  const double setup_ms = msSince(t0);
  Matcher again = matcher;
  again.local = voter.get();
  // The weak detections' points count as removed while the pass runs; what it removes stays so.
  const std::vector<char> removed = std::exchange(state.removed, explained);
  const std::size_t first = state.hypotheses.size(), first_found = state.found.size();
  GroupSchedule schedule(db, p, shape, again, groups, voter.get(), may_vote, state);
  schedule.run(order, false);
  for (std::size_t i = 0; i < removed.size(); ++i) state.removed[i] = removed[i] || (state.removed[i] && !explained[i]);
  dropWeakAdded(state, first, first_found, std::max(p.min_score, p.retry_min_score));
  ScheduleTimes times = schedule.times();
  times.local_vote_ms += setup_ms;
  return times;
}

}  // namespace binpose
