// binpose command-line front end.
#include <binpose/io.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/shapes.hpp>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>
#include <string_view>

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr std::string_view kBuiltin = "builtin:";

/// A model file, or a built-in part named "builtin:NAME" (mm).
binpose::ModelFile loadModel(const std::string& spec, double scale) {
  if (spec.rfind(kBuiltin, 0) != 0) return binpose::readModelFile(spec, scale);
  binpose::ModelFile file;
  file.is_mesh = true;
  file.mesh = binpose::builtinPart(spec.substr(kBuiltin.size()));
  return file;
}

struct TrainOptions {
  std::string model, out, units = "mm";
  int points = 4000;
  double rho_model = 0;
  std::optional<double> d_dist, d_angle_deg, overlap;
  std::uint64_t seed = 1;
};

void addTrain(CLI::App& app, TrainOptions& o) {
  CLI::App* train = app.add_subcommand("train", "Build a model's feature database (thesis ch. 4.2 and 6)");
  train->add_option("--model", o.model, "Model: mesh (PLY/STL/OBJ), point cloud (PLY/PCD), or builtin:cap|sphere|box")
      ->required();
  train->add_option("--out", o.out, "Database file to write")->required();
  train->add_option("--points", o.points, "Model points n_M after Poisson-disk sampling")->capture_default_str();
  train->add_option("--rho-model", o.rho_model, "Model density rho_model, points/mm^2 (overrides --points; meshes only)");
  train->add_option("--d-dist", o.d_dist, "Distance step d_dist, mm (default: 1 mm x diameter/60 mm)");
  train->add_option("--d-angle", o.d_angle_deg, "Angle step d_angle, degrees (default 8)");
  train->add_option("--overlap", o.overlap, "Bin overlap p_d, fraction of a step in [0, 0.5) (default 0.15)");
  train->add_option("--units", o.units, "Length unit of the model file: mm or m")->check(CLI::IsMember({"mm", "m"}))->capture_default_str();
  train->add_option("--seed", o.seed, "Sampling seed")->capture_default_str();
}

int runTrain(const TrainOptions& o) {
  const auto t0 = Clock::now();
  const double scale = binpose::unitScale(binpose::parseUnits(o.units));
  binpose::ModelParams params;
  params.num_points = o.points;
  params.rho_model = o.rho_model;
  params.seed = o.seed;
  const binpose::ModelFile file = loadModel(o.model, scale);
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"binpose: find every copy of a rigid part in a 3D scan and its 6D pose"};
  app.require_subcommand(1);
  TrainOptions train;
  addTrain(app, train);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (app.got_subcommand("train")) return runTrain(train);
  } catch (const binpose::Error& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
