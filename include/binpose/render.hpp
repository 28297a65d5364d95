#pragma once
// Pictures of detections for a person: a PNG from the sensor's view and a coloured PLY.
#include <binpose/detector.hpp>

#include <string>

namespace binpose {

/// Draws the scan as seen from `viewpoint` (shaded by range, near is bright), each detection's
/// visible model points in its own colour, and its rank at its centre. `width` px wide.
void renderDetections(const std::string& png_path, const PointCloud& scan, const std::vector<Detection>& detections,
                      const Points& model_points, const Points& model_normals, const Vec3& viewpoint, int width = 800);

/// The scan (grey) and each posed model (in the colours of renderDetections) in one PLY.
void exportDetectionsPly(const std::string& ply_path, const PointCloud& scan, const std::vector<Detection>& detections,
                         const Points& model_points);

}  // namespace binpose
