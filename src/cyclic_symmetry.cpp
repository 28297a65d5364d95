// Parts with n-fold symmetry about an axis: the symmetry, classes of images, their consistency
// and the pose of a clique of class members.
#include <binpose/cyclic_symmetry.hpp>

#include "graph_workspace.hpp"

#include <binpose/kdtree.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <bit>
#include <limits>
#include <optional>
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

/// A cyclic graph's candidates side by side, one field after another (field f of candidate j at
/// f * n + j), so a row's partners run on SIMD lanes: the scene point and normal, and in the
/// axis's frame the model point q, its normal u's z, the lengths of q and u across the axis,
/// |q|^2 and u . q.
enum Column { kSx, kSy, kSz, kNx, kNy, kNz, kQx, kQy, kQz, kUz, kFlat, kNflat, kNorm2, kUq, kColumns };
/// The candidates' model points q and normals u in the axis's frame, and their columns.
struct CandidateColumns {
  std::vector<Vec3> q, u;
  std::vector<float> col;            ///< Column f of candidate j at f * n + j
  std::vector<std::uint32_t> scene;  ///< each candidate's scene point
  CandidateColumns(std::span<const Correspondence> cps, const Points& scene_points, const Points& scene_normals,
                   const OrientedModel& model, const AxisFrame& frame)
      : q(cps.size()), u(cps.size()), col(static_cast<std::size_t>(kColumns) * cps.size()), scene(cps.size()) {
    const std::size_t n = cps.size();
    for (std::size_t i = 0; i < n; ++i) {
      q[i] = frame.of(model.points[cps[i].model]);
      const Vec3& m = model.normals[cps[i].model];
      u[i] = {m.dot(frame.ex), m.dot(frame.ey), m.dot(frame.ez)};
      const Vec3& s = scene_points[cps[i].scene];
      const Vec3& ns = scene_normals[cps[i].scene];
      const float values[kColumns] = {s.x(), s.y(), s.z(), ns.x(), ns.y(), ns.z(), q[i].x(), q[i].y(), q[i].z(), u[i].z(),
                                      std::hypot(q[i].x(), q[i].y()), std::hypot(u[i].x(), u[i].y()),
                                      q[i].squaredNorm(), u[i].dot(q[i])};
      for (int f = 0; f < kColumns; ++f) col[static_cast<std::size_t>(f) * n + i] = values[f];
      scene[i] = cps[i].scene;
    }
  }
};

/// Row i's constants for screenRow.
struct RowTerms {
  float col[kColumns];
  std::uint32_t scene;
  float e_gmax, tol;
};

/// The screen of row i's partners j in [begin, end): each pair's terms for the turn test, and its
/// band [t_lo, t_hi] left empty unless it may be linked at some turn (distinct scene points, and
/// the distance and three angles within the bounds they keep whatever the turn: a product's z
/// part plus or minus the product of the parts across the axis; most pairs fail one). Branch-free
/// on SIMD lanes, AVX2 or the baseline chosen at run time; no FMA, so every build screens alike.
__attribute__((target_clones("avx2", "default")))
void screenRow(const float* __restrict c, const std::uint32_t* __restrict scene, int n, const RowTerms& r, int begin,
               int end, float* __restrict t_lo, float* __restrict t_hi, float* __restrict nn, float* __restrict ni_d,
               float* __restrict nj_d, float* __restrict slack) {
  float ci[kColumns];  // on the stack: loads the stores cannot touch
  std::copy(r.col, r.col + kColumns, ci);
  const float e_gmax = r.e_gmax, tol = r.tol;
  const std::uint32_t scene_i = r.scene;
  for (int j = begin; j < end; ++j) {
    const float dx = c[kSx * n + j] - ci[kSx], dy = c[kSy * n + j] - ci[kSy], dz = c[kSz * n + j] - ci[kSz];
    const float nxj = c[kNx * n + j], nyj = c[kNy * n + j], nzj = c[kNz * n + j];
    const float ds = std::sqrt(dx * dx + dy * dy + dz * dz);
    const float below = ds - e_gmax, hi = ds + e_gmax;
    const float lo = 0.5f * (below + std::abs(below));  // max(below, 0) exactly, without a branch
    // |a - R_k b|^2 = |a|^2 + |b|^2 - 2 a.R_k b: within the band of the scene distance when
    // a.R_k b lies in [t_lo, t_hi].
    const float base = ci[kNorm2] + c[kNorm2 * n + j];
    t_lo[j] = 0.5f * (base - hi * hi);
    t_hi[j] = 0.5f * (base - lo * lo);
    nn[j] = ci[kNx] * nxj + ci[kNy] * nyj + ci[kNz] * nzj;
    ni_d[j] = (ci[kNx] * dx + ci[kNy] * dy + ci[kNz] * dz) + ci[kUq];  // n_i . d + u_i . a
    nj_d[j] = c[kUq * n + j] - (nxj * dx + nyj * dy + nzj * dz);      // u_j . b - n_j . d
    slack[j] = tol * ds + e_gmax;
    const float z = ci[kQz] * c[kQz * n + j], across = ci[kFlat] * c[kFlat * n + j];
    int ok = scene[j] != scene_i;
    ok &= t_lo[j] <= z + across;
    ok &= t_hi[j] >= z - across;
    ok &= std::abs(nn[j] - ci[kUz] * c[kUz * n + j]) <= tol + ci[kNflat] * c[kNflat * n + j];
    ok &= std::abs(ni_d[j] - ci[kUz] * c[kQz * n + j]) <= slack[j] + ci[kNflat] * c[kFlat * n + j];
    ok &= std::abs(nj_d[j] - ci[kQz] * c[kUz * n + j]) <= slack[j] + ci[kFlat] * c[kNflat * n + j];
    t_hi[j] -= static_cast<float>(1 - ok) * 1e30f;  // a band no turn is in when screened out (no branch)
  }
}

/// A row's partners that passed the screen, packed in order: their index, model point q (in the
/// axis's frame) and band, each array padded to a multiple of 8 with bands no turn is in.
struct Kept {
  std::vector<int> j;
  std::vector<float> bx, by, bz, lo, hi;
  int count = 0;
  explicit Kept(std::size_t n) : j(n), bx(n + 8), by(n + 8), bz(n + 8), lo(n + 8), hi(n + 8) {}
};

/// The partners j in [begin, end) whose band screenRow left open, into `kept`: of IPD obj 8's
/// pairs 29% pass, and only those go on to the turns.
void keepScreened(const float* __restrict c, int n, int begin, int end, const float* __restrict t_lo,
                  const float* __restrict t_hi, Kept& kept) {
  int m = 0;
  for (int j = begin; j < end; ++j) {  // no branch: each j written, kept when its band is open
    kept.j[m] = j;
    m += t_hi[j] > -1e29f;  // a screened-out band lies at about -1e30, an open one near the model's size squared
  }
  for (int p = 0; p < m; ++p) {
    const int j = kept.j[p];
    kept.bx[p] = c[kQx * n + j];
    kept.by[p] = c[kQy * n + j];
    kept.bz[p] = c[kQz * n + j];
    kept.lo[p] = t_lo[j];
    kept.hi[p] = t_hi[j];
  }
  // Padding, so that turnsInBand runs whole SIMD steps (a row keeps 18 partners on average on
  // IPD obj 8: remainder loops were half its time).
  for (int p = m; p < ((m + 7) & ~7); ++p) {
    kept.bx[p] = kept.by[p] = kept.bz[p] = 0.0f;
    kept.lo[p] = 1.0f;
    kept.hi[p] = -1.0f;
  }
  kept.count = m;
}

/// A row's buffers for n candidates, one set per thread, kept in the caller's GraphWorkspace
/// from graph to graph (every value read is written first).
struct RowScratch {
  std::vector<float> dot, cross, z;
  std::vector<std::uint32_t> turns;
  std::vector<float> t_lo, t_hi, nn_scene, ni_d, nj_d, slack;
  Kept kept{0};
  void fit(std::size_t n) {
    if (t_lo.size() >= n) return;
    for (auto* v : {&dot, &cross, &z}) v->resize(n + 8);
    turns.resize(n + 8);
    for (auto* v : {&t_lo, &t_hi, &nn_scene, &ni_d, &nj_d, &slack}) v->resize(n);
    kept = Kept(n);
  }
};

/// The turns k in [k0, k1), k1 - k0 <= 32, at which row i's model pair has the scene pair's
/// distance: bit k - k0 of turns[p] set when a . R_k b = ck[k] (a.b across the axis) - sk[k]
/// (a x b)_z + a_z b_z lies in [lo[p], hi[p]], for the m kept partners p (b their q, m padded
/// to a multiple of 8). One turn at a time over all of them, on SIMD lanes (AVX2 or the
/// baseline; no FMA).
__attribute__((target_clones("avx2", "default")))
void turnsInBand(const float* __restrict bx, const float* __restrict by, const float* __restrict bz,
                 const float* __restrict lo, const float* __restrict hi, int m, const float* a, const float* ck,
                 const float* sk, int k0, int k1, float* __restrict dot, float* __restrict cross, float* __restrict z,
                 std::uint32_t* __restrict turns) {
  const float ax = a[0], ay = a[1], az = a[2];
  for (int p0 = 0; p0 < m; p0 += 8)
    for (int p = p0; p < p0 + 8; ++p) {  // eight lanes at a step, no remainder
      dot[p] = ax * bx[p] + ay * by[p];
      cross[p] = ax * by[p] - ay * bx[p];
      z[p] = az * bz[p];
      turns[p] = 0;
    }
  for (int k = k0; k < k1; ++k) {
    const float ckk = ck[k], skk = sk[k];
    for (int p0 = 0; p0 < m; p0 += 8)
      for (int p = p0; p < p0 + 8; ++p) {
        const float t = ckk * dot[p] - skk * cross[p] + z[p];
        turns[p] |= static_cast<std::uint32_t>((t >= lo[p]) & (t <= hi[p])) << (k - k0);
      }
  }
}

}  // namespace

Pose CyclicSymmetry::turn(int k) const {
  return turnAbout(axis.direction, kTwoPi * static_cast<float>(k) / static_cast<float>(order), axis.point);
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
                             const OrientedModel& model, const CyclicSymmetry& sym, float e_gmax, float max_angle_deg,
                             GraphWorkspace* workspace) {
  std::optional<GraphWorkspace> own;  // made only for a caller without one
  GraphWorkspace& ws = workspace != nullptr ? *workspace : own.emplace();
  const int n = static_cast<int>(cps.size());
  Graph g(n);
  const CandidateColumns c(cps, scene, scene_normals, model, AxisFrame(sym.axis));
  const std::vector<Vec3>& q = c.q;
  const std::vector<Vec3>& u = c.u;
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
  // Row i's partners j > i into row i alone (rows apart on the cores), mirrored after (mirrorUpper):
  // screened, then the turns of the right distance found, both on SIMD lanes; the three angles
  // are tested only at those turns (1.8 a pair on average of IPD obj 8's 17, where any).
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& rows) {
    RowScratch& scratch = ws.impl().local<RowScratch>();
    scratch.fit(cps.size());
    auto& [dot, cross, z, turns, t_lo, t_hi, nn_scene, ni_d, nj_d, slack, kept] = scratch;
    for (int i = rows.begin(); i < rows.end(); ++i) {
      RowTerms terms{};
      for (int f = 0; f < kColumns; ++f) terms.col[f] = c.col[static_cast<std::size_t>(f) * n + i];
      terms.scene = c.scene[i];
      terms.e_gmax = e_gmax;
      terms.tol = tol;
      screenRow(c.col.data(), c.scene.data(), n, terms, i + 1, n, t_lo.data(), t_hi.data(), nn_scene.data(), ni_d.data(),
                nj_d.data(), slack.data());
      keepScreened(c.col.data(), n, i + 1, n, t_lo.data(), t_hi.data(), kept);
      std::uint64_t* row = g.mutableRow(i);
      const Vec3& a = q[i];
      for (int k0 = 0; k0 < sym.order; k0 += 32) {  // 32 turns at a time: one pass for n <= 32
        turnsInBand(kept.bx.data(), kept.by.data(), kept.bz.data(), kept.lo.data(), kept.hi.data(), (kept.count + 7) & ~7,
                    q[i].data(), ck.data(), sk.data(), k0, std::min(sym.order, k0 + 32), dot.data(), cross.data(), z.data(),
                    turns.data());
        // At a turn of the right distance, the three angles of the pair (4.1) as in the scene, within
        // tol, at every such turn (see above) without a branch: 78% of the kept pairs have a turn
        // and 44% of those link, which no branch predicts.
        for (int p = 0; p < kept.count; ++p) {
          const int j = kept.j[p];
          const Turned nn = turned(u[i], u[j]), na = turned(u[i], q[j]), bn = turned(a, u[j]);
          bool linked = false;
          for (std::uint32_t bits = turns[p]; bits; bits &= bits - 1) {
            const int k = k0 + std::countr_zero(bits);
            linked |= !(std::abs(nn.at(ck[k], sk[k]) - nn_scene[j]) > tol) &
                      !(std::abs(na.at(ck[k], sk[k]) - ni_d[j]) > slack[j]) &  // n_i . (R_k b - a)
                      !(std::abs(bn.at(ck[k], sk[k]) - nj_d[j]) > slack[j]);   // R_k n_j . (a - R_k b)
          }
          row[j / 64] |= std::uint64_t{linked} << (j % 64);
        }
      }
    }
  });
  g.mirrorUpper();
  return g;
}

PoseFit solveCyclicPose(const CyclicSymmetry& sym, const Points& model, const Points& scene) {
  CyclicPoseBuffers buffers;
  return solveCyclicPose(sym, model, scene, buffers);
}

PoseFit solveCyclicPose(const CyclicSymmetry& sym, const Points& model, const Points& scene, CyclicPoseBuffers& b) {
  const int m = static_cast<int>(model.size());
  if (m < 3 || scene.size() != model.size()) return {};
  const int n = sym.order;
  // Every image of every clique point, in one block (image k of point v at v * n + k).
  auto& [image_block, chosen, anchor_model, anchor_scene, misfit, pose_buffer] = b;
  image_block.resize(static_cast<std::size_t>(m) * static_cast<std::size_t>(n));
  misfit.resize(static_cast<std::size_t>(n));
  chosen.resize(static_cast<std::size_t>(m));
  const auto images = [&](int v) { return image_block.data() + static_cast<std::ptrdiff_t>(v) * n; };
  for (int k = 0; k < n; ++k) {
    const Pose t = sym.turn(k);
    for (int v = 0; v < m; ++v) images(v)[k] = t * model[v];
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
  auto fill = [&](int v, std::span<const std::pair<int, int>> placed) {
    for (int k = 0; k < n; ++k) {
      float e = 0;
      for (const auto& [u, ku] : placed) {
        const float r = (scene[v] - scene[u]).norm() - (images(v)[k] - images(u)[ku]).norm();
        e += r * r;
      }
      misfit[k] = e;
    }
  };
  PoseFit best;
  best.rms = std::numeric_limits<float>::max();
  fill(a1, std::array{std::pair{a0, 0}});
  const int k1_best = smallest(misfit);
  const std::array<int, 2> k1s{k1_best, smallest(misfit, k1_best)};  // a reflection of the pair fits as well
  for (const int k1 : k1s) {
    const std::array placed{std::pair{a0, 0}, std::pair{a1, k1}};
    fill(a2, placed);
    const int k2_best = smallest(misfit);
    for (const int k2 : {k2_best, smallest(misfit, k2_best)}) {
      anchor_model = {images(a0)[0], images(a1)[k1], images(a2)[k2]};
      anchor_scene = {scene[a0], scene[a1], scene[a2]};
      const PoseFit start = solvePose(anchor_model, anchor_scene, pose_buffer);
      if (!start.ok) continue;
      // Each point at its image nearest the scene under the anchors' pose.
      for (int v = 0; v < m; ++v) {
        int kv = 0;
        float d_best = std::numeric_limits<float>::max();
        for (int k = 0; k < n; ++k)
          if (const float d = (start.pose * images(v)[k] - scene[v]).squaredNorm(); d < d_best) {
            d_best = d;
            kv = k;
          }
        chosen[v] = images(v)[kv];
      }
      const PoseFit fit = solvePose(chosen, scene, pose_buffer);
      if (fit.ok && fit.rms < best.rms) best = fit;
    }
  }
  if (!best.ok) return {};
  return best;
}

}  // namespace binpose
