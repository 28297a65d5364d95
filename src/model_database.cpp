// Feature database: build (thesis 4.2, eq. 4-7), save and load.
#include <binpose/model_database.hpp>

#include "io_detail.hpp"

#include <binpose/geometry.hpp>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <fstream>
#include <numbers>
#include <utility>

namespace binpose {
namespace {

static_assert(std::endian::native == std::endian::little, "database files are little-endian");
constexpr char kMagic[8] = {'B', 'P', 'O', 'S', 'E', 'D', 'B', '\0'};

/// The CRC-32 of `size` bytes (zlib's, as crc32_z gives it), pieces of 1 MiB side by side and
/// joined in order with crc32_combine: the same value, on every core (a 32 MB database's check
/// took 10% of its load).
std::uint32_t parallelCrc32(const char* data, std::size_t size) {
  constexpr std::size_t kPiece = std::size_t{1} << 20;
  const std::size_t pieces = (size + kPiece - 1) / kPiece;
  std::vector<uLong> crc(pieces);
  tbb::parallel_for(std::size_t{0}, pieces, [&](std::size_t k) {
    const std::size_t at = k * kPiece, len = std::min(kPiece, size - at);
    crc[k] = crc32_z(0, reinterpret_cast<const Bytef*>(data + at), len);
  });
  uLong all = crc32_z(0, Z_NULL, 0);
  for (std::size_t k = 0; k < pieces; ++k)
    all = crc32_combine(all, crc[k], static_cast<z_off_t>(std::min(kPiece, size - k * kPiece)));
  return static_cast<std::uint32_t>(all);
}

/// Sorts keys below `limit` by least-significant-digit radix, 11 bits a pass. It replaced
/// std::sort (15% of a build in perf): the cap's database build 836 -> 732 ms.
void radixSort(std::vector<std::uint32_t>& v, std::vector<std::uint32_t>& tmp, std::uint32_t limit) {
  constexpr int kBits = 11;
  constexpr std::uint32_t kMask = (1u << kBits) - 1;
  tmp.resize(v.size());
  std::array<std::uint32_t, kMask + 1> count{};
  const auto bits = static_cast<int>(std::bit_width(limit));
  for (int shift = 0; shift < bits; shift += kBits) {
    count.fill(0);
    for (const auto x : v) ++count[(x >> shift) & kMask];
    std::uint32_t sum = 0;
    for (auto& c : count) sum += std::exchange(c, sum);
    for (const auto x : v) tmp[count[(x >> shift) & kMask]++] = x;
    v.swap(tmp);
  }
}

/// What a thread keeps between model points: a bit per key, all clear between points; the keys
/// of one point's features, then the distinct ones, and the sort's buffer.
struct PointScratch {
  std::vector<std::uint64_t> taken;
  std::vector<std::uint32_t> keys, distinct, sort_buffer;
};

/// Sorted, distinct keys of every directed feature starting at model point i (eq. 5, 7).
/// `taken` marks keys already taken for i, so that only the distinct keys are sorted. A bit per
/// key keeps the marks in the core's L2 cache (a 32-bit stamp per key did not fit: 17% of a
/// build in perf).
std::vector<std::uint32_t> keysOfPoint(const OrientedModel& m, const KeySpace& keys, std::size_t i,
                                       PointScratch& scratch) {
  scratch.keys.clear();
  overlapFeatureKeys(i, m.points, m.normals, keys, scratch.keys);
  auto& distinct = scratch.distinct;
  distinct.clear();
  for (const auto key : scratch.keys) {
    std::uint64_t& word = scratch.taken[key / 64];
    const std::uint64_t bit = 1ull << (key % 64);
    if (!(word & bit)) {  // m_i at most once per key
      word |= bit;
      distinct.push_back(key);
    }
  }
  for (const auto key : distinct) scratch.taken[key / 64] = 0;
  radixSort(distinct, scratch.sort_buffer, keys.size());
  return {distinct.begin(), distinct.end()};
}

void validateModel(const OrientedModel& m) {
  if (m.points.size() < 2) throw Error("model has fewer than two points");
  if (m.points.size() > 65535) throw Error(fmt::format("model has {} points; the database holds at most 65535", m.points.size()));
  if (m.normals.size() != m.points.size()) throw Error("model has no normal for every point");
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    if (!m.points[i].allFinite()) throw Error(fmt::format("model point {} is not finite", i));
    if (std::abs(m.normals[i].norm() - 1.0f) > 1e-3f) throw Error(fmt::format("model normal {} is not a unit vector", i));
  }
}

class Writer {
 public:
  template <typename T>
  void put(const T& v) { bytes.append(reinterpret_cast<const char*>(&v), sizeof(T)); }
  template <typename T>
  void putArray(const T* data, std::size_t n) { bytes.append(reinterpret_cast<const char*>(data), n * sizeof(T)); }
  std::string bytes;
};

class Reader {
 public:
  Reader(const std::string& path, const std::string& bytes, std::size_t end) : path_(path), bytes_(bytes), end_(end) {}
  template <typename T>
  T get(const char* what) {
    T v;
    getArray(&v, 1, what);
    return v;
  }
  template <typename T>
  void getArray(T* out, std::size_t n, const char* what) {
    if (n > (end_ - pos_) / sizeof(T)) detail::fail(path_, fmt::format("database file is truncated (in {})", what));
    if (n == 0) return;  // an empty vector's data() may be null, which memcpy must not get
    std::memcpy(static_cast<void*>(out), bytes_.data() + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
  }
  [[nodiscard]] std::size_t remaining() const { return end_ - pos_; }

 private:
  const std::string& path_;
  const std::string& bytes_;
  std::size_t pos_ = 0, end_;
};

}  // namespace

QuantizationParams defaultQuantization(float model_diameter) {
  QuantizationParams q;
  q.d_dist = 1.0f * thesisScale(model_diameter);
  q.d_angle = 8.0f * std::numbers::pi_v<float> / 180.0f;
  q.overlap = 0.15f;
  return q;
}

ModelDatabase ModelDatabase::build(OrientedModel model, const QuantizationParams& params) {
  validateModel(model);
  if (!(model.diameter > 0)) model.diameter = diameter(model.points);
  ModelDatabase db;
  db.keys_ = KeySpace(params, model.diameter);
  const std::size_t n = model.points.size();
  std::vector<std::vector<std::uint32_t>> per_point(n);
  tbb::enumerable_thread_specific<PointScratch> scratch(PointScratch{std::vector<std::uint64_t>(db.keys_.size() / 64 + 1, 0), {}, {}, {}});
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) { per_point[i] = keysOfPoint(model, db.keys_, i, scratch.local()); });

  std::uint64_t total = 0;
  for (const auto& k : per_point) total += k.size();
  if (total >= 0xFFFFFFFFull) throw Error(fmt::format("database would hold {} entries (limit 2^32); use fewer model points", total));

  // Compressed rows, filled in parallel over disjoint key ranges (each task owns its keys, and
  // visits the points in order, so the ids under a key come out sorted whatever the threads).
  const std::uint32_t n_keys = db.keys_.size();
  const std::size_t chunks = 32;
  auto chunkBegin = [&](std::size_t c) { return static_cast<std::uint32_t>(std::uint64_t(n_keys) * c / chunks); };
  auto forChunk = [&](std::size_t c, auto&& visit) {
    const std::uint32_t lo = chunkBegin(c), hi = chunkBegin(c + 1);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& k = per_point[i];
      for (auto it = std::lower_bound(k.begin(), k.end(), lo); it != k.end() && *it < hi; ++it) visit(*it, i);
    }
  };
  db.offsets_.assign(std::size_t{n_keys} + 1, 0);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    forChunk(c, [&](std::uint32_t key, std::size_t) { ++db.offsets_[key + 1]; });
  });
  for (std::size_t k = 0; k < n_keys; ++k) db.offsets_[k + 1] += db.offsets_[k];
  db.entries_.resize(total);
  std::vector<std::uint32_t> cursor(db.offsets_.begin(), db.offsets_.end() - 1);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    forChunk(c, [&](std::uint32_t key, std::size_t i) { db.entries_[cursor[key]++] = static_cast<PointId>(i); });
  });
  db.model_ = std::move(model);
  db.indexDenseLists();
  return db;
}

void ModelDatabase::indexDenseLists() {
  dense_words_ = 4 * ((model_.points.size() + 255) / 256);  // whole 256-bit blocks
  dense_slot_.assign(offsets_.empty() ? 0 : offsets_.size() - 1, kNoSlot);
  std::uint32_t slots = 0;
  for (std::size_t key = 0; key < dense_slot_.size(); ++key)
    if (offsets_[key + 1] - offsets_[key] >= denseListSize()) dense_slot_[key] = slots++;
  dense_bits_.assign(std::size_t{slots} * dense_words_, 0);
  // Each list's bits gathered word by word in a register (a list's points come in increasing
  // order: setting them in memory one at a time waited on the store before), the keys in parallel.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, dense_slot_.size(), 4096), [&](const auto& range) {
    for (std::size_t key = range.begin(); key < range.end(); ++key) {
      if (dense_slot_[key] == kNoSlot) continue;
      std::uint64_t* bits = dense_bits_.data() + std::size_t{dense_slot_[key]} * dense_words_;
      std::size_t at = 0;
      std::uint64_t word = 0;
      for (const PointId id : lookup(static_cast<std::uint32_t>(key))) {
        if (id / 64 != at) {
          bits[at] |= word;
          at = id / 64;
          word = 0;
        }
        word |= 1ull << (id % 64);
      }
      bits[at] |= word;
    }
  });
}

DatabaseStats ModelDatabase::stats() const {
  DatabaseStats s;
  s.keys_total = keys_.size();
  s.entries = entries_.size();
  std::vector<std::uint32_t> sizes;
  for (std::uint32_t k = 0; k < keys_.size(); ++k)
    if (const std::uint32_t c = offsets_[k + 1] - offsets_[k]; c > 0) sizes.push_back(c);
  s.keys_used = static_cast<std::uint32_t>(sizes.size());
  if (sizes.empty()) return s;
  std::sort(sizes.begin(), sizes.end());
  const std::size_t h = sizes.size() / 2;
  s.median_per_key = sizes.size() % 2 ? sizes[h] : 0.5 * (sizes[h - 1] + sizes[h]);
  s.mean_per_key = static_cast<double>(s.entries) / static_cast<double>(sizes.size());
  s.max_per_key = sizes.back();
  return s;
}

void ModelDatabase::save(const std::string& path) const {
  if (offsets_.empty()) throw Error(fmt::format("{}: cannot save an empty database", path));
  Writer w;
  w.putArray(kMagic, sizeof kMagic);
  w.put(kFormatVersion);
  const QuantizationParams& q = keys_.params();
  w.put(q.d_dist); w.put(q.d_angle); w.put(q.overlap);
  w.put(model_.diameter); w.put(model_.area); w.put(model_.sample_radius);
  w.put(static_cast<std::uint32_t>(model_.points.size()));
  w.put(keys_.size());
  w.put(static_cast<std::uint64_t>(entries_.size()));
  for (const Vec3& p : model_.points) w.putArray(p.data(), 3);
  for (const Vec3& nrm : model_.normals) w.putArray(nrm.data(), 3);
  w.putArray(offsets_.data(), offsets_.size());
  w.putArray(entries_.data(), entries_.size());
  const auto crc = static_cast<std::uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(w.bytes.data()), w.bytes.size()));
  w.put(crc);
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error(fmt::format("{}: cannot write database file", path));
  out.write(w.bytes.data(), static_cast<std::streamsize>(w.bytes.size()));
  if (!out) throw Error(fmt::format("{}: write failed", path));
}

bool ModelDatabase::isDatabaseFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[sizeof kMagic] = {};
  return in.read(magic, sizeof magic) && std::equal(magic, magic + sizeof magic, kMagic);
}

namespace {

/// A loaded model as training makes one: finite points, unit normals, a positive finite
/// diameter and sample radius (a checksum guards against damage, not against a crafted file).
void checkModel(const std::string& path, const OrientedModel& model) {
  if (!(model.diameter > 0) || !std::isfinite(model.diameter) || !(model.sample_radius > 0) ||
      !std::isfinite(model.sample_radius) || model.sample_radius > model.diameter)
    detail::fail(path, fmt::format("database has an invalid diameter {} or sample radius {}", model.diameter, model.sample_radius));
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    if (!model.points[i].allFinite()) detail::fail(path, fmt::format("database model point {} is not finite", i));
    if (!model.normals[i].allFinite() || std::abs(model.normals[i].norm() - 1.0f) > 1e-3f)
      detail::fail(path, fmt::format("database model normal {} is not a unit vector", i));
  }
}

}  // namespace

ModelDatabase ModelDatabase::load(const std::string& path) {
  const std::string bytes = detail::readFileBytes(path);
  if (bytes.size() < sizeof kMagic + 8 || bytes.compare(0, sizeof kMagic, kMagic, sizeof kMagic) != 0)
    detail::fail(path, "not a binpose database file (bad magic)");
  std::uint32_t version = 0;
  std::memcpy(&version, bytes.data() + sizeof kMagic, sizeof version);
  if (version != kFormatVersion)
    detail::fail(path, fmt::format("database format version {} is not supported (this build reads {}); retrain it",
                                   version, kFormatVersion));
  const std::size_t body = bytes.size() - sizeof(std::uint32_t);
  std::uint32_t stored_crc = 0;
  std::memcpy(&stored_crc, bytes.data() + body, sizeof stored_crc);
  if (parallelCrc32(bytes.data(), body) != stored_crc)
    detail::fail(path, "database file is corrupt or truncated (checksum mismatch)");

  Reader r(path, bytes, body);
  char magic[sizeof kMagic];
  r.getArray(magic, sizeof magic, "header");
  r.get<std::uint32_t>("header");
  QuantizationParams q;
  q.d_dist = r.get<float>("parameters");
  q.d_angle = r.get<float>("parameters");
  q.overlap = r.get<float>("parameters");
  ModelDatabase db;
  db.model_.diameter = r.get<float>("parameters");
  db.model_.area = r.get<double>("parameters");
  db.model_.sample_radius = r.get<float>("parameters");
  const auto n_points = r.get<std::uint32_t>("parameters");
  const auto n_keys = r.get<std::uint32_t>("parameters");
  const auto n_entries = r.get<std::uint64_t>("parameters");
  try {
    db.keys_ = KeySpace(q, db.model_.diameter);
  } catch (const Error& e) {
    detail::fail(path, fmt::format("invalid parameters in database ({})", e.what()));
  }
  if (db.keys_.size() != n_keys || n_points < 2 || n_points > 65535)
    detail::fail(path, "database header is inconsistent");
  if (n_entries == 0) detail::fail(path, "database holds no point-pair features; retrain it");
  const std::size_t tables = std::size_t{n_points} * 24 + (std::size_t{n_keys} + 1) * 4;
  if (r.remaining() < tables || n_entries != (r.remaining() - tables) / 2 || (r.remaining() - tables) % 2 != 0)
    detail::fail(path, "database size does not match its header");
  db.model_.points.resize(n_points);
  db.model_.normals.resize(n_points);
  for (Vec3& p : db.model_.points) r.getArray(p.data(), 3, "model points");
  for (Vec3& nrm : db.model_.normals) r.getArray(nrm.data(), 3, "model normals");
  db.offsets_.resize(std::size_t{n_keys} + 1);
  r.getArray(db.offsets_.data(), db.offsets_.size(), "offsets");
  db.entries_.resize(n_entries);
  r.getArray(db.entries_.data(), db.entries_.size(), "entries");
  // Structural checks, so that no lookup can read out of bounds even from a crafted file.
  if (db.offsets_.front() != 0 || db.offsets_.back() != n_entries || !std::is_sorted(db.offsets_.begin(), db.offsets_.end()))
    detail::fail(path, "database offsets are inconsistent");
  if (std::any_of(db.entries_.begin(), db.entries_.end(), [&](PointId id) { return id >= n_points; }))
    detail::fail(path, "database refers to a model point that does not exist");
  checkModel(path, db.model_);
  db.indexDenseLists();
  return db;
}

}  // namespace binpose
