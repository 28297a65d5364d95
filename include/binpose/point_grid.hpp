#pragma once
// A uniform grid over a point cloud for short-range neighbour queries: what the scan is asked
// during detection (the k nearest of a normal's plane fit, 5.2.2; the nearest within ICP's gate
// and within the score's tolerance). Built by one counting sort, O(n): about 3 ms for a
// 100 000-point scan against 15 ms for nanoflann's kd-tree, and faster to query at these
// ranges (bench_stages: BM_ScanIndex, BM_ScanNearest).
#include <binpose/types.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace binpose {

/// An organized cloud's point spacing without a search: the median, over a sample of its points,
/// of the distance to the nearest of the four pixel neighbours (about the median nearest-neighbour
/// spacing PointGrid estimates with a first grid). 0 when the cloud is not organized with one
/// pixel per point, or too few sampled points have a neighbour.
float pixelSpacing(const PointCloud& cloud);

class PointGrid {
 public:
  /// Cubic cells of side `cell` (mm; 0: twice the median nearest-neighbour spacing, estimated on
  /// a sample of the points) over the bulk of the points (1st-99th percentile per axis, widened
  /// by a tenth; points beyond go into the border cells, and every answer stays exact). The cell
  /// grows when that box would need more than about max(4 n, 2^20) cells. Non-finite points are
  /// left out of every answer.
  explicit PointGrid(const Points& points, float cell = 0.0f);

  /// Up to k nearest points of q: indices into the points and squared distances, nearest first
  /// (equal distances by index); returns the count (k unless the cloud holds fewer points).
  std::size_t knn(const Vec3& q, std::size_t k, std::uint32_t* indices, float* sq_dists) const;
  /// The nearest point of q within `max_distance` (equal distances: the lower index); false when
  /// there is none.
  bool nearest(const Vec3& q, float max_distance, std::uint32_t& index, float& sq_dist) const;
  /// nearest(), and when there is none, `clearance`: a distance (max_distance or more) within
  /// which q has no point, the nearer of the searched cells' nearest point and the searched
  /// box's nearest inner face (0 when one is found). A caller whose query moves a little (ICP)
  /// knows without a search that the query moved by less than clearance - max_distance still
  /// has none. On entry, a clearance above 0 (the query's last search found none) skips the
  /// small boxes around q that settle most queries, and searches a box 1.5 times as wide (a
  /// larger clearance, that spares the next searches): the same answer.
  bool nearest(const Vec3& q, float max_distance, std::uint32_t& index, float& sq_dist, float& clearance) const;
  /// The nearest point of q at a squared distance of at most `sq_limit`, as nearest() with
  /// max_distance^2 = sq_limit: for a caller that knows a point that close (ICP, whose pairs move
  /// little from one step to the next), a search of that small box alone.
  bool nearestWithin(const Vec3& q, float sq_limit, std::uint32_t& index, float& sq_dist) const;

  /// Whether some point lies within `max_distance` of q (squared distance <= max_distance^2):
  /// nearest()'s answer is found, but the search stops at the first such point.
  [[nodiscard]] bool anyWithin(const Vec3& q, float max_distance) const;

  /// Every point closer than `radius` to q (squared distance < radius^2, as nanoflann's radius
  /// search): indices into the points, in no particular order, into `out` (cleared).
  void within(const Vec3& q, float radius, std::vector<std::uint32_t>& out) const;
  [[nodiscard]] float cellSize() const { return cell_; }
  [[nodiscard]] std::size_t size() const { return ids_.size(); }

 private:
  struct Box { int x0, x1, y0, y1, z0, z1; };
  [[nodiscard]] Box boxAround(const Vec3& q, float radius) const;
  /// The nearest point with squared distance <= limit in the cells of the box of `radius`
  /// around q (radius >= sqrt(limit): all of them).
  bool searchBox(const Vec3& q, float radius, float limit, std::uint32_t& index, float& sq_dist) const;
  /// How far from q every point lies inside the cells of `b` (the distance to the box's nearest
  /// face not on the grid's border; infinite when every face is on it).
  [[nodiscard]] float coveredDistance(const Vec3& q, const Box& b) const;
  /// row(first, end) for each row of the cells of `b` (the slots first to end - 1, side by side)
  /// until one returns true; whether one did.
  template <class Row>
  bool anyRow(const Box& b, Row&& row) const;
  /// hit(slot, d2) for each slot of [first, end) whose squared distance d2 to q is at most
  /// `limit`, in slot order, until one returns true; whether one did. Four points at a time, with
  /// the very sums of (p - q).squaredNorm(). With `seen`, also lowers *seen to every distance.
  template <class Hit>
  bool scan(std::uint32_t first, std::uint32_t end, const Vec3& q, float limit, Hit&& hit, float* seen = nullptr) const;
  [[nodiscard]] Vec3 pointAt(std::uint32_t slot) const { return {x_[slot], y_[slot], z_[slot]}; }
  void build(const Points& points, float cell);

  float cell_ = 1.0f;
  Vec3 lo_ = Vec3::Zero();
  int nx_ = 0, ny_ = 0, nz_ = 0;
  std::vector<std::uint32_t> offsets_;  ///< cells + 1 offsets into ids_ and x_, y_, z_ (x fastest)
  std::vector<std::uint32_t> ids_;      ///< point indices in cell order
  /// The points in cell order (a cell's points side by side), each coordinate apart for SIMD
  /// lanes, with kPad unused entries at the end (a last load of four stays inside).
  std::vector<float> x_, y_, z_;
  static constexpr std::size_t kPad = 3;
};

}  // namespace binpose
