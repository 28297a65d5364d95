// Beyond the thesis: a weak detection on a noisy scan tried again from poses turned a little.
//
// ICP (5.2.6) settles in the nearest minimum of its point-to-plane error. On a noisy scan that
// minimum is often a few degrees and millimetres off the part: a clique's pose from noisy normals
// starts 10-25 degrees off, and a flat part's face or a neighbour's surface holds ICP there. The
// score shows it (supported minus contradicted model points): on the simulated structured-light
// and time-of-flight bins, 26 of 32 detections 5-28 degrees off their copy score 0.05-0.5 less
// than the copy's true pose refined the same way. Turned starts let ICP leave that minimum.
#include "reseat.hpp"

#include <tbb/parallel_for.h>

#include <cmath>

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

/// `h` replaced by the best of its turned starts, refined, where that one is clearly better: each
/// start takes kShortSteps of ICP and is scored on ICP's model points, and the best of them goes
/// on to full ICP and the full score. True when `h` moved.
bool reseat(Hypothesis& h, const Matcher& m, const ModelShape& shape, const Vec3& centre) {
  const IcpParams short_icp = m.icpParams(kShortSteps);
  float best_short = -1.0f;
  Pose start = h.detection.pose;
  const RevolutionAxis* axis = m.symmetry.orbits() != nullptr ? &m.symmetry.orbits()->axis : nullptr;
  for (const Pose& turned : turnedStarts(h.detection.pose, shape.centroid(), axis)) {
    const Pose pose = refinePose(turned, m.icp_model, m.scan.points, m.scan_grid, short_icp);
    if (const float s = m.evidence.evaluate(pose, m.icp_model, m.p.verify_tolerance, 0.0f).score(); s > best_short) {
      best_short = s;
      start = pose;
    }
  }
  const Pose pose = refinePose(start, m.icp_model, m.scan.points, m.scan_grid, m.icpParams(m.p.icp_iterations));
  if ((pose * shape.centroid() - centre).norm() > kMostShift * shape.radius()) return false;
  std::vector<std::uint32_t> support;
  const Evidence e = m.scoredEvidence(pose, support);
  if (e.score() < h.detection.score + kGain || !m.stands(pose, e.score(), e, support)) return false;
  h.detection.pose = pose;
  h.detection.score = e.score();
  h.support = std::move(support);
  return true;
}

}  // namespace

void reseatWeak(std::vector<Hypothesis>& hypotheses, const Matcher& matcher, const ModelShape& shape) {
  tbb::parallel_for(std::size_t{0}, hypotheses.size(), [&](std::size_t i) {
    Hypothesis& h = hypotheses[i];
    const Vec3 centre = h.detection.pose * shape.centroid();
    for (int round = 0; round < kMostRounds && h.detection.score < kWeakScore; ++round)
      if (!reseat(h, matcher, shape, centre)) break;
  });
}

}  // namespace binpose
