#pragma once
// The scan's noise, measured on the scan itself: the residuals of small plane fits.
#include "stage_settings.hpp"
#include <binpose/types.hpp>

#include <cstdint>
#include <functional>
#include <span>

namespace binpose {

struct NoiseEstimate {
  float sigma = 0;   ///< median residual of a point's plane fit, 1 sigma, mm
  float reach = 0;   ///< median distance to the fit's farthest neighbour, mm
  int samples = 0;   ///< plane fits it rests on (0: none could be made; sigma and reach 0)
};

/// Up to `count` neighbours of cloud point i (itself included) into `indices`; how many it gave
/// (0: it could not say).
using NeighbourQuery = std::function<std::size_t(std::uint32_t i, std::size_t count, std::uint32_t* indices)>;

/// Fits planes to the kNoiseNeighbours nearest points of an even sample of `chosen` and takes
/// the medians of their residuals (sqrt(lambda_0 / (k - 3)), eq. 33-35's least eigenvalue) and
/// of their reaches. Deterministic.
NoiseEstimate estimateNoise(const Points& cloud, std::span<const std::uint32_t> chosen, const NeighbourQuery& neighbours);

/// The values that depend on the noise, raised to what a scan this noisy needs (never lowered):
/// the normals' neighbours k (so that a fit's tilt from noise stays small), e_gmax, the plane
/// tolerance and the verification tolerance (each a multiple of sigma). The same parameters for
/// a scan as clean as the simulator's ideal sensor.
StageSettings adaptedToNoise(const StageSettings& p, const NoiseEstimate& noise);

}  // namespace binpose
