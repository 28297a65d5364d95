#pragma once
// Removal of a found object's points (thesis 5.2.6, eq. 39).
#include "model_shape.hpp"

#include <vector>

namespace binpose {

/// Marks in `removed` the scene points within sigma_dist (mm) of the model posed by `pose`:
/// they are explained, and later sub-groups run without them. Each point is decided on its
/// own, so the answer is the same whatever the thread count.
void removeExplained(const Points& scene, const Pose& pose, const ModelShape& shape, float sigma_dist,
                     std::vector<char>& removed);

}  // namespace binpose
