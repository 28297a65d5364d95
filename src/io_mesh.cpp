// Triangle meshes: PLY and OFF by binpose's own readers, every other format by assimp.
#include "io_detail.hpp"

#include <binpose/io.hpp>

#include <assimp/Importer.hpp>
#include <assimp/scene.h>

#include <binpose/geometry.hpp>

namespace binpose {
namespace {

/// Deepest node hierarchy read (the formats read here give one or two levels).
constexpr int kMostNodeDepth = 64;

/// Appends the node's meshes, moved by its transform to the root, and its children's. Polygons
/// are fan-triangulated here rather than by assimp's post-processing, whose internal assertions
/// abort the process on some crafted faces; every index is checked against the mesh's vertices.
void appendNode(const std::string& path, const aiScene& scene, const aiNode& node, aiMatrix4x4 to_root,
                double scale, int depth, Mesh& out) {
  if (depth > kMostNodeDepth) detail::fail(path, "mesh nodes are nested too deep");
  to_root = to_root * node.mTransformation;
  for (unsigned i = 0; i < node.mNumMeshes; ++i) {
    if (node.mMeshes[i] >= scene.mNumMeshes) detail::fail(path, "mesh node refers to a missing mesh");
    const aiMesh& m = *scene.mMeshes[node.mMeshes[i]];
    const int base = static_cast<int>(out.vertices.size());
    for (unsigned v = 0; v < m.mNumVertices; ++v) {
      const aiVector3D p = to_root * m.mVertices[v];
      out.vertices.emplace_back(float(p.x * scale), float(p.y * scale), float(p.z * scale));
    }
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
      const aiFace& face = m.mFaces[f];
      for (unsigned k = 0; k < face.mNumIndices; ++k)
        if (face.mIndices[k] >= m.mNumVertices) detail::fail(path, fmt::format("face {} refers to a missing vertex", f));
      for (unsigned k = 2; k < face.mNumIndices; ++k)  // points and lines give no triangle
        out.faces.emplace_back(base + int(face.mIndices[0]), base + int(face.mIndices[k - 1]), base + int(face.mIndices[k]));
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c)
    appendNode(path, scene, *node.mChildren[c], to_root, scale, depth + 1, out);
}

}  // namespace

namespace detail {

Mesh readMeshFile(const std::string& path, double scale) {
  if (extensionOf(path) == "off") return readOffMesh(path, scale);
  readFileBytes(path);  // same "no such file" / "empty" errors as the other readers
  Assimp::Importer importer;
  // No post-processing: identical vertices are welded and polygons split here. Vertex normals
  // of the file are not read: model normals come from the faces (chapter 6).
  const aiScene* scene = importer.ReadFile(path, 0);
  if (scene == nullptr || scene->mRootNode == nullptr)
    fail(path, fmt::format("cannot read mesh ({})", importer.GetErrorString()));
  Mesh mesh;
  appendNode(path, *scene, *scene->mRootNode, aiMatrix4x4(), scale, 0, mesh);
  return mesh;
}

void weldChecked(const std::string& path, Mesh& mesh) {
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
    if (!mesh.vertices[i].allFinite()) fail(path, fmt::format("vertex {} has a non-finite coordinate", i));
  weldVertices(mesh);
}

}  // namespace detail

Mesh readMesh(const std::string& path, double scale) {
  if (detail::extensionOf(path) == "ply") return readPlyMesh(path, scale);
  Mesh mesh = detail::readMeshFile(path, scale);
  if (mesh.faces.empty()) detail::fail(path, "mesh has no triangles");
  detail::weldChecked(path, mesh);
  return mesh;
}

}  // namespace binpose
