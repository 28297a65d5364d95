// The C++ API in brief: train on a mesh, find every copy in a scan, print the poses.
//   detect_parts MODEL.ply SCAN.ply   (mm; a PCD, or a PLY with or without normals)
#include <binpose/detector.hpp>
#include <binpose/io.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) try {
  if (argc != 3) return std::fprintf(stderr, "usage: %s MODEL SCAN\n", argv[0]), 2;
  const binpose::ModelFile file = binpose::readModelFile(argv[1]);  // mesh or point cloud, mm
  const binpose::OrientedModel model = file.is_mesh ? binpose::prepareModel(file.mesh, binpose::ModelParams{})
                                                    : binpose::prepareModel(file.cloud, binpose::ModelParams{});
  const auto db = binpose::ModelDatabase::build(model, binpose::defaultQuantization(model.diameter));
  // The presets are set for the thesis's 60 mm part; scaledToModel fits them to this one.
  const binpose::Detector detector(db, binpose::scaledToModel(binpose::defaultPreset(), model.diameter));
  const binpose::DetectionResult result = detector.detect(binpose::readCloud(argv[2]));
  for (const binpose::Detection& d : result.detections) {  // best first; model -> scan, mm
    const auto t = d.pose.translation();
    std::printf("score %.2f  t = (%.1f, %.1f, %.1f) mm\n", d.score, t.x(), t.y(), t.z());
  }
  std::printf("%zu detections in %.0f ms\n", result.detections.size(), result.timing.total_ms);
} catch (const std::exception& e) {
  std::fprintf(stderr, "error: %s\n", e.what());
  return 2;
}
