#pragma once
// Every value the stages read: the user's (DetectionParams) and the internal ones, which follow
// the pipeline (Pipeline::Binpose or Thesis). A user does not set the internal values; tests and
// benchmarks inside the project may, to show what each one does. Why each is what it is:
// docs/design.md.
#include <binpose/params.hpp>
#include <binpose/planes.hpp>
#include <binpose/scene.hpp>

#include <cstdint>

namespace binpose {

struct MildOutliers;  // voting.hpp

struct StageSettings : DetectionParams {
  // --- scene preparation (5.2.1-5.2.2) ------------------------------------------------------
  Subsampling subsampling = Subsampling::Voxel;
  /// Measure a depth image's noise and raise what depends on it for a noisy one (k_normals,
  /// e_gmax, plane_tolerance, plane_max_angle, verify_tolerance, revolution_angle_tolerance;
  /// noise.cpp).
  bool adapt_to_noise = true;
  /// ... and leave out of the matching the ranges where the scan is measured this noisy (1 sigma,
  /// mm; 1.2 mm for the 60 mm part: 2 % of its diameter) and three times noisier than nearer
  /// (farNoisyRange, noise.hpp): a room's far walls behind the bin (0: none left out).
  float far_noise = 1.2f;
  /// ... and where the noise wants more neighbours than the pixel search answers, fit each
  /// normal to every scan point within a radius set from the noise (noise.cpp), at most this (mm;
  /// for the 60 mm part 0.15 of its diameter: the bends and edges the votes tell a part by stay
  /// sharper than that).
  float normal_max_radius = 9.0f;
  float normal_radius = 0.0f;  ///< that radius, set from the noise (mm; 0: the k_normals nearest)
  /// ... and take every second pixel of every second row of a depth image whose depths are copied
  /// over blocks of pixels (registered to a sharper camera; correlated_noise.hpp), until they are not.
  bool thin_correlated_pixels = true;
  /// ... and drop a depth image's flying pixels, which lie between two surfaces (flying_pixels.hpp).
  bool remove_flying_pixels = true;
  /// Take the bin's floor and walls (connected flat patches of at least plane_min_area) out of
  /// the voting points (planes.hpp); they stay in the scan for ICP and verification.
  bool remove_planes = true;
  float plane_min_area = 0.0f;   ///< mm^2; 0: the model's largest possible flat face (boundingFaceArea)
  float plane_tolerance = 1.5f;  ///< largest distance of a plane's point from it, mm
  /// PlaneParams::fit_band, mm: set from the noise (noise.cpp; 0: the hypotheses' counts alone).
  float plane_fit_band = 0.0f;
  /// Largest angle of a plane's point's normal from the plane's, radians (20 degrees;
  /// PlaneParams::max_angle; raised on a scan whose normals stay rough, noise.cpp).
  float plane_max_angle = 0.35f;
  /// A background plane's extent has holes up to this wide filled, mm (PlaneParams::hole): the
  /// model's diameter, what a copy lying on the floor hides of it.
  float plane_hole = 60.0f;

  // --- votes (4.3-4.4) ----------------------------------------------------------------------
  int candidates_per_point = 12;  ///< model points kept per scene point (the thesis: 1, eq. 12's maximum)
  float candidate_spacing = 2.7f; ///< least model distance between a point's candidates, mm (0: none)
  /// A point whose votes hold no upper outlier (eq. 11: none above x_u + 3 xi_s) keeps its
  /// mild_outlier_candidates most voted above x_u + mild_outlier_spreads xi_s (MildOutliers in
  /// voting.hpp; 0 candidates: none, as the thesis). On a large or smooth part (the bunny, a cup)
  /// the right model point is often among a point's few most voted, rarely 3 spreads clear.
  float mild_outlier_spreads = 2.0f;
  int mild_outlier_candidates = 4;
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
  /// On a quiet scan, after both passes, the sub-groups mostly made of points left unexplained
  /// run again, those points voting among themselves alone; their detections must score
  /// retry_min_score (left_points.hpp).
  bool revote_left = true;
  float grazing_angle = 80.0f;    ///< model points seen at more than this to the line of sight are grazing, degrees

  // --- clique and pose (4.5-4.6) --------------------------------------------------------------
  std::uint64_t clique_work_limit = 1000;  ///< branch-and-bound nodes per clique search (the best found is kept)
  /// A pair of correspondences is consistent only when the angle between its scene normals
  /// matches that between its model normals within this, degrees (0: distances alone, eq. 15-16;
  /// a symmetric part's graph tests angles by revolution_angle_tolerance).
  float pair_angle_tolerance = 25.0f;
  int mirror_retries = 1;     ///< searches again without a clique that fits only a mirror image, this many times
  /// ... and when none fits the part itself, a mirror-symmetric part's first such clique is fitted
  /// with its model points reflected in the part's mirror plane (PartSymmetry::mirror); its pose
  /// is kept from alternative_alone_score.
  bool reflect_mirrors = true;
  /// After the clique that gave the pose, the largest without its pairs gives another, this many
  /// times (0: the thesis's one clique). On a noisy scan the largest clique is often a wrong pose
  /// and the right one among the next. The best of them at the ICP gate is refined and scored
  /// beside the first clique's pose, and the better score is the hypothesis; it alone is
  /// verified when the first fails the pre-screen.
  int alternative_cliques = 3;
  /// ... when it scores at least this at the ICP gate;
  float alternative_min_score = 0.3f;
  /// ... and at least this to be verified alone: the largest clique stays the rule, an other one
  /// needs strong support to stand in for it.
  float alternative_alone_score = 0.5f;
  /// On a noisy scan (polished detections), a detection scoring under 0.7 is refined again from
  /// its pose turned by 15 degrees either way about each of the part's axes, and takes the best
  /// that scores 0.05 more and stands (src/reseat.cpp): ICP settles a few degrees off the part.
  bool reseat_weak = true;
  /// With reseat_weak, a detection scoring under 0.8 is also tried turned over by the part's
  /// near-symmetric half turns (src/near_flips.cpp, found when the detector is made), refined,
  /// and takes the best that scores 0.05 more and stands: a noisy scan often leaves the side
  /// that tells the part from its turned self unresolved. On a quiet scan too, with the half
  /// turns that lay one of the part's flat faces on itself (a bracket seen by one plate, its body
  /// behind it on one side or the other).
  bool flip_weak = true;
  /// A body of revolution's verified pose that does not stand (a cap upside down, its inside
  /// laid on the copy's top) is tried turned end over end, at 9 heights along its axis; the best
  /// at the ICP gate, refined, replaces it where it stands and scores alternative_min_score.
  bool turn_over = true;
  /// On a noisy scan (polished detections), a detection whose support lies on one plane is moved
  /// along that plane while its score grows (src/face_slide.cpp): ICP cannot place a flat face
  /// along itself.
  bool slide_faces = true;

  // --- symmetry (set from use_symmetry) -------------------------------------------------------
  bool use_revolution = true;       ///< a body of revolution votes for orbits (symmetry.hpp)
  bool use_cyclic_symmetry = true;  ///< an n-fold symmetric part votes for classes of images (cyclic_symmetry.hpp)
  float revolution_angle_tolerance = 15.0f;  ///< each angle of a symmetric pair's consistency test, degrees
  int revolution_candidates = 4;    ///< candidates per point of a symmetric part (at most candidates_per_point)

  // --- verification: pre-screen, ICP, score ---------------------------------------------------
  float verify_tolerance = 1.0f;  ///< a scan point within this supports a model point, mm
  /// A detection's facing points that nothing in the scan hides must be supported at least this
  /// share (Evidence::visibleSupport; 0: no test).
  float min_visible_support = 0.4f;
  /// A detection whose visible outline the scan's surface goes on past, along the part's own
  /// tangent planes, at more than this share of its judged steps is dropped
  /// (SceneEvidence::outline: one face laid on a larger surface; 1: no test). Right poses reach
  /// 0.55 where a copy lies flush against another.
  float max_outline_share = 0.6f;
  /// ... and one whose support lies on more than one plane at more than this share (at least
  /// max_outline_share): the scan shows more of the part's shape than one face, and a surface
  /// going on past its outline is most often a neighbour lying flush against it, a block's faces
  /// in line with its neighbours' (right poses of IPD obj 4 packed side by side read 0.74-0.88).
  /// Lowered to max_outline_share on a scan whose normals stay rough (adaptedToNoise), where a
  /// copy turned over reads as many planes as a right one.
  float many_faces_outline_share = 0.85f;
  /// A detection whose support lies on one plane (the scan shows it by one flat face) must stand
  /// out of what lies behind it: beyond at least this share of its judged outline steps the scan
  /// lies clearly behind the part's tangent plane (OutlineEvidence::dropped; 0: no test). A pose
  /// laid on a patch of a larger flat surface (a table, a box's side, a face of another part),
  /// its body sunk into it, meets the scan on one plane, and nothing falls away around it.
  float min_outline_drop = 0.15f;
  /// A detection with more than this share of its model points inside the bin's floor, a wall or
  /// a table that the scan shows around it (SceneEvidence::sinking) is dropped: no part can lie
  /// there, though the part above hides the floor from the free-space test (1: no test).
  float max_sunk_share = 0.05f;
  /// Detections scoring under this after refinement are not reported (0: min_score alone decides).
  /// Raised on rough scans (adapt_to_noise, noise.cpp), where wrong and turned-over poses score
  /// low and right ones seldom do; min_score stays the gate within the loop.
  float report_score = 0.0f;
  /// After the sub-groups, the scene's flat regions that no detection explains, each about as large
  /// as a flat face of the model, are tried as that face (face_hypotheses.hpp): a copy that shows
  /// one flat face only gives no clique.
  bool face_hypotheses = true;
  bool prescreen = true;          ///< drop a pose scoring under min_score at the ICP gate before ICP
  int prescreen_retry_steps = 2;  ///< coarse ICP steps for a pose just short of the pre-screen (0: none)
  float prescreen_retry_share = 0.33f;  ///< ... when it scores at least this share of min_score
  int icp_iterations = 20;
  int icp_model_points = 1000;    ///< model points ICP pairs up (an even share; 0: all)
  float icp_max_distance = 3.0f;  ///< ICP's correspondence gate at the start, mm

  // --- removal and duplicates (5.2.6) -----------------------------------------------------------
  float removal_score = 0.6f;     ///< a detection scoring this removes its points (0: every one, as the thesis)
  float explain_score = 0.3f;     ///< a detection scoring this is a found object: its pose is not verified again
  float tried_share = 0.5f;       ///< a clique pose this close (share of 0.1 d) to one verified is not verified again
  float refound_share = 0.25f;    ///< ICP stops when this close (share of 0.1 d) to a found object
};

/// The stages' values for `params` (absolute units, see scaledToModel) on a model of this
/// diameter: the pipeline's internal values, their distances scaled like the user's (by
/// diameter / 60 mm), plane_min_area resolved from the model when 0 is left to the caller.
StageSettings stageSettings(const DetectionParams& params, float model_diameter);

/// The plane search for these settings: their plane_min_area, plane_tolerance and seed,
/// patches linked over 2.5 sample spacings (1 / sqrt(rho_sub)).
PlaneParams planeParams(const StageSettings& s);

/// The voters' candidates of a point without an upper outlier: mild_outlier_spreads and
/// mild_outlier_candidates.
MildOutliers mildOutliers(const StageSettings& s);

/// validate() of the user's values, then of the internal ones (tests and benchmarks set them).
void validateStages(const StageSettings& s);

}  // namespace binpose
