#pragma once
// How a part's symmetry enters matching, behind one interface: none (point to point, thesis
// 4.5-4.6), a body of revolution (votes for orbits, symmetry.hpp) or n-fold symmetry about an
// axis (candidates as classes of images, cyclic_symmetry.hpp).
#include <binpose/clique.hpp>
#include <binpose/cyclic_symmetry.hpp>
#include <binpose/model_database.hpp>
#include <binpose/pose.hpp>
#include <binpose/symmetry.hpp>
#include <binpose/voting.hpp>

#include "stage_settings.hpp"

#include <optional>
#include <span>
#include <vector>

namespace binpose {

/// A clique's points gathered for the pose fit (kept between calls: no allocation per clique).
struct CliqueBuffers {
  Points model, scene, scene_normals;
  std::vector<std::uint32_t> model_ids;
  GraphWorkspace graph;      ///< the consistency graphs' rows'
  CliqueWorkspace clique;    ///< maximumClique's
  CyclicPoseBuffers cyclic;  ///< solveCyclicPose's
  std::vector<double> pose;  ///< solvePose's
};

/// A plane that maps the model onto itself: x -> x - 2 (normal . x - d) normal.
struct MirrorPlane {
  Vec3 normal = Vec3::UnitZ();
  float d = 0;
  [[nodiscard]] Vec3 reflect(const Vec3& x) const { return x - 2.0f * (normal.dot(x) - d) * normal; }
};

/// The model's mirror plane, when it has one: of the three planes through its centroid across its
/// principal axes, the one whose reflection of the model points lies nearest the model, when that
/// is within one sample radius (RMS of each reflected point's distance to the nearest model
/// point; a sampled, exactly symmetric part gives about half). None otherwise.
std::optional<MirrorPlane> mirrorPlane(const OrientedModel& model);

class PartSymmetry {
 public:
  enum class Kind { None, Revolution, Cyclic };

  /// The model's symmetry as the parameters allow it (use_revolution, use_cyclic_symmetry); a
  /// body of revolution is looked for first.
  PartSymmetry(const ModelDatabase& db, const StageSettings& p);

  [[nodiscard]] Kind kind() const { return kind_; }
  /// What the votes go to: orbits or classes of images (null: model points).
  [[nodiscard]] const Orbits* votingOrbits() const;
  /// The body of revolution's orbits (null for another kind).
  [[nodiscard]] const Orbits* orbits() const { return orbits_ ? &*orbits_ : nullptr; }
  /// The n-fold symmetry (null for another kind).
  [[nodiscard]] const CyclicSymmetry* cyclic() const { return cyclic_ ? &*cyclic_ : nullptr; }
  /// Candidates kept per scene point: a symmetric part's votes do not spread over its images.
  [[nodiscard]] int candidatesPerPoint(const StageSettings& p) const;
  /// The consistency graph of 4.5 (eq. 13-16), or its symmetric form.
  [[nodiscard]] Graph consistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& scene_normals,
                                       const OrientedModel& model, const StageSettings& p, GraphWorkspace& workspace) const;
  /// The closed-form poses of a clique's pairs (4.6), best first: one, or for a body of
  /// revolution both axis signs where the normals leave it open. None when there is no pose.
  /// `reflected`: the pairs' model points taken in the part's mirror plane (mirror()), for a
  /// clique that fits only a mirror image of the part.
  [[nodiscard]] std::vector<PoseFit> solve(std::span<const Correspondence> clique, const Points& scene,
                                           const Points& scene_normals, const Points& model, CliqueBuffers& buffers,
                                           bool reflected = false) const;
  /// True when a refused (mirror-image) clique may give way to the next largest.
  [[nodiscard]] bool retriesMirrors() const { return kind_ != Kind::Revolution; }
  /// The part's mirror plane, for a part without another symmetry that has one (mirrorPlane).
  [[nodiscard]] const std::optional<MirrorPlane>& mirror() const { return mirror_; }

 private:
  Kind kind_ = Kind::None;
  std::optional<Orbits> orbits_;
  std::optional<CyclicSymmetry> cyclic_;
  std::optional<Orbits> classes_;  ///< cyclic_'s classes of images
  std::optional<MirrorPlane> mirror_;
};

}  // namespace binpose
