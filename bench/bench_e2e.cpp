// End-to-end benchmark: binpose against OpenCV's PPF detector (Drost et al. 2010,
// cv::ppf_match_3d::PPF3DDetector) on the very same inputs, in the same run.
//
//   binpose_bench_e2e [--data ../shared/data] [--cache out/bench] [--out bench/results.json]
//                     [--repeats 5] [--inputs a,b] [--methods a,b] [--seed-offset N]
//
// Inputs: seeded simulated bins (16 and 32 copies of the built-in cap, IPD obj 0 and obj 8, seen by
// the ideal sensor; 16 of the cap, IPD obj 0, 8 and 1 seen by the structured-light, industrial and
// time-of-flight sensor models, -sl, -ind and -tof) and
// the real scans UWA rs1 (parasaurolophus) and PCL milk (carton). Each (input, method) runs in a
// child process (this program re-executed with --run) so that its peak memory is its own.
// Timings: training once; detection the median of --repeats runs, file reading excluded,
// preprocessing (normals, sub-sampling) included for both methods.
#include <binpose/detector.hpp>
#include <binpose/evaluation.hpp>
#include <binpose/io.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>

#include <opencv2/surface_matching.hpp>
#include <opencv2/surface_matching/ppf_helpers.hpp>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

using namespace binpose;
using json = nlohmann::json;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

struct InputSpec {
  std::string name;
  std::string model;     ///< builtin:cap or a mesh/cloud path relative to --data
  std::string obj_id;    ///< models_info entry of the part (IPD) or "" (cap: its own)
  int instances = 0;     ///< simulated copies (0: a real scan)
  std::uint64_t seed = 0;
  SensorKind sensor = SensorKind::Ideal;  ///< the simulated sensor (sensor_model.hpp)
  float distance = 500;  ///< sensor to bin floor, mm
  int width = 640, height = 480;
  double fx = 550;
};

/// A structured-light sensor (Kinect v1 class) 800 mm above the floor: the parts at 0.7-0.8 m.
constexpr float kStructuredLightDistance = 800;
/// An industrial sensor 1 m above the floor at 1280 x 960 px (about 0.9 mm a pixel there).
constexpr float kIndustrialDistance = 1000;
/// A time-of-flight sensor (Kinect v2 class) 800 mm above the floor, as the structured-light one.
constexpr float kTimeOfFlightDistance = 800;

const std::vector<InputSpec>& inputSpecs() {
  static const std::vector<InputSpec> specs = {
      {"cap-16", "builtin:cap", "", 16, 101},
      {"cap-32", "builtin:cap", "", 32, 102},
      {"ipd0-16", "ipd_parts/models/obj_000000.ply", "0", 16, 103},
      {"ipd0-32", "ipd_parts/models/obj_000000.ply", "0", 32, 104},
      {"ipd8-16", "ipd_parts/models/obj_000008.ply", "8", 16, 105},
      {"ipd8-32", "ipd_parts/models/obj_000008.ply", "8", 32, 106},
      {"cap-16-sl", "builtin:cap", "", 16, 101, SensorKind::StructuredLight, kStructuredLightDistance},
      {"ipd0-16-sl", "ipd_parts/models/obj_000000.ply", "0", 16, 103, SensorKind::StructuredLight, kStructuredLightDistance},
      {"ipd8-16-sl", "ipd_parts/models/obj_000008.ply", "8", 16, 105, SensorKind::StructuredLight, kStructuredLightDistance},
      {"ipd1-16-sl", "ipd_parts/models/obj_000001.ply", "1", 16, 107, SensorKind::StructuredLight, kStructuredLightDistance},
      {"cap-16-ind", "builtin:cap", "", 16, 101, SensorKind::Industrial, kIndustrialDistance, 1280, 960, 1100},
      {"ipd0-16-ind", "ipd_parts/models/obj_000000.ply", "0", 16, 103, SensorKind::Industrial, kIndustrialDistance, 1280, 960, 1100},
      {"ipd8-16-ind", "ipd_parts/models/obj_000008.ply", "8", 16, 105, SensorKind::Industrial, kIndustrialDistance, 1280, 960, 1100},
      {"ipd1-16-ind", "ipd_parts/models/obj_000001.ply", "1", 16, 107, SensorKind::Industrial, kIndustrialDistance, 1280, 960, 1100},
      {"cap-16-tof", "builtin:cap", "", 16, 101, SensorKind::TimeOfFlight, kTimeOfFlightDistance},
      {"ipd0-16-tof", "ipd_parts/models/obj_000000.ply", "0", 16, 103, SensorKind::TimeOfFlight, kTimeOfFlightDistance},
      {"ipd8-16-tof", "ipd_parts/models/obj_000008.ply", "8", 16, 105, SensorKind::TimeOfFlight, kTimeOfFlightDistance},
      {"ipd1-16-tof", "ipd_parts/models/obj_000001.ply", "1", 16, 107, SensorKind::TimeOfFlight, kTimeOfFlightDistance},
      {"uwa-rs1", "uwa/parasaurolophus_6700.ply", "", 0, 0},
      {"pcl-milk", "pcl_milk/milk.pcd", "", 0, 0},
  };
  return specs;
}

struct Options {
  std::string data = "../shared/data", cache = "out/bench", out = "bench/results.json";
  int repeats = 5;
  int timeout_s = 1800;  ///< per input and method
  std::vector<std::string> inputs, methods = {"binpose", "binpose-thesis", "opencv-sample", "opencv-tuned"};
  /// Added to every simulated bin's seed: other bins of the same kinds (their own cache folders),
  /// to check that what a preset gains on the fixed bins is not fitted to them.
  std::uint64_t seed_offset = 0;
  std::string params;  ///< JSON file of parameter overrides for binpose, in the thesis's 60 mm units
  int model_points = 0;  ///< points of binpose's model database (0: each input's own, ModelParams' default)
  std::string run_input, run_method;  // child mode
};

std::string modelPath(const Options& o, const InputSpec& s) {
  return s.model.starts_with("builtin:") ? s.model : o.data + "/" + s.model;
}

/// A loaded input: the model, the scan and the ground truth.
struct Input {
  ModelFile model;
  double model_scale = 1.0;
  PointCloud scan;
  GroundTruth truth;
  EvalModel eval;
};

Pose readPoseSection(const std::string& path, const std::string& section, float translation_scale) {
  std::ifstream in(path);
  if (!in) throw Error(fmt::format("{}: cannot open", path));
  std::string line;
  if (!section.empty())
    while (std::getline(in, line) && line.find(section) == std::string::npos) {}
  while (in.peek() == '#') std::getline(in, line);
  Eigen::Matrix4f T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      if (!(in >> T(r, c))) throw Error(fmt::format("{}: no 4x4 pose after '{}'", path, section));
  Pose pose = Pose::Identity();
  pose.matrix() = T;
  pose.translation() *= translation_scale;
  return pose;
}

/// An evaluation model for a point-cloud model (no mesh): its points stand for the surface.
EvalModel cloudEvalModel(const OrientedModel& m) {
  EvalModel e;
  e.points = e.dense = m.points;
  e.dense_normals = m.normals;
  for (const Vec3& p : m.points) e.centroid += p;
  e.centroid /= float(m.points.size());
  e.diameter = m.diameter;
  e.transforms = {Pose::Identity()};
  return e;
}

std::uint64_t binSeed(const Options& o, const InputSpec& s) { return s.seed + o.seed_offset; }

std::string sceneDir(const Options& o, const InputSpec& s) {
  if (o.seed_offset == 0 || s.instances == 0) return o.cache + "/" + s.name;
  return o.cache + "/" + s.name + "-seed" + std::to_string(binSeed(o, s));
}

/// Simulates the bin of `s` into the cache unless it is there already.
void ensureScene(const Options& o, const InputSpec& s) {
  const std::string dir = sceneDir(o, s);
  if (fs::exists(dir + "/ground_truth.json")) return;
  fmt::print(stderr, "simulating {} ({} copies of {}, seed {})...\n", s.name, s.instances, s.model, binSeed(o, s));
  const ModelFile file = readModelOrBuiltin(modelPath(o, s));
  SimulationParams sp;
  sp.instances = s.instances;
  sp.seed = binSeed(o, s);
  sp.sensor.model = sensorModel(s.sensor);
  sp.sensor.distance = s.distance;
  sp.sensor.width = s.width;
  sp.sensor.height = s.height;
  sp.sensor.fx = sp.sensor.fy = s.fx;
  sp.sensor.cx = (s.width - 1) / 2.0;
  sp.sensor.cy = (s.height - 1) / 2.0;
  fs::create_directories(dir);
  writeScene(dir, simulateBin(file.mesh, sp), s.model, defaultModelInfo(s.model, file.mesh));
}

Input loadInput(const Options& o, const InputSpec& s) {
  Input in;
  if (s.instances > 0) {
    in.model = readModelOrBuiltin(modelPath(o, s));
    const std::string dir = sceneDir(o, s);
    in.scan = readDepthPng(dir + "/depth.png", readIntrinsics(dir + "/camera.json"));
    in.truth = readGroundTruth(dir);
    const Symmetries sym = s.obj_id.empty() ? readSymmetries(dir + "/models_info.json", "1")
                                            : readSymmetries(o.data + "/ipd_parts/models/models_info.json", s.obj_id);
    in.eval = makeEvalModel(in.model.mesh, sym);
  } else if (s.name == "uwa-rs1") {
    in.model = readModelFile(o.data + "/uwa/parasaurolophus_6700.ply");
    in.scan = readPlyCloud(o.data + "/uwa/rs1_normals.ply");
    in.truth.instances.push_back(
        {readPoseSection(o.data + "/uwa/REFERENCE_pose_parasaurolophus_in_rs1_DERIVED.txt", "", 1.0f), 1.0f, 0, 1.0f});
    in.eval = makeEvalModel(in.model.mesh, {});
  } else {  // pcl-milk: a partial-view cloud model, metres
    in.model_scale = 1000.0;
    in.model = readModelFile(o.data + "/pcl_milk/milk.pcd", 1000.0);
    in.scan = readPcd(o.data + "/pcl_milk/milk_cartoon_all_small_clorox.pcd", 1000.0);
    in.truth.instances.push_back(
        {readPoseSection(o.data + "/pcl_milk/GT_milk_poses.txt", "[test/milk.pcd", 1000.0f), 1.0f, 0, 1.0f});
  }
  return in;
}

ModelParams modelParams(const InputSpec& s) {
  ModelParams mp;
  if (s.name == "pcl-milk") mp.num_points = 2000;  // the view holds about 13 700 points
  return mp;
}

/// The input's model sampled to `points` points (0: binpose's default for the input).
OrientedModel orientedModel(const Input& in, const InputSpec& s, int points = 0) {
  ModelParams mp = modelParams(s);
  if (points > 0) mp.num_points = points;
  return in.model.is_mesh ? prepareModel(in.model.mesh, mp) : prepareModel(in.model.cloud, mp);
}

/// What one method gives on one input.
struct Outcome {
  double train_ms = 0;
  std::vector<double> detect_ms;
  std::vector<Pose> poses;
  std::vector<DetectionTiming> stages;  ///< binpose's stage times, one per run
  float noise_mm = 0;  ///< binpose's estimate of the scan's noise
  int k_normals = 0;   ///< the normals' neighbours it used
};

Outcome runBinpose(const OrientedModel& model, const PointCloud& scan, const std::string& preset, int repeats,
                   const std::string& params_file) {
  Outcome out;
  const auto t0 = Clock::now();
  const ModelDatabase db = ModelDatabase::build(model, defaultQuantization(model.diameter));
  out.train_ms = msSince(t0);
  DetectionParams params = presetByName(preset);
  if (!params_file.empty()) applyJsonFile(params, params_file);  // before scaling: one file for parts of any size
  const Detector detector(db, scaledToModel(params, model.diameter));
  for (int r = 0; r < repeats; ++r) {
    const auto t = Clock::now();
    const DetectionResult result = detector.detect(scan);
    out.detect_ms.push_back(msSince(t));
    out.stages.push_back(result.timing);
    out.noise_mm = result.noise_mm;
    out.k_normals = result.k_normals;
    if (r == 0)
      for (const Detection& d : result.detections) out.poses.push_back(d.pose);
  }
  return out;
}

cv::Mat toMat(const Points& points, const Points& normals) {
  cv::Mat m(static_cast<int>(points.size()), normals.empty() ? 3 : 6, CV_32F);
  for (int i = 0; i < m.rows; ++i) {
    for (int k = 0; k < 3; ++k) m.at<float>(i, k) = points[i][k];
    if (!normals.empty())
      for (int k = 0; k < 3; ++k) m.at<float>(i, 3 + k) = normals[i][k];
  }
  return m;
}

/// OpenCV's settings: the sample's (ppf_load_match.cpp) or ours, tuned for bins of many parts.
struct OpencvSettings {
  double sampling = 0.025, distance = 0.05;          // training: relative sampling step, distance step
  double scene_sample = 1.0 / 40.0, scene_distance = 0.05;  // matching
  int icp_iterations = 100;
  float icp_tolerance = 0.005f, icp_rejection = 2.5f;
  int icp_levels = 8;
  int icp_top = 2;  // poses refined by ICP (the sample: N = 2)
  /// OpenCV trains on this many of binpose's Poisson-disk model points. Its training walks each
  /// hash chain on every insert, quadratic in the pairs sharing a key: with binpose's 4000 points
  /// it ran past 12 minutes on the cap, with 1000 it takes 10-70 s.
  int model_points = 1000;
};

OpencvSettings opencvSettings(const std::string& method, std::size_t instances) {
  OpencvSettings s;
  if (method == "opencv-tuned") {  // for bins of many parts: 4 x the reference points, each result refined
    s.scene_sample = 1.0 / 10.0;
    s.icp_top = static_cast<int>(instances);
  }
  return s;
}

/// OpenCV's PPF detector; its answer is its `instances` best-voted poses (it has no threshold
/// of its own, so it is told how many parts there are: an advantage binpose does not get).
Outcome runOpencv(const OrientedModel& model, const PointCloud& scan, const OpencvSettings& s, std::size_t instances,
                  int repeats) {
  Outcome out;
  const cv::Mat model_pc = toMat(model.points, model.normals);
  cv::ppf_match_3d::PPF3DDetector detector(s.sampling, s.distance);
  const auto t0 = Clock::now();
  detector.trainModel(model_pc);
  out.train_ms = msSince(t0);
  const cv::Mat scene_xyz = toMat(scan.points, {});
  for (int r = 0; r < repeats; ++r) {
    const auto t = Clock::now();
    cv::Mat scene_pc;
    cv::ppf_match_3d::computeNormalsPC3d(scene_xyz, scene_pc, 6, true, cv::Vec3f(0, 0, 0));  // facing the sensor
    std::vector<cv::ppf_match_3d::Pose3DPtr> results;
    detector.match(scene_pc, results, s.scene_sample, s.scene_distance);
    const std::size_t keep = std::min(results.size(), std::max<std::size_t>(instances, s.icp_top));
    std::vector<cv::ppf_match_3d::Pose3DPtr> top(results.begin(), results.begin() + static_cast<long>(keep));
    std::vector<cv::ppf_match_3d::Pose3DPtr> refined(top.begin(), top.begin() + std::min<long>(s.icp_top, long(keep)));
    if (!refined.empty()) {
      cv::ppf_match_3d::ICP icp(s.icp_iterations, s.icp_tolerance, s.icp_rejection, s.icp_levels);
      icp.registerModelToScene(model_pc, scene_pc, refined);
    }
    out.detect_ms.push_back(msSince(t));
    if (r > 0) continue;
    for (std::size_t i = 0; i < std::min(top.size(), instances); ++i) {
      Eigen::Matrix4f T;
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) T(a, b) = static_cast<float>(top[i]->pose(a, b));
      Pose p = Pose::Identity();
      p.matrix() = T;
      out.poses.push_back(p);
    }
  }
  return out;
}

long residentKiB() {
  std::ifstream in("/proc/self/statm");
  long size = 0, resident = 0;
  in >> size >> resident;
  return resident * (sysconf(_SC_PAGESIZE) / 1024);
}

/// Child mode: one method on one input, its result as one JSON line on stdout.
int runOne(const Options& o) {
  const auto spec = std::find_if(inputSpecs().begin(), inputSpecs().end(), [&](auto& s) { return s.name == o.run_input; });
  if (spec == inputSpecs().end()) throw Error(fmt::format("unknown input '{}'", o.run_input));
  const Input in = loadInput(o, *spec);
  const OrientedModel model = orientedModel(in, *spec, o.model_points);  // binpose's; a cloud model's evaluation surface
  const EvalModel eval = in.model.is_mesh ? in.eval : cloudEvalModel(orientedModel(in, *spec));  // the same whatever model_points
  const long baseline = residentKiB();
  const std::size_t instances = in.truth.instances.size();
  Outcome r;
  if (o.run_method == "binpose") r = runBinpose(model, in.scan, "default", o.repeats, o.params);
  else if (o.run_method.starts_with("binpose-")) r = runBinpose(model, in.scan, o.run_method.substr(8), o.repeats, o.params);
  else if (o.run_method.starts_with("opencv")) {
    const OpencvSettings settings = opencvSettings(o.run_method, instances);
    r = runOpencv(orientedModel(in, *spec, settings.model_points), in.scan, settings, instances, o.repeats);
  }
  else throw Error(fmt::format("unknown method '{}'", o.run_method));
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const double ms = median(r.detect_ms);
  const EvaluationReport rep = evaluate(in.truth, r.poses, ms, eval);
  json j = {{"input", o.run_input},
            {"method", o.run_method},
            {"scan_points", in.scan.size()},
            {"instances", instances},
            {"train_ms", r.train_ms},
            {"detect_ms_median", ms},
            {"detect_ms_runs", r.detect_ms},
            {"detections", rep.detections},
            {"found", rep.matched},
            {"ms_per_found", rep.matched > 0 ? ms / rep.matched : 0.0},
            {"recall", rep.recall},
            {"recall_over_half_visible", rep.recall_over_half_visible},
            {"precision", rep.precision},
            {"centroid_mm", rep.mean_centroid_mm},
            {"angle_deg", rep.mean_angle_deg},
            {"peak_rss_mib", static_cast<double>(usage.ru_maxrss) / 1024.0},
            {"peak_above_input_mib", static_cast<double>(std::max(0L, usage.ru_maxrss - baseline)) / 1024.0}};
  // The first run's poses (model -> scan, row-major 3x4, mm): two builds' detections compared row for row.
  json poses = json::array();
  for (const Pose& pose : r.poses) {
    json row = json::array();
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 4; ++k) row.push_back(pose.matrix()(i, k));
    poses.push_back(row);
  }
  j["poses"] = poses;
  j["noise_mm"] = r.noise_mm;
  j["k_normals"] = r.k_normals;
  if (!r.stages.empty()) {  // binpose's stages, each the median over the runs
    const auto stage = [&](double DetectionTiming::*field) {
      std::vector<double> v;
      for (const DetectionTiming& t : r.stages) v.push_back(t.*field);
      return median(v);
    };
    j["stage_ms_median"] = {{"preprocess", stage(&DetectionTiming::preprocess_ms)},
                            {"vote", stage(&DetectionTiming::vote_ms)},
                            {"match", stage(&DetectionTiming::match_ms)},
                            {"refine", stage(&DetectionTiming::refine_ms)}};
  }
  std::fputs((j.dump() + "\n").c_str(), stdout);
  return 0;
}

/// Runs this program with --run INPUT METHOD in a child; its JSON line.
json runChild(const std::string& self, const Options& o, const std::string& input, const std::string& method) {
  int fds[2];
  if (pipe(fds) != 0) throw Error("pipe failed");
  const std::string repeats = std::to_string(o.repeats), offset = std::to_string(o.seed_offset);
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(fds[1], 1);
    close(fds[0]);
    close(fds[1]);
    alarm(static_cast<unsigned>(o.timeout_s));  // kept across exec: a run past it is killed
    std::vector<const char*> args = {self.c_str(), "--data", o.data.c_str(), "--cache", o.cache.c_str(),
                                     "--repeats", repeats.c_str(), "--seed-offset", offset.c_str(),
                                     "--run", input.c_str(), method.c_str()};
    if (!o.params.empty()) args.insert(args.end(), {"--params", o.params.c_str()});
    const std::string model_points = std::to_string(o.model_points);
    args.insert(args.end(), {"--model-points", model_points.c_str()});
    args.push_back(nullptr);
    execv(self.c_str(), const_cast<char* const*>(args.data()));
    _exit(127);
  }
  close(fds[1]);
  std::string text;
  char buf[4096];
  for (ssize_t n; (n = read(fds[0], buf, sizeof buf)) > 0;) text.append(buf, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || text.empty())
    return {{"input", input},
            {"method", method},
            {"error", WIFSIGNALED(status) && WTERMSIG(status) == SIGALRM ? fmt::format("ran past {} s", o.timeout_s)
                                                                       : fmt::format("child failed (status {})", status)}};
  return json::parse(text);
}

std::string pct(double v) { return fmt::format("{:.0f}%", 100 * v); }

void printTable(const json& rows) {
  fmt::print("{:<9} {:<15} {:>7} {:>9} {:>9} {:>8} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}\n", "input", "method", "points",
             "train ms", "detect ms", "ms/obj", "found", "recall", "prec", "c mm", "ang deg", "MiB");
  for (const json& r : rows) {
    if (r.contains("error")) {
      fmt::print("{:<9} {:<15} {}\n", r["input"].get<std::string>(), r["method"].get<std::string>(), r["error"].get<std::string>());
      continue;
    }
    fmt::print("{:<9} {:<15} {:>7} {:>9.0f} {:>9.1f} {:>8.1f} {:>3}/{:<3} {:>7} {:>7} {:>7.2f} {:>7.2f} {:>7.0f}\n",
               r["input"].get<std::string>(), r["method"].get<std::string>(), r["scan_points"].get<long>(),
               r["train_ms"].get<double>(), r["detect_ms_median"].get<double>(), r["ms_per_found"].get<double>(),
               r["found"].get<int>(), r["instances"].get<int>(), pct(r["recall"].get<double>()),
               pct(r["precision"].get<double>()), r["centroid_mm"].get<double>(), r["angle_deg"].get<double>(),
               r["peak_above_input_mib"].get<double>());
  }
}

/// binpose / OpenCV ratios per input: speed-up of detection and recall of each.
json ratios(const json& rows) {
  json out = json::array();
  for (const json& b : rows) {
    if (b.contains("error") || b["method"] != "binpose") continue;
    for (const json& c : rows) {
      if (c.contains("error") || c["input"] != b["input"] || !c["method"].get<std::string>().starts_with("opencv")) continue;
      out.push_back({{"input", b["input"]},
                     {"peer", c["method"]},
                     {"speedup", c["detect_ms_median"].get<double>() / b["detect_ms_median"].get<double>()},
                     {"train_speedup", c["train_ms"].get<double>() / b["train_ms"].get<double>()},
                     {"recall_binpose", b["recall"]},
                     {"recall_peer", c["recall"]}});
    }
  }
  return out;
}

std::string machine() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.starts_with("model name")) return line.substr(line.find(':') + 2);
  return "unknown";
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"binpose end-to-end benchmark against OpenCV's PPF detector"};
  app.add_option("--data", o.data, "The shared data folder")->capture_default_str();
  app.add_option("--cache", o.cache, "Folder of the simulated bins (made once)")->capture_default_str();
  app.add_option("--out", o.out, "JSON file of the results")->capture_default_str();
  app.add_option("--repeats", o.repeats, "Detection runs per input and method (median)")->capture_default_str()->check(CLI::Range(1, 100));
  app.add_option("--inputs", o.inputs, "Inputs to run (default: all)")->delimiter(',');
  app.add_option("--methods", o.methods, "Methods to run")->delimiter(',')->capture_default_str();
  app.add_option("--timeout", o.timeout_s, "Seconds allowed per input and method")->capture_default_str();
  app.add_option("--seed-offset", o.seed_offset, "Added to the simulated bins' seeds (other bins, in CACHE/NAME-seedN)")
      ->capture_default_str();
  app.add_option("--params", o.params,
                 "JSON file of binpose parameter overrides, in the thesis's units (60 mm part), applied before scaling");
  std::vector<std::string> run;
  app.add_option("--model-points", o.model_points, "Points of binpose's model database (0: the input's default)")
      ->capture_default_str()
      ->check(CLI::Range(0, 65535));
  app.add_option("--run", run, "Child mode: INPUT METHOD")->expected(2);
  CLI11_PARSE(app, argc, argv);
  try {
    if (!run.empty()) {
      o.run_input = run[0];
      o.run_method = run[1];
      return runOne(o);
    }
    json rows = json::array();
    for (const InputSpec& s : inputSpecs()) {
      if (!o.inputs.empty() && std::find(o.inputs.begin(), o.inputs.end(), s.name) == o.inputs.end()) continue;
      if (s.instances > 0) ensureScene(o, s);
      else if (!fs::exists(o.data + "/" + s.model)) {
        fmt::print(stderr, "{}: {} missing, skipped\n", s.name, s.model);
        continue;
      }
      for (const std::string& m : o.methods) {
        fmt::print(stderr, "running {} on {}...\n", m, s.name);
        rows.push_back(runChild("/proc/self/exe", o, s.name, m));
        printTable(json::array({rows.back()}));
      }
    }
    fmt::print("\n");
    printTable(rows);
    const json report = {{"machine", machine()},
                         {"threads", std::thread::hardware_concurrency()},
                         {"repeats", o.repeats},
                         {"seed_offset", o.seed_offset},
                         {"rows", rows},
                         {"ratios", ratios(rows)}};
    for (const json& r : report["ratios"])
      fmt::print("{:<9} binpose vs {:<13}: {:6.1f}x faster detection, recall {} vs {}\n", r["input"].get<std::string>(),
                 r["peer"].get<std::string>(), r["speedup"].get<double>(), pct(r["recall_binpose"].get<double>()),
                 pct(r["recall_peer"].get<double>()));
    if (!o.out.empty()) {
      std::ofstream(o.out) << report.dump(2) << "\n";
      fmt::print("results: {}\n", o.out);
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
