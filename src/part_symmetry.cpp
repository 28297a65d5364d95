// The three kinds of part symmetry behind one interface.
#include "part_symmetry.hpp"

#include <binpose/point_grid.hpp>
#include <binpose/symmetry.hpp>

#include <algorithm>
#include <cmath>

namespace binpose {

std::optional<MirrorPlane> mirrorPlane(const OrientedModel& model) {
  const Points& points = model.points;
  if (points.size() < 3 || !(model.sample_radius > 0)) return std::nullopt;
  const PrincipalAxes principal = principalAxes(points);
  const PointGrid grid(points);
  std::optional<MirrorPlane> best;
  double best_rms = model.sample_radius;
  for (int k = 0; k < 3; ++k) {
    MirrorPlane plane;
    plane.normal = principal.axes.col(k).normalized();
    plane.d = plane.normal.dot(principal.centre);
    double sum = 0;
    for (const Vec3& x : points) {
      std::uint32_t index;
      float d2 = 0;
      if (!grid.nearest(plane.reflect(x), 2.0f * model.sample_radius, index, d2)) d2 = 4.0f * model.sample_radius * model.sample_radius;
      sum += d2;
    }
    if (const double rms = std::sqrt(sum / static_cast<double>(points.size())); rms <= best_rms) {
      best_rms = rms;
      best = plane;
    }
  }
  return best;
}

PartSymmetry::PartSymmetry(const ModelDatabase& db, const StageSettings& p) {
  const OrientedModel& model = db.model();
  if (p.use_revolution)
    if (const auto axis = findRevolutionAxis(model)) {
      orbits_ = makeOrbits(db, *axis, model.sample_radius);
      kind_ = Kind::Revolution;
      return;
    }
  if (p.use_cyclic_symmetry)
    if ((cyclic_ = findCyclicSymmetry(model))) {
      classes_ = makeCyclicClasses(db, *cyclic_);
      kind_ = Kind::Cyclic;
    }
  if (kind_ == Kind::None) mirror_ = mirrorPlane(model);
}

const Orbits* PartSymmetry::votingOrbits() const {
  return orbits_ ? &*orbits_ : classes_ ? &*classes_ : nullptr;
}

int PartSymmetry::candidatesPerPoint(const StageSettings& p) const {
  return kind_ == Kind::None ? p.candidates_per_point : std::min(p.candidates_per_point, p.revolution_candidates);
}

Graph PartSymmetry::consistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& scene_normals,
                                     const OrientedModel& model, const StageSettings& p, GraphWorkspace& workspace) const {
  switch (kind_) {
    case Kind::Revolution:
      return revolutionConsistencyGraph(cps, scene, scene_normals, *orbits_, p.e_gmax, p.revolution_angle_tolerance);
    case Kind::Cyclic:
      return cyclicConsistencyGraph(cps, scene, scene_normals, model, *cyclic_, p.e_gmax, p.revolution_angle_tolerance, &workspace);
    case Kind::None:
      break;
  }
  return binpose::consistencyGraph(cps, scene, model.points, p.e_gmax, &workspace,
                                   {&scene_normals, &model.normals, p.pair_angle_tolerance});
}

std::vector<PoseFit> PartSymmetry::solve(std::span<const Correspondence> clique, const Points& scene,
                                         const Points& scene_normals, const Points& model, CliqueBuffers& b,
                                         bool reflected) const {
  b.scene.clear();
  for (const Correspondence& c : clique) b.scene.push_back(scene[c.scene]);
  if (kind_ == Kind::Revolution) {  // the axis of the clique's orbits
    b.scene_normals.clear();
    b.model_ids.clear();
    for (const Correspondence& c : clique) {
      b.scene_normals.push_back(scene_normals[c.scene]);
      b.model_ids.push_back(c.model);
    }
    return solveRevolutionPoses(*orbits_, b.model_ids, model, b.scene, b.scene_normals);
  }
  b.model.clear();
  for (const Correspondence& c : clique) b.model.push_back(model[c.model]);
  if (reflected && mirror_)
    for (Vec3& x : b.model) x = mirror_->reflect(x);
  PoseFit fit = kind_ == Kind::Cyclic ? solveCyclicPose(*cyclic_, b.model, b.scene, b.cyclic) : solvePose(b.model, b.scene, b.pose);
  if (!fit.ok) return {};
  return {fit};
}

}  // namespace binpose
