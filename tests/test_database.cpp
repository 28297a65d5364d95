// The feature database (thesis 4.2): contents against brute force, save/load, refusal of bad files.
#include <binpose/model_database.hpp>
#include <binpose/geometry.hpp>
#include <binpose/shapes.hpp>

#include "test_util.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <bit>
#include <numeric>
#include <set>

using namespace binpose;

namespace {
OrientedModel smallModel(int points = 300) {
  ModelParams params;
  params.num_points = points;
  return prepareModel(makeBox({30, 20, 10}, 2), params);
}

void expectSameTable(const ModelDatabase& a, const ModelDatabase& b) {
  ASSERT_EQ(a.keySpace().size(), b.keySpace().size());
  ASSERT_EQ(a.entryCount(), b.entryCount());
  for (std::uint32_t k = 0; k < a.keySpace().size(); ++k) {
    const auto x = a.lookup(k), y = b.lookup(k);
    ASSERT_TRUE(std::equal(x.begin(), x.end(), y.begin(), y.end())) << "key " << k;
  }
}
}  // namespace

TEST(Database, MatchesBruteForce) {
  const OrientedModel model = smallModel();
  const QuantizationParams q = defaultQuantization(model.diameter);
  const ModelDatabase db = ModelDatabase::build(model, q);
  // Brute force: the set of (key, i) over every directed pair, with the overlap rule.
  std::set<std::pair<std::uint32_t, std::uint32_t>> expected;
  std::array<std::uint32_t, KeySpace::kMaxKeys> keys{};
  const std::size_t n = model.points.size();
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      PairFeature f;
      if (i == j || !computeFeature(model.points[i], model.normals[i], model.points[j], model.normals[j], f)) continue;
      const int c = db.keySpace().overlapKeys(f, keys);
      ASSERT_GE(c, 1);
      for (int k = 0; k < c; ++k) expected.insert({keys[k], static_cast<std::uint32_t>(i)});
    }
  EXPECT_EQ(db.entryCount(), expected.size());
  std::uint64_t seen = 0;
  for (std::uint32_t k = 0; k < db.keySpace().size(); ++k) {
    const auto ids = db.lookup(k);
    EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end()));
    EXPECT_EQ(std::adjacent_find(ids.begin(), ids.end()), ids.end()) << "a model point twice under key " << k;
    for (auto id : ids) {
      EXPECT_TRUE(expected.count({k, id})) << "unexpected point " << id << " under key " << k;
      ++seen;
    }
  }
  EXPECT_EQ(seen, expected.size());
  EXPECT_TRUE(db.lookup(KeySpace::kInvalid).empty());
}

TEST(Database, SameTableWhateverTheThreadCount) {
  const OrientedModel model = smallModel(500);
  const QuantizationParams q = defaultQuantization(model.diameter);
  ModelDatabase one, many;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = ModelDatabase::build(model, q);
  }
  many = ModelDatabase::build(model, q);
  expectSameTable(one, many);
}

TEST(Database, SaveLoadRoundTrip) {
  const ModelDatabase db = ModelDatabase::build(smallModel(), defaultQuantization(30.0f));
  const std::string path = test::tempPath("db.bpdb");
  db.save(path);
  const ModelDatabase back = ModelDatabase::load(path);
  expectSameTable(db, back);
  EXPECT_EQ(back.model().points, db.model().points);
  EXPECT_EQ(back.model().normals, db.model().normals);
  EXPECT_EQ(back.model().diameter, db.model().diameter);
  EXPECT_EQ(back.keySpace().params().d_dist, db.keySpace().params().d_dist);
  EXPECT_EQ(back.keySpace().params().d_angle, db.keySpace().params().d_angle);
  EXPECT_EQ(back.keySpace().params().overlap, db.keySpace().params().overlap);
}

TEST(Database, RefusesCorruptTruncatedAndForeignFiles) {
  const ModelDatabase db = ModelDatabase::build(smallModel(), defaultQuantization(30.0f));
  const std::string path = test::tempPath("db.bpdb");
  db.save(path);
  const std::string good = test::readAll(path);
  auto refusal = [&](const std::string& bytes) -> std::string {
    const std::string bad = test::tempPath("bad.bpdb");
    test::writeAll(bad, bytes);
    try {
      ModelDatabase::load(bad);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x5A;
  EXPECT_NE(refusal(flipped).find("corrupt"), std::string::npos);
  EXPECT_NE(refusal(good.substr(0, good.size() / 3)).find("corrupt or truncated"), std::string::npos);
  EXPECT_NE(refusal(good.substr(0, 10)).find("database"), std::string::npos);
  std::string version = good;
  version[8] = 99;  // format version field follows the 8-byte magic
  EXPECT_NE(refusal(version).find("version 99"), std::string::npos);
  std::string magic = good;
  magic[0] = 'X';
  EXPECT_NE(refusal(magic).find("bad magic"), std::string::npos);
  EXPECT_NE(refusal("ply\nformat ascii 1.0\n").find("bad magic"), std::string::npos);
}

TEST(Database, LoadChecksMultiMegabyteFilesAndIndexesTheirDenseLists) {
  // A file of several MiB: its checksum is taken in 1 MiB pieces, joined in order; a file written
  // with one CRC over all its bytes must load, and a byte changed in any piece must not.
  const ModelDatabase db = ModelDatabase::build(smallModel(1500), defaultQuantization(30.0f));
  const std::string path = test::tempPath("large.bpdb");
  db.save(path);
  const std::string good = test::readAll(path);
  ASSERT_GT(good.size(), std::size_t{3} << 20);
  const ModelDatabase back = ModelDatabase::load(path);
  expectSameTable(db, back);
  // Each list of denseListSize() points or more also as a bitset holding exactly its points.
  std::size_t dense = 0;
  for (std::uint32_t k = 0; k < back.keySpace().size(); ++k) {
    const auto ids = back.lookup(k);
    const auto bits = back.denseBits(k);
    ASSERT_EQ(bits.empty(), ids.size() < back.denseListSize()) << "key " << k;
    if (bits.empty()) continue;
    ++dense;
    std::vector<std::uint16_t> set;
    for (std::size_t w = 0; w < bits.size(); ++w)
      for (std::uint64_t word = bits[w]; word != 0; word &= word - 1)
        set.push_back(static_cast<std::uint16_t>(64 * w + std::countr_zero(word)));
    ASSERT_TRUE(std::equal(set.begin(), set.end(), ids.begin(), ids.end())) << "key " << k;
  }
  EXPECT_GT(dense, 0u);
  for (const std::size_t at : {std::size_t{100}, good.size() / 2, good.size() - 10}) {
    std::string bad = good;
    bad[at] ^= 0x21;
    const std::string bad_path = test::tempPath("large_bad.bpdb");
    test::writeAll(bad_path, bad);
    try {
      ModelDatabase::load(bad_path);
      ADD_FAILURE() << "a byte changed at " << at << " was not noticed";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("corrupt"), std::string::npos) << e.what();
    }
  }
}

TEST(Database, RefusesBadModels) {
  OrientedModel model = smallModel(100);
  model.normals[3] = Vec3(0, 0, 0);
  EXPECT_THROW(ModelDatabase::build(model, defaultQuantization(30.0f)), Error);
  model = smallModel(100);
  model.points[5].x() = NAN;
  EXPECT_THROW(ModelDatabase::build(model, defaultQuantization(30.0f)), Error);
  model = smallModel(100);
  model.normals.pop_back();
  EXPECT_THROW(ModelDatabase::build(model, defaultQuantization(30.0f)), Error);
}

TEST(Database, LargeTablesLieOn2MiBBoundaries) {
  // The table's large arrays are allocated for huge pages (madvise needs a 2 MiB aligned range);
  // small ones as usual. Either way they hold what is written.
  HugeVector<std::uint32_t> large(std::size_t{3} << 20 >> 2), small(1000);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(large.data()) % (std::uintptr_t{2} << 20), 0u);
  for (std::size_t i = 0; i < large.size(); i += 4097) large[i] = static_cast<std::uint32_t>(i);
  std::iota(small.begin(), small.end(), 7u);
  for (std::size_t i = 0; i < large.size(); i += 4097) ASSERT_EQ(large[i], i);
  EXPECT_EQ(small.back(), 1006u);
  large.resize(large.size() * 2);  // moved to a new 2 MiB aligned block
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(large.data()) % (std::uintptr_t{2} << 20), 0u);
  EXPECT_EQ(large[4097], 4097u);
}
