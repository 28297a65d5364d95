#pragma once
// Parameters of online recognition (thesis chapters 4-5), with the thesis's values as defaults.
// Distance-like values are for the thesis's 60 mm part (tau_object); scaledToModel() scales
// them by (model diameter / 60 mm), and an explicit user value replaces the scaled one.
#include <binpose/types.hpp>

#include <cstdint>
#include <string>

namespace binpose {

/// How the scan is thinned to rho_sub (5.2.1).
enum class Subsampling {
  Random,  ///< the thesis's uniform random selection
  Voxel,   ///< one scan point per cube of side 1/sqrt(rho_sub): even spacing (binpose's default)
};

/// Every value of online recognition, grouped by the stage that reads it. The defaults are
/// binpose's recommended settings (the `default` preset); thesisPreset() gives chapter 5 as
/// written. Why each default is what it is: docs/design.md.
struct DetectionParams {
  // --- scene preparation (5.2.1-5.2.2) ------------------------------------------------------
  float rho_sub = 0.06f;      ///< rho_sub: density after sub-sampling, points/mm^2 (5.2.1)
  Subsampling subsampling = Subsampling::Voxel;
  int k_normals = 8;          ///< k: neighbours of a scene normal's plane fit in the full scan (5.2.2; the thesis: 6)
  Vec3 viewpoint = Vec3::Zero();  ///< sensor origin in the scan's frame, mm (normals face it)
  std::uint64_t seed = 1;     ///< seed of the random sub-sampling
  /// Measure a depth image's noise and raise what depends on it for a noisy one (k_normals,
  /// e_gmax, plane_tolerance, verify_tolerance; noise.cpp); a clean scan keeps the values as
  /// given, and so does an unorganized cloud (its noise is only reported).
  bool adapt_to_noise = true;
  /// Take the bin's floor and walls (connected flat patches of at least plane_min_area) out of
  /// the voting points (planes.hpp); they stay in the scan for ICP and verification.
  bool remove_planes = true;
  float plane_min_area = 0.0f;   ///< mm^2; 0: the model's largest possible flat face (boundingFaceArea)
  float plane_tolerance = 1.5f;  ///< largest distance of a plane's point from it, mm

  // --- sub-groups (5.2.3-5.2.4) -------------------------------------------------------------
  float r = 25.0f;            ///< r: sampling radius of a sub-group, mm (5.2.3)
  float eta = 15.0f;          ///< eta: grid spacing of the sub-group centres, mm (5.2.3)

  // --- votes (4.3-4.4) ----------------------------------------------------------------------
  int candidates_per_point = 12;  ///< model points kept per scene point (the thesis: 1, eq. 12's maximum)
  float candidate_spacing = 2.7f; ///< least model distance between a point's candidates, mm (0: none)
  /// Each scene point votes once with its neighbours within vote_radius, and its sub-groups
  /// reuse its candidates (false: it votes in every sub-group with that group's points, 4.3).
  bool local_votes = true;
  float vote_radius = 40.0f;      ///< partners of a local vote lie within this, mm
  float voter_spacing = 5.0f;     ///< one voting point per cube of this side, mm (0: every point votes)
  float partner_spacing = 8.0f;   ///< one partner per cube of this side, mm (0: every point)
  /// After all sub-groups, those whose largest clique reached retry_min_clique but not C_n run
  /// again with every point voting (with voter_spacing only); their detections must score
  /// retry_min_score without grazing model points.
  bool retry_all_voters = true;
  int retry_min_clique = 3;
  float retry_min_score = 0.4f;
  float grazing_angle = 80.0f;    ///< model points seen at more than this to the line of sight are grazing, degrees

  // --- clique and pose (4.5-4.6) --------------------------------------------------------------
  float e_gmax = 1.5f;        ///< e_gmax: geometric consistency limit, mm (4.5, eq. 15-16)
  int C_n = 6;                ///< C_n: smallest accepted clique (4.5; the thesis: 8)
  std::uint64_t clique_work_limit = 1000;  ///< branch-and-bound nodes per clique search (the best found is kept)
  int mirror_retries = 1;     ///< searches again without a clique that fits only a mirror image, this many times

  // --- symmetry -------------------------------------------------------------------------------
  bool use_revolution = true;       ///< a body of revolution votes for orbits (symmetry.hpp)
  bool use_cyclic_symmetry = true;  ///< an n-fold symmetric part votes for classes of images (cyclic_symmetry.hpp)
  float revolution_angle_tolerance = 15.0f;  ///< each angle of a symmetric pair's consistency test, degrees
  int revolution_candidates = 4;    ///< candidates per point of a symmetric part (at most candidates_per_point)

  // --- verification: pre-screen, ICP, score ---------------------------------------------------
  bool verify = true;             ///< score = share of the posed model's sensor-facing points the scan supports
  float min_score = 0.15f;        ///< detections scoring less are rejected (verify only), in [0, 1]
  float verify_tolerance = 1.0f;  ///< a scan point within this supports a model point, mm
  bool prescreen = true;          ///< drop a pose scoring under min_score at the ICP gate before ICP
  int prescreen_retry_steps = 2;  ///< coarse ICP steps for a pose just short of the pre-screen (0: none)
  float prescreen_retry_share = 0.33f;  ///< ... when it scores at least this share of min_score
  bool refine = true;             ///< point-to-plane ICP of each pose against the full scan
  int icp_iterations = 20;
  int icp_model_points = 1000;    ///< model points ICP pairs up (an even share; 0: all)
  float icp_max_distance = 3.0f;  ///< ICP's correspondence gate at the start, mm

  // --- removal and duplicates (5.2.6) -----------------------------------------------------------
  float sigma_dist = 6.0f;        ///< sigma_dist: removal distance around a found object, mm (5.2.6, eq. 39)
  float removal_score = 0.6f;     ///< a detection scoring this removes its points (0: every one, as the thesis)
  float explain_score = 0.3f;     ///< a detection scoring this is a found object: its pose is not verified again
  float tried_share = 0.5f;       ///< a clique pose this close (share of 0.1 d) to one verified is not verified again
  float refound_share = 0.25f;    ///< ICP stops when this close (share of 0.1 d) to a found object
  int max_instances = 0;          ///< stop after this many confident detections, report at most this many (0: no limit)
};

/// The thesis's pipeline as written (chapter 5): random sub-sampling, k = 6, one candidate per
/// point voting in each sub-group, C_n = 8, every detection removes its points; no planes, no
/// symmetry, no refinement, no verification.
DetectionParams thesisPreset();
/// binpose's recommended settings: DetectionParams{}.
DetectionParams defaultPreset();
/// A preset by name: "default" or "thesis" ("fast", the earlier name of today's default, is
/// still accepted and gives the default).
DetectionParams presetByName(const std::string& name);

/// Distance-like values (r, eta, e_gmax, sigma_dist, vote_radius, the voter, partner and
/// candidate spacings, plane tolerance, ICP gate, verify tolerance) times s, plane_min_area (when set)
/// times s^2 and rho_sub divided by s^2, for s = model_diameter / 60 mm.
DetectionParams scaledToModel(const DetectionParams& params, float model_diameter);

/// Throws binpose::Error naming the first absurd value.
void validate(const DetectionParams& params);

/// Overrides fields from a JSON object (keys as the field names; "subsampling": "random"|"voxel",
/// "viewpoint": [x, y, z]); an unknown key or a wrong type is an error.
void applyJson(DetectionParams& params, const std::string& json_text, const std::string& source);
/// applyJson on the text of a file; an unreadable file is an error.
void applyJsonFile(DetectionParams& params, const std::string& path);
/// All fields as a JSON object text.
std::string toJson(const DetectionParams& params);

}  // namespace binpose
