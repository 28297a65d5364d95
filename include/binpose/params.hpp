#pragma once
// What a user sets for online recognition (thesis chapters 4-5). Distance-like values are for
// the thesis's 60 mm part (tau_object); scaledToModel() scales them by (model diameter / 60 mm),
// and an explicit user value replaces the scaled one. Every other value of the stages is
// internal (src/stage_settings.hpp) and follows the pipeline chosen here.
#include <binpose/types.hpp>

#include <cstdint>
#include <string>

namespace binpose {

/// Which recipe the stages follow.
enum class Pipeline {
  Binpose,  ///< binpose's: even sub-sampling, the bin's planes out of the votes, local votes with
            ///< several candidates, noise adaptation, verification-driven removal (docs/design.md)
  Thesis,   ///< chapter 5 as written: random sub-sampling, one candidate per point voting in each
            ///< sub-group, every detection removes its points
};

/// The user's values; defaults are binpose's recommended settings (the `default` preset).
struct DetectionParams {
  Pipeline pipeline = Pipeline::Binpose;

  // --- the thesis's symbols ---------------------------------------------------------------
  float rho_sub = 0.06f;   ///< rho_sub: scene density after sub-sampling, points/mm^2 (5.2.1)
  int k_normals = 8;       ///< k: neighbours of a scene normal's plane fit (5.2.2; the thesis: 6)
  float r = 25.0f;         ///< r: sampling radius of a sub-group, mm (5.2.3)
  float eta = 15.0f;       ///< eta: grid spacing of the sub-group centres, mm (5.2.3)
  float e_gmax = 1.5f;     ///< e_gmax: geometric consistency limit, mm (4.5, eq. 15-16)
  int C_n = 6;             ///< C_n: smallest accepted clique (4.5; the thesis: 8)
  float sigma_dist = 6.0f; ///< sigma_dist: removal distance around a found object, mm (5.2.6, eq. 39)

  // --- what is kept ------------------------------------------------------------------------
  bool verify = true;       ///< score each pose by the share of its sensor-facing points the scan supports
  float min_score = 0.15f;  ///< detections scoring less are rejected (verify only), in [0, 1]
  int max_instances = 0;    ///< stop after this many confident detections, report at most this many (0: no limit)
  bool refine = true;       ///< point-to-plane ICP of each pose against the full scan
  bool use_symmetry = true; ///< match a body of revolution or an n-fold symmetric part by its symmetry

  // --- the scan ----------------------------------------------------------------------------
  Vec3 viewpoint = Vec3::Zero();  ///< sensor origin in the scan's frame, mm (normals face it)
  std::uint64_t seed = 1;         ///< seed of every random choice (the thesis's sub-sampling, RANSAC)
};

/// The thesis's pipeline as written (chapter 5): Pipeline::Thesis, k = 6, C_n = 8; no symmetry,
/// no refinement, no verification.
DetectionParams thesisPreset();
/// binpose's recommended settings: DetectionParams{}.
DetectionParams defaultPreset();
/// A preset by name: "default" or "thesis" ("fast", the earlier name of today's default, is
/// still accepted and gives the default).
DetectionParams presetByName(const std::string& name);

/// 60 mm-part values in absolute units for a model of this diameter: r, eta, e_gmax and
/// sigma_dist times s, rho_sub divided by s^2, for s = model_diameter / 60 mm.
DetectionParams scaledToModel(const DetectionParams& params, float model_diameter);

/// Throws binpose::Error naming the first absurd value.
void validate(const DetectionParams& params);

/// Overrides fields from a JSON object (keys as the field names; "pipeline": "binpose"|"thesis",
/// "viewpoint": [x, y, z]); an unknown key or a wrong type is an error.
void applyJson(DetectionParams& params, const std::string& json_text, const std::string& source);
/// applyJson on the text of a file; an unreadable file is an error.
void applyJsonFile(DetectionParams& params, const std::string& path);
/// All fields as a JSON object text.
std::string toJson(const DetectionParams& params);

}  // namespace binpose
