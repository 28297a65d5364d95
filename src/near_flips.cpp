// A part's near-symmetric half turns (near_flips.hpp).
#include "near_flips.hpp"

#include "face_hypotheses.hpp"

#include <binpose/point_grid.hpp>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>

namespace binpose {

namespace {

/// Directions of the half turns tried: an even spread over a hemisphere (a half turn about -a
/// is the one about a).
constexpr int kDirections = 96;
/// Model points aligned (an even share) and ICP steps per direction.
constexpr std::size_t kAligned = 256;
constexpr int kSteps = 8;
/// ICP's pair gate, as a share of the diameter: wide enough for a turn through the centroid to
/// reach a line 10-20 mm off it, then narrowed.
constexpr float kFirstGate = 0.15f;
constexpr float kLastGate = 0.03f;
/// A model point lies on the turned model within this share of the diameter, normals within 60
/// degrees: as near as a noisy scan tells surfaces apart.
constexpr float kOnShare = 0.05f;
constexpr float kOnCos = 0.5f;
/// A turn is kept when this share of the model lies on itself: a cap turned end over end keeps
/// its outer wall (0.43), a bracket's plate turned over its width 0.51, IPD obj 1 turned about
/// a diagonal 0.71. Each turn kept costs a short ICP run per weak hypothesis; those under 0.4,
/// or beyond the best three, turned no more copies right on the simulated noisy bins.
constexpr float kLeastOverlap = 0.4f;
constexpr std::size_t kMostFlips = 3;
/// Two turns are the same (and a turn the identity) within this many of ModelShape::samePose's
/// shares: about 30 degrees apart.
constexpr float kDistinctShare = 2.5f;

/// The i-th of n directions of a Fibonacci spiral over the upper hemisphere.
Vec3 spread(int i, int n) {
  const float z = 1.0f - (static_cast<float>(i) + 0.5f) / static_cast<float>(n);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = static_cast<float>(i) * 2.39996323f;  // the golden angle
  return {r * std::cos(phi), r * std::sin(phi), z};
}

/// `turn` aligned by point-to-point ICP (the closed form of 4.6, solvePose) of the `aligned`
/// model points against the whole model.
Pose alignedToSelf(Pose turn, const Points& aligned, const Points& points, const PointGrid& grid, float diameter) {
  Points from, to;
  std::vector<double> buffer;
  for (int step = 0; step < kSteps; ++step) {
    const float share = kFirstGate + (kLastGate - kFirstGate) * static_cast<float>(step) / static_cast<float>(kSteps - 1);
    from.clear();
    to.clear();
    for (const Vec3& p : aligned) {
      std::uint32_t nearest;
      float d2;
      if (!grid.nearest(turn * p, share * diameter, nearest, d2)) continue;
      from.push_back(p);
      to.push_back(points[nearest]);
    }
    const PoseFit fit = solvePose(from, to, buffer);
    if (!fit.ok) break;
    turn = fit.pose;
  }
  return turn;
}

/// The share of the `aligned` points (with `aligned_normals`) that `turn` lays on the model.
float overlap(const Pose& turn, const Points& aligned, const Points& aligned_normals, const Points& normals,
              const PointGrid& grid, float diameter) {
  std::size_t on = 0;
  for (std::size_t i = 0; i < aligned.size(); ++i) {
    std::uint32_t nearest;
    float d2;
    on += grid.nearest(turn * aligned[i], kOnShare * diameter, nearest, d2) &&
          (turn.linear() * aligned_normals[i]).dot(normals[nearest]) >= kOnCos;
  }
  return aligned.empty() ? 0.0f : static_cast<float>(on) / static_cast<float>(aligned.size());
}

}  // namespace

std::vector<Pose> nearFlips(const Points& points, const Points& normals, const ModelShape& shape) {
  if (points.size() < 3 || normals.size() != points.size()) return {};
  const float diameter = 2.0f * shape.radius();
  const PointGrid grid(points);
  Points aligned, aligned_normals;
  const std::size_t every = std::max<std::size_t>(1, points.size() / kAligned);
  for (std::size_t i = 0; i < points.size(); i += every) {
    aligned.push_back(points[i]);
    aligned_normals.push_back(normals[i]);
  }
  // Each direction on its own (in parallel, gathered in order: the same whatever the threads).
  std::vector<std::optional<std::pair<float, Pose>>> tried(kDirections);
  tbb::parallel_for(0, kDirections, [&](int k) {
    const Pose turn = alignedToSelf(turnAbout(spread(k, kDirections), static_cast<float>(M_PI), shape.centroid()),
                                    aligned, points, grid, diameter);
    if (shape.samePose(Pose::Identity(), turn, kDistinctShare)) return;  // back to itself, or a symmetry's image
    if (const float o = overlap(turn, aligned, aligned_normals, normals, grid, diameter); o >= kLeastOverlap)
      tried[static_cast<std::size_t>(k)] = std::make_pair(o, turn);
  });
  std::vector<std::pair<float, Pose>> found;
  for (const auto& t : tried)
    if (t) found.push_back(*t);
  std::stable_sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Pose> flips;
  for (const auto& [o, turn] : found)
    if (flips.size() < kMostFlips &&
        std::none_of(flips.begin(), flips.end(), [&](const Pose& f) { return shape.samePose(f, turn, kDistinctShare); }))
      flips.push_back(turn);
  return flips;
}

std::vector<Pose> withFaceFlips(std::vector<Pose> near, const std::vector<ModelFace>& faces, const ModelShape& shape) {
  std::vector<Pose> turns;
  for (const ModelFace& face : faces)
    for (const Vec3& axis : face.axes) {
      const Pose turn = turnAbout(axis, static_cast<float>(M_PI), face.centre);
      const auto same =
          std::find_if(turns.begin(), turns.end(), [&](const Pose& t) { return shape.samePose(t, turn, kDistinctShare); });
      if (same == turns.end())
        turns.push_back(turn);
      else  // the other side of a plate: half turns about parallel lines, whose mean is the one midway
        same->translation() = 0.5f * (same->translation() + turn.translation());
    }
  std::erase_if(near, [&](const Pose& n) {
    return std::any_of(turns.begin(), turns.end(), [&](const Pose& t) { return shape.samePose(t, n, kDistinctShare); });
  });
  near.insert(near.end(), turns.begin(), turns.end());
  return near;
}

}  // namespace binpose
