#pragma once
// Parameter sweeps over simulated bins (thesis 7.2-7.4, Tables 1-7).
#include <binpose/evaluation.hpp>
#include <binpose/params.hpp>
#include <binpose/thesis_scene.hpp>

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace binpose {

/// Values to try for each swept parameter, by name: r, rho_sub, eta, e_gmax, C_n (absolute,
/// mm), and the database's d_dist (mm) and p_d. Unswept parameters keep the preset's values.
using SweepGrid = std::map<std::string, std::vector<double>>;

struct SweepSettings {
  std::string model = "builtin:cap";  ///< mesh path or builtin:NAME
  std::string preset = "default";
  int scenes = 10;
  int instances = 16;
  std::uint64_t seed = 1;
  SimulationParams simulation;
  bool thesis_style = false;  ///< thesis-style scenes (thesis_scene.hpp) instead of physics bins
  ThesisSceneParams thesis;   ///< their parameters (instances and seed from above)
  std::string out;  ///< folder: scenes/, results.csv, instances.csv, plots
};

/// One row per (parameter combination, scene).
struct SweepRow {
  std::map<std::string, double> params;
  int scene = 0;
  EvaluationReport report;
};

/// Simulates the scenes (kept in out/scenes/NNN and reused when present), trains one database per
/// (d_dist, p_d), detects and evaluates every combination on every scene. `progress(done, total)`
/// is called after each run. Writes out/results.csv and out/instances.csv.
std::vector<SweepRow> runSweep(const SweepSettings& settings, const SweepGrid& grid,
                               const std::function<void(int, int)>& progress);

/// Writes out/summary.csv (means per combination), out/recognition.csv (recognition rate in 10%
/// bins of visible surface) and out/plots.gp (the thesis's figures: centroid error, angular error,
/// time per object and recall against names[0], a curve per value of names[1]; recognition rate
/// against visible surface), and runs gnuplot on it when installed. Returns the PNGs made.
std::vector<std::string> plotSweep(const std::string& out, const std::vector<SweepRow>& rows,
                                   const std::vector<std::string>& names);

}  // namespace binpose
