// The final refinement of a detection: point-to-plane ICP whose pairs go both ways, model to
// scan and scan to model, and agree in their normals.
#include <binpose/refine.hpp>

#include "icp_step.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace binpose {
namespace {

/// A pair counts only where its scan and model normals make less than 60 degrees (Rusinkiewicz &
/// Levoy 2001): a model point on a part's side paired with the floor beside it pulls the part
/// sideways by its distance from the floor's points.
constexpr float kCompatibleCos = 0.5f;
/// The scan points taken near the part lie within this many pair distances of its surface at
/// the start, so that the pose may move by a pair distance while they stay in reach.
constexpr float kNearReach = 2.0f;
/// Scan points paired to the model at most: where more lie near it (a large part in a dense scan:
/// 14 000 on PCL's milk carton), every k-th of them, so that a detection's polish costs a few
/// milliseconds at most. The structured-light bins' parts have 1 300-4 300, and every one of them
/// counts there: half of them leave a median centroid error of 1.02 mm instead of 0.89.
constexpr std::size_t kMostScanPoints = 4000;

/// The scan points near the posed model (within kNearReach pair distances of a model point) that
/// have a normal: their indices into the scan, ascending, and their normals.
struct NearScan {
  std::vector<std::uint32_t> index;
  Points normals;
  /// The normal of scan point i, or null when it is not near or has none.
  [[nodiscard]] const Vec3* normalOf(std::uint32_t i) const {
    const auto at = std::lower_bound(index.begin(), index.end(), i);
    return at != index.end() && *at == i ? &normals[static_cast<std::size_t>(at - index.begin())] : nullptr;
  }
};

NearScan nearScan(const Pose& pose, const PreparedModel& model, const PointGrid& model_grid, const PolishScan& scan, float gate) {
  const float reach = kNearReach * gate;
  std::vector<std::uint32_t> around;
  scan.grid.within(pose * model.centre(), static_cast<float>(model.reach()) + reach, around);
  std::sort(around.begin(), around.end());
  const Pose inverse = pose.inverse();
  NearScan near;
  for (std::uint32_t i : around) {
    const Vec3& q = scan.points[i];
    std::uint32_t m, o;
    float d2;
    if (!model_grid.nearest(inverse * q, reach, m, d2) || !scan.oriented_grid.nearest(q, scan.oriented_reach, o, d2)) continue;
    near.index.push_back(i);
    near.normals.push_back(scan.oriented_normals[o]);
  }
  if (const std::size_t n = near.index.size(); n > kMostScanPoints) {  // an even share, in order
    for (std::size_t k = 0; k < kMostScanPoints; ++k) {
      near.index[k] = near.index[k * n / kMostScanPoints];
      near.normals[k] = near.normals[k * n / kMostScanPoints];
    }
    near.index.resize(kMostScanPoints);
    near.normals.resize(kMostScanPoints);
  }
  return near;
}

constexpr std::uint32_t kUnpaired = ~std::uint32_t{0};

/// The nearest point of `grid` to q within `gate`, as PointGrid::nearest gives it. `pair` holds
/// q's pair of the step before (kUnpaired: none) and gets this one: the pose moves little from
/// step to step, so the nearest lies no farther than the old pair, and a search of that small
/// box finds it.
bool nearestAgain(const PointGrid& grid, const Points& points, const Vec3& q, float gate, std::uint32_t& pair) {
  float d2;
  if (pair != kUnpaired) {
    const float old_d2 = (points[pair] - q).squaredNorm();
    if (old_d2 <= gate * gate) return grid.nearestWithin(q, old_d2, pair, d2);
  }
  if (grid.nearest(q, gate, pair, d2)) return true;
  pair = kUnpaired;
  return false;
}

}  // namespace

Pose polishPose(const Pose& pose, const PreparedModel& model, const PointGrid& model_grid, const PolishScan& scan,
                const PolishParams& params) {
  const Points& mp = model.points();
  const Points& mn = model.normals();
  const float gate = params.max_distance;
  if (mp.size() < 3 || scan.points.empty() || !(gate > 0)) return pose;
  const NearScan near = nearScan(pose, model, model_grid, scan, gate);
  const auto faces = [&](const Vec3& p, const Vec3& n) { return n.dot(params.viewpoint - p) > 0; };
  std::vector<std::uint32_t> to_scan(mp.size(), kUnpaired), to_model(near.index.size(), kUnpaired);
  Pose current = pose;
  for (int it = 0; it < params.iterations; ++it) {
    const Vec3 c = current * model.centre();
    const Pose inverse = current.inverse();
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    int pairs = 0;
    for (std::size_t i = 0; i < mp.size(); ++i) {  // model to scan
      const Vec3 p = current * mp[i], n = current.linear() * mn[i];
      if (!faces(p, n) || !nearestAgain(scan.grid, scan.points, p, gate, to_scan[i])) continue;
      const Vec3* normal = near.normalOf(to_scan[i]);
      if (normal == nullptr || n.dot(*normal) < kCompatibleCos) continue;
      detail::addPointToPlane(p, n, scan.points[to_scan[i]], c, A, b);
      ++pairs;
    }
    for (std::size_t k = 0; k < near.index.size(); ++k) {  // scan to model
      const Vec3& q = scan.points[near.index[k]];
      if (!nearestAgain(model_grid, mp, inverse * q, gate, to_model[k])) continue;
      const Vec3 p = current * mp[to_model[k]], n = current.linear() * mn[to_model[k]];
      if (!faces(p, n) || n.dot(near.normals[k]) < kCompatibleCos) continue;
      detail::addPointToPlane(p, n, q, c, A, b);
      ++pairs;
    }
    if (pairs < 12) break;
    const Eigen::Matrix<double, 6, 1> x = detail::constrainedStep(A, b, model.reach());
    if (!x.allFinite()) break;
    current = detail::stepAbout(c, x) * current;
    if (detail::stepMotion(x, model.reach()) < detail::kConverged) break;
  }
  return current;
}

}  // namespace binpose
