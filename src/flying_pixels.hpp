#pragma once
// Flying pixels: a depth sensor's pixel that straddles a depth edge reads a mix of its two
// surfaces (a time-of-flight camera's mixed pixels, a structured-light camera's correlation
// window across the edge) and lies in the empty space between them.
#include "stage_settings.hpp"
#include <binpose/types.hpp>

#include <optional>
#include <vector>

namespace binpose {

/// For each point of a depth image (organized, on its pixel's ray: PointCloud::fx and pixel
/// given), whether it is a flying pixel: a neighbour more than a jump nearer and one more than a
/// jump farther among its 8 neighbouring pixels, and fewer than two within a jump of its own
/// depth. The jump at depth z is 3 sigma (the scan's noise, mm) and the step of a surface at 60
/// degrees to the line of sight, tan(60) z / fx: a neighbour on the same surface differs by less.
/// Such a point belongs to neither surface. Empty for any other cloud, or a sigma that is
/// negative or not finite.
std::vector<char> flyingPixels(const PointCloud& scan, float sigma);

/// The scan without its flying pixels, at the noise measured on it as prepareScan measures it
/// (through its pixels); empty when `p` does not adapt to the noise (the thesis's chapter 5),
/// the scan is no depth image, or it has none. The points kept keep their order and pixels.
std::optional<PointCloud> withoutFlyingPixels(const PointCloud& scan, const StageSettings& p);

}  // namespace binpose
