// The redundant sub-group pipeline (thesis chapter 5) with binpose's refinements.
#include <binpose/detector.hpp>

#include <binpose/clique.hpp>
#include <binpose/geometry.hpp>
#include <binpose/normals.hpp>
#include <binpose/planes.hpp>
#include <binpose/refine.hpp>
#include <binpose/scene.hpp>
#include <binpose/voting.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <numeric>
#include <optional>
#include <span>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

namespace binpose {
namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

/// The scene without the points of the bin's floor and walls. Normals left pending (NaN, their
/// fits in `fits` by place among the chosen points `chosen`, of which the scene's are a part)
/// are computed only where the plane search or the points kept need them: the scene of every
/// normal computed. Empty when a pending fit turns out degenerate after all (the scene should
/// not have held its point: start again with every normal computed).
std::optional<PreparedScene> withoutPlanes(PreparedScene scene, const DetectionParams& p, std::vector<Plane>& planes,
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
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, todo.size(), 16), [&](const auto& range) {
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

/// Appends the voters (may_vote, or all with `all_voters`) among the points of `group` not yet
/// removed, when there are at least `min_size` such points (fewer: the sub-group will not run).
void appendLiveVoters(std::span<const std::uint32_t> group, const std::vector<char>& removed, const std::vector<char>& may_vote,
                      bool all_voters, std::size_t min_size, std::vector<std::uint32_t>& voters) {
  const std::size_t mark = voters.size();
  std::size_t live = 0;
  for (const auto i : group) {
    if (removed[i]) continue;
    ++live;
    if (all_voters || may_vote[i]) voters.push_back(i);
  }
  if (live < min_size) voters.resize(mark);
}

/// What one sub-group gave on the scene as it stood when it ran (5.2.3-5.2.5). Sub-groups run
/// side by side in batches and are taken in their order afterwards (see Detector::detect).
struct GroupOutcome {
  std::vector<std::uint32_t> members;      ///< its points not removed when it ran
  bool ran = false;                        ///< enough members to vote
  std::vector<Correspondence> clique;      ///< the clique's pairs (empty: no pose)
  std::vector<Pose> poses;                 ///< the clique's closed-form pose, then its alternatives
                                           ///< (a body of revolution's other axis sign)
  bool screened_out = false;               ///< the pose failed the pre-screen
  bool pending = false;                    ///< a pose not seen when it ran, not verified yet (Matcher::verify)
  bool held = false;                       ///< its clique not searched yet (run when taken, see runGroups)
  std::vector<Pose> path;                  ///< ICP's pose after each step
  bool refound = false;                    ///< ICP came to an object already found (and stopped there)
  bool all_voters = false;                 ///< every member's candidates taken, not only the voters'
  int largest_clique = 0;                  ///< size of the first clique searched (0: none searched)
  Hypothesis hypothesis;                   ///< refined and scored (when the clique gave a pose that passed)
  float score_without_grazing = 0;         ///< the hypothesis's (Evidence::scoreWithoutGrazing)
  double vote_ms = 0, match_ms = 0, refine_ms = 0;  ///< the thread's time in each stage
};

/// Candidates kept per scene point: a body of revolution's votes do not spread over rings.
int candidatesPerPoint(const DetectionParams& p, const Orbits* orbits) {
  return orbits != nullptr ? std::min(p.candidates_per_point, p.revolution_candidates) : p.candidates_per_point;
}

/// The buffers and the outcome of one place in a batch (the outcome is kept until it is taken).
struct Slot {
  explicit Slot(const ModelDatabase& db, const DetectionParams& p, std::uint32_t max_list, const Orbits* orbits)
      : voter(db, candidatesPerPoint(p, orbits), max_list, p.candidate_spacing, p.weigh_rare_keys, orbits) {}
  Voter voter;
  std::vector<Correspondence> candidates;
  Points clique_model, clique_scene, clique_normals;
  std::vector<std::uint32_t> clique_ids;
  GroupOutcome outcome;
};

/// Everything a sub-group reads (nothing it writes is shared).
struct Matcher {
  const ModelDatabase& db;
  const DetectionParams& p;
  const PreparedModel& icp_model;   ///< ICP's share of the model points
  const PreparedModel& scored_model;  ///< all of them, for the score
  const PreparedScene& scene;
  const PointCloud& scan;
  const PointGrid& scan_grid;
  const PixelNeighbours* pixels;    ///< the scan's, for ICP's searches (null: the grid alone)
  const SceneEvidence& evidence;
  const NeighbourhoodVoter* local;  ///< the local votes (null: each sub-group votes, 4.3)
  const std::vector<char>& may_vote;  ///< with local votes, the points of voter_spacing
  const Orbits* orbits;             ///< a body of revolution's (null: matched point to point)
  const CyclicSymmetry* cyclic;     ///< a part of n-fold symmetry's (candidates: class members)
  /// True when a pose is another of an object already found (explain_score), or close to a
  /// clique pose already verified (tried_share): its clique is not verified again.
  std::function<bool(const Pose&)> seen;
  /// True when a pose is another of an object already found: ICP stops there (refound).
  std::function<bool(const Pose&)> found;

  /// Votes (4.3-4.4), clique (4.5), pose (4.6), pre-screen, ICP and score of one sub-group,
  /// with the scene points not yet removed: prepare(), then verify() when it asks for it.
  void run(std::span<const std::uint32_t> group, const std::vector<char>& removed, Slot& s, bool all_voters,
           const GroupOutcome* earlier = nullptr, ParallelVoter* parallel = nullptr) const {
    if (prepare(group, removed, s, all_voters, earlier, parallel)) verify(s);
  }

  /// Votes, clique and pose of one sub-group; true when its pose is to be verified (the outcome
  /// is then `pending`). A clique whose pose (or one of its alternatives) is seen() is not
  /// verified: it stays so when taken. The pose, ICP and score depend on the clique's pairs
  /// alone: when `earlier` (a run of the same sub-group with more points) verified the same
  /// clique, its verdict is taken instead of verifying again. `parallel`: votes with it instead
  /// of the slot's voter, on all cores (a sub-group run again on its own). `all_voters`: with
  /// local votes, the candidates of every member (which must all have voted), not only of the
  /// voters of voter_spacing.
  bool prepare(std::span<const std::uint32_t> group, const std::vector<char>& removed, Slot& s, bool all_voters,
               const GroupOutcome* earlier = nullptr, ParallelVoter* parallel = nullptr,
               const std::function<bool(const GroupOutcome&)>& hold = {}) const {
    GroupOutcome& out = s.outcome;
    out.members.clear();
    out.clique.clear();
    out.poses.clear();
    out.ran = out.screened_out = out.pending = out.refound = out.held = false;
    out.path.clear();
    out.all_voters = all_voters;
    out.largest_clique = 0;
    out.hypothesis = {};
    out.score_without_grazing = 0;
    out.vote_ms = out.match_ms = out.refine_ms = 0;
    for (const auto i : group)
      if (!removed[i]) out.members.push_back(i);
    if (out.members.size() < static_cast<std::size_t>(p.C_n)) return false;
    out.ran = true;
    const auto t_vote = Clock::now();
    s.candidates.clear();
    if (local) {
      // The second pass (retry_all_voters): nothing new when the other points have no candidate.
      if (all_voters && std::none_of(out.members.begin(), out.members.end(),
                                     [&](std::uint32_t i) { return may_vote[i] == 0 && !local->candidates(i).empty(); }))
        return false;
      for (const auto i : out.members)
        if (all_voters || may_vote[i] != 0)  // the others' votes, if any, are for the second pass
          for (const auto m : local->candidates(i)) s.candidates.push_back({i, m});
    } else if (parallel != nullptr) {
      parallel->vote(scene.points, scene.normals, out.members, s.candidates);  // the same pairs
    } else {
      s.voter.vote(scene.points, scene.normals, out.members, s.candidates);
    }
    const auto t_match = Clock::now();
    out.vote_ms = msSince(t_vote);
    if (hold && hold(out)) {  // its clique waits (see runGroups)
      out.held = true;
      return false;
    }
    const bool matched = match(s);
    out.match_ms = msSince(t_match);
    if (!matched) return false;
    if (p.verify && std::any_of(out.poses.begin(), out.poses.end(), seen)) return false;  // still seen when taken
    if (earlier != nullptr && !earlier->pending && earlier->clique == out.clique) {
      out.screened_out = earlier->screened_out;
      out.hypothesis = earlier->hypothesis;
      out.score_without_grazing = earlier->score_without_grazing;
      out.path = earlier->path;
      out.refound = earlier->refound;
      return false;
    }
    out.pending = true;
    return true;
  }

  /// Pre-screen, ICP and score of a pending outcome's pose.
  void verify(Slot& s) const {
    const auto t_refine = Clock::now();
    screenRefineScore(s);
    s.outcome.pending = false;
    s.outcome.refine_ms = msSince(t_refine);
  }

 private:
  /// Clique and closed-form pose (a refused mirror-image clique gives way to the next, up to
  /// mirror_retries times); false when there is none. The pose goes into the outcome.
  bool match(Slot& s) const {
    const Points& model = db.model().points;
    if (s.candidates.size() < static_cast<std::size_t>(p.C_n)) return false;
    Graph graph = orbits != nullptr
                      ? revolutionConsistencyGraph(s.candidates, scene.points, scene.normals, *orbits, p.e_gmax,
                                                   p.revolution_angle_tolerance)
                  : cyclic != nullptr
                      ? cyclicConsistencyGraph(s.candidates, scene.points, scene.normals, db.model(), *cyclic, p.e_gmax,
                                               p.revolution_angle_tolerance)
                      : consistencyGraph(s.candidates, scene.points, model, p.e_gmax);
    for (int retry = 0;; ++retry) {
      const CliqueResult clique = maximumClique(graph, p.clique_work_limit);
      if (retry == 0) s.outcome.largest_clique = static_cast<int>(clique.vertices.size());
      if (clique.vertices.size() < static_cast<std::size_t>(p.C_n)) return false;
      if (fitClique(s, clique)) return true;
      // A mirror image (or a degenerate set): the next largest clique without its pairs.
      if (orbits != nullptr || retry >= p.mirror_retries) return false;
      graph.isolate(clique.vertices);
    }
  }

  /// The closed-form pose of a clique's pairs into the outcome; false when there is none.
  bool fitClique(Slot& s, const CliqueResult& clique) const {
    const Points& model = db.model().points;
    s.clique_scene.clear();
    for (const int v : clique.vertices) s.clique_scene.push_back(scene.points[s.candidates[v].scene]);
    PoseFit fit;
    std::vector<PoseFit> fits;  // a body of revolution's: the first, then the other axis sign, if any
    if (orbits != nullptr) {  // the axis of the clique's orbits; the other axis sign, if any, kept for the scan
      s.clique_normals.clear();
      s.clique_ids.clear();
      for (const int v : clique.vertices) {
        s.clique_normals.push_back(scene.normals[s.candidates[v].scene]);
        s.clique_ids.push_back(s.candidates[v].model);
      }
      fits = solveRevolutionPoses(*orbits, s.clique_ids, model, s.clique_scene, s.clique_normals);
      if (!fits.empty()) fit = fits.front();
    } else {
      s.clique_model.clear();
      for (const int v : clique.vertices) s.clique_model.push_back(model[s.candidates[v].model]);
      fit = cyclic != nullptr ? solveCyclicPose(*cyclic, s.clique_model, s.clique_scene)
                              : solvePose(s.clique_model, s.clique_scene);
    }
    if (!fit.ok) return false;
    for (const int v : clique.vertices) s.outcome.clique.push_back(s.candidates[v]);
    s.outcome.poses.push_back(fit.pose);
    for (std::size_t f = 1; f < fits.size(); ++f) s.outcome.poses.push_back(fits[f].pose);
    s.outcome.hypothesis.detection = Detection{fit.pose, 0.0f, static_cast<int>(clique.vertices.size()), fit.rms};
    return true;
  }

  /// Pre-screen, ICP and score of the outcome's pose.
  void screenRefineScore(Slot& s) const {
    Hypothesis& h = s.outcome.hypothesis;
    Detection& det = h.detection;
    // A pose of the second pass (retry_all_voters) is screened as it will be judged: by its score
    // without grazing points, against retry_min_score.
    const bool second_pass = s.outcome.all_voters;
    const float gate = second_pass ? std::max(p.min_score, p.retry_min_score) : p.min_score;
    auto prescore = [&](const Pose& pose) {
      const Evidence e = evidence.evaluate(pose, icp_model, p.icp_max_distance, 0.0f);
      return second_pass ? e.scoreWithoutGrazing() : e.score();
    };
    if (p.verify) {  // the scan decides between a clique's poses, and screens out one far from it
      const auto alternatives = std::span<const Pose>(s.outcome.poses).subspan(1);
      float best = p.prescreen || !alternatives.empty() ? prescore(det.pose) : 1.0f;
      for (const Pose& other : alternatives)
        if (const float score = prescore(other); score > best) {
          best = score;
          det.pose = other;
        }
      if (p.prescreen && best < gate) {
        if (p.prescreen_retry_steps > 0 && best >= p.prescreen_retry_share * gate) {
          // Near the scan but a few mm off: a few coarse ICP steps, and another look.
          const IcpParams nudge{p.prescreen_retry_steps, p.icp_max_distance, p.verify_tolerance, p.viewpoint, {}, nullptr, pixels};
          const Pose moved = refinePose(det.pose, icp_model, scan.points, scan_grid, nudge);
          if (const float score = prescore(moved); score >= gate) {
            best = score;
            det.pose = moved;
          }
        }
        if (best < gate) {
          s.outcome.screened_out = true;  // far from the scan even at the ICP gate: not worth refining
          return;
        }
      }
    }
    if (p.refine) {
      IcpParams icp{p.icp_iterations, p.icp_max_distance, p.verify_tolerance, p.viewpoint, {}, nullptr, pixels};
      if (p.verify && p.refound_share > 0) {  // see take() in Detector::detect
        icp.path = &s.outcome.path;
        icp.stop = found;
      }
      det.pose = refinePose(det.pose, icp_model, scan.points, scan_grid, icp);
      if (p.verify && p.refound_share > 0 && found(det.pose)) {
        s.outcome.refound = true;
        return;
      }
    }
    const Evidence e = evidence.evaluate(det.pose, scored_model, p.verify_tolerance,
                                         db.model().sample_radius, &h.support);
    det.score = e.score();
    s.outcome.score_without_grazing = e.scoreWithoutGrazing();
    std::sort(h.support.begin(), h.support.end());
    h.support.erase(std::unique(h.support.begin(), h.support.end()), h.support.end());
  }
};

}  // namespace

Detector::Detector(const ModelDatabase& db, const DetectionParams& params)
    : db_(db), params_(params), model_grid_(db.model().points, std::max(params.sigma_dist, 0.1f * db.model().diameter)),
      icp_model_([&] {
        OrientedPoints share = evenShare(db.model().points, db.model().normals, static_cast<std::size_t>(std::max(0, params.icp_model_points)));
        return PreparedModel(std::move(share.points), std::move(share.normals));
      }()),
      scored_model_(db.model().points, db.model().normals) {
  validate(params_);
  if (params_.plane_min_area == 0) params_.plane_min_area = boundingFaceArea(db.model().points);
  const Points& m = db.model().points;
  model_centroid_ = Vec3::Zero();
  for (const Vec3& p : m) model_centroid_ += p;
  model_centroid_ /= static_cast<float>(m.size());
  for (const Vec3& p : m) model_radius_ = std::max(model_radius_, (p - model_centroid_).norm());
  bounds(m, model_lo_, model_hi_);
  if (params_.use_revolution)
    if (const auto axis = findRevolutionAxis(db.model()))
      orbits_ = makeOrbits(db, *axis, db.model().sample_radius);
  if (params_.use_cyclic_symmetry && !orbits_)
    if ((cyclic_ = findCyclicSymmetry(db.model()))) classes_ = makeCyclicClasses(db, *cyclic_);
}

bool Detector::nearModel(const Vec3& x, float distance) const {
  // Most points of a neighbouring part's pose, or of the scene around a found part, lie far
  // outside the model's box: no grid query for them.
  if ((x.array() < model_lo_.array() - distance).any() || (x.array() > model_hi_.array() + distance).any()) return false;
  return model_grid_.anyWithin(x, distance);
}

bool Detector::samePose(const Pose& a, const Pose& b, float share) const {
  const float tolerance = share * 0.1f * db_.model().diameter;  // the usual correctness radius (ADD < 0.1 d)
  if ((a * model_centroid_ - b * model_centroid_).squaredNorm() > tolerance * tolerance) return false;
  if (orbits_) {  // the turn about the axis is free: the axis's end moves model_radius_ times its change
    const Vec3& axis = orbits_->axis.direction;
    return model_radius_ * (a.linear() * axis - b.linear() * axis).norm() <= tolerance;
  }
  // A turn by angle t moves a point at distance r from its axis by 2 r sin(t / 2); for a part of
  // n-fold symmetry, the least turn from a to one of b's n images.
  const Eigen::Matrix3f a_to_b = a.linear().transpose() * b.linear();
  float turn = Eigen::AngleAxisf(a_to_b).angle();
  if (cyclic_)
    for (int k = 1; k < cyclic_->order; ++k)
      turn = std::min(turn, Eigen::AngleAxisf(a_to_b * cyclic_->turn(k).linear()).angle());
  return 2.0f * model_radius_ * std::sin(0.5f * turn) <= tolerance;
}

bool Detector::mostlyOverlaps(const Pose& a, const Pose& b) const {
  if ((a * model_centroid_ - b * model_centroid_).norm() > 2 * model_radius_) return false;
  const Points& model = icp_model_.points();  // an even share: the same fraction as all points
  const Pose b_from_a = b.inverse() * a;
  const float near_distance = 0.1f * db_.model().diameter;  // the usual correctness radius (ADD < 0.1 d)
  const std::size_t half = model.size() / 2;
  std::size_t near = 0, far = 0;
  for (const Vec3& m : model) {  // stops as soon as the answer is known
    if (nearModel(b_from_a * m, near_distance)) {
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
    // Another pose of an object already found (a near-symmetric flip, say) shares some of its
    // support; a pose that shares almost none (under a twentieth) explains other points: a
    // neighbour, however close (thin caps stacked rim to rim overlap in that measure).
    if (20 * taken >= h.support.size() &&
        std::any_of(kept.begin(), kept.end(), [&](const Detection& k) { return mostlyOverlaps(h.detection.pose, k.pose); }))
      continue;
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

  // The scan's grid (one core) is built while the other core sub-samples, indexes a depth
  // image's points by pixel and starts on the normals whose neighbours the pixels give (most of
  // them; the first core joins in when the grid is done); the rest are found through the grid,
  // there and then once it is built (the few met before, after). A depth image's cells are
  // sized from its pixel neighbours' spacing (no first grid to estimate it); any size gives the
  // same answers.
  std::optional<PointGrid> grid;
  std::optional<PixelNeighbours> pixels;
  std::vector<std::uint32_t> chosen, deferred;
  Points normals;
  // The normals that need Eigen's iterative solver wait for the plane search to ask for them:
  // most lie on the bin's floor and walls, which it removes (ipd8-16: 1908 of 4104 never asked for).
  std::vector<PendingFit> fits;
  std::vector<PendingFit>* late = p.remove_planes ? &fits : nullptr;
  std::atomic<const PointGrid*> grid_ready{nullptr};  // the pixels' misses go to the grid once it is built
  tbb::parallel_invoke([&] { grid_ready.store(&grid.emplace(scan.points, 2.0f * pixelSpacing(scan)), std::memory_order_release); },
                       [&] {
                         chosen = subsampleScene(scan.points, p);
                         pixels.emplace(scan);
                         normals = pixelNormals(*pixels, scan.points, chosen, p.k_normals, p.viewpoint, deferred, &grid_ready, late);
                       });
  const PointGrid& scan_grid = *grid;
  finishNormals(scan_grid, scan.points, chosen, deferred, p.k_normals, p.viewpoint, normals, late);
  PreparedScene scene = orientedScene(scan.points, chosen, normals);
  result.sampled_points = scene.points.size();
  // The bin's planes and the score's view of the scan side by side, then the sub-groups and the
  // local voters' setup.
  std::vector<Plane> planes;  // the bin's
  std::optional<SceneEvidence> evidence_slot;
  auto removePlanes = [&] {
    if (!p.remove_planes) return;
    if (auto lazy = withoutPlanes(std::move(scene), p, planes, chosen, fits)) {
      scene = std::move(*lazy);
      return;
    }
    for (std::size_t i = 0; i < chosen.size(); ++i)  // a pending fit was degenerate: all of them now, and again
      if (std::isnan(normals[i].x()) && !finishPending(fits[i], scan.points[chosen[i]], p.viewpoint, normals[i]))
        normals[i] = Vec3::Zero();
    planes.clear();
    PreparedScene every = orientedScene(scan.points, chosen, normals);
    result.sampled_points = every.points.size();
    scene = *withoutPlanes(std::move(every), p, planes, chosen, fits);  // nothing pending: never empty
  };
  tbb::parallel_invoke(removePlanes,
                       [&] {
                         evidence_slot.emplace(scan.points, scan_grid, p.viewpoint, &*pixels);
                         evidence_slot->setGrazingAngle(p.grazing_angle);
                       });
  evidence_slot->setBackground(std::move(planes), std::min(p.verify_tolerance, p.plane_tolerance));
  std::vector<PendingFit>().swap(fits);  // not needed any more: its memory back before the votes (the pixels stay for ICP)
  result.plane_points = result.sampled_points - scene.points.size();
  std::vector<std::vector<std::uint32_t>> groups;
  const auto max_list = static_cast<std::uint32_t>(p.max_key_share * static_cast<float>(model.size()));
  // Local votes (each point votes once, when a sub-group first needs it; see NeighbourhoodVoter).
  std::unique_ptr<NeighbourhoodVoter> local;
  std::vector<char> may_vote;  // the reference points of voter_spacing (all without it)
  double vote_setup_ms = 0;
  tbb::parallel_invoke(
      [&] { groups = makeSubGroups(scene.points, p.eta, p.r, static_cast<std::size_t>(p.C_n)); },
      [&] {
        if (!p.local_votes) return;
        const auto t_setup = Clock::now();
        std::vector<std::uint32_t> partners;
        if (p.partner_spacing > 0) partners = voxelSubsample(scene.points, p.partner_spacing);
        local = std::make_unique<NeighbourhoodVoter>(db_, scene.points, scene.normals, p.vote_radius,
                                                     candidatesPerPoint(p, votingOrbits()), max_list, partners, p.candidate_spacing,
                                                     p.weigh_rare_keys, votingOrbits());
        may_vote.assign(scene.points.size(), p.voter_spacing > 0 ? 0 : 1);
        if (p.voter_spacing > 0)
          for (const auto i : voxelSubsample(scene.points, p.voter_spacing)) may_vote[i] = 1;
        vote_setup_ms = msSince(t_setup);
      });
  const SceneEvidence& evidence = *evidence_slot;
  result.subgroups = groups.size();
  result.timing.preprocess_ms = msSince(t0) - vote_setup_ms;  // the voters' setup counts as voting
  double vote_ms = vote_setup_ms;  // the setup, then the local votes of each batch

  std::vector<Pose> found;  // poses of the detections scoring at least explain_score, or removal_score
  std::vector<Pose> tried;  // the closed-form poses of the cliques verified (empty when tried_share is 0)
  auto refound = [&](const Pose& pose) {
    return p.refound_share > 0 &&
           std::any_of(found.begin(), found.end(), [&](const Pose& f) { return samePose(pose, f, p.refound_share); });
  };
  auto seen = [&](const Pose& pose) {
    return std::any_of(found.begin(), found.end(), [&](const Pose& f) { return samePose(pose, f); }) || std::any_of(tried.begin(), tried.end(), [&](const Pose& t) { return samePose(pose, t, p.tried_share); });
  };
  const Matcher matcher{db_,      p,        icp_model_,  scored_model_, scene,    scan,
                        scan_grid, &*pixels, evidence,    local.get(),   may_vote, orbits(),
                        cyclicSymmetry(), seen, refound};
  std::vector<char> removed(scene.points.size(), 0);
  std::vector<Hypothesis> hypotheses;
  int confident = 0;  // detections that removed their points
  bool enough = false;

  // The outcome of a sub-group, taken in the sub-groups' order: the same counts, hypotheses
  // and removals as running them one after the other.
  auto take = [&](GroupOutcome& o) {
    if (!o.ran) return;
    ++result.subgroups_run;
    if (o.clique.empty()) return;
    if (p.verify && std::any_of(o.poses.begin(), o.poses.end(), seen)) return;  // that object again
    ++result.hypotheses;
    if (p.tried_share > 0) tried.insert(tried.end(), o.poses.begin(), o.poses.end());
    if (o.screened_out) return;
    ++result.refined;
    // ICP brought the pose to an object found before this sub-group's turn: that object again.
    // When it ran, fewer objects may have been found (a batch's run side by side); its path is
    // looked at again, so the outcome is what running one after the other gives.
    if (p.verify && (o.refound || std::any_of(o.path.begin(), o.path.end(), refound))) {
      ++result.refound;
      return;
    }
    const Detection det = o.hypothesis.detection;
    if (p.verify && det.score < p.min_score) return;
    if (p.verify && o.all_voters && o.score_without_grazing < p.retry_min_score) return;  // see retry_min_score
    const bool remove = det.score >= p.removal_score;
    if (remove || det.score >= p.explain_score) found.push_back(det.pose);
    if (remove) {  // 5.2.6, eq. 39: the scene points within sigma_dist of the posed model are removed
      const Pose inverse = det.pose.inverse();
      const Vec3 centre = det.pose * model_centroid_;
      const float reach = model_radius_ + p.sigma_dist;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, scene.points.size(), 1024), [&](const auto& range) {
        for (std::size_t i = range.begin(); i < range.end(); ++i) {  // each point on its own: any thread count
          if (removed[i] || (scene.points[i] - centre).squaredNorm() > reach * reach) continue;
          if (nearModel(inverse * scene.points[i], p.sigma_dist)) removed[i] = 1;
        }
      });
    }
    hypotheses.push_back(std::move(o.hypothesis));
    if (!remove) return;  // not sure enough to take its points away
    if (p.max_instances > 0 && ++confident >= p.max_instances) enough = true;  // enough sure detections
  };

  // Sub-groups run a batch at a time, side by side, on the scene as it stands at the batch's
  // start; their outcomes are then taken in order. A sub-group some of whose points a detection
  // of the batch has removed runs again, then and there, on the points left (its earlier
  // verdict kept when the clique is the same): what is taken is what the sub-groups give one
  // after the other, whatever the thread count.
  const std::size_t threads = std::min<std::size_t>(static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency())),
                                                    tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  const std::size_t batch = 4 * std::max<std::size_t>(1, threads);
  std::vector<Slot> slots;
  for (std::size_t k = 0; k < batch; ++k) slots.emplace_back(db_, p, max_list, votingOrbits());
  GroupOutcome earlier;
  ParallelVoter parallel(db_, candidatesPerPoint(p, votingOrbits()), max_list, p.candidate_spacing, p.weigh_rare_keys,
                         votingOrbits());  // for those run again
  std::vector<std::uint32_t> voters;
  double work_ms = 0, group_vote_ms = 0, group_match_ms = 0, group_refine_ms = 0;  // see below
  std::vector<int> largest_clique(groups.size(), 0);  // each sub-group's first clique (for the second pass)
  // The batch's pending poses to verify side by side. A pose near one that a sub-group earlier
  // in the batch found is most likely that object again: once the earlier one is taken, its
  // points are removed (the sub-group runs again) or its pose is found or tried (this one is
  // seen). Its verification waits until it is taken, and is skipped then if so. On ipd8-16 such
  // verifications were half of the work that the batch's later removals wasted.
  std::vector<std::size_t> to_verify;  // slots
  // A sub-group's clique search waits until it is taken when a sub-group earlier in the batch,
  // already prepared, has a pose to verify from a clique of at least 2 C_n pairs on some of its
  // points: such a pose is most often a part found, whose points are then removed, and this
  // sub-group runs again anyway (on ipd8-16 such first runs spent 5.6 ms on cliques; with any
  // clique size, cap-16's low-scoring poses held 20 sub-groups that then ran one at a time).
  // Which earlier ones are prepared in time varies from run to run; the outcome does not: a
  // held sub-group whose points all remain runs when taken, on the same points.
  std::unique_ptr<std::atomic<bool>[]> prepared(new std::atomic<bool>[batch]);
  auto heldBehind = [&](const GroupOutcome& o, std::size_t slot) {
    if (!p.verify) return false;
    for (std::size_t e = 0; e < slot; ++e) {
      if (!prepared[e].load(std::memory_order_acquire)) continue;
      const GroupOutcome& before = slots[e].outcome;
      if (before.pending && before.clique.size() >= 2 * static_cast<std::size_t>(p.C_n) && std::any_of(before.clique.begin(), before.clique.end(), [&](const Correspondence& c) {
            return std::binary_search(o.members.begin(), o.members.end(), c.scene);
          }))
        return true;
    }
    return false;
  };
  auto deferPosesNearEarlier = [&](std::size_t next, std::size_t end) {
    to_verify.clear();
    for (std::size_t g = next; g < end; ++g) {
      const GroupOutcome& o = slots[g - next].outcome;
      if (!o.pending) continue;
      const auto near = [&](const Pose& pose) {
        return std::any_of(slots.begin(), slots.begin() + static_cast<long>(g - next), [&](const Slot& e) {
          return std::any_of(e.outcome.poses.begin(), e.outcome.poses.end(), [&](const Pose& q) { return samePose(pose, q); });
        });
      };
      if (!p.verify || !std::any_of(o.poses.begin(), o.poses.end(), near)) to_verify.push_back(g - next);
    }
  };
  // The sub-groups of `order`, a batch at a time (see above).
  auto runGroups = [&](const std::vector<std::uint32_t>& order, bool all_voters) {
    for (std::size_t next = 0; next < order.size() && !enough; next += batch) {
      const std::size_t end = std::min(order.size(), next + batch);
      if (local) {  // the batch's voters that have not voted yet vote first, all together
        const auto t_vote = Clock::now();
        voters.clear();
        for (std::size_t g = next; g < end; ++g)
          appendLiveVoters(groups[order[g]], removed, may_vote, all_voters, static_cast<std::size_t>(p.C_n), voters);
        local->vote(voters);
        vote_ms += msSince(t_vote);
      }
      const auto t_work = Clock::now();
      // Isolated: a thread waiting inside a nested loop (graph, ICP) takes up no other sub-group
      // meanwhile, which would hold up its own.
      for (std::size_t g = next; g < end; ++g) prepared[g - next].store(false, std::memory_order_relaxed);
      std::atomic<std::size_t> ticket{next};  // the batch's sub-groups started in order
      tbb::parallel_for(std::size_t{0}, threads, [&](std::size_t) {
        for (std::size_t g; (g = ticket.fetch_add(1)) < end;) {
          Slot& slot = slots[g - next];
          const auto hold = [&](const GroupOutcome& o) { return heldBehind(o, g - next); };
          tbb::this_task_arena::isolate([&] { matcher.prepare(groups[order[g]], removed, slot, all_voters, nullptr, nullptr, hold); });
          prepared[g - next].store(true, std::memory_order_release);
        }
      });
      deferPosesNearEarlier(next, end);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, to_verify.size(), 1), [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t k = range.begin(); k < range.end(); ++k)
          tbb::this_task_arena::isolate([&] { matcher.verify(slots[to_verify[k]]); });
      }, tbb::simple_partitioner());
      work_ms += msSince(t_work);
      for (std::size_t g = next; g < end && !enough; ++g) {
        Slot& slot = slots[g - next];
        if (std::any_of(slot.outcome.members.begin(), slot.outcome.members.end(), [&](std::uint32_t i) { return removed[i] != 0; })) {
          const auto t_again = Clock::now();
          std::swap(earlier, slot.outcome);
          matcher.run(groups[order[g]], removed, slot, all_voters, &earlier, &parallel);
          work_ms += msSince(t_again);
        } else if (slot.outcome.held) {
          const auto t_late = Clock::now();  // held, and its points all still there: it runs now
          matcher.run(groups[order[g]], removed, slot, all_voters, nullptr, &parallel);
          work_ms += msSince(t_late);
        } else if (slot.outcome.pending && !std::any_of(slot.outcome.poses.begin(), slot.outcome.poses.end(), seen)) {
          const auto t_late = Clock::now();  // deferred, and not the object found meanwhile after all
          matcher.verify(slot);
          work_ms += msSince(t_late);
        }
        group_vote_ms += slot.outcome.vote_ms;
        group_match_ms += slot.outcome.match_ms;
        group_refine_ms += slot.outcome.refine_ms;
        if (!all_voters) largest_clique[order[g]] = slot.outcome.largest_clique;
        take(slot.outcome);
      }
    }
  };
  const auto t_match = Clock::now();
  std::vector<std::uint32_t> order(groups.size());
  std::iota(order.begin(), order.end(), 0u);
  runGroups(order, false);
  if (p.retry_all_voters && local && p.voter_spacing > 0) {
    // Second pass: the sub-groups whose largest clique came close to C_n (retry_min_clique) and
    // that still have C_n points, with every point voting (most of the scene is removed by now:
    // few sub-groups, few new voters). One that reached C_n but gave no pose (a mirror image
    // refused) is not run again: on ipd0-16 those were a quarter of the retried sub-groups,
    // and found nothing. A first clique under C_n is a sub-group that gave none; one that did
    // not run had fewer than C_n points, and has no more now.
    order.clear();
    const auto live = [&](std::uint32_t g) {
      return std::count_if(groups[g].begin(), groups[g].end(), [&](std::uint32_t i) { return removed[i] == 0; });
    };
    for (std::uint32_t g = 0; g < groups.size(); ++g)
      if (largest_clique[g] >= p.retry_min_clique && largest_clique[g] < p.C_n && live(g) >= p.C_n)
        order.push_back(g);
    result.subgroups_retried = order.size();
    runGroups(order, true);
  }
  const double group_ms = group_vote_ms + group_match_ms + group_refine_ms;
  const double to_wall = group_ms > 0 ? work_ms / group_ms : 0.0;
  const double loop_ms = msSince(t_match);
  result.timing.vote_ms = vote_ms + group_vote_ms * to_wall;
  result.timing.refine_ms = group_refine_ms * to_wall;
  result.timing.match_ms = loop_ms - (vote_ms - vote_setup_ms) - group_vote_ms * to_wall - result.timing.refine_ms;
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
