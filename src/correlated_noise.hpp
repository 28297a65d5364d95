#pragma once
// A depth image with more pixels than independent depth samples: a stereo or structured-light
// camera's matching window, a driver's smoothing, or a registration to a sharper camera that
// copies each depth over a block of pixels gives neighbouring pixels shared noise. Plane fits
// over a few pixels then read that noise low, the normals fitted to as many neighbours cover too
// little of the surface, and every tolerance set from the noise is too tight. Copies are thinned
// out; mixes (smoothing, interpolation) are not (docs/design.md, Pixels that share their noise).
#include "stage_settings.hpp"
#include <binpose/types.hpp>

#include <limits>
#include <optional>

namespace binpose {

/// What the 5 x 5 pixel windows around an even sample of a depth image's points tell of its noise,
/// from those whose depths fit a quadric in the pixels' offsets with residuals: NaN when the
/// cloud is no depth image (PointCloud::fx, fy and pixel given, one point per pixel, in pixel
/// order) or fewer than 32 such windows are full.
struct PixelNoise {
  /// The lower quartile of the correlation of each fit's residuals between neighbouring pixels
  /// (the mean product over the 40 pairs of pixels side by side or one above the other, over the
  /// mean square). Independent noise reads about -0.3 (the fit takes some of it out); noise that
  /// neighbouring pixels share, over 0. The lower quartile is that of the windows on smooth
  /// surfaces: one across an edge or a bend reads high whatever the noise.
  float correlation = std::numeric_limits<float>::quiet_NaN();
  /// The share of the windows whose centre depth a pixel beside it and one above or below it
  /// repeat exactly: 1 where each depth is copied over a block of pixels.
  float repeated = std::numeric_limits<float>::quiet_NaN();
};
PixelNoise pixelNoise(const PointCloud& scan);

/// The depth image's points seen through every second pixel of every second row (the even ones),
/// with the intrinsics of that image (fx, fy, cx and cy halved) and their own pixels. The scan
/// must be a depth image as above.
PointCloud halvedImage(const PointCloud& scan);

/// The scan halved (halvedImage) as long as its depths are copied over blocks of pixels
/// (pixelNoise: correlation over 0 and at least 95 % of the windows repeated: a registration to a
/// camera with twice the pixels or more), at most twice and down to 160 x 120 pixels; `stride`
/// the pixels from one kept to the next (1, 2 or 4). Empty (stride 1) when it is not so, the
/// scan is no depth image, or `p` does not adapt to the noise or thin correlated pixels.
std::optional<PointCloud> thinnedToIndependentNoise(const PointCloud& scan, const StageSettings& p, int& stride);

}  // namespace binpose
