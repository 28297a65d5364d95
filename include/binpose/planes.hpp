#pragma once
// Beyond the thesis: the bin's floor and walls (and a table under the parts) taken out of the
// sampled scene before voting. Their points pair with nothing on the part, yet cost as much to
// vote as the part's own points and feed the clique search with wrong correspondences.
#include <binpose/types.hpp>

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace binpose {

struct PlaneParams {
  float min_area = 6000.0f;   ///< smallest connected flat patch removed, mm^2 (larger than any face of the part)
  float tolerance = 1.5f;     ///< largest distance of a point from the plane, mm
  /// A band about a plane narrower than the tolerance, mm (0, or as wide: none), for a scan far
  /// quieter than the tolerance. There a plane tilted through two parallel surfaces a few
  /// millimetres apart (a floor and the insides of caps lying open side up on it) holds as many
  /// points within the tolerance as either surface alone, in stripes. With the band, the best
  /// hypotheses are refitted to their points within it and compared on how many lie within it
  /// (LO-RANSAC), a plane is refitted to its inliers within it, and a background plane with a
  /// parallel one just behind it is a layer of parts on that one. The detector sets it to 3 sigma
  /// of the scan's noise.
  float fit_band = 0.0f;
  float max_angle = 0.35f;    ///< largest angle of a point's normal from the plane's normal, radians (20 degrees)
  float link = 10.0f;         ///< points closer than this are connected within one patch, mm
  /// Background only: a plane that hides more than this share of the points behind its extent
  /// (farther than 3 tolerances on the side away from the sensor, their foot on the plane within
  /// its inliers' bounding rectangle), and more than this share of its inliers' count seen
  /// through it (their line of sight crossing it where its inliers lie), is a layer of parts,
  /// not the bin.
  float max_behind = 0.02f;
  /// A background plane's extent (Plane::extent) bridges holes up to this wide, mm: what the
  /// parts lying on it hide of it.
  float hole = 0.0f;
  Vec3 viewpoint = Vec3::Zero();  ///< the sensor's position, mm (normals face it)
  int max_planes = 8;         ///< planes looked for, largest first
  int trials = 300;           ///< RANSAC hypotheses per plane (one oriented point each)
  std::uint64_t seed = 1;
};

class PlaneFootprint;

/// A plane n . x = d (n a unit vector, d in mm).
struct Plane {
  Vec3 normal = Vec3::UnitZ();
  float d = 0;
  /// Where the scan shows the plane (largePlanes sets it on the planes it finds; none: everywhere).
  std::shared_ptr<const PlaneFootprint> extent;
  /// x's distance from the plane, positive on the normal's side, mm.
  [[nodiscard]] float side(const Vec3& x) const { return normal.dot(x) - d; }
  [[nodiscard]] float distance(const Vec3& x) const { return std::abs(side(x)); }
  /// Whether x's foot on the plane lies on its extent (PlaneFootprint::covers).
  [[nodiscard]] bool covers(const Vec3& x) const;
};

/// A plane's inliers' footprint on it: cells (u, v along the plane) of side `cell` or more (at
/// most about 4 M cells), set where an inlier lies or in a gap of up to two cells between such
/// cells.
class PlaneFootprint {
 public:
  /// `hole`: covers() bridges holes up to this wide, mm.
  PlaneFootprint(const Points& points, std::span<const std::uint32_t> inliers, const Plane& plane, float cell, float hole);
  [[nodiscard]] bool empty() const { return on_.empty(); }
  /// The set cells' area, mm^2.
  [[nodiscard]] float area() const { return area_; }
  /// Whether p's foot on the plane lies within the inliers' bounding rectangle.
  [[nodiscard]] bool within(const Vec3& p) const {
    const float a = u_.dot(p), b = v_.dot(p);
    return a >= u0_ && a <= u1_ && b >= v0_ && b <= v1_;
  }
  /// Whether p's foot lies within that rectangle on a set cell.
  [[nodiscard]] bool on(const Vec3& p) const { return within(p) && on_[cell(p)] != 0; }
  /// Whether p's foot lies on a set cell or in a hole of the footprint, with set cells within
  /// `hole` of it along all four directions of the grid (what a part lying on a floor hides of
  /// it; not the inside of a bin's rim, nor a bay in its edge).
  [[nodiscard]] bool covers(const Vec3& p) const { return within(p) && covered_[cell(p)] != 0; }

 private:
  [[nodiscard]] std::size_t cell(const Vec3& p) const;
  Vec3 u_, v_;
  float side_ = 0, area_ = 0, u0_ = INFINITY, v0_ = INFINITY, u1_ = -INFINITY, v1_ = -INFINITY;
  long cols_ = 0, rows_ = 0;
  std::vector<char> on_, covered_;
};

inline bool Plane::covers(const Vec3& x) const { return extent == nullptr || extent->covers(x); }

/// The least-squares plane of points[which] (fitPlaneNormal, eq. 30-38, through their centroid);
/// false for fewer than three points or a degenerate fit.
bool fitPlane(const Points& points, std::span<const std::uint32_t> which, Plane& plane);

/// Normals not all computed when the planes are looked for (see pixelNormals's pending fits):
/// `pending` flags the points whose normal is still to come; `finish(indices)` computes those
/// among `indices` into the normals largePlanes was given, clearing their flags;
/// `aligned(i, m, min_cos)` settles |m . n_i| >= min_cos for a pending point where it can
/// (1 yes, 0 no, -1 not without its normal).
struct LateNormals {
  const std::vector<char>* pending = nullptr;
  std::function<void(std::span<const std::uint32_t>)> finish;
  std::function<int(std::uint32_t, const Vec3&, float)> aligned;
};

/// Marks the points of large planes: RANSAC on oriented points (each hypothesis is the plane of
/// one point and its normal, refitted to its inliers by least squares), then the inliers split
/// into connected patches, and every patch of
/// at least `min_area` (at the points' density `density`, points/mm^2) removed. Only background
/// planes go, with (almost) nothing behind them (max_behind): the floor, the walls, a table
/// (the room's floor seen past its edge is not seen through it); the tops of a layer of parts
/// lying flat, touching one another, have the floor behind them and stay, and coplanar faces of
/// parts that do not touch stay. So does a plane tilted (by more than 15 degrees) from square to
/// the first background plane: a bin's floor and walls meet at right angles, and a tilted face
/// that hides little is a part's. Normals face the sensor at `viewpoint`. Returns one
/// flag per point: 1 on a removed plane; `removed`, when given, receives every background plane found
/// (with at least min_area of inliers in all, even where no one patch is that large).
/// Deterministic for a given seed. With `late`, only the normals the search needs are computed
/// (its hypotheses', its probes', the points near a plane whose angle the fit cannot settle):
/// the same flags as with every normal.
std::vector<char> largePlanes(const Points& points, const Points& normals, float density, const PlaneParams& params,
                              std::vector<Plane>* removed = nullptr, const LateNormals* late = nullptr);

namespace detail {
/// The bin's floor and walls meet at right angles; planes within this many degrees of parallel
/// (or square) are taken as parallel (or square): drafted walls, a tilted scan, the bin's rim
/// over its floor.
inline constexpr float kSquareDegrees = 15.0f;
/// Whether two unit normals lie within kSquareDegrees of parallel (or of opposite).
inline bool nearlyParallel(const Vec3& a, const Vec3& b) {
  static const float min_cos = std::cos(kSquareDegrees * float(M_PI) / 180.0f);
  return std::abs(a.dot(b)) >= min_cos;
}
/// A link from patch point a to its neighbour b, both indices into the points, in the patch
/// grown from `seed`: whether b joins the patch.
using Joins = std::function<bool(std::uint32_t b, std::uint32_t a, std::uint32_t seed)>;
/// The connected patches of points[members] (links shorter than `link`, kept where `joins` says
/// so; every link when it is empty) by a flood fill through a grid of them: lists of point
/// indices, each in the order reached, the patches in the order of their first member in
/// `members`. For a `joins` that depends on a and b only through their own test (or on b and
/// the seed), a patch is the same set whatever the order of the fill.
std::vector<std::vector<std::uint32_t>> floodPatches(const Points& points, const std::vector<std::uint32_t>& members, float link,
                                                     const Joins& joins = {});
/// The connected patches of points[members] (pairs strictly closer than `link`, by the squared
/// distance x^2 + (y^2 + z^2) of their difference, in float): lists of point indices, in the
/// order of their first member in `members`. largePlanes's split of a plane's inliers; `normal`
/// (a unit vector) is the plane's, and any gives the same patches (the points near a plane
/// with it are found faster).
std::vector<std::vector<std::uint32_t>> linkedPatches(const Points& points, const std::vector<std::uint32_t>& members, float link,
                                                      const Vec3& normal);
}  // namespace detail

}  // namespace binpose
