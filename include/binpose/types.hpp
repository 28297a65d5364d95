#pragma once
// Plain data types shared by every stage. Units: millimetres everywhere inside binpose.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace binpose {

using Vec3 = Eigen::Vector3f;
using Points = std::vector<Vec3>;

/// Any error binpose reports to its caller: one line, naming the file or parameter at fault.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A point cloud in millimetres. `normals` is empty or has one unit vector per point.
/// An organized cloud (from a depth image or an organized PCD) keeps width x height and,
/// for each kept point, its pixel index (row * width + col); invalid pixels are dropped.
struct PointCloud {
  Points points;
  Points normals;
  int width = 0;
  int height = 0;
  std::vector<std::int32_t> pixel;
  Vec3 viewpoint = Vec3::Zero();  ///< sensor origin, for orienting normals (PCD VIEWPOINT)
  /// Whether the file gives the sensor origin (a depth image's camera frame, a PCD's VIEWPOINT
  /// other than its default, the origin); false for a PLY or a mesh, whose origin may be
  /// anywhere (guessViewpoint in viewpoint.hpp).
  bool has_viewpoint = false;
  /// The pinhole camera's focal lengths in pixels, when each point lies on the ray from the
  /// origin through its pixel (depthToCloud: the camera frame); 0 when not known. Neighbour
  /// searches then start from the pixel's neighbours (PixelNeighbours). Keep them 0 for a cloud
  /// whose points were moved out of that frame.
  float fx = 0, fy = 0;
  float cx = 0, cy = 0;  ///< the principal point, pixels (with fx and fy)

  [[nodiscard]] std::size_t size() const { return points.size(); }
  [[nodiscard]] bool empty() const { return points.empty(); }
  [[nodiscard]] bool hasNormals() const { return !normals.empty() && normals.size() == points.size(); }
  [[nodiscard]] bool organized() const { return width > 0 && height > 0; }
};

/// A triangle mesh in millimetres. `normals` is empty or one unit vector per vertex (as given
/// by the file; used only to orient faces).
struct Mesh {
  Points vertices;
  std::vector<Eigen::Vector3i> faces;
  Points normals;

  [[nodiscard]] bool hasNormals() const { return !normals.empty() && normals.size() == vertices.size(); }
};

/// Whether a scan point holds a measurement: finite, and not exactly the origin. A depth
/// camera's driver or SDK writes a pixel without a depth as NaN or as (0, 0, 0) (RealSense's
/// point cloud, Azure Kinect's point image, Open3D's depth-to-cloud with every pixel kept): in
/// the camera's frame no surface can lie at the sensor's own centre, and in another frame a
/// measured point lands exactly on the origin, to the last bit, one time in billions.
[[nodiscard]] inline bool isMeasured(const Vec3& p) { return p.allFinite() && (p.x() != 0.0f || p.y() != 0.0f || p.z() != 0.0f); }

/// Unit vector n normalised in place; false (and n untouched) for a zero or non-finite vector.
bool normalizeSafe(Vec3& n);

}  // namespace binpose
