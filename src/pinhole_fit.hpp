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

}  // namespace binpose
