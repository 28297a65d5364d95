#pragma once
// Synthetic bins with exact ground truth (thesis 7.1.2, "Synthetic Scenes"): copies of a part
// dropped into a bin with rigid-body physics (Bullet), seen by a virtual depth sensor (Embree ray
// casting) with noise and grazing-angle dropout.
#include <binpose/io.hpp>
#include <binpose/pose.hpp>
#include <binpose/sensor_model.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace binpose {

/// A pinhole depth sensor above the bin, looking straight down. Defaults: a structured-light
/// sensor at 0.5 m (VGA, 0.9 mm pixels at the bin floor).
struct SensorParams {
  int width = 640, height = 480;
  double fx = 550, fy = 550, cx = 319.5, cy = 239.5;
  float distance = 500.0f;       ///< camera to bin floor, mm
  float noise_sigma = 0.1f;      ///< depth noise (1 sigma) at 500 mm, mm; grows with range^2
  float grazing_deg = 80.0f;     ///< pixels seeing a surface more obliquely than this are dropped
  double depth_scale = 0.1;      ///< mm per depth unit in the PNG (BOP convention)
  /// What the sensor does beyond noise_sigma (sensor_model.hpp). The ideal sensor: Gaussian
  /// noise of noise_sigma at 500 mm growing with range^2, and nothing else; any other kind
  /// replaces that noise with its own.
  SensorModel model;
};

struct BinParams {
  Vec3 inner{200.0f, 200.0f, 120.0f};  ///< inner length, width, height, mm
  float wall = 10.0f;                  ///< wall thickness, mm
};

struct SimulationParams {
  int instances = 16;
  std::uint64_t seed = 1;
  SensorParams sensor;
  BinParams bin;
  float settle_seconds = 4.0f;  ///< simulated time for the parts to come to rest
};

struct SimulatedInstance {
  Pose pose;                  ///< model -> camera, mm
  float visible_fraction = 0; ///< visible surface / whole surface (thesis 7.4; at most about 0.5)
  int visible_pixels = 0;     ///< pixels of the depth image on this instance
  float visib_fract = 0;      ///< visible pixels / pixels it would cover alone in the bin (BOP)
};

struct SimulatedScene {
  std::vector<SimulatedInstance> instances;
  Intrinsics intrinsics;
  std::vector<std::uint16_t> depth;  ///< row-major, raw units (x depth_scale = mm); 0: no data
  PointCloud cloud;                  ///< the depth image as points, camera frame, mm
  Pose camera_from_world;            ///< world: bin floor at z = 0, z up, bin centred at the origin
};

/// Rests `count` copies of the mesh in the bin (world frame), dropped from random poses. Each
/// copy collides as the convex hull of the mesh. Deterministic for a seed.
std::vector<Pose> dropIntoBin(const Mesh& mesh, int count, const BinParams& bin, float settle_seconds, std::uint64_t seed);

/// Renders the copies at `world_poses` in the bin with the sensor; visible fractions by casting
/// rays to even samples of each copy's surface.
SimulatedScene renderBin(const Mesh& mesh, const std::vector<Pose>& world_poses, const BinParams& bin,
                         const SensorParams& sensor, std::uint64_t seed);

/// dropIntoBin then renderBin.
SimulatedScene simulateBin(const Mesh& mesh, const SimulationParams& params);

/// Writes DIR/depth.png, DIR/camera.json, DIR/scene.ply (camera frame, mm), DIR/ground_truth.json,
/// and BOP's DIR/scene_gt.json, scene_gt_info.json, scene_camera.json (no depth.png, camera.json
/// or scene_camera.json for a scene without a depth image). `model_info` (BOP
/// models_info.json entry text for obj_id 1, may be empty) goes to DIR/models_info.json.
void writeScene(const std::string& dir, const SimulatedScene& scene, const std::string& model_name,
                const std::string& model_info);

/// The scene as image 0 of scene `scene_id` of a BOP dataset (Hodan et al. 2018) under `dataset`:
/// models/obj_XXXXXX.ply (the part, mm) and models_info.json (`model_info` as object `obj_id`,
/// merged with the file's other objects), test/SSSSSS/depth/000000.png, scene_camera.json,
/// scene_gt.json, scene_gt_info.json, and the scene's entry in test_targets_bop19.json (its
/// copies at least 10 % visible). Several calls with other scene ids build a dataset.
void writeBopScene(const std::string& dataset, int scene_id, int obj_id, const SimulatedScene& scene, const Mesh& mesh,
                   const std::string& model_info);

/// A BOP models_info.json entry for a part: its diameter, and for builtin:cap and builtin:sphere
/// their continuous symmetry about z (other parts: none declared).
std::string defaultModelInfo(const std::string& model_name, const Mesh& mesh);

/// A scene written by writeScene: its instances (poses, visible fractions) and the scan.
struct GroundTruth {
  std::vector<SimulatedInstance> instances;
  std::string model;
};
GroundTruth readGroundTruth(const std::string& dir);

}  // namespace binpose
