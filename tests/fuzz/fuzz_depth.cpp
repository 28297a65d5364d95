// libFuzzer harness: a depth image and its camera. The first byte picks what the rest is:
// even, a camera JSON (camera.json or scene_camera.json, read with and without an image id);
// odd, a 16-bit PNG read with intrinsics that leave its size to the image, or (bit 1 set too) a
// TIFF read as a depth map and as a point map.
#include "fuzz_common.hpp"

#include <binpose/io.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace binpose;
  if (size == 0) return 0;
  if (data[0] % 2 == 0) {
    const std::string path = fuzz::writeInput(data + 1, size - 1, "json");
    fuzz::expectReadOrError(path, [&] { readIntrinsics(path); });
    fuzz::expectReadOrError(path, [&] { readIntrinsics(path, "1"); });
    return 0;
  }
  Intrinsics camera;
  camera.fx = camera.fy = 500.0;
  camera.cx = 2.0;
  camera.cy = 1.5;
  if (data[0] & 2) {
    const std::string path = fuzz::writeInput(data + 1, size - 1, "tif");
    fuzz::expectReadOrError(path, [&] { fuzz::checkCloud(readDepthTiff(path, camera)); });
    fuzz::expectReadOrError(path, [&] { fuzz::checkCloud(readTiffPointMap(path)); });
    return 0;
  }
  const std::string path = fuzz::writeInput(data + 1, size - 1, "png");
  fuzz::expectReadOrError(path, [&] { fuzz::checkCloud(readDepthPng(path, camera)); });
  return 0;
}
