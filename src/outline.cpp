// Beyond the thesis: the scan just past a posed part's outline (SceneEvidence::outline).
//
// The score asks whether the scan supports the part where the part is; it cannot see a pose that
// lays one face of the part on a larger surface of the scan: the top of another copy, a box's
// side, the floor. Every facing point of such a pose is supported, and its other faces lie hidden
// behind that face. What gives it away is the outline: at a right pose's visible edge the scan
// drops to what lies behind the part or meets what lies in front of it; at such a wrong pose the
// scan goes on along the part's own surface. The test extrapolates the part's tangent plane at
// each outline cell two cells outwards and asks whether the scan lies on it there, or clearly
// behind it (the part stands out of what lies behind it). For a pose laid on one face, a
// background plane there (the bin's floor) that the part stands clear of counts as behind it,
// however thin the part: a plate of 3 mm sheet lying on the floor has the floor within the band
// of its face's plane.
#include <binpose/refine.hpp>

#include "facing_points.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace binpose {

namespace {

/// The model's cells: two sample spacings (as the self-occlusion test's), so that a face seen
/// head-on leaves no empty cell inside the outline.
constexpr float kCellSpacings = 2.0f;
/// The scan is read this many cells past the outline: a sensor blurs or drops the cell at a depth
/// edge (flying pixels, edge drop-outs), the next one shows what lies beyond.
constexpr int kStepCells = 2;
/// Tangent planes at more than 70 degrees to the line of sight are not extrapolated: a few cells
/// there spread over tens of mm of depth.
constexpr float kMinCosine = 0.34f;
/// The scan beyond a step continues the part's tangent plane within this many tolerances, and
/// lies clearly behind it past them. The plane is extrapolated from a noisy fit and the scan
/// point beyond it is noisy too; a structured-light sensor's depth also steps by whole disparity
/// quanta (about 3 mm at 1 m for a Kinect-class one). Within one tolerance, a pose sunk flush
/// into a real table read 30 % of its outline as dropped and half of it as continued.
constexpr float kBandTolerances = 2.0f;
/// The model's cells are at most this many across (a pose seen from very near).
constexpr long kMaxCells = 1L << 18;

/// The model's cell grid over its image: each cell's nearest facing point (the part's front).
struct Silhouette {
  float size = 0, u0 = 0, v0 = 0;
  long width = 0, height = 0;
  std::vector<std::int32_t> front;  ///< index into the facing points, -1 where the part is not

  [[nodiscard]] bool inside(long x, long y) const {
    return x >= 0 && y >= 0 && x < width && y < height && front[static_cast<std::size_t>(y * width + x)] >= 0;
  }
};

/// The silhouette of the facing points on cells of `size`, with kStepCells + 1 empty cells of
/// margin; empty when that would take more than kMaxCells.
Silhouette silhouetteOf(const std::vector<Facing>& seen, float size) {
  Silhouette s;
  float u1 = -INFINITY, v1 = -INFINITY;
  s.u0 = s.v0 = INFINITY;
  for (const Facing& f : seen) {
    s.u0 = std::min(s.u0, f.u); u1 = std::max(u1, f.u);
    s.v0 = std::min(s.v0, f.v); v1 = std::max(v1, f.v);
  }
  const float margin = static_cast<float>(kStepCells + 1) * size;
  s.size = size;
  s.u0 -= margin;
  s.v0 -= margin;
  s.width = static_cast<long>((u1 + margin - s.u0) / size) + 1;
  s.height = static_cast<long>((v1 + margin - s.v0) / size) + 1;
  if (!(s.width > 0 && s.height > 0) || s.width * s.height > kMaxCells) return {};
  s.front.assign(static_cast<std::size_t>(s.width * s.height), -1);
  for (std::size_t i = 0; i < seen.size(); ++i) {
    const auto x = static_cast<long>((seen[i].u - s.u0) / size), y = static_cast<long>((seen[i].v - s.v0) / size);
    std::int32_t& at = s.front[static_cast<std::size_t>(y * s.width + x)];
    if (at < 0 || seen[i].range < seen[static_cast<std::size_t>(at)].range) at = static_cast<std::int32_t>(i);
  }
  return s;
}

}  // namespace

OutlineEvidence SceneEvidence::outline(const Pose& pose, const PreparedModel& model, float tolerance,
                                       float model_spacing, bool on_bin) const {
  OutlineEvidence out;
  const std::vector<Facing> seen = facingPoints(pose, model, to_view_, viewpoint_, cos_grazing_);
  if (width_ == 0 || seen.empty() || !(model_spacing > 0)) return out;
  float mean_range = 0;
  for (const Facing& f : seen) mean_range += f.range / static_cast<float>(seen.size());
  const Silhouette s = silhouetteOf(seen, std::max(bin_, kCellSpacings * model_spacing / mean_range));
  const long steps[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  for (long y = 0; y < s.height; ++y)
    for (long x = 0; x < s.width; ++x) {
      if (!s.inside(x, y)) continue;
      const Facing& f = seen[static_cast<std::size_t>(s.front[static_cast<std::size_t>(y * s.width + x)])];
      // The edge must be one the scan shows: the part seen there, nothing in front of it.
      const long at = cellAt(f.u, f.v);
      if (at < 0 || !(std::abs(nearest_[static_cast<std::size_t>(at)] - f.range) <= 2 * tolerance)) continue;
      for (const auto& d : steps) {
        // An outline step: the part behind this cell, none in the next kStepCells outwards.
        if (!s.inside(x - d[0], y - d[1])) continue;
        bool outside = true;
        for (long k = 1; k <= kStepCells && outside; ++k) outside = !s.inside(x + k * d[0], y + k * d[1]);
        if (!outside) continue;
        const float u = s.u0 + (static_cast<float>(x + kStepCells * d[0]) + 0.5f) * s.size;
        const float v = s.v0 + (static_cast<float>(y + kStepCells * d[1]) + 0.5f) * s.size;
        const long beyond = cellAt(u, v);
        if (beyond < 0 || !std::isfinite(nearest_[static_cast<std::size_t>(beyond)])) continue;
        // Where the line of sight through that cell meets the part's tangent plane here.
        const Vec3 ray = (to_view_.transpose() * Vec3(u, v, 1.0f)).normalized();
        const float cosine = f.n.dot(ray);
        if (!(-cosine >= kMinCosine)) continue;
        const float range = f.n.dot(f.p - viewpoint_) / cosine;
        ++out.judged;
        const float seen = nearest_[static_cast<std::size_t>(beyond)];
        const float past = seen - range;  // > 0: the scan lies behind
        const float band = kBandTolerances * tolerance;
        const bool within = std::abs(past) <= band;
        // A thin part lying on the floor has the floor beyond its edge within the band: the bin
        // it stands on, not its own surface going on.
        const bool on_floor = within && on_bin && standsOnBackground(f.p, viewpoint_ + seen * ray);
        out.continued += within && !on_floor;
        out.dropped += past > band || on_floor;
      }
    }
  return out;
}

bool SceneEvidence::standsOnBackground(const Vec3& part, const Vec3& beyond) const {
  return std::any_of(background_.begin(), background_.end(), [&](const Plane& b) {
    const float side = b.side(part);
    return b.distance(beyond) <= background_tolerance_ && std::abs(side) > background_tolerance_ &&
           side * b.side(viewpoint_) > 0 && b.covers(beyond);
  });
}

}  // namespace binpose
