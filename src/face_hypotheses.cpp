// Beyond the thesis: poses of a copy seen by one flat face (face_hypotheses.hpp).
#include "face_hypotheses.hpp"

#include <binpose/planes.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <numeric>
#include <optional>
#include <span>

namespace binpose {

namespace {

/// Normals of one model face: the model's are exact, only a crease turns them.
constexpr float kModelFaceDegrees = 5.0f;
/// ... and its points within this share of the model's sample spacing of one plane.
constexpr float kFaceFlatness = 0.25f;
/// Normals of one flat scene region, neighbour to neighbour: a noisy scan's are 10-15 degrees off.
constexpr float kRegionDegrees = 20.0f;
/// Neighbours link within this many sample spacings (the plane search's 2.5).
constexpr float kLinkSpacings = 2.5f;
/// A region this share of a face's area to this share: the face about wholly in view, so that
/// its centre is the region's.
constexpr float kLeastAreaShare = 0.6f, kMostAreaShare = 1.3f;
/// A region too large for any face but as large as 2 to this many copies of one is tried in
/// pieces, one per copy lying side by side.
constexpr int kMostCopies = 6;
/// A region that is not one plane is split into planes (planarPieces): this many plane
/// hypotheses each, and at most this many planes taken out of it.
constexpr int kPieceTrials = 48;
constexpr int kMostPieces = 6;
/// A region is one plane when its points' RMS distance from their plane fit is at most this
/// share of the plane tolerance (2.3 sigma of a noisy scan's noise: noise.cpp), about the noise
/// itself; else it is split into the planes it holds (planarPieces). A flat face's region on a
/// structured-light scan also takes in the first millimetres of a face bent away from it, where
/// the smoothed normals turn gradually, and then outgrows the model's face (RMS 1.5-2.8 mm where
/// the noise gives 1.2-1.4 mm).
constexpr float kOnePlaneRms = 0.5f;
/// k-means steps of a split (from farthest-point seeds, a few settle touching faces).
constexpr int kSplitSteps = 8;
/// ... and its extent along each principal axis (RMS from the centre) within this share of the face's.
constexpr float kLeastSpreadShare = 0.75f;
/// The turn about the face's normal: first in kSpins steps, then in steps of kFineDegrees and
/// shifts of kFineShiftTolerances verification tolerances along the face while the support grows.
constexpr float kFullTurn = static_cast<float>(2 * M_PI);
constexpr int kSpins = 72;  // 5 degrees
/// An axis of revolution within about 8 degrees of a face's normal turns the face onto itself.
constexpr float kAxisCosine = 0.99f;
/// The coarse spins are judged on this many model points, each face's best kShortlist of them again on
/// kJudgedPoints (ICP's share is finer than the choice needs).
constexpr std::size_t kCoarsePoints = 48;
constexpr std::size_t kJudgedPoints = 250;
constexpr std::size_t kShortlist = 4;
constexpr float kFineDegrees = 1.0f;
constexpr float kFineShiftTolerances = 0.5f;
constexpr int kMostFineSteps = 12;
/// Rivals: other faces or turns (ones the part's symmetry does not make the same pose) that the
/// scan supports at least this share as well as the best laid pose, before refinement: a block's
/// square faces, a plate's two sides look alike from one side, and the part behind the face is
/// hidden. Twice as well (0.5) left the gears lying flat on the structured-light bins to their
/// wrong clique poses (scores 0.2-0.35), where the laid poses of the gear's two sides came within
/// a factor of two.
constexpr float kMostRivalShare = 0.7f;
/// Each rival is refined as the best is, and the pose that then scores most is kept unless another
/// scores this share of it: a tie that the scan cannot settle. Laid poses start a few degrees and
/// millimetres off, and the face's outline alone ranks them little better than chance: an L-shaped
/// sheet-metal part (IPD obj 0, 1) seen by one plate scores 0.73-0.95 at its pose and 0.41-0.88
/// turned about that plate's normal, refined, while their coarse support comes within 0.7.
constexpr float kTieShare = 0.95f;

/// The points at `members`' plane fit: centroid, unit normal turned like `towards`, RMS distance.
struct PlaneFit {
  Vec3 centre = Vec3::Zero(), normal = Vec3::Zero();
  float rms = 0;
  float spread[2] = {0, 0};  ///< RMS distance from the centre along the plane's two principal axes, largest first
  Vec3 axes[2] = {Vec3::UnitX(), Vec3::UnitY()};  ///< those axes (unit), largest first
};

PlaneFit fitPlane(const Points& points, const std::vector<std::uint32_t>& members, const Vec3& towards) {
  PlaneFit fit;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::uint32_t i : members) c += points[i].cast<double>();
  c /= static_cast<double>(members.size());
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
  for (std::uint32_t i : members) {
    const Eigen::Vector3d x = points[i].cast<double>() - c;
    W += x * x.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(W);
  fit.centre = c.cast<float>();
  fit.normal = solver.eigenvectors().col(0).cast<float>().normalized();
  if (fit.normal.dot(towards) < 0) fit.normal = -fit.normal;
  const auto rms = [&](int k) { return static_cast<float>(std::sqrt(std::max(0.0, solver.eigenvalues()[k]) / static_cast<double>(members.size()))); };
  fit.rms = rms(0);
  fit.spread[0] = rms(2);
  fit.spread[1] = rms(1);
  fit.axes[0] = solver.eigenvectors().col(2).cast<float>().normalized();
  fit.axes[1] = solver.eigenvectors().col(1).cast<float>().normalized();
  return fit;
}

/// The patches of points[members] linked within `link` where `joins` says so (planes.hpp's flood
/// fill), each sorted: one order of the sums, whatever the fill's.
std::vector<std::vector<std::uint32_t>> regionsOf(const Points& points, const std::vector<std::uint32_t>& members, float link,
                                                 const detail::Joins& joins) {
  std::vector<std::vector<std::uint32_t>> regions = detail::floodPatches(points, members, link, joins);
  for (auto& region : regions) std::sort(region.begin(), region.end());
  return regions;
}

/// The pose that lays `face` on the plane (centre, normal), turned by `spin` radians about the
/// normal and shifted by `shift` along it.
Pose facePose(const ModelFace& face, const PlaneFit& plane, float spin, const Vec3& shift) {
  // The face's outward normal onto the region's normal, which faces the sensor.
  const Eigen::Matrix3f lay = Eigen::Quaternionf::FromTwoVectors(face.normal, plane.normal).toRotationMatrix();
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisf(spin, plane.normal).toRotationMatrix() * lay;
  pose.translation() = plane.centre + shift - pose.linear() * face.centre;
  return pose;
}

/// The support of a pose on a share of the model at the verification tolerance.
float support(const Matcher& m, const PreparedModel& model, const Pose& pose) {
  return m.evidence.evaluate(pose, model, m.p.verify_tolerance, 0.0f).score();
}

/// The scene's flat regions not explained yet, each with its plane fit and area (mm^2).
struct FlatRegion {
  std::vector<std::uint32_t> members;
  PlaneFit plane;
  float area = 0;
};

/// The area (mm^2) that points[members] cover on their plane: the cells of side `spacing` in the
/// plane that they fall in. Sub-sampled to one point per voxel of that side, a region fills about
/// every cell it covers, whatever its tilt to the voxels; counting its points would also count
/// the voxels a plane crosses twice where noise straddles a voxel boundary (a fifth to a third
/// more area on a face square to the sensor).
float coveredArea(const Points& points, std::span<const std::uint32_t> members, const PlaneFit& plane, float spacing) {
  const Vec3 u = plane.normal.unitOrthogonal(), w = plane.normal.cross(u);
  std::vector<std::uint64_t> cells;
  cells.reserve(members.size());
  for (const std::uint32_t i : members) {
    const Vec3 d = points[i] - plane.centre;
    const auto cu = static_cast<std::uint32_t>(static_cast<std::int32_t>(std::floor(d.dot(u) / spacing)));
    const auto cw = static_cast<std::uint32_t>(static_cast<std::int32_t>(std::floor(d.dot(w) / spacing)));
    cells.push_back(static_cast<std::uint64_t>(cu) << 32 | cw);
  }
  std::sort(cells.begin(), cells.end());
  const auto distinct = std::unique(cells.begin(), cells.end()) - cells.begin();
  return static_cast<float>(distinct) * spacing * spacing;
}

/// The scene's sample spacing, mm: one point per voxel of this side (5.2.1).
float sampleSpacing(const Matcher& m) { return 1.0f / std::sqrt(m.p.rho_sub); }

/// The flat region of points[members]: its plane fit, turned towards the viewpoint, and the area it covers.
FlatRegion regionOf(const Matcher& m, std::vector<std::uint32_t> members) {
  FlatRegion region;
  region.plane = fitPlane(m.scene.points, members, m.p.viewpoint - m.scene.points[members.front()]);
  region.area = coveredArea(m.scene.points, members, region.plane, sampleSpacing(m));
  region.members = std::move(members);
  return region;
}

/// The `members` within `tolerance` of the plane through `centre` with unit `normal`, their own
/// normals within `min_cos` of its.
std::vector<std::uint32_t> onPlane(const PreparedScene& scene, std::span<const std::uint32_t> members, const Vec3& centre,
                                   const Vec3& normal, float tolerance, float min_cos) {
  std::vector<std::uint32_t> on;
  for (const std::uint32_t i : members)
    if (std::abs(normal.dot(scene.points[i] - centre)) <= tolerance && std::abs(normal.dot(scene.normals[i])) >= min_cos)
      on.push_back(i);
  return on;
}

/// A region that is not one plane split into the planes it holds. Normals that turn a little
/// from one point to the next link a part's flat face to a tilted neighbour, or to another
/// copy's face at another height, across their teeth or a fillet. Each plane is the one
/// through a member, with its normal, that most members lie on (RANSAC, Fischler & Bolles 1981,
/// on kPieceTrials members spread over the region), refitted to them by least squares; its
/// members' connected patches are pieces, and the rest is split again.
std::vector<std::vector<std::uint32_t>> planarPieces(const Matcher& m, std::vector<std::uint32_t> members, float link,
                                                     std::size_t fewest, float min_cos, const detail::Joins& joins) {
  const PreparedScene& scene = m.scene;
  const float tolerance = m.p.plane_tolerance;
  fewest = std::max<std::size_t>(fewest, 3);
  std::vector<std::vector<std::uint32_t>> pieces;
  for (int k = 0; k < kMostPieces && members.size() >= fewest; ++k) {
    std::vector<std::uint32_t> best;
    const std::size_t stride = std::max<std::size_t>(1, members.size() / kPieceTrials);
    for (std::size_t t = 0; t < members.size(); t += stride) {
      const std::uint32_t seed = members[t];
      std::vector<std::uint32_t> on = onPlane(scene, members, scene.points[seed], scene.normals[seed], tolerance, min_cos);
      if (on.size() > best.size()) best = std::move(on);
    }
    if (best.size() < fewest) break;
    const PlaneFit fit = fitPlane(scene.points, best, scene.normals[best.front()]);
    best = onPlane(scene, members, fit.centre, fit.normal, tolerance, min_cos);
    for (auto& patch : regionsOf(scene.points, best, link, joins))
      if (patch.size() >= fewest) pieces.push_back(std::move(patch));
    std::vector<std::uint32_t> rest;  // members and best are both sorted
    std::set_difference(members.begin(), members.end(), best.begin(), best.end(), std::back_inserter(rest));
    members = std::move(rest);
  }
  return pieces;
}

std::vector<FlatRegion> flatRegions(const Matcher& m, const std::vector<char>& removed, float least_area) {
  const PreparedScene& scene = m.scene;
  std::vector<std::uint32_t> left;  // the points no detection explains
  for (std::uint32_t i = 0; i < scene.points.size(); ++i)
    if (!removed[i]) left.push_back(i);
  const float spacing = sampleSpacing(m);
  std::vector<FlatRegion> flat;
  const float min_cos = std::cos(kRegionDegrees * static_cast<float>(M_PI) / 180.0f);
  const auto joins = [&](std::uint32_t b, std::uint32_t a, std::uint32_t) { return scene.normals[b].dot(scene.normals[a]) >= min_cos; };
  // Each point covers at most one cell of spacing^2 (coveredArea): fewer cannot make the area.
  const auto fewest = static_cast<std::size_t>(least_area / (spacing * spacing));
  for (auto& members : regionsOf(scene.points, left, kLinkSpacings * spacing, joins)) {
    if (members.size() < std::max<std::size_t>(fewest, 3)) continue;
    FlatRegion region = regionOf(m, std::move(members));
    if (region.plane.rms <= kOnePlaneRms * m.p.plane_tolerance) {
      if (region.area >= least_area) flat.push_back(std::move(region));
      continue;
    }
    for (auto& piece : planarPieces(m, std::move(region.members), kLinkSpacings * spacing, fewest, min_cos, joins))
      if (FlatRegion part = regionOf(m, std::move(piece)); part.area >= least_area && part.plane.rms <= m.p.plane_tolerance)
        flat.push_back(std::move(part));
  }
  return flat;
}

/// Farthest-point seeds for splitRegion: each the member farthest from the region's centre and
/// the seeds before it.
std::vector<Vec3> farthestSeeds(const Points& points, const FlatRegion& region, int count) {
  std::vector<Vec3> seeds;
  std::vector<float> nearest(region.members.size(), INFINITY);
  Vec3 last = region.plane.centre;
  for (int c = 0; c < count; ++c) {
    std::size_t far = 0;
    for (std::size_t k = 0; k < region.members.size(); ++k) {
      nearest[k] = std::min(nearest[k], (points[region.members[k]] - last).squaredNorm());
      if (nearest[k] > nearest[far]) far = k;
    }
    last = points[region.members[far]];
    seeds.push_back(last);
  }
  return seeds;
}

/// `region` split into `copies` pieces about as many centres in its plane (k-means, Lloyd 1982,
/// from farthest-point seeds), each piece a region of its own. Copies of a flat part lying side
/// by side at one height show faces that touch, and their points link into one region as large
/// as several faces.
std::vector<FlatRegion> splitRegion(const Matcher& m, const FlatRegion& region, int copies) {
  const Points& points = m.scene.points;
  std::vector<Vec3> centres = farthestSeeds(points, region, copies);
  std::vector<int> label(region.members.size(), 0);
  for (int step = 0; step < kSplitSteps; ++step) {
    std::vector<Vec3> sum(copies, Vec3::Zero());
    std::vector<int> count(copies, 0);
    for (std::size_t k = 0; k < region.members.size(); ++k) {
      const Vec3& q = points[region.members[k]];
      label[k] = 0;
      for (int c = 1; c < copies; ++c)
        if ((q - centres[c]).squaredNorm() < (q - centres[label[k]]).squaredNorm()) label[k] = c;
      sum[label[k]] += q;
      ++count[label[k]];
    }
    for (int c = 0; c < copies; ++c)
      if (count[c] > 0) centres[c] = sum[c] / static_cast<float>(count[c]);
  }
  std::vector<std::vector<std::uint32_t>> members(copies);
  for (std::size_t k = 0; k < region.members.size(); ++k) members[label[k]].push_back(region.members[k]);
  std::vector<FlatRegion> pieces;
  for (auto& piece : members)
    if (piece.size() >= 3) pieces.push_back(regionOf(m, std::move(piece)));
  return pieces;
}

/// The regions to try: each flat region, or where one is too large for any face but as large as
/// 2 to kMostCopies copies of one, its pieces for each count of copies whose faces could make up
/// its area (splitRegion): copies of a face seen whole or in part, or of two faces of a part that
/// lie at one height. A region that one face could cover whole is not split: its halves would fit
/// a smaller face.
std::vector<FlatRegion> regionsToTry(const Matcher& m, std::vector<FlatRegion> regions, const std::vector<ModelFace>& faces) {
  float largest = 0;
  for (const ModelFace& face : faces) largest = std::max(largest, face.area);
  std::vector<FlatRegion> all;
  for (FlatRegion& region : regions) {
    std::vector<int> splits;
    if (region.area > kMostAreaShare * largest)
      for (const ModelFace& face : faces) {
        const int fewest = std::max(2, static_cast<int>(std::ceil(region.area / (kMostAreaShare * face.area))));
        const int most = std::min(kMostCopies, static_cast<int>(std::floor(region.area / (kLeastAreaShare * face.area))));
        for (int copies = fewest; copies <= most; ++copies) splits.push_back(copies);
      }
    std::sort(splits.begin(), splits.end());
    splits.erase(std::unique(splits.begin(), splits.end()), splits.end());
    for (const int copies : splits)
      for (FlatRegion& piece : splitRegion(m, region, copies)) all.push_back(std::move(piece));
    if (splits.empty()) all.push_back(std::move(region));
  }
  return all;
}

/// Whether a region's spread along an axis is the face's, within a sampled region's error.
bool alike(float region, float face) { return region >= kLeastSpreadShare * face && region <= face / kLeastSpreadShare; }

/// A laid pose of a face, turned about its normal, with its support.
struct Laid {
  Pose pose;
  float support = -1;
};

/// The face laid on the region in coarse steps of spin; none when the region's size or extent is not the face's.
std::vector<Laid> coarseLaid(const Matcher& m, const PreparedModel& coarse, const ModelFace& face, const FlatRegion& region) {
  std::vector<Laid> laid;
  if (region.area < kLeastAreaShare * face.area || region.area > kMostAreaShare * face.area) return laid;
  if (!alike(region.plane.spread[0], face.spread[0]) || !alike(region.plane.spread[1], face.spread[1])) return laid;
  const int spins = face.turns ? kSpins : 1;
  for (int k = 0; k < spins; ++k) {
    const Pose pose = facePose(face, region.plane, kFullTurn * static_cast<float>(k) / kSpins, Vec3::Zero());
    laid.push_back({pose, support(m, coarse, pose)});
  }
  return laid;
}

/// `start` turned about the region's normal and shifted along its plane in fine steps while the
/// support grows.
Laid finer(const Matcher& m, const PreparedModel& judged, const PlaneFit& plane, Laid start) {
  const Vec3 u = plane.normal.unitOrthogonal(), w = plane.normal.cross(u);
  const float d_spin = kFineDegrees * static_cast<float>(M_PI) / 180.0f, d_shift = kFineShiftTolerances * m.p.verify_tolerance;
  for (int step = 0; step < kMostFineSteps; ++step) {
    bool better = false;
    for (int move = 0; move < 6; ++move) {
      Pose pose = start.pose;
      const float sign = move % 2 == 0 ? 1.0f : -1.0f;
      if (move < 2) {  // a turn about the normal through the face's centre on the plane
        const Eigen::Matrix3f turn = Eigen::AngleAxisf(sign * d_spin, plane.normal).toRotationMatrix();
        pose.linear() = turn * pose.linear();
        pose.translation() = plane.centre + turn * (pose.translation() - plane.centre);
      } else {
        pose.translation() += sign * d_shift * (move < 4 ? u : w);
      }
      if (const float v = support(m, judged, pose); v > start.support) {
        start = {pose, v};
        better = true;
      }
    }
    if (!better) break;
  }
  return start;
}

/// The laid poses of the faces on `region`: each face's best kShortlist judged again on
/// `judged`, best first; empty when no face fits the region. A pose whose body lies inside the
/// bin's floor or a wall (Matcher::sunk) is none: a bracket lying on the floor by one plate fits
/// that plate's outer face as well as its inner one, and the outer one, its other plate then
/// thrust into the floor, would take the region and be ruled out with it.
std::vector<Laid> shortlist(const Matcher& m, const PreparedModel& coarse, const PreparedModel& judged,
                            const std::vector<ModelFace>& faces, const FlatRegion& region) {
  const auto better = [](const Laid& a, const Laid& b) { return a.support > b.support; };
  std::vector<Laid> kept;
  for (const ModelFace& face : faces) {
    std::vector<Laid> laid = coarseLaid(m, coarse, face, region);
    std::stable_sort(laid.begin(), laid.end(), better);  // ties in the order laid
    laid.resize(std::min(laid.size(), kShortlist));
    for (Laid& l : laid)
      if (!m.sunk(l.pose)) kept.push_back({l.pose, support(m, judged, l.pose)});
  }
  std::stable_sort(kept.begin(), kept.end(), better);
  return kept;
}

/// A laid pose with its final score's evidence and the scan points supporting it.
struct Scored {
  Pose pose;
  Evidence evidence;
  std::vector<std::uint32_t> support;
};

Scored scored(const Matcher& m, const Pose& pose) {
  Scored s{pose, {}, {}};
  s.evidence = m.scoredEvidence(pose, s.support);
  return s;
}

/// `start` refined by ICP, scored.
Scored refined(const Matcher& m, const Pose& start) {
  return scored(m, refinePose(start, m.icp_model, m.scan.points, m.scan_grid, m.icpParams(m.p.icp_iterations)));
}

/// The laid pose the scan settles on: the shortlist's best refined. Where the scan supports
/// another face, or the same turned otherwise (not by the part's symmetry), kMostRivalShare as
/// well, each such rival is moved finer and refined too. Of the refined poses that stand
/// (Matcher::stands, as laid poses), the best scoring is kept unless another comes within
/// kTieShare of it. A pose the scan rules out (sunk into the floor, its outline not falling away)
/// neither wins nor ties: the best scoring pose may be one such, with a right one among its rivals.
/// Without refinement a rival leaves the region, as no score can settle it.
std::optional<Scored> settled(const Matcher& m, const ModelShape& shape, const PreparedModel& judged, const PlaneFit& plane,
                              const std::vector<Laid>& laid) {
  if (laid.empty()) return std::nullopt;
  const Laid best = finer(m, judged, plane, laid.front());
  if (best.support < m.p.min_score) return std::nullopt;
  std::vector<Laid> rivals;
  for (const Laid& l : laid)
    if (l.support > kMostRivalShare * best.support && !shape.samePose(l.pose, best.pose)) rivals.push_back(l);
  const auto ruledOut = [&](const Scored& s) { return !m.stands(s.pose, s.evidence.score(), s.evidence, s.support, true); };
  std::vector<Scored> poses;
  if (!m.p.refine) {
    if (!rivals.empty()) return std::nullopt;
    poses.push_back(scored(m, best.pose));
  } else {
    poses.push_back(refined(m, best.pose));
    for (const Laid& rival : rivals) poses.push_back(refined(m, finer(m, judged, plane, rival).pose));
  }
  std::erase_if(poses, ruledOut);  // a pose the scan rules out neither wins nor ties
  if (poses.empty()) return std::nullopt;
  const auto by_score = [](const Scored& a, const Scored& b) { return a.evidence.score() < b.evidence.score(); };
  const auto winner = std::max_element(poses.begin(), poses.end(), by_score);
  for (const Scored& other : poses)
    if (&other != &*winner && other.evidence.score() >= kTieShare * winner->evidence.score() &&
        !shape.samePose(other.pose, winner->pose))
      return std::nullopt;  // a tie
  return std::move(*winner);
}

}  // namespace

std::vector<ModelFace> flatFaces(const Points& points, const Points& normals, float sample_radius, float area_per_point,
                                 float min_area, const Vec3* revolution_axis) {
  std::vector<ModelFace> faces;
  std::vector<std::uint32_t> all(points.size());
  std::iota(all.begin(), all.end(), 0u);
  const float min_cos = std::cos(kModelFaceDegrees * static_cast<float>(M_PI) / 180.0f);
  // One plane: a face's normals and points those of its seed's plane (a fillet's normals turn
  // little from one point to the next, and would link parallel faces).
  const auto joins = [&](std::uint32_t b, std::uint32_t, std::uint32_t seed) {
    return normals[b].dot(normals[seed]) >= min_cos && std::abs(normals[seed].dot(points[b] - points[seed])) <= kFaceFlatness * sample_radius;
  };
  for (const auto& members : regionsOf(points, all, 2.0f * sample_radius, joins)) {
    const float area = static_cast<float>(members.size()) * area_per_point;
    if (area < min_area) continue;
    Vec3 mean = Vec3::Zero();
    for (std::uint32_t i : members) mean += normals[i];
    const PlaneFit plane = fitPlane(points, members, mean);
    if (plane.rms > kFaceFlatness * sample_radius) continue;  // a gently curved surface, not a face
    const bool about_axis = revolution_axis != nullptr && std::abs(revolution_axis->dot(plane.normal)) >= kAxisCosine;
    faces.push_back(
        {plane.normal, plane.centre, area, !about_axis, {plane.spread[0], plane.spread[1]}, {plane.axes[0], plane.axes[1]}});
  }
  return faces;
}

void addFaceDetections(const std::vector<ModelFace>& faces, const Matcher& m, const ModelShape& shape, MatchState& state) {
  if (faces.empty()) return;
  const StageSettings& p = m.p;
  const auto shareOf = [&](std::size_t count) { return preparedShare(m.scored_model.points(), m.scored_model.normals(), count); };
  float least = INFINITY;
  for (const ModelFace& f : faces) least = std::min(least, f.area);
  const std::vector<FlatRegion> regions = regionsToTry(m, flatRegions(m, state.removed, kLeastAreaShare * least), faces);
  if (regions.empty()) return;
  const PreparedModel coarse = shareOf(kCoarsePoints), judged = shareOf(kJudgedPoints);
  for (const FlatRegion& region : regions) {
    const auto gone = std::count_if(region.members.begin(), region.members.end(), [&](std::uint32_t i) { return state.removed[i] != 0; });
    if (2 * static_cast<std::size_t>(gone) > region.members.size()) continue;  // a detection before explains it
    // settled() keeps only poses that stand (as laid poses: standing out of the scan around them).
    std::optional<Scored> laid = settled(m, shape, judged, region.plane, shortlist(m, coarse, judged, faces, region));
    if (!laid || state.refoundAt(laid->pose, shape, p.refound_share)) continue;
    Hypothesis h;
    h.detection.pose = laid->pose;
    h.detection.score = laid->evidence.score();
    h.support = std::move(laid->support);
    state.accept(std::move(h), p, shape, m.scene.points);
    if (state.enough) return;
  }
}

}  // namespace binpose
