#pragma once
// The k nearest points of a depth image's point, looked for among the points of the pixels
// around its own (the neighbourhoods of the normals' plane fits, 5.2.2), with a bound that proves
// them the nearest of the whole cloud, so that they are the ones PointGrid::knn finds.
#include <binpose/types.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace binpose {

class PixelNeighbours {
 public:
  /// The cloud's points by pixel. Usable when the cloud is a pinhole camera's image
  /// (PointCloud::fx and fy given, every point in front of the camera) with one pixel per point,
  /// none twice, in pixel order (as the readers give them); otherwise knn() always answers
  /// false. The cloud must outlive this.
  explicit PixelNeighbours(const PointCloud& cloud);

  [[nodiscard]] bool usable() const { return first_ != nullptr; }

  /// The k nearest points of the cloud's point `i` (itself included), as PointGrid::knn gives
  /// them (indices and squared distances, nearest first, equal distances by index), found among
  /// the points of the (2 w + 1) x (2 w + 1) pixels around i's (w = 1, then 4). True only when
  /// they are proved the nearest of the whole cloud: any other point is seen through a pixel at
  /// least w + 1 columns or rows away, so it lies beyond a plane through the camera at least
  /// `reach` from the point, and the k-th found lies closer than that. False otherwise, and for
  /// k over 32 (then ask the grid); the outputs are written only when true.
  bool knn(std::uint32_t i, std::size_t k, std::uint32_t* indices, float* sq_dists) const;

  /// What a search among the pixels proved of the whole cloud.
  enum class Proof { kFound, kNone, kUnknown };
  /// The nearest cloud point of any point q in front of the camera (ICP's posed model points,
  /// the score's), with a squared distance of at most `sq_limit`, as PointGrid::nearest gives it
  /// (equal distances by index): looked for among the points of the pixels around q's image
  /// (3 x 3, then 9 x 9), proved as knn's. kFound (index and sq_dist written), or kNone with
  /// `clearance` (when given) a distance, sqrt(sq_limit) or more, within which q has no point;
  /// kUnknown when the pixels prove neither (ask the grid), and for q outside the image.
  Proof nearest(const Vec3& q, float sq_limit, std::uint32_t& index, float& sq_dist, float* clearance = nullptr) const;

 private:
  [[nodiscard]] float reach(const Vec3& q, float pixels) const;
  /// The padded pixel table's entry of q's pixel, or null when q's image lies outside the image.
  [[nodiscard]] const std::int32_t* centreOf(const Vec3& q) const;

  const PointCloud& cloud_;
  std::ptrdiff_t pitch_ = 0;  ///< a row's pixels with the margins
  /// For each pixel of the image with a margin all round (row-major), the number of points seen
  /// through the pixels before it: a row's points between two columns are contiguous.
  std::unique_ptr<std::int32_t[]> first_;
};

}  // namespace binpose
