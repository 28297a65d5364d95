// Large planes (bin floor, walls, table) found by one-point RANSAC and removed by patch.
#include <binpose/planes.hpp>

#include <binpose/geometry.hpp>
#include <binpose/normals.hpp>
#include <binpose/point_grid.hpp>

#include "oriented_lanes.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

namespace binpose {
namespace {

/// Union-find over n items; a set's root is its smallest item.
struct DisjointSets {
  explicit DisjointSets(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  std::uint32_t root(std::uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void join(std::uint32_t a, std::uint32_t b) {
    const std::uint32_t ra = root(a), rb = root(b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  }
  /// members[k] grouped by k's set, the groups in the order of their first item.
  std::vector<std::vector<std::uint32_t>> groups(const std::vector<std::uint32_t>& members) {
    std::vector<std::vector<std::uint32_t>> out;
    std::vector<std::uint32_t> group_of(parent.size(), ~std::uint32_t{0});
    for (std::uint32_t k = 0; k < parent.size(); ++k) {
      std::uint32_t& g = group_of[root(k)];
      if (g == ~std::uint32_t{0}) {
        g = static_cast<std::uint32_t>(out.size());
        out.emplace_back();
      }
      out[g].push_back(members[k]);
    }
    return out;
  }
  std::vector<std::uint32_t> parent;
};

}  // namespace

namespace detail {

std::vector<std::vector<std::uint32_t>> floodPatches(const Points& points, const std::vector<std::uint32_t>& members, float link,
                                                     const Joins& joins) {
  const std::size_t n = members.size();
  std::vector<std::vector<std::uint32_t>> out;
  Points sub;
  for (const auto i : members) sub.push_back(points[i]);
  const PointGrid grid(sub, link);
  std::vector<char> seen(n, 0);
  std::vector<std::uint32_t> stack, found;
  for (std::uint32_t s = 0; s < n; ++s) {
    if (seen[s]) continue;
    std::vector<std::uint32_t> patch;
    seen[s] = 1;
    stack.assign(1, s);
    while (!stack.empty()) {
      const std::uint32_t a = stack.back();
      stack.pop_back();
      patch.push_back(members[a]);
      grid.within(sub[a], link, found);
      for (const auto b : found)
        if (!seen[b] && (!joins || joins(members[b], members[a], members[s]))) {
          seen[b] = 1;
          stack.push_back(b);
        }
    }
    out.push_back(std::move(patch));
  }
  return out;
}

std::vector<std::vector<std::uint32_t>> linkedPatches(const Points& points, const std::vector<std::uint32_t>& members, float link,
                                                      const Vec3& normal) {
  const std::size_t n = members.size();
  std::vector<std::vector<std::uint32_t>> out;
  if (n == 0) return out;
  // The points in the plane's coordinates (u, v along it, w across), bucketed by (u, v) in
  // square cells of a side s with 2 s^2 + (w's range)^2 under link^2, a fiftieth of margin over
  // the float roundings: any two points of a cell are linked, so a cell joins whole, and two
  // cells join by their first linked pair, looked for only while they are apart. A pair closer
  // than link in space is closer along the plane, so its cells are at most `reach` apart.
  const Vec3 e1 = normal.unitOrthogonal(), e2 = normal.cross(e1);
  std::vector<float> u(n), v(n);
  float u_lo = INFINITY, u_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY, w_lo = INFINITY, w_hi = -INFINITY;
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3& p = points[members[k]];
    u[k] = e1.dot(p);
    v[k] = e2.dot(p);
    const float w = normal.dot(p);
    u_lo = std::min(u_lo, u[k]), u_hi = std::max(u_hi, u[k]);
    v_lo = std::min(v_lo, v[k]), v_hi = std::max(v_hi, v[k]);
    w_lo = std::min(w_lo, w), w_hi = std::max(w_hi, w);
  }
  const float thickness = w_hi - w_lo;
  const float side = std::sqrt(std::max(0.0f, (0.98f * link * link - thickness * thickness) / 2.0f));
  const double nu = std::floor(double(u_hi - u_lo) / side) + 1, nv = std::floor(double(v_hi - v_lo) / side) + 1;
  if (!(side >= 0.125f * link) || !(side >= 1e-6f * std::max(u_hi - u_lo, v_hi - v_lo)) ||
      !(nu * nv <= std::max(8.0 * double(n), double(1 << 20))))
    return floodPatches(points, members, link);  // a thick slab, or a box too wide for such cells
  const auto cols = static_cast<std::size_t>(nu), rows = static_cast<std::size_t>(nv);
  const auto reach = static_cast<std::ptrdiff_t>(std::ceil(1.01f * link / side));
  std::vector<std::uint32_t> cell_of(n), offsets, order;
  for (std::size_t k = 0; k < n; ++k) {
    const auto cu = std::min(static_cast<std::size_t>(std::max(0.0f, std::floor((u[k] - u_lo) / side))), cols - 1);
    const auto cv = std::min(static_cast<std::size_t>(std::max(0.0f, std::floor((v[k] - v_lo) / side))), rows - 1);
    cell_of[k] = static_cast<std::uint32_t>(cv * cols + cu);
  }
  sortByCell(cell_of, cols * rows, offsets, order);
  DisjointSets sets(n);
  const float limit = link * link;
  auto linkCells = [&](std::size_t a, std::size_t b) {  // a's and b's points joined by their first linked pair
    if (sets.root(order[offsets[a]]) == sets.root(order[offsets[b]])) return;
    for (std::uint32_t s = offsets[a]; s < offsets[a + 1]; ++s)
      for (std::uint32_t t = offsets[b]; t < offsets[b + 1]; ++t) {
        const Vec3 d = points[members[order[t]]] - points[members[order[s]]];
        if (d.x() * d.x() + (d.y() * d.y() + d.z() * d.z()) >= limit) continue;
        sets.join(order[s], order[t]);
        return;
      }
  };
  for (std::size_t first = 0; first < n;) {  // the occupied cells, in order
    const std::size_t a = cell_of[order[first]];
    first = offsets[a + 1];
    for (std::uint32_t s = offsets[a] + 1; s < offsets[a + 1]; ++s) sets.join(order[offsets[a]], order[s]);
    const auto x = static_cast<std::ptrdiff_t>(a % cols), y = static_cast<std::ptrdiff_t>(a / cols);
    // The cells within reach that come after a in (v, u) order.
    for (std::ptrdiff_t dy = 0; dy <= reach; ++dy)
      for (std::ptrdiff_t dx = dy == 0 ? 1 : -reach; dx <= reach; ++dx) {
        const std::ptrdiff_t bx = x + dx, by = y + dy;
        if (bx < 0 || bx >= std::ptrdiff_t(cols) || by >= std::ptrdiff_t(rows)) continue;
        const std::size_t b = std::size_t(by) * cols + std::size_t(bx);
        if (offsets[b] != offsets[b + 1]) linkCells(a, b);
      }
  }
  return sets.groups(members);
}

}  // namespace detail

namespace {

/// How many probe points lie on `plane` (largePlanes's inlier test, within `within` of it, the
/// same sums in the same order), on SIMD lanes (300 hypotheses a plane made this loop half of
/// the plane search's time).
__attribute__((target_clones("avx2", "default")))
std::uint32_t countOnPlane(const detail::OrientedLanes& probe, const Plane& plane, float within, float min_cos) {
  const float* x = probe.c[0].data();
  const float* y = probe.c[1].data();
  const float* z = probe.c[2].data();
  const float* nx = probe.c[3].data();
  const float* ny = probe.c[4].data();
  const float* nz = probe.c[5].data();
  const float a = plane.normal.x(), b = plane.normal.y(), c = plane.normal.z(), d = plane.d;
  std::uint32_t count = 0;
  for (std::size_t k = 0; k < probe.size; ++k) {
    const bool near = std::abs(a * x[k] + b * y[k] + c * z[k] - d) <= within;
    const bool aligned = std::abs(a * nx[k] + b * ny[k] + c * nz[k]) >= min_cos;
    count += static_cast<std::uint32_t>(near & aligned);
  }
  return count;
}

void checkPlaneInputs(const Points& points, const Points& normals, float density, const PlaneParams& params,
                      const LateNormals* late) {
  if (points.size() != normals.size()) throw Error("largePlanes: one normal per point needed");
  if (late != nullptr && (late->pending == nullptr || late->pending->size() != points.size() || !late->finish || !late->aligned))
    throw Error("largePlanes: late normals need one pending flag per point, finish and aligned");
  if (!(density > 0) || !(params.min_area > 0) || !(params.tolerance > 0) || !(params.link > 0))
    throw Error(fmt::format("plane removal needs positive density, area, tolerance and link, got {}, {}, {}, {}", density,
                            params.min_area, params.tolerance, params.link));
  if (!(params.hole >= 0) || !std::isfinite(params.hole))
    throw Error(fmt::format("plane removal needs a finite hole width >= 0, got {}", params.hole));
}

/// The least-squares plane of `inliers` (fitPlaneNormal, eq. 30-38, through their centroid), its
/// normal on the side of `like`'s: a hypothesis takes one point's normal, as noisy as the sensor,
/// and a plane tilted by it leaves the far side of a floor out of tolerance.
Plane refitted(const Points& points, std::span<const std::uint32_t> inliers, const Plane& like) {
  Plane fit;
  if (!fitPlane(points, inliers, fit)) return like;
  return fit.normal.dot(like.normal) < 0 ? Plane{-fit.normal, -fit.d, {}} : fit;
}

/// The fit band in use: PlaneParams::fit_band where it is narrower than the tolerance, else 0.
float fitBand(const PlaneParams& params) {
  return params.fit_band > 0 && params.fit_band < params.tolerance ? params.fit_band : 0.0f;
}

/// With a fit band, the hypotheses with the most probe points within the tolerance that are
/// locally optimised (LO-RANSAC, Chum, Matas & Kittler 2003) and compared on the points within
/// the band, and the refits of each.
constexpr std::size_t kLocallyOptimised = 8;
constexpr int kLocalRefits = 3;

/// `plane` refitted kLocalRefits times to the probe points within `band` of it (fewer than 3: as
/// it is), and how many lie within the band of the last fit.
std::pair<Plane, std::uint32_t> locallyOptimised(const Points& points, std::span<const std::uint32_t> probe,
                                                 const detail::OrientedLanes& probe_points, Plane plane, float band,
                                                 float min_cos) {
  std::vector<std::uint32_t> near;
  for (int fit = 0; fit < kLocalRefits; ++fit) {
    near.clear();
    const Vec3& n = plane.normal;
    for (std::size_t k = 0; k < probe.size(); ++k) {
      const float side = n.x() * probe_points.c[0][k] + n.y() * probe_points.c[1][k] + n.z() * probe_points.c[2][k] - plane.d;
      const float along = n.x() * probe_points.c[3][k] + n.y() * probe_points.c[4][k] + n.z() * probe_points.c[5][k];
      if (std::abs(side) <= band && std::abs(along) >= min_cos) near.push_back(probe[k]);
    }
    plane = refitted(points, near, plane);
  }
  return {plane, countOnPlane(probe_points, plane, band, min_cos)};
}

/// The first of the hypotheses, scored side by side, with the most probe points within the
/// tolerance. With a fit band (PlaneParams::fit_band), of the kLocallyOptimised with the most,
/// the one whose local optimisation holds the most within the band, as optimised: a plane tilted
/// through two parallel surfaces holds as many within the tolerance as either alone, in stripes,
/// and its fit to the stripes stays tilted; a hypothesis off one surface by its point's normal
/// holds a stripe of it, and its fit settles on it.
Plane bestHypothesis(const Points& points, std::span<const std::uint32_t> probe, const detail::OrientedLanes& probe_points,
                     const std::vector<Plane>& hypotheses, const PlaneParams& params, float min_cos,
                     std::vector<std::uint32_t>& counts) {
  counts.resize(hypotheses.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, hypotheses.size(), 32), [&](const auto& range) {
    for (std::size_t t = range.begin(); t < range.end(); ++t)
      counts[t] = countOnPlane(probe_points, hypotheses[t], params.tolerance, min_cos);
  });
  const float band = fitBand(params);
  if (band == 0.0f) {  // the first with the most
    const auto most = std::max_element(counts.begin(), counts.end());
    return most == counts.end() || *most == 0 ? Plane{} : hypotheses[static_cast<std::size_t>(most - counts.begin())];
  }
  // The kLocallyOptimised with the most, the first of equal counts first.
  std::vector<std::uint32_t> order(hypotheses.size());
  std::iota(order.begin(), order.end(), 0u);
  const std::size_t tried = std::min(kLocallyOptimised, order.size());
  const auto more = [&](std::uint32_t a, std::uint32_t b) { return counts[a] > counts[b] || (counts[a] == counts[b] && a < b); };
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(tried), order.end(), more);
  if (tried == 0 || counts[order.front()] == 0) return {};
  // Optimised side by side, each into its own slot, then compared in order.
  std::vector<std::pair<Plane, std::uint32_t>> optimised(tried);
  tbb::parallel_for(std::size_t{0}, tried, [&](std::size_t r) {
    if (counts[order[r]] > 0)
      optimised[r] = locallyOptimised(points, probe, probe_points, hypotheses[order[r]], band, min_cos);
  });
  Plane best = optimised.front().first;
  std::uint32_t best_near = optimised.front().second;
  for (std::size_t r = 1; r < tried; ++r)
    if (optimised[r].second > best_near) {
      best = optimised[r].first;
      best_near = optimised[r].second;
    }
  return best;
}

/// A plane's refits until its inliers grow by less than kRefitGrowth, at most kMostRefits. A
/// hypothesis takes one point's normal: on a noisy scan (a Kinect's normals tilt by 10-20
/// degrees) its inliers are a band of the floor, and each refit widens the band. Two refits left
/// a real Kinect frame's table in four to six tilted slices, and whether each slice counted as
/// background turned on which point the search drew.
constexpr int kMostRefits = 10;
constexpr float kRefitGrowth = 0.01f;

/// With a fit band, a plane can settle through two parallel surfaces a few millimetres apart:
/// a floor and the insides of caps lying open side up on it, about as many points each, meet a
/// plane tilted by 1-2 degrees across the bin within the tolerance in stripes, and its refits
/// stay there (the floor up to 3 mm behind it on one side). A background plane is the farthest
/// surface, the floor and not what lies on it. Where the points within the tolerance of the
/// plane moved kFartherTolerances tolerances behind it (away from the sensor), over its inliers'
/// bounding rectangle and facing as it does, number kFartherLayerShare of those within its band,
/// they are a farther surface: the plane is refitted to them and its refits run again.
constexpr float kFartherLayerShare = 0.25f;
constexpr float kFartherTolerances = 1.5f;
/// A tilted plane's points just behind it hold stripes of both surfaces too, fewer of the nearer
/// one each time: at most this many refits to them.
constexpr int kFartherSteps = 3;

/// The points of `left` that `inlier` takes for those of `plane` moved kFartherTolerances
/// tolerances behind it (away from the sensor), over its inliers' bounding rectangle (`footprint`).
template <class Inlier>
std::vector<std::uint32_t> justBehind(const Points& points, std::span<const std::uint32_t> left, const Plane& plane,
                                      const PlaneFootprint& footprint, const PlaneParams& params, Inlier&& inlier) {
  Plane behind = plane;
  behind.d -= (plane.side(params.viewpoint) > 0 ? 1.0f : -1.0f) * kFartherTolerances * params.tolerance;
  std::vector<std::uint32_t> farther;
  for (const auto i : left)
    if (footprint.within(points[i]) && inlier(i, behind)) farther.push_back(i);
  return farther;
}

/// The points farther than 3 tolerances behind a plane, on the side away from the sensor.
struct Behind {
  /// ... whose foot on the plane lies within its inliers' extent (their bounding rectangle on
  /// it): what a wall hides. The far walls' inner faces have nothing behind them; the near wall
  /// seen from outside has the bin's contents behind it.
  std::size_t below = 0;
  /// ... whose line of sight crosses the plane on its inliers' footprint: what a floor hides,
  /// seen through it. The tops of a layer of parts lying flat, touching, have the floor behind
  /// them, seen through the gaps between them; a table has the room's floor and a lower desk
  /// behind it, but seen past its edge, off it.
  std::size_t seen_through = 0;
};

/// No plane found yet holds the point (largePlanes's found_in).
constexpr std::uint8_t kOnNoPlane = 0xff;

/// What `plane` hides from the sensor at `viewpoint`, `footprint` its inliers': the points
/// farther than 3 tolerances behind it (first), and the same with the inliers of a parallel
/// plane found before it counted from one tolerance on (second): that plane is a surface of its
/// own, such as the floor seen between caps lying open side up, their insides 3 mm above it.
/// found_in[i]: the index in `found` of the plane found before that holds point i, or kOnNoPlane.
std::pair<Behind, Behind> pointsBehind(const Points& points, const Plane& plane, const PlaneFootprint& footprint,
                                       float tolerance, const Vec3& viewpoint, std::span<const std::uint8_t> found_in,
                                       const std::vector<Plane>& found) {
  std::pair<Behind, Behind> behind;
  if (footprint.empty()) return behind;
  std::vector<float> margin(std::size_t{kOnNoPlane} + 1, 3.0f * tolerance);
  for (std::size_t f = 0; f < found.size(); ++f)
    if (detail::nearlyParallel(found[f].normal, plane.normal)) margin[f] = tolerance;
  const float sensor_side = plane.side(viewpoint);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3& p = points[i];
    const float point_side = plane.side(p);
    if (!(point_side < -margin[found_in[i]])) continue;
    const bool beyond = point_side < -3.0f * tolerance;
    const bool within = footprint.within(p);
    behind.first.below += beyond && within;
    behind.second.below += within;
    if (!(sensor_side > 0)) continue;
    const Vec3 crossing = viewpoint + (sensor_side / (sensor_side - point_side)) * (p - viewpoint);
    const bool through = footprint.on(crossing);
    behind.first.seen_through += beyond && through;
    behind.second.seen_through += through;
  }
  return behind;
}

/// A plane the search found that hides (almost) nothing by one test or the other (Behind), and
/// its connected patches of min_count points or more.
struct Background {
  Plane plane;
  std::vector<std::uint32_t> inliers;
  bool hides_nothing_below = false;    ///< Behind::below at most max_behind of the points
  bool hides_nothing_through = false;  ///< Behind::seen_through at most max_behind of its inliers
  std::vector<std::vector<std::uint32_t>> patches;
};

/// Whether what a plane hides (pointsBehind) is more than max_behind allows by both tests.
bool hidesMuch(const Behind& behind, std::size_t points, std::size_t inliers, float max_behind) {
  return static_cast<float>(behind.below) > max_behind * static_cast<float>(points) &&
         static_cast<float>(behind.seen_through) > max_behind * static_cast<float>(inliers);
}

/// The background planes that hide a parallel surface a few millimetres behind them, found after
/// them (pointsBehind's second count, now with every plane found), dropped where largePlanes
/// drops them when the surface comes first: in pieces each smaller than min_count, a layer of
/// parts lying flat on it. The insides of caps lying open side up, 3 mm above the floor, can show
/// more than the floor between them, and come first. With a fit band (a scan far quieter than the
/// tolerance), in any pieces: two such surfaces are two, not slabs of one noisy table, and the
/// insides of caps touching each other join in one piece.
void dropLayersFoundFirst(std::vector<Background>& background, const Points& points, const PlaneParams& params,
                          std::span<const std::uint8_t> found_in, const std::vector<Plane>& found) {
  std::erase_if(background, [&](const Background& b) {
    if ((!b.patches.empty() && fitBand(params) == 0.0f) || !b.plane.extent) return false;
    const Behind on_found =
        pointsBehind(points, b.plane, *b.plane.extent, params.tolerance, params.viewpoint, found_in, found).second;
    return hidesMuch(on_found, points.size(), b.inliers.size(), params.max_behind);
  });
}

/// b's connected patches of min_count points or more.
void patchesOf(Background& b, const Points& points, float link, std::size_t min_count) {
  for (auto& patch : detail::linkedPatches(points, b.inliers, link, b.plane.normal))
    if (patch.size() >= min_count) b.patches.push_back(std::move(patch));
}

/// Whether a background plane is a surface of the bin or the table, given the planes kept
/// before it. The first one kept has nothing behind it within its extent, or is the largest
/// plane and hides nothing seen through it (a table with the room's floor seen past its edges).
/// The others are parallel to the first (another floor, a table, a step, the bin's rim) and hide
/// nothing by either test, or at right angles to it (a wall) with nothing behind it within its
/// extent: not the near wall seen from outside, with the bin's contents behind it. A tilted plane
/// is a face of a part, or the faces of several lying side by side, that happen to hide little:
/// as background it would hide that part from the votes and take its support away in
/// verification.
bool ofTheBin(const Background& b, bool largest, const std::vector<Plane>& kept) {
  if (kept.empty()) return b.hides_nothing_below || (largest && b.hides_nothing_through);
  if (detail::nearlyParallel(b.plane.normal, kept.front().normal)) return b.hides_nothing_below || b.hides_nothing_through;
  const float c = std::abs(b.plane.normal.dot(kept.front().normal)), off = detail::kSquareDegrees * float(M_PI) / 180.0f;
  return c <= std::sin(off) && b.hides_nothing_below;
}

/// Share of a parallel plane's inliers that must lie over a kept plane's extent to be parts on it.
constexpr float kOnKeptShare = 0.5f;

/// Whether most of b's inliers lie over where a kept plane parallel to it is hidden by what
/// stands on it (PlaneFootprint::covers), on the sensor's side and less than a hole's width (the
/// part's size) from it: a layer of flat parts lying on the floor (brackets' plates a few
/// millimetres up), which hides nothing farther than 3 tolerances behind it. A second floor (a
/// bin on a table) hides the first over more than a hole's width, a rim lies past the floor's
/// edge, and the bin's far wall lies farther from the near one than a part is long.
bool liesOnKept(const Background& b, const std::vector<Plane>& kept, const Points& points, const PlaneParams& params) {
  for (const Plane& under : kept) {
    if (!under.extent || !detail::nearlyParallel(b.plane.normal, under.normal)) continue;
    const float sensor = under.side(params.viewpoint) > 0 ? 1.0f : -1.0f;
    std::size_t over = 0;
    for (const auto i : b.inliers) {
      const float up = sensor * under.side(points[i]);
      over += up > params.tolerance && up < params.hole && under.extent->covers(points[i]);
    }
    if (static_cast<float>(over) >= kOnKeptShare * static_cast<float>(b.inliers.size())) return true;
  }
  return false;
}

/// The background planes of the bin (ofTheBin), their patches flagged in `plane`. The largest
/// plane (of `most_inliers`) first: a table that hides nothing seen through it, the room's floor
/// seen past its edge, is the first one kept, and what is parallel to it may be seen through it too.
std::vector<Plane> keptOfTheBin(std::vector<Background>& background, std::size_t most_inliers, const Points& points,
                                const PlaneParams& params, std::vector<char>& plane) {
  const auto largest = [&](const Background& b) { return b.inliers.size() == most_inliers; };
  std::stable_partition(background.begin(), background.end(), largest);
  std::vector<Plane> kept;
  for (const Background& b : background) {
    if (!ofTheBin(b, largest(b), kept) || liesOnKept(b, kept, points, params)) continue;  // its points stay in the votes
    kept.push_back(b.plane);
    for (const auto& patch : b.patches)
      for (const auto i : patch) plane[i] = 1;
  }
  return kept;
}

}  // namespace

bool fitPlane(const Points& points, std::span<const std::uint32_t> which, Plane& plane) {
  Vec3 n;
  if (!fitPlaneNormal(points, which, n)) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto i : which) mean += points[i].cast<double>();
  mean /= static_cast<double>(which.size());
  plane = {n, n.dot(mean.cast<float>()), {}};
  return true;
}

namespace {

/// largePlanes's search, one plane a round: one-point RANSAC hypotheses drawn among the points
/// not tried yet, the best refitted until its inliers stop growing and, with a fit band, moved
/// to the farthest of parallel surfaces just behind it; its inliers are then tried.
class PlaneSearch {
 public:
  PlaneSearch(const Points& points, const Points& normals, float density, const PlaneParams& params, const LateNormals* late)
      : points_(points),
        normals_(normals),
        params_(params),
        late_(late),
        tried_(points.size(), 0),
        min_count_(static_cast<std::size_t>(std::ceil(params.min_area * density))),
        min_cos_(std::cos(params.max_angle)),
        band_(fitBand(params)),
        rng_(params.seed) {}

  /// The next plane, its extent set, and its inliers (inliers()) tried; false when the points
  /// left, or the largest plane among them, hold fewer than minCount().
  bool next(Plane& plane) {
    left_.clear();
    for (std::uint32_t i = 0; i < points_.size(); ++i)
      if (!tried_[i]) left_.push_back(i);
    if (left_.size() < min_count_) return false;
    plane = bestDrawn();
    settle(plane);
    std::shared_ptr<const PlaneFootprint> extent = onFarthest(plane);
    if (inliers_.size() < min_count_) return false;  // the largest plane left is too small: done
    for (const auto i : inliers_) tried_[i] = 1;     // small patches of it stay in the scene, and are not tried again
    plane.extent = std::move(extent);
    return true;
  }
  [[nodiscard]] const std::vector<std::uint32_t>& inliers() const { return inliers_; }
  [[nodiscard]] std::size_t minCount() const { return min_count_; }

 private:
  void finish(std::span<const std::uint32_t> which) const {
    if (late_ != nullptr) late_->finish(which);
  }
  /// A point within the tolerance of the plane, its normal within max_angle of the plane's (a
  /// pending normal's angle settled from its fit where it can be).
  bool inlier(std::uint32_t i, const Plane& on) const {
    if (!(on.distance(points_[i]) <= params_.tolerance)) return false;
    if (late_ != nullptr && (*late_->pending)[i]) {
      if (const int aligned = late_->aligned(i, on.normal, min_cos_); aligned >= 0) return aligned == 1;
      finish(std::span<const std::uint32_t>(&i, 1));
    }
    return std::abs(on.normal.dot(normals_[i])) >= min_cos_;
  }
  /// The hypotheses drawn in turn, scored side by side on an even sample of at most 1000 of the
  /// points left, the first of the highest score kept (bestHypothesis).
  Plane bestDrawn() {
    probe_.clear();
    const std::size_t step = std::max<std::size_t>(1, left_.size() / 1000);
    for (std::size_t k = 0; k < left_.size(); k += step) probe_.push_back(left_[k]);
    finish(probe_);
    probe_points_.assign(points_, normals_, probe_.size(), [&](std::size_t k) { return probe_[k]; });
    drawn_.clear();
    for (int t = 0; t < params_.trials; ++t) drawn_.push_back(left_[rng_.below(left_.size())]);
    finish(drawn_);
    hypotheses_.clear();
    for (const auto s : drawn_) hypotheses_.push_back({normals_[s], normals_[s].dot(points_[s]), {}});
    return bestHypothesis(points_, probe_, probe_points_, hypotheses_, params_, min_cos_, counts_);
  }
  /// The plane's inliers, then those of their own plane, refitted until they stop growing; with a
  /// fit band, refitted to those within it: from a hypothesis tilted a little off one of two
  /// parallel surfaces, the inliers within the tolerance hold stripes of both, and their fit
  /// settles midway; those within the band lie on one, and each refit widens its stripe.
  void settle(Plane& best) {
    for (int fit = 0; fit <= kMostRefits; ++fit) {
      if (fit > 0) best = refitted(points_, band_ > 0 ? fitted_ : inliers_, best);
      const std::size_t before = inliers_.size();
      inliers_.clear();
      fitted_.clear();
      for (const auto i : left_)
        if (inlier(i, best)) {
          inliers_.push_back(i);
          if (band_ > 0 && best.distance(points_[i]) <= band_) fitted_.push_back(i);
        }
      if (fit > 1 && static_cast<float>(inliers_.size()) <= (1.0f + kRefitGrowth) * static_cast<float>(before)) break;
    }
  }
  /// The inliers' footprint, once per fit: with a fit band, the plane moved to a farther surface
  /// just behind it (justBehind) and settled again, up to kFartherSteps times.
  std::shared_ptr<const PlaneFootprint> onFarthest(Plane& best) {
    std::shared_ptr<const PlaneFootprint> extent;
    for (int k = 0; inliers_.size() >= min_count_; ++k) {
      extent = std::make_shared<const PlaneFootprint>(points_, inliers_, best, params_.link, params_.hole);
      if (band_ == 0 || k == kFartherSteps) break;
      const std::vector<std::uint32_t> farther =
          justBehind(points_, left_, best, *extent, params_, [this](std::uint32_t i, const Plane& on) { return inlier(i, on); });
      if (static_cast<float>(farther.size()) < kFartherLayerShare * static_cast<float>(fitted_.size())) break;
      best = refitted(points_, farther, best);
      settle(best);
    }
    return extent;
  }

  const Points& points_;
  const Points& normals_;
  const PlaneParams& params_;
  const LateNormals* late_;
  std::vector<char> tried_;
  std::size_t min_count_;
  float min_cos_, band_;
  Rng rng_;
  std::vector<std::uint32_t> left_, probe_, inliers_, fitted_, drawn_, counts_;
  detail::OrientedLanes probe_points_;  // the points a hypothesis is scored on
  std::vector<Plane> hypotheses_;
};

/// The planes found so far, background or not, in turn (at most kOnNoPlane), and the one each
/// point lies on (kOnNoPlane: none).
struct FoundPlanes {
  explicit FoundPlanes(std::size_t points) : on(points, kOnNoPlane) {}
  void add(const Plane& plane, std::span<const std::uint32_t> inliers) {
    if (all.size() >= kOnNoPlane) return;
    for (const auto i : inliers) on[i] = static_cast<std::uint8_t>(all.size());
    all.push_back(plane);
  }
  std::vector<Plane> all;
  std::vector<std::uint8_t> on;
};

}  // namespace

std::vector<char> largePlanes(const Points& points, const Points& normals, float density, const PlaneParams& params,
                              std::vector<Plane>* removed, const LateNormals* late) {
  checkPlaneInputs(points, normals, density, params, late);
  PlaneSearch search(points, normals, density, params, late);
  const std::size_t min_count = search.minCount();
  // A background plane's inliers split into patches (a flood fill, a third of the search's
  // time) while the next rounds look for planes: the next round's points do not depend on it
  // (every inlier is tried, whatever patch it falls in), and rounds' inliers are disjoint.
  std::vector<Background> background;
  background.reserve(static_cast<std::size_t>(std::max(0, params.max_planes)));  // no move under a running task
  tbb::task_group flood;
  std::size_t most_inliers = 0;  // of every plane found, background or not
  FoundPlanes found(points.size());
  Plane best;
  for (int round = 0; round < params.max_planes && search.next(best); ++round) {
    const std::vector<std::uint32_t>& inliers = search.inliers();
    most_inliers = std::max(most_inliers, inliers.size());
    const auto [behind, on_found] =
        pointsBehind(points, best, *best.extent, params.tolerance, params.viewpoint, found.on, found.all);
    found.add(best, inliers);
    const bool below = static_cast<float>(behind.below) <= params.max_behind * static_cast<float>(points.size());
    const bool through = static_cast<float>(behind.seen_through) <= params.max_behind * static_cast<float>(inliers.size());
    if (!below && !through) continue;  // not background: a layer of parts
    // The farthest surface, the bin's floor or a table: background for verification even where
    // what the parts leave of it is in pieces each smaller than min_count (those stay in the votes).
    Background* b = &background.emplace_back(Background{best, inliers, below, through, {}});
    if (hidesMuch(on_found, points.size(), inliers.size(), params.max_behind)) {
      // It hides a parallel surface found before it, a few millimetres behind. In pieces, each
      // smaller than min_count, it is a layer of parts lying flat on that surface (caps open side
      // up, brackets' plates) and no background. In one piece as large, it is another slab of a
      // noisy table (a Kinect's disparity steps, 3-5 mm apart), which stays background.
      patchesOf(*b, points, params.link, min_count);
      if (b->patches.empty()) background.pop_back();
      continue;
    }
    flood.run([&, b] { patchesOf(*b, points, params.link, min_count); });
  }
  flood.wait();
  dropLayersFoundFirst(background, points, params, found.on, found.all);
  std::vector<char> plane(points.size(), 0);
  const std::vector<Plane> kept = keptOfTheBin(background, most_inliers, points, params, plane);
  if (removed) removed->insert(removed->end(), kept.begin(), kept.end());
  return plane;
}

}  // namespace binpose
