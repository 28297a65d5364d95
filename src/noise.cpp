// Noise of a scan from the residuals of plane fits over small neighbourhoods.
#include "noise.hpp"

#include <binpose/geometry.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <vector>

namespace binpose {
namespace {

/// Plane fits the estimate rests on: enough for a steady median, few enough to cost nothing.
constexpr std::size_t kNoiseSamples = 256;
/// Neighbours of a fit: about a 5 x 5 pixel window, wider than a structured-light sensor's
/// correlated, quantised noise (on 8 neighbours a patch often lies on one disparity step and
/// reads flat).
constexpr std::size_t kNoiseNeighbours = 24;
/// The reach is that of the normals' default k, the neighbours the tilt is judged for.
constexpr std::size_t kReachNeighbours = 8;
/// The spacing is the distance to the fourth nearest other point: on a grid the four beside it,
/// on a tilted surface the wider of its two spacings.
constexpr std::size_t kSpacingNeighbour = 4;

/// Noise over reach of a k = 8 fit under which its normal is sound; noisier scans fit more neighbours.
constexpr float kSoundTilt = 0.08f;
/// The most neighbours a noisy scan's normals fit (the pixel search's limit).
constexpr int kMostNeighbours = 32;
/// A scan that wants more neighbours than kMostNeighbours fits its normals to every point within
/// this many sigmas instead (at most StageSettings::normal_max_radius), when that reaches past
/// the kMostNeighbours nearest (twice the reach of 8: a surface's count grows with the reach
/// squared). On the fresh time-of-flight bins (sigma 1.5-1.7 mm, 32 neighbours reach about 7
/// mm) the points on an IPD obj 0 copy voting for its right model point went from 13 % to 27 %,
/// and the floor was found in 17 bins of 32 instead of 9. Over the 32 structured-light and 32
/// time-of-flight fresh bins the copies found more than half visible rose from 281 to 285 of
/// 344 and from 267 to 300 of 362 (without the limit by the part's size: 281 and 292, the
/// small parts' edges blurred; 6 or 7 sigmas: 281 and 292-293; 0.09 of the part's diameter
/// alone: 279 and 262).
constexpr float kSigmasOfNormalReach = 8.0f;
constexpr float kMostNeighboursReach = 2.0f;
/// ... and at most this many times the reach of 8, so that a fit holds at most about 8 x 8^2 =
/// 512 points whatever the scan (the bench's noisy bins: 23-27 mm, never reached).
constexpr float kWidestNormalReach = 8.0f;
/// Over this tilt (twice the sound one) the normals stay rough even on kMostNeighbours (the
/// simulated Kinect-class bins read 0.43, the real IC-BIN frames 0.24-0.27; the industrial model
/// 0.15, the ideal sensor 0.07-0.11), and a symmetric part's pairs are let through at angles up to
/// kRoughRevolutionTolerance: on the 12 seeded structured-light bins 78 -> 82 right (18 and 25
/// degrees: 80 and 79), the industrial and clean bins unchanged. A pose seen by more than one
/// face is then held to max_outline_share like one seen by one face: at 0.85 the fresh
/// structured-light bins kept 4 more copies turned over (MSSD 10 mm or more) and no more right.
constexpr float kRoughTilt = 2.0f * kSoundTilt;
constexpr float kRoughRevolutionTolerance = 20.0f;
/// From kReportTilt to kHighReportTilt the reported detections' least score rises from min_score
/// to kRoughReportScore. On such scans the right poses score high and the wrong and turned-over
/// ones low: over the fresh and cached bins' time-of-flight scans (tilt 0.50) 6 of 217 right
/// detections score under 0.5 against 41 of 76 others, and on the simulated structured-light scans
/// (0.43, least score 0.38) 5 of 293 right under 0.4 against 9 of 42 others. On clean,
/// industrial and real Kinect-class scans (the IC-BIN frames 0.26-0.27, PCL's milk 0.14, SICK
/// 0.18) partly hidden copies score 0.2-0.4 and right, and nothing changes.
constexpr float kReportTilt = 0.3f;
constexpr float kHighReportTilt = 0.5f;
constexpr float kRoughReportScore = 0.5f;
/// From kPlaneTilt to kRoughPlaneTilt the plane search's normal test (PlaneParams::max_angle)
/// widens from its setting to kRoughPlaneAngle (55 degrees, in radians). On such a scan a fit's
/// normal strays by 10-25 degrees, and at 20 degrees most of a floor's points fail the test: the
/// search takes a layer of parts' tops, or a slice of floor and parts, for the largest plane and
/// never finds the floor, whose absence lets poses sink into it (on 12 time-of-flight bins the
/// floor was found in 2). Over 32 fresh time-of-flight bins and 32 structured-light ones: 270 ->
/// 274 and 281 -> 288 copies found, 31 -> 18 and 6 -> 4 detections off their copy (the same
/// angle on every noisy scan: 35 degrees 274, 279; 26, 6; 45: 275, 283; 20, 6; 70: 277, 282;
/// 17, 5). From tilt 0.2 the real Kinect frames of IC-BIN (0.26-0.27) got 38 degrees, and the
/// room's floor behind their bin was found in slices that hide too much to be background: the
/// detections of parts that are not there rose from 217 to 238. Industrial and clean scans
/// (0.07-0.15) keep 20 degrees.
constexpr float kPlaneTilt = 0.3f;
constexpr float kRoughPlaneTilt = 0.4f;
constexpr float kRoughPlaneAngle = 0.96f;
/// e_gmax and the plane tolerance at least this many sigmas: two noisy points' distance varies by
/// about sqrt(2) sigma (2.3 sigma is 1.6 of its sigmas), a plane's points lie within about 2 sigma
/// of it. Set with the 24-neighbour estimate on the bench's structured-light bins and the IC-BIN
/// frames (3.3 and 2.2 let far, noisy background through on a real Kinect frame).
constexpr float kSigmasOfConsistency = 2.3f;
/// The plane search's fit band (PlaneParams::fit_band): this many sigmas, where that is at most
/// kMostFitBandShare of the plane tolerance (a scan quieter than 0.25 mm for a 60 mm part). On a
/// noisier one surfaces a few millimetres apart are hard to tell apart by their points: a Kinect
/// frame's table comes in slabs 3-5 mm apart. There the band (the tolerance of a 120 mm part is
/// 3 mm, 3 sigma of IC-BIN's first frame 2.8 mm) placed a bracket that is not in it 17 times,
/// against 13.
constexpr float kSigmasOfFitBand = 3.0f;
constexpr float kMostFitBandShare = 0.5f;
/// The verification's tolerance at least this many sigmas: 87 % of a right surface's points.
constexpr float kSigmasOfSupport = 1.5f;
/// farNoisyRange's bands: each this many times as far as the one before; a band judged from
/// this many fits; noisy when this many times as noisy as the least noisy nearer band.
constexpr float kBandRatio = 1.25f;
constexpr std::size_t kLeastBandFits = 12;
constexpr float kNoisierThanBest = 3.0f;
/// How far `tilt` has come from `from` towards `to` (both tilts, from < to), at most the whole way:
/// the share of a value's rise that adaptedToNoise gives a scan between the two.
float rampShare(float tilt, float from, float to) { return std::min(1.0f, (tilt - from) / (to - from)); }

/// The most neighbours a query answers at once (the pixel search's limit).
constexpr std::size_t kMaxQuery = 32;

}  // namespace

NeighbourQuery pixelQuery(const PixelNeighbours& pixels) {
  return [&pixels](std::uint32_t i, std::size_t k, std::uint32_t* idx) {
    float d2[kMaxQuery];
    return k <= kMaxQuery && pixels.knn(i, k, idx, d2) ? k : std::size_t{0};
  };
}

NeighbourQuery gridQuery(const PointGrid& grid, const Points& points) {
  return [&grid, &points](std::uint32_t i, std::size_t k, std::uint32_t* idx) {
    float d2[kMaxQuery];
    return k <= kMaxQuery ? grid.knn(points[i], k, idx, d2) : std::size_t{0};
  };
}

float farNoisyRange(std::vector<NoiseSample> samples, float limit) {
  if (!(limit > 0) || samples.empty()) return INFINITY;
  std::sort(samples.begin(), samples.end(), [](const NoiseSample& a, const NoiseSample& b) { return a.range < b.range; });
  float best = INFINITY;  // the least median residual of the bands judged so far
  std::vector<float> band;
  for (std::size_t first = 0; first < samples.size();) {
    const float start = samples[first].range, end = std::max(start, 1e-3f) * kBandRatio;
    band.clear();
    std::size_t next = first;
    for (; next < samples.size() && samples[next].range < end; ++next) band.push_back(samples[next].sigma);
    if (band.size() >= kLeastBandFits) {
      const float sigma = medianOf(band);
      if (sigma > limit && sigma > kNoisierThanBest * best) return start;
      best = std::min(best, sigma);
    }
    first = next;
  }
  return INFINITY;
}

NoiseEstimate estimateNoise(const Points& cloud, std::span<const std::uint32_t> chosen, const NeighbourQuery& neighbours,
                            const Vec3& viewpoint, float far_limit) {
  NoiseEstimate out;
  if (chosen.empty()) return out;
  const std::size_t step = std::max<std::size_t>(1, chosen.size() / kNoiseSamples);
  std::vector<NoiseSample> fits;
  std::uint32_t idx[kNoiseNeighbours];
  for (std::size_t s = 0; s < chosen.size(); s += step) {
    const std::uint32_t i = chosen[s];
    if (neighbours(i, kNoiseNeighbours, idx) < kNoiseNeighbours) continue;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto j : idx) c += cloud[j].cast<double>();
    c /= double(kNoiseNeighbours);
    Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
    float distances[kNoiseNeighbours];
    for (std::size_t k = 0; k < kNoiseNeighbours; ++k) {
      const Eigen::Vector3d d = cloud[idx[k]].cast<double>() - c;
      W += d * d.transpose();
      distances[k] = (cloud[idx[k]] - cloud[i]).norm();
    }
    std::nth_element(distances, distances + kReachNeighbours - 1, distances + kNoiseNeighbours);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(W);
    const double lambda0 = solver.eigenvalues()(0);
    const auto sigma = static_cast<float>(std::sqrt(std::max(0.0, lambda0) / double(kNoiseNeighbours - 3)));
    const Vec3 normal = solver.eigenvectors().col(0).cast<float>();
    float along[kNoiseNeighbours];  // each neighbour's distance in the fit's plane (along[0]: the point itself)
    for (std::size_t k = 0; k < kNoiseNeighbours; ++k) {
      const Vec3 d = cloud[idx[k]] - cloud[i];
      along[k] = (d - d.dot(normal) * normal).norm();
    }
    std::nth_element(along, along + kSpacingNeighbour, along + kNoiseNeighbours);
    fits.push_back({(cloud[i] - viewpoint).norm(), sigma, distances[kReachNeighbours - 1], along[kSpacingNeighbour]});
  }
  out.far_range = farNoisyRange(fits, far_limit);
  std::vector<float> sigmas, reaches, spacings;  // of the fits nearer than far_range
  for (const NoiseSample& f : fits)
    if (f.range < out.far_range) {
      sigmas.push_back(f.sigma);
      reaches.push_back(f.reach);
      spacings.push_back(f.spacing);
    }
  if (sigmas.empty()) return out;
  out.samples = static_cast<int>(sigmas.size());
  out.sigma = medianOf(sigmas);
  out.reach = medianOf(reaches);
  const auto quartile = spacings.begin() + static_cast<long>(spacings.size() / 4);
  std::nth_element(spacings.begin(), quartile, spacings.end());
  out.spacing = *quartile;
  return out;
}

StageSettings adaptedToNoise(const StageSettings& p, const NoiseEstimate& noise) {
  StageSettings a = p;
  if (noise.samples == 0 || !(noise.reach > 0)) return a;
  const float tilt = noise.sigma / noise.reach;
  if (tilt > kSoundTilt) {
    const auto k = static_cast<int>(std::lround(static_cast<float>(p.k_normals) * tilt / kSoundTilt));
    a.k_normals = std::clamp(k, p.k_normals, std::max(p.k_normals, kMostNeighbours));
    const float radius = std::min({kSigmasOfNormalReach * noise.sigma, p.normal_max_radius, kWidestNormalReach * noise.reach});
    if (k > kMostNeighbours && radius > kMostNeighboursReach * noise.reach) a.normal_radius = radius;
  }
  if (tilt > kRoughTilt) {
    a.revolution_angle_tolerance = std::max(p.revolution_angle_tolerance, kRoughRevolutionTolerance);
    a.many_faces_outline_share = p.max_outline_share;
  }
  a.e_gmax = std::max(p.e_gmax, kSigmasOfConsistency * noise.sigma);
  a.plane_tolerance = std::max(p.plane_tolerance, kSigmasOfConsistency * noise.sigma);
  if (kSigmasOfFitBand * noise.sigma <= kMostFitBandShare * a.plane_tolerance) a.plane_fit_band = kSigmasOfFitBand * noise.sigma;
  if (tilt > kPlaneTilt) {
    const float rise = rampShare(tilt, kPlaneTilt, kRoughPlaneTilt);
    a.plane_max_angle = std::max(p.plane_max_angle, p.plane_max_angle + rise * (kRoughPlaneAngle - p.plane_max_angle));
  }
  a.verify_tolerance = std::max(p.verify_tolerance, kSigmasOfSupport * noise.sigma);
  if (tilt > kReportTilt) {
    const float rise = rampShare(tilt, kReportTilt, kHighReportTilt);
    a.report_score = std::max(p.report_score, p.min_score + rise * (kRoughReportScore - p.min_score));
  }
  return a;
}

}  // namespace binpose
