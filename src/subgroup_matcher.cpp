// One sub-group: votes, clique, pose (thesis 4.3-4.6, 5.2.5), then pre-screen, ICP and score.
#include "subgroup_matcher.hpp"

#include "stopwatch.hpp"

#include <binpose/clique.hpp>
#include <binpose/planes.hpp>
#include <binpose/pose.hpp>

#include <algorithm>
#include <cmath>
#include <optional>

namespace binpose {
namespace {

void reset(GroupOutcome& out, bool all_voters) {
  out.members.clear();
  out.clique.clear();
  out.poses.clear();
  out.other_poses.clear();
  out.other.reset();
  out.ran = out.screened_out = out.pending = out.refound = out.reflected = false;
  out.path.clear();
  out.all_voters = all_voters;
  out.largest_clique = 0;
  out.hypothesis = {};
  out.evidence = {};
  out.stands.reset();
  out.vote_ms = out.match_ms = out.refine_ms = 0;
}

/// Heights along a body of revolution's axis at which a pose is turned end over end.
constexpr int kTurnHeights = 9;

/// `pose` turned end over end: half turns about lines across the axis, at kTurnHeights heights
/// spread over the model's extent along it.
std::vector<Pose> turnedOver(const Pose& pose, const RevolutionAxis& axis, const Points& model) {
  float lo = INFINITY, hi = -INFINITY;
  for (const Vec3& q : model) {
    const float z = (q - axis.point).dot(axis.direction);
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  const Vec3 across = axis.direction.unitOrthogonal();
  std::vector<Pose> turned;
  for (int k = 0; k < kTurnHeights; ++k) {
    const Vec3 c = axis.point + (lo + (hi - lo) * (static_cast<float>(k) + 0.5f) / kTurnHeights) * axis.direction;
    turned.push_back(pose * turnAbout(across, static_cast<float>(M_PI), c));
  }
  return turned;
}

}  // namespace

bool Matcher::prepare(std::span<const std::uint32_t> group, const std::vector<char>& removed, Slot& s, bool all_voters,
                      const GroupOutcome* earlier, ParallelVoter* parallel) const {
  GroupOutcome& out = s.outcome;
  reset(out, all_voters);
  for (const auto i : group)
    if (!removed[i]) out.members.push_back(i);
  if (out.members.size() < static_cast<std::size_t>(p.C_n)) return false;
  out.ran = true;
  const auto t_vote = Clock::now();
  if (!collectVotes(s, all_voters, parallel)) return false;
  const auto t_match = Clock::now();
  out.vote_ms = msSince(t_vote);
  const bool matched = match(s);
  out.match_ms = msSince(t_match);
  if (!matched) return false;
  if (p.verify && std::any_of(out.poses.begin(), out.poses.end(), seen)) return false;  // still seen when taken
  if (earlier != nullptr && !earlier->pending && earlier->clique == out.clique) {
    out.screened_out = earlier->screened_out;
    out.hypothesis = earlier->hypothesis;
    out.evidence = earlier->evidence;
    out.stands = earlier->stands;
    out.path = earlier->path;
    out.refound = earlier->refound;
    out.other = earlier->other;
    return false;
  }
  out.pending = true;
  return true;
}

void Matcher::verify(Slot& s) const {
  const auto t_refine = Clock::now();
  screenRefineScore(s);
  s.outcome.pending = false;
  s.outcome.refine_ms = msSince(t_refine);
}

bool Matcher::collectVotes(Slot& s, bool all_voters, ParallelVoter* parallel) const {
  const GroupOutcome& out = s.outcome;
  s.candidates.clear();
  if (local == nullptr) {  // 4.3: the sub-group's points vote among themselves
    if (parallel != nullptr)
      parallel->vote(scene.points, scene.normals, out.members, s.candidates);  // the same pairs
    else
      s.voter.vote(scene.points, scene.normals, out.members, s.candidates);
    return true;
  }
  // The second pass (retry_all_voters): nothing new when the other points have no candidate.
  if (all_voters && std::none_of(out.members.begin(), out.members.end(),
                                 [&](std::uint32_t i) { return may_vote[i] == 0 && !local->candidates(i).empty(); }))
    return false;
  for (const auto i : out.members)
    if (all_voters || may_vote[i] != 0)  // the others' votes, if any, are for the second pass
      for (const auto m : local->candidates(i)) s.candidates.push_back({i, m});
  return true;
}

bool Matcher::match(Slot& s) const {
  if (s.candidates.size() < static_cast<std::size_t>(p.C_n)) return false;
  Graph graph = symmetry.consistencyGraph(s.candidates, scene.points, scene.normals, db.model(), p, s.buffers.graph);
  std::optional<CliqueResult> mirrored;  // the first clique refused as a mirror image
  for (int retry = 0;; ++retry) {
    const CliqueResult clique = maximumClique(graph, p.clique_work_limit, s.buffers.clique);
    if (retry == 0) s.outcome.largest_clique = static_cast<int>(clique.vertices.size());
    if (clique.vertices.size() < static_cast<std::size_t>(p.C_n)) break;
    if (fitClique(s, clique)) {
      addAlternativeCliques(s, graph, clique.vertices);
      return true;
    }
    if (!mirrored) mirrored = clique;
    // A mirror image (or a degenerate set): the next largest clique without its pairs.
    if (!symmetry.retriesMirrors() || retry >= p.mirror_retries) break;
    graph.isolate(clique.vertices);
  }
  // No clique fits the part itself. Point-pair features do not change under a reflection, so a
  // copy of a mirror-symmetric part also votes for the mirror images of its points, and a clique
  // of such pairs fits only a mirror image of the part. Their images in the part's own mirror
  // plane are points of the part as well, and fit the copy's pose.
  if (!p.reflect_mirrors || !mirrored || !symmetry.mirror() || !fitClique(s, *mirrored, true)) return false;
  s.outcome.reflected = true;
  addAlternativeCliques(s, graph, mirrored->vertices);
  return true;
}

std::vector<PoseFit> Matcher::posesOf(Slot& s, std::span<const int> vertices, bool reflected) const {
  s.clique.clear();
  for (const int v : vertices) s.clique.push_back(s.candidates[v]);
  std::vector<PoseFit> fits = symmetry.solve(s.clique, scene.points, scene.normals, db.model().points, s.buffers, reflected);
  if (!fits.empty() && !fits.front().ok) fits.clear();
  return fits;
}

bool Matcher::fitClique(Slot& s, const CliqueResult& clique, bool reflected) const {
  const std::vector<PoseFit> fits = posesOf(s, clique.vertices, reflected);
  if (fits.empty()) return false;
  s.outcome.clique.insert(s.outcome.clique.end(), s.clique.begin(), s.clique.end());
  for (const PoseFit& fit : fits) s.outcome.poses.push_back(fit.pose);  // the first, then its alternatives
  const PoseFit& fit = fits.front();
  s.outcome.hypothesis.detection = Detection{fit.pose, 0.0f, static_cast<int>(clique.vertices.size()), fit.rms};
  return true;
}

// Beyond the thesis: on a noisy scan the largest clique is often a wrong pose a pair or two
// larger than the right one's (a part turned over, or pairs of its neighbours). Each such clique
// is sound in its distances (4.5), so the scan judges (screenRefineScore, GroupSchedule::take).
void Matcher::addAlternativeCliques(Slot& s, Graph& graph, std::vector<int> taken) const {
  for (int a = 0; a < p.alternative_cliques; ++a) {
    graph.isolate(taken);
    const CliqueResult other = maximumClique(graph, p.clique_work_limit, s.buffers.clique);
    if (other.vertices.size() < static_cast<std::size_t>(p.C_n)) return;
    for (const PoseFit& fit : posesOf(s, other.vertices)) s.outcome.other_poses.push_back(fit.pose);
    taken = other.vertices;
  }
}

IcpParams Matcher::icpParams(int iterations) const {
  return {iterations, p.icp_max_distance, p.verify_tolerance, p.viewpoint, {}, nullptr, pixels};
}

Evidence Matcher::scoredEvidence(const Pose& pose, std::vector<std::uint32_t>& support) const {
  const Evidence e = evidence.evaluate(pose, scored_model, p.verify_tolerance, db.model().sample_radius, &support);
  std::sort(support.begin(), support.end());
  support.erase(std::unique(support.begin(), support.end()), support.end());
  return e;
}

Refusal Matcher::refusal(const Pose& pose, float score, const Evidence& e, std::span<const std::uint32_t> support,
                         bool laid) const {
  if (score < p.min_score) return Refusal::score;
  if (e.visibleSupport() < p.min_visible_support) return Refusal::visible_support;  // met by the scan only in passing
  if (sunk(pose)) return Refusal::sunk;                                             // inside the floor, a wall or the table
  const std::optional<Plane> face = faceOf(support);  // the scan shows it one flat face
  if (sunkBehindFace(pose, face, e)) return Refusal::behind_face;  // inside a surface that goes on from its face
  return outlineStandsOut(pose, face, laid) ? Refusal::none : Refusal::outline;
}

bool Matcher::sunkBehindFace(const Pose& pose, const std::optional<Plane>& face, const Evidence& e) const {
  // A right pose seen by one face shows nothing of itself hidden behind that face's plane; a
  // pose laid on a patch of a larger surface (a table that no background plane fits: warped, or
  // stepped by a sensor's disparity quanta) has the rest of its body there, hidden by that
  // surface. Copies lying side by side, their faces level, hide a little of one another so, and
  // then among much else that hides them: those points must also be a quarter of all it hides.
  constexpr float kMostBehindFace = 0.1f;   // of the visible points (Sinking::share)
  constexpr float kMostOfOccluded = 0.25f;  // of those the scan hides (Evidence::occluded)
  if (!face) return false;
  const Sinking s = evidence.sunkBehind(*face, pose, scored_model, p.verify_tolerance, db.model().sample_radius);
  return s.share() > kMostBehindFace && static_cast<float>(s.sunk) > kMostOfOccluded * static_cast<float>(e.occluded);
}

bool Matcher::outlineStandsOut(const Pose& pose, const std::optional<Plane>& face, bool laid) const {
  constexpr int kMinJudged = 4;         // one or two coincidences do not decide
  constexpr int kMinDropJudged = 8;     // a drop is missing by chance on a short outline
  // A pose laid on one flat face (face_hypotheses.hpp) has no evidence of the part's shape
  // beyond that face: a patch of a larger or gently curved surface fits it as well. Around a part
  // lying on that face the scan falls away behind its outline, where the rest of the part holds
  // the face up; around such a patch the surface goes on or bends away slowly. On the simulated
  // bins the laid poses of right copies fall away at 0.6-0.8 of their judged outline (median),
  // against 0.25 on scans of other objects.
  constexpr float kLaidMinDrop = 0.4f;
  if (!laid && p.max_outline_share >= 1.0f && p.min_outline_drop <= 0.0f) return true;
  const OutlineEvidence o = evidence.outline(pose, scored_model, p.verify_tolerance, db.model().sample_radius, laid);
  if (laid && !(o.judged >= kMinJudged && o.droppedShare() >= kLaidMinDrop)) return false;
  const float most = face ? p.max_outline_share : std::max(p.max_outline_share, p.many_faces_outline_share);
  if (o.judged >= kMinJudged && o.share() > most) return false;  // a face laid on a larger surface
  if (o.judged < kMinDropJudged || o.droppedShare() >= p.min_outline_drop) return true;
  // Nothing falls away around it: it stands only where the scan shows more of it than one plane.
  return !face;
}

std::optional<Plane> Matcher::faceOf(std::span<const std::uint32_t> support) const {
  constexpr float kOnePlaneShare = 0.8f;  // of the support within kOnePlaneTolerances of one plane
  constexpr float kOnePlaneTolerances = 2.0f;
  Plane plane;
  if (!fitPlane(scan.points, support, plane)) return std::nullopt;
  const float band = kOnePlaneTolerances * p.verify_tolerance;
  const auto on = std::count_if(support.begin(), support.end(), [&](std::uint32_t i) { return plane.distance(scan.points[i]) <= band; });
  if (static_cast<float>(on) < kOnePlaneShare * static_cast<float>(support.size())) return std::nullopt;
  return plane;
}

bool Matcher::sunk(const Pose& pose) const {
  // Deeper than three tolerances: a right pose on a floor whose fit a sensor's bias tilts stays
  // clear. To half the part's diameter: a pose sunk into a floor has part of its body just
  // beneath it, and what lies deeper under a plane's edge (below the bin's rim) is under
  // something else.
  constexpr float kMarginTolerances = 3.0f;
  constexpr float kReachDiameters = 0.5f;
  if (p.max_sunk_share >= 1.0f || evidence.background().empty()) return false;
  const Sinking s = evidence.sinking(pose, scored_model, kMarginTolerances * p.verify_tolerance,
                                     kReachDiameters * db.model().diameter);
  return s.share() > p.max_sunk_share;
}

float Matcher::prescore(const Pose& pose, bool second_pass) const {
  const Evidence e = evidence.evaluate(pose, prescore_model, p.icp_max_distance, 0.0f);
  return second_pass ? e.scoreWithoutGrazing() : e.score();
}

bool Matcher::prescreen(Slot& s) const {
  Detection& det = s.outcome.hypothesis.detection;
  // A pose of the second pass (retry_all_voters) is screened as it will be judged: by its score
  // without grazing points, against retry_min_score.
  const bool second_pass = s.outcome.all_voters;
  const float gate = second_pass ? std::max(p.min_score, p.retry_min_score) : p.min_score;
  const auto alternatives = std::span<const Pose>(s.outcome.poses).subspan(1);
  float best = p.prescreen || !alternatives.empty() ? prescore(det.pose, second_pass) : 1.0f;
  for (const Pose& other : alternatives)
    if (const float score = prescore(other, second_pass); score > best) {
      best = score;
      det.pose = other;
    }
  if (!p.prescreen || best >= gate) return true;
  if (p.prescreen_retry_steps > 0 && best >= p.prescreen_retry_share * gate) {
    // Near the scan but a few mm off: a few coarse ICP steps, and another look.
    const Pose moved = refinePose(det.pose, icp_model, scan.points, scan_grid, icpParams(p.prescreen_retry_steps));
    if (prescore(moved, second_pass) >= gate) {
      det.pose = moved;
      return true;
    }
  }
  return false;  // far from the scan even at the ICP gate: not worth refining
}

std::optional<OtherPose> Matcher::otherCliquePose(const Slot& s) const {
  std::optional<OtherPose> best;
  for (const Pose& other : s.outcome.other_poses)
    if (const float score = prescore(other, s.outcome.all_voters); score >= (best ? best->prescore : p.alternative_min_score))
      best = OtherPose{other, score};
  return best;
}

void Matcher::verifyOther(Slot& s, const Pose& start) const {
  OtherHypothesis& other = s.outcome.other.emplace();
  other.start = start;
  Detection& det = other.hypothesis.detection;
  det = s.outcome.hypothesis.detection;
  det.pose = start;
  if (p.refine) {
    IcpParams icp = icpParams(p.icp_iterations);
    if (p.refound_share > 0) icp.path = &other.path;  // looked at when taken, as the first's
    det.pose = refinePose(start, icp_model, scan.points, scan_grid, icp);
  }
  other.evidence = scoredEvidence(det.pose, other.hypothesis.support);
  det.score = other.evidence.score();
}

void Matcher::screenRefineScore(Slot& s) const {
  Hypothesis& h = s.outcome.hypothesis;
  Detection& det = h.detection;
  std::optional<OtherPose> other = p.verify ? otherCliquePose(s) : std::nullopt;
  if (p.verify && !prescreen(s)) {
    if (!other || other->prescore < p.alternative_alone_score) {
      s.outcome.screened_out = true;
      return;
    }
    det.pose = other->pose;  // the first clique's poses fail the pre-screen, the other's stands in
    s.outcome.poses = {other->pose};
    s.outcome.reflected = false;
    other.reset();
  }
  if (p.refine) {
    const bool stop_at_found = p.verify && p.refound_share > 0;  // see takeOutcome (group_schedule.cpp)
    IcpParams icp = icpParams(p.icp_iterations);
    if (stop_at_found) {
      icp.path = &s.outcome.path;
      icp.stop = found;
    }
    det.pose = refinePose(det.pose, icp_model, scan.points, scan_grid, icp);
    if (stop_at_found && found(det.pose)) {
      s.outcome.refound = true;
      return;
    }
  }
  s.outcome.evidence = scoredEvidence(det.pose, h.support);
  det.score = s.outcome.evidence.score();
  if (p.verify && p.turn_over && symmetry.orbits()) {  // the verdict kept for GroupSchedule::take
    s.outcome.stands = stands(det.pose, det.score, s.outcome.evidence, h.support);
    if (!*s.outcome.stands) s.outcome.stands = turnOver(s);
  }
  if (other) verifyOther(s, other->pose);  // both refined and scored: the better is taken (GroupSchedule::take)
}

// Beyond the thesis: a cap seen from above shows a disc and the outside of its wall; its clique
// often lays the inside of the closed end on that disc, the copy upside down and 30-40 mm off
// (docs/design.md, Turned copies). Such a pose rarely stands (its body sinks into the floor or
// what lies beside it), and turned end over end about a line across the axis, at the height that
// the scan supports best, it is the copy.
bool Matcher::turnOver(Slot& s) const {
  Hypothesis& h = s.outcome.hypothesis;
  Detection& det = h.detection;
  float best = p.min_score;
  std::optional<Pose> start;
  for (const Pose& turned : turnedOver(det.pose, symmetry.orbits()->axis, icp_model.points()))
    if (const float score = prescore(turned, s.outcome.all_voters); score >= best) {
      best = score;
      start = turned;
    }
  if (!start) return false;
  std::vector<Pose> path;
  IcpParams icp = icpParams(p.icp_iterations);
  if (p.refound_share > 0) icp.path = &path;
  const Pose pose = p.refine ? refinePose(*start, icp_model, scan.points, scan_grid, icp) : *start;
  std::vector<std::uint32_t> support;
  const Evidence e = scoredEvidence(pose, support);
  if (e.score() < p.alternative_min_score || !stands(pose, e.score(), e, support)) return false;
  det.pose = pose;
  det.score = e.score();
  s.outcome.evidence = e;
  h.support = std::move(support);
  s.outcome.path = std::move(path);
  return true;
}

}  // namespace binpose
