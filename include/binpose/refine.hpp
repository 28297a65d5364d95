#pragma once
// Beyond the thesis: pose refinement by ICP and a verification score, both against the full scan.
#include <binpose/pixel_neighbours.hpp>
#include <binpose/point_grid.hpp>
#include <binpose/planes.hpp>
#include <binpose/pose.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <vector>

namespace binpose {

struct IcpParams {
  int iterations = 20;
  float max_distance = 3.0f;  ///< correspondence gate at the start, mm; shrinks to min_distance
  float min_distance = 1.0f;  ///< smallest gate, mm
  Vec3 viewpoint = Vec3::Zero();
  /// When set: given the pose after each step, true ends ICP there (that pose is returned).
  std::function<bool(const Pose&)> stop;
  std::vector<Pose>* path = nullptr;  ///< when set: each step's pose is appended
  /// When set: the PixelNeighbours of the very cloud whose points are the scan (a depth image's),
  /// asked first for each model point's nearest scan point: the same pairs as the grid's, faster
  /// where the pixels prove them (most points of a part the scan sees).
  const PixelNeighbours* pixels = nullptr;
};

/// Oriented model points, without the rest of a model's description.
struct OrientedPoints {
  Points points, normals;
};

/// About `count` of the model's points with their normals (all when 0): every k-th, an even
/// share, as the Poisson-disk order is spatially random. ICP's cost is one scan-grid query per
/// model point and iteration; a thousand points fix a pose as well as four thousand.
OrientedPoints evenShare(const Points& points, const Points& normals, std::size_t count);

namespace detail {
struct OrientedLanes;
}

/// Oriented model points made ready once for refinePose and SceneEvidence::evaluate, which pose
/// them four at a time (SIMD lanes) and linearise ICP about their centre: the coordinate arrays
/// (all points, and ICP's coarse share), the centre and the reach, built once instead of at
/// every call (cap-16 makes about 80 ICP runs and 90 scores).
class PreparedModel {
 public:
  /// One normal per point (else Error).
  PreparedModel(Points points, Points normals);
  ~PreparedModel();
  PreparedModel(PreparedModel&&) noexcept;
  PreparedModel& operator=(PreparedModel&&) noexcept;
  [[nodiscard]] const Points& points() const { return points_; }
  [[nodiscard]] const Points& normals() const { return normals_; }
  [[nodiscard]] const Vec3& centre() const { return centre_; }  ///< the points' mean
  [[nodiscard]] double reach() const { return reach_; }         ///< farthest point from the centre, mm (at least 1e-3)
  [[nodiscard]] const detail::OrientedLanes& lanes() const { return *lanes_; }
  [[nodiscard]] const detail::OrientedLanes& coarseLanes() const { return *coarse_; }  ///< ICP's first steps' share

 private:
  Points points_, normals_;
  Vec3 centre_;
  double reach_;
  std::unique_ptr<detail::OrientedLanes> lanes_, coarse_;
};

/// evenShare's `count` points (all when 0), made ready as a PreparedModel.
PreparedModel preparedShare(const Points& points, const Points& normals, std::size_t count);

/// Point-to-plane ICP (Chen & Medioni) of the model's sensor-facing points against the scan,
/// with the model's normals as the planes; each step a linearised 6-dof least-squares solve.
/// Returns the refined pose (the input pose when too few points pair up).
Pose refinePose(const Pose& pose, const PreparedModel& model, const Points& scan, const PointGrid& scan_grid,
                const IcpParams& params);
/// The same for points and normals not made ready.
Pose refinePose(const Pose& pose, const Points& model_points, const Points& model_normals, const Points& scan,
                const PointGrid& scan_grid, const IcpParams& params);

/// The final refinement of a detection (src/polish.cpp).
struct PolishParams {
  int iterations = 5;         ///< at most this many steps (fewer once converged)
  float max_distance = 1.0f;  ///< pairs farther apart are left out, mm (the verification tolerance)
  Vec3 viewpoint = Vec3::Zero();
};

/// The scan as polishPose pairs it: every point, and oriented points (the scan's voting points
/// with their normals), each with a grid of them. A scan point takes the normal of the nearest
/// oriented point within `oriented_reach` mm, and has none (pairs with nothing) without one: the
/// voting points leave out the bin's floor and walls.
struct PolishScan {
  const Points& points;
  const PointGrid& grid;
  const Points& oriented_points;
  const Points& oriented_normals;
  const PointGrid& oriented_grid;
  float oriented_reach;
};

/// Point-to-plane ICP from a pose already close, with pairs both ways: each sensor-facing model
/// point with its nearest scan point, and each scan point near the part with its nearest
/// sensor-facing model point; a pair counts only where the scan's normal there and the model's
/// agree within 60 degrees (normal compatibility, Rusinkiewicz & Levoy 2001). On a noisy scan,
/// model-to-scan pairs alone (refinePose) settle a pose about a noise sigma away from the truth:
/// each model point picks the noisy scan point nearest to it, and at the part's outline the
/// floor or a neighbour beside it (docs/design.md). `model_grid`: a grid of model.points().
Pose polishPose(const Pose& pose, const PreparedModel& model, const PointGrid& model_grid, const PolishScan& scan,
                const PolishParams& params);

/// What the scan says about a posed model's sensor-facing points.
struct Evidence {
  int facing = 0;      ///< model points facing the sensor and not hidden by the part itself
  int supported = 0;   ///< ... with a scan point within the tolerance
  int contradicted = 0;  ///< ... where the scan sees a surface clearly behind them (free space)
  int occluded = 0;      ///< ... where the scan sees a surface clearly in front of them
  int on_background = 0; ///< ... on a background plane the scan shows there (not supported)
  /// Of the counts above, those of points seen at more than the grazing angle
  /// (SceneEvidence::setGrazingAngle; none without one).
  int grazing = 0, grazing_supported = 0, grazing_contradicted = 0;
  /// (supported - contradicted) / facing, in [0, 1]: near 1 for a fully visible, correct pose.
  [[nodiscard]] float score() const {
    return facing == 0 ? 0.0f : std::max(0.0f, float(supported - contradicted) / float(facing));
  }
  /// The share of the facing points that the scan should show where the pose is right (not
  /// occluded, not on a background plane, where the scan cannot tell part from bin) that it
  /// supports: near the sensor's support rate for a right pose however much of it is hidden,
  /// low for a pose that the scan meets only in passing.
  [[nodiscard]] float visibleSupport() const {
    const int expected = facing - occluded - on_background;
    return expected <= 0 ? 0.0f : static_cast<float>(supported) / static_cast<float>(expected);
  }
  /// The score of the points seen at the grazing angle or less: a sensor drops surface seen
  /// nearly edge-on (the side walls of a part lying flat), which the score counts as missing.
  [[nodiscard]] float scoreWithoutGrazing() const {
    const int seen = facing - grazing;
    const int net = (supported - grazing_supported) - (contradicted - grazing_contradicted);
    return seen == 0 ? 0.0f : std::max(0.0f, float(net) / float(seen));
  }
};

/// How far a posed model lies inside the bin's planes (SceneEvidence::sinking): on the side of a
/// floor, a wall or a table away from the sensor, within the plane's extent, where no part can be.
struct Sinking {
  int points = 0;      ///< model points judged
  int sunk = 0;        ///< ... inside a background plane (SceneEvidence::sinking)
  /// sunk / points (0 when none is judged).
  [[nodiscard]] float share() const { return points == 0 ? 0.0f : static_cast<float>(sunk) / static_cast<float>(points); }
};

/// What the scan shows just beyond a posed model's outline, as the sensor sees it: where the scan
/// there lies on the part's own surface continued (its tangent plane), the scan's surface goes on
/// where the part ends, and the part explains only a piece of it.
struct OutlineEvidence {
  int judged = 0;     ///< outline steps with a visible part edge and a scan surface beyond it
  /// ... where that surface lies on the part's tangent plane, continued (within two tolerances:
  /// the plane is extrapolated, and both it and the scan are noisy), but a background plane there
  /// (outline's `on_bin`)
  int continued = 0;
  /// ... where it lies clearly behind that plane (farther than two tolerances), or (`on_bin`) on
  /// a background plane that the part stands clear of: the part stands out of what lies behind it.
  int dropped = 0;
  /// continued / judged (0 when none is judged).
  [[nodiscard]] float share() const { return judged == 0 ? 0.0f : static_cast<float>(continued) / static_cast<float>(judged); }
  /// dropped / judged (0 when none is judged).
  [[nodiscard]] float droppedShare() const {
    return judged == 0 ? 0.0f : static_cast<float>(dropped) / static_cast<float>(judged);
  }
};

/// The scan as seen from its viewpoint: a grid for support, and a range image (nearest range
/// per direction, built from the points themselves, so unorganized scans work too) for
/// free-space contradictions.
class SceneEvidence {
 public:
  /// `scan` and `grid` (a grid of it) must outlive this. `pixels`, when given, is the scan's
  /// PixelNeighbours, which must outlive this too: the scan
  /// spacing's sample and evaluate()'s searches ask it first (the same answers as the grid,
  /// faster).
  SceneEvidence(const Points& scan, const PointGrid& grid, const Vec3& viewpoint, const PixelNeighbours* pixels = nullptr);
  /// `background`: the bin's planes (planes.hpp; none by default). A model point within
  /// `background_tolerance` of one is not supported by the scan there: the bin is seen, not the
  /// part. Without this an L-shaped part fits the corner of floor and wall and scores as if it
  /// were there. A model point clearly behind one, where the scan shows the plane in front of
  /// it, is contradicted: a part cannot lie inside the floor or a wall. Set apart from the
  /// constructor: the planes may be found while it runs.
  void setBackground(std::vector<Plane> background, float background_tolerance) {
    background_ = std::move(background);
    background_tolerance_ = background_tolerance;
  }
  /// The background planes set by setBackground.
  [[nodiscard]] const std::vector<Plane>& background() const { return background_; }
  /// Model points whose normal makes more than `degrees` with the line of sight are counted
  /// apart as grazing (Evidence::grazing). 90, the default: none.
  void setGrazingAngle(float degrees) { cos_grazing_ = std::cos(degrees * float(M_PI) / 180.0f); }
  /// The scan's sampling across the surface, mm (0, the default: none). A model point of a
  /// right pose lies up to about 0.7 point spacings from the nearest scan point, however
  /// small the noise; where `lateral` exceeds evaluate()'s tolerance, a scan point also
  /// supports a model point when it lies within the tolerance of the model point's tangent
  /// plane and within `lateral` of it along that plane. The slack is along the surface only:
  /// a surface in front of or behind the part counts no more than before.
  void setLateralSlack(float lateral) { lateral_ = lateral; }
  /// `model_spacing`: the model's sample spacing, mm, for its self-occlusion test (0: none).
  /// The scan points that support the pose are appended to `support` when it is given.
  [[nodiscard]] Evidence evaluate(const Pose& pose, const PreparedModel& model, float tolerance, float model_spacing,
                                  std::vector<std::uint32_t>* support = nullptr) const;
  /// The same for points and normals not made ready.
  [[nodiscard]] Evidence evaluate(const Pose& pose, const Points& model_points, const Points& model_normals,
                                  float tolerance, float model_spacing,
                                  std::vector<std::uint32_t>* support = nullptr) const;
  /// Every model point posed, hidden or not, against the background planes (Sinking): a pose
  /// sunk into the floor that the scan shows around it, though the part above hides the floor
  /// beneath it from the free-space test. A point is sunk when it lies behind a plane by more
  /// than `margin` and at most `reach` (mm), its foot on the plane's extent (Plane::covers), and
  /// over no plane parallel to it and deeper that the scan shows there. Planes whose extent is
  /// smaller than (2 reach)^2 are not judged.
  [[nodiscard]] Sinking sinking(const Pose& pose, const PreparedModel& model, float margin, float reach) const;
  /// The posed model's facing points not hidden by the part itself (Sinking::points) that lie
  /// behind `face` where the scan shows that plane in front of them (Sinking::sunk), as
  /// evaluate() counts a point inside a background plane; those clearly behind the part's own
  /// front are not counted (the plane in front of them may be the part's own face). `face`: the
  /// plane of the scan points that support the pose, when they lie on one. A part cannot lie
  /// inside a surface that goes on from its own face: a pose that lays one face on a patch of a
  /// table, its body sunk into it, which a warped or noisy table (no background plane there) does
  /// not give away otherwise.
  [[nodiscard]] Sinking sunkBehind(const Plane& face, const Pose& pose, const PreparedModel& model, float tolerance,
                                   float model_spacing) const;
  /// The scan beyond the posed model's outline (OutlineEvidence; src/outline.cpp): a wrong pose
  /// that lays one face of the part on a larger surface of the scan (the top of another part,
  /// the floor) is supported wherever it lies, but the surface goes on past its edges.
  /// `model_spacing` (> 0): the model's sample spacing, mm. `on_bin`: a pose laid on one face
  /// (face_hypotheses.hpp), which may be a thin part lying on the bin: a background plane beyond
  /// its edge that it stands clear of counts as dropped, however near its face's plane.
  [[nodiscard]] OutlineEvidence outline(const Pose& pose, const PreparedModel& model, float tolerance,
                                        float model_spacing, bool on_bin = false) const;

 private:
  /// Range-image cell of the direction (u, v) (x / z and y / z in the image frame), or -1
  /// outside the image.
  [[nodiscard]] long cellAt(float u, float v) const;
  /// Whether `beyond` (a scan point) lies on a background plane that `part` (a model point)
  /// stands clear of, on the sensor's side: the bin seen past the edge of a part lying on it.
  [[nodiscard]] bool standsOnBackground(const Vec3& part, const Vec3& beyond) const;
  /// Whether model point p (at `range` from the viewpoint) lies clearly behind a background
  /// plane that the scan shows where the line of sight crosses it (`seen_range`: the scan's
  /// nearest range in p's direction): inside the floor or a wall, where no part can be.
  [[nodiscard]] bool insideBackground(const Vec3& p, float range, float seen_range, float tolerance) const;

  const Points& scan_;
  const PointGrid& grid_;
  const PixelNeighbours* pixels_;
  Vec3 viewpoint_;
  std::vector<Plane> background_;
  float background_tolerance_ = 0;
  float cos_grazing_ = 0;  ///< cosine of the grazing angle
  float lateral_ = 0;      ///< setLateralSlack's
  Eigen::Matrix3f to_view_;  ///< rotation into the image frame (z along the scan's mean direction)
  float bin_ = 0;            ///< cell size in tangent-plane units
  float u0_ = 0, v0_ = 0;
  long width_ = 0, height_ = 0;
  std::vector<float> nearest_;  ///< per cell, the nearest range seen (infinity when empty)
};

}  // namespace binpose
