// binpose command-line front end.
#include <binpose/bop.hpp>
#include <binpose/detector.hpp>
#include <binpose/evaluation.hpp>
#include <binpose/geometry.hpp>
#include <binpose/io.hpp>
#include <binpose/scan_file.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/render.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>
#include <binpose/sweep.hpp>
#include <binpose/thesis_scene.hpp>
#include <binpose/viewpoint.hpp>

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// A part this small (mm) is no bin-picking part: a model file spanning less is in metres.
constexpr float kSmallestPart = 2.0f;
/// A model file read in millimetres that spans less than this may be in inches or centimetres,
/// which no extent tells apart from a small part: a note says so.
constexpr float kSmallPart = 10.0f;

/// The model file in millimetres. `units` "auto": millimetres, unless the file spans less than
/// kSmallestPart, then metres, with a note; under kSmallPart a note names --units in and cm.
binpose::ModelFile readModelInUnits(const std::string& path, const std::string& units) {
  if (units != "auto") return binpose::readModelOrBuiltin(path, binpose::unitScale(binpose::parseUnits(units)));
  binpose::ModelFile file = binpose::readModelOrBuiltin(path, 1.0);
  const float extent = binpose::boundsDiagonal(file.is_mesh ? file.mesh.vertices : file.cloud.points);
  if (extent > 0 && extent < kSmallestPart) {
    fmt::print(stderr, "note: the model spans {:.3g} units, less than {} mm: reading it in metres (--units mm keeps millimetres)\n",
               extent, kSmallestPart);
    file = binpose::readModelOrBuiltin(path, binpose::unitScale(binpose::Units::Metres));
  } else if (extent > 0 && extent < kSmallPart) {
    fmt::print(stderr,
               "note: the model spans {:.3g} mm; if its file is in inches or centimetres, give --units in or --units cm\n",
               extent);
  }
  return file;
}

struct TrainOptions {
  std::string model, out, units = "auto";
  int points = 4000;
  double rho_model = 0;
  std::optional<double> d_dist, d_angle_deg, overlap;
  std::uint64_t seed = 1;
};

void addTrain(CLI::App& app, TrainOptions& o) {
  CLI::App* train = app.add_subcommand("train", "Build a model's feature database (thesis ch. 4.2 and 6)");
  train->add_option("--model", o.model, "Model: mesh (PLY/STL/OBJ), point cloud (PLY/PCD/XYZ), or builtin:cap|sphere|box")
      ->required();
  train->add_option("--out", o.out, "Database file to write")->required();
  train->add_option("--points", o.points, "Model points n_M after Poisson-disk sampling")->capture_default_str();
  train->add_option("--rho-model", o.rho_model, "Model density rho_model, points/mm^2 (overrides --points; meshes only)");
  train->add_option("--d-dist", o.d_dist, "Distance step d_dist, mm (default: 1 mm x diameter/60 mm)");
  train->add_option("--d-angle", o.d_angle_deg, "Angle step d_angle, degrees (default 8)");
  train->add_option("--overlap", o.overlap, "Bin overlap p_d, fraction of a step in [0, 0.5) (default 0.15)");
  train
      ->add_option(
          "--units", o.units,
          "Length unit of the model file: mm, cm, m, in, or auto (mm, unless the file spans less than 2 mm: then m, with a note)")
      ->check(CLI::IsMember({"auto", "mm", "cm", "m", "in"}))
      ->capture_default_str();
  train->add_option("--seed", o.seed, "Sampling seed")->capture_default_str();
}

int runTrain(const TrainOptions& o) {
  const auto t0 = Clock::now();
  binpose::ModelParams params;
  params.num_points = o.points;
  params.rho_model = o.rho_model;
  params.seed = o.seed;
  const binpose::ModelFile file = readModelInUnits(o.model, o.units);
  const binpose::OrientedModel model =
      file.is_mesh ? binpose::prepareModel(file.mesh, params) : binpose::prepareModel(file.cloud, params);
  const double t_sample = secondsSince(t0);

  binpose::QuantizationParams q = binpose::defaultQuantization(model.diameter);
  if (o.d_dist) q.d_dist = static_cast<float>(*o.d_dist);
  if (o.d_angle_deg) q.d_angle = static_cast<float>(*o.d_angle_deg * std::numbers::pi / 180.0);
  if (o.overlap) q.overlap = static_cast<float>(*o.overlap);
  const auto t1 = Clock::now();
  const binpose::ModelDatabase db = binpose::ModelDatabase::build(model, q);
  const double t_build = secondsSince(t1);
  db.save(o.out);
  const binpose::DatabaseStats s = db.stats();

  fmt::print("model        {} ({})\n", o.model, file.is_mesh ? "mesh" : "point cloud");
  fmt::print("diameter     {:.2f} mm\n", model.diameter);
  if (model.area > 0) fmt::print("area         {:.0f} mm^2\n", model.area);
  fmt::print("points       {} (Poisson-disk radius {:.3f} mm)\n", model.points.size(), model.sample_radius);
  fmt::print("d_dist       {:.3f} mm, d_angle {:.1f} deg, p_d {:.0f}%\n", q.d_dist, q.d_angle * 180 / std::numbers::pi,
             q.overlap * 100);
  fmt::print("keys         {} used of {} ({} x {}^3)\n", s.keys_used, s.keys_total, db.keySpace().distanceBins(),
             db.keySpace().angleBins());
  fmt::print("entries      {} (median {:.0f}, mean {:.1f}, max {} model points per key)\n", s.entries, s.median_per_key,
             s.mean_per_key, s.max_per_key);
  fmt::print("file         {} ({:.1f} MiB)\n", o.out, static_cast<double>(std::filesystem::file_size(o.out)) / 1048576.0);
  fmt::print("time         {:.3f} s (read+sample {:.3f} s, build {:.3f} s)\n", secondsSince(t0), t_sample, t_build);
  return 0;
}

struct DetectOptions {
  std::string model, scene, intrinsics, image_id, out, preset = "default", params_file, render, export_ply, poses;
  std::string units = "auto", model_units = "auto";
  std::optional<int> max_instances, C_n, k_normals, obj_id;
  std::optional<float> r, rho_sub, eta, e_gmax, sigma_dist, min_score;
  std::optional<bool> refine, verify, symmetry;
  std::vector<float> viewpoint;
  std::optional<std::uint64_t> seed;
  int model_points = 4000;
  int threads = 0;
};

/// The options detect and check share: the model, the scan and the parameters.
void addScanOptions(CLI::App* d, DetectOptions& o) {
  d->add_option("--model", o.model, "Database (.bpdb) or a model to train on the fly (mesh, cloud, builtin:NAME)")->required();
  d->add_option("--scene", o.scene,
                "Scan: PLY, PCD, ASCII points (.xyz/.txt/.csv/.asc/.pts), a TIFF point map, or a depth image (16-bit PNG, or "
                "TIFF, with --intrinsics)")
      ->required();
  d->add_option("--intrinsics", o.intrinsics,
                "Camera JSON for a depth image (PNG or TIFF): BOP camera.json or scene_camera.json, or fx/fy/cx/cy or a 3 x 3 K, "
                "camera_matrix or intrinsic_matrix, with depth_scale");
  d->add_option("--image-id", o.image_id, "Entry of scene_camera.json (default: the first)");
  d->add_option("--preset", o.preset, "Parameter preset: default, or thesis (chapter 5 as written); fast: an alias of default")
      ->check(CLI::IsMember({"default", "fast", "thesis"}))->capture_default_str();
  d->add_option("--params", o.params_file, "JSON file of parameters (absolute units, mm), applied after the preset");
  d->add_option(
       "--units", o.units,
       "Length unit of the scene file (of a depth image: its values times depth_scale): mm, cm, m, in, or auto (mm, unless the "
       "scene spans less than half the model's diameter: then m, with a note)")
      ->check(CLI::IsMember({"auto", "mm", "cm", "m", "in"}))
      ->capture_default_str();
  d->add_option("--model-units", o.model_units,
                "Length unit of a model file trained on the fly: mm, cm, m, in, or auto (as train's --units)")
      ->check(CLI::IsMember({"auto", "mm", "cm", "m", "in"}))
      ->capture_default_str();
  d->add_option("--model-points", o.model_points, "Model points when training on the fly")->capture_default_str();
  d->add_option("--r", o.r, "Sampling radius r, mm (default 25 mm x diameter/60 mm)");
  d->add_option("--rho-sub", o.rho_sub, "Scene density after sub-sampling, points/mm^2 (default 0.06 x (60 mm/diameter)^2)");
  d->add_option("--eta", o.eta, "Grid spacing eta, mm (default 15 mm x diameter/60 mm)");
  d->add_option("--e-gmax", o.e_gmax, "Geometric consistency limit e_gmax, mm (default 1.5 mm x diameter/60 mm)");
  d->add_option("--c-n", o.C_n, "Smallest accepted clique C_n (default 6; the thesis: 8)");
  d->add_option("--sigma-dist", o.sigma_dist, "Removal distance sigma_dist, mm (default 6 mm x diameter/60 mm)");
  d->add_option("--k-normals", o.k_normals, "Neighbours of a scene normal's plane fit (default 8, raised for a noisy depth image; the thesis: 6)");
  d->add_option("--refine", o.refine, "ICP refinement on/off (true|false)");
  d->add_option("--symmetry", o.symmetry, "Match a symmetric part by its symmetry on/off (true|false)");
  d->add_option("--verify", o.verify, "Verification score and rejection on/off (true|false)");
  d->add_option("--min-score", o.min_score, "Smallest accepted verification score in [0, 1]");
  d->add_option("--viewpoint", o.viewpoint, "Sensor origin x y z in the scan frame, mm (default: the file's; else the origin, or a guess from the scan when the origin cannot have seen it)")->expected(3);
  d->add_option("--seed", o.seed, "Seed of the random sub-sampling");
  d->add_option("--threads", o.threads, "Worker threads (0: all cores); the detections are the same whatever the count")
      ->check(CLI::Range(0, 1024))->capture_default_str();
}

void addDetect(CLI::App& app, DetectOptions& o) {
  CLI::App* d = app.add_subcommand("detect", "Find every instance of a model in a scan (thesis ch. 4-5)");
  addScanOptions(d, o);
  d->add_option("--out", o.out, "Write the detections as JSON here");
  d->add_option("--render", o.render, "Draw the scan with the detections, ranked, into this PNG");
  d->add_option("--export-ply", o.export_ply, "Write the scan and the posed models (coloured) into this PLY");
  d->add_option("--max-instances", o.max_instances, "Stop after N detections (0: no limit)");
}

void addCheck(CLI::App& app, DetectOptions& o) {
  CLI::App* c = app.add_subcommand(
      "check", "Judge given poses as detect judges its own: why a part known to lie there is, or is not, found");
  addScanOptions(c, o);
  c->add_option("--poses", o.poses,
                "JSON of poses (model -> scan, mm, 4 x 4 rows): a detect result, a simulated scene's ground_truth.json, "
                "{\"poses\": [...]}, or a BOP scene_gt.json")
      ->required();
  c->add_option("--obj-id", o.obj_id, "With a BOP scene_gt.json: only this object's poses (--image-id picks the image)");
  c->add_option("--out", o.out, "Write each pose's verdict as JSON here");
}

/// The scan file's viewpoint; for a file that gives none, its origin when that can have seen the
/// scan, else a guess from the scan (said on stderr).
binpose::Vec3 sceneViewpoint(const binpose::PointCloud& scan) {
  if (scan.has_viewpoint) return scan.viewpoint;
  const binpose::ViewpointGuess g = binpose::guessViewpoint(scan.points, scan.viewpoint);
  if (g.moved)
    fmt::print(stderr,
               "note: the scan gives no viewpoint and its origin cannot see {:.0f} % of it; using ({:.1f}, {:.1f}, {:.1f}) mm, "
               "which hides {:.0f} % (--viewpoint sets it)\n",
               100 * g.assumed_hidden, g.viewpoint.x(), g.viewpoint.y(), g.viewpoint.z(), 100 * g.hidden);
  return g.viewpoint;
}

/// Preset, scaled to the model, then the JSON file, then the options given on the command line.
binpose::DetectionParams detectParams(const DetectOptions& o, float diameter, const binpose::PointCloud& scan) {
  if (o.preset == "fast")
    fmt::print(stderr, "note: --preset fast is now the default preset; the name 'fast' will be removed in a later release\n");
  binpose::DetectionParams p = binpose::scaledToModel(binpose::presetByName(o.preset), diameter);
  p.viewpoint = binpose::Vec3::Constant(NAN);  // a JSON file cannot give NaN: still NaN, the file gave none
  if (!o.params_file.empty()) binpose::applyJsonFile(p, o.params_file);
  if (std::isnan(p.viewpoint.x()) && o.viewpoint.empty()) p.viewpoint = sceneViewpoint(scan);
  if (o.r) p.r = *o.r;
  if (o.rho_sub) p.rho_sub = *o.rho_sub;
  if (o.eta) p.eta = *o.eta;
  if (o.e_gmax) p.e_gmax = *o.e_gmax;
  if (o.C_n) p.C_n = *o.C_n;
  if (o.sigma_dist) p.sigma_dist = *o.sigma_dist;
  if (o.k_normals) p.k_normals = *o.k_normals;
  if (o.refine) p.refine = *o.refine;
  if (o.verify) p.verify = *o.verify;
  if (o.symmetry) p.use_symmetry = *o.symmetry;
  if (o.min_score) p.min_score = *o.min_score;
  if (o.max_instances) p.max_instances = *o.max_instances;
  if (o.seed) p.seed = *o.seed;
  if (o.viewpoint.size() == 3) p.viewpoint = binpose::Vec3(o.viewpoint[0], o.viewpoint[1], o.viewpoint[2]);
  binpose::validate(p);
  return p;
}

binpose::ModelDatabase loadOrTrain(const DetectOptions& o) {
  if (binpose::ModelDatabase::isDatabaseFile(o.model)) return binpose::ModelDatabase::load(o.model);
  binpose::ModelParams mp;
  mp.num_points = o.model_points;
  const binpose::ModelFile file = readModelInUnits(o.model, o.model_units);
  const binpose::OrientedModel model = file.is_mesh ? binpose::prepareModel(file.mesh, mp) : binpose::prepareModel(file.cloud, mp);
  return binpose::ModelDatabase::build(model, binpose::defaultQuantization(model.diameter));
}

/// The scene, in millimetres (loadScan), with a note where its unit was taken for metres.
binpose::PointCloud loadScene(const DetectOptions& o, float diameter) {
  const binpose::LoadedScan scan = binpose::loadScan({o.scene, o.intrinsics, o.image_id, o.units}, diameter);
  if (scan.guessed_metres)
    fmt::print(stderr,
               "note: the scene spans {:.3g} units, less than half the model's {:.3g} mm: reading it in metres (--units mm keeps "
               "millimetres)\n",
               scan.extent_in_file_units, diameter);
  return scan.cloud;
}

/// Warnings about a scene read: none of its points holds a measurement, or its extent says its
/// units or the model's are not millimetres.
void warnAboutScene(const binpose::PointCloud& scan, float diameter) {
  if (scan.empty()) {
    fmt::print(stderr, "warning: the scene holds no measured point (NaN and (0, 0, 0), a pixel without a depth, are dropped)\n");
    return;
  }
  const float extent = binpose::boundsDiagonal(scan.points);
  if (extent <= 0) return;
  if (extent < binpose::kLeastScanShareOfPart * diameter)
    fmt::print(stderr, "warning: the scene spans {:.3g} mm but the model is {:.3g} mm across: is the scene in metres? (use --units m)\n",
               extent, diameter);
  else if (extent > 1000.0f * diameter)
    fmt::print(stderr, "warning: the scene spans {:.3g} mm, over 1000 times the model's {:.3g} mm: is the model in metres? (--units m when training it, --model-units m when detect trains it)\n",
               extent, diameter);
}

/// A pose as JSON: its 4 x 4 matrix's rows.
nlohmann::json rowsOf(const binpose::Pose& pose) {
  const Eigen::Matrix4f T = pose.matrix();
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < 4; ++i) rows.push_back({T(i, 0), T(i, 1), T(i, 2), T(i, 3)});
  return rows;
}

/// `text` and a newline into `path`, said on stdout; an error when it cannot be written.
void writeResult(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text << "\n";
  if (!out) throw binpose::Error(fmt::format("{}: cannot write result", path));
  fmt::print("result: {}\n", path);
}

std::string resultJson(const binpose::DetectionResult& r, const binpose::DetectionParams& p) {
  nlohmann::json j;
  j["detections"] = nlohmann::json::array();
  for (const auto& d : r.detections)
    j["detections"].push_back(
        {{"pose", rowsOf(d.pose)}, {"score", d.score}, {"correspondences", d.correspondences}, {"fit_rms_mm", d.rms}});
  j["timing_ms"] = {{"preprocess", r.timing.preprocess_ms}, {"vote", r.timing.vote_ms}, {"match", r.timing.match_ms}, {"refine", r.timing.refine_ms},
                    {"total", r.timing.total_ms}};
  j["scene_points"] = r.scene_points;
  j["pixel_stride"] = r.pixel_stride;
  j["flying_points"] = r.flying_points;
  j["sampled_points"] = r.sampled_points;
  j["noise_mm"] = r.noise_mm;
  j["k_normals"] = r.k_normals;
  j["normal_radius_mm"] = r.normal_radius;
  j["least_score"] = r.least_score;
  j["plane_points"] = r.plane_points;
  j["subgroups"] = r.subgroups;
  j["subgroups_run"] = r.subgroups_run;
  j["subgroups_retried"] = r.subgroups_retried;
  j["hypotheses"] = r.hypotheses;
  j["refined"] = r.refined;
  j["refound"] = r.refound;
  j["params"] = nlohmann::json::parse(binpose::toJson(p));
  return j.dump(2);
}

int runDetect(const DetectOptions& o) {
  std::optional<tbb::global_control> threads;
  if (o.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(o.threads));
  const binpose::ModelDatabase db = loadOrTrain(o);
  const float diameter = db.model().diameter;
  const binpose::PointCloud scan = loadScene(o, diameter);
  warnAboutScene(scan, diameter);
  const binpose::DetectionParams params = detectParams(o, diameter, scan);
  const binpose::Detector detector(db, params);
  const binpose::DetectionResult r = detector.detect(scan);

  fmt::print("scene {}: {} points ({} flying pixels dropped), {} sampled ({} on the bin's planes, left out), {} sub-groups; model {:.1f} mm across\n",
             o.scene, r.scene_points, r.flying_points, r.sampled_points, r.plane_points, r.subgroups, diameter);
  if (r.pixel_stride > 1)
    fmt::print("depth image thinned to one pixel in each {0} x {0} block: its depths are copies over blocks of pixels\n", r.pixel_stride);
  fmt::print("{:>4}  {:>6}  {:>5}  {:>27}  {:>8}\n", "rank", "score", "|C|", "position (mm)", "angle");
  for (std::size_t i = 0; i < r.detections.size(); ++i) {
    const auto& d = r.detections[i];
    const binpose::Vec3 t = d.pose.translation();
    const float angle = Eigen::AngleAxisf(d.pose.linear()).angle() * 180.0f / std::numbers::pi_v<float>;
    fmt::print("{:>4}  {:>6.3f}  {:>5}  {:>8.2f} {:>8.2f} {:>9.2f}  {:>7.2f}d\n", i + 1, d.score, d.correspondences, t.x(),
               t.y(), t.z(), angle);
  }
  fmt::print("{} detections in {:.1f} ms (preprocess {:.1f}, vote {:.1f}, match {:.1f}, refine {:.1f}); {} poses verified, {} refined\n",
             r.detections.size(), r.timing.total_ms, r.timing.preprocess_ms, r.timing.vote_ms, r.timing.match_ms,
             r.timing.refine_ms, r.hypotheses, r.refined);
  if (!o.render.empty()) {
    binpose::renderDetections(o.render, scan, r.detections, db.model().points, db.model().normals, params.viewpoint);
    fmt::print("picture: {}\n", o.render);
  }
  if (!o.export_ply.empty()) {
    binpose::exportDetectionsPly(o.export_ply, scan, r.detections, db.model().points);
    fmt::print("3D view: {}\n", o.export_ply);
  }
  if (!o.out.empty()) writeResult(o.out, resultJson(r, params));
  return 0;
}

/// One pose of a JSON file, `m` its 4 x 4 (or top 3 x 4) rows: a rigid transform, else an error
/// naming the file and the pose.
binpose::Pose poseFromRows(const nlohmann::json& m, const std::string& path, std::size_t index) {
  const auto bad = [&](const char* what) { return binpose::Error(fmt::format("{}: pose {}: {}", path, index + 1, what)); };
  if (!m.is_array() || m.size() < 3 || m.size() > 4) throw bad("not 3 or 4 rows of 4 numbers");
  binpose::Pose pose = binpose::Pose::Identity();
  for (int r = 0; r < 3; ++r) {
    const nlohmann::json& row = m[static_cast<std::size_t>(r)];
    if (!row.is_array() || row.size() != 4) throw bad("a row is not 4 numbers");
    for (int c = 0; c < 4; ++c) {
      const nlohmann::json& v = row[static_cast<std::size_t>(c)];
      if (!v.is_number() || !std::isfinite(v.get<double>())) throw bad("a value is not a finite number");
      (c < 3 ? pose.linear()(r, c) : pose.translation()(r)) = v.get<float>();
    }
  }
  if (!binpose::isRotation(pose.linear())) throw bad("its 3 x 3 part is not a rotation");
  return pose;
}

/// The poses of one image of a BOP scene_gt.json (`image_id`, else its first): each object's
/// cam_R_m2c (row-major) and cam_t_m2c (mm), of object `obj_id` alone when it is given.
std::vector<binpose::Pose> bopPoses(const nlohmann::json& j, const std::string& path, const std::string& image_id,
                                    std::optional<int> obj_id) {
  if (!image_id.empty() && !j.contains(image_id)) throw binpose::Error(fmt::format("{}: no entry for image '{}'", path, image_id));
  const nlohmann::json& image = image_id.empty() ? j.begin().value() : j.at(image_id);
  if (!image.is_array()) throw binpose::Error(fmt::format("{}: image '{}' holds no list of objects", path, image_id));
  std::vector<binpose::Pose> poses;
  for (const auto& item : image) {
    const bool has = item.is_object() && item.contains("cam_R_m2c") && item.contains("cam_t_m2c");
    const nlohmann::json r = has ? item.at("cam_R_m2c") : nlohmann::json(), t = has ? item.at("cam_t_m2c") : nlohmann::json();
    if (!r.is_array() || r.size() != 9 || !t.is_array() || t.size() != 3)
      throw binpose::Error(fmt::format("{}: an object has no 9-number cam_R_m2c and 3-number cam_t_m2c", path));
    if (obj_id && !(item.contains("obj_id") && item.at("obj_id").is_number_integer() && item.at("obj_id").get<int>() == *obj_id)) continue;
    const nlohmann::json rows = {{r[0], r[1], r[2], t[0]}, {r[3], r[4], r[5], t[1]}, {r[6], r[7], r[8], t[2]}};
    poses.push_back(poseFromRows(rows, path, poses.size()));
  }
  return poses;
}

/// The poses of a JSON file: its "poses" (4 x 4 rows each), the "pose" of each of its
/// "detections" (a detect result) or "instances" (a simulated scene's ground_truth.json), or a
/// BOP scene_gt.json's (bopPoses).
std::vector<binpose::Pose> readPoses(const std::string& path, const std::string& image_id, std::optional<int> obj_id) {
  std::ifstream in(path);
  if (!in) throw binpose::Error(fmt::format("{}: cannot open", path));
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded() || !j.is_object()) throw binpose::Error(fmt::format("{}: not a JSON object", path));
  if (!j.empty() && j.begin().value().is_array() && !j.begin().value().empty() && j.begin().value()[0].is_object() &&
      j.begin().value()[0].contains("cam_R_m2c"))
    return bopPoses(j, path, image_id, obj_id);
  std::vector<binpose::Pose> poses;
  if (j.contains("poses") && j["poses"].is_array()) {
    for (const auto& m : j["poses"]) poses.push_back(poseFromRows(m, path, poses.size()));
    return poses;
  }
  for (const char* key : {"detections", "instances"}) {
    if (!j.contains(key) || !j[key].is_array()) continue;
    for (const auto& item : j[key]) {
      if (!item.is_object() || !item.contains("pose"))
        throw binpose::Error(fmt::format("{}: an entry of \"{}\" has no pose", path, key));
      poses.push_back(poseFromRows(item["pose"], path, poses.size()));
    }
    return poses;
  }
  throw binpose::Error(fmt::format("{}: no \"poses\", \"detections\" or \"instances\" array in it, nor a BOP scene_gt.json", path));
}

std::string checksJson(const std::vector<binpose::Pose>& poses, const std::vector<binpose::PoseCheck>& checks) {
  nlohmann::json j;
  j["checks"] = nlohmann::json::array();
  for (std::size_t i = 0; i < checks.size(); ++i) {
    const binpose::PoseCheck& c = checks[i];
    const binpose::Evidence& e = c.evidence;
    j["checks"].push_back({{"pose", rowsOf(poses[i])},
                           {"refined", rowsOf(c.refined)},
                           {"moved_mm", c.moved_mm},
                           {"score", c.score},
                           {"visible_support", c.visible_support},
                           {"as_found", binpose::refusalName(c.as_found)},
                           {"as_laid", binpose::refusalName(c.as_laid)},
                           {"facing", e.facing},
                           {"supported", e.supported},
                           {"contradicted", e.contradicted},
                           {"occluded", e.occluded},
                           {"on_background", e.on_background}});
  }
  return j.dump(2);
}

int runCheck(const DetectOptions& o) {
  std::optional<tbb::global_control> threads;
  if (o.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(o.threads));
  const std::vector<binpose::Pose> poses = readPoses(o.poses, o.image_id, o.obj_id);
  const binpose::ModelDatabase db = loadOrTrain(o);
  const float diameter = db.model().diameter;
  const binpose::PointCloud scan = loadScene(o, diameter);
  warnAboutScene(scan, diameter);
  const binpose::DetectionParams params = detectParams(o, diameter, scan);
  const std::vector<binpose::PoseCheck> checks = binpose::Detector(db, params).check(scan, poses);
  fmt::print("{:>4}  {:>6}  {:>7}  {:>8}  {:>27}  {:<15}  {:<15}\n", "pose", "score", "visible", "moved", "refined position (mm)",
             "as found", "as laid");
  int found = 0, laid = 0;
  for (std::size_t i = 0; i < checks.size(); ++i) {
    const binpose::PoseCheck& c = checks[i];
    const binpose::Vec3 t = c.refined.translation();
    fmt::print("{:>4}  {:>6.3f}  {:>7.2f}  {:>5.1f} mm  {:>8.2f} {:>8.2f} {:>9.2f}  {:<15}  {:<15}\n", i + 1, c.score,
               c.visible_support, c.moved_mm, t.x(), t.y(), t.z(), binpose::refusalName(c.as_found),
               binpose::refusalName(c.as_laid));
    found += c.as_found == binpose::Refusal::none;
    laid += c.as_found != binpose::Refusal::none && c.as_laid == binpose::Refusal::none;
  }
  fmt::print(
      "{} poses: {} stand as detect's clique poses do, {} more only as a pose laid on a flat face, {} refused "
      "(as found: the first test each fails)\n",
      checks.size(), found, laid, static_cast<int>(checks.size()) - found - laid);
  if (!o.out.empty()) writeResult(o.out, checksJson(poses, checks));
  return 0;
}

struct SimulateOptions {
  std::string model = "builtin:cap", out, units = "mm", model_info, sensor = "ideal", bop, style = "bin";
  int obj_id = 1, scene_id = 1;
  float density = binpose::ThesisSceneParams{}.density;
  std::vector<float> bin;
  binpose::SimulationParams params;
};

void addSimulate(CLI::App& app, SimulateOptions& o) {
  CLI::App* s = app.add_subcommand("simulate", "Drop copies of a part into a bin and render a depth sensor's view (thesis 7.1.2)");
  s->add_option("--model", o.model, "Mesh (PLY/STL/OBJ) or builtin:cap|sphere|box")->capture_default_str();
  s->add_option("--instances", o.params.instances, "Copies dropped into the bin")->capture_default_str();
  s->add_option("--seed", o.params.seed, "Seed of the drop and the sensor noise")->capture_default_str();
  s->add_option("--out", o.out, "Folder for depth.png, camera.json, scene.ply, ground_truth.json and BOP files")->required();
  s->add_option("--units", o.units, "Length unit of the model file: mm, cm, m or in")
      ->check(CLI::IsMember({"mm", "cm", "m", "in"}))
      ->capture_default_str();
  s->add_option("--model-info", o.model_info, "BOP models_info.json giving the part's symmetries");
  s->add_option("--obj-id", o.obj_id, "Entry of --model-info")->capture_default_str();
  s->add_option("--width", o.params.sensor.width, "Image width, px")->capture_default_str();
  s->add_option("--height", o.params.sensor.height, "Image height, px")->capture_default_str();
  s->add_option("--fx", o.params.sensor.fx, "Focal length, px (fy = fx; principal point at the centre)")->capture_default_str();
  s->add_option("--distance", o.params.sensor.distance, "Sensor to bin floor, mm")->capture_default_str();
  s->add_option("--noise", o.params.sensor.noise_sigma, "Ideal sensor's depth noise at 500 mm (1 sigma), mm")->capture_default_str();
  s->add_option("--sensor", o.sensor,
                "Sensor model: ideal (Gaussian noise only), structured-light (Kinect v1 class), industrial "
                "(Photoneo/Zivid class) or tof (Kinect v2 class); see include/binpose/sensor_model.hpp")
      ->check(CLI::IsMember({"ideal", "structured-light", "industrial", "tof"}))
      ->capture_default_str();
  s->add_option("--bin", o.bin, "Bin inside length width height, mm (default 200 200 120)")->expected(3);
  s->add_option("--style", o.style, "bin: parts dropped into a bin, seen by the sensor; thesis: the thesis's synthetic "
                "scenes (7.4): copies apart at random poses, random surface samples, random occlusion, no bin or sensor")
      ->check(CLI::IsMember({"bin", "thesis"}))->capture_default_str();
  s->add_option("--density", o.density, "Thesis style: points drawn per mm^2 of each copy's surface")->capture_default_str();
  s->add_option("--bop", o.bop, "Also add the scene to this BOP dataset folder (models/, test/, test_targets_bop19.json)");
  s->add_option("--scene-id", o.scene_id, "The scene's id in the BOP dataset")->check(CLI::Range(0, 999999))->capture_default_str();
}

/// BOP models_info entry (diameter, symmetries) of the simulated part, as JSON text.
std::string modelInfo(const SimulateOptions& o, const binpose::Mesh& mesh) {
  if (!o.model_info.empty()) {
    std::ifstream in(o.model_info);
    const auto j = nlohmann::json::parse(in, nullptr, false);
    const std::string key = std::to_string(o.obj_id);
    if (j.is_discarded() || !j.contains(key)) throw binpose::Error(fmt::format("{}: no entry '{}'", o.model_info, key));
    return j[key].dump();
  }
  return binpose::defaultModelInfo(o.model, mesh);
}

int runSimulate(SimulateOptions o) {
  const auto t0 = Clock::now();
  if (o.bin.size() == 3) o.params.bin.inner = binpose::Vec3(o.bin[0], o.bin[1], o.bin[2]);
  o.params.sensor.fy = o.params.sensor.fx;
  o.params.sensor.model = binpose::sensorModel(binpose::parseSensorKind(o.sensor));
  o.params.sensor.cx = (o.params.sensor.width - 1) / 2.0;
  o.params.sensor.cy = (o.params.sensor.height - 1) / 2.0;
  const binpose::ModelFile file = binpose::readModelOrBuiltin(o.model, binpose::unitScale(binpose::parseUnits(o.units)));
  if (!file.is_mesh) throw binpose::Error(fmt::format("{}: the simulator needs a mesh, not a point cloud", o.model));
  binpose::ThesisSceneParams thesis;
  thesis.instances = o.params.instances;
  thesis.seed = o.params.seed;
  thesis.density = o.density;
  const binpose::SimulatedScene scene =
      o.style == "thesis" ? binpose::simulateThesisScene(file.mesh, thesis) : binpose::simulateBin(file.mesh, o.params);
  binpose::writeScene(o.out, scene, o.model, modelInfo(o, file.mesh));
  if (!o.bop.empty()) binpose::writeBopScene(o.bop, o.scene_id, o.obj_id, scene, file.mesh, modelInfo(o, file.mesh));
  if (o.style == "thesis")
    fmt::print("{} copies of {} at random poses {} mm from the viewer, {} points/mm^2, randomly occluded (thesis 7.4)\n",
               o.params.instances, o.model, thesis.distance, thesis.density);
  else
    fmt::print("{} copies of {} in a {}x{}x{} mm bin; sensor {}x{} px at {} mm\n", o.params.instances, o.model,
               o.params.bin.inner.x(), o.params.bin.inner.y(), o.params.bin.inner.z(), o.params.sensor.width,
               o.params.sensor.height, o.params.sensor.distance);
  fmt::print("{:>4}  {:>27}  {:>8}  {:>7}  {:>11}\n", "copy", "position in camera (mm)", "surface", "pixels", "visib_fract");
  for (std::size_t i = 0; i < scene.instances.size(); ++i) {
    const auto& inst = scene.instances[i];
    const binpose::Vec3 t = inst.pose.translation();
    fmt::print("{:>4}  {:>8.1f} {:>8.1f} {:>9.1f}  {:>7.0f}%  {:>7}  {:>10.0f}%\n", i, t.x(), t.y(), t.z(),
               100 * inst.visible_fraction, inst.visible_pixels, 100 * inst.visib_fract);
  }
  fmt::print("scan: {} points; written to {} in {:.2f} s\n", scene.cloud.size(), o.out, secondsSince(t0));
  return 0;
}

struct EvalOptions {
  std::string truth, result, model, out, units = "mm", models_info, obj_id = "1";
  std::optional<int> scene_id;
  int im_id = 0;
  float threshold = 0.1f;
};

void addEval(CLI::App& app, EvalOptions& o) {
  CLI::App* e = app.add_subcommand("eval", "Score detections against a simulated scene's ground truth (thesis 7.1.3)");
  e->add_option("--truth", o.truth, "Folder written by binpose simulate")->required();
  e->add_option("--result", o.result, "result.json written by binpose detect, or a BOP19 results CSV (binpose bop)")->required();
  e->add_option("--scene-id", o.scene_id, "The CSV rows' scene (default: the CSV's only one)");
  e->add_option("--im-id", o.im_id, "The CSV rows' image")->capture_default_str();
  e->add_option("--model", o.model, "The part's mesh (or builtin:NAME), as simulated")->required();
  e->add_option("--units", o.units, "Length unit of the model file: mm, cm, m or in")
      ->check(CLI::IsMember({"mm", "cm", "m", "in"}))
      ->capture_default_str();
  e->add_option("--models-info", o.models_info, "BOP models_info.json with the symmetries (default: the truth folder's)");
  e->add_option("--obj-id", o.obj_id, "Entry of models_info.json")->capture_default_str();
  e->add_option("--threshold", o.threshold, "A detection is correct when ADD-S < threshold x diameter")->capture_default_str();
  e->add_option("--out", o.out, "Write the evaluation as JSON here");
}

/// Poses (best first) and time of one image's object in a BOP19 results CSV.
std::pair<std::vector<binpose::Pose>, double> readCsvResult(const EvalOptions& o) {
  auto rows = binpose::readBopCsv(o.result);
  int scene = o.scene_id.value_or(rows.empty() ? 0 : rows.front().scene_id);
  for (const auto& r : rows)
    if (!o.scene_id && r.scene_id != scene)
      throw binpose::Error(fmt::format("{}: rows of several scenes; choose one with --scene-id", o.result));
  std::erase_if(rows, [&](const binpose::BopResult& r) { return r.scene_id != scene || r.im_id != o.im_id || std::to_string(r.obj_id) != o.obj_id; });
  std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.score > b.score; });
  std::vector<binpose::Pose> poses;
  for (const auto& r : rows) poses.push_back(r.pose);
  return {poses, rows.empty() || rows.front().time_s < 0 ? 0.0 : 1000.0 * rows.front().time_s};
}

/// Poses and total time of a result.json.
std::pair<std::vector<binpose::Pose>, double> readResult(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw binpose::Error(fmt::format("{}: cannot open result", path));
  const auto j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded() || !j.contains("detections")) throw binpose::Error(fmt::format("{}: not a binpose result", path));
  std::vector<binpose::Pose> poses;
  try {
    for (const auto& d : j["detections"]) {
      Eigen::Matrix4f T;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) T(r, c) = d.at("pose").at(r).at(c).get<float>();
      binpose::Pose p = binpose::Pose::Identity();
      p.matrix() = T;
      poses.push_back(p);
    }
  } catch (const nlohmann::json::exception& e) {
    throw binpose::Error(fmt::format("{}: malformed pose ({})", path, e.what()));
  }
  return {poses, j.contains("timing_ms") ? j["timing_ms"].value("total", 0.0) : 0.0};
}

nlohmann::json reportJson(const binpose::EvaluationReport& r) {
  nlohmann::json j{{"recall", r.recall}, {"precision", r.precision}, {"recall_over_half_visible", r.recall_over_half_visible},
                   {"detections", r.detections}, {"matched", r.matched}, {"instances_total", r.instances.size()},
                   {"mean_centroid_error_mm", r.mean_centroid_mm}, {"mean_angle_error_deg", r.mean_angle_deg},
                   {"mean_add_s_mm", r.mean_add_s_mm}, {"mean_mssd_mm", r.mean_mssd_mm}, {"total_ms", r.total_ms},
                   {"ms_per_object", r.ms_per_object}};
  j["recall_by_visible_fraction"] = nlohmann::json::array();
  for (int b = 0; b < 10; ++b)
    j["recall_by_visible_fraction"].push_back({{"from", b / 10.0}, {"to", (b + 1) / 10.0}, {"instances", r.visible_bin_total[b]},
                                               {"found", r.visible_bin_found[b]}});
  j["instances"] = nlohmann::json::array();
  for (const auto& i : r.instances)
    j["instances"].push_back({{"truth", i.truth}, {"detection", i.detection}, {"visible_fraction", i.visible_fraction}, {"visib_fract", i.visib_fract},
                              {"centroid_error_mm", i.errors.centroid_mm}, {"angle_error_deg", i.errors.angle_deg},
                              {"add_s_mm", i.errors.add_s_mm}, {"mssd_mm", i.errors.mssd_mm}});
  return j;
}

int runEval(const EvalOptions& o) {
  const binpose::GroundTruth truth = binpose::readGroundTruth(o.truth);
  const bool csv = o.result.size() > 4 && o.result.substr(o.result.size() - 4) == ".csv";
  const auto [poses, total_ms] = csv ? readCsvResult(o) : readResult(o.result);
  const binpose::ModelFile file = binpose::readModelOrBuiltin(o.model, binpose::unitScale(binpose::parseUnits(o.units)));
  if (!file.is_mesh) throw binpose::Error(fmt::format("{}: evaluation needs the part's mesh", o.model));
  const std::string info = o.models_info.empty() ? o.truth + "/models_info.json" : o.models_info;
  const binpose::EvalModel model = binpose::makeEvalModel(file.mesh, binpose::readSymmetries(info, o.obj_id));
  const binpose::EvaluationReport r = binpose::evaluate(truth, poses, total_ms, model, o.threshold);
  fmt::print("{:>4}  {:>8}  {:>6}  {:>5}  {:>10}  {:>9}  {:>8}  {:>8}\n", "copy", "surface", "visib", "det", "centroid", "angle",
             "ADD-S", "MSSD");
  for (const auto& i : r.instances) {
    if (i.detection < 0) {
      fmt::print("{:>4}  {:>7.0f}%  {:>5.0f}%  {:>5}\n", i.truth, 100 * i.visible_fraction, 100 * i.visib_fract, "-");
      continue;
    }
    fmt::print("{:>4}  {:>7.0f}%  {:>5.0f}%  {:>5}  {:>7.3f} mm  {:>7.3f} d  {:>5.3f} mm  {:>5.3f} mm\n", i.truth,
               100 * i.visible_fraction, 100 * i.visib_fract, i.detection + 1, i.errors.centroid_mm, i.errors.angle_deg, i.errors.add_s_mm, i.errors.mssd_mm);
  }
  fmt::print("recall {:.1f}% ({} of {}; {:.1f}% of those with visib_fract > 50%), precision {:.1f}% ({} detections)\n",
             100 * r.recall, r.matched, r.instances.size(), 100 * r.recall_over_half_visible, 100 * r.precision, r.detections);
  fmt::print("mean centroid error {:.3f} mm, angle {:.3f} deg, ADD-S {:.3f} mm, MSSD {:.3f} mm; {:.1f} ms per object found\n",
             r.mean_centroid_mm, r.mean_angle_deg, r.mean_add_s_mm, r.mean_mssd_mm, r.ms_per_object);
  if (!o.out.empty()) {
    std::ofstream out(o.out);
    out << reportJson(r).dump(1) << "\n";
    if (!out) throw binpose::Error(fmt::format("{}: cannot write", o.out));
  }
  return 0;
}

struct SweepOptions {
  binpose::SweepSettings settings;
  std::vector<double> r, rho_sub, eta, e_gmax, C_n, d_dist, p_d;
};

void addSweep(CLI::App& app, SweepOptions& o) {
  CLI::App* w = app.add_subcommand("sweep", "Sweep parameters over simulated bins: CSV and the thesis's plots (Tables 1-7)");
  w->add_option("--model", o.settings.model, "Mesh or builtin:NAME")->capture_default_str();
  w->add_option("--preset", o.settings.preset, "default or thesis (fast: an alias of default)")->check(CLI::IsMember({"default", "fast", "thesis"}))->capture_default_str();
  w->add_option("--scenes", o.settings.scenes, "Simulated bins")->capture_default_str();
  w->add_option("--instances", o.settings.instances, "Parts per bin")->capture_default_str();
  w->add_option("--seed", o.settings.seed, "Seed of the first bin")->capture_default_str();
  w->add_flag("--thesis-scenes", o.settings.thesis_style, "Thesis-style scenes (simulate --style thesis) instead of bins");
  w->add_option("--density", o.settings.thesis.density, "Thesis-style scenes: points drawn per mm^2 of surface")->capture_default_str();
  w->add_option("--out", o.settings.out, "Output folder")->required();
  w->add_option("--r", o.r, "Sampling radii r, mm (comma-separated)")->delimiter(',');
  w->add_option("--rho-sub", o.rho_sub, "Densities rho_sub, points/mm^2")->delimiter(',');
  w->add_option("--eta", o.eta, "Grid spacings eta, mm")->delimiter(',');
  w->add_option("--e-gmax", o.e_gmax, "Consistency limits e_gmax, mm")->delimiter(',');
  w->add_option("--c-n", o.C_n, "Smallest cliques C_n")->delimiter(',');
  w->add_option("--d-dist", o.d_dist, "Distance steps d_dist, mm (one database each)")->delimiter(',');
  w->add_option("--overlap", o.p_d, "Bin overlaps p_d (one database each)")->delimiter(',');
}

int runSweepCommand(const SweepOptions& o) {
  binpose::SweepGrid grid;
  std::vector<std::string> order;  // plotted against the first, a curve per value of the second
  for (const auto& [name, values] : std::vector<std::pair<std::string, const std::vector<double>*>>{
           {"r", &o.r}, {"rho_sub", &o.rho_sub}, {"e_gmax", &o.e_gmax}, {"C_n", &o.C_n}, {"eta", &o.eta},
           {"d_dist", &o.d_dist}, {"p_d", &o.p_d}})
    if (!values->empty()) {
      grid[name] = *values;
      order.push_back(name);
    }
  if (grid.empty()) throw binpose::Error("sweep: give at least one parameter to sweep (for example --r 20,25,30)");
  const auto t0 = Clock::now();
  const auto rows = binpose::runSweep(o.settings, grid, [&](int done, int total) {
    const int width = 40, filled = width * done / total;
    fmt::print(stderr, "\r[{}{}] {}/{} runs, {:.0f} s", std::string(filled, '#'), std::string(width - filled, '.'), done, total,
               secondsSince(t0));
    if (done == total) fmt::print(stderr, "\n");
  });
  fmt::print("{} runs; {}/results.csv, {}/instances.csv\n", rows.size(), o.settings.out, o.settings.out);
  for (const auto& png : binpose::plotSweep(o.settings.out, rows, order)) fmt::print("plot: {}\n", png);
  return 0;
}

struct BopOptions {
  binpose::BopRun run;
  std::string out;
  int threads = 0;
};

void addBop(CLI::App& app, BopOptions& o) {
  CLI::App* b = app.add_subcommand("bop", "Detect the targets of a BOP dataset's split; write the BOP19 results CSV");
  b->add_option("--dataset", o.run.dataset, "The dataset's folder (models/, SPLIT/SCENE/depth, scene_camera.json)")->required();
  b->add_option("--split", o.run.split, "The split's folder")->capture_default_str();
  b->add_option("--targets", o.run.targets, "test_targets_bop19.json (default: the dataset's)");
  b->add_option("--objects", o.run.objects, "Only these obj_ids (comma-separated)")->delimiter(',');
  b->add_option("--out", o.out, "Results CSV (scene_id,im_id,obj_id,score,R,t,time)")->required();
  b->add_option("--cache", o.run.cache, "Folder of trained databases, reused (default: binpose_models beside --out)");
  b->add_option("--preset", o.run.preset, "Parameter preset: default or thesis")->check(CLI::IsMember({"default", "fast", "thesis"}))->capture_default_str();
  b->add_option("--params", o.run.params_file, "JSON file of parameters (absolute units, mm), applied after the preset");
  b->add_option("--model-points", o.run.model_points, "Model points when training")->capture_default_str();
  b->add_option("--threads", o.threads, "Worker threads (0: all cores)")->check(CLI::Range(0, 1024))->capture_default_str();
}

int runBopCommand(BopOptions o) {
  std::optional<tbb::global_control> threads;
  if (o.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(o.threads));
  if (o.run.cache.empty())
    o.run.cache = (std::filesystem::absolute(o.out).parent_path() / "binpose_models").string();
  const auto t0 = Clock::now();
  const auto results = binpose::runBop(o.run, [&](std::size_t done, std::size_t total) {
    const auto bar = static_cast<std::size_t>(30 * done / std::max<std::size_t>(1, total));
    fmt::print(stderr, "\r[{:<30}] {}/{} images, {:.0f} s", std::string(bar, '#'), done, total, secondsSince(t0));
    if (done == total) fmt::print(stderr, "\n");
  });
  binpose::writeBopCsv(o.out, results);
  fmt::print("{} poses in {:.1f} s; written to {} (databases in {})\n", results.size(), secondsSince(t0), o.out, o.run.cache);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"binpose: find every copy of a rigid part in a 3D scan and its 6D pose"};
  app.require_subcommand(1);
  TrainOptions train;
  addTrain(app, train);
  DetectOptions detect, check;
  addDetect(app, detect);
  addCheck(app, check);
  SimulateOptions simulate;
  addSimulate(app, simulate);
  EvalOptions eval;
  addEval(app, eval);
  SweepOptions sweep;
  addSweep(app, sweep);
  BopOptions bop;
  addBop(app, bop);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (app.got_subcommand("train")) return runTrain(train);
    if (app.got_subcommand("detect")) return runDetect(detect);
    if (app.got_subcommand("check")) return runCheck(check);
    if (app.got_subcommand("simulate")) return runSimulate(simulate);
    if (app.got_subcommand("eval")) return runEval(eval);
    if (app.got_subcommand("sweep")) return runSweepCommand(sweep);
    if (app.got_subcommand("bop")) return runBopCommand(bop);
  } catch (const binpose::Error& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
