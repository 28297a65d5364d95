#pragma once
// A scan file read as `binpose detect` reads it: a cloud by its extension, or a depth image by
// its camera file, in millimetres, its unit guessed from the part's size when not given.
#include <binpose/types.hpp>

#include <string>

namespace binpose {

/// Where a scan comes from.
struct ScanSource {
  /// PLY, PCD, ASCII points, a TIFF point map or a mesh's vertices (readCloud); or a depth image,
  /// a 16-bit PNG or a TIFF depth map, read with `intrinsics`.
  std::string path;
  /// BOP camera.json or scene_camera.json of a depth image ("" for a cloud; a PNG needs one).
  std::string intrinsics;
  /// The scene_camera.json entry ("": the first).
  std::string image_id;
  /// Length unit of the file (of a depth image: of its values times depth_scale): "mm", "cm", "m",
  /// "in", or
  /// "auto": millimetres, unless the scan then spans less than kLeastScanShareOfPart of the part's
  /// diameter, which it could not hold: metres.
  std::string units = "auto";
};

/// The scan, and whether "auto" took it for metres.
struct LoadedScan {
  PointCloud cloud;
  bool guessed_metres = false;
  float extent_in_file_units = 0;  ///< its bounding box's diagonal as the file gives it
};

/// Reads `source` in millimetres; `part_diameter` (mm) judges the unit under "auto". Throws
/// binpose::Error on a bad file, a PNG without intrinsics, or an unknown unit.
LoadedScan loadScan(const ScanSource& source, float part_diameter);

}  // namespace binpose
