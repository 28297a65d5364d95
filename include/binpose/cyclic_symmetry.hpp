#pragma once
// Beyond the thesis: parts with a discrete symmetry, n turns about an axis (IPD obj 8, a ring
// of 17 teeth). The n images of a model point have the same point pair features, so a scene
// point's votes spread over them, and of the right candidates of a sub-group's points only
// those that happen to agree on the same image fit one rigid pose (4.5): in a flat view of obj 8,
// 4-6 of the 10-14 points with a right candidate. Here a point's candidates are classes of
// images (each class stands for its point in the wedge [0, 2 pi / n)), two candidates are
// consistent when some turn of one against the other gives the scene pair's distance and
// angles, and the pose comes from the image of each clique point that fits them all.
#include <binpose/clique.hpp>
#include <binpose/model_database.hpp>
#include <binpose/pose.hpp>
#include <binpose/symmetry.hpp>
#include <binpose/voting.hpp>

#include <optional>
#include <span>
#include <vector>

namespace binpose {

/// Turns by 2 pi k / order (k = 0..order-1) about the axis map the model onto itself.
struct CyclicSymmetry {
  RevolutionAxis axis;  ///< through axis.point (the model points' centroid)
  int order = 1;
  /// The model's turn by 2 pi k / order about the axis.
  [[nodiscard]] Pose turn(int k) const;
};

/// The largest order n (3 <= n <= max_order) for which one of the model's principal axes
/// (through the centroid) is an axis of n-fold symmetry: turned by each multiple of 2 pi / n,
/// at least 97% of the model points lie within `tolerance` (mm; 0: 1.5 x
/// the sample radius) of a model point. None for a part without (a body of revolution has every
/// order: findRevolutionAxis comes first).
std::optional<CyclicSymmetry> findCyclicSymmetry(const OrientedModel& model, int max_order = 36, float tolerance = 0.0f);

/// The model points grouped into classes of images: a point of the wedge [0, 2 pi / n) about
/// the axis is its own class's member, any other point joins the class of the wedge point
/// nearest its image turned into the wedge (Orbits with cyclic = true: no profile, no lists by
/// key). Votes
/// still go to single points (a class's count would be the most any of its n images has, and
/// a wrong class would draw n times a wrong point's votes: on obj 8, 0.1 candidates a point
/// were left against 4-8); a point's candidates are then classes, each once.
Orbits makeCyclicClasses(const ModelDatabase& db, const CyclicSymmetry& sym);

/// Consistency graph (eq. 13-16) with the symmetry: CP_i and CP_j (distinct scene points; each
/// model point a class member) are linked when at some turn k of CP_j's model point the model
/// pair's distance lies within e_gmax of the scene pair's, and its three angles (normal to
/// normal, each normal to the line joining them; 4.1) within `max_angle_deg` of the scene
/// pair's. The distance alone, tested against n turns, linked 0.6-0.7 of the pairs of a copy's
/// candidates.
Graph cyclicConsistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& scene_normals,
                             const OrientedModel& model, const CyclicSymmetry& sym, float e_gmax, float max_angle_deg,
                             GraphWorkspace* workspace = nullptr);

/// The pose (4.6) of a clique of class members: three anchors (the first point at its own
/// image, the scene point farthest from it, the one farthest from the line through both) each
/// take one of the two images whose distances to the anchors before fit best; the closed form
/// of those three poses each point at its image nearest the scene, and solvePose on all of them
/// gives the fit, the least rms of the four kept. ok = false when every choice is degenerate
/// or a mirror image.
PoseFit solveCyclicPose(const CyclicSymmetry& sym, const Points& model, const Points& scene);

/// solveCyclicPose's buffers, reused by a caller that fits many cliques (a bin's clique fits
/// allocated them thousands of times).
struct CyclicPoseBuffers {
  Points images, chosen, anchor_model, anchor_scene;
  std::vector<float> misfit;
  std::vector<double> pose;  ///< solvePose's
};

/// solveCyclicPose with the caller's buffers; the same fit.
PoseFit solveCyclicPose(const CyclicSymmetry& sym, const Points& model, const Points& scene, CyclicPoseBuffers& buffers);

}  // namespace binpose
