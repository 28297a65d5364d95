// The redundant sub-group pipeline (thesis chapter 5) with binpose's refinements.
#include <binpose/detector.hpp>

#include <binpose/clique.hpp>
#include <binpose/planes.hpp>
#include <binpose/refine.hpp>
#include <binpose/scene.hpp>
#include <binpose/voting.hpp>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <tbb/parallel_invoke.h>

namespace binpose {
namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

/// The scene without the points of the bin's floor and walls.
PreparedScene withoutPlanes(PreparedScene scene, const DetectionParams& p, std::vector<Plane>& planes) {
  const std::vector<char> flat = largePlanes(scene.points, scene.normals, p.rho_sub, planeParams(p), &planes);
  PreparedScene kept;
  for (std::size_t i = 0; i < flat.size(); ++i) {
    if (flat[i]) continue;
    kept.points.push_back(scene.points[i]);
    kept.normals.push_back(scene.normals[i]);
    kept.scan_index.push_back(scene.scan_index[i]);
  }
  return kept;
}

}  // namespace

Detector::Detector(const ModelDatabase& db, const DetectionParams& params)
    : db_(db), params_(params), model_tree_(db.model().points),
      icp_model_(evenShare(db.model().points, db.model().normals, static_cast<std::size_t>(std::max(0, params.icp_model_points)))) {
  validate(params_);
  if (params_.plane_min_area == 0) params_.plane_min_area = boundingFaceArea(db.model().points);
  const Points& m = db.model().points;
  model_centroid_ = Vec3::Zero();
  for (const Vec3& p : m) model_centroid_ += p;
  model_centroid_ /= static_cast<float>(m.size());
  for (const Vec3& p : m) model_radius_ = std::max(model_radius_, (p - model_centroid_).norm());
}

bool Detector::mostlyOverlaps(const Pose& a, const Pose& b) const {
  if ((a * model_centroid_ - b * model_centroid_).norm() > 2 * model_radius_) return false;
  const Points& model = icp_model_.points;  // an even share: the same fraction as all points
  const Pose b_from_a = b.inverse() * a;
  const float near_distance = 0.1f * db_.model().diameter;  // the usual correctness radius (ADD < 0.1 d)
  const std::size_t half = model.size() / 2;
  std::size_t near = 0, far = 0;
  for (const Vec3& m : model) {  // stops as soon as the answer is known
    std::uint32_t j;
    float d2;
    if (model_tree_.nearest(b_from_a * m, j, d2) && d2 <= near_distance * near_distance) {
      if (++near > half) return true;
    } else if (++far >= model.size() - half) {
      return false;
    }
  }
  return false;
}

std::vector<Detection> Detector::suppressDuplicates(std::vector<Hypothesis> hypotheses, std::size_t scan_size) const {
  std::stable_sort(hypotheses.begin(), hypotheses.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.detection.score > b.detection.score; });
  std::vector<char> claimed(scan_size, 0);
  std::vector<Detection> kept;
  for (const Hypothesis& h : hypotheses) {
    std::size_t taken = 0;
    for (const auto i : h.support) taken += claimed[i];
    if (4 * taken > h.support.size()) continue;  // a quarter explained already: not a new object
    if (std::any_of(kept.begin(), kept.end(), [&](const Detection& k) { return mostlyOverlaps(h.detection.pose, k.pose); }))
      continue;  // another pose of an object already found (a near-symmetric flip, say)
    for (const auto i : h.support) claimed[i] = 1;
    kept.push_back(h.detection);
  }
  return kept;
}

DetectionResult Detector::detect(const PointCloud& scan) const {
  const auto t0 = Clock::now();
  DetectionResult result;
  result.scene_points = scan.size();
  if (scan.empty()) return result;
  const DetectionParams& p = params_;
  const Points& model = db_.model().points;
  const Points& model_normals = db_.model().normals;

  // The scan's kd-tree (one core) is built while the other core sub-samples.
  std::optional<KdTree> tree;
  std::vector<std::uint32_t> chosen;
  tbb::parallel_invoke([&] { tree.emplace(scan.points); }, [&] { chosen = subsampleScene(scan.points, p); });
  const KdTree& scan_tree = *tree;
  PreparedScene scene = prepareScene(scan.points, scan_tree, chosen, p);
  result.sampled_points = scene.points.size();
  std::vector<Plane> planes;  // the bin's
  if (p.remove_planes) scene = withoutPlanes(std::move(scene), p, planes);
  result.plane_points = result.sampled_points - scene.points.size();
  const SceneEvidence evidence(scan.points, scan_tree, p.viewpoint, planes, std::min(p.verify_tolerance, p.plane_tolerance));
  const auto groups = makeSubGroups(scene.points, p.eta, p.r, static_cast<std::size_t>(p.C_n));
  result.subgroups = groups.size();
  result.timing.preprocess_ms = msSince(t0);

  const auto max_list = static_cast<std::uint32_t>(p.max_key_share * static_cast<float>(model.size()));
  // Local votes (each point votes once, when a sub-group first needs it; see NeighbourhoodVoter).
  std::unique_ptr<NeighbourhoodVoter> local;
  std::vector<char> may_vote;  // the reference points of voter_spacing (all without it)
  if (p.local_votes) {
    std::vector<std::uint32_t> partners;
    if (p.partner_spacing > 0) partners = voxelSubsample(scene.points, p.partner_spacing);
    local = std::make_unique<NeighbourhoodVoter>(db_, scene.points, scene.normals, p.vote_radius, p.candidates_per_point,
                                                 max_list, partners, p.candidate_spacing);
    may_vote.assign(scene.points.size(), p.voter_spacing > 0 ? 0 : 1);
    if (p.voter_spacing > 0)
      for (const auto i : voxelSubsample(scene.points, p.voter_spacing)) may_vote[i] = 1;
  }
  const double vote_setup_ms = msSince(t0) - result.timing.preprocess_ms;
  double vote_ms = 0;  // inside the sub-group loop

  std::vector<char> removed(scene.points.size(), 0);
  ParallelVoter voter(db_, p.candidates_per_point, max_list, p.candidate_spacing);
  std::vector<std::uint32_t> members, voters;
  std::vector<Correspondence> candidates;
  Points clique_model, clique_scene;
  std::vector<Hypothesis> hypotheses;
  std::vector<char> explained(scan.size(), 0);  // scan points supporting a detection scoring >= 0.5
  int confident = 0;  // detections that removed their points
  double refine_ms = 0;
  const auto t_match = Clock::now();
  for (const auto& group : groups) {
    members.clear();
    for (const auto i : group)
      if (!removed[i]) members.push_back(i);
    if (members.size() < static_cast<std::size_t>(p.C_n)) continue;
    ++result.subgroups_run;
    candidates.clear();
    const auto t_vote = Clock::now();
    if (p.local_votes) {
      voters.clear();
      for (const auto i : members)
        if (may_vote[i]) voters.push_back(i);
      local->vote(voters);
      for (const auto i : members)
        for (const auto m : local->candidates(i)) candidates.push_back({i, m});
    } else {
      voter.vote(scene.points, scene.normals, members, candidates);  // 4.3-4.4
    }
    vote_ms += msSince(t_vote);
    if (candidates.size() < static_cast<std::size_t>(p.C_n)) continue;
    const CliqueResult clique =
        maximumClique(consistencyGraph(candidates, scene.points, model, p.e_gmax), p.clique_work_limit);  // 4.5
    if (clique.vertices.size() < static_cast<std::size_t>(p.C_n)) continue;
    clique_model.clear();
    clique_scene.clear();
    for (const int v : clique.vertices) {
      clique_model.push_back(model[candidates[v].model]);
      clique_scene.push_back(scene.points[candidates[v].scene]);
    }
    const PoseFit fit = solvePose(clique_model, clique_scene);  // 4.6
    if (!fit.ok) continue;
    Detection det{fit.pose, 0.0f, static_cast<int>(clique.vertices.size()), fit.rms};
    if (p.verify) {  // most of the clique on an object already scored well: the same object again
      int taken = 0;
      for (const int v : clique.vertices) taken += explained[scene.scan_index[candidates[v].scene]];
      if (2 * taken > static_cast<int>(clique.vertices.size())) continue;
    }

    const auto t_refine = Clock::now();
    ++result.hypotheses;
    if (p.verify && p.prescreen &&
        evidence.evaluate(det.pose, icp_model_.points, icp_model_.normals, p.icp_max_distance, 0.0f).score() < p.min_score) {
      refine_ms += msSince(t_refine);
      continue;  // far from the scan even at the ICP gate: not worth refining
    }
    ++result.refined;
    if (p.refine) {
      const IcpParams icp{p.icp_iterations, p.icp_max_distance, p.verify_tolerance, p.viewpoint};
      det.pose = refinePose(det.pose, icp_model_.points, icp_model_.normals, scan.points, scan_tree, icp);
    }
    Hypothesis h;
    det.score = evidence.evaluate(det.pose, model, model_normals, p.verify_tolerance, db_.model().sample_radius, &h.support)
                    .score();
    refine_ms += msSince(t_refine);
    if (p.verify && det.score < p.min_score) continue;

    std::sort(h.support.begin(), h.support.end());
    h.support.erase(std::unique(h.support.begin(), h.support.end()), h.support.end());
    h.detection = det;
    if (det.score >= 0.5f)
      for (const auto i : h.support) explained[i] = 1;
    hypotheses.push_back(std::move(h));
    if (det.score < p.removal_score) continue;  // not sure enough to take its points away
    if (p.max_instances > 0 && ++confident >= p.max_instances) break;  // enough sure detections
    // 5.2.6, eq. 39: remove the scene points within sigma_dist of the posed model.
    const Pose inverse = det.pose.inverse();
    const Vec3 centre = det.pose * model_centroid_;
    const float reach = model_radius_ + p.sigma_dist;
    for (std::size_t i = 0; i < scene.points.size(); ++i) {
      if (removed[i] || (scene.points[i] - centre).squaredNorm() > reach * reach) continue;
      std::uint32_t j;
      float d2;
      if (model_tree_.nearest(inverse * scene.points[i], j, d2) && d2 <= p.sigma_dist * p.sigma_dist) removed[i] = 1;
    }
  }
  result.timing.vote_ms = vote_setup_ms + vote_ms;
  result.timing.refine_ms = refine_ms;
  result.timing.match_ms = msSince(t_match) - refine_ms - vote_ms;
  if (p.verify) {
    const auto t_suppress = Clock::now();
    result.detections = suppressDuplicates(std::move(hypotheses), scan.size());
    if (p.max_instances > 0 && static_cast<int>(result.detections.size()) > p.max_instances)
      result.detections.resize(static_cast<std::size_t>(p.max_instances));
    result.timing.match_ms += msSince(t_suppress);
  } else {
    for (Hypothesis& h : hypotheses) result.detections.push_back(h.detection);
  }
  result.timing.total_ms = msSince(t0);
  return result;
}

}  // namespace binpose
