// Outward normals of a point-cloud model (Hoppe et al. 1992, "Surface reconstruction from
// unorganized points", section 3.3: consistent tangent plane orientation).
#include "outward_normals.hpp"

#include <binpose/kdtree.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <queue>
#include <tuple>
#include <vector>

namespace binpose {
namespace {

/// Neighbours of each point in the graph the sign passes along.
constexpr std::size_t kNeighbours = 10;
/// A neighbour farther off either point's tangent plane than this share of their distance is not
/// linked: a thin plate's other side lies across it (at 0.35 or 0.45 the sign crossed IPD obj 0's
/// or obj 1's plates on some samplings, and half the model pointed in).
constexpr float kMostRise = 0.25f;

struct Link {
  float weight;
  std::uint32_t to, from;
  friend bool operator>(const Link& a, const Link& b) {
    return std::tie(a.weight, a.to, a.from) > std::tie(b.weight, b.to, b.from);
  }
};

/// Twice the largest distance of a point from `centre`: no ray through the part is longer.
float diameterBound(const Points& points, const Vec3& centre) {
  float most = 0;
  for (const Vec3& p : points) most = std::max(most, (p - centre).norm());
  return 2.0f * most;
}

/// Each point's links: its nearest neighbours near its tangent plane, and those that link to it.
std::vector<std::vector<Link>> neighbourGraph(const KdTree& tree, const Points& points, const Points& normals) {
  std::vector<std::vector<Link>> links(points.size());
  std::uint32_t idx[kNeighbours + 1];
  float d2[kNeighbours + 1];
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    if (normals[i].squaredNorm() < 0.5f) continue;
    const std::size_t found = tree.knn(points[i], kNeighbours + 1, idx, d2);
    for (std::size_t k = 0; k < found; ++k) {
      const std::uint32_t j = idx[k];
      if (j == i || normals[j].squaredNorm() < 0.5f) continue;
      const Vec3 d = points[j] - points[i];
      if (std::max(std::abs(normals[i].dot(d)), std::abs(normals[j].dot(d))) > kMostRise * d.norm()) continue;
      const float w = 1.0f - std::abs(normals[i].dot(normals[j]));
      links[i].push_back({w, j, i});
      links[j].push_back({w, i, j});
    }
  }
  return links;
}

/// Points of a piece whose outward rays are counted, spread evenly over it.
constexpr std::size_t kPieceVoters = 31;
/// A ray passes through the part's surface where a point lies within this many point spacings.
constexpr float kCrossingSpacings = 1.0f;
/// Pieces whose rays are counted, largest first: a cloud too rough for any link would otherwise
/// cast two rays from every point. The rest keep their start's side (away from the centroid).
constexpr std::size_t kMostVotedPieces = 256;

/// The number of times the ray from p along d (unit) passes through the cloud's surface, marched
/// in half spacings from two spacings out to `length`: each run of steps with a point within
/// kCrossingSpacings is one crossing. Out of a closed surface an even number, into it odd.
int crossings(const KdTree& tree, const Vec3& p, const Vec3& d, float spacing, float length) {
  const float reach = kCrossingSpacings * spacing;
  int count = 0;
  bool inside = false;
  for (float t = 2.0f * spacing; t <= length; t += 0.5f * spacing) {
    std::uint32_t j;
    float d2;
    const bool near = tree.nearest(p + t * d, j, d2) && d2 <= reach * reach;
    count += near && !inside;
    inside = near;
  }
  return count;
}

/// The median distance of a point to its nearest neighbour.
float medianSpacing(const KdTree& tree, const Points& points) {
  std::vector<float> gaps;
  std::uint32_t idx[2];
  float d2[2];
  for (const Vec3& p : points)
    if (tree.knn(p, 2, idx, d2) == 2) gaps.push_back(std::sqrt(d2[1]));
  if (gaps.empty()) return 0.0f;
  std::nth_element(gaps.begin(), gaps.begin() + static_cast<long>(gaps.size() / 2), gaps.end());
  return gaps[gaps.size() / 2];
}

/// Whether most of the piece's voters' normals point into the part: an odd count of crossings
/// ahead of them, an even one behind.
bool pointsIn(const KdTree& tree, const Points& points, const Points& normals, const std::vector<std::uint32_t>& piece,
              float spacing, float length) {
  int in = 0, out = 0;
  const std::size_t step = std::max<std::size_t>(1, piece.size() / kPieceVoters);
  for (std::size_t k = 0; k < piece.size(); k += step) {  // both ways: out of the part the count is even, into it odd
    const Vec3 &p = points[piece[k]], &n = normals[piece[k]];
    (crossings(tree, p, n, spacing, length) % 2 == 1 ? in : out) += 1;
    (crossings(tree, p, -n, spacing, length) % 2 == 0 ? in : out) += 1;
  }
  return in > out;
}

}  // namespace

void orientOutward(const Points& points, Points& normals) {
  if (points.empty()) return;
  Vec3 centre = Vec3::Zero();
  for (const Vec3& p : points) centre += p;
  centre /= static_cast<float>(points.size());
  const KdTree tree(points);
  const auto links = neighbourGraph(tree, points, normals);
  // The pieces' starts: farthest from the centroid first (equal distances by index).
  std::vector<std::uint32_t> starts(points.size());
  for (std::uint32_t i = 0; i < starts.size(); ++i) starts[i] = i;
  std::stable_sort(starts.begin(), starts.end(), [&](std::uint32_t a, std::uint32_t b) {
    return (points[a] - centre).squaredNorm() > (points[b] - centre).squaredNorm();
  });
  const float spacing = medianSpacing(tree, points), length = diameterBound(points, centre);
  std::vector<char> done(points.size(), 0);
  std::priority_queue<Link, std::vector<Link>, std::greater<>> frontier;
  std::vector<std::vector<std::uint32_t>> pieces;
  for (const std::uint32_t start : starts) {
    if (done[start] || normals[start].squaredNorm() < 0.5f) continue;
    if (normals[start].dot(points[start] - centre) < 0) normals[start] = -normals[start];
    done[start] = 1;
    std::vector<std::uint32_t>& piece = pieces.emplace_back(1, start);
    for (const Link& l : links[start]) frontier.push(l);
    while (!frontier.empty()) {  // Prim's tree: the lightest link to a point not yet reached
      const Link l = frontier.top();
      frontier.pop();
      if (done[l.to]) continue;
      done[l.to] = 1;
      piece.push_back(l.to);
      if (normals[l.from].dot(normals[l.to]) < 0) normals[l.to] = -normals[l.to];
      for (const Link& next : links[l.to])
        if (!done[next.to]) frontier.push(next);
    }
  }
  // The starts' sides are a guess (an L's inner faces look at the centroid): the rays decide.
  std::stable_sort(pieces.begin(), pieces.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  if (pieces.size() > kMostVotedPieces) pieces.resize(kMostVotedPieces);
  for (const auto& piece : pieces)
    if (spacing > 0 && pointsIn(tree, points, normals, piece, spacing, length))
      for (const std::uint32_t i : piece) normals[i] = -normals[i];
}

}  // namespace binpose
