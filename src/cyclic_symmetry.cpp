// Parts with n-fold symmetry about an axis: the symmetry, classes of images, their consistency
// and the pose of a clique of class members.
#include <binpose/cyclic_symmetry.hpp>

#include <binpose/kdtree.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <bit>
#include <limits>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace binpose {
namespace {

constexpr float kTwoPi = 2.0f * float(M_PI);

/// A point's coordinates about the axis: (x, y) in the plane across it, z along it.
struct AxisFrame {
  Vec3 c, ex, ey, ez;
  explicit AxisFrame(const RevolutionAxis& axis) : c(axis.point), ez(axis.direction) { basisAround(ez, ex, ey); }
  [[nodiscard]] Vec3 of(const Vec3& p) const {
    const Vec3 v = p - c;
    return {v.dot(ex), v.dot(ey), v.dot(ez)};
  }
};

/// Index of the smallest of `values` other than `skip` (-1: none skipped).
int smallest(std::span<const float> values, int skip = -1) {
  int best = -1;
  for (int k = 0; k < static_cast<int>(values.size()); ++k)
    if (k != skip && (best < 0 || values[k] < values[best])) best = k;
  return best;
}

}  // namespace

Pose CyclicSymmetry::turn(int k) const {
  Pose t = Pose::Identity();
  t.linear() = Eigen::AngleAxisf(kTwoPi * static_cast<float>(k) / static_cast<float>(order), axis.direction).toRotationMatrix();
  t.translation() = axis.point - t.linear() * axis.point;
  return t;
}

std::optional<CyclicSymmetry> findCyclicSymmetry(const OrientedModel& model, int max_order, float tolerance) {
  const Points& pts = model.points;
  if (pts.size() < 10 || max_order < 3) return std::nullopt;
  if (tolerance <= 0) tolerance = 1.5f * model.sample_radius;
  if (!(tolerance > 0)) return std::nullopt;
  const PrincipalAxes principal = principalAxes(pts);
  const Vec3& centre = principal.centre;
  const KdTree tree(pts);
  std::optional<CyclicSymmetry> best;
  for (int c = 0; c < 3; ++c) {
    const Vec3 axis = principal.axes.col(c).normalized();
    for (int n = max_order; n >= 3 && (!best || n > best->order); --n) {
      // Every turn, not just 2 pi / n: a ring of 17 teeth turned by 2 pi / 21 is off by a fifth
      // of a tooth, within the tolerance, but by two fifths at twice that turn.
      const float step = kTwoPi / static_cast<float>(n);
      bool all = true;
      for (int k = 1; k <= n / 2 && all; ++k) all = turnKeepsShape(pts, tree, centre, axis, step * static_cast<float>(k), tolerance);
      if (all) {
        best = CyclicSymmetry{RevolutionAxis{centre, axis}, n};
        break;
      }
    }
  }
  return best;
}

Orbits makeCyclicClasses(const ModelDatabase& db, const CyclicSymmetry& sym) {
  const OrientedModel& model = db.model();
  if (model.points.size() > 65535) throw Error("too many model points for symmetry classes");
  const AxisFrame frame(sym.axis);
  const float wedge = kTwoPi / static_cast<float>(sym.order);
  // Each point's turn into the wedge [0, wedge) about the axis.
  std::vector<int> turns(model.points.size());
  Points in_wedge;
  Orbits o;
  o.axis = sym.axis;
  o.cyclic = true;
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    const Vec3 q = frame.of(model.points[i]);
    float phi = std::atan2(q.y(), q.x());
    if (phi < 0) phi += kTwoPi;
    turns[i] = std::clamp(static_cast<int>(phi / wedge), 0, sym.order - 1);
    if (turns[i] == 0) {
      o.member.push_back(static_cast<std::uint32_t>(i));
      in_wedge.push_back(model.points[i]);
    }
  }
  o.count = static_cast<std::uint32_t>(o.member.size());
  if (o.count == 0) throw Error("no model point in the symmetry's wedge");
  const KdTree tree(in_wedge);
  o.of.resize(model.points.size());
  std::uint32_t next = 0;
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    if (turns[i] == 0) {
      o.of[i] = next++;
      continue;
    }
    std::uint32_t j;
    float d2;
    tree.nearest(sym.turn(-turns[i]) * model.points[i], j, d2);
    o.of[i] = j;
  }
  return o;
}

Graph cyclicConsistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& scene_normals,
                             const OrientedModel& model, const CyclicSymmetry& sym, float e_gmax, float max_angle_deg) {
  const int n = static_cast<int>(cps.size());
  Graph g(n);
  const AxisFrame frame(sym.axis);
  // Model points and normals in the axis's frame.
  std::vector<Vec3> q(cps.size()), u(cps.size());
  std::vector<float> flat(cps.size()), nflat(cps.size());  // their lengths across the axis
  for (int i = 0; i < n; ++i) {
    q[i] = frame.of(model.points[cps[i].model]);
    const Vec3& m = model.normals[cps[i].model];
    u[i] = {m.dot(frame.ex), m.dot(frame.ey), m.dot(frame.ez)};
    flat[i] = std::hypot(q[i].x(), q[i].y());
    nflat[i] = std::hypot(u[i].x(), u[i].y());
  }
  std::vector<float> ck(sym.order), sk(sym.order);
  for (int k = 0; k < sym.order; ++k) {
    ck[k] = std::cos(kTwoPi * static_cast<float>(k) / static_cast<float>(sym.order));
    sk[k] = std::sin(kTwoPi * static_cast<float>(k) / static_cast<float>(sym.order));
  }
  // a . R_k b for a turn R_k about the frame's z: cos_k (a.b across the axis) - sin_k (a x b)_z + a_z b_z.
  struct Turned {
    float dot, cross, z;
    [[nodiscard]] float at(float c, float s) const { return c * dot - s * cross + z; }
  };
  auto turned = [](const Vec3& a, const Vec3& b) {
    return Turned{a.x() * b.x() + a.y() * b.y(), a.x() * b.y() - a.y() * b.x(), a.z() * b.z()};
  };
  const float tol = std::sin(max_angle_deg * float(M_PI) / 180.0f);
  // Row i's partners j > i into row i alone (rows apart on the cores), mirrored below after.
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& rows) {
    std::vector<float> t(sym.order);
    for (int i = rows.begin(); i < rows.end(); ++i) {
      std::uint64_t* row = g.mutableRow(i);
      const Vec3& si = scene[cps[i].scene];
      const Vec3& ni = scene_normals[cps[i].scene];
      const Vec3& a = q[i];
      for (int j = i + 1; j < n; ++j) {
        if (cps[i].scene == cps[j].scene) continue;
        const Vec3& b = q[j];
        const Vec3 d = scene[cps[j].scene] - si;
        const float ds = d.norm();
        const float lo = std::max(0.0f, ds - e_gmax), hi = ds + e_gmax;
        // |a - R_k b|^2 = |a|^2 + |b|^2 - 2 a.R_k b: within the band of the scene distance when
        // a.R_k b lies in [t_lo, t_hi].
        const float base = a.squaredNorm() + b.squaredNorm();
        const float t_lo = 0.5f * (base - hi * hi), t_hi = 0.5f * (base - lo * lo);
        // Each of a.R_k b, u_i.R_k u_j, u_i.R_k b, a.R_k u_j lies within its z part plus or minus
        // the product of the parts across the axis, whatever the turn: most pairs fail one.
        const Turned ab = turned(a, b);
        if (t_lo > ab.z + flat[i] * flat[j] || t_hi < ab.z - flat[i] * flat[j]) continue;
        const Vec3& nj = scene_normals[cps[j].scene];
        const float nn_scene = ni.dot(nj), ni_d = ni.dot(d) + u[i].dot(a), nj_d = u[j].dot(b) - nj.dot(d);
        const float slack = tol * ds + e_gmax;
        if (std::abs(nn_scene - u[i].z() * u[j].z()) > tol + nflat[i] * nflat[j]) continue;
        if (std::abs(ni_d - u[i].z() * b.z()) > slack + nflat[i] * flat[j]) continue;
        if (std::abs(nj_d - a.z() * u[j].z()) > slack + flat[i] * nflat[j]) continue;
        int hits = 0;  // every turn at once (SIMD lanes), most pairs having none
        for (int k = 0; k < sym.order; ++k) {
          t[k] = ab.at(ck[k], sk[k]);
          hits += (t[k] >= t_lo) & (t[k] <= t_hi);
        }
        if (hits == 0) continue;
        // At such a turn, the three angles of the pair (4.1) as in the scene, within tol.
        const Turned nn = turned(u[i], u[j]), na = turned(u[i], b), bn = turned(a, u[j]);
        for (int k = 0; k < sym.order; ++k) {
          if (t[k] < t_lo || t[k] > t_hi) continue;
          if (std::abs(nn.at(ck[k], sk[k]) - nn_scene) > tol) continue;
          if (std::abs(na.at(ck[k], sk[k]) - ni_d) > slack) continue;  // n_i . (R_k b - a)
          if (std::abs(bn.at(ck[k], sk[k]) - nj_d) > slack) continue;  // R_k n_j . (a - R_k b)
          row[j / 64] |= 1ull << (j % 64);
          break;
        }
      }
    }
  });
  for (int i = 0; i < n; ++i) {
    const std::uint64_t* row = g.row(i);
    for (int w = i / 64; w < g.words(); ++w)
      for (std::uint64_t bits = row[w]; bits; bits &= bits - 1) {
        const int j = w * 64 + std::countr_zero(bits);
        if (j > i) g.mutableRow(j)[i / 64] |= 1ull << (i % 64);
      }
  }
  return g;
}

PoseFit solveCyclicPose(const CyclicSymmetry& sym, const Points& model, const Points& scene) {
  const int m = static_cast<int>(model.size());
  if (m < 3 || scene.size() != model.size()) return {};
  const int n = sym.order;
  // Every image of every clique point.
  std::vector<Points> images(m, Points(n));
  for (int k = 0; k < n; ++k) {
    const Pose t = sym.turn(k);
    for (int v = 0; v < m; ++v) images[v][k] = t * model[v];
  }
  // Anchors: point 0 at its own image, the scene point farthest from it, and the one farthest
  // from the line through both.
  const int a0 = 0;
  int a1 = 1;
  for (int v = 1; v < m; ++v)
    if ((scene[v] - scene[a0]).squaredNorm() > (scene[a1] - scene[a0]).squaredNorm()) a1 = v;
  const Vec3 line = (scene[a1] - scene[a0]).normalized();
  auto off_line = [&](int v) { return (scene[v] - scene[a0]).cross(line).squaredNorm(); };
  int a2 = -1;
  for (int v = 1; v < m; ++v)
    if (v != a1 && (a2 < 0 || off_line(v) > off_line(a2))) a2 = v;
  // A point's misfit at each image against the anchors placed so far.
  std::vector<float> misfit(n);
  auto fill = [&](int v, std::span<const std::pair<int, int>> placed) {
    for (int k = 0; k < n; ++k) {
      float e = 0;
      for (const auto& [u, ku] : placed) {
        const float r = (scene[v] - scene[u]).norm() - (images[v][k] - images[u][ku]).norm();
        e += r * r;
      }
      misfit[k] = e;
    }
  };
  PoseFit best;
  best.rms = std::numeric_limits<float>::max();
  Points chosen(m);
  fill(a1, std::array{std::pair{a0, 0}});
  const int k1_best = smallest(misfit);
  const std::array<int, 2> k1s{k1_best, smallest(misfit, k1_best)};  // a reflection of the pair fits as well
  for (const int k1 : k1s) {
    const std::array placed{std::pair{a0, 0}, std::pair{a1, k1}};
    fill(a2, placed);
    const int k2_best = smallest(misfit);
    for (const int k2 : {k2_best, smallest(misfit, k2_best)}) {
      const PoseFit start = solvePose(Points{images[a0][0], images[a1][k1], images[a2][k2]},
                                      Points{scene[a0], scene[a1], scene[a2]});
      if (!start.ok) continue;
      // Each point at its image nearest the scene under the anchors' pose.
      for (int v = 0; v < m; ++v) {
        int kv = 0;
        float d_best = std::numeric_limits<float>::max();
        for (int k = 0; k < n; ++k)
          if (const float d = (start.pose * images[v][k] - scene[v]).squaredNorm(); d < d_best) {
            d_best = d;
            kv = k;
          }
        chosen[v] = images[v][kv];
      }
      const PoseFit fit = solvePose(chosen, scene);
      if (fit.ok && fit.rms < best.rms) best = fit;
    }
  }
  if (!best.ok) return {};
  return best;
}

}  // namespace binpose
