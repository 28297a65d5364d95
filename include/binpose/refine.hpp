#pragma once
// Beyond the thesis: pose refinement by ICP and a verification score, both against the full scan.
#include <binpose/kdtree.hpp>
#include <binpose/pose.hpp>

namespace binpose {

struct IcpParams {
  int iterations = 20;
  float max_distance = 3.0f;  ///< correspondence gate at the start, mm; shrinks to min_distance
  float min_distance = 1.0f;  ///< smallest gate, mm
  Vec3 viewpoint = Vec3::Zero();
};

/// Point-to-plane ICP (Chen & Medioni) of the model's sensor-facing points against the scan,
/// with the model's normals as the planes; each step a linearised 6-dof least-squares solve.
/// Returns the refined pose (the input pose when too few points pair up).
Pose refinePose(const Pose& pose, const Points& model_points, const Points& model_normals, const Points& scan,
                const KdTree& scan_tree, const IcpParams& params);

/// Share of the posed model's sensor-facing points with a scan point within `tolerance` mm:
/// 1 for a fully supported visible side, about 0 for a pose in empty space.
float supportScore(const Pose& pose, const Points& model_points, const Points& model_normals, const KdTree& scan_tree,
                   float tolerance, const Vec3& viewpoint);

}  // namespace binpose
