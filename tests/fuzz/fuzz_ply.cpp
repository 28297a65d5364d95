// libFuzzer harness: PLY as a mesh and as a cloud (readPlyMesh, readPlyCloud).
#include "fuzz_common.hpp"

#include <binpose/io.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace binpose;
  const std::string path = fuzz::writeInput(data, size, "ply");
  fuzz::expectReadOrError(path, [&] { fuzz::checkMesh(readPlyMesh(path, 1.0)); });
  fuzz::expectReadOrError(path, [&] { fuzz::checkCloud(readPlyCloud(path, 1000.0)); });
  return 0;
}
