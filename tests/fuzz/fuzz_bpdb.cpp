// libFuzzer harness: model databases (ModelDatabase::load). The input's last four bytes are
// replaced by the CRC-32 of the rest, as a crafted file would carry, so that the fuzzer reaches
// the header and the tables instead of stopping at the checksum.
#include "fuzz_common.hpp"

#include <binpose/model_database.hpp>

#include <cstring>
#include <vector>
#include <zlib.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace binpose;
  if (size < 4) return 0;
  std::vector<std::uint8_t> bytes(data, data + size);
  const auto crc = static_cast<std::uint32_t>(crc32_z(0, bytes.data(), size - 4));
  std::memcpy(bytes.data() + size - 4, &crc, 4);
  const std::string path = fuzz::writeInput(bytes.data(), bytes.size(), "bpdb");
  fuzz::expectReadOrError(path, [&] { ModelDatabase::load(path); });
  return 0;
}
