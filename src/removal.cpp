// Removal of the scene points a found object explains (thesis 5.2.6, eq. 39).
#include "removal.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace binpose {
namespace {

/// Points per task: the test is a box check and, near the part, one grid query.
constexpr std::size_t kPointsPerTask = 1024;

}  // namespace

void removeExplained(const Points& scene, const Pose& pose, const ModelShape& shape, float sigma_dist,
                     std::vector<char>& removed) {
  const Pose inverse = pose.inverse();
  const Vec3 centre = pose * shape.centroid();
  const float reach = shape.radius() + sigma_dist;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, scene.size(), kPointsPerTask), [&](const auto& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      if (removed[i] || (scene[i] - centre).squaredNorm() > reach * reach) continue;
      if (shape.near(inverse * scene[i], sigma_dist)) removed[i] = 1;
    }
  });
}

}  // namespace binpose
