#pragma once
// The scan's noise, measured on the scan itself: the residuals of small plane fits.
#include "stage_settings.hpp"
#include <binpose/pixel_neighbours.hpp>
#include <binpose/point_grid.hpp>
#include <binpose/types.hpp>

#include <cmath>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace binpose {

struct NoiseEstimate {
  float sigma = 0;   ///< median residual of a point's plane fit, 1 sigma, mm
  float reach = 0;   ///< median distance to the fit's farthest neighbour, mm
  int samples = 0;   ///< plane fits it rests on (0: none could be made; sigma, reach and spacing 0)
  /// Points this far from the viewpoint or farther lie where the scan is too noisy to match
  /// (farNoisyRange), mm; infinity: nowhere. sigma and reach are measured nearer.
  float far_range = INFINITY;
  /// Distance between neighbouring scan points along the surface (in each fit's plane, so the
  /// noise across it does not count) to the fourth nearest, the wider spacing where a tilted
  /// surface's pixels lie farther apart one way; the lower quartile of the fits' (the scan's
  /// nearest surfaces, a bin rather than the room behind it), mm. Measured nearer than far_range.
  float spacing = 0;
};

/// One plane fit: its distance from the viewpoint, its residual, its reach and spacing, mm.
struct NoiseSample {
  float range = 0;
  float sigma = 0;
  float reach = 0;
  float spacing = 0;
};

/// The range from which the scan is too noisy to match, from its plane fits: the nearest band of
/// ranges (each 1.25 times the one before) whose median residual is over `limit` and over three
/// times that of the least noisy band nearer than it, bands of at least 12 fits judged; the
/// bands beyond it count as noisy too. A depth sensor's noise grows with range (a Kinect's as
/// its square): a room's far walls behind a bin are measured several times noisier than the bin.
/// Infinity when there is no such band, or `limit` is 0.
float farNoisyRange(std::vector<NoiseSample> samples, float limit);

/// Up to `count` neighbours of cloud point i (itself included) into `indices`; how many it gave
/// (0: it could not say).
using NeighbourQuery = std::function<std::size_t(std::uint32_t i, std::size_t count, std::uint32_t* indices)>;

/// The query through a depth image's pixels (PixelNeighbours::knn; 0 where they cannot prove
/// the nearest), and through a grid of `points` (PointGrid::knn). The pixels must be usable.
NeighbourQuery pixelQuery(const PixelNeighbours& pixels);
NeighbourQuery gridQuery(const PointGrid& grid, const Points& points);

/// Fits planes to the kNoiseNeighbours nearest points of an even sample of `chosen` and takes
/// the medians of their residuals (sqrt(lambda_0 / (k - 3)), eq. 33-35's least eigenvalue) and
/// of their reaches. With `far_limit` > 0 (mm), farNoisyRange of the fits by their distance from
/// `viewpoint` is found too, and the medians are those of the fits nearer than it. Deterministic.
NoiseEstimate estimateNoise(const Points& cloud, std::span<const std::uint32_t> chosen, const NeighbourQuery& neighbours,
                            const Vec3& viewpoint = Vec3::Zero(), float far_limit = 0.0f);

/// The values that depend on the noise, raised to what a scan this noisy needs (never lowered):
/// the normals' neighbours k (so that a fit's tilt from noise stays small), e_gmax, the plane
/// tolerance and the verification tolerance (each a multiple of sigma), and on a scan whose
/// normals stay rough, the symmetric parts' angle tolerance. The same parameters for a scan as
/// clean as the simulator's ideal sensor.
StageSettings adaptedToNoise(const StageSettings& p, const NoiseEstimate& noise);

}  // namespace binpose
