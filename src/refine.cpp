// ICP refinement and verification score.
#include <binpose/refine.hpp>

#include <binpose/geometry.hpp>

#include "oriented_lanes.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <bit>
#include <cmath>
#include <optional>
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include "facing_points.hpp"
#include "icp_step.hpp"
#include "refine_kernels.hpp"

namespace binpose {
namespace {

bool facesSensor(const Vec3& p, const Vec3& n, const Vec3& viewpoint) { return n.dot(viewpoint - p) > 0.0f; }

/// Points per task of the parallel loops: fixed, so the partial sums and their order (and so
/// every bit of the result) are the same whatever the thread count.
constexpr std::size_t kChunk = 128;
/// A model point farther than this many verification tolerances behind the floor or a wall the
/// scan shows in front of it lies inside that solid: physically impossible, counted as
/// contradicted (a right pose resting on the floor touches it within the noise).
constexpr float kInsideMargin = 2.0f;
static_assert(kChunk % 4 == 0, "a chunk starts on a SIMD lane boundary");

/// One chunk's share of ICP's normal equations.
struct NormalEquations {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
  int pairs = 0;
};

/// The nearest range seen in each image cell of a posed model (its own z-buffer): a dense
/// array over the cells its points cover, so a lookup is one load.
class ZBuffer {
 public:
  /// Cells of side `size` (in the image's u-v units) over [u0, u1] x [v0, v1]; wider when that
  /// would take more than kMaxCells.
  ZBuffer(float u0, float u1, float v0, float v1, float size) : size_(size) {
    for (;;) {  // cells at multiples of size_, as they would lie on an unbounded image
      x0_ = cellAt(u0);
      y0_ = cellAt(v0);
      width_ = cellAt(u1) - x0_ + 1;
      height_ = cellAt(v1) - y0_ + 1;
      if (width_ * height_ <= kMaxCells) break;
      size_ *= 2;
    }
    nearest_.assign(static_cast<std::size_t>(width_ * height_), INFINITY);
  }
  void add(float u, float v, float range) {
    float& at = nearest_[index(u, v)];
    at = std::min(at, range);
  }
  [[nodiscard]] float at(float u, float v) const { return nearest_[index(u, v)]; }

 private:
  static constexpr long kMaxCells = 1 << 20;
  [[nodiscard]] long cellAt(float u) const { return static_cast<long>(std::floor(u / size_)); }
  [[nodiscard]] std::size_t index(float u, float v) const {
    const long x = std::clamp(cellAt(u) - x0_, 0L, width_ - 1);
    const long y = std::clamp(cellAt(v) - y0_, 0L, height_ - 1);
    return static_cast<std::size_t>(y * width_ + x);
  }
  float size_;
  long x0_ = 0, y0_ = 0, width_ = 0, height_ = 0;
  std::vector<float> nearest_;
};

/// Every `stride`-th model point and normal as lanes (poseFour's input).
detail::OrientedLanes lanesOf(const Points& points, const Points& normals, std::size_t stride) {
  detail::OrientedLanes lanes;
  lanes.assign(points, normals, (points.size() + stride - 1) / stride, [stride](std::size_t s) { return s * stride; });
  return lanes;
}

/// Four points of `lanes` from slot s posed (p = pose * m, n = pose.linear() * n_m) into p and n
/// (four x, then four y, then four z each), and a mask of those facing the viewpoint: the very
/// sums Eigen's products and facesSensor() make (a Transform times a vector sums its columns in
/// turn, ((R0 x + R1 y) + R2 z) + t; a matrix times a vector and a dot product sum a + (b + c)),
/// so each lane is bit for bit what the scalar code gives.
unsigned poseFour(const detail::OrientedLanes& lanes, std::size_t s, const Pose& pose, const Vec3& viewpoint, float* p, float* n) {
#if defined(__SSE2__)
  return kernels::poseFour(lanes, s, pose, viewpoint, p, n);
#endif
  unsigned facing = 0;
  for (int l = 0; l < 4; ++l) {
    const Vec3 q = pose * Vec3(lanes.c[0][s + l], lanes.c[1][s + l], lanes.c[2][s + l]);
    const Vec3 v = pose.linear() * Vec3(lanes.c[3][s + l], lanes.c[4][s + l], lanes.c[5][s + l]);
    for (int k = 0; k < 3; ++k) {
      p[4 * k + l] = q[k];
      n[4 * k + l] = v[k];
    }
    facing |= unsigned(facesSensor(q, v, viewpoint)) << l;
  }
  return facing;
}

constexpr std::uint32_t kUnpaired = ~std::uint32_t{0};

/// Coarse to fine: ICP first steps with every kCoarseStride-th model point, then with all of
/// them once a coarse step moves no point more than kCoarseConverged mm, or no less than the
/// step before (the few points' pairs flip back and forth), or after kCoarseSteps steps (or
/// too few pairs are left). Most of the way is covered at a quarter of the queries.
constexpr std::size_t kCoarseStride = 4;
constexpr double kCoarseConverged = 0.05;
constexpr int kCoarseSteps = 6;

/// The stride of ICP's first steps for a model of `points` points (1: too few to thin).
std::size_t coarseStride(std::size_t points) { return points >= 64 * kCoarseStride ? kCoarseStride : 1; }

/// ICP also stops when a step below this, mm, moves the pose no less than the step before: the
/// pairs then flip back and forth between two sets (a limit cycle), and the pose with them.
constexpr double kStalled = 0.01;

/// Rounding allowance of the clearance test (mm): far above float rounding at a scan's
/// coordinates, far below the clearances that let a search be skipped.
constexpr float kClearanceMargin = 0.01f;

/// The scan points in front of the sensor (z > 0 in the image frame), each as its direction in
/// the image (u, v: x / z and y / z) and its range, in the scan's order.
struct Projected {
  std::vector<float> u, v, range;
};

/// Projected's entries of every scan point, four at a time where SSE allows (ViewLanes: the
/// same sums as the scalar code).
void projectAll(const Points& scan, const Vec3& viewpoint, const Eigen::Matrix3f& to_view, Projected& out) {
  out.u.reserve(scan.size());
  out.v.reserve(scan.size());
  out.range.reserve(scan.size());
  std::size_t i = 0;
#if defined(__SSE2__)
  i = kernels::projectBlocks(scan, viewpoint, to_view, out);  // whole blocks of four, the same sums as below
#endif
  for (; i < scan.size(); ++i) {
    const Vec3 q = to_view * (scan[i] - viewpoint);
    if (q.z() <= 0) continue;
    out.u.push_back(q.x() / q.z());
    out.v.push_back(q.y() / q.z());
    out.range.push_back(q.norm());
  }
}

}  // namespace

OrientedPoints evenShare(const Points& points, const Points& normals, std::size_t count) {
  const std::size_t stride = count > 0 ? std::max<std::size_t>(1, (points.size() + count - 1) / count) : 1;
  OrientedPoints out;
  for (std::size_t i = 0; i < points.size(); i += stride) {
    out.points.push_back(points[i]);
    out.normals.push_back(normals[i]);
  }
  return out;
}

PreparedModel preparedShare(const Points& points, const Points& normals, std::size_t count) {
  OrientedPoints share = evenShare(points, normals, count);
  return PreparedModel(std::move(share.points), std::move(share.normals));
}

PreparedModel::PreparedModel(Points points, Points normals)
    : points_(std::move(points)), normals_(std::move(normals)), centre_(Vec3::Zero()), reach_(0) {
  if (points_.size() != normals_.size())
    throw Error(fmt::format("a model needs one normal per point, got {} points and {} normals", points_.size(), normals_.size()));
  for (const Vec3& m : points_) centre_ += m;
  centre_ /= static_cast<float>(std::max<std::size_t>(1, points_.size()));
  for (const Vec3& m : points_) reach_ = std::max(reach_, double((m - centre_).norm()));
  reach_ = std::max(reach_, 1e-3);
  lanes_ = std::make_unique<detail::OrientedLanes>(lanesOf(points_, normals_, 1));
  coarse_ = std::make_unique<detail::OrientedLanes>(lanesOf(points_, normals_, coarseStride(points_.size())));
}

PreparedModel::~PreparedModel() = default;
PreparedModel::PreparedModel(PreparedModel&&) noexcept = default;
PreparedModel& PreparedModel::operator=(PreparedModel&&) noexcept = default;

Pose refinePose(const Pose& pose, const Points& model_points, const Points& model_normals, const Points& scan,
                const PointGrid& scan_grid, const IcpParams& params) {
  return refinePose(pose, PreparedModel(model_points, model_normals), scan, scan_grid, params);
}

namespace {

// The scan's nearest point through its pixels where they prove it, else through the grid: the
// same answers as PointGrid's (the squared limits computed as it computes them).
using Proof = PixelNeighbours::Proof;

/// The pixels' proof for q's nearest within sqrt(sq_limit) (kUnknown without pixels: the grid's).
Proof askPixels(const PixelNeighbours* pixels, const Vec3& q, float sq_limit, std::uint32_t& index, float& sq_dist,
                float* clearance = nullptr) {
  return pixels != nullptr ? pixels->nearest(q, sq_limit, index, sq_dist, clearance) : Proof::kUnknown;
}

/// max_distance squared as PointGrid::nearest squares it; negative (no search) when it is.
float squaredLimit(float max_distance) { return max_distance >= 0 ? max_distance * max_distance : -1.0f; }

/// PointGrid::nearestWithin.
bool nearestWithin(const PointGrid& grid, const PixelNeighbours* pixels, const Vec3& q, float sq_limit, std::uint32_t& index,
                   float& sq_dist) {
  const Proof proof = askPixels(pixels, q, sq_limit, index, sq_dist);
  return proof == Proof::kFound || (proof == Proof::kUnknown && grid.nearestWithin(q, sq_limit, index, sq_dist));
}

/// PointGrid::nearest with its clearance (any that holds: the caller skips only searches that
/// would find nothing).
bool nearest(const PointGrid& grid, const PixelNeighbours* pixels, const Vec3& q, float max_distance, std::uint32_t& index,
             float& sq_dist, float& clearance) {
  float none = 0;
  const Proof proof = askPixels(pixels, q, squaredLimit(max_distance), index, sq_dist, &none);
  if (proof == Proof::kUnknown) return grid.nearest(q, max_distance, index, sq_dist, clearance);
  clearance = proof == Proof::kFound ? 0.0f : none;
  return proof == Proof::kFound;
}

/// PointGrid::nearest.
bool nearest(const PointGrid& grid, const PixelNeighbours* pixels, const Vec3& q, float max_distance, std::uint32_t& index,
             float& sq_dist) {
  const Proof proof = askPixels(pixels, q, squaredLimit(max_distance), index, sq_dist);
  return proof == Proof::kFound || (proof == Proof::kUnknown && grid.nearest(q, max_distance, index, sq_dist));
}

}  // namespace

namespace {

/// ICP's memory between steps, per model point.
struct IcpPairs {
  explicit IcpPairs(std::size_t n) : paired(n, kUnpaired), missed_at(n), clearance(n, 0.0f), parts((n + kChunk - 1) / kChunk) {}
  // Each model point's scan pair of the step before: the pairs move little from step to step, so
  // the nearest lies no farther than the old pair, and a search of that small box finds it (the
  // same pair as a search out to the gate).
  std::vector<std::uint32_t> paired;
  // An unpaired point's last search: where the point was, and how far around it the scan had no
  // point. Most of a posed model's sensor-facing points lie where the scan sees another surface
  // (under other parts, or the part's own hidden side): each step's search for them finds
  // nothing. Moved by less than clearance - gate since, such a point still has none within the
  // gate (triangle inequality), and is not searched.
  std::vector<Vec3> missed_at;
  std::vector<float> clearance;
  std::vector<NormalEquations> parts;  ///< per chunk of model points, added in order
};

/// The point-to-plane normal equations of one step about centre c: every `stride`-th model
/// point facing the viewpoint, paired with its nearest scan point within the gate.
NormalEquations pairUp(const detail::OrientedLanes& lanes, std::size_t used, std::size_t stride, const Pose& current,
                       const Vec3& c, float gate, const Points& scan, const PointGrid& scan_grid, const PixelNeighbours* pixels,
                       const Vec3& viewpoint, IcpPairs& state) {
  const std::size_t chunks = (used + kChunk - 1) / kChunk;
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t k) {
    NormalEquations& e = state.parts[k];
    e = NormalEquations{};
    const std::size_t end = std::min(used, (k + 1) * kChunk);
    alignas(16) float pf[12], nf[12];  // four posed points and normals, coordinate by coordinate
    unsigned facing = 0;
    for (std::size_t s = k * kChunk; s < end; ++s) {
      const std::size_t lane = (s - k * kChunk) % 4;  // kChunk is a multiple of 4
      if (lane == 0) facing = poseFour(lanes, s, current, viewpoint, pf, nf);
      if ((facing >> lane & 1u) == 0) continue;
      const std::size_t i = s * stride;
      const Vec3 p(pf[lane], pf[4 + lane], pf[8 + lane]);
      const Vec3 n(nf[lane], nf[4 + lane], nf[8 + lane]);
      std::uint32_t& j = state.paired[i];
      if (j == kUnpaired && state.clearance[i] - (p - state.missed_at[i]).norm() > gate + kClearanceMargin) continue;
      float d2;
      const float old_d2 = j != kUnpaired ? (scan[j] - p).squaredNorm() : INFINITY;
      const bool found = old_d2 <= gate * gate ? nearestWithin(scan_grid, pixels, p, old_d2, j, d2)
                                               : nearest(scan_grid, pixels, p, gate, j, d2, state.clearance[i]);
      if (!found) {
        j = kUnpaired;
        state.missed_at[i] = p;
        continue;
      }
      detail::addPointToPlane(p, n, scan[j], c, e.A, e.b);
      ++e.pairs;
    }
  });
  NormalEquations sum;  // the chunks added in order
  for (std::size_t k = 0; k < chunks; ++k) {
    sum.A += state.parts[k].A;
    sum.b += state.parts[k].b;
    sum.pairs += state.parts[k].pairs;
  }
  return sum;
}

}  // namespace

Pose refinePose(const Pose& pose, const PreparedModel& model, const Points& scan, const PointGrid& scan_grid,
                const IcpParams& params) {
  const Points& model_points = model.points();
  const PixelNeighbours* pixels = params.pixels != nullptr && params.pixels->usable() ? params.pixels : nullptr;
  const double length = model.reach();  // the part's reach from its centre: rotations in mm at its edge
  Pose current = pose;
  float gate = params.max_distance;
  std::size_t stride = coarseStride(model_points.size());
  IcpPairs pairs(model_points.size());
  double last_moved = INFINITY;  // the last step's, in the current stage
  for (int it = 0; it < params.iterations; ++it) {
    // Linearised about the posed model's centre: a part's free motions (the spin of a body of
    // revolution) then stay pure rotations about its own axis instead of leaking into t.
    const Vec3 c = current * model.centre();
    const std::size_t used = (model_points.size() + stride - 1) / stride;  // points i = s * stride
    const detail::OrientedLanes& lanes = stride == 1 ? model.lanes() : model.coarseLanes();
    const NormalEquations sum = pairUp(lanes, used, stride, current, c, gate, scan, scan_grid, pixels, params.viewpoint, pairs);
    if (sum.pairs < 12) {
      if (stride == 1) break;
      stride = 1;  // too few pairs among the coarse points: on with all of them
      continue;
    }
    const Eigen::Matrix<double, 6, 1> x = detail::constrainedStep(sum.A, sum.b, length);
    if (!x.allFinite()) break;
    current = detail::stepAbout(c, x) * current;
    if (params.path != nullptr) params.path->push_back(current);
    if (params.stop && params.stop(current)) break;
    gate = std::max(params.min_distance, gate * 0.7f);
    // Converged when no model point moves more than kConverged (the step's rotation at the
    // part's reach plus its translation), or stalled (kStalled); the coarse points hand over
    // at kCoarseConverged.
    const double moved = detail::stepMotion(x, length);
    if (stride > 1) {
      if (moved < kCoarseConverged || moved >= last_moved || it + 1 >= kCoarseSteps) {
        stride = 1;
        last_moved = INFINITY;
      } else {
        last_moved = moved;
      }
      continue;
    }
    if (moved < detail::kConverged || (moved < kStalled && moved >= last_moved)) break;
    last_moved = moved;
  }
  return current;
}

SceneEvidence::SceneEvidence(const Points& scan, const PointGrid& grid, const Vec3& viewpoint, const PixelNeighbours* pixels)
    : scan_(scan), grid_(grid), pixels_(pixels != nullptr && pixels->usable() ? pixels : nullptr), viewpoint_(viewpoint),
      to_view_(Eigen::Matrix3f::Identity()) {
  if (scan.empty()) return;
  Vec3 axis = Vec3::Zero();
  for (const Vec3& p : scan) axis += p - viewpoint;
  if (!normalizeSafe(axis)) return;
  to_view_ = lookingAlong(axis);  // image frame: z along the mean viewing direction
  // Cell size: about 1.5 scan spacings at the median range (spacing from a sample of points).
  std::vector<float> spacing, depth;
  const std::size_t step = std::max<std::size_t>(1, scan.size() / 2000);
  for (std::size_t i = 0; i < scan.size(); i += step) {
    std::uint32_t idx[2];
    float d2[2];
    const auto at = static_cast<std::uint32_t>(i);
    if ((pixels != nullptr && pixels->knn(at, 2, idx, d2)) || grid.knn(scan[i], 2, idx, d2) == 2)
      spacing.push_back(std::sqrt(d2[1]));
    depth.push_back((to_view_ * (scan[i] - viewpoint)).z());
  }
  if (spacing.empty()) return;
  const float mid_depth = medianOf(depth);
  if (!(mid_depth > 0)) return;
  bin_ = 1.5f * std::max(medianOf(spacing), 1e-6f) / mid_depth;
  // Each point's direction (u, v: x / z and y / z in the image frame) and range, once.
  Projected seen;
  projectAll(scan, viewpoint, to_view_, seen);
  float u1 = -INFINITY, v1 = -INFINITY;
  u0_ = v0_ = INFINITY;
  for (std::size_t i = 0; i < seen.u.size(); ++i) {
    u0_ = std::min(u0_, seen.u[i]); u1 = std::max(u1, seen.u[i]);
    v0_ = std::min(v0_, seen.v[i]); v1 = std::max(v1, seen.v[i]);
  }
  if (!(u1 >= u0_)) return;
  bin_ = std::max(bin_, std::sqrt((u1 - u0_) * (v1 - v0_) / 4e6f));  // at most about 4 M cells
  width_ = static_cast<long>((u1 - u0_) / bin_) + 1;
  height_ = static_cast<long>((v1 - v0_) / bin_) + 1;
  nearest_.assign(static_cast<std::size_t>(width_ * height_), INFINITY);
  std::size_t i = 0;
#if defined(__SSE4_1__)
  i = kernels::nearestBlocks(seen.u, seen.v, seen.range, u0_, v0_, bin_, width_, height_, nearest_);  // cellAt's sums
#endif
  for (; i < seen.u.size(); ++i)
    if (const long c = cellAt(seen.u[i], seen.v[i]); c >= 0) nearest_[c] = std::min(nearest_[c], seen.range[i]);
}

long SceneEvidence::cellAt(float u, float v) const {
  if (width_ == 0) return -1;
  const auto x = static_cast<long>(std::floor((u - u0_) / bin_));
  const auto y = static_cast<long>(std::floor((v - v0_) / bin_));
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return -1;
  return y * width_ + x;
}

namespace {

/// Whether p (at `range` from `viewpoint`) lies behind plane b by more than kInsideMargin
/// tolerances, where the scan sees the plane in front of it: the line of sight to p crosses b
/// where the scan's nearest range (`seen_range`) lies on it.
bool behindSeenPlane(const Plane& b, const Vec3& viewpoint, const Vec3& p, float range, float seen_range, float tolerance) {
  const float side_viewpoint = b.side(viewpoint), side_point = b.side(p);
  if (side_viewpoint * side_point >= 0 || std::abs(side_point) <= kInsideMargin * tolerance) return false;  // in front, or touching
  const float crossing = range * side_viewpoint / (side_viewpoint - side_point);
  return std::abs(seen_range - crossing) <= 2 * tolerance;
}

}  // namespace

bool SceneEvidence::insideBackground(const Vec3& p, float range, float seen_range, float tolerance) const {
  return std::any_of(background_.begin(), background_.end(),
                     [&](const Plane& b) { return behindSeenPlane(b, viewpoint_, p, range, seen_range, tolerance); });
}

namespace {

/// Whether p lies inside background plane b: behind it as the sensor at `viewpoint` sees it, by
/// more than `margin` and at most `reach`, its foot on b's extent, and over no other plane
/// parallel to b and behind it that the scan shows there (b then ends short of p: the bin's rim
/// above the floor).
bool inside(const Plane& b, std::span<const Plane> planes, const Vec3& p, const Vec3& viewpoint, float margin, float reach) {
  const float side_viewpoint = b.side(viewpoint), side_point = b.side(p);
  const float depth = std::abs(side_point);
  if (!(side_viewpoint * side_point < 0 && depth > margin && depth <= reach && b.covers(p))) return false;
  return std::none_of(planes.begin(), planes.end(), [&](const Plane& c) {
    if (&c == &b || !detail::nearlyParallel(c.normal, b.normal)) return false;  // another floor, a step, the bin's rim
    const float c_viewpoint = c.side(viewpoint), c_point = c.side(p);
    return std::abs(c_viewpoint) > std::abs(side_viewpoint) && (c_viewpoint * c_point > 0 || std::abs(c_point) <= margin) &&
           c.covers(p);
  });
}

}  // namespace

Sinking SceneEvidence::sinking(const Pose& pose, const PreparedModel& model, float margin, float reach) const {
  Sinking s;
  s.points = static_cast<int>(model.points().size());
  // Planes smaller than the part (a face of one taken for background) are not judged.
  std::vector<const Plane*> judged;
  for (const Plane& b : background_)
    if (b.extent == nullptr || b.extent->area() >= 4 * reach * reach) judged.push_back(&b);
  if (judged.empty()) return s;
  for (const Vec3& x : model.points()) {
    const Vec3 p = pose * x;
    s.sunk += std::any_of(judged.begin(), judged.end(),
                          [&](const Plane* b) { return inside(*b, background_, p, viewpoint_, margin, reach); });
  }
  return s;
}

Evidence SceneEvidence::evaluate(const Pose& pose, const Points& model_points, const Points& model_normals,
                                 float tolerance, float model_spacing, std::vector<std::uint32_t>* support) const {
  return evaluate(pose, PreparedModel(model_points, model_normals), tolerance, model_spacing, support);
}

std::vector<Facing> facingPoints(const Pose& pose, const PreparedModel& model, const Eigen::Matrix3f& to_view,
                                 const Vec3& viewpoint, float cos_grazing_angle) {
  std::vector<Facing> facing;
  facing.reserve(model.points().size() / 2 + 64);  // about half face the sensor: one allocation, not one per doubling
  std::size_t i = 0;
#if defined(__SSE2__)
  i = kernels::facingBlocks(model.lanes(), pose, viewpoint, to_view, cos_grazing_angle,  // the same sums as below
                            [&](const Vec3& p, const Vec3& n, float range, float u, float v, bool grazing) {
                              facing.push_back({p, n, range, u, v, grazing});
                            });
#endif
  const Points &model_points = model.points(), &model_normals = model.normals();
  for (; i < model_points.size(); ++i) {
    const Vec3 p = pose * model_points[i];
    const Vec3 n = pose.linear() * model_normals[i];
    if (!facesSensor(p, n, viewpoint)) continue;
    const Vec3 q = to_view * (p - viewpoint);
    if (q.z() <= 0) continue;
    const float range = q.norm();  // the normal is of unit length: its dot is the incidence's cosine times range
    facing.push_back({p, n, range, q.x() / q.z(), q.y() / q.z(), n.dot(viewpoint - p) < cos_grazing_angle * range});
  }
  return facing;
}

namespace {

/// The model's own z-buffer on cells of two sample spacings: a facing point with the model's
/// surface clearly in front of it is hidden by the part itself and is not expected in the scan.
std::optional<ZBuffer> selfOcclusion(const std::vector<Facing>& facing, float model_spacing) {
  std::optional<ZBuffer> front;
  if (!facing.empty() && model_spacing > 0) {
    float mean_range = 0, u0 = INFINITY, u1 = -INFINITY, v0 = INFINITY, v1 = -INFINITY;
    for (const Facing& f : facing) {
      mean_range += f.range;
      u0 = std::min(u0, f.u); u1 = std::max(u1, f.u);
      v0 = std::min(v0, f.v); v1 = std::max(v1, f.v);
    }
    front.emplace(u0, u1, v0, v1, 2.0f * model_spacing / (mean_range / static_cast<float>(facing.size())));
    for (const Facing& f : facing) front->add(f.u, f.v, f.range);
  }
  return front;
}

enum Verdict : std::uint8_t { kHidden, kSupported, kContradicted, kOccluded, kOnBackground, kUnknown };

/// A scan point within `tolerance` of the facing point's tangent plane and within `lateral` of it
/// along that plane (SceneEvidence::setLateralSlack): the nearest such, into `index`. `near`:
/// scratch for the radius search.
bool alongSurface(const PointGrid& grid, const Points& scan, const Facing& f, float tolerance, float lateral,
                  std::vector<std::uint32_t>& near, std::uint32_t& index) {
  grid.within(f.p, std::sqrt(tolerance * tolerance + lateral * lateral), near);
  float best = INFINITY;
  for (const std::uint32_t j : near) {
    const Vec3 d = scan[j] - f.p;
    const float across = d.dot(f.n), along2 = d.squaredNorm() - across * across;
    if (std::abs(across) <= tolerance && along2 <= lateral * lateral && along2 < best) {
      best = along2;
      index = j;
    }
  }
  return std::isfinite(best);
}

/// The counts of the verdicts, in order; the supporting scan points into `support` when given.
Evidence tally(const std::vector<Facing>& facing, const std::vector<Verdict>& verdict, const std::vector<std::uint32_t>& nearest,
               std::vector<std::uint32_t>* support) {
  Evidence e;
  for (std::size_t i = 0; i < facing.size(); ++i) {
    if (verdict[i] == kHidden) continue;
    ++e.facing;
    e.supported += verdict[i] == kSupported;
    e.contradicted += verdict[i] == kContradicted;
    e.occluded += verdict[i] == kOccluded;
    e.on_background += verdict[i] == kOnBackground;
    if (facing[i].grazing) {
      ++e.grazing;
      e.grazing_supported += verdict[i] == kSupported;
      e.grazing_contradicted += verdict[i] == kContradicted;
    }
    if (support && verdict[i] == kSupported) support->push_back(nearest[i]);
  }
  return e;}

}  // namespace

Sinking SceneEvidence::sunkBehind(const Plane& face, const Pose& pose, const PreparedModel& model, float tolerance,
                                  float model_spacing) const {
  const std::vector<Facing> facing = facingPoints(pose, model, to_view_, viewpoint_, cos_grazing_);
  const std::optional<ZBuffer> front = selfOcclusion(facing, model_spacing);
  Sinking s;
  for (const Facing& f : facing) {
    if (front && front->at(f.u, f.v) < f.range - 2 * model_spacing) continue;  // hidden by the part itself
    ++s.points;
    // Clearly behind the part's own front, though closer than the self-occlusion margin: the
    // plane the scan shows in front of it may be the part's own face (a thin-walled cap's inner
    // wall under its 2 mm top, its outer wall under the rim), which a right pose shows as well.
    if (front && front->at(f.u, f.v) < f.range - kInsideMargin * tolerance) continue;
    const long c = cellAt(f.u, f.v);
    s.sunk += c >= 0 && std::isfinite(nearest_[c]) && behindSeenPlane(face, viewpoint_, f.p, f.range, nearest_[c], tolerance);
  }
  return s;
}

Evidence SceneEvidence::evaluate(const Pose& pose, const PreparedModel& model, float tolerance, float model_spacing,
                                 std::vector<std::uint32_t>* support) const {
  const std::vector<Facing> facing = facingPoints(pose, model, to_view_, viewpoint_, cos_grazing_);
  const std::optional<ZBuffer> front = selfOcclusion(facing, model_spacing);
  // Each facing point's verdict, in parallel (the tree queries), then counted in order.
  std::vector<Verdict> verdict(facing.size());
  std::vector<std::uint32_t> nearest(facing.size());
  const bool slack = lateral_ > tolerance;
  tbb::parallel_for(std::size_t{0}, (facing.size() + kChunk - 1) / kChunk, [&](std::size_t k) {
    std::vector<std::uint32_t> near;
    for (std::size_t i = k * kChunk; i < std::min(facing.size(), (k + 1) * kChunk); ++i) {
      const Facing& f = facing[i];
      verdict[i] = kUnknown;
      if (front && front->at(f.u, f.v) < f.range - 2 * model_spacing) {
        verdict[i] = kHidden;  // self-occluded
        continue;
      }
      float d2;
      // The nearest scan point itself only for the support list; the score asks only whether there is one.
      // (Only the nearest through the pixels: most of the score's points with none within the
      // tolerance lie off the scan's surface, where the grid's cells are empty and the pixels'
      // windows full; asked first for any point, the pixels lost 0.4-0.9 ms a run.)
      if ((support != nullptr ? binpose::nearest(grid_, pixels_, f.p, tolerance, nearest[i], d2) : grid_.anyWithin(f.p, tolerance)) ||
          (slack && alongSurface(grid_, scan_, f, tolerance, lateral_, near, nearest[i]))) {
        const bool on_bin = std::any_of(background_.begin(), background_.end(),
                                        [&](const Plane& b) { return b.distance(f.p) <= background_tolerance_; });
        verdict[i] = on_bin ? kOnBackground : kSupported;
        continue;
      }
      const long c = cellAt(f.u, f.v);
      if (c < 0 || !std::isfinite(nearest_[c])) continue;
      // Free space seen through the point, or the point inside the floor or a wall the scan shows.
      if (nearest_[c] > f.range + 2 * tolerance || insideBackground(f.p, f.range, nearest_[c], tolerance))
        verdict[i] = kContradicted;
      else if (nearest_[c] < f.range - 2 * tolerance)
        verdict[i] = kOccluded;  // the scan sees something clearly in front of it
    }
  });
  return tally(facing, verdict, nearest, support);
}

}  // namespace binpose
