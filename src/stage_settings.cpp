// The stages' values: the user's and the pipeline's internal ones, scaled to the model.
#include "stage_settings.hpp"

#include <binpose/model.hpp>
#include <binpose/voting.hpp>

#include <cmath>
#include <fmt/format.h>

namespace binpose {
namespace {

/// Chapter 5 as written: random sub-sampling, one candidate per point voting in each
/// sub-group, every detection removing its points; no planes, noise adaptation or pre-screen.
StageSettings thesisStages() {
  StageSettings s;
  s.subsampling = Subsampling::Random;
  s.adapt_to_noise = false;  // and so no far_noise or flying pixels either
  s.remove_planes = false;
  s.candidates_per_point = 1;
  s.candidate_spacing = 0.0f;
  s.mild_outlier_candidates = 0;
  s.local_votes = false;
  s.voter_spacing = 0.0f;
  s.partner_spacing = 0.0f;
  s.retry_all_voters = false;
  s.revote_left = false;
  s.pair_angle_tolerance = 0.0f;
  s.mirror_retries = 0;
  s.reflect_mirrors = false;
  s.alternative_cliques = 0;
  s.turn_over = false;
  s.slide_faces = false;
  s.reseat_weak = false;
  s.flip_weak = false;
  s.face_hypotheses = false;
  s.prescreen = false;
  s.prescreen_retry_steps = 0;
  s.removal_score = 0.0f;
  return s;
}

/// Plane patches are linked over this many sample spacings: neighbours on a plane are one
/// spacing apart.
constexpr float kPlaneLinkSpacings = 2.5f;

void positive(float v, const char* name) {
  if (!(v > 0) || !std::isfinite(v)) throw Error(fmt::format("{} must be a positive length in mm, got {}", name, v));
}

void nonNegative(float v, const char* name) {
  if (!(v >= 0) || !std::isfinite(v)) throw Error(fmt::format("{} must be >= 0, got {}", name, v));
}

void share(float v, const char* name) {
  if (!(v >= 0 && v <= 1)) throw Error(fmt::format("{} must lie in [0, 1], got {}", name, v));
}

void range(int v, int lo, int hi, const char* name) {
  if (v < lo || v > hi) throw Error(fmt::format("{} must lie in [{}, {}], got {}", name, lo, hi, v));
}

}  // namespace

StageSettings stageSettings(const DetectionParams& params, float model_diameter) {
  StageSettings s = params.pipeline == Pipeline::Thesis ? thesisStages() : StageSettings{};
  static_cast<DetectionParams&>(s) = params;
  s.use_revolution = s.use_cyclic_symmetry = params.use_symmetry;
  const float k = thesisScale(model_diameter);
  s.vote_radius *= k;
  s.voter_spacing *= k;
  s.partner_spacing *= k;
  s.candidate_spacing *= k;
  s.plane_min_area *= k * k;
  s.plane_tolerance *= k;
  s.plane_hole *= k;
  s.icp_max_distance *= k;
  s.verify_tolerance *= k;
  s.far_noise *= k;
  s.normal_max_radius *= k;
  return s;
}

MildOutliers mildOutliers(const StageSettings& s) { return {s.mild_outlier_spreads, s.mild_outlier_candidates}; }

PlaneParams planeParams(const StageSettings& s) {
  PlaneParams planes;
  planes.min_area = s.plane_min_area;
  planes.tolerance = s.plane_tolerance;
  planes.fit_band = s.plane_fit_band;
  planes.max_angle = s.plane_max_angle;
  planes.link = kPlaneLinkSpacings / std::sqrt(s.rho_sub);
  planes.hole = s.plane_hole;
  planes.seed = s.seed;
  planes.viewpoint = s.viewpoint;
  return planes;
}

void validateStages(const StageSettings& s) {
  validate(static_cast<const DetectionParams&>(s));
  positive(s.vote_radius, "vote_radius");
  nonNegative(s.plane_min_area, "plane_min_area");
  nonNegative(s.far_noise, "far_noise");
  nonNegative(s.normal_max_radius, "normal_max_radius");
  positive(s.plane_tolerance, "plane_tolerance");
  nonNegative(s.plane_hole, "plane_hole");
  nonNegative(s.candidate_spacing, "candidate_spacing");
  nonNegative(s.partner_spacing, "partner_spacing");
  nonNegative(s.voter_spacing, "voter_spacing");
  positive(s.icp_max_distance, "icp_max_distance");
  positive(s.verify_tolerance, "verify_tolerance");
  range(s.icp_model_points, 0, 1 << 24, "icp_model_points");
  range(s.icp_iterations, 0, 1000, "icp_iterations");
  share(s.removal_score, "removal_score");
  share(s.explain_score, "explain_score");
  share(s.retry_min_score, "retry_min_score");
  share(s.min_visible_support, "min_visible_support");
  share(s.max_outline_share, "max_outline_share");
  share(s.many_faces_outline_share, "many_faces_outline_share");
  share(s.min_outline_drop, "min_outline_drop");
  share(s.max_sunk_share, "max_sunk_share");
  share(s.report_score, "report_score");
  range(s.retry_min_clique, 0, 1 << 20, "retry_min_clique");
  if (!(s.plane_max_angle > 0 && s.plane_max_angle <= 0.5f * static_cast<float>(M_PI)))
    throw Error(fmt::format("plane_max_angle must lie in (0, pi/2] radians, got {}", s.plane_max_angle));
  if (!(s.grazing_angle > 0 && s.grazing_angle <= 90))
    throw Error(fmt::format("grazing_angle must lie in (0, 90] degrees, got {}", s.grazing_angle));
  share(s.tried_share, "tried_share");
  share(s.refound_share, "refound_share");
  range(s.prescreen_retry_steps, 0, 20, "prescreen_retry_steps");
  share(s.prescreen_retry_share, "prescreen_retry_share");
  range(s.candidates_per_point, 1, 64, "candidates_per_point");
  range(s.mild_outlier_candidates, 0, 64, "mild_outlier_candidates");
  if (!(s.mild_outlier_spreads >= 0 && s.mild_outlier_spreads <= 3))
    throw Error(fmt::format("mild_outlier_spreads must lie in [0, 3] fourth-spreads, got {}", s.mild_outlier_spreads));
  if (s.clique_work_limit < 1) throw Error("clique_work_limit must be >= 1");
  if (!(s.pair_angle_tolerance >= 0 && s.pair_angle_tolerance < 180))
    throw Error(fmt::format("pair_angle_tolerance must lie in [0, 180) degrees, got {}", s.pair_angle_tolerance));
  range(s.mirror_retries, 0, 10, "mirror_retries");
  range(s.alternative_cliques, 0, 10, "alternative_cliques");
  share(s.alternative_min_score, "alternative_min_score");
  share(s.alternative_alone_score, "alternative_alone_score");
  range(s.revolution_candidates, 1, 64, "revolution_candidates");
  if (!(s.revolution_angle_tolerance > 0 && s.revolution_angle_tolerance < 90))
    throw Error(fmt::format("revolution_angle_tolerance must lie in (0, 90) degrees, got {}", s.revolution_angle_tolerance));
}

}  // namespace binpose
