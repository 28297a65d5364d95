// libFuzzer harness: ASCII point files (readXyz): headers, comments, separators, normal columns.
#include "fuzz_common.hpp"

#include <binpose/io.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace binpose;
  const std::string path = fuzz::writeInput(data, size, "xyz");
  fuzz::expectReadOrError(path, [&] { fuzz::checkCloud(readXyz(path, 1.0)); });
  return 0;
}
