// BOP datasets: targets, the BOP19 results CSV, and the runner over a split's images.
#include "io_detail.hpp"

#include <binpose/bop.hpp>
#include <binpose/io.hpp>
#include <binpose/model.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

namespace binpose {
namespace {

using detail::fail;

/// A target's field: a whole number in [lo, 10^9].
int field(const std::string& path, const nlohmann::json& entry, const char* key, int lo) {
  if (!entry.contains(key) || !entry[key].is_number_integer() || entry[key].get<long long>() < lo ||
      entry[key].get<long long>() > 1000000000)
    fail(path, fmt::format("target {} has no whole {} of at least {}", entry.dump(), key, lo));
  return entry[key].get<int>();
}

std::vector<std::string_view> splitOn(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  std::size_t at = 0;
  while (true) {
    const std::size_t end = text.find(separator, at);
    parts.push_back(text.substr(at, end == std::string_view::npos ? std::string_view::npos : end - at));
    if (end == std::string_view::npos) return parts;
    at = end + 1;
  }
}

/// `count` numbers separated by spaces, from a CSV field.
std::vector<double> numbers(const std::string& path, std::size_t line, std::string_view text, std::size_t count) {
  std::vector<double> values;
  for (const std::string_view word : detail::splitWords(text)) {
    double v = 0;
    if (!detail::parseNumber(word, v) || !std::isfinite(v)) fail(path, fmt::format("line {}: '{}' is not a number", line, word));
    values.push_back(v);
  }
  if (values.size() != count) fail(path, fmt::format("line {}: {} values where {} belong", line, values.size(), count));
  return values;
}

BopResult parseRow(const std::string& path, std::size_t line, std::string_view text) {
  const auto cells = splitOn(text, ',');
  if (cells.size() != 7) fail(path, fmt::format("line {}: {} fields, not scene_id,im_id,obj_id,score,R,t,time", line, cells.size()));
  BopResult r;
  r.scene_id = static_cast<int>(detail::parseCount(path, cells[0], "scene_id", 1000000000));
  r.im_id = static_cast<int>(detail::parseCount(path, cells[1], "im_id", 1000000000));
  r.obj_id = static_cast<int>(detail::parseCount(path, cells[2], "obj_id", 1000000000));
  r.score = static_cast<float>(numbers(path, line, cells[3], 1)[0]);
  const auto R = numbers(path, line, cells[4], 9), t = numbers(path, line, cells[5], 3);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r.pose.matrix()(i, j) = static_cast<float>(R[std::size_t(3 * i + j)]);
    r.pose.matrix()(i, 3) = static_cast<float>(t[std::size_t(i)]);
  }
  r.time_s = numbers(path, line, cells[6], 1)[0];
  return r;
}

std::string idName(int id) { return fmt::format("{:06}", id); }

/// An object's database (from the cache, else trained on models/obj_XXXXXX.ply and cached) and
/// its detectors, one per instance count asked for (max_instances differs).
struct ObjectDetectors {
  std::unique_ptr<const ModelDatabase> db;
  DetectionParams params;
  std::map<int, std::unique_ptr<const Detector>> by_count;

  const Detector& forCount(int inst_count) {
    auto& d = by_count[inst_count];
    if (!d) {
      DetectionParams p = params;
      p.max_instances = inst_count;
      d = std::make_unique<const Detector>(*db, p);
    }
    return *d;
  }
};

ModelDatabase databaseFor(const BopRun& run, int obj_id) {
  const std::string cached = run.cache + "/obj_" + idName(obj_id) + ".bpdb";
  if (!run.cache.empty() && std::filesystem::exists(cached)) return ModelDatabase::load(cached);
  ModelParams mp;
  mp.num_points = run.model_points;
  const ModelFile file = readModelFile(run.dataset + "/models/obj_" + idName(obj_id) + ".ply");
  OrientedModel model = file.is_mesh ? prepareModel(file.mesh, mp) : prepareModel(file.cloud, mp);
  const QuantizationParams quantization = defaultQuantization(model.diameter);
  ModelDatabase db = ModelDatabase::build(std::move(model), quantization);
  if (!run.cache.empty()) {
    std::filesystem::create_directories(run.cache);
    db.save(cached);
  }
  return db;
}

ObjectDetectors detectorsFor(const BopRun& run, int obj_id) {
  ObjectDetectors o;
  o.db = std::make_unique<const ModelDatabase>(databaseFor(run, obj_id));
  o.params = scaledToModel(presetByName(run.preset), o.db->model().diameter);
  if (!run.params_file.empty()) applyJsonFile(o.params, run.params_file);
  validate(o.params);
  return o;
}

/// The targets of each image, images in the order they first appear.
std::vector<std::vector<BopTarget>> byImage(const std::vector<BopTarget>& targets) {
  std::vector<std::vector<BopTarget>> images;
  std::map<std::pair<int, int>, std::size_t> slot;
  for (const BopTarget& t : targets) {
    const auto [it, added] = slot.try_emplace({t.scene_id, t.im_id}, images.size());
    if (added) images.emplace_back();
    images[it->second].push_back(t);
  }
  return images;
}

/// One image's rows: each target object detected in its depth image, best first.
std::vector<BopResult> detectImage(const BopRun& run, const std::vector<BopTarget>& targets,
                                   std::map<int, ObjectDetectors>& objects) {
  const std::string scene = run.dataset + "/" + run.split + "/" + idName(targets[0].scene_id);
  const Intrinsics camera = readIntrinsics(scene + "/scene_camera.json", std::to_string(targets[0].im_id));
  const PointCloud scan = readDepthPng(scene + "/depth/" + idName(targets[0].im_id) + ".png", camera);
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<BopResult> rows;
  for (const BopTarget& t : targets) {
    for (const Detection& d : objects.at(t.obj_id).forCount(t.inst_count).detect(scan).detections)
      rows.push_back({t.scene_id, t.im_id, t.obj_id, d.score, d.pose, -1.0});
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (BopResult& r : rows) r.time_s = seconds;
  return rows;
}

}  // namespace

std::vector<BopResult> runBop(const BopRun& run, const std::function<void(std::size_t, std::size_t)>& progress) {
  std::vector<BopTarget> targets = readBopTargets(run.targets.empty() ? run.dataset + "/test_targets_bop19.json" : run.targets);
  if (!run.objects.empty())
    std::erase_if(targets, [&](const BopTarget& t) { return std::find(run.objects.begin(), run.objects.end(), t.obj_id) == run.objects.end(); });
  const auto images = byImage(targets);
  std::map<int, ObjectDetectors> objects;  // trained when first needed (training time is not an image's)
  std::vector<BopResult> results;
  for (std::size_t i = 0; i < images.size(); ++i) {
    for (const BopTarget& t : images[i])
      if (!objects.contains(t.obj_id)) objects.emplace(t.obj_id, detectorsFor(run, t.obj_id));
    const auto rows = detectImage(run, images[i], objects);
    results.insert(results.end(), rows.begin(), rows.end());
    if (progress) progress(i + 1, images.size());
  }
  return results;
}

std::vector<BopTarget> readBopTargets(const std::string& path) {
  const std::string text = detail::readFileBytes(path);
  if (detail::jsonDepth(text) > detail::kMostJsonDepth) fail(path, "JSON nested too deeply to be a targets file");
  const auto j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_array()) fail(path, "not a JSON list of targets");
  std::vector<BopTarget> targets;
  for (const auto& entry : j) {
    if (!entry.is_object()) fail(path, "a target is not a JSON object");
    targets.push_back({field(path, entry, "scene_id", 0), field(path, entry, "im_id", 0), field(path, entry, "obj_id", 1),
                       field(path, entry, "inst_count", 1)});
  }
  return targets;
}

void writeBopCsv(const std::string& path, const std::vector<BopResult>& results) {
  std::ofstream out(path);
  if (!out) fail(path, "cannot write results");
  out << "scene_id,im_id,obj_id,score,R,t,time\n";
  for (const BopResult& r : results) {
    const Eigen::Matrix4f T = r.pose.matrix();
    out << fmt::format("{},{},{},{},{} {} {} {} {} {} {} {} {},{} {} {},{}\n", r.scene_id, r.im_id, r.obj_id, r.score,
                       T(0, 0), T(0, 1), T(0, 2), T(1, 0), T(1, 1), T(1, 2), T(2, 0), T(2, 1), T(2, 2), T(0, 3), T(1, 3),
                       T(2, 3), r.time_s);
  }
  if (!out) fail(path, "write failed");
}

std::vector<BopResult> readBopCsv(const std::string& path) {
  std::istringstream in(detail::readFileBytes(path));
  std::vector<BopResult> results;
  std::string text;
  for (std::size_t line = 1; std::getline(in, text); ++line) {
    if (!text.empty() && text.back() == '\r') text.pop_back();
    if (text.empty() || (line == 1 && text.rfind("scene_id", 0) == 0)) continue;
    results.push_back(parseRow(path, line, text));
  }
  return results;
}

}  // namespace binpose
