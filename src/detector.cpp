// Online recognition (thesis chapter 5): the redundant sub-group pipeline as a sequence of stages.
#include <binpose/detector.hpp>

#include "correlated_noise.hpp"
#include "duplicates.hpp"
#include "face_hypotheses.hpp"
#include "face_slide.hpp"
#include "flying_pixels.hpp"
#include "group_schedule.hpp"
#include "left_points.hpp"
#include "local_votes.hpp"
#include "model_shape.hpp"
#include "near_flips.hpp"
#include "part_symmetry.hpp"
#include "reseat.hpp"
#include "scan_preparation.hpp"
#include "stopwatch.hpp"
#include "subgroup_matcher.hpp"

#include <binpose/planes.hpp>

#include <algorithm>
#include <fmt/format.h>
#include <iterator>
#include <numeric>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

namespace binpose {
namespace {

/// Poses Detector::check judges in one call: each takes an ICP run (a millisecond or so), and a
/// file of millions is a mistake, not a question.
constexpr std::size_t kMostCheckedPoses = 10000;
/// The near-model grid's cell: the removal distance, and at least the same-place tolerance.
constexpr float kShapeCellShare = 0.1f;
/// A flat face of the model is tried from a quarter of its diameter squared (face_hypotheses).
constexpr float kLeastFaceShare = 0.25f;
/// The pre-screen (Matcher::prescore) scores every clique pose, its alternatives and the turned
/// starts at ICP's gate on every kPrescoreStride-th of ICP's model points. It only decides which
/// poses go on to ICP and the full score: on the simulated and unseen bins every second point
/// finds as many copies (within one or two a sensor) in 5-10 % less time on the noisy 16-part
/// bins (docs/design.md, Pre-screen).
constexpr std::size_t kPrescoreStride = 2;
/// No scan in millimetres has a point this far from its origin (100 km): such a file is not a
/// scan in mm, and the grids over it would overflow.
constexpr float kFarthestCoordinate = 1e8f;
/// Detections are polished (polishPose) on scans measured at least this noisy, mm (1 sigma): on
/// the structured-light bins (1.3 mm) the model-to-scan ICP's median centroid error is 1.35 mm
/// and polishing halves it; on the industrial ones (0.2 mm) it is 0.14 mm, and 0.06 mm on the
/// clean ones, where polishing gains a few hundredths of a millimetre for a tenth more time.
/// Under it a scan is quiet: weak poses are only turned over (reseat.hpp), and the points left
/// vote again (left_points.hpp), which costs more on a noisier scan, where less is explained.
constexpr float kPolishNoise = 0.5f;

/// Error naming the first point of `scan` beyond kFarthestCoordinate (non-finite ones are skipped).
void checkCoordinates(const PointCloud& scan) {
  for (const Vec3& p : scan.points)
    if (p.allFinite() && p.cwiseAbs().maxCoeff() > kFarthestCoordinate)
      throw Error(fmt::format("scan point ({:.3g}, {:.3g}, {:.3g}) lies beyond {:.0g} mm of the origin: not a scan in mm", p.x(),
                              p.y(), p.z(), kFarthestCoordinate));
}

/// The sub-groups whose largest clique came close to C_n (retry_min_clique) and that still have
/// C_n points: the second pass runs them with every point voting. One that reached C_n but gave
/// no pose (a mirror image refused) is not run again; one that did not run had fewer than C_n
/// points, and has no more now.
std::vector<std::uint32_t> groupsToRetry(const std::vector<std::vector<std::uint32_t>>& groups,
                                         const std::vector<int>& largest_clique, const std::vector<char>& removed,
                                         const StageSettings& p) {
  std::vector<std::uint32_t> order;
  const auto live = [&](std::uint32_t g) {
    return std::count_if(groups[g].begin(), groups[g].end(), [&](std::uint32_t i) { return removed[i] == 0; });
  };
  for (std::uint32_t g = 0; g < groups.size(); ++g)
    if (largest_clique[g] >= p.retry_min_clique && largest_clique[g] < p.C_n && live(g) >= p.C_n) order.push_back(g);
  return order;
}

/// Each detection's pose polished (polishPose) against the full scan, with the normals of the
/// voting points within one sample spacing; in parallel, each its own, so the result is the same
/// whatever the threads.
void polishAll(std::vector<Detection>& detections, const PreparedModel& model, const PointCloud& scan,
               const PreparedScan& prepared) {
  const StageSettings& p = prepared.params;
  const PreparedScene& scene = prepared.scene;
  const PointGrid oriented_grid(scene.points);
  const PolishScan polish_scan{scan.points, *prepared.grid, scene.points, scene.normals, oriented_grid,
                               1.0f / std::sqrt(p.rho_sub)};
  PolishParams params;
  params.max_distance = p.verify_tolerance;
  params.viewpoint = p.viewpoint;
  const PointGrid model_grid(model.points(), params.max_distance);
  tbb::parallel_for(std::size_t{0}, detections.size(), [&](std::size_t i) {
    detections[i].pose = polishPose(detections[i].pose, model, model_grid, polish_scan, params);
  });
}

/// The sub-groups' wall time shared among voting, matching and refinement in proportion to
/// their threads' time in each.
void shareTimes(const ScheduleTimes& t, double setup_ms, double loop_ms, DetectionTiming& timing) {
  const double group_ms = t.vote_ms + t.match_ms + t.refine_ms;
  const double to_wall = group_ms > 0 ? t.work_ms / group_ms : 0.0;
  timing.vote_ms = setup_ms + t.local_vote_ms + t.vote_ms * to_wall;
  timing.refine_ms = t.refine_ms * to_wall;
  timing.match_ms = loop_ms - t.local_vote_ms - t.vote_ms * to_wall - timing.refine_ms;
}

/// The counts of each stage into the result.
void countStages(const PreparedScan& prepared, std::size_t groups, const MatchState& state, DetectionResult& result) {
  result.sampled_points = prepared.sampled_points;
  result.noise_mm = prepared.noise.sigma;
  result.k_normals = prepared.params.k_normals;
  result.normal_radius = prepared.params.normal_radius;
  const StageSettings& p = prepared.params;
  result.least_score = p.verify ? std::max(p.min_score, p.report_score) : 0.0f;  // no score without verification
  result.plane_points = prepared.plane_points;
  result.subgroups = groups;
  result.subgroups_run = state.subgroups_run;
  result.hypotheses = state.hypotheses_made;
  result.refined = state.refined;
  result.refound = state.refound;
}

/// The scan without its points that hold no measurement (isMeasured: NaN, or the origin as a
/// depth camera's SDK writes a pixel without a depth); empty when every point holds one. The
/// points kept keep their order, normals and pixels. Left in, a few thousand copies of the origin
/// are a dense cluster that no pixel lattice, noise estimate or neighbour search expects.
std::optional<PointCloud> withoutUnmeasured(const PointCloud& scan) {
  if (std::all_of(scan.points.begin(), scan.points.end(), isMeasured)) return std::nullopt;
  PointCloud kept = scan;
  const bool normals = scan.hasNormals(), pixels = scan.pixel.size() == scan.size();
  std::size_t n = 0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!isMeasured(scan.points[i])) continue;
    kept.points[n] = scan.points[i];
    if (normals) kept.normals[n] = scan.normals[i];
    if (pixels) kept.pixel[n] = scan.pixel[i];
    ++n;
  }
  kept.points.resize(n);
  if (normals) kept.normals.resize(n);
  if (pixels) kept.pixel.resize(n);
  return kept;
}

/// A scan made ready for matching: points without a measurement dropped, depths copied over
/// blocks of pixels thinned out, flying pixels dropped, then sub-sampled, oriented, measured and
/// its planes found (prepareScan).
struct ReadyScan {
  std::optional<PointCloud> measured, thinned, cleaned;
  const PointCloud* scan = nullptr;  ///< the cloud matched: cleaned, else thinned, else the input
  std::size_t flying = 0;            ///< flying pixels dropped
  int pixel_stride = 1;
  PreparedScan prepared;
};

void readyScan(const PointCloud& input, const StageSettings& settings, ReadyScan& out) {
  out.measured = withoutUnmeasured(input);
  const PointCloud& measured = out.measured ? *out.measured : input;
  checkCoordinates(measured);
  out.thinned = thinnedToIndependentNoise(measured, settings, out.pixel_stride);
  const PointCloud& kept = out.thinned ? *out.thinned : measured;
  out.cleaned = withoutFlyingPixels(kept, settings);
  out.scan = out.cleaned ? &*out.cleaned : &kept;
  out.flying = kept.size() - out.scan->size();
  prepareScan(*out.scan, settings, out.prepared);
}

/// `pose` refined as verification refines a clique's pose, scored, and judged by each of its
/// tests, as a clique's pose and as a laid one; under `least_score` counts as Refusal::score.
PoseCheck checkedPose(const Matcher& m, const ModelShape& shape, const Pose& pose, float least_score) {
  PoseCheck c;
  c.refined = m.p.refine ? refinePose(pose, m.icp_model, m.scan.points, m.scan_grid, m.icpParams(m.p.icp_iterations)) : pose;
  c.moved_mm = (c.refined * shape.centroid() - pose * shape.centroid()).norm();
  std::vector<std::uint32_t> support;
  c.evidence = m.scoredEvidence(c.refined, support);
  c.score = c.evidence.score();
  c.visible_support = c.evidence.visibleSupport();
  const auto judged = [&](bool laid) {
    const Refusal r = m.refusal(c.refined, c.score, c.evidence, support, laid);
    return r == Refusal::none && c.score < least_score ? Refusal::score : r;
  };
  c.as_found = judged(false);
  c.as_laid = judged(true);
  return c;
}

/// The settings validated, a plane_min_area of 0 resolved to the model's largest flat face.
std::unique_ptr<const StageSettings> checkedSettings(const StageSettings& settings, const OrientedModel& model) {
  validateStages(settings);
  auto s = std::make_unique<StageSettings>(settings);
  if (s->plane_min_area == 0) s->plane_min_area = boundingFaceArea(model.points);
  return s;
}

}  // namespace

Detector::Detector(const ModelDatabase& db, const DetectionParams& params)
    : Detector(db, stageSettings(params, db.model().diameter)) {}

Detector::Detector(const ModelDatabase& db, const StageSettings& settings)
    : db_(db),
      settings_(checkedSettings(settings, db.model())),
      icp_model_(preparedShare(db.model().points, db.model().normals, static_cast<std::size_t>(settings_->icp_model_points))),
      prescore_model_(preparedShare(icp_model_.points(), icp_model_.normals(), icp_model_.points().size() / kPrescoreStride)),
      scored_model_(db.model().points, db.model().normals) {
  const OrientedModel& model = db.model();
  symmetry_ = std::make_unique<const PartSymmetry>(db, *settings_);
  shape_ = std::make_unique<const ModelShape>(model.points, model.diameter,
                                              std::max(settings_->sigma_dist, kShapeCellShare * model.diameter), icp_model_.points(),
                                              orbits() != nullptr ? &orbits()->axis : nullptr, cyclicSymmetry());
  // A face counts from a quarter of the part's diameter squared (a gear's or a plate's side).
  const float per_point = model.area > 0 && !model.points.empty() ? static_cast<float>(model.area / static_cast<double>(model.points.size()))
                                                                  : model.sample_radius * model.sample_radius;
  faces_ = std::make_unique<const std::vector<ModelFace>>(
      settings_->face_hypotheses ? flatFaces(model.points, model.normals, model.sample_radius, per_point,
                                             kLeastFaceShare * kLeastFaceShare * model.diameter * model.diameter,
                                             orbits() != nullptr ? &orbits()->axis.direction : nullptr)
                                 : std::vector<ModelFace>{});
  if (settings_->reseat_weak && settings_->flip_weak) {
    flips_ = nearFlips(icp_model_.points(), icp_model_.normals(), *shape_);
    quiet_flips_ = withFaceFlips(flips_, *faces_, *shape_);
  }
}

Detector::~Detector() = default;
const Orbits* Detector::orbits() const { return symmetry_->orbits(); }
const CyclicSymmetry* Detector::cyclicSymmetry() const { return symmetry_->cyclic(); }
const DetectionParams& Detector::params() const { return *settings_; }
Detector::Detector(Detector&&) noexcept = default;

DetectionResult Detector::detect(const PointCloud& input) const {
  const auto t0 = Clock::now();
  DetectionResult result;
  result.scene_points = input.size();
  if (std::none_of(input.points.begin(), input.points.end(), isMeasured)) return result;
  ReadyScan ready;  // 5.2.1-5.2.2: sub-sampled, oriented, the bin's planes apart; the noise measured
  readyScan(input, *settings_, ready);
  const PointCloud& scan = *ready.scan;
  const PreparedScan& prepared = ready.prepared;
  result.pixel_stride = ready.pixel_stride;
  result.flying_points = ready.flying;
  const StageSettings& p = prepared.params;  // adapted to the scan's noise
  const PreparedScene& scene = prepared.scene;
  std::vector<std::vector<std::uint32_t>> groups;  // 5.2.3-5.2.4, beside the local voters' set-up
  LocalVotes local;
  tbb::parallel_invoke([&] { groups = makeSubGroups(scene.points, p.eta, p.r, static_cast<std::size_t>(p.C_n)); },
                       [&] { local = makeLocalVotes(db_, scene, p, *symmetry_); });
  result.timing.preprocess_ms = msSince(t0) - local.setup_ms;  // the voters' set-up counts as voting

  const auto t_match = Clock::now();  // 5.2.5-5.2.6: votes, clique, pose, verification, removal
  MatchState state(scene.points.size());
  // clang-format off
  const Matcher matcher{db_, p, icp_model_, prescore_model_, scored_model_, scene, scan, *prepared.grid, &*prepared.pixels,
                        *prepared.evidence, local.voter.get(), local.may_vote, *symmetry_,
                        [&](const Pose& pose) { return state.seen(pose, *shape_, p.tried_share); },
                        [&](const Pose& pose) { return state.refoundAt(pose, *shape_, p.refound_share); }};
  // clang-format on
  GroupSchedule schedule(db_, p, *shape_, matcher, groups, local.voter.get(), local.may_vote, state);
  std::vector<std::uint32_t> order(groups.size());
  std::iota(order.begin(), order.end(), 0u);
  schedule.run(order, false);
  if (p.retry_all_voters && local.voter && p.voter_spacing > 0) {  // the second pass, every point voting
    order = groupsToRetry(groups, schedule.largestCliques(), state.removed, p);
    result.subgroups_retried = order.size();
    schedule.run(order, true);
  }
  ScheduleTimes times = schedule.times();
  const bool quiet = prepared.noise.sigma < kPolishNoise;
  if (p.revote_left && quiet && local.voter && !state.enough)  // where nothing was found, votes among the points left
    times += revoteLeftPoints(db_, p, *shape_, *symmetry_, scene, matcher, groups, local.may_vote, state);
  if (p.verify && p.face_hypotheses && !state.enough) addFaceDetections(*faces_, matcher, *shape_, state);
  shareTimes(times, local.setup_ms, msSince(t_match), result.timing);

  if (p.refine && p.verify && p.reseat_weak && (!quiet || !quiet_flips_.empty())) {
    const auto t_reseat = Clock::now();  // ICP's minimum a few degrees off, or the part turned over
    state.hypotheses = distinctObjects(std::move(state.hypotheses), scan.size(), *shape_);
    reseatWeak(state.hypotheses, matcher, *shape_, quiet ? quiet_flips_ : flips_, quiet);
    result.timing.refine_ms += msSince(t_reseat);
  }
  const auto t_suppress = Clock::now();  // best first, one detection per object
  if (p.verify)
    result.detections = suppressDuplicates(std::move(state.hypotheses), scan.size(), *shape_);
  else
    for (Hypothesis& h : state.hypotheses) result.detections.push_back(h.detection);
  if (p.max_instances > 0 && static_cast<int>(result.detections.size()) > p.max_instances && p.verify)
    result.detections.resize(static_cast<std::size_t>(p.max_instances));
  result.timing.match_ms += msSince(t_suppress);
  if (p.refine && p.verify && !result.detections.empty() && !quiet) {
    const auto t_polish = Clock::now();
    polishAll(result.detections, icp_model_, scan, prepared);
    if (p.slide_faces) slideAlongFaces(result.detections, matcher);  // what ICP cannot fix: a flat face's place along it
    result.timing.refine_ms += msSince(t_polish);
  }
  if (p.verify)  // rough scans (noise.cpp); an unverified pose has no score to judge
    std::erase_if(result.detections, [&](const Detection& d) { return d.score < p.report_score; });
  countStages(prepared, groups.size(), state, result);
  result.timing.total_ms = msSince(t0);
  return result;
}

std::vector<PoseCheck> Detector::check(const PointCloud& input, const std::vector<Pose>& poses) const {
  if (!settings_->verify) throw Error("checking a pose needs verification on (verify: true)");
  if (std::none_of(input.points.begin(), input.points.end(), isMeasured))
    throw Error("checking a pose needs a scan with points; this one has none that holds a measurement");
  if (poses.size() > kMostCheckedPoses)
    throw Error(fmt::format("checking {} poses at once: at most {} a call", poses.size(), kMostCheckedPoses));
  ReadyScan ready;
  readyScan(input, *settings_, ready);
  const PreparedScan& prepared = ready.prepared;
  const StageSettings& p = prepared.params;
  const std::vector<char> no_voters;
  const auto never = [](const Pose&) { return false; };
  // clang-format off
  const Matcher matcher{db_, p, icp_model_, prescore_model_, scored_model_, prepared.scene, *ready.scan, *prepared.grid, &*prepared.pixels,
                        *prepared.evidence, nullptr, no_voters, *symmetry_, never, never};
  // clang-format on
  const float least_score = std::max(p.min_score, p.report_score);
  std::vector<PoseCheck> checks(poses.size());
  tbb::parallel_for(std::size_t{0}, poses.size(),
                    [&](std::size_t i) { checks[i] = checkedPose(matcher, *shape_, poses[i], least_score); });
  return checks;
}

const char* refusalName(Refusal r) {
  // In Refusal's order.
  static constexpr const char* kNames[] = {"none", "score", "visible_support", "sunk", "behind_face", "outline"};
  const auto i = static_cast<std::size_t>(r);
  return i < std::size(kNames) ? kNames[i] : "unknown";
}

}  // namespace binpose
