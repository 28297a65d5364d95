// Offline model preparation (thesis chapter 6).
#include <binpose/model.hpp>

#include <Eigen/Eigenvalues>

#include <binpose/geometry.hpp>
#include <binpose/normals.hpp>
#include <binpose/sampling.hpp>
#include <binpose/viewpoint.hpp>

#include "outward_normals.hpp"

#include <array>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <numeric>
#include <utility>
#include <vector>
#include <algorithm>
#include <cstdint>

namespace binpose {
namespace {

/// A point-cloud model hiding more than this share of itself from its viewpoint is no single view
/// (guessViewpoint's own bound for a scan seen by its sensor).
constexpr float kOneViewHidden = 0.05f;

void checkParams(const ModelParams& p) {
  if (p.rho_model < 0 || !std::isfinite(p.rho_model))
    throw Error(fmt::format("rho_model must be >= 0 points/mm^2, got {}", p.rho_model));
  if (p.rho_model == 0 && (p.num_points < 16 || p.num_points > 65535))
    throw Error(fmt::format("model points must lie in [16, 65535], got {}", p.num_points));
  if (p.normal_k < 3 || p.normal_k > 1000) throw Error(fmt::format("normal k must lie in [3, 1000], got {}", p.normal_k));
}

std::size_t targetCount(const ModelParams& p, double area) {
  if (p.rho_model <= 0) return static_cast<std::size_t>(p.num_points);
  const double n = std::round(p.rho_model * area);
  if (n < 16 || n > 65535)
    throw Error(fmt::format("rho_model {} points/mm^2 over {:.0f} mm^2 gives {:.0f} points; need 16..65535",
                            p.rho_model, area, n));
  return static_cast<std::size_t>(n);
}

/// For each face corner, the area-weighted mean normal of the faces around that vertex whose
/// normal lies within the crease angle of this face's: smooth across soft edges, sharp at creases.
std::vector<std::array<Vec3, 3>> cornerNormals(const Mesh& mesh, const Points& face_n, double crease_deg) {
  std::vector<std::vector<int>> faces_of(mesh.vertices.size());
  std::vector<float> area(mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& t = mesh.faces[f];
    area[f] = 0.5f * (mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]).norm();
    for (int k = 0; k < 3; ++k) faces_of[t[k]].push_back(static_cast<int>(f));
  }
  const float cos_crease = static_cast<float>(std::cos(crease_deg * std::numbers::pi / 180.0));
  std::vector<std::array<Vec3, 3>> corners(mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      Vec3 sum = Vec3::Zero();
      for (const int g : faces_of[mesh.faces[f][k]])
        if (face_n[g].dot(face_n[f]) >= cos_crease) sum += area[g] * face_n[g];
      corners[f][k] = normalizeSafe(sum) ? sum : face_n[f];
    }
  return corners;
}

/// Each vertex's first vertex at the same position, bit for bit: a mesh saved face by face (STL,
/// a PLY with a vertex per face corner) repeats a position once per face around it.
std::vector<std::uint32_t> samePositions(const Points& vertices) {
  std::vector<std::uint32_t> order(vertices.size());
  std::iota(order.begin(), order.end(), 0u);
  const auto key = [&](std::uint32_t i) { return std::array<float, 3>{vertices[i].x(), vertices[i].y(), vertices[i].z()}; };
  std::sort(order.begin(), order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return std::pair(key(a), a) < std::pair(key(b), b); });
  std::vector<std::uint32_t> first(vertices.size());
  for (std::size_t k = 0; k < order.size(); ++k)
    first[order[k]] = k > 0 && key(order[k]) == key(order[k - 1]) ? first[order[k - 1]] : order[k];
  return first;
}

/// The faces of each edge shared by exactly two (vertices matched by position), with whether
/// they run it in opposite directions, as a consistently wound surface does.
std::vector<std::vector<std::pair<std::uint32_t, bool>>> edgeNeighbours(const Mesh& mesh) {
  const std::vector<std::uint32_t> same = samePositions(mesh.vertices);
  struct Side {
    std::uint64_t edge;
    std::uint32_t face;
    bool forward;
  };
  std::vector<Side> sides;
  for (std::uint32_t f = 0; f < mesh.faces.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t a = same[mesh.faces[f][k]], b = same[mesh.faces[f][(k + 1) % 3]];
      if (a != b) sides.push_back({std::min(a, b) << 32 | std::max(a, b), f, a < b});
    }
  std::sort(sides.begin(), sides.end(),
            [](const Side& x, const Side& y) { return std::pair(x.edge, x.face) < std::pair(y.edge, y.face); });
  std::vector<std::vector<std::pair<std::uint32_t, bool>>> neighbours(mesh.faces.size());
  for (std::size_t i = 0, j = 0; i < sides.size(); i = j) {
    j = i + 1;
    while (j < sides.size() && sides[j].edge == sides[i].edge) ++j;
    if (j - i != 2 || sides[i].face == sides[i + 1].face) continue;  // a boundary or a non-manifold edge
    const bool opposite = sides[i].forward != sides[i + 1].forward;
    neighbours[sides[i].face].emplace_back(sides[i + 1].face, opposite);
    neighbours[sides[i + 1].face].emplace_back(sides[i].face, opposite);
  }
  return neighbours;
}

/// The faces wound against the rest of their connected surface (a mesh without normals): across
/// the edges that two faces share, each patch is made consistent, wound as most of its faces are.
/// An exporter that flips some faces leaves their normals inward, and every feature with them.
std::vector<char> againstTheirSurface(const Mesh& mesh) {
  const auto neighbours = edgeNeighbours(mesh);
  std::vector<char> flip(mesh.faces.size(), 0), seen(mesh.faces.size(), 0);
  std::vector<std::uint32_t> patch;
  for (std::uint32_t start = 0; start < mesh.faces.size(); ++start) {
    if (seen[start]) continue;
    patch.assign(1, start);
    seen[start] = 1;
    for (std::size_t k = 0; k < patch.size(); ++k)  // breadth first; a non-orientable surface keeps the first reached
      for (const auto& [g, opposite] : neighbours[patch[k]])
        if (!seen[g]) {
          seen[g] = 1;
          flip[g] = static_cast<char>(flip[patch[k]] ^ !opposite);
          patch.push_back(g);
        }
    const auto flipped = std::count_if(patch.begin(), patch.end(), [&](std::uint32_t f) { return flip[f] != 0; });
    if (2 * static_cast<std::size_t>(flipped) > patch.size())
      for (const std::uint32_t f : patch) flip[f] = static_cast<char>(!flip[f]);
  }
  return flip;
}

}  // namespace

Points faceNormals(const Mesh& mesh) {
  Points normals(mesh.faces.size(), Vec3::Zero());
  const std::vector<char> flip = mesh.hasNormals() ? std::vector<char>(mesh.faces.size(), 0) : againstTheirSurface(mesh);
  double signed_volume = 0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Vec3 &a = mesh.vertices[mesh.faces[f][0]], &b = mesh.vertices[mesh.faces[f][1]], &c = mesh.vertices[mesh.faces[f][2]];
    const float side = flip[f] ? -1.0f : 1.0f;
    Vec3 n = side * (b - a).cross(c - a);
    signed_volume += side * static_cast<double>(a.dot(b.cross(c))) / 6.0;
    if (!normalizeSafe(n)) continue;
    if (mesh.hasNormals()) {  // trust the file's vertex normals for the side, face by face
      const Vec3 given = mesh.normals[mesh.faces[f][0]] + mesh.normals[mesh.faces[f][1]] + mesh.normals[mesh.faces[f][2]];
      if (n.dot(given) < 0) n = -n;
    }
    normals[f] = n;
  }
  if (!mesh.hasNormals() && signed_volume < 0)  // wound inwards: turn every face
    for (Vec3& n : normals) n = -n;
  return normals;
}

OrientedModel prepareModel(const Mesh& mesh, const ModelParams& params) {
  checkParams(params);
  OrientedModel model;
  model.area = meshArea(mesh);
  if (!(model.area > 0)) throw Error("model mesh has zero surface area");
  const std::size_t target = targetCount(params, model.area);
  const Points face_n = faceNormals(mesh);
  const auto corners = cornerNormals(mesh, face_n, params.crease_angle_deg);
  // A pool 20x denser than the target, thinned by dart throwing (Cline et al. 2009).
  const auto pool = sampleSurfaceUniform(mesh, std::max<std::size_t>(20 * target, 20000), params.seed);
  Points pool_points(pool.size());
  for (std::size_t i = 0; i < pool.size(); ++i) pool_points[i] = pool[i].point;
  const auto kept = poissonDiskSelectCount(pool_points, target, params.seed + 1, &model.sample_radius);
  for (const std::uint32_t i : kept) {
    const SurfacePoint& s = pool[i];
    const auto& c = corners[s.face];
    Vec3 n = s.weights[0] * c[0] + s.weights[1] * c[1] + s.weights[2] * c[2];
    if (!normalizeSafe(n)) continue;  // only on a degenerate face
    model.points.push_back(s.point);
    model.normals.push_back(n);
  }
  model.diameter = diameter(model.points);
  return model;
}

OrientedModel prepareModel(const PointCloud& cloud, const ModelParams& params) {
  checkParams(params);
  if (cloud.size() < 16) throw Error(fmt::format("model cloud has {} points; need at least 16", cloud.size()));
  if (params.rho_model > 0) throw Error("rho_model needs a mesh (a point cloud has no known area); give --points");
  OrientedModel model;
  const auto target = static_cast<std::size_t>(params.num_points);
  const auto kept = poissonDiskSelectCount(cloud.points, target, params.seed, &model.sample_radius);
  Points sampled;
  for (const std::uint32_t i : kept) sampled.push_back(cloud.points[i]);
  Points fitted = estimateNormals(cloud.points, sampled, params.normal_k, cloud.viewpoint);
  // Points all round the part face no one viewpoint: seen from anywhere, a share of them is
  // hidden behind the rest (a single view of the part hides none from its sensor).
  if (!cloud.hasNormals() && guessViewpoint(cloud.points, cloud.viewpoint).assumed_hidden > kOneViewHidden)
    orientOutward(sampled, fitted);
  for (std::size_t s = 0; s < kept.size(); ++s) {
    const bool given = cloud.hasNormals() && cloud.normals[kept[s]].squaredNorm() > 0.5f;
    const Vec3 n = given ? cloud.normals[kept[s]] : fitted[s];
    if (n.squaredNorm() < 0.5f) continue;  // no usable normal
    model.points.push_back(sampled[s]);
    model.normals.push_back(n);
  }
  if (model.points.size() < 16) throw Error("model cloud has too few points with a usable normal");
  model.diameter = diameter(model.points);
  return model;
}

float boundingFaceArea(const Points& points) {
  if (points.size() < 3) return 0.0f;
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : points) mean += p;
  mean /= static_cast<float>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& p : points) cov += (p - mean).cast<double>() * (p - mean).cast<double>().transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);  // eigenvalues increasing
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (const Vec3& p : points) {
    const Eigen::Vector3d q = eig.eigenvectors().transpose() * (p - mean).cast<double>();
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  const Eigen::Vector3d extent = hi - lo;
  return static_cast<float>(extent(1) * extent(2));
}

}  // namespace binpose
