// A scan file by its extension and camera file, its unit given or guessed from the part's size.
#include <binpose/geometry.hpp>
#include <binpose/io.hpp>
#include <binpose/scan_file.hpp>

#include "io_detail.hpp"

#include <fmt/format.h>

namespace binpose {
namespace {

/// A PNG by its extension in any case (scan.PNG), as TIFFs and clouds are told.
bool isPng(const std::string& path) { return detail::extensionOf(path) == "png"; }

/// The file times `unit_scale`: a depth image (a PNG, or a TIFF given intrinsics) by its camera
/// file (its values times depth_scale, times `unit_scale`), any other file as a cloud.
PointCloud readScan(const ScanSource& source, double unit_scale) {
  const bool png = isPng(source.path);
  if (png && source.intrinsics.empty())
    throw Error(
        fmt::format("{}: a depth image needs its camera's intrinsics (--intrinsics; intrinsics= in Python)", source.path));
  if (!png && (source.intrinsics.empty() || !isTiffPath(source.path))) return readCloud(source.path, unit_scale);
  Intrinsics camera = readIntrinsics(source.intrinsics, source.image_id);
  camera.depth_scale *= unit_scale;
  return png ? readDepthPng(source.path, camera) : readDepthTiff(source.path, camera);
}

}  // namespace

LoadedScan loadScan(const ScanSource& source, float part_diameter) {
  LoadedScan out;
  if (source.units != "auto") {
    out.cloud = readScan(source, unitScale(parseUnits(source.units)));
    return out;
  }
  out.cloud = readScan(source, 1.0);
  out.extent_in_file_units = boundsDiagonal(out.cloud.points);
  if (out.extent_in_file_units > 0 && out.extent_in_file_units < kLeastScanShareOfPart * part_diameter) {
    out.cloud = readScan(source, unitScale(Units::Metres));  // read again: a depth image's lattice is fitted anew
    out.guessed_metres = true;
  }
  return out;
}

}  // namespace binpose
