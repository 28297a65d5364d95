// Evaluation of detections against ground truth (thesis 7.1.3; BOP's ADD-S and MSSD).
#include <binpose/evaluation.hpp>

#include <binpose/features.hpp>
#include <binpose/geometry.hpp>
#include <binpose/kdtree.hpp>
#include <binpose/model.hpp>
#include <binpose/pose.hpp>
#include <binpose/sampling.hpp>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <nlohmann/json.hpp>

namespace binpose {
namespace {

float degrees(float rad) { return rad * 180.0f / static_cast<float>(M_PI); }

/// Least rotation angle between R_est and R_true R_s over the symmetries. For a continuous axis
/// a the spin about a is free, and the least angle is the angle between R_est a and R_true R_d a.
float symmetricAngle(const Pose& est, const Pose& truth, const EvalModel& m) {
  std::vector<Pose> discrete{Pose::Identity()};
  discrete.insert(discrete.end(), m.symmetries.discrete.begin(), m.symmetries.discrete.end());
  float best = INFINITY;
  for (const Pose& d : discrete) {
    const Eigen::Matrix3f R = truth.linear() * d.linear();
    if (m.symmetries.continuous.empty()) {
      best = std::min(best, Eigen::AngleAxisf(est.linear().transpose() * R).angle());
    } else {
      for (const auto& c : m.symmetries.continuous)
        best = std::min(best, angleBetween(est.linear() * c.axis, R * c.axis));
    }
  }
  return degrees(best);
}

}  // namespace

Symmetries readSymmetries(const std::string& path, const std::string& obj_id) {
  Symmetries s;
  std::ifstream in(path);
  if (!in) return s;
  const auto j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded() || !j.contains(obj_id)) throw Error(fmt::format("{}: no entry '{}'", path, obj_id));
  const auto& e = j[obj_id];
  try {
    for (const auto& d : e.value("symmetries_discrete", nlohmann::json::array())) {
      if (d.size() != 16) throw Error(fmt::format("{}: a discrete symmetry needs 16 numbers", path));
      Eigen::Matrix4f T;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) T(r, c) = d[4 * r + c].get<float>();
      Pose p = Pose::Identity();
      p.matrix() = T;
      s.discrete.push_back(p);
    }
    for (const auto& c : e.value("symmetries_continuous", nlohmann::json::array())) {
      const auto a = c.at("axis"), o = c.at("offset");
      Vec3 axis(a[0].get<float>(), a[1].get<float>(), a[2].get<float>());
      if (!normalizeSafe(axis)) throw Error(fmt::format("{}: a symmetry axis is zero", path));
      s.continuous.push_back({axis, Vec3(o[0].get<float>(), o[1].get<float>(), o[2].get<float>())});
    }
  } catch (const nlohmann::json::exception& ex) {
    throw Error(fmt::format("{}: malformed symmetries ({})", path, ex.what()));
  }
  return s;
}

std::vector<Pose> symmetryTransforms(const Symmetries& s, float step_deg) {
  std::vector<Pose> discrete{Pose::Identity()};
  discrete.insert(discrete.end(), s.discrete.begin(), s.discrete.end());
  if (s.continuous.empty()) return discrete;
  std::vector<Pose> out;
  const int steps = std::max(1, static_cast<int>(std::round(360.0f / step_deg)));
  for (const Pose& d : discrete)
    for (const auto& c : s.continuous)
      for (int k = 0; k < steps; ++k)  // about the axis through the offset
        out.push_back(d * turnAbout(c.axis, float(2 * M_PI) * float(k) / float(steps), c.offset));
  return out;
}

EvalModel makeEvalModel(const Mesh& mesh, const Symmetries& symmetries) {
  EvalModel m;
  for (const auto& s : sampleSurfaceUniform(mesh, 2000, 12345)) m.points.push_back(s.point);
  const Points face_normals = faceNormals(mesh);
  for (const auto& s : sampleSurfaceUniform(mesh, 50000, 54321)) {
    m.dense.push_back(s.point);
    m.dense_normals.push_back(face_normals[s.face]);
  }
  m.centroid = surfaceCentroid(mesh);
  m.diameter = diameter(mesh.vertices);
  m.symmetries = symmetries;
  m.transforms = symmetryTransforms(symmetries);
  return m;
}

PoseErrors poseErrors(const Pose& est, const Pose& truth, const EvalModel& m) {
  PoseErrors e;
  e.centroid_mm = (est * m.centroid - truth * m.centroid).norm();
  e.angle_deg = symmetricAngle(est, truth, m);
  Points posed_truth;  // dense, so that the nearest surface point is found, not the nearest sample
  for (const Vec3& p : m.dense) posed_truth.push_back(truth * p);
  const KdTree tree(posed_truth);
  double sum = 0;
  for (const Vec3& p : m.points) {  // distance to the surface: to the nearest sample's tangent plane
    std::uint32_t j;
    float d2;
    const Vec3 q = est * p;
    tree.nearest(q, j, d2);
    const Vec3 n = truth.linear() * m.dense_normals[j];
    sum += n.squaredNorm() > 0.5f ? std::abs(n.dot(q - posed_truth[j])) : std::sqrt(d2);
  }
  e.add_s_mm = static_cast<float>(sum / static_cast<double>(m.points.size()));
  e.mssd_mm = INFINITY;
  for (const Pose& s : m.transforms) {
    float worst = 0;
    for (const Vec3& p : m.points) worst = std::max(worst, (est * p - truth * (s * p)).norm());
    e.mssd_mm = std::min(e.mssd_mm, worst);
  }
  return e;
}

EvaluationReport evaluate(const GroundTruth& truth, const std::vector<Pose>& detections, double total_ms,
                          const EvalModel& model, float threshold) {
  EvaluationReport r;
  r.detections = static_cast<int>(detections.size());
  r.total_ms = total_ms;
  const float limit = threshold * model.diameter;
  // Candidate pairs near enough to matter, best (lowest ADD-S) first; each side used once.
  struct Pair { PoseErrors errors; int det, gt; };
  std::vector<Pair> pairs;
  for (std::size_t d = 0; d < detections.size(); ++d)
    for (std::size_t g = 0; g < truth.instances.size(); ++g) {
      if ((detections[d] * model.centroid - truth.instances[g].pose * model.centroid).norm() > model.diameter) continue;
      const PoseErrors e = poseErrors(detections[d], truth.instances[g].pose, model);
      if (e.add_s_mm < limit) pairs.push_back({e, int(d), int(g)});
    }
  std::stable_sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.errors.add_s_mm < b.errors.add_s_mm; });
  std::vector<char> det_used(detections.size(), 0);
  r.instances.resize(truth.instances.size());
  for (std::size_t g = 0; g < truth.instances.size(); ++g) {
    r.instances[g].truth = static_cast<int>(g);
    r.instances[g].visible_fraction = truth.instances[g].visible_fraction;
    r.instances[g].visib_fract = truth.instances[g].visib_fract;
  }
  for (const Pair& p : pairs) {
    InstanceResult& inst = r.instances[p.gt];
    if (det_used[p.det] || inst.detection >= 0) continue;
    det_used[p.det] = 1;
    inst.detection = p.det;
    inst.errors = p.errors;
  }
  r.visible_bin_total.assign(10, 0);
  r.visible_bin_found.assign(10, 0);
  int over_half = 0, over_half_found = 0;
  for (const InstanceResult& inst : r.instances) {
    const int bin = std::clamp(static_cast<int>(inst.visible_fraction * 10.0f), 0, 9);
    ++r.visible_bin_total[bin];
    const bool found = inst.detection >= 0;
    if (found) {
      ++r.matched;
      ++r.visible_bin_found[bin];
      r.mean_centroid_mm += inst.errors.centroid_mm;
      r.mean_angle_deg += inst.errors.angle_deg;
      r.mean_add_s_mm += inst.errors.add_s_mm;
      r.mean_mssd_mm += inst.errors.mssd_mm;
    }
    if (inst.visib_fract > 0.5f) {
      ++over_half;
      over_half_found += found;
    }
  }
  if (r.matched > 0) {
    r.mean_centroid_mm /= r.matched;
    r.mean_angle_deg /= r.matched;
    r.mean_add_s_mm /= r.matched;
    r.mean_mssd_mm /= r.matched;
    r.ms_per_object = total_ms / r.matched;
  }
  r.recall = truth.instances.empty() ? 0.0 : double(r.matched) / double(truth.instances.size());
  r.precision = detections.empty() ? 0.0 : double(r.matched) / double(detections.size());
  r.recall_over_half_visible = over_half == 0 ? 0.0 : double(over_half_found) / over_half;
  return r;
}

}  // namespace binpose
