#pragma once
// The pinhole camera of an organized cloud whose file gives its pixels but not its intrinsics (a
// PCD from OpenNI or a ROS depth driver): each point lies on the ray through its pixel.
#include <binpose/types.hpp>

namespace binpose {

/// Fits u = fx x / z + cx and v = fy y / z + cy by least squares over the cloud's points and
/// their pixels (PointCloud::pixel, row-major over width). When every point lies in front of the
/// origin on its pixel's ray (within 0.01 pixel: only the file's rounding) with fx and fy
/// positive, sets fx, fy, cx and cy and returns true: the cloud is then a depth image (its pixel
/// neighbours, flying pixels and repeated depths are found as a depth image's). Otherwise, and
/// for a cloud that is not organized or already has them, leaves it as it is and returns false
/// (a cloud moved out of the camera's frame, or resampled).
bool fitPinhole(PointCloud& cloud);

/// The pixels and pinhole of an unorganized cloud in a depth camera's frame (a depth image saved
/// as a PLY): its points' x / z and y / z fall on a lattice (u - cx) / fx, (v - cy) / fy. The step
/// is the median gap between the distinct values of a sample, the least value is pixel 0, and both
/// are refined by least squares over every point; when every point lies
/// within 0.01 pixel of a lattice point, no two on one, and the image spans at most 64 pixels a
/// point (at most 16384 a side), the cloud is given its pixels (its points reordered by them),
/// intrinsics, and the origin as viewpoint, and true is returned. Otherwise (a cloud in another
/// frame, resampled or merged from views) it is left as it is.
bool fitPixelLattice(PointCloud& cloud);

}  // namespace binpose
