#pragma once
// BOP datasets (Hodan et al., BOP: Benchmark for 6D Object Pose Estimation, ECCV 2018; the BOP
// toolkit's layout and its 2019 results format): the images and objects to detect, the results
// CSV, and a runner that detects the targets of a dataset's split with binpose.
#include <binpose/detector.hpp>

#include <functional>
#include <string>
#include <vector>

namespace binpose {

/// One image's request: find up to `inst_count` copies of object `obj_id` (test_targets_bop19.json).
struct BopTarget {
  int scene_id = 0, im_id = 0, obj_id = 0, inst_count = 0;
};

/// The targets of a test_targets_bop19.json file (a list of {scene_id, im_id, obj_id, inst_count}).
std::vector<BopTarget> readBopTargets(const std::string& path);

/// One row of a BOP19 results CSV: the pose of one found copy, model -> camera, mm.
struct BopResult {
  int scene_id = 0, im_id = 0, obj_id = 0;
  float score = 0;
  Pose pose = Pose::Identity();
  double time_s = -1;  ///< the image's detection time, s (-1: unknown)
};

/// Writes `scene_id,im_id,obj_id,score,R,t,time` rows (R row-major, 9 values; t in mm; both
/// space-separated) under BOP's header line.
void writeBopCsv(const std::string& path, const std::vector<BopResult>& results);
/// Reads a results CSV written by writeBopCsv or by another method for the BOP toolkit.
std::vector<BopResult> readBopCsv(const std::string& path);

/// What the runner needs to know: the dataset, its split, which targets and objects, where to
/// keep the trained databases, and the detector's preset and parameters (mm, for each object
/// scaled to its diameter as `binpose detect` does).
struct BopRun {
  std::string dataset;             ///< the dataset's root folder (models/, SPLIT/)
  std::string split = "test";      ///< the split's folder
  std::string targets;             ///< test_targets_bop19.json (default: DATASET/test_targets_bop19.json)
  std::vector<int> objects;        ///< only these obj_ids (empty: every object of the targets)
  std::string cache;               ///< folder of trained databases, obj_XXXXXX.bpdb (reused when present)
  std::string preset = "default";
  std::string params_file;         ///< JSON of parameters applied after the preset (optional)
  int model_points = 4000;
};

/// Detects every target image's objects (inst_count copies at most, best first) and returns the
/// rows, in the targets' order. `progress(done, total)` is called after each image.
std::vector<BopResult> runBop(const BopRun& run, const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace binpose
