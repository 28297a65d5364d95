#pragma once
// The sensor models' effects on a rendered depth image (sensor_model.hpp), for the simulator.
#include <binpose/sensor_model.hpp>

#include <cstdint>
#include <vector>

namespace binpose {

/// Axial noise, 1 sigma, mm, at range z (mm) and angle theta (rad) between the ray and the normal.
float axialSigma(const SensorModel& m, float z, float theta);
/// The depth z (mm) read through a disparity of f b / z quantised to the model's step (fx in px).
float quantisedDepth(const SensorModel& m, float z, double fx);
/// Drop-outs and flying pixels at depth edges, on a row-major image of depths in mm (0: none).
/// Deterministic for a seed: each pixel draws from its own generator.
void applyEdgeEffects(std::vector<float>& depth, int width, int height, const SensorModel& m, std::uint64_t seed);
/// The simplified multipath bias of a time-of-flight sensor: a pixel deeper than the mean of
/// its neighbours (a concave corner) reads farther still.
void applyMultipath(std::vector<float>& depth, int width, int height, const SensorModel& m);

}  // namespace binpose
