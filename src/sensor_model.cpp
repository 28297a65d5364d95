// Depth sensor models: parameters from the literature (sensor_model.hpp) and their effects.
#include <binpose/sensor_model.hpp>

#include "sensor_effects.hpp"

#include <binpose/geometry.hpp>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

namespace binpose {
namespace {

/// Salt of the edge pass's per-pixel generators (the render's use the seed itself).
constexpr std::uint64_t kEdgeSalt = 0xED6E5A17ull;
/// Half the side of the multipath window, px.
constexpr int kMultipathReach = 3;
/// Neighbours farther than this many edge jumps from a pixel are another surface, not its corner.
constexpr float kMultipathSameSurface = 3.0f;

/// The largest depth difference to a valid 4-neighbour (0 when none differs), and that neighbour's depth.
float largestJump(const std::vector<float>& depth, int width, int height, int u, int v, float& other) {
  const float d = depth[static_cast<std::size_t>(v) * width + u];
  float jump = 0;
  const int du[4] = {1, -1, 0, 0}, dv[4] = {0, 0, 1, -1};
  for (int k = 0; k < 4; ++k) {
    const int x = u + du[k], y = v + dv[k];
    if (x < 0 || y < 0 || x >= width || y >= height) continue;
    const float n = depth[static_cast<std::size_t>(y) * width + x];
    if (n > 0 && std::abs(n - d) > jump) {
      jump = std::abs(n - d);
      other = n;
    }
  }
  return jump;
}

}  // namespace

SensorModel sensorModel(SensorKind kind) {
  SensorModel m;
  m.kind = kind;
  switch (kind) {
    case SensorKind::Ideal:
      break;
    case SensorKind::StructuredLight:  // Nguyen et al. 2012 (eq. 7), Khoshelham & Elberink 2012
      m.noise_base = 1.2f, m.noise_quadratic = 1.9f, m.noise_offset = 0.4f, m.noise_angular = 0.1f;
      m.disparity_step = 0.125f, m.baseline = 75.0f, m.lateral_px = 0.8f;
      m.edge_dropout = 0.5f, m.flying_pixels = 0.1f;
      break;
    case SensorKind::Industrial:  // vendors' figures: 0.1-0.3 mm at 1 m
      m.noise_quadratic = 0.2f, m.noise_angular = 0.02f;
      m.baseline = 200.0f, m.lateral_px = 0.2f;
      m.edge_dropout = 0.3f, m.flying_pixels = 0.02f;
      break;
    case SensorKind::TimeOfFlight:  // Kinect v2 class
      m.noise_base = 1.0f, m.noise_linear = 1.5f, m.noise_angular = 0.1f;
      m.lateral_px = 0.3f, m.flying_pixels = 0.6f;
      m.multipath_gain = 0.5f, m.multipath_max = 5.0f;
      break;
  }
  return m;
}

SensorKind parseSensorKind(const std::string& name) {
  if (name == "ideal") return SensorKind::Ideal;
  if (name == "structured-light") return SensorKind::StructuredLight;
  if (name == "industrial") return SensorKind::Industrial;
  if (name == "tof") return SensorKind::TimeOfFlight;
  throw Error(fmt::format("unknown sensor '{}' (known: ideal, structured-light, industrial, tof)", name));
}

std::string sensorKindName(SensorKind kind) {
  switch (kind) {
    case SensorKind::StructuredLight: return "structured-light";
    case SensorKind::Industrial: return "industrial";
    case SensorKind::TimeOfFlight: return "tof";
    case SensorKind::Ideal: break;
  }
  return "ideal";
}

float axialSigma(const SensorModel& m, float z, float theta) {
  const float zm = z / 1000.0f, off = zm - m.noise_offset;
  const float t = std::min(theta, 1.5f);  // the angle term's pole at grazing: such pixels are dropped anyway
  const float angular = m.noise_angular / std::sqrt(std::max(zm, 0.05f)) * t * t / ((0.5f * float(M_PI) - t) * (0.5f * float(M_PI) - t));
  return m.noise_base + m.noise_quadratic * off * off + m.noise_linear * zm + angular;
}

float quantisedDepth(const SensorModel& m, float z, double fx) {
  if (!(m.disparity_step > 0) || !(m.baseline > 0) || !(z > 0)) return z;
  const double fb = fx * m.baseline, disparity = fb / z;
  const double step = m.disparity_step, q = std::round(disparity / step) * step;
  return q > 0 ? static_cast<float>(fb / q) : 0.0f;
}

void applyEdgeEffects(std::vector<float>& depth, int width, int height, const SensorModel& m, std::uint64_t seed) {
  if (!(m.edge_dropout > 0) && !(m.flying_pixels > 0)) return;
  const std::vector<float> before = depth;
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      const std::size_t pixel = static_cast<std::size_t>(v) * width + u;
      if (before[pixel] <= 0) continue;
      float other = 0;
      if (largestJump(before, width, height, u, v, other) <= m.edge_jump) continue;
      Rng rng((seed ^ kEdgeSalt) * 0x9E3779B97F4A7C15ull + pixel);
      const double draw = rng.uniform();
      if (draw < m.edge_dropout) depth[pixel] = 0;
      else if (draw < m.edge_dropout + m.flying_pixels)
        depth[pixel] = before[pixel] + static_cast<float>(rng.uniform()) * (other - before[pixel]);
    }
}

void applyMultipath(std::vector<float>& depth, int width, int height, const SensorModel& m) {
  if (!(m.multipath_gain > 0)) return;
  const std::vector<float> before = depth;
  const float same = kMultipathSameSurface * m.edge_jump;
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      const float d = before[static_cast<std::size_t>(v) * width + u];
      if (d <= 0) continue;
      double sum = 0;
      int count = 0;
      for (int y = std::max(0, v - kMultipathReach); y <= std::min(height - 1, v + kMultipathReach); ++y)
        for (int x = std::max(0, u - kMultipathReach); x <= std::min(width - 1, u + kMultipathReach); ++x) {
          const float n = before[static_cast<std::size_t>(y) * width + x];
          if (n > 0 && std::abs(n - d) <= same && (x != u || y != v)) sum += n, ++count;
        }
      if (count == 0) continue;
      const float concavity = d - static_cast<float>(sum / count);  // deeper than around it: a concave corner
      if (concavity > 0) depth[static_cast<std::size_t>(v) * width + u] = d + std::min(m.multipath_max, m.multipath_gain * concavity);
    }
}

}  // namespace binpose
