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

struct DetectionParams {
  // --- the thesis's pipeline (symbols of chapters 4-5; defaults from Tables 1-7) -----------
  float r = 25.0f;            ///< r: sampling radius of a sub-group, mm (5.2.3; Tables swept 20-30)
  float rho_sub = 0.06f;      ///< rho_sub: density after sub-sampling, points/mm^2 (5.2.1; Tables 2-4)
  float eta = 15.0f;          ///< eta: grid spacing of the sub-group centres, mm (5.2.3; Tables 1, 5-7)
  float e_gmax = 1.5f;        ///< e_gmax: geometric consistency limit, mm (4.5, eq. 15-16; Table 1)
  int C_n = 8;                ///< C_n: smallest accepted clique (4.5; Table 1)
  float sigma_dist = 6.0f;    ///< sigma_dist: removal distance around a found object, mm (5.2.6, eq. 39)
  int k_normals = 6;          ///< k: neighbours of a scene normal's plane fit in the full scan (5.2.2)
  Subsampling subsampling = Subsampling::Voxel;

  // --- beyond the thesis (each switchable; the thesis preset turns them off) ----------------
  /// The bin's floor and walls (connected flat patches of at least plane_min_area) taken out of
  /// the sampled scene before voting (planes.hpp). They stay in the scan for ICP and verification.
  bool remove_planes = true;
  /// Smallest flat patch removed, mm^2. 0: the part's own bound on a flat face (boundingFaceArea
  /// of the model, set by the Detector): no face of the part is that large, and a bin floor or
  /// wall seen in pieces between crowded parts still is. (Scaling 6000 mm^2 for the 60 mm part
  /// by diameter^2 gave 17 500 mm^2 for IPD's 102 mm bracket: no plane of its bins was removed.)
  float plane_min_area = 0.0f;
  float plane_tolerance = 1.5f;   ///< largest distance of a plane's point from it, mm
  int candidates_per_point = 1;   ///< model points kept per scene point: 1 is eq. 12's maximum; 8-12 for
                                  ///< bodies of revolution, whose symmetric points share their votes
  /// Each scene point votes once, with the points within vote_radius of it, and its sub-groups reuse its
  /// candidates (false: it votes again in every sub-group with that group's points, as 4.3 does).
  bool local_votes = false;
  /// With local votes, only one point per cube of this side votes (the others are its partners):
  /// fewer, evenly spread reference points, mm. 0: every point votes.
  float voter_spacing = 0.0f;
  /// With voter_spacing: after all sub-groups have run, those that gave no clique of C_n but one
  /// of at least retry_min_clique, and still hold C_n points, run again, each of their points
  /// voting (once; a point's candidates do not depend on when it votes). A part seen mostly by
  /// flat faces gets few right candidates, and half its points left out of the votes can leave
  /// it under C_n. Off by default; on in `fast` (params.cpp).
  bool retry_all_voters = false;
  int retry_min_clique = 3;
  /// A detection of that second pass must also score at least this with the model points seen
  /// at more than grazing_angle left out (Evidence::scoreWithoutGrazing): the side walls of a
  /// part lying flat, seen nearly edge-on, are missing from a scan, and its right pose scores
  /// low (0.37 for bench ipd8-16's copy 5), as low as the wrong poses the pass also finds.
  float retry_min_score = 0.4f;
  float grazing_angle = 80.0f;  ///< degrees between a model normal and the line of sight
  /// With local votes, a point's partners are only one point per cube of this side (a coarser
  /// cloud: fewer features per voter, the same reference points), mm. 0: every point is a partner.
  float partner_spacing = 0.0f;
  /// With several candidates per point, each one at least this far (mm) in the model from every
  /// better-voted one kept: the slots spread over a ring of equal votes (a body of revolution)
  /// instead of bunching at one place of it. 0: the best-voted, however close.
  float candidate_spacing = 0.0f;
  float vote_radius = 40.0f;  ///< partners of a point's local votes lie within this, mm (about 2/3 of the part)
  /// Features whose key lists more than this share of the model's points are not counted (the
  /// pairs of a plane, found on nearly every flat region: many votes, little information). 1: all.
  float max_key_share = 1.0f;
  /// Each feature adds keyWeight(n_M, list length) votes (voting.hpp: the bits its key tells of
  /// the model point, 1 to 12 for 4000 points) instead of one (eq. 9). Off in every preset: with
  /// `fast` on the 18 bench bins it found 227 parts instead of 218 (caps +14, IPD parts -5) in
  /// 1.15x the time, and with 2000 model points and 6 mm voters 234 in 0.85x; but on the PCL milk
  /// scan it gave 7 false poses (scores 0.16-0.37, cliques of 6-7, on the far clutter) besides
  /// the carton, and a min_score of 0.35-0.4 that rejects them lost 19-30 parts of the bins.
  bool weigh_rare_keys = false;
  /// A part that is a body of revolution (findRevolutionAxis, symmetry.hpp) votes for orbits,
  /// rings of model points about its axis, instead of single points; cliques are tested by what
  /// two orbits allow at some turn between them (within e_gmax and revolution_angle_tolerance),
  /// and the pose comes from the axis that fits the clique. A part without such an axis is
  /// matched as before. Off in the thesis preset.
  bool use_revolution = true;
  float revolution_angle_tolerance = 15.0f;  ///< degrees, for each of a pair's three angles
  /// Candidates per point of a body of revolution: at most this many of candidates_per_point
  /// (its votes no longer spread over rings; with 4 instead of 12 `fast` found the same 15 caps
  /// on cap-16 in 44 ms instead of 51, median of 7, its consistency graphs 3x smaller).
  int revolution_candidates = 4;
  /// A part with n-fold symmetry about an axis (3 <= n <= 36; findCyclicSymmetry,
  /// cyclic_symmetry.hpp), and not a body of revolution, votes for classes of a point's n images
  /// instead of single points; two candidates are consistent when some turn of one against the
  /// other gives the scene distance and the pair's angles (within revolution_angle_tolerance),
  /// and the pose takes each clique point's image that fits. Candidates per point as for a body
  /// of revolution (revolution_candidates: with 12, `fast`'s graphs took 3-5x longer for the
  /// same parts). On IPD obj 8 (17 teeth) the default found 108 of 144 parts on the six ipd8
  /// bench bins (92 without), all 100 more than half visible ones (90 without), in 1.2-2.3x
  /// the time; `fast` 176 parts of ten obj 8 bins against 167, ipd8-16 in 45.5 ms warm against
  /// 43.0 (the graph on SIMD lanes). Off in the thesis preset.
  bool use_cyclic_symmetry = true;
  bool refine = true;             ///< point-to-plane ICP of each pose against the full scan
  int icp_iterations = 20;
  /// ICP pairs up at most about this many model points (an even share of them): ICP's cost is
  /// one scan-tree query per model point and iteration. 0: all of them.
  int icp_model_points = 1000;
  /// Before ICP, a pose whose score at the ICP gate (icp_max_distance) on those points is below
  /// min_score is dropped: a wrong clique costs one pass instead of icp_iterations.
  bool prescreen = true;
  /// A pose the pre-screen would drop, but that scores at least prescreen_retry_share of
  /// min_score at the gate, is given prescreen_retry_steps coarse ICP steps (on a quarter of
  /// the ICP points) and screened again; it goes on to ICP if it then passes. A right clique
  /// on few of a part's faces can put it a few mm off: ipd8-16's fully visible copy 1 (2.9 mm
  /// ADD-S) was dropped so. With `fast` on the 18 bench bins, 2 steps found 265 parts instead
  /// of 264, with the same 7 false, refining 436 poses instead of 403; 1 step found none more.
  /// A pose that passes at once is not touched. 0: no retry, the default: with the default
  /// preset 2 steps found 254 parts instead of 253 but 23 false instead of 21 (on IPD obj 0).
  int prescreen_retry_steps = 0;
  float prescreen_retry_share = 0.33f;
  float icp_max_distance = 3.0f;  ///< ICP correspondence gate at the start, mm (shrinks as it converges)
  bool verify = true;             ///< score = share of the posed model's sensor-facing points the scan supports
  float verify_tolerance = 1.0f;  ///< distance within which a scan point supports a model point, mm
  float min_score = 0.15f;        ///< detections scoring less are rejected (verify only)
  /// Scene points are removed (5.2.6) only after a detection scoring at least this; a less
  /// certain one leaves them for later sub-groups, and overlap suppression keeps the better pose.
  /// 0 removes after every detection, as the thesis does.
  float removal_score = 0.8f;
  /// A detection scoring at least this (or removal_score) is a found object: a later clique
  /// whose closed-form pose puts the model in nearly the same place (centroid within 0.1
  /// diameter, no model point turned further) is not verified again (a cap seen in part, found
  /// by each of the sub-groups over it, was refined up to ten times). A different pose of the
  /// same place (a flip, say) is still verified, and the better one kept: a wrong pose found
  /// first does not hide the right one.
  float explain_score = 0.3f;
  /// A clique whose closed-form pose is within this share of that same-place tolerance (0.1
  /// diameter) of a clique pose already verified (refined, or screened out) is not verified
  /// again: its ICP would start from nearly where the other's did. On the 18 bench bins with
  /// `fast` 0.5 found the same 263 parts, and cap-16 refined 28 poses instead of 36 (42 ms
  /// against 48 warm, median of 9); 0.75 lost a cap, and a share of 1 lost 2 parts. 0: each
  /// such clique is verified again.
  float tried_share = 0.5f;
  /// ICP stops when its pose comes within this share of that same-place tolerance of an object
  /// already found, and the hypothesis is dropped as that object again: a cap lying flat and
  /// scoring 0.57 (under removal_score, its points left) was found again by 5 later sub-groups
  /// whose cliques lay 8-16 mm off, each refined for 12-20 steps to the same pose. On the 18
  /// bench bins with `fast` 0.25 found the same 284 parts (8 false), cap-16 in 54.9-59.5 ms
  /// against 58.2-62.7; 0.5 also, with a few poses a little worse; a share of 1 lost ipd8-16's
  /// best pose of a copy (0.81) for a poorer one (0.54). 0: ICP always runs to the end.
  float refound_share = 0.25f;

  // --- limits and determinism --------------------------------------------------------------
  int max_instances = 0;  ///< stop after this many confident detections, report at most this many (0: no limit)
  /// Branch-and-bound nodes per clique search. On the bins of bench/ the same detections came
  /// out with 1000, 5000 and 20 000 nodes (the largest clique is found early; proving it the
  /// largest took up to 200 000 nodes, 0.5 s, on dense graphs), so the search stops at 1000 and
  /// keeps the best found.
  std::uint64_t clique_work_limit = 1000;
  /// A sub-group's largest clique whose pairs fit only a mirror image of the part (pose.hpp:
  /// the distances of 4.5 agree, no rotation does) is refused; the search then runs again
  /// without that clique's pairs, up to this many times (0: the sub-group gives nothing, as
  /// in the thesis preset). A part with a near mirror plane lost most of its sub-groups so: 44
  /// of the 61 that gave no pose in one IPD obj 0 bin. On the 18 bench bins one retry found 274
  /// parts with `fast` (265 without), 268 with the default (253), a false pose more each.
  int mirror_retries = 1;
  std::uint64_t seed = 1;             ///< random sub-sampling seed
  Vec3 viewpoint = Vec3::Zero();      ///< sensor origin in the scan's frame (normals face it)
};

/// The thesis's pipeline as written: random sub-sampling, no refinement, no verification.
DetectionParams thesisPreset();
/// binpose's defaults.
DetectionParams defaultPreset();
/// binpose's defaults, but each scene point votes once (local_votes), only one point per 5 mm
/// cube votes (voter_spacing), with partners one per 8 mm cube (partner_spacing), and keeps its
/// 12 best model points at least 2.7 mm apart (candidate_spacing); cliques of C_n = 6 are
/// accepted, normals fit k = 8 neighbours, a detection scoring 0.6 removes its points
/// (removal_score), and a pose just short of the pre-screen gets 2 coarse ICP steps and
/// another look (prescreen_retry_steps). The measurements behind each: params.cpp.
DetectionParams fastPreset();
/// A preset by name: "thesis", "default" or "fast".
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
