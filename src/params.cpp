// The user's detection parameters: presets, scaling to the model, validation, JSON.
#include <binpose/params.hpp>

#include <binpose/model.hpp>

#include "io_detail.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <sstream>
#include <nlohmann/json.hpp>

namespace binpose {
namespace {

using nlohmann::json;

template <typename T>
void field(json& j, const char* key, T& value, bool write) {
  if (write) j[key] = value;
  else if (j.contains(key)) value = j.at(key).get<T>();
}

/// One list of every field, for reading and writing alike.
void visit(json& j, DetectionParams& p, bool write) {
  field(j, "rho_sub", p.rho_sub, write);
  field(j, "k_normals", p.k_normals, write);
  field(j, "r", p.r, write);
  field(j, "eta", p.eta, write);
  field(j, "e_gmax", p.e_gmax, write);
  field(j, "C_n", p.C_n, write);
  field(j, "sigma_dist", p.sigma_dist, write);
  field(j, "verify", p.verify, write);
  field(j, "min_score", p.min_score, write);
  field(j, "max_instances", p.max_instances, write);
  field(j, "refine", p.refine, write);
  field(j, "use_symmetry", p.use_symmetry, write);
  field(j, "seed", p.seed, write);
  if (write) {
    j["pipeline"] = p.pipeline == Pipeline::Thesis ? "thesis" : "binpose";
    j["viewpoint"] = {p.viewpoint.x(), p.viewpoint.y(), p.viewpoint.z()};
    return;
  }
  if (j.contains("pipeline")) {
    const std::string s = j.at("pipeline").get<std::string>();
    if (s != "binpose" && s != "thesis") throw Error(fmt::format("pipeline must be 'binpose' or 'thesis', got '{}'", s));
    p.pipeline = s == "thesis" ? Pipeline::Thesis : Pipeline::Binpose;
  }
  if (j.contains("viewpoint")) {
    const auto v = j.at("viewpoint").get<std::vector<float>>();
    if (v.size() != 3) throw Error("viewpoint must hold 3 numbers");
    p.viewpoint = Vec3(v[0], v[1], v[2]);
  }
}

void positive(float v, const char* name, const char* unit) {
  if (!(v > 0) || !std::isfinite(v)) throw Error(fmt::format("{} must be a positive {}, got {}", name, unit, v));
}

}  // namespace

DetectionParams thesisPreset() {
  DetectionParams p;
  p.pipeline = Pipeline::Thesis;
  p.k_normals = 6;
  p.C_n = 8;
  p.use_symmetry = false;
  p.verify = false;
  p.refine = false;
  return p;
}

DetectionParams defaultPreset() { return DetectionParams{}; }

DetectionParams presetByName(const std::string& name) {
  if (name == "thesis") return thesisPreset();
  if (name == "default" || name == "fast") return defaultPreset();
  throw Error(fmt::format("unknown preset '{}' (known: default, thesis)", name));
}

DetectionParams scaledToModel(const DetectionParams& params, float model_diameter) {
  const float s = thesisScale(model_diameter);
  DetectionParams p = params;
  p.r *= s;
  p.eta *= s;
  p.e_gmax *= s;
  p.sigma_dist *= s;
  p.rho_sub /= s * s;
  return p;
}

void validate(const DetectionParams& p) {
  positive(p.r, "r (sampling radius)", "length in mm");
  positive(p.rho_sub, "rho_sub", "density in points/mm^2");
  positive(p.eta, "eta (grid spacing)", "length in mm");
  positive(p.e_gmax, "e_gmax", "length in mm");
  positive(p.sigma_dist, "sigma_dist", "length in mm");
  if (p.C_n < 3) throw Error(fmt::format("C_n must be >= 3 (a pose needs 3 correspondences), got {}", p.C_n));
  if (p.k_normals < 3 || p.k_normals > 200) throw Error(fmt::format("k_normals must lie in [3, 200], got {}", p.k_normals));
  if (!(p.min_score >= 0 && p.min_score <= 1)) throw Error(fmt::format("min_score must lie in [0, 1], got {}", p.min_score));
  if (p.max_instances < 0) throw Error(fmt::format("max_instances must be >= 0, got {}", p.max_instances));
  if (!p.viewpoint.allFinite()) throw Error("viewpoint must be finite");
  if (p.eta < 0.01f * p.r) throw Error(fmt::format("eta {} mm is absurdly small for r {} mm", p.eta, p.r));
}

void applyJson(DetectionParams& params, const std::string& json_text, const std::string& source) {
  if (detail::jsonDepth(json_text) > detail::kMostJsonDepth)  // refused before the parser recurses
    throw Error(fmt::format("{}: JSON nested too deeply to be a parameter file", source));
  json j = json::parse(json_text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) throw Error(fmt::format("{}: not a JSON object", source));
  json known;
  DetectionParams probe;
  visit(known, probe, true);
  for (const auto& [key, value] : j.items())
    if (!known.contains(key)) throw Error(fmt::format("{}: unknown parameter '{}'", source, key));
  try {
    visit(j, params, false);
  } catch (const json::exception& e) {
    throw Error(fmt::format("{}: wrong type ({})", source, e.what()));
  }
}

void applyJsonFile(DetectionParams& params, const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(fmt::format("{}: cannot open parameter file", path));
  std::stringstream text;
  text << in.rdbuf();
  applyJson(params, text.str(), path);
}

std::string toJson(const DetectionParams& params) {
  json j;
  DetectionParams copy = params;
  visit(j, copy, true);
  return j.dump();
}

}  // namespace binpose
