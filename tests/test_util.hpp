#pragma once
#include <binpose/evaluation.hpp>
#include <binpose/types.hpp>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace binpose::test {

/// ADD-S of `estimate` against copy `truth` (infinite for a copy a diameter away).
inline float addSTo(const Pose& estimate, const Pose& truth, const EvalModel& eval) {
  if ((estimate * eval.centroid - truth * eval.centroid).norm() > eval.diameter) return INFINITY;
  return poseErrors(estimate, truth, eval).add_s_mm;
}

/// A file of ../shared/data (third-party data, read where it lies).
inline std::string dataPath(const std::string& relative) { return std::string(BINPOSE_DATA_DIR) + "/" + relative; }

/// A fresh temporary file path for this test.
inline std::string tempPath(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const auto dir = std::filesystem::temp_directory_path() / "binpose_tests";
  std::filesystem::create_directories(dir);
  return (dir / (std::string(info->test_suite_name()) + "_" + info->name() + "_" + name)).string();
}

inline std::string readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void writeAll(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// The k nearest of q by brute force: (squared distance, index), nearest first, ties by index.
inline std::vector<std::pair<float, std::uint32_t>> bruteKnn(const Points& points, const Vec3& q, std::size_t k) {
  std::vector<std::pair<float, std::uint32_t>> all;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) all.push_back({(points[i] - q).squaredNorm(), static_cast<std::uint32_t>(i)});
  k = std::min(k, all.size());
  std::partial_sort(all.begin(), all.begin() + static_cast<long>(k), all.end());
  all.resize(k);
  return all;
}

inline double deg(double rad) { return rad * 180.0 / 3.14159265358979323846; }

/// What `run()` returns when run on a new thread of its own, in an arena of one thread: the
/// buffers the library keeps per thread start empty there.
template <class Run>
auto onFreshThread(Run run) {
  std::optional<decltype(run())> out;
  std::thread([&] { tbb::task_arena(1).execute([&] { out.emplace(run()); }); }).join();
  return std::move(*out);
}

/// The message of the binpose::Error `f` throws, "(no error)" when it throws none.
inline std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace binpose::test

/// The shared data is part of the test set-up; a missing folder is a failure, not a skip.
#define REQUIRE_DATA(rel)                                                                     \
  ASSERT_TRUE(std::filesystem::exists(::binpose::test::dataPath(rel)))                        \
      << "missing " << ::binpose::test::dataPath(rel) << " (../shared/data must sit beside the repo)"
