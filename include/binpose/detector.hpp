#pragma once
// Online recognition (thesis chapters 4-5): scan -> preprocess -> sub-groups -> votes ->
// correspondences -> clique -> pose -> detections, removing each found object's points.
#include <binpose/cyclic_symmetry.hpp>
#include <binpose/model_database.hpp>
#include <binpose/params.hpp>
#include <binpose/pose.hpp>
#include <binpose/refine.hpp>
#include <binpose/symmetry.hpp>

#include <memory>
#include <optional>
#include <vector>

namespace binpose {

struct Detection {
  Pose pose;               ///< model -> scan frame: p_scan = R p_model + t, mm
  float score = 0;         ///< (supported - contradicted) / sensor-facing model points (see Evidence)
  int correspondences = 0; ///< size of the accepted clique |C| (0: found by a flat face, face_hypotheses)
  float rms = 0;           ///< residual of the clique's closed-form fit, mm
};

/// Wall time of each stage, ms. vote_ms: all voting (4.3-4.4); match_ms: clique, pose and
/// duplicate suppression. Sub-groups run side by side: their wall time is shared among voting,
/// matching and refinement in proportion to their threads' time in each.
struct DetectionTiming {
  double preprocess_ms = 0, vote_ms = 0, match_ms = 0, refine_ms = 0, total_ms = 0;
};

struct DetectionResult {
  std::vector<Detection> detections;  ///< best first (by score when verifying, else in order found)
  DetectionTiming timing;
  std::size_t scene_points = 0;    ///< points of the scan
  /// A depth image's pixels used: every pixel_stride-th of every pixel_stride-th row (2 or 4 where
  /// each depth is copied over a block of pixels, as a registration to a sharper camera gives: the
  /// copies add no independent depth and hide the noise).
  int pixel_stride = 1;
  std::size_t flying_points = 0;   ///< ... of the points kept, flying pixels between two surfaces, dropped (a depth image's)
  std::size_t sampled_points = 0;  ///< oriented points after sub-sampling
  float noise_mm = 0;              ///< the scan's noise, 1 sigma, measured on it (plane-fit residuals)
  int k_normals = 0;               ///< the normals' neighbours used (k_normals, raised for a noisy scan)
  float normal_radius = 0.0f;      ///< mm: the normals fitted to every point within it (a very noisy scan; 0: k_normals)
  float least_score = 0;           ///< the least score reported: min_score, raised on a rough scan (0: not verified)
  std::size_t plane_points = 0;    ///< ... of them on large planes (floor, walls), left out of voting
  std::size_t subgroups = 0;       ///< sub-groups created
  std::size_t subgroups_run = 0;   ///< sub-groups that went through voting
  std::size_t subgroups_retried = 0;  ///< sub-groups run again with all their points voting (retry_all_voters)
  std::size_t hypotheses = 0;      ///< clique poses that reached verification
  std::size_t refined = 0;         ///< ... that passed the pre-screen and went through ICP
  std::size_t refound = 0;         ///< ... that ICP brought to an object already found (refound_share)
};

/// A detection with the scan points that support it.
struct Hypothesis {
  Detection detection;
  std::vector<std::uint32_t> support;  ///< sorted, distinct scan point indices
};

/// Which verification test refuses a pose (Detector::check), in the order they are asked.
enum class Refusal {
  none,             ///< it stands: the detector would report it
  score,            ///< its score is under the least score reported (min_score, raised on a rough scan)
  visible_support,  ///< the scan supports less than min_visible_support of what it could show of it
  sunk,             ///< it lies inside the bin's floor, a wall or the table the scan shows
  behind_face,      ///< its body hides behind the plane of the one face the scan shows of it
  outline,          ///< the scan goes on past its outline, or does not fall away behind it
};

/// Refusal's name: "none", "score", "visible_support", "sunk", "behind_face", "outline".
const char* refusalName(Refusal r);

/// What verification makes of one given pose (Detector::check): why a part known to lie there
/// is, or is not, reported.
struct PoseCheck {
  Pose refined;                      ///< the given pose after ICP (5.2.6), model -> scan, mm
  float moved_mm = 0;                ///< how far ICP moved the model's centroid, mm
  float score = 0;                   ///< Detection::score of the refined pose
  float visible_support = 0;         ///< Evidence::visibleSupport of the refined pose
  Evidence evidence;                 ///< its counts
  Refusal as_found = Refusal::none;  ///< as a clique's pose is judged
  Refusal as_laid = Refusal::none;   ///< as a pose laid on one flat face is judged (face_hypotheses)
};

class ModelShape;
class PartSymmetry;
struct ModelFace;
struct StageSettings;

class Detector {
 public:
  /// `params` in absolute units (see scaledToModel); validated here.
  Detector(const ModelDatabase& db, const DetectionParams& params);
  /// Every value of the stages given (src/stage_settings.hpp: for tests and benchmarks of the
  /// project, which show what the internal values do); validated here.
  Detector(const ModelDatabase& db, const StageSettings& settings);
  ~Detector();
  Detector(Detector&&) noexcept;

  /// Every instance of the model in the scan. An empty scan gives no detection.
  [[nodiscard]] DetectionResult detect(const PointCloud& scan) const;
  /// Each of `poses` (model -> scan, mm; where a part is known to lie, say) refined and judged
  /// as detect() judges its own: on the same prepared scan, by the same tests. A pose that
  /// stands but was not detected was never found by the search; one that is refused names the
  /// test. Needs verification on (DetectionParams::verify); an empty scan is an error.
  [[nodiscard]] std::vector<PoseCheck> check(const PointCloud& scan, const std::vector<Pose>& poses) const;

  /// The user's values the detector runs with.
  [[nodiscard]] const DetectionParams& params() const;
  /// Every value of the stages (src/stage_settings.hpp), in absolute units.
  [[nodiscard]] const StageSettings& settings() const { return *settings_; }
  /// The model's orbits when it is matched as a body of revolution (use_revolution), else null.
  [[nodiscard]] const Orbits* orbits() const;
  /// The model's n-fold symmetry when it is matched by classes of images (use_cyclic_symmetry), else null.
  [[nodiscard]] const CyclicSymmetry* cyclicSymmetry() const;

 private:
  const ModelDatabase& db_;
  std::unique_ptr<const StageSettings> settings_;
  PreparedModel icp_model_;                       ///< the model points ICP pairs up (icp_model_points of them)
  PreparedModel prescore_model_;                  ///< a share of those, for the pre-screen's score at ICP's gate
  PreparedModel scored_model_;                    ///< all the model points, for the score
  std::unique_ptr<const PartSymmetry> symmetry_;  ///< none, a body of revolution, or n-fold symmetry
  std::unique_ptr<const ModelShape> shape_;  ///< removal, same-pose and overlap tests
  std::unique_ptr<const std::vector<ModelFace>> faces_;  ///< the model's flat faces (face_hypotheses)
  std::vector<Pose> flips_;  ///< the model's near-symmetric half turns (reseat_weak)
  std::vector<Pose> quiet_flips_;  ///< ... with those laying a flat face on itself, tried on a quiet scan
};

}  // namespace binpose
