#pragma once
// Depth sensor models for the simulator: what real structured-light, industrial and
// time-of-flight cameras do to a depth image, beyond the ideal sensor's Gaussian noise.
//
// - Structured light, Kinect v1 / PrimeSense class: axial noise growing with range and with the
//   surface's angle to the ray (Nguyen, Izadi & Lovell 2012, eq. 7:
//   sigma_z = 1.2 + 1.9 (z - 0.4)^2 mm + 0.1 mm / sqrt(z) * theta^2 / (pi/2 - theta)^2, z in m),
//   depth from a disparity quantised to 1/8 px (f b / z; Khoshelham & Elberink 2012: the
//   resulting error grows as z^2, about 1.425e-3 z^2 m), lateral noise of about 0.8 px, shadows
//   where the projector (75 mm beside the camera) cannot see the surface, and drop-outs at depth
//   edges, where the correlation window straddles two surfaces.
// - Industrial structured light, Photoneo / Zivid class: 0.2 mm at 1 m (growing as z^2 and with
//   the angle), a 200 mm baseline's shadows, drop-outs at depth edges, no quantisation to speak of.
// - Time of flight, Kinect v2 class: about 1 mm plus 1.5 mm per metre, no shadows, flying pixels
//   at depth edges (a pixel's depth mixed between its two surfaces), and a simplified multipath
//   bias: concave corners, where light bounces between two faces, read farther.
#include <cstdint>
#include <string>

namespace binpose {

enum class SensorKind { Ideal, StructuredLight, Industrial, TimeOfFlight };

/// What a sensor does to the depth image. Lengths in mm, angles in radians.
struct SensorModel {
  SensorKind kind = SensorKind::Ideal;
  /// Axial noise sigma_z(z, theta) = (base + quadratic (z_m - offset)^2 + linear z_m) mm, plus
  /// the angle term angular / sqrt(z_m) * theta^2 / (pi/2 - theta)^2, z_m the range in metres.
  float noise_base = 0, noise_quadratic = 0, noise_offset = 0, noise_linear = 0, noise_angular = 0;
  float disparity_step = 0;   ///< disparity quantisation, px (0: none)
  float baseline = 0;         ///< projector beside the camera along +x, mm (0: no shadows)
  float lateral_px = 0;       ///< lateral noise, 1 sigma, px
  float edge_jump = 10;       ///< a pixel is on a depth edge when a 4-neighbour differs by more, mm
  float edge_dropout = 0;     ///< probability that an edge pixel is dropped
  float flying_pixels = 0;    ///< probability that an edge pixel reads a mix of its two surfaces
  float multipath_gain = 0;   ///< ToF: concave corners read farther by this share of their concavity
  float multipath_max = 0;    ///< ... at most this much, mm
};

/// The documented model of a kind (the ideal sensor: no change to the rendered depth).
SensorModel sensorModel(SensorKind kind);
/// "ideal", "structured-light", "industrial" or "tof"; anything else is an error.
SensorKind parseSensorKind(const std::string& name);
std::string sensorKindName(SensorKind kind);

}  // namespace binpose
