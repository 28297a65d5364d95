#pragma once
// What every libFuzzer harness shares: the input written to a file (binpose's readers take
// paths, as the CLI does), a reader called on it, and the contract checked on what comes back.
// A reader may refuse an input only with a binpose::Error of one line; any other exception
// (std::bad_alloc, a library's own), a sanitizer report or a result that breaks the types'
// invariants aborts, and libFuzzer keeps the input.
#include <binpose/types.hpp>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <string>
#include <unistd.h>

namespace binpose::fuzz {

/// A file of this process's own (libFuzzer's -jobs and -fork run several), on /dev/shm when it
/// exists so that each execution stays in memory.
inline std::string writeInput(const std::uint8_t* data, std::size_t size, const char* extension) {
  const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  const std::string path = std::string(dir) + "/binpose_fuzz_" + std::to_string(getpid()) + "." + extension;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) std::abort();
  return path;
}

[[noreturn]] inline void broken(const char* what) {
  std::fprintf(stderr, "fuzz contract broken: %s\n", what);
  std::abort();
}

/// Calls `read()`; a binpose::Error must be one line that names the file, anything else thrown
/// is a finding.
template <class Read>
void expectReadOrError(const std::string& path, Read&& read) {
  try {
    read();
  } catch (const binpose::Error& e) {
    const std::string message = e.what();
    if (message.find('\n') != std::string::npos) broken("error message of more than one line");
    if (message.rfind(path, 0) != 0) broken("error message does not start with the file's path");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz contract broken: %s\n", e.what());
    std::abort();
  }
}

inline void checkCloud(const PointCloud& cloud) {
  for (const Vec3& p : cloud.points)
    if (!p.allFinite()) broken("non-finite point kept");
  if (!cloud.normals.empty() && cloud.normals.size() != cloud.points.size()) broken("normals do not match points");
  if (cloud.organized()) {
    if (cloud.pixel.size() != cloud.points.size()) broken("organized cloud without a pixel per point");
    const auto pixels = static_cast<std::int64_t>(cloud.width) * cloud.height;
    for (std::int32_t px : cloud.pixel)
      if (px < 0 || px >= pixels) broken("pixel index outside the image");
  }
}

inline void checkMesh(const Mesh& mesh) {
  for (const Vec3& v : mesh.vertices)
    if (!v.allFinite()) broken("non-finite vertex kept");
  const auto n = static_cast<int>(mesh.vertices.size());
  for (const Eigen::Vector3i& f : mesh.faces)
    if ((f.array() < 0).any() || (f.array() >= n).any()) broken("face refers to a missing vertex");
  if (!mesh.normals.empty() && mesh.normals.size() != mesh.vertices.size()) broken("normals do not match vertices");
}

}  // namespace binpose::fuzz
