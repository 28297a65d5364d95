// libFuzzer harness: meshes through assimp (readMesh). The first byte picks the format by
// extension, as a user's file name would: STL (ASCII or binary), OBJ or OFF.
#include "fuzz_common.hpp"

#include <binpose/io.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace binpose;
  if (size == 0) return 0;
  static const char* const kExtensions[] = {"stl", "obj", "off"};
  const char* extension = kExtensions[data[0] % 3];
  const std::string path = fuzz::writeInput(data + 1, size - 1, extension);
  fuzz::expectReadOrError(path, [&] { fuzz::checkMesh(readMesh(path, 1.0)); });
  return 0;
}
