#pragma once
// The model's feature database (thesis 4.2 "Data Structure Storage", chapter 6): for every
// quantized directed feature key, the model points m_i of the pairs (m_i -> m_j) with that key,
// each model point at most once per key. Immutable once built; a compressed-row layout (one
// offset per key of the dense key space, then the model point ids), so a lookup is two loads.
#include <binpose/features.hpp>
#include <binpose/memory.hpp>
#include <binpose/model.hpp>

#include <algorithm>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace binpose {

/// Quantization defaults for a model of the given diameter: d_dist = 1.0 mm for the thesis's
/// 60 mm part, scaled by diameter / 60 mm (the thesis swept 0.5-1.2 mm, Table 5); d_angle = 8
/// degrees (6.4); p_d = 15% (Tables 1-7).
QuantizationParams defaultQuantization(float model_diameter);

struct DatabaseStats {
  std::uint32_t keys_total = 0;   ///< size of the dense key space
  std::uint32_t keys_used = 0;    ///< keys holding at least one model point
  std::uint64_t entries = 0;      ///< stored (key, model point) pairs
  double median_per_key = 0;      ///< median model points per used key
  double mean_per_key = 0;
  std::uint32_t max_per_key = 0;
};

class ModelDatabase {
 public:
  using PointId = std::uint16_t;  ///< model points are limited to 65535
  static constexpr std::uint32_t kFormatVersion = 1;

  ModelDatabase() = default;

  /// Builds the table from every ordered pair of model points, using all cores. Deterministic:
  /// the ids under each key are in increasing order.
  static ModelDatabase build(OrientedModel model, const QuantizationParams& params);

  /// Versioned binary file: magic, format version, parameters, model points and normals, the
  /// table, and a CRC-32 of all of it. Throws binpose::Error on any failure.
  void save(const std::string& path) const;
  /// True when the file starts with the database magic (whatever its version or state).
  static bool isDatabaseFile(const std::string& path);
  /// Refuses (binpose::Error) a file of another version, a truncated or corrupt file.
  static ModelDatabase load(const std::string& path);

  /// Model points stored under `key` (empty for kInvalid or an unused key).
  [[nodiscard]] std::span<const PointId> lookup(std::uint32_t key) const {
    if (key >= keys_.size()) return {};
    return {entries_.data() + offsets_[key], entries_.data() + offsets_[key + 1]};
  }
  /// Starts fetching what lookup(key) and denseBits(key) read first (the table does not fit in
  /// the cache: a caller that knows its next keys hides the misses).
  void prefetch(std::uint32_t key) const {
    if (key >= keys_.size()) return;
    __builtin_prefetch(offsets_.data() + key);
    __builtin_prefetch(dense_slot_.data() + key);
  }
  /// The same model points as lookup(key), as a bitset of model().points.size() bits (64 to a
  /// word, zeros after the last point up to a multiple of 256 bits), for a key listing at least
  /// denseListSize() points; empty for a shorter list.
  [[nodiscard]] std::span<const std::uint64_t> denseBits(std::uint32_t key) const {
    if (key >= dense_slot_.size() || dense_slot_[key] == kNoSlot) return {};
    return {dense_bits_.data() + std::size_t{dense_slot_[key]} * dense_words_, dense_words_};
  }
  /// Lists of at least this many points are also kept as bitsets (a 48th of the points: longer
  /// ones are counted faster by bitset than point by point; see Voter::countDense).
  [[nodiscard]] std::size_t denseListSize() const { return std::max<std::size_t>(1, model_.points.size() / 48); }
  [[nodiscard]] const KeySpace& keySpace() const { return keys_; }
  [[nodiscard]] const OrientedModel& model() const { return model_; }
  [[nodiscard]] std::uint64_t entryCount() const { return entries_.size(); }
  [[nodiscard]] DatabaseStats stats() const;

 private:
  OrientedModel model_;
  KeySpace keys_;
  HugeVector<std::uint32_t> offsets_;  ///< keys_.size() + 1 offsets into entries_
  HugeVector<PointId> entries_;
  /// Bitsets of the long lists (derived from the lists when built or loaded; not in the file).
  void indexDenseLists();
  static constexpr std::uint32_t kNoSlot = UINT32_MAX;
  HugeVector<std::uint32_t> dense_slot_;  ///< per key: its bitset's place, or kNoSlot
  HugeVector<std::uint64_t> dense_bits_;
  std::size_t dense_words_ = 0;
};

}  // namespace binpose
