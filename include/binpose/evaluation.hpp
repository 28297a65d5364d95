#pragma once
// Evaluation against exact ground truth (thesis 7.1.3): centroid and angular error, BOP's
// ADD-S and MSSD, all symmetry-aware; one-to-one matching; recall against visible surface.
#include <binpose/detector.hpp>
#include <binpose/simulation.hpp>

#include <string>
#include <vector>

namespace binpose {

/// A part's symmetries in BOP's form (models_info.json): discrete transforms, and continuous
/// rotations about an axis through an offset point.
struct Symmetries {
  std::vector<Pose> discrete;
  struct Axis {
    Vec3 axis, offset;
  };
  std::vector<Axis> continuous;
};

/// The entry `obj_id` of a BOP models_info.json; no file gives no symmetry.
Symmetries readSymmetries(const std::string& models_info_path, const std::string& obj_id);

/// Every symmetry as a transform (identity first): the discrete ones, times the continuous ones
/// sampled every `step_deg` degrees.
std::vector<Pose> symmetryTransforms(const Symmetries& symmetries, float step_deg = 1.0f);

struct PoseErrors {
  float centroid_mm = 0;  ///< |CM_est - CM_true| (eq. 41-42)
  float angle_deg = 0;    ///< Euler axis-angle of R_est^T R_true, least over the symmetries (7.1.3)
  float add_s_mm = 0;     ///< mean distance of an estimated model point to the nearest true one
  float mssd_mm = 0;      ///< max distance of corresponding points, least over the symmetries (BOP)
};

/// The evaluated part: surface samples, centroid, diameter, symmetries.
struct EvalModel {
  Points points;  ///< 2000 surface samples, moved by the poses
  Points dense;   ///< 50000 surface samples, the surface the ADD-S distances are taken to
  Points dense_normals;  ///< their faces' normals
  Vec3 centroid = Vec3::Zero();
  float diameter = 0;
  Symmetries symmetries;
  std::vector<Pose> transforms;  ///< symmetryTransforms(symmetries)
};
EvalModel makeEvalModel(const Mesh& mesh, const Symmetries& symmetries);

PoseErrors poseErrors(const Pose& estimate, const Pose& truth, const EvalModel& model);

struct InstanceResult {
  int truth = -1;          ///< ground-truth instance
  int detection = -1;      ///< matched detection, -1 when missed
  float visible_fraction = 0;  ///< visible surface / whole surface (thesis)
  float visib_fract = 0;       ///< visible pixels / pixels if unoccluded (BOP)
  PoseErrors errors;
};

struct EvaluationReport {
  std::vector<InstanceResult> instances;  ///< one per ground-truth instance
  int detections = 0, matched = 0;
  double recall = 0, precision = 0;
  double recall_over_half_visible = 0;  ///< over instances with BOP visib_fract > 0.5
  double mean_centroid_mm = 0, mean_angle_deg = 0, mean_add_s_mm = 0, mean_mssd_mm = 0;  ///< over matches
  std::vector<int> visible_bin_total, visible_bin_found;  ///< 10 bins of visible fraction
  double total_ms = 0, ms_per_object = 0;
};

/// Matches detections to instances one to one (greedy by ADD-S, a detection at most once,
/// accepted under `threshold` x diameter) and sums up.
EvaluationReport evaluate(const GroundTruth& truth, const std::vector<Pose>& detections, double total_ms,
                          const EvalModel& model, float threshold = 0.1f);

}  // namespace binpose
