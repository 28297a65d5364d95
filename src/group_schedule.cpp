// Sub-groups side by side in batches, taken in order (thesis 5.2.5-5.2.6).
#include "group_schedule.hpp"

#include "removal.hpp"
#include "stopwatch.hpp"

#include <algorithm>
#include <atomic>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

namespace binpose {
namespace {

/// Sub-groups per batch, whatever the thread count: each runs on the scene as it stands at its
/// batch's start, so the batches, and with them the detections, must not follow the cores. Four
/// per thread on two cores keep both busy while few of a batch's outcomes are wasted by an earlier
/// one's removal.
constexpr std::size_t kGroupsPerBatch = 8;

/// Appends the voters (may_vote, or all with `all_voters`) among the points of `group` not yet
/// removed, when there are at least `min_size` such points (fewer: the sub-group will not run).
void appendLiveVoters(std::span<const std::uint32_t> group, const std::vector<char>& removed, const std::vector<char>& may_vote,
                      bool all_voters, std::size_t min_size, std::vector<std::uint32_t>& voters) {
  const std::size_t mark = voters.size();
  std::size_t live = 0;
  for (const auto i : group) {
    if (removed[i]) continue;
    ++live;
    if (all_voters || may_vote[i]) voters.push_back(i);
  }
  if (live < min_size) voters.resize(mark);
}

std::size_t workerThreads() {
  return std::min<std::size_t>(static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency())),
                               tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

bool anyRemoved(const std::vector<std::uint32_t>& members, const std::vector<char>& removed) {
  return std::any_of(members.begin(), members.end(), [&](std::uint32_t i) { return removed[i] != 0; });
}

}  // namespace

bool MatchState::seen(const Pose& pose, const ModelShape& shape, float tried_share) const {
  return std::any_of(found.begin(), found.end(), [&](const Pose& f) { return shape.samePose(pose, f); }) ||
         std::any_of(tried.begin(), tried.end(), [&](const Pose& t) { return shape.samePose(pose, t, tried_share); });
}

void MatchState::accept(Hypothesis h, const StageSettings& p, const ModelShape& shape, const Points& scene) {
  const Pose pose = h.detection.pose;
  const bool remove = h.detection.score >= p.removal_score;
  if (remove || h.detection.score >= p.explain_score) found.push_back(pose);
  if (remove) removeExplained(scene, pose, shape, p.sigma_dist, removed);  // 5.2.6
  hypotheses.push_back(std::move(h));
  if (remove && p.max_instances > 0 && ++confident >= p.max_instances) enough = true;
}

bool MatchState::refoundAt(const Pose& pose, const ModelShape& shape, float refound_share) const {
  return refound_share > 0 &&
         std::any_of(found.begin(), found.end(), [&](const Pose& f) { return shape.samePose(pose, f, refound_share); });
}

GroupSchedule::GroupSchedule(const ModelDatabase& db, const StageSettings& p, const ModelShape& shape, const Matcher& matcher,
                             const std::vector<std::vector<std::uint32_t>>& groups, NeighbourhoodVoter* local,
                             const std::vector<char>& may_vote, MatchState& state)
    : p_(p),
      shape_(shape),
      matcher_(matcher),
      groups_(groups),
      local_(local),
      may_vote_(may_vote),
      state_(state),
      threads_(workerThreads()),
      parallel_(db, matcher.symmetry.candidatesPerPoint(p), p.candidate_spacing, matcher.symmetry.votingOrbits(),
                mildOutliers(p)),
      largest_clique_(groups.size(), 0) {
  for (std::size_t k = 0; k < kGroupsPerBatch; ++k) slots_.emplace_back(db, p, matcher.symmetry);
}

void GroupSchedule::run(const std::vector<std::uint32_t>& order, bool all_voters) {
  for (std::size_t next = 0; next < order.size() && !state_.enough; next += slots_.size()) {
    const std::size_t end = std::min(order.size(), next + slots_.size());
    runBatch(order, next, end, all_voters);
    takeBatch(order, next, end, all_voters);
  }
}

void GroupSchedule::runBatch(const std::vector<std::uint32_t>& order, std::size_t next, std::size_t end, bool all_voters) {
  if (local_ != nullptr) {  // the batch's voters that have not voted yet vote first, all together
    const auto t_vote = Clock::now();
    voters_.clear();
    for (std::size_t g = next; g < end; ++g)
      appendLiveVoters(groups_[order[g]], state_.removed, may_vote_, all_voters, static_cast<std::size_t>(p_.C_n), voters_);
    local_->vote(voters_);
    times_.local_vote_ms += msSince(t_vote);
  }
  const auto t_work = Clock::now();
  // Isolated: a thread waiting inside a nested loop (graph, ICP) takes up no other sub-group
  // meanwhile, which would hold up its own.
  std::atomic<std::size_t> ticket{next};  // the batch's sub-groups started in order
  tbb::parallel_for(std::size_t{0}, std::min(threads_, end - next), [&](std::size_t) {
    for (std::size_t g; (g = ticket.fetch_add(1)) < end;) {
      Slot& slot = slots_[g - next];
      tbb::this_task_arena::isolate([&] { matcher_.prepare(groups_[order[g]], state_.removed, slot, all_voters); });
    }
  });
  choosePosesToVerify(end - next);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, to_verify_.size(), 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t k = range.begin(); k < range.end(); ++k)
          tbb::this_task_arena::isolate([&] { matcher_.verify(slots_[to_verify_[k]]); });
      },
      tbb::simple_partitioner());
  times_.work_ms += msSince(t_work);
}

void GroupSchedule::takeBatch(const std::vector<std::uint32_t>& order, std::size_t next, std::size_t end, bool all_voters) {
  for (std::size_t g = next; g < end && !state_.enough; ++g) {
    Slot& slot = slots_[g - next];
    const auto t_late = Clock::now();
    if (anyRemoved(slot.outcome.members, state_.removed)) {  // runs again on the points left
      std::swap(earlier_, slot.outcome);
      matcher_.run(groups_[order[g]], state_.removed, slot, all_voters, &earlier_, &parallel_);
      times_.work_ms += msSince(t_late);
    } else if (slot.outcome.pending && !std::any_of(slot.outcome.poses.begin(), slot.outcome.poses.end(), matcher_.seen)) {
      matcher_.verify(slot);  // deferred, and not the object found meanwhile after all
      times_.work_ms += msSince(t_late);
    }
    times_.vote_ms += slot.outcome.vote_ms;
    times_.match_ms += slot.outcome.match_ms;
    times_.refine_ms += slot.outcome.refine_ms;
    if (!all_voters) largest_clique_[order[g]] = slot.outcome.largest_clique;
    take(slot.outcome);
  }
}

void GroupSchedule::choosePosesToVerify(std::size_t count) {
  // A pose near one that a sub-group earlier in the batch found is most likely that object
  // again: once the earlier one is taken, its points are removed or its pose is found or tried.
  // Its verification waits until it is taken, and is skipped then if so.
  to_verify_.clear();
  for (std::size_t k = 0; k < count; ++k) {
    const GroupOutcome& o = slots_[k].outcome;
    if (!o.pending) continue;
    const auto near = [&](const Pose& pose) {
      return std::any_of(slots_.begin(), slots_.begin() + static_cast<long>(k), [&](const Slot& e) {
        return std::any_of(e.outcome.poses.begin(), e.outcome.poses.end(),
                           [&](const Pose& q) { return shape_.samePose(pose, q); });
      });
    };
    if (!p_.verify || !std::any_of(o.poses.begin(), o.poses.end(), near)) to_verify_.push_back(k);
  }
}

void GroupSchedule::preferOther(GroupOutcome& o) const {
  const auto any = [](const std::vector<Pose>& poses, const std::function<bool(const Pose&)>& test) {
    return std::any_of(poses.begin(), poses.end(), test);
  };
  // Run in turn, a first pose seen or come to a found object is dropped before the other is tried.
  if (!o.other || any(o.poses, matcher_.seen) || o.refound || any(o.path, matcher_.found)) return;
  OtherHypothesis& other = *o.other;
  if (other.hypothesis.detection.score <= o.hypothesis.detection.score || matcher_.seen(other.start) ||
      any(other.path, matcher_.found))
    return;
  o.poses = {other.start};
  o.hypothesis = std::move(other.hypothesis);
  o.evidence = other.evidence;
  o.path = std::move(other.path);
  o.stands.reset();  // judged for the first hypothesis, not this one
  o.reflected = false;
}

void GroupSchedule::take(GroupOutcome& o) {
  MatchState& s = state_;
  if (!o.ran) return;
  ++s.subgroups_run;
  if (o.clique.empty()) return;
  if (p_.verify) preferOther(o);
  if (p_.verify && std::any_of(o.poses.begin(), o.poses.end(), matcher_.seen)) return;  // that object again
  ++s.hypotheses_made;
  if (p_.tried_share > 0) s.tried.insert(s.tried.end(), o.poses.begin(), o.poses.end());
  if (o.screened_out) return;
  ++s.refined;
  // ICP brought the pose to an object found before this sub-group's turn: that object again.
  // When it ran, fewer objects may have been found (a batch's run side by side); its path is
  // looked at again, so the outcome is what running one after the other gives.
  if (p_.verify && (o.refound || std::any_of(o.path.begin(), o.path.end(), matcher_.found))) {
    ++s.refound;
    return;
  }
  const Detection det = o.hypothesis.detection;
  if (p_.verify && o.all_voters && o.evidence.scoreWithoutGrazing() < p_.retry_min_score) return;  // see retry_min_score
  // A reflected mirror-image clique stands in where no clique fits the part itself: as another
  // clique verified alone, it needs strong support (alternative_alone_score).
  if (p_.verify && o.reflected && det.score < p_.alternative_alone_score) return;
  if (p_.verify && !(o.stands ? *o.stands : matcher_.stands(det.pose, det.score, o.evidence, o.hypothesis.support))) return;
  s.accept(std::move(o.hypothesis), p_, shape_, matcher_.scene.points);
}

}  // namespace binpose
