// Beyond the thesis: a weak detection tried again from poses turned a little (on a noisy scan),
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
//
// A quiet scan leaves a part turned over too, where the side that tells it apart is hidden: a
// bracket seen face-on by one plate, the other plate behind it, laid over its mirror image across
// that plate (IPD obj 1 on the simulated ideal and industrial bins: detections 55-75 mm off their
// copy, turned 180 degrees, scoring 0.5-0.6 where the copy's true pose scores 0.9). There the weak
// detections are tried turned over only, by the near-symmetric half turns and those that lay one
// of the part's flat faces on itself (withFaceFlips); the small turns found no more copies on
// those bins (2 fewer detections off, of 44) for a seventh more time.
#include "reseat.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>

#include <cmath>
#include <functional>
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
/// `self_hidden`: leave out the points that the part hides of itself (SceneEvidence::evaluate's
/// model spacing: ICP's share of the points, spaced wider than the model's). Without it a thin
/// part's far side, hidden behind its near side, counts as facing the sensor unsupported, and a
/// start that lays the near side right scores no more than one that lays it wrong.
float shortScore(const Pose& pose, const Matcher& m, bool self_hidden = false) {
  float spacing = 0.0f;
  if (self_hidden && !m.icp_model.points().empty())
    spacing = m.db.model().sample_radius *
              std::sqrt(static_cast<float>(m.scored_model.points().size()) / static_cast<float>(m.icp_model.points().size()));
  return m.evidence.evaluate(pose, m.icp_model, m.p.verify_tolerance, spacing).score();
}

/// The best of `starts` after kShortSteps of ICP each, scored on ICP's model points (shortScore):
/// its index and the pose it reached; its score into `score` when given.
std::pair<std::size_t, Pose> bestAfterShortIcp(const std::vector<Pose>& starts, const Matcher& m, float* score = nullptr,
                                               bool self_hidden = false) {
  const IcpParams short_icp = m.icpParams(kShortSteps);
  float best_score = -1.0f;
  std::pair<std::size_t, Pose> best{0, starts.front()};
  for (std::size_t i = 0; i < starts.size(); ++i) {
    const Pose pose = refinePose(starts[i], m.icp_model, m.scan.points, m.scan_grid, short_icp);
    if (const float s = shortScore(pose, m, self_hidden); s > best_score) {
      best_score = s;
      best = {i, pose};
    }
  }
  if (score != nullptr) *score = best_score;
  return best;
}

/// `start` refined in full replaces `h` where it scores kGain more, stands, its centroid lies
/// within kMostShift of the part's radius from `anchor`, and (when given) `taken` does not say
/// that another hypothesis lies there, scoring within kGain as much. True when it did.
bool takeIfBetter(Hypothesis& h, const Matcher& m, const ModelShape& shape, const Pose& start, const Vec3& anchor,
                  const std::function<bool(const Pose&, float)>& taken = {}) {
  const Pose pose = refinePose(start, m.icp_model, m.scan.points, m.scan_grid, m.icpParams(m.p.icp_iterations));
  if ((pose * shape.centroid() - anchor).norm() > kMostShift * shape.radius()) return false;
  std::vector<std::uint32_t> support;
  const Evidence e = m.scoredEvidence(pose, support);
  if (e.score() < h.detection.score + kGain || !m.stands(pose, e.score(), e, support)) return false;
  if (taken && taken(pose, e.score())) return false;
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

/// `pose` turned by each of the part's half turns (`flips`, near_flips.hpp). On a noisy scan
/// (`shift_lines`) each turn's line is also tried kLineShift of the diameter aside, either way along
/// two directions across it (a half turn about a parallel line moves the part by twice the
/// shift), and the start is the one that the scan supports best at ICP's gate: the line found
/// offline lays most of the part on itself, while the scan's copy may turn about another (a cap
/// seen down its axis about a line at its closed end's height, 8 mm from the one that keeps its
/// wall).
std::vector<Pose> flippedStarts(const Pose& pose, const Matcher& m, const ModelShape& shape, const std::vector<Pose>& flips,
                                bool shift_lines) {
  if (!shift_lines) {
    std::vector<Pose> starts;
    for (const Pose& flip : flips) starts.push_back(pose * flip);
    return starts;
  }
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
/// Only a start that scores more than `h` itself after the short ICP goes on to the full one. On
/// a quiet scan the lines are not shifted, the starts are compared without the points the part
/// hides of itself (shortScore), and the pose is not taken where `taken` (when given) says another
/// hypothesis lies, scoring within kGain as much: a half turn about a face far from the centroid
/// reaches a neighbour found already (a copy of the fandisk on an industrial bin, a cap stacked rim
/// to rim on another), and the copy would be lost as that neighbour's duplicate. True when `h`
/// moved.
bool flipOver(Hypothesis& h, const Matcher& m, const ModelShape& shape, const std::vector<Pose>& flips, bool quiet,
              const std::function<bool(const Pose&, float)>& taken = {}) {
  if (flips.empty()) return false;
  const std::vector<Pose> starts = flippedStarts(h.detection.pose, m, shape, flips, !quiet);
  float best = 0;
  const auto [i, pose] = bestAfterShortIcp(starts, m, &best, quiet);
  if (best <= shortScore(h.detection.pose, m, quiet)) return false;
  return takeIfBetter(h, m, shape, pose, starts[i] * shape.centroid(), taken);
}

}  // namespace

void reseatWeak(std::vector<Hypothesis>& hypotheses, const Matcher& matcher, const ModelShape& shape,
                const std::vector<Pose>& flips, bool quiet) {
  std::vector<Detection> placed;  // on a quiet scan, as each lies before any moves: the same whatever the threads
  if (quiet)
    for (const Hypothesis& h : hypotheses) placed.push_back(h.detection);
  tbb::parallel_for(std::size_t{0}, hypotheses.size(), [&](std::size_t i) {
    Hypothesis& h = hypotheses[i];
    const auto taken = [&](const Pose& pose, float score) {
      for (std::size_t j = 0; j < placed.size(); ++j)
        if (j != i && placed[j].score + kGain > score && shape.mostlyOverlaps(pose, placed[j].pose)) return true;
      return false;
    };
    const auto rounds = [&](float below) {  // set right, then again from its new place
      const Vec3 centre = h.detection.pose * shape.centroid();
      for (int round = 0; round < kMostRounds && h.detection.score < below; ++round)
        if (!reseat(h, matcher, shape, centre)) break;
    };
    if (quiet) {
      if (h.detection.score < kFlipScore) flipOver(h, matcher, shape, flips, true, taken);
      return;
    }
    rounds(kWeakScore);
    // A turned-over pose set right by its half turn is still a few degrees off, like any other.
    if (h.detection.score < kFlipScore && flipOver(h, matcher, shape, flips, false)) rounds(kFlipScore);
  });
}

}  // namespace binpose
