// Triangle meshes: PLY by binpose's own reader, every other format by assimp.
#include "io_detail.hpp"

#include <binpose/io.hpp>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <binpose/geometry.hpp>

namespace binpose {
namespace {

void appendNode(const aiScene& scene, const aiNode& node, double scale, Mesh& out) {
  for (unsigned i = 0; i < node.mNumMeshes; ++i) {
    const aiMesh& m = *scene.mMeshes[node.mMeshes[i]];
    const int base = static_cast<int>(out.vertices.size());
    for (unsigned v = 0; v < m.mNumVertices; ++v) {
      const aiVector3D& p = m.mVertices[v];
      out.vertices.emplace_back(float(p.x * scale), float(p.y * scale), float(p.z * scale));
    }
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
      const aiFace& face = m.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines left by triangulation
      out.faces.emplace_back(base + int(face.mIndices[0]), base + int(face.mIndices[1]), base + int(face.mIndices[2]));
    }
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c) appendNode(scene, *node.mChildren[c], scale, out);
}

}  // namespace

Mesh readMesh(const std::string& path, double scale) {
  if (detail::extensionOf(path) == "ply") return readPlyMesh(path, scale);
  detail::readFileBytes(path);  // same "no such file" / "empty" errors as the other readers
  Assimp::Importer importer;
  // Vertex normals of the file are not read: model normals come from the faces (chapter 6).
  const aiScene* scene = importer.ReadFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                                     aiProcess_PreTransformVertices);
  if (scene == nullptr || scene->mRootNode == nullptr)
    detail::fail(path, fmt::format("cannot read mesh ({})", importer.GetErrorString()));
  Mesh mesh;
  appendNode(*scene, *scene->mRootNode, scale, mesh);
  if (mesh.faces.empty()) detail::fail(path, "mesh has no triangles");
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
    if (!mesh.vertices[i].allFinite()) detail::fail(path, fmt::format("vertex {} has a non-finite coordinate", i));
  weldVertices(mesh);
  return mesh;
}

}  // namespace binpose
