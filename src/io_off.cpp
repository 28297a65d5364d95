// OFF meshes (Geomview's Object File Format), read by binpose itself: assimp 5.2's OFF importer
// reads out of bounds on crafted counts (found by tests/fuzz/fuzz_mesh).
#include "io_detail.hpp"

#include <binpose/io.hpp>

#include <cmath>
#include <limits>

namespace binpose {
namespace {

/// Most vertices of one face, and most vertices or faces of a file (indices must fit an int).
constexpr std::size_t kMostFaceSize = 1 << 16;
constexpr std::size_t kMostCount = (std::size_t{1} << 31) - 1;

/// The file's lines without comments (from '#') and blank ones, each split into words.
std::vector<std::vector<std::string_view>> contentLines(std::string_view text) {
  std::vector<std::vector<std::string_view>> lines;
  std::size_t at = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(at, end - at);
    line = line.substr(0, line.find('#'));
    auto words = detail::splitWords(line);
    if (!words.empty()) lines.push_back(std::move(words));
    at = end + 1;
  }
  return lines;
}

Vec3 vertexOf(const std::string& path, const std::vector<std::string_view>& words, std::size_t i, double scale) {
  double v[3];
  if (words.size() < 3) detail::fail(path, fmt::format("OFF vertex {} has fewer than 3 coordinates", i));
  for (int k = 0; k < 3; ++k) {
    if (!detail::parseNumber(words[k], v[k]) || !std::isfinite(v[k]))
      detail::fail(path, fmt::format("OFF vertex {} has a bad coordinate '{}'", i, words[k]));
    if (!(std::abs(v[k] * scale) <= double(std::numeric_limits<float>::max())))  // finite as a double, past a float's range
      detail::fail(path, fmt::format("OFF vertex {} has a coordinate out of range '{}'", i, words[k]));
  }
  return Vec3(float(v[0] * scale), float(v[1] * scale), float(v[2] * scale));
}

/// Face `f` (n, i_1 .. i_n, then optional colour values) fan-triangulated into `mesh`.
void addFace(const std::string& path, const std::vector<std::string_view>& words, std::size_t f, Mesh& mesh) {
  const std::size_t n = detail::parseCount(path, words[0], "OFF face size", kMostFaceSize);
  if (n + 1 > words.size()) detail::fail(path, fmt::format("OFF face {} lists {} vertices but gives {}", f, n, words.size() - 1));
  std::vector<int> ids(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t id = detail::parseCount(path, words[k + 1], "OFF vertex index", kMostCount);
    if (id >= mesh.vertices.size())
      detail::fail(path, fmt::format("OFF face {} refers to vertex {} of {}", f, id, mesh.vertices.size()));
    ids[k] = static_cast<int>(id);
  }
  for (std::size_t k = 2; k < n; ++k) mesh.faces.emplace_back(ids[0], ids[k - 1], ids[k]);
}

}  // namespace

Mesh readOffMesh(const std::string& path, double scale) {
  const std::string bytes = detail::readFileBytes(path);
  const auto lines = contentLines(bytes);
  if (lines.empty() || lines[0][0] != "OFF") detail::fail(path, "not an OFF file (no OFF keyword)");
  // "OFF nv nf ne" on one line, or "OFF" alone with the counts on the next.
  std::vector<std::string_view> counts(lines[0].begin() + 1, lines[0].end());
  std::size_t at = 1;
  if (counts.empty() && lines.size() > 1) counts = lines[at++];
  if (counts.size() < 2) detail::fail(path, "OFF counts are missing");
  const std::size_t n_vertices = detail::parseCount(path, counts[0], "OFF vertex count", lines.size());
  const std::size_t n_faces = detail::parseCount(path, counts[1], "OFF face count", lines.size());
  if (n_vertices < 3) detail::fail(path, fmt::format("OFF file has {} vertices; a mesh needs 3", n_vertices));
  if (lines.size() - at < n_vertices + n_faces)
    detail::fail(path, fmt::format("OFF file is truncated ({} vertices and {} faces announced)", n_vertices, n_faces));
  Mesh mesh;
  mesh.vertices.reserve(n_vertices);
  for (std::size_t i = 0; i < n_vertices; ++i) mesh.vertices.push_back(vertexOf(path, lines[at + i], i, scale));
  for (std::size_t f = 0; f < n_faces; ++f) addFace(path, lines[at + n_vertices + f], f, mesh);
  return mesh;
}

}  // namespace binpose
