// Trains on the built-in cap and finds it in a scan: find_caps SCAN (PLY/PCD in mm, or a depth
// PNG with its camera.json as a second argument).
#include <binpose/detector.hpp>
#include <binpose/io.hpp>
#include <binpose/model.hpp>
#include <binpose/shapes.hpp>

#include <cstdio>
#include <string>

int main(int argc, char** argv) try {
  if (argc < 2) return std::fprintf(stderr, "usage: %s SCAN [camera.json]\n", argv[0]), 2;
  const binpose::OrientedModel model = binpose::prepareModel(binpose::builtinPart("cap"), binpose::ModelParams{});
  const auto db = binpose::ModelDatabase::build(model, binpose::defaultQuantization(model.diameter));
  const binpose::Detector detector(db, binpose::scaledToModel(binpose::defaultPreset(), model.diameter));
  const binpose::PointCloud scan = argc > 2 ? binpose::readDepthPng(argv[1], binpose::readIntrinsics(argv[2]))
                                            : binpose::readCloud(argv[1]);
  const binpose::DetectionResult result = detector.detect(scan);
  for (const binpose::Detection& d : result.detections) {
    const auto t = d.pose.translation();
    std::printf("score %.3f  t = (%.2f, %.2f, %.2f) mm\n", d.score, t.x(), t.y(), t.z());
  }
  std::printf("%zu detections\n", result.detections.size());
} catch (const std::exception& e) {
  std::fprintf(stderr, "error: %s\n", e.what());
  return 2;
}
