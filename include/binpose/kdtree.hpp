#pragma once
// nanoflann kd-tree over a binpose::Points array.
#include <binpose/types.hpp>

#include <nanoflann.hpp>

#include <memory>

namespace binpose {

struct PointsAdaptor {
  const Points& pts;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return pts.size(); }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t dim) const { return pts[i][static_cast<int>(dim)]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const { return false; }
};

class KdTree {
 public:
  using Index = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointsAdaptor>,
                                                    PointsAdaptor, 3, std::uint32_t>;
  /// `points` must outlive the tree.
  explicit KdTree(const Points& points)
      : adaptor_{points}, index_(std::make_unique<Index>(3, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(16))) {
    index_->buildIndex();
  }
  /// Up to k nearest neighbours of q (indices into the points, nearest first); returns the count.
  std::size_t knn(const Vec3& q, std::size_t k, std::uint32_t* indices, float* sq_dists) const {
    return index_->knnSearch(q.data(), k, indices, sq_dists);
  }
  /// Nearest point of q: its index and squared distance; false for an empty tree.
  bool nearest(const Vec3& q, std::uint32_t& index, float& sq_dist) const { return knn(q, 1, &index, &sq_dist) == 1; }
  /// All points within `radius` of q (unsorted).
  void radius(const Vec3& q, float radius, std::vector<std::pair<std::uint32_t, float>>& out) const {
    nanoflann::SearchParams params;
    params.sorted = false;
    index_->radiusSearch(q.data(), radius * radius, out, params);
  }

 private:
  PointsAdaptor adaptor_;
  std::unique_ptr<Index> index_;
};

}  // namespace binpose
