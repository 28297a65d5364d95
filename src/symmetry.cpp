// Bodies of revolution: orbits of model points, their consistency, the pose from an axis.
#include <binpose/symmetry.hpp>

#include <binpose/kdtree.hpp>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

namespace binpose {
namespace {

/// True when every turn in the test set keeps at least 97% of the points within `tolerance`.
bool isRevolutionAxis(const Points& points, const KdTree& tree, const Vec3& centre, const Vec3& axis, float tolerance) {
  constexpr float kTurnsDeg[] = {29.0f, 83.0f, 137.0f, 211.0f, 290.0f};
  for (const float deg : kTurnsDeg)
    if (!turnKeepsShape(points, tree, centre, axis, deg * float(M_PI) / 180.0f, tolerance)) return false;
  return true;
}

/// Axis directions a (|a| = 1) minimising sum (n_i . a - nz_i)^2: each point's normal tilt
/// (ProfilePoint::nz) is what a turn keeps. A constrained least squares (the trust-region
/// subproblem): a = (M - mu I)^-1 g with mu < the least eigenvalue of M chosen so |a| = 1.
/// Two answers where the tilts leave the sign free (all nz_i = 0: points on a cylinder).
std::vector<Vec3> axesFromNormals(const Points& normals, std::span<const float> nz) {
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const Eigen::Vector3d n = normals[i].cast<double>();
    M += n * n.transpose();
    g += double(nz[i]) * n;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(M);
  const Eigen::Vector3d lambda = eig.eigenvalues();  // ascending
  const Eigen::Vector3d gh = eig.eigenvectors().transpose() * g;
  auto length2 = [&](double mu) {
    double s = 0;
    for (int k = 0; k < 3; ++k) s += gh[k] * gh[k] / ((lambda[k] - mu) * (lambda[k] - mu));
    return s;
  };
  const double scale = std::max(1.0, lambda[2]);
  if (std::abs(gh[0]) > 1e-6 * scale) {  // the usual case: one answer, mu in (lambda_0 - |g|, lambda_0)
    double lo = lambda[0] - g.norm() - 1e-9, hi = lambda[0];
    for (int it = 0; it < 100; ++it) {
      const double mid = 0.5 * (lo + hi);
      (length2(mid) < 1.0 ? lo : hi) = mid;
    }
    Eigen::Vector3d y;
    for (int k = 0; k < 3; ++k) y[k] = gh[k] / (lambda[k] - lo);
    return {(eig.eigenvectors() * y).normalized().cast<float>()};
  }
  // The hard case: a = the other components at mu = lambda_0, plus +-tau along the least
  // eigenvector to unit length.
  Eigen::Vector3d y = Eigen::Vector3d::Zero();
  for (int k = 1; k < 3; ++k) y[k] = lambda[k] - lambda[0] > 1e-12 ? gh[k] / (lambda[k] - lambda[0]) : 0.0;
  const double tau = std::sqrt(std::max(0.0, 1.0 - y.squaredNorm()));
  std::vector<Vec3> out;
  for (const double sign : {1.0, -1.0}) {
    Eigen::Vector3d a = y;
    a[0] = sign * tau;
    if (a.norm() > 1e-9) out.push_back((eig.eigenvectors() * a).normalized().cast<float>());
  }
  return out;
}


/// The scene axis (direction a, the point c where the model's axis point lands) of oriented
/// scene points with known profiles: initial guess and Gauss-Newton refinement.
struct AxisFit {
  const Points* scene = nullptr;
  const Points* normals = nullptr;
  std::vector<ProfilePoint> profile;
  static constexpr double kTiltWeight = 5.0;  ///< mm per unit of normal tilt residual
  /// Residual and Jacobian buffers, sized once for all the steps (a cap bin's clique fits
  /// allocated some 5700 times a run with a vector per residual evaluation).
  mutable Eigen::VectorXd r0_, r1_;
  mutable Eigen::MatrixXd J_;

  /// The centre q across the axis (basis fx, fy) of the circles of the known radii:
  /// |p_i - q|^2 = r_i^2, less its mean, is linear in q. False when the points leave it open.
  bool circleCentre(const Eigen::Vector3d& fx, const Eigen::Vector3d& fy, Eigen::Vector2d& centre) const {
    const std::size_t n = profile.size();
    std::vector<Eigen::Vector2d> ps;
    Eigen::Vector2d pm = Eigen::Vector2d::Zero();
    double q = 0, r2 = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d s = (*scene)[i].cast<double>();
      ps.emplace_back(s.dot(fx), s.dot(fy));
      pm += ps.back();
      q += ps.back().squaredNorm();
      r2 += double(profile[i].r) * profile[i].r;
    }
    pm /= double(n), q /= double(n), r2 /= double(n);
    Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d row = 2.0 * (ps[i] - pm);
      A += row * row.transpose();
      b += ((ps[i].squaredNorm() - q) - (double(profile[i].r) * profile[i].r - r2)) * row;
    }
    if (std::abs(A.determinant()) < 1e-6 * std::max(1.0, A.squaredNorm())) return false;
    centre = A.ldlt().solve(b);
    return true;
  }

  /// c for axis a: the height from the mean of s_i . a - z_i; across the axis, each point's
  /// radius back along its normal's radial part (the normal of a body of revolution lies in its
  /// meridian plane), or with too few such points the circle of the known radii.
  bool initialCentre(const Eigen::Vector3d& a, Eigen::Vector3d& c) const {
    const std::size_t n = profile.size();
    Vec3 fx3, fy3;
    basisAround(a.cast<float>(), fx3, fy3);
    const Eigen::Vector3d fx = fx3.cast<double>(), fy = fy3.cast<double>();
    double h = 0;
    for (std::size_t i = 0; i < n; ++i) h += (*scene)[i].cast<double>().dot(a) - profile[i].z;
    h /= double(n);
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    double weight = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const ProfilePoint& m = profile[i];
      const Eigen::Vector3d s = (*scene)[i].cast<double>(), nrm = (*normals)[i].cast<double>();
      const Eigen::Vector2d nperp(nrm.dot(fx), nrm.dot(fy));
      if (std::abs(m.nr) < 0.3f || nperp.norm() < 0.3) continue;
      const double w = std::abs(m.nr);
      centre += w * (Eigen::Vector2d(s.dot(fx), s.dot(fy)) - double(m.r) * (m.nr > 0 ? 1.0 : -1.0) * nperp.normalized());
      weight += w;
    }
    if (weight >= 0.5) {
      centre /= weight;
    } else if (!circleCentre(fx, fy, centre)) {
      return false;
    }
    c = centre.x() * fx + centre.y() * fy + h * a;
    return c.allFinite();
  }

  /// Residuals: each point's height and radius about the axis less its profile's (mm), and its
  /// normal's axial part less the profile's (times kTiltWeight).
  void residuals(const Eigen::Vector3d& a, const Eigen::Vector3d& c, Eigen::VectorXd& r) const {
    const std::size_t n = profile.size();
    r.resize(static_cast<Eigen::Index>(3 * n));  // no allocation once sized
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d v = (*scene)[i].cast<double>() - c;
      const double z = v.dot(a);
      r[3 * i] = z - profile[i].z;
      r[3 * i + 1] = (v - z * a).norm() - profile[i].r;
      r[3 * i + 2] = kTiltWeight * ((*normals)[i].cast<double>().dot(a) - profile[i].nz);
    }
  }

  [[nodiscard]] double positionRms(const Eigen::Vector3d& a, const Eigen::Vector3d& c) const {
    Eigen::VectorXd& r = r0_;
    residuals(a, c, r);
    double sq = 0;
    for (std::size_t i = 0; i < profile.size(); ++i) sq += r[3 * i] * r[3 * i] + r[3 * i + 1] * r[3 * i + 1];
    return std::sqrt(sq / double(profile.size()));
  }

  /// Gauss-Newton (Levenberg-damped) over the axis's 2 turns and the point's 3 shifts, with a
  /// numeric Jacobian: a few points, a few steps.
  void refine(Eigen::Vector3d& a, Eigen::Vector3d& c) const {
    auto moved = [](const Eigen::Vector3d& a0, const Eigen::Vector3d& c0, const Eigen::Matrix<double, 5, 1>& d,
                    Eigen::Vector3d& a1, Eigen::Vector3d& c1) {
      Vec3 e1f, e2f;
      basisAround(a0.cast<float>(), e1f, e2f);
      const Eigen::Vector3d e1 = e1f.cast<double>(), e2 = e2f.cast<double>();
      a1 = (a0 + d[0] * e1 + d[1] * e2).normalized();
      c1 = c0 + d[2] * e1 + d[3] * e2 + d[4] * a0;
    };
    Eigen::VectorXd &r0 = r0_, &r1 = r1_;  // the residuals here and at a trial step
    Eigen::MatrixXd& J = J_;
    residuals(a, c, r0);
    double cost = r0.squaredNorm();
    for (int it = 0; it < 4; ++it) {
      J.resize(r0.size(), 5);
      for (int k = 0; k < 5; ++k) {
        Eigen::Matrix<double, 5, 1> d = Eigen::Matrix<double, 5, 1>::Zero();
        const double step = k < 2 ? 1e-5 : 1e-4;
        d[k] = step;
        Eigen::Vector3d a1, c1;
        moved(a, c, d, a1, c1);
        residuals(a1, c1, r1);
        J.col(k) = (r1 - r0) / step;
      }
      Eigen::Matrix<double, 5, 5> H = J.transpose() * J;
      H.diagonal() *= 1.0 + 1e-6;
      const Eigen::Matrix<double, 5, 1> d = -H.ldlt().solve(J.transpose() * r0);
      if (!d.allFinite()) return;
      Eigen::Vector3d a1, c1;
      moved(a, c, d, a1, c1);
      residuals(a1, c1, r1);
      const double next = r1.squaredNorm();
      if (!(next < cost)) return;
      const bool done = cost - next < 1e-9 * cost;
      a = a1, c = c1, cost = next;
      r0.swap(r1);  // the residuals at the step taken are those here now
      if (done) return;
    }
  }
};

/// The pose taking the model's axis frame onto the scene's (a through c), turned so that
/// `first` (a model point) lands at the azimuth of `at` (its scene point).
Pose axisPose(const Orbits& orbits, const Vec3& first, const Vec3& a, const Vec3& c, const Vec3& at) {
  Vec3 ex, ey, fx, fy;
  basisAround(orbits.axis.direction, ex, ey);
  basisAround(a, fx, fy);
  const Vec3 vm = first - orbits.axis.point, vs = at - c;
  const float turn = std::atan2(vs.dot(fy), vs.dot(fx)) - std::atan2(vm.dot(ey), vm.dot(ex));
  Eigen::Matrix3f Bm, Bs;
  Bm << ex, ey, orbits.axis.direction;
  Bs << fx, fy, a;
  Pose pose = Pose::Identity();
  pose.linear() = Bs * Eigen::AngleAxisf(turn, Vec3::UnitZ()).toRotationMatrix() * Bm.transpose();
  pose.translation() = c - pose.linear() * orbits.axis.point;
  return pose;
}

}  // namespace

void basisAround(const Vec3& z, Vec3& x, Vec3& y) {
  const Vec3 helper = std::abs(z.x()) < 0.6f ? Vec3::UnitX() : Vec3::UnitY();
  x = (helper - helper.dot(z) * z).normalized();
  y = z.cross(x);
}

PrincipalAxes principalAxes(const Points& points) {
  PrincipalAxes out;
  if (points.empty()) return out;
  for (const Vec3& p : points) out.centre += p;
  out.centre /= static_cast<float>(points.size());
  Eigen::Matrix3f cov = Eigen::Matrix3f::Zero();
  for (const Vec3& p : points) cov += (p - out.centre) * (p - out.centre).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eig(cov);
  out.values = eig.eigenvalues();
  out.axes = eig.eigenvectors();
  return out;
}

bool turnKeepsShape(const Points& points, const KdTree& tree, const Vec3& centre, const Vec3& axis, float angle,
                    float tolerance) {
  const Eigen::AngleAxisf turn(angle, axis);
  const auto allowed = static_cast<std::size_t>(0.03 * static_cast<double>(points.size()));
  std::size_t off = 0;
  for (const Vec3& p : points) {
    std::uint32_t j;
    float d2;
    if (!tree.nearest(centre + turn * (p - centre), j, d2) || d2 > tolerance * tolerance) ++off;
    if (off > allowed) return false;
  }
  return true;
}

std::optional<RevolutionAxis> findRevolutionAxis(const OrientedModel& model, float tolerance) {
  const Points& pts = model.points;
  if (pts.size() < 10) return std::nullopt;
  if (tolerance <= 0) tolerance = 1.5f * model.sample_radius;
  if (!(tolerance > 0)) return std::nullopt;
  const PrincipalAxes principal = principalAxes(pts);
  const Vec3& centre = principal.centre;
  // The axis of a body of revolution is the principal axis whose eigenvalue stands apart: try
  // the one farthest from the other two first.
  const Eigen::Vector3f& l = principal.values;
  std::array<int, 3> order{0, 1, 2};
  auto apart = [&](int k) { return std::min(std::abs(l[k] - l[(k + 1) % 3]), std::abs(l[k] - l[(k + 2) % 3])); };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return apart(a) > apart(b); });
  const KdTree tree(pts);
  for (const int k : order) {
    const Vec3 axis = principal.axes.col(k).normalized();
    if (isRevolutionAxis(pts, tree, centre, axis, tolerance)) return RevolutionAxis{centre, axis};
  }
  return std::nullopt;
}

ProfilePoint profileOf(const RevolutionAxis& axis, const Vec3& point, const Vec3& normal) {
  const Vec3 v = point - axis.point;
  ProfilePoint p;
  p.z = v.dot(axis.direction);
  const Vec3 radial = v - p.z * axis.direction;
  p.r = radial.norm();
  p.nz = normal.dot(axis.direction);
  // The normal's radial part: along the point's own radial direction (a normal of a body of
  // revolution lies in its meridian plane); at the axis itself, its whole off-axis part.
  p.nr = p.r > 1e-6f ? normal.dot(radial / p.r) : std::sqrt(std::max(0.0f, 1.0f - p.nz * p.nz));
  return p;
}

Orbits makeOrbits(const ModelDatabase& db, const RevolutionAxis& axis, float cell) {
  const OrientedModel& model = db.model();
  if (model.points.size() > 65535) throw Error("too many model points for orbits");
  Orbits o;
  o.axis = axis;
  std::map<std::tuple<int, int, int>, std::uint32_t> ids;  // (r cell, z cell, tilt octant) -> orbit
  std::vector<Eigen::Vector4d> sum;  // per orbit: sums of r, z, nr, nz
  std::vector<int> size;
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    const ProfilePoint p = profileOf(axis, model.points[i], model.normals[i]);
    const float tilt = std::atan2(p.nz, p.nr);  // [-pi, pi]
    const auto key = std::make_tuple(static_cast<int>(std::floor(p.r / cell)), static_cast<int>(std::floor(p.z / cell)),
                                     std::min(7, static_cast<int>(std::floor((tilt + float(M_PI)) / (float(M_PI) / 4)))));
    const auto [it, fresh] = ids.emplace(key, o.count);
    if (fresh) {
      ++o.count;
      o.member.push_back(static_cast<std::uint32_t>(i));
      sum.emplace_back(Eigen::Vector4d::Zero());
      size.push_back(0);
    }
    o.of.push_back(it->second);
    sum[it->second] += Eigen::Vector4d(p.r, p.z, p.nr, p.nz);
    ++size[it->second];
  }
  for (std::uint32_t k = 0; k < o.count; ++k) {
    const Eigen::Vector4d mean = sum[k] / double(size[k]);
    const double tilt = std::hypot(mean[2], mean[3]);
    ProfilePoint p;
    p.r = float(mean[0]);
    p.z = float(mean[1]);
    p.nr = tilt > 1e-9 ? float(mean[2] / tilt) : 0.0f;
    p.nz = tilt > 1e-9 ? float(mean[3] / tilt) : 1.0f;
    o.profile.push_back(p);
  }
  // Each key's list of model points as a list of their orbits, each once, ascending.
  const auto keys = db.keySpace().size();
  o.offsets.assign(std::size_t{keys} + 1, 0);
  std::vector<char> seen(o.count, 0);
  std::vector<ModelDatabase::PointId> list;
  for (std::uint32_t k = 0; k < keys; ++k) {
    o.offsets[k] = static_cast<std::uint32_t>(o.entries.size());
    list.clear();
    for (const auto id : db.lookup(k))
      if (!seen[o.of[id]]) {
        seen[o.of[id]] = 1;
        list.push_back(static_cast<ModelDatabase::PointId>(o.of[id]));
      }
    for (const auto orbit : list) seen[orbit] = 0;
    std::sort(list.begin(), list.end());
    o.entries.insert(o.entries.end(), list.begin(), list.end());
  }
  o.offsets[keys] = static_cast<std::uint32_t>(o.entries.size());
  return o;
}

Graph revolutionConsistencyGraph(std::span<const Correspondence> cps, const Points& scene, const Points& scene_normals,
                                 const Orbits& orbits, float e_gmax, float max_angle_deg) {
  const int n = static_cast<int>(cps.size());
  Graph g(n);
  const float tol = std::sin(max_angle_deg * float(M_PI) / 180.0f);
  for (int i = 0; i < n; ++i) {
    const ProfilePoint& a = orbits.profile[orbits.of[cps[i].model]];
    const Vec3& si = scene[cps[i].scene];
    const Vec3& ni = scene_normals[cps[i].scene];
    for (int j = i + 1; j < n; ++j) {
      if (cps[i].scene == cps[j].scene) continue;
      const ProfilePoint& b = orbits.profile[orbits.of[cps[j].model]];
      const Vec3 d = scene[cps[j].scene] - si;
      const Vec3& nj = scene_normals[cps[j].scene];
      const float dist = d.norm();
      const float dz = b.z - a.z;
      // |m_j - m_i|^2 = r_i^2 + r_j^2 - 2 r_i r_j cos(turn) + dz^2: the turn's cosine from the
      // scene distance, if some turn (cosine in [-1, 1]) gives it within e_gmax.
      const float base = a.r * a.r + b.r * b.r + dz * dz, span = 2.0f * a.r * b.r;
      const float lo = std::max(0.0f, dist - e_gmax), hi = dist + e_gmax;
      if (base - span > hi * hi || base + span < lo * lo) continue;
      const float c = span > 1e-6f ? std::clamp((base - dist * dist) / span, -1.0f, 1.0f) : 1.0f;
      // The model pair at that turn (point i in the plane of zero turn): normals' dot product
      // and each normal's component along the line to the other point.
      const float nn = a.nr * b.nr * c + a.nz * b.nz;
      const float ni_d = a.nr * (b.r * c - a.r) + a.nz * dz;
      const float nj_d = b.nr * (a.r * c - b.r) - b.nz * dz;
      if (std::abs(nn - ni.dot(nj)) > tol) continue;
      const float slack = tol * dist + e_gmax;
      if (std::abs(ni_d - ni.dot(d)) > slack || std::abs(nj_d + nj.dot(d)) > slack) continue;
      g.addEdge(i, j);
    }
  }
  return g;
}

std::vector<PoseFit> solveRevolutionPoses(const Orbits& orbits, std::span<const std::uint32_t> model_ids,
                                          const Points& model_points, const Points& scene, const Points& scene_normals) {
  std::vector<PoseFit> fits;
  const std::size_t n = model_ids.size();
  if (n < 3 || scene.size() != n || scene_normals.size() != n) return fits;
  AxisFit fit;
  fit.scene = &scene;
  fit.normals = &scene_normals;
  fit.profile.reserve(n);
  for (std::size_t i = 0; i < n; ++i) fit.profile.push_back(orbits.profile[orbits.of[model_ids[i]]]);
  std::vector<float> nz(n);
  for (std::size_t i = 0; i < n; ++i) nz[i] = fit.profile[i].nz;
  for (const Vec3& start : axesFromNormals(scene_normals, nz)) {
    Eigen::Vector3d a = start.cast<double>(), c;
    if (!a.allFinite() || !fit.initialCentre(a, c)) continue;
    fit.refine(a, c);
    PoseFit f;
    f.pose = axisPose(orbits, model_points[model_ids[0]], a.cast<float>(), c.cast<float>(), scene[0]);
    f.rms = static_cast<float>(fit.positionRms(a, c));
    f.ok = f.pose.matrix().allFinite() && std::isfinite(f.rms);
    if (f.ok) fits.push_back(f);
  }
  std::stable_sort(fits.begin(), fits.end(), [](const PoseFit& x, const PoseFit& y) { return x.rms < y.rms; });
  return fits;
}

PoseFit solveRevolutionPose(const Orbits& orbits, std::span<const std::uint32_t> model_ids, const Points& model_points,
                            const Points& scene, const Points& scene_normals) {
  const auto fits = solveRevolutionPoses(orbits, model_ids, model_points, scene, scene_normals);
  return fits.empty() ? PoseFit{} : fits.front();
}

}  // namespace binpose
