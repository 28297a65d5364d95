// Parameter sweeps over simulated bins (thesis 7.2-7.4).
#include <binpose/sweep.hpp>

#include <binpose/detector.hpp>
#include <binpose/io.hpp>
#include <binpose/model_database.hpp>
#include <binpose/shapes.hpp>

#include <Eigen/QR>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <optional>
#include <algorithm>

namespace binpose {
namespace {

/// Every combination of the grid's values (the cartesian product), in a fixed order.
std::vector<std::map<std::string, double>> combinations(const SweepGrid& grid) {
  std::vector<std::map<std::string, double>> out{{}};
  for (const auto& [name, values] : grid) {
    std::vector<std::map<std::string, double>> next;
    for (const auto& partial : out)
      for (const double v : values) {
        auto c = partial;
        c[name] = v;
        next.push_back(std::move(c));
      }
    out = std::move(next);
  }
  return out;
}

void apply(DetectionParams& p, const std::map<std::string, double>& combo) {
  for (const auto& [name, v] : combo) {
    if (name == "r") p.r = float(v);
    else if (name == "rho_sub") p.rho_sub = float(v);
    else if (name == "eta") p.eta = float(v);
    else if (name == "e_gmax") p.e_gmax = float(v);
    else if (name == "C_n") p.C_n = static_cast<int>(v);
    else if (name != "d_dist" && name != "p_d") throw Error(fmt::format("cannot sweep '{}'", name));
  }
}

}  // namespace

std::vector<SweepRow> runSweep(const SweepSettings& s, const SweepGrid& grid, const std::function<void(int, int)>& progress) {
  if (s.scenes < 1 || s.out.empty()) throw Error("a sweep needs at least one scene and an output folder");
  const ModelFile file = readModelOrBuiltin(s.model);
  if (!file.is_mesh) throw Error(fmt::format("{}: a sweep simulates bins and needs a mesh", s.model));
  const Mesh& mesh = file.mesh;
  std::filesystem::create_directories(s.out);
  // Scenes: simulated once, reused by every combination (and by a later run).
  std::vector<std::string> dirs;
  for (int i = 0; i < s.scenes; ++i) {
    const std::string dir = fmt::format("{}/scenes/{:03d}", s.out, i);
    if (!std::filesystem::exists(dir + "/ground_truth.json")) {
      const std::uint64_t seed = s.seed + static_cast<std::uint64_t>(i);
      if (s.thesis_style) {
        ThesisSceneParams thesis = s.thesis;
        thesis.instances = s.instances;
        thesis.seed = seed;
        writeScene(dir, simulateThesisScene(mesh, thesis), s.model, defaultModelInfo(s.model, mesh));
      } else {
        SimulationParams sim = s.simulation;
        sim.instances = s.instances;
        sim.seed = seed;
        writeScene(dir, simulateBin(mesh, sim), s.model, defaultModelInfo(s.model, mesh));
      }
    }
    dirs.push_back(dir);
  }
  const auto combos = combinations(grid);
  const int total = static_cast<int>(combos.size()) * s.scenes;
  std::vector<SweepRow> rows;
  std::map<std::pair<double, double>, ModelDatabase> databases;  // by (d_dist, p_d)
  ModelParams mp;
  const OrientedModel model = prepareModel(mesh, mp);
  const EvalModel eval_model = makeEvalModel(mesh, readSymmetries(dirs.front() + "/models_info.json", "1"));
  int done = 0;
  for (const auto& combo : combos) {
    QuantizationParams q = defaultQuantization(model.diameter);
    if (combo.count("d_dist")) q.d_dist = float(combo.at("d_dist"));
    if (combo.count("p_d")) q.overlap = float(combo.at("p_d"));
    const auto key = std::make_pair(double(q.d_dist), double(q.overlap));
    if (!databases.count(key)) databases.emplace(key, ModelDatabase::build(model, q));
    const ModelDatabase& db = databases.at(key);
    DetectionParams p = scaledToModel(presetByName(s.preset), model.diameter);
    apply(p, combo);
    const Detector detector(db, p);
    for (int i = 0; i < s.scenes; ++i) {
      const PointCloud scan = readPlyCloud(dirs[i] + "/scene.ply");
      const DetectionResult result = detector.detect(scan);
      std::vector<Pose> poses;
      for (const auto& d : result.detections) poses.push_back(d.pose);
      rows.push_back({combo, i, evaluate(readGroundTruth(dirs[i]), poses, result.timing.total_ms, eval_model)});
      progress(++done, total);
    }
  }
  // results.csv: one line per run; instances.csv: one line per ground-truth instance and run.
  std::ofstream results(s.out + "/results.csv"), instances(s.out + "/instances.csv");
  std::string header;
  for (const auto& [name, values] : grid) header += name + ",";
  results << header << "scene,instances,detections,found,recall,precision,recall_visib_over_half,centroid_mm,angle_deg,add_s_mm,mssd_mm,total_ms,ms_per_object\n";
  instances << header << "scene,instance,visible_fraction,visib_fract,found,centroid_mm,angle_deg\n";
  for (const SweepRow& row : rows) {
    std::string values;
    for (const auto& [name, v] : row.params) values += fmt::format("{},", v);
    const EvaluationReport& r = row.report;
    results << values << fmt::format("{},{},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.2f},{:.2f}\n", row.scene,
                                     r.instances.size(), r.detections, r.matched, r.recall, r.precision,
                                     r.recall_over_half_visible, r.mean_centroid_mm, r.mean_angle_deg, r.mean_add_s_mm,
                                     r.mean_mssd_mm, r.total_ms, r.ms_per_object);
    for (const InstanceResult& inst : r.instances)
      instances << values << fmt::format("{},{},{:.4f},{:.4f},{},{:.4f},{:.4f}\n", row.scene, inst.truth, inst.visible_fraction,
                                         inst.visib_fract, inst.detection >= 0 ? 1 : 0, inst.errors.centroid_mm,
                                         inst.errors.angle_deg);
  }
  if (!results || !instances) throw Error(fmt::format("{}: cannot write the sweep's CSV files", s.out));
  return rows;
}

namespace {

/// One combination's sums over its scenes.
struct Sum {
  int runs = 0, found = 0;
  double recall = 0, precision = 0, centroid = 0, angle = 0, ms = 0;
};

/// The sums by combination, and the recognition rate's polynomial fit when there is one.
struct Summaries {
  std::map<std::vector<double>, Sum> sums;
  std::optional<Eigen::Vector4d> fit;
};

/// The thesis's polynomial fit of recognition rate (%) against visible surface (Figures 34 and
/// 38), of third order in u = visible % / 100, weighted by each bin's count: the 10 % bins give at
/// most six points, which its fifth order would only interpolate. None under five bins.
std::optional<Eigen::Vector4d> recognitionFit(const std::vector<int>& total, const std::vector<int>& found) {
  std::vector<int> bins;
  for (std::size_t b = 0; b < total.size(); ++b)
    if (total[b] > 0) bins.push_back(static_cast<int>(b));
  if (bins.size() < 5) return std::nullopt;
  Eigen::MatrixXd A(bins.size(), 4);
  Eigen::VectorXd y(bins.size());
  for (std::size_t i = 0; i < bins.size(); ++i) {
    const double u = (10.0 * bins[i] + 5.0) / 100.0, w = std::sqrt(double(total[std::size_t(bins[i])]));
    A.row(Eigen::Index(i)) << w, w * u, w * u * u, w * u * u * u;
    y(Eigen::Index(i)) = w * 100.0 * found[std::size_t(bins[i])] / total[std::size_t(bins[i])];
  }
  return Eigen::Vector4d(A.colPivHouseholderQr().solve(y));
}

/// Writes summary.csv (the means over the scenes of each combination; time per object pooled)
/// and recognition.csv (recognition rate in 10 % bins of visible surface).
Summaries writeSummaries(const std::string& out, const std::vector<SweepRow>& rows, const std::vector<std::string>& names) {
  // summary.csv: means over the scenes of each combination (time per object pooled).
  std::map<std::vector<double>, Sum> sums;
  std::vector<int> bin_total(10, 0), bin_found(10, 0);
  for (const SweepRow& row : rows) {
    std::vector<double> key;
    for (const auto& n : names) key.push_back(row.params.at(n));
    Sum& sum = sums[key];
    const EvaluationReport& r = row.report;
    ++sum.runs;
    sum.found += r.matched;
    sum.recall += r.recall;
    sum.precision += r.precision;
    sum.centroid += r.mean_centroid_mm * r.matched;
    sum.angle += r.mean_angle_deg * r.matched;
    sum.ms += r.total_ms;
    for (int b = 0; b < 10; ++b) {
      bin_total[b] += r.visible_bin_total[b];
      bin_found[b] += r.visible_bin_found[b];
    }
  }
  std::ofstream summary(out + "/summary.csv");
  for (const auto& n : names) summary << n << ",";
  summary << "runs,recall,precision,centroid_mm,angle_deg,ms_per_object\n";
  for (const auto& [key, sum] : sums) {
    for (const double v : key) summary << v << ",";
    const double found = std::max(1, sum.found);
    summary << fmt::format("{},{:.4f},{:.4f},{:.4f},{:.4f},{:.2f}\n", sum.runs, sum.recall / sum.runs, sum.precision / sum.runs,
                           sum.centroid / found, sum.angle / found, sum.ms / found);
  }
  std::ofstream recognition(out + "/recognition.csv");
  recognition << "visible_percent,instances,found,rate_percent\n";
  for (int b = 0; b < 10; ++b)
    if (bin_total[b] > 0)
      recognition << fmt::format("{},{},{},{:.2f}\n", 10 * b + 5, bin_total[b], bin_found[b], 100.0 * bin_found[b] / bin_total[b]);
  summary.close();
  recognition.close();
  return {std::move(sums), recognitionFit(bin_total, bin_found)};
}

}  // namespace

std::vector<std::string> plotSweep(const std::string& out, const std::vector<SweepRow>& rows,
                                   const std::vector<std::string>& names) {
  if (names.empty() || rows.empty()) return {};
  const Summaries summaries = writeSummaries(out, rows, names);
  const std::map<std::vector<double>, Sum>& sums = summaries.sums;

  // plots.gp: each metric against the first parameter, one curve per value of the second.
  std::ofstream gp(out + "/plots.gp");
  gp << "set terminal pngcairo size 800,560 noenhanced\nset grid\nset key outside right\n";
  const int nparams = static_cast<int>(names.size());
  // plot.dat: one block per value of the second parameter (gnuplot's `index`), rows by the first.
  std::map<double, std::vector<std::pair<std::vector<double>, const Sum*>>> blocks;
  for (const auto& [key, sum] : sums) blocks[nparams > 1 ? key[1] : 0.0].push_back({key, &sum});
  std::ofstream dat(out + "/plot.dat");
  std::string series_values;
  for (const auto& [series, block] : blocks) {
    series_values += fmt::format("{} ", series);
    for (const auto& [key, sum] : block) {
      const double found = std::max(1, sum->found);
      dat << fmt::format("{} {} {} {} {} {}\n", key[0], sum->recall / sum->runs, sum->precision / sum->runs,
                         sum->centroid / found, sum->angle / found, sum->ms / found);
    }
    dat << "\n\n";
  }
  dat.close();
  std::vector<std::string> pngs;
  const std::vector<std::pair<std::string, std::string>> metrics{
      {"centroid_mm", "centroid error (mm)"}, {"angle_deg", "angular error (deg)"}, {"ms_per_object", "time per object (ms)"},
      {"recall", "recall"}};
  const std::map<std::string, int> column{{"recall", 2}, {"precision", 3}, {"centroid_mm", 4}, {"angle_deg", 5}, {"ms_per_object", 6}};
  const int n_blocks = static_cast<int>(blocks.size());
  for (const auto& [metric, label] : metrics) {
    const std::string png = fmt::format("{}/{}_vs_{}.png", out, metric, names[0]);
    const int c = column.at(metric);
    gp << fmt::format("set output '{}'\nset xlabel '{}'\nset ylabel '{}'\nset title '{} against {}'\nset autoscale y\n", png,
                      names[0], label, label, names[0]);
    if (nparams > 1)
      gp << fmt::format("plot for [i=0:{}] '{}/plot.dat' index i using 1:{} with linespoints title '{} = '.word(\"{}\", i + 1)\n",
                        n_blocks - 1, out, c, names[1], series_values);
    else
      gp << fmt::format("plot '{}/plot.dat' index 0 using 1:{} with linespoints title '{}'\n", out, c, metric);
    pngs.push_back(png);
  }
  const std::string png = fmt::format("{}/recognition_vs_visible_surface.png", out);
  gp << fmt::format("set output '{}'\nset xlabel 'visible surface (% of the whole surface)'\nset ylabel 'recognition rate (%)'\n"
                    "set title 'recognition rate against visible surface (all runs)'\nset yrange [0:105]\n"
                    "set datafile separator ','\nplot '{}/recognition.csv' skip 1 using 1:4 with linespoints title 'recognised'",
                    png, out);
  if (summaries.fit)  // the thesis's polynomial fit (Figures 34 and 38), in u = visible % / 100
    gp << fmt::format(", ({}) + ({})*(x/100) + ({})*(x/100)**2 + ({})*(x/100)**3 title 'third-order fit'", (*summaries.fit)[0],
                      (*summaries.fit)[1], (*summaries.fit)[2], (*summaries.fit)[3]);
  gp << "\n";
  pngs.push_back(png);
  gp.close();
  if (std::system("command -v gnuplot > /dev/null 2>&1") != 0) return {};
  if (std::system(fmt::format("gnuplot '{}/plots.gp' 2> '{}/plots.log'", out, out).c_str()) != 0)
    throw Error(fmt::format("{}/plots.gp: gnuplot failed (see plots.log)", out));
  return pngs;
}

}  // namespace binpose
