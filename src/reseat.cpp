// Beyond the thesis: a weak detection on a noisy scan tried again from poses turned a little,
// and from the part turned over.
//
// ICP (5.2.6) settles in the nearest minimum of its point-to-plane error. On a noisy scan that
// minimum is often a few degrees and millimetres off the part: a clique's pose from noisy normals
// starts 10-25 degrees off, and a flat part's face or a neighbour's surface holds ICP there. The
// score shows it (supported minus contradicted model points): on the simulated structured-light
// and time-of-flight bins, 26 of 32 detections 5-28 degrees off their copy score 0.05-0.5 less
// than the copy's true pose refined the same way. Turned starts let ICP leave that minimum.
//
// Where the part is nearly symmetric under a half turn, the noisy side that tells the two apart
// leaves a clique's pose turned over at the copy's place: 27 detections on the 72 fresh simulated
// bins lie 150-180 degrees off their copy, and refined from the copy's true pose 25 of those
// copies score more. The part's near-symmetric half turns (near_flips.hpp) give those starts.
#include "reseat.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>

#include <cmath>
#include <utility>

namespace binpose {

namespace {

/// Hypotheses scoring under this are tried again: on the simulated structured-light bins, 24 of
/// the 32 detections off their copy and 76 of the 187 right ones.
constexpr float kWeakScore = 0.7f;
/// A pose set right moves on from its new place, this many times at most.
constexpr int kMostRounds = 3;
/// Each start is the pose turned by this about one of the part's three axes, either way, degrees.
constexpr float kTurnDegrees = 15.0f;
/// ICP steps each start takes before the best of them (scored on ICP's model points) is refined
/// in full: refining and scoring all six in full found 6 more copies over the 48 fresh noisy bins
/// for about a fifth more time on them (docs/design.md).
constexpr int kShortSteps = 5;
/// The best start's refined pose replaces the hypothesis when it scores this much more.
constexpr float kGain = 0.05f;
/// ... and its centroid moved by at most this share of the part's radius: a pose that moved
/// further is another object's (a neighbour's surface), not this one's set right.
constexpr float kMostShift = 0.5f;
/// Hypotheses scoring under this are also tried turned over (the detections turned over on the
/// simulated noisy bins score 0.17-0.89; from 0.9, as many copies set right at more cost).
constexpr float kFlipScore = 0.8f;
/// A half turn's line is also tried this share of the diameter aside (flippedStarts).
constexpr float kLineShift = 0.14f;

/// The starts: `pose` turned by kTurnDegrees either way about the part's three axes through
/// `centroid`; for a body of revolution (`axis`), about the two axes across its axis only, since
/// a turn about it changes nothing.
std::vector<Pose> turnedStarts(const Pose& pose, const Vec3& centroid, const RevolutionAxis* axis) {
  std::vector<Vec3> axes{Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  if (axis != nullptr) {
    const Vec3 across = axis->direction.unitOrthogonal();
    axes = {across, axis->direction.cross(across)};
  }
  std::vector<Pose> starts;
  const float angle = kTurnDegrees * static_cast<float>(M_PI) / 180.0f;
  for (const Vec3& a : axes)
    for (const float sign : {-1.0f, 1.0f}) starts.push_back(pose * turnAbout(a, sign * angle, centroid));
  return starts;
}

/// A pose's score on ICP's model points at the verification tolerance: how the starts compare.
float shortScore(const Pose& pose, const Matcher& m) {
  return m.evidence.evaluate(pose, m.icp_model, m.p.verify_tolerance, 0.0f).score();
}

/// The best of `starts` after kShortSteps of ICP each, scored on ICP's model points: its index
/// and the pose it reached; its score into `score` when given.
std::pair<std::size_t, Pose> bestAfterShortIcp(const std::vector<Pose>& starts, const Matcher& m, float* score = nullptr) {
  const IcpParams short_icp = m.icpParams(kShortSteps);
  float best_score = -1.0f;
  std::pair<std::size_t, Pose> best{0, starts.front()};
  for (std::size_t i = 0; i < starts.size(); ++i) {
    const Pose pose = refinePose(starts[i], m.icp_model, m.scan.points, m.scan_grid, short_icp);
    if (const float s = shortScore(pose, m); s > best_score) {
      best_score = s;
      best = {i, pose};
    }
  }
  if (score != nullptr) *score = best_score;
  return best;
}

/// `start` refined in full replaces `h` where it scores kGain more, stands and its centroid lies
/// within kMostShift of the part's radius from `anchor`. True when it did.
bool takeIfBetter(Hypothesis& h, const Matcher& m, const ModelShape& shape, const Pose& start, const Vec3& anchor) {
  const Pose pose = refinePose(start, m.icp_model, m.scan.points, m.scan_grid, m.icpParams(m.p.icp_iterations));
  if ((pose * shape.centroid() - anchor).norm() > kMostShift * shape.radius()) return false;
  std::vector<std::uint32_t> support;
  const Evidence e = m.scoredEvidence(pose, support);
  if (e.score() < h.detection.score + kGain || !m.stands(pose, e.score(), e, support)) return false;
  h.detection.pose = pose;
  h.detection.score = e.score();
  h.support = std::move(support);
  return true;
}

/// `h` replaced by the best of its turned starts, refined, where that one is clearly better
/// (takeIfBetter, held to `centre`). True when `h` moved.
bool reseat(Hypothesis& h, const Matcher& m, const ModelShape& shape, const Vec3& centre) {
  const RevolutionAxis* axis = m.symmetry.orbits() != nullptr ? &m.symmetry.orbits()->axis : nullptr;
  return takeIfBetter(h, m, shape, bestAfterShortIcp(turnedStarts(h.detection.pose, shape.centroid(), axis), m).second, centre);
}

/// `pose` turned by each of the part's near-symmetric half turns (`flips`, near_flips.hpp).
/// Each turn's line is also tried kLineShift of the diameter aside, either way along two
/// directions across it (a half turn about a parallel line moves the part by twice the shift),
/// and the start is the one that the scan supports best at ICP's gate: the line found offline
/// lays most of the part on itself, while the scan's copy may turn about another (a cap seen down
/// its axis about a line at its closed end's height, 8 mm from the one that keeps its wall).
std::vector<Pose> flippedStarts(const Pose& pose, const Matcher& m, const ModelShape& shape, const std::vector<Pose>& flips) {
  const float step = 2.0f * kLineShift * 2.0f * shape.radius();
  std::vector<Pose> starts;
  for (const Pose& flip : flips) {
    const Vec3 axis = Eigen::AngleAxisf(flip.linear()).axis();
    const Vec3 u = axis.unitOrthogonal(), w = axis.cross(u);
    float best = -1.0f;
    Pose start = pose * flip;
    for (int i = -1; i <= 1; ++i)
      for (int j = -1; j <= 1; ++j) {
        Pose shifted = flip;
        shifted.translation() += step * (static_cast<float>(i) * u + static_cast<float>(j) * w);
        const Pose candidate = pose * shifted;
        if (const float s = m.prescore(candidate, false); s > best) {
          best = s;
          start = candidate;
        }
      }
    starts.push_back(start);
  }
  return starts;
}

/// `h` replaced by the best of its flipped starts, refined, where that one is clearly better.
/// The copy lies up to a diameter from `h`: the refined pose is held to its start's centroid.
/// Only a start that scores more than `h` itself after the short ICP goes on to the full one.
/// True when `h` moved.
bool flipOver(Hypothesis& h, const Matcher& m, const ModelShape& shape, const std::vector<Pose>& flips) {
  if (flips.empty()) return false;
  const std::vector<Pose> starts = flippedStarts(h.detection.pose, m, shape, flips);
  float best = 0;
  const auto [i, pose] = bestAfterShortIcp(starts, m, &best);
  if (best <= shortScore(h.detection.pose, m)) return false;
  return takeIfBetter(h, m, shape, pose, starts[i] * shape.centroid());
}

}  // namespace

void reseatWeak(std::vector<Hypothesis>& hypotheses, const Matcher& matcher, const ModelShape& shape,
                const std::vector<Pose>& flips) {
  tbb::parallel_for(std::size_t{0}, hypotheses.size(), [&](std::size_t i) {
    Hypothesis& h = hypotheses[i];
    const auto rounds = [&](float below) {  // set right, then again from its new place
      const Vec3 centre = h.detection.pose * shape.centroid();
      for (int round = 0; round < kMostRounds && h.detection.score < below; ++round)
        if (!reseat(h, matcher, shape, centre)) break;
    };
    rounds(kWeakScore);
    // A turned-over pose set right by its half turn is still a few degrees off, like any other.
    if (h.detection.score < kFlipScore && flipOver(h, matcher, shape, flips)) rounds(kFlipScore);
  });
}

}  // namespace binpose
