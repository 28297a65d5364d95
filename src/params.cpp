// Detection parameters: presets, scaling to the model, validation, JSON.
#include <binpose/params.hpp>

#include <binpose/model.hpp>

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
  field(j, "r", p.r, write);
  field(j, "rho_sub", p.rho_sub, write);
  field(j, "eta", p.eta, write);
  field(j, "e_gmax", p.e_gmax, write);
  field(j, "C_n", p.C_n, write);
  field(j, "sigma_dist", p.sigma_dist, write);
  field(j, "k_normals", p.k_normals, write);
  field(j, "remove_planes", p.remove_planes, write);
  field(j, "plane_min_area", p.plane_min_area, write);
  field(j, "plane_tolerance", p.plane_tolerance, write);
  field(j, "candidates_per_point", p.candidates_per_point, write);
  field(j, "local_votes", p.local_votes, write);
  field(j, "vote_radius", p.vote_radius, write);
  field(j, "partner_spacing", p.partner_spacing, write);
  field(j, "candidate_spacing", p.candidate_spacing, write);
  field(j, "voter_spacing", p.voter_spacing, write);
  field(j, "retry_all_voters", p.retry_all_voters, write);
  field(j, "retry_min_clique", p.retry_min_clique, write);
  field(j, "retry_min_score", p.retry_min_score, write);
  field(j, "grazing_angle", p.grazing_angle, write);
  field(j, "use_revolution", p.use_revolution, write);
  field(j, "revolution_angle_tolerance", p.revolution_angle_tolerance, write);
  field(j, "revolution_candidates", p.revolution_candidates, write);
  field(j, "refine", p.refine, write);
  field(j, "icp_iterations", p.icp_iterations, write);
  field(j, "icp_model_points", p.icp_model_points, write);
  field(j, "prescreen", p.prescreen, write);
  field(j, "prescreen_retry_steps", p.prescreen_retry_steps, write);
  field(j, "prescreen_retry_share", p.prescreen_retry_share, write);
  field(j, "icp_max_distance", p.icp_max_distance, write);
  field(j, "verify", p.verify, write);
  field(j, "verify_tolerance", p.verify_tolerance, write);
  field(j, "min_score", p.min_score, write);
  field(j, "removal_score", p.removal_score, write);
  field(j, "explain_score", p.explain_score, write);
  field(j, "tried_share", p.tried_share, write);
  field(j, "refound_share", p.refound_share, write);
  field(j, "max_instances", p.max_instances, write);
  field(j, "clique_work_limit", p.clique_work_limit, write);
  field(j, "mirror_retries", p.mirror_retries, write);
  field(j, "use_cyclic_symmetry", p.use_cyclic_symmetry, write);
  field(j, "seed", p.seed, write);
  field(j, "adapt_to_noise", p.adapt_to_noise, write);
  if (write) {
    j["subsampling"] = p.subsampling == Subsampling::Random ? "random" : "voxel";
    j["viewpoint"] = {p.viewpoint.x(), p.viewpoint.y(), p.viewpoint.z()};
    return;
  }
  if (j.contains("subsampling")) {
    const std::string s = j.at("subsampling").get<std::string>();
    if (s != "random" && s != "voxel") throw Error(fmt::format("subsampling must be 'random' or 'voxel', got '{}'", s));
    p.subsampling = s == "random" ? Subsampling::Random : Subsampling::Voxel;
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

void nonNegative(float v, const char* name, const char* unit) {
  if (!(v >= 0) || !std::isfinite(v)) throw Error(fmt::format("{} must be >= 0 {}, got {}", name, unit, v));
}

}  // namespace

DetectionParams thesisPreset() {
  DetectionParams p;
  p.subsampling = Subsampling::Random;
  p.k_normals = 6;
  p.adapt_to_noise = false;
  p.remove_planes = false;
  p.candidates_per_point = 1;
  p.candidate_spacing = 0.0f;
  p.local_votes = false;
  p.voter_spacing = 0.0f;
  p.partner_spacing = 0.0f;
  p.retry_all_voters = false;
  p.C_n = 8;
  p.mirror_retries = 0;
  p.use_revolution = false;
  p.use_cyclic_symmetry = false;
  p.verify = false;
  p.prescreen = false;
  p.prescreen_retry_steps = 0;
  p.refine = false;
  p.removal_score = 0.0f;
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
  p.vote_radius *= s;
  p.voter_spacing *= s;
  p.partner_spacing *= s;
  p.candidate_spacing *= s;
  p.plane_min_area *= s * s;
  p.plane_tolerance *= s;
  p.eta *= s;
  p.e_gmax *= s;
  p.sigma_dist *= s;
  p.icp_max_distance *= s;
  p.verify_tolerance *= s;
  p.rho_sub /= s * s;
  return p;
}

void validate(const DetectionParams& p) {
  positive(p.r, "r (sampling radius)", "length in mm");
  positive(p.rho_sub, "rho_sub", "density in points/mm^2");
  positive(p.eta, "eta (grid spacing)", "length in mm");
  positive(p.vote_radius, "vote_radius", "length in mm");
  nonNegative(p.plane_min_area, "plane_min_area", "mm^2 (0: from the model)");
  positive(p.plane_tolerance, "plane_tolerance", "distance in mm");
  nonNegative(p.candidate_spacing, "candidate_spacing", "mm");
  nonNegative(p.partner_spacing, "partner_spacing", "mm");
  nonNegative(p.voter_spacing, "voter_spacing", "mm");
  positive(p.e_gmax, "e_gmax", "length in mm");
  positive(p.sigma_dist, "sigma_dist", "length in mm");
  positive(p.icp_max_distance, "icp_max_distance", "length in mm");
  positive(p.verify_tolerance, "verify_tolerance", "length in mm");
  if (p.C_n < 3) throw Error(fmt::format("C_n must be >= 3 (a pose needs 3 correspondences), got {}", p.C_n));
  if (p.k_normals < 3 || p.k_normals > 200) throw Error(fmt::format("k_normals must lie in [3, 200], got {}", p.k_normals));
  if (p.icp_model_points < 0) throw Error(fmt::format("icp_model_points must be >= 0, got {}", p.icp_model_points));
  if (p.icp_iterations < 0 || p.icp_iterations > 1000) throw Error(fmt::format("icp_iterations must lie in [0, 1000], got {}", p.icp_iterations));
  if (!(p.min_score >= 0 && p.min_score <= 1)) throw Error(fmt::format("min_score must lie in [0, 1], got {}", p.min_score));
  if (!(p.removal_score >= 0 && p.removal_score <= 1)) throw Error(fmt::format("removal_score must lie in [0, 1], got {}", p.removal_score));
  if (!(p.explain_score >= 0 && p.explain_score <= 1)) throw Error(fmt::format("explain_score must lie in [0, 1], got {}", p.explain_score));
  if (!(p.retry_min_score >= 0 && p.retry_min_score <= 1))
    throw Error(fmt::format("retry_min_score must lie in [0, 1], got {}", p.retry_min_score));
  if (p.retry_min_clique < 0) throw Error(fmt::format("retry_min_clique must be >= 0, got {}", p.retry_min_clique));
  if (!(p.grazing_angle > 0 && p.grazing_angle <= 90))
    throw Error(fmt::format("grazing_angle must lie in (0, 90] degrees, got {}", p.grazing_angle));
  if (!(p.tried_share >= 0 && p.tried_share <= 1)) throw Error(fmt::format("tried_share must lie in [0, 1], got {}", p.tried_share));
  if (!(p.refound_share >= 0 && p.refound_share <= 1)) throw Error(fmt::format("refound_share must lie in [0, 1], got {}", p.refound_share));
  if (p.prescreen_retry_steps < 0 || p.prescreen_retry_steps > 20)
    throw Error(fmt::format("prescreen_retry_steps must lie in [0, 20], got {}", p.prescreen_retry_steps));
  if (!(p.prescreen_retry_share >= 0 && p.prescreen_retry_share <= 1))
    throw Error(fmt::format("prescreen_retry_share must lie in [0, 1], got {}", p.prescreen_retry_share));
  if (p.candidates_per_point < 1 || p.candidates_per_point > 64)
    throw Error(fmt::format("candidates_per_point must lie in [1, 64], got {}", p.candidates_per_point));
  if (p.max_instances < 0) throw Error(fmt::format("max_instances must be >= 0, got {}", p.max_instances));
  if (p.clique_work_limit < 1) throw Error("clique_work_limit must be >= 1");
  if (p.mirror_retries < 0 || p.mirror_retries > 10)
    throw Error(fmt::format("mirror_retries must lie in [0, 10], got {}", p.mirror_retries));
  if (p.revolution_candidates < 1 || p.revolution_candidates > 64)
    throw Error(fmt::format("revolution_candidates must lie in [1, 64], got {}", p.revolution_candidates));
  if (!(p.revolution_angle_tolerance > 0 && p.revolution_angle_tolerance < 90))
    throw Error(fmt::format("revolution_angle_tolerance must lie in (0, 90) degrees, got {}", p.revolution_angle_tolerance));
  if (!p.viewpoint.allFinite()) throw Error("viewpoint must be finite");
  if (p.eta < 0.01f * p.r) throw Error(fmt::format("eta {} mm is absurdly small for r {} mm", p.eta, p.r));
}

void applyJson(DetectionParams& params, const std::string& json_text, const std::string& source) {
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
