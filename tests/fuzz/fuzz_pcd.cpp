// libFuzzer harness: PCD, every DATA kind (readPcd).
#include "fuzz_common.hpp"

#include <binpose/io.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace binpose;
  const std::string path = fuzz::writeInput(data, size, "pcd");
  fuzz::expectReadOrError(path, [&] { fuzz::checkCloud(readPcd(path, 1.0)); });
  return 0;
}
