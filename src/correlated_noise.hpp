#pragma once
// A depth image with more pixels than independent depth samples: a stereo or structured-light
// camera's matching window, a driver's smoothing or an upsampled (registered) image gives
// neighbouring pixels shared noise. Plane fits over a few pixels then read that noise low, the
// normals fitted to as many neighbours cover too little of the surface, and every tolerance set
// from the noise is too tight (docs/benchmarks.md, Denser scans with correlated noise).
#include "stage_settings.hpp"
#include <binpose/types.hpp>

#include <optional>

namespace binpose {

/// The lower quartile, over quadric fits to the 5 x 5 pixel windows around an even sample of a
/// depth image's points, of the correlation of each fit's residuals between neighbouring pixels
/// (the mean product over the 40 pairs of pixels side by side or one above the other, over the
/// mean square), the depths fitted as a quadric in the pixels' offsets. Independent noise reads
/// about -0.3 (the fit takes some of it out); noise that neighbouring pixels share, over 0. The
/// lower quartile is that of the windows on smooth surfaces: one across an edge or a bend reads
/// high whatever the noise. NaN when the cloud is no depth image (PointCloud::fx, fy and pixel
/// given, one point per pixel, in pixel order) or fewer than 32 windows are full and noisy.
float neighbourNoiseCorrelation(const PointCloud& scan);

/// The depth image's points seen through every second pixel of every second row (the even ones),
/// with the intrinsics of that image (fx, fy, cx and cy halved) and their own pixels. The scan
/// must be a depth image as above.
PointCloud halvedImage(const PointCloud& scan);

/// The scan halved (halvedImage) as long as its noise is correlated over neighbouring pixels
/// (neighbourNoiseCorrelation over 0), at most twice and down to 160 x 120 pixels; `stride`
/// the pixels from one kept to the next (1, 2 or 4). Empty (stride 1) when it is not so, the
/// scan is no depth image, or `p` does not adapt to the noise or thin correlated pixels.
std::optional<PointCloud> thinnedToIndependentNoise(const PointCloud& scan, const StageSettings& p, int& stride);

}  // namespace binpose
