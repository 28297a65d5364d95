#pragma once
// Beyond the thesis: parts that are bodies of revolution (the built-in cap). Their point pair
// features do not change when a point moves round the axis, so a scene point's votes spread
// over a whole ring of model points (an orbit), and the rigid consistency of 4.5 needs the one
// ring point of the right turn. Here votes are taken per orbit, cliques are tested by what a
// pair of orbits allows at some turn between them, and the pose (its turn about the axis free)
// comes from the axis that fits the clique.
#include <binpose/clique.hpp>
#include <binpose/model_database.hpp>
#include <binpose/pose.hpp>
#include <binpose/voting.hpp>

#include <optional>
#include <span>
#include <vector>

namespace binpose {

class KdTree;

/// Two unit vectors completing `z` (unit) to a right-handed basis (the same for the same z).
void basisAround(const Vec3& z, Vec3& x, Vec3& y);

/// The points' centroid and principal axes: the eigenvectors (unit columns) of their
/// covariance, with its eigenvalues, ascending.
struct PrincipalAxes {
  Vec3 centre = Vec3::Zero();
  Eigen::Vector3f values = Eigen::Vector3f::Zero();
  Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();
};
PrincipalAxes principalAxes(const Points& points);

/// True when the turn by `angle` (rad) about `axis` (unit) through `centre` keeps at least
/// 97% of the points within `tolerance` (mm) of one of them (`tree`: over the points).
bool turnKeepsShape(const Points& points, const KdTree& tree, const Vec3& centre, const Vec3& axis, float angle,
                    float tolerance);

/// The axis of a body of revolution, in the model's frame.
struct RevolutionAxis {
  Vec3 point = Vec3::Zero();      ///< a point of the axis (the model points' centroid), mm
  Vec3 direction = Vec3::UnitZ(); ///< unit
};

/// The axis about which the model is a body of revolution, if one of its three principal axes
/// (through the centroid) is: at each of several turns about it, at least 97% of the turned
/// model points lie within `tolerance` (mm; 0: 1.5 x the sample radius) of a model point.
/// None for a part with no such axis (or only discrete symmetries).
std::optional<RevolutionAxis> findRevolutionAxis(const OrientedModel& model, float tolerance = 0.0f);

/// An oriented point in the axis's half-plane: what a turn about the axis keeps.
struct ProfilePoint {
  float r = 0, z = 0;    ///< distance from the axis and height along it, mm
  float nr = 0, nz = 0;  ///< the normal's radial and axial components
};
ProfilePoint profileOf(const RevolutionAxis& axis, const Vec3& point, const Vec3& normal);

/// The model points grouped into orbits (rings about the axis): those in one cell of side
/// `cell` (mm) of the (r, z) half-plane whose normals tilt alike (the same octant). With the
/// database's lists turned into lists of orbits (each orbit once per key): about 20 times fewer
/// entries for the cap, each scene point's votes counted over its ~130 orbits.
struct Orbits {
  RevolutionAxis axis;
  std::vector<std::uint32_t> of;      ///< per model point: its orbit
  std::uint32_t count = 0;            ///< orbits
  std::vector<std::uint32_t> member;  ///< per orbit: its lowest model point, which stands for it
  std::vector<ProfilePoint> profile;  ///< per orbit: its points' mean (normal tilt renormalised)
  /// Classes of a discrete symmetry's images (cyclic_symmetry.hpp), not rings: votes go to
  /// model points, and a point's candidates are its classes' members (no profile, no lists by
  /// key).
  bool cyclic = false;
  /// An orbit's (r, z, 0): distances between orbits in the axis's half-plane.
  [[nodiscard]] Vec3 inPlane(std::uint32_t orbit) const { return {profile[orbit].r, profile[orbit].z, 0.0f}; }
  /// The orbits of the model points under `key` (ModelDatabase::lookup), ascending.
  [[nodiscard]] std::span<const ModelDatabase::PointId> lookup(std::uint32_t key) const {
    if (key + 1 >= offsets.size()) return {};
    return {entries.data() + offsets[key], entries.data() + offsets[key + 1]};
  }
  std::vector<std::uint32_t> offsets;  ///< per key of the database, into entries
  std::vector<ModelDatabase::PointId> entries;
};
Orbits makeOrbits(const ModelDatabase& db, const RevolutionAxis& axis, float cell);

/// Consistency graph for a body of revolution (each CP's model point read as its orbit): CP_i
/// and CP_j (distinct scene points) are linked
/// when some turn between their orbits gives the scene pair's distance (within e_gmax) and the
/// scene pair's three angles (normal to normal, each normal to the line joining them) within
/// `max_angle_deg`. The four values depend on the turn only through its cosine, which the
/// distance fixes (the model pair's features of 4.1 at that turn).
Graph revolutionConsistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& scene_normals,
                                 const Orbits& orbits, float e_gmax, float max_angle_deg);

/// The pose of a body of revolution from oriented scene points and their model points (read
/// as their orbits): the scene axis that gives each point its model point's normal tilt, height and radius, least
/// squares; the turn about it set so that the first model point lands on the first scene point.
/// rms: the points' radius and height residuals, mm. ok = false for a degenerate set.
PoseFit solveRevolutionPose(const Orbits& orbits, std::span<const std::uint32_t> model_ids, const Points& model_points,
                            const Points& scene, const Points& scene_normals);
/// Every pose solveRevolutionPose weighs, best (least rms) first: two where the normals leave
/// the axis's sign free (all the points on faces parallel to the axis, the side of a cylinder),
/// for the scan to decide between; none for a degenerate set.
std::vector<PoseFit> solveRevolutionPoses(const Orbits& orbits, std::span<const std::uint32_t> model_ids,
                                          const Points& model_points, const Points& scene, const Points& scene_normals);

}  // namespace binpose
