// Scene preparation (thesis 5.2.1-5.2.2) with the bin's planes taken out, both cores busy.
#include "scan_preparation.hpp"

#include <binpose/normals.hpp>
#include <binpose/planes.hpp>

#include <atomic>
#include <cmath>
#include <span>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <vector>

namespace binpose {
namespace {

/// Pending fits finished a few at a time, side by side.
constexpr std::size_t kFitsPerTask = 16;

/// The scene without the points of the bin's floor and walls. Normals left pending (NaN, their
/// fits in `fits` by place among the chosen points `chosen`, of which the scene's are a part)
/// are computed only where the plane search or the points kept need them: the scene of every
/// normal computed. Empty when a pending fit turns out degenerate after all (the scene should
/// not have held its point: start again with every normal computed).
std::optional<PreparedScene> withoutPlanes(PreparedScene scene, const StageSettings& p, std::vector<Plane>& planes,
                                           std::span<const std::uint32_t> chosen, std::span<const PendingFit> fits) {
  std::vector<char> pending(scene.points.size(), 0);
  std::vector<std::uint32_t> place(scene.points.size());  // each point's among the chosen
  for (std::size_t j = 0, i = 0; j < scene.points.size(); ++j) {
    while (chosen[i] != scene.scan_index[j]) ++i;
    place[j] = static_cast<std::uint32_t>(i);
    pending[j] = std::isnan(scene.normals[j].x());
  }
  std::atomic<bool> degenerate{false};
  std::vector<std::uint32_t> todo;
  LateNormals late;
  late.pending = &pending;
  late.finish = [&](std::span<const std::uint32_t> which) {
    todo.clear();
    for (const auto j : which)
      if (pending[j]) {
        pending[j] = 0;
        todo.push_back(j);
      }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, todo.size(), kFitsPerTask), [&](const auto& range) {
      for (std::size_t k = range.begin(); k < range.end(); ++k) {
        const std::uint32_t j = todo[k];
        if (!finishPending(fits[place[j]], scene.points[j], p.viewpoint, scene.normals[j])) degenerate = true;
      }
    });
  };
  late.aligned = [&](std::uint32_t j, const Vec3& m, float min_cos) { return pendingAligned(fits[place[j]], m, min_cos); };
  const std::vector<char> flat = largePlanes(scene.points, scene.normals, p.rho_sub, planeParams(p), &planes, &late);
  std::vector<std::uint32_t> kept_pending;
  for (std::size_t j = 0; j < flat.size(); ++j)
    if (!flat[j] && pending[j]) kept_pending.push_back(static_cast<std::uint32_t>(j));
  late.finish(kept_pending);
  if (degenerate) return std::nullopt;
  PreparedScene kept;
  for (std::size_t i = 0; i < flat.size(); ++i) {
    if (flat[i]) continue;
    kept.points.push_back(scene.points[i]);
    kept.normals.push_back(scene.normals[i]);
    kept.scan_index.push_back(scene.scan_index[i]);
  }
  return kept;
}

/// A right pose's model points lie up to 0.71 scan spacings from the nearest scan point of a
/// square grid: the score's support reaches this many spacings along the surface
/// (SceneEvidence::setLateralSlack). An industrial sensor's 640 x 480 view from 1.5 m has 2.7 mm
/// between points; at the 1 mm tolerance of a 60 mm part the copies' true poses scored 0-0.15.
constexpr float kSpacingsOfSupport = 0.75f;
/// ... on a scan whose noise (1 sigma) is under this share of its spacing. On a noisier one the
/// noise's tolerance (1.5 sigma, docs/design.md, The scan's noise) already reaches most of the
/// way, and the slack lets its scattered points meet a wrong pose as often as a right one: on
/// the real Kinect-class and SICK scans (noise 0.3-0.5 of the spacing) the detections of parts
/// that are not there rose from 263 to 522 with the slack everywhere, to 334 from a third.
constexpr float kCleanSpacingShare = 0.25f;

/// The chosen points' normals (5.2.2). The scan's grid (one core) is built while the other core
/// sub-samples, indexes a depth image's points by pixel and starts on the normals whose
/// neighbours the pixels give (most of them; the first core joins in when the grid is done); the
/// rest are found through the grid. A depth image's cells are sized from its pixel neighbours'
/// spacing; any size gives the same answers. Fits that need Eigen's iterative solver go to
/// `late` (when given) for the plane search to ask for: most lie on the floor and walls.
Points orientedNormals(const PointCloud& scan, const StageSettings& p, PreparedScan& out, std::vector<std::uint32_t>& chosen,
                       std::vector<PendingFit>* late) {
  std::vector<std::uint32_t> deferred;
  Points normals;
  std::atomic<const PointGrid*> grid_ready{nullptr};  // the pixels' misses go to the grid once it is built
  // The noise is measured before the normals, whose k depends on it, and the values that depend
  // on it are adapted: through the pixels in a depth image, else through the grid once it is
  // built. A single view saved as an unorganized file (a PLY from the sensor's software) is as
  // noisy as its depth image; a clean or resampled scan reads low and keeps the defaults.
  const auto measure = [&](const NeighbourQuery& query) {
    out.noise = estimateNoise(scan.points, chosen, query, p.viewpoint, p.adapt_to_noise ? p.far_noise : 0.0f);
    out.params = p.adapt_to_noise ? adaptedToNoise(p, out.noise) : p;
    if (std::isfinite(out.noise.far_range))  // too noisy there to match: those points are not sampled
      std::erase_if(chosen, [&](std::uint32_t i) { return (scan.points[i] - p.viewpoint).norm() >= out.noise.far_range; });
  };
  const auto normalsFor = [&] {
    if (out.params.normal_radius > 0) return;  // radiusNormals, once the grid is built
    normals = pixelNormals(*out.pixels, scan.points, chosen, out.params.k_normals, p.viewpoint, deferred, &grid_ready, late);
  };
  tbb::parallel_invoke(
      [&] { grid_ready.store(&out.grid.emplace(scan.points, 2.0f * pixelSpacing(scan)), std::memory_order_release); },
      [&] {
        chosen = subsampleScene(scan.points, p.rho_sub, p.subsampling, p.seed);
        out.pixels.emplace(scan);
        if (!out.pixels->usable()) return;
        measure(pixelQuery(*out.pixels));
        normalsFor();
      });
  if (!out.pixels->usable()) {  // an unorganized scan: the grid answers every search
    measure(gridQuery(*out.grid, scan.points));
    normalsFor();
  }
  if (out.params.normal_radius > 0) {
    if (late != nullptr) late->assign(chosen.size(), PendingFit{});  // none left pending
    return radiusNormals(*out.grid, scan.points, chosen, out.params.normal_radius, p.viewpoint);
  }
  finishNormals(*out.grid, scan.points, chosen, deferred, out.params.k_normals, p.viewpoint, normals, late);
  return normals;
}

/// The bin's planes out of out.scene; a degenerate pending fit means every normal computed, and again.
void removePlanes(const PointCloud& scan, const StageSettings& p, std::span<const std::uint32_t> chosen, Points& normals,
                  std::span<const PendingFit> fits, PreparedScan& out, std::vector<Plane>& planes) {
  if (auto lazy = withoutPlanes(std::move(out.scene), p, planes, chosen, fits)) {
    out.scene = std::move(*lazy);
    return;
  }
  for (std::size_t i = 0; i < chosen.size(); ++i)
    if (std::isnan(normals[i].x()) && !finishPending(fits[i], scan.points[chosen[i]], p.viewpoint, normals[i]))
      normals[i] = Vec3::Zero();
  planes.clear();
  PreparedScene every = orientedScene(scan.points, chosen, normals);
  out.sampled_points = every.points.size();
  out.scene = *withoutPlanes(std::move(every), p, planes, chosen, fits);  // nothing pending: never empty
}

}  // namespace

void prepareScan(const PointCloud& scan, const StageSettings& user, PreparedScan& out) {
  std::vector<std::uint32_t> chosen;
  std::vector<PendingFit> fits;
  Points normals = orientedNormals(scan, user, out, chosen, user.remove_planes ? &fits : nullptr);
  const StageSettings& p = out.params;  // adapted to the noise from here on
  out.scene = orientedScene(scan.points, chosen, normals);
  out.sampled_points = out.scene.points.size();
  // The bin's planes and the score's view of the scan side by side.
  std::vector<Plane> planes;
  tbb::parallel_invoke(
      [&] {
        if (p.remove_planes) removePlanes(scan, p, chosen, normals, fits, out, planes);
      },
      [&] {
        out.evidence.emplace(scan.points, *out.grid, p.viewpoint, &*out.pixels);
        out.evidence->setGrazingAngle(p.grazing_angle);
        if (p.adapt_to_noise && out.noise.sigma < kCleanSpacingShare * out.noise.spacing)
          out.evidence->setLateralSlack(kSpacingsOfSupport * out.noise.spacing);
      });
  out.evidence->setBackground(std::move(planes), std::min(p.verify_tolerance, p.plane_tolerance));
  out.plane_points = out.sampled_points - out.scene.points.size();
}

}  // namespace binpose
