// The command-line front end: `binpose train` and `binpose detect`, run as a user would.
#include <binpose/io.hpp>
#include <binpose/model_database.hpp>

#include "test_util.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <sys/wait.h>
#include <unistd.h>

using namespace binpose;
using test::dataPath;

namespace {
struct CliRun {
  int code;
  std::string out;  ///< stdout and stderr
  std::string err;  ///< stderr
};

/// Runs the CLI with stdout and stderr captured (stderr alone in `err`).
CliRun runCli(const std::string& args) {
  const std::string log = test::tempPath("cli.log"), err = test::tempPath("cli.err");
  const int status = std::system((std::string(BINPOSE_CLI) + " " + args + " > " + log + " 2> " + err).c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, test::readAll(log) + test::readAll(err), test::readAll(err)};
}
}  // namespace

TEST(TrainCli, UwaAndIpdModelsTrainAndLoad) {
  REQUIRE_DATA("uwa/parasaurolophus_6700.ply");
  for (const std::string model : {"uwa/parasaurolophus_6700.ply", "ipd_parts/models/obj_000008.ply"}) {
    const std::string db = test::tempPath("model.bpdb");
    const CliRun run = runCli(fmt::format("train --model {} --out {} --points 1500", dataPath(model), db));
    ASSERT_EQ(run.code, 0) << run.out;
    EXPECT_NE(run.out.find("diameter"), std::string::npos);
    EXPECT_NE(run.out.find("entries"), std::string::npos);
    const ModelDatabase loaded = ModelDatabase::load(db);
    EXPECT_NEAR(double(loaded.model().points.size()), 1500.0, 15.0);
    EXPECT_GT(loaded.stats().keys_used, 1000u);
  }
}

TEST(TrainCli, MetresAndParameters) {
  REQUIRE_DATA("pcl_milk/milk.pcd");
  const std::string db = test::tempPath("milk.bpdb");
  const CliRun run = runCli(fmt::format("train --model {} --out {} --units m --points 1000 --d-dist 3 --d-angle 10 --overlap 0.2",
                                     dataPath("pcl_milk/milk.pcd"), db));
  ASSERT_EQ(run.code, 0) << run.out;
  const ModelDatabase loaded = ModelDatabase::load(db);
  EXPECT_FLOAT_EQ(loaded.keySpace().params().d_dist, 3.0f);
  EXPECT_NEAR(test::deg(loaded.keySpace().params().d_angle), 10.0, 1e-4);
  EXPECT_FLOAT_EQ(loaded.keySpace().params().overlap, 0.2f);
  EXPECT_GT(loaded.model().diameter, 100.0f);  // a carton of about 0.2 m, now in mm
}

// PCL's milk carton view is in metres (about 0.2 across): by default (--units auto) no part is
// under 2 mm across, so it is read in metres, with a note, as with --units m; --units mm keeps it
// 0.2 mm across.
TEST(TrainCli, ModelInMetresIsReadInMetresUnlessMillimetresAreGiven) {
  REQUIRE_DATA("pcl_milk/milk.pcd");
  const std::string by_auto = test::tempPath("milk_auto.bpdb"), by_m = test::tempPath("milk_m.bpdb"), by_mm = test::tempPath("milk_mm.bpdb");
  const std::string model = dataPath("pcl_milk/milk.pcd");
  const CliRun run = runCli(fmt::format("train --model {} --out {} --points 500", model, by_auto));
  ASSERT_EQ(run.code, 0) << run.out;
  EXPECT_NE(run.err.find("reading it in metres"), std::string::npos) << run.err;
  ASSERT_EQ(runCli(fmt::format("train --model {} --out {} --points 500 --units m", model, by_m)).code, 0);
  ASSERT_EQ(runCli(fmt::format("train --model {} --out {} --points 500 --units mm", model, by_mm)).code, 0);
  EXPECT_FLOAT_EQ(ModelDatabase::load(by_auto).model().diameter, ModelDatabase::load(by_m).model().diameter);
  EXPECT_LT(ModelDatabase::load(by_mm).model().diameter, 1.0f);
}

// A model file in inches (a CAD export) spans a few units: read in millimetres it is a part of a
// few millimetres, which its size cannot tell from one in inches, so a note names --units in;
// with it the model is the millimetre file's.
TEST(TrainCli, ModelInInchesGetsANoteAndItsSizeWithUnitsIn) {
  REQUIRE_DATA("ipd_parts/models/obj_000001.ply");
  const Mesh mesh = readPlyMesh(dataPath("ipd_parts/models/obj_000001.ply"));
  Points inches = mesh.vertices;
  for (Vec3& v : inches) v /= 25.4f;
  const std::string model = test::tempPath("obj1_inches.ply");
  writePly(model, inches, mesh.normals, mesh.faces);
  const std::string by_auto = test::tempPath("obj1_auto.bpdb"), by_in = test::tempPath("obj1_in.bpdb");
  const CliRun run = runCli(fmt::format("train --model {} --out {} --points 500", model, by_auto));
  ASSERT_EQ(run.code, 0) << run.out;
  EXPECT_NE(run.err.find("--units in"), std::string::npos) << run.err;
  ASSERT_EQ(runCli(fmt::format("train --model {} --out {} --points 500 --units in", model, by_in)).code, 0);
  EXPECT_NEAR(ModelDatabase::load(by_in).model().diameter, 25.4f * ModelDatabase::load(by_auto).model().diameter, 0.01f);
  EXPECT_GT(ModelDatabase::load(by_in).model().diameter, 100.0f);
}

TEST(TrainCli, BadInputExitsTwoWithOneLine) {
  const std::string junk = test::tempPath("junk.ply");
  test::writeAll(junk, "ply\nformat ascii 1.0\nelement vertex 100\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n");
  CliRun run = runCli(fmt::format("train --model {} --out {}", junk, test::tempPath("x.bpdb")));
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.out.find("truncated"), std::string::npos) << run.out;
  EXPECT_EQ(std::count(run.out.begin(), run.out.end(), '\n'), 1) << run.out;
  run = runCli(fmt::format("train --model {} --out {} --d-angle 0", dataPath("ipd_parts/models/obj_000001.ply"),
                           test::tempPath("x.bpdb")));
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.out.find("d_angle"), std::string::npos) << run.out;
  run = runCli(fmt::format("train --model {} --out {} --units inch", dataPath("ipd_parts/models/obj_000001.ply"),
                           test::tempPath("x.bpdb")));
  EXPECT_EQ(run.code, 2);
  run = runCli(fmt::format("train --model {} --out {} --points 3", dataPath("ipd_parts/models/obj_000001.ply"),
                           test::tempPath("x.bpdb")));
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.out.find("model points"), std::string::npos) << run.out;
}

namespace {
/// A small cap database shared by the detect tests.
std::string capDatabase() {
  static const std::string path = [] {
    // one per process: CTest runs the tests as parallel processes
    const std::string db = (std::filesystem::temp_directory_path() / "binpose_tests" /
                            ("cli_cap_" + std::to_string(::getpid()) + ".bpdb")).string();
    std::filesystem::create_directories(std::filesystem::path(db).parent_path());
    const int status = std::system((std::string(BINPOSE_CLI) + " train --model builtin:cap --points 1000 --out " + db + " > /dev/null").c_str());
    EXPECT_EQ(status, 0);
    return db;
  }();
  return path;
}
}  // namespace

TEST(DetectCli, JsonResultOnARealScan) {
  REQUIRE_DATA("uwa/rs1_normals.ply");
  const std::string out = test::tempPath("rs1.json");
  const CliRun run = runCli(fmt::format("detect --model {} --model-points 2000 --scene {} --out {}",
                                        dataPath("uwa/parasaurolophus_6700.ply"), dataPath("uwa/rs1_normals.ply"), out));
  ASSERT_EQ(run.code, 0) << run.out;
  const auto j = nlohmann::json::parse(test::readAll(out));
  ASSERT_GE(j["detections"].size(), 1u);
  const auto& pose = j["detections"][0]["pose"];
  ASSERT_EQ(pose.size(), 4u);
  EXPECT_EQ(pose[3], nlohmann::json({0.0, 0.0, 0.0, 1.0}));
  Eigen::Matrix3f R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = pose[r][c].get<float>();
  EXPECT_TRUE((R * R.transpose()).isIdentity(1e-4f)) << "a rotation";
  EXPECT_NEAR(R.determinant(), 1.0f, 1e-4f);
  for (const char* key : {"preprocess", "match", "refine", "total"}) EXPECT_TRUE(j["timing_ms"].contains(key)) << key;
  EXPECT_EQ(j["scene_points"].get<int>(), 114373);
  EXPECT_GT(j["params"]["r"].get<double>(), 100.0) << "r scaled to the 312 mm model";
  EXPECT_NE(run.out.find("rank"), std::string::npos) << "a summary table";
}

// An empty scene, or one whose every point is a pixel without a depth (NaN, or (0, 0, 0) as depth
// SDKs write it): no detection, exit 0, and a warning that nothing was measured.
TEST(DetectCli, EmptySceneIsZeroDetectionsAndExitZero) {
  const std::string empty = test::tempPath("empty.ply"), unmeasured = test::tempPath("unmeasured.ply");
  test::writeAll(empty, "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
  test::writeAll(unmeasured,
                 "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "end_header\n0 0 0\nnan 0 700\n0 0 0\n");
  for (const std::string& scene : {empty, unmeasured}) {
    const std::string out = test::tempPath("empty.json");
    const CliRun run = runCli(fmt::format("detect --model {} --scene {} --out {}", capDatabase(), scene, out));
    ASSERT_EQ(run.code, 0) << run.out;
    EXPECT_EQ(nlohmann::json::parse(test::readAll(out))["detections"].size(), 0u) << scene;
    EXPECT_NE(run.out.find("no measured point"), std::string::npos) << run.out;
  }
}

// PCL's milk frame is in metres, as many sensors' software writes: by default (--units auto) it
// spans less than half the carton's diameter, so it is read in metres, with a note, and gives the
// detections that --units m gives; --units mm keeps millimetres and warns.
TEST(DetectCli, SceneInMetresIsReadInMetresUnlessMillimetresAreGiven) {
  REQUIRE_DATA("pcl_milk/milk.pcd");
  const std::string model = dataPath("pcl_milk/milk.pcd"), scene = dataPath("pcl_milk/milk_cartoon_all_small_clorox.pcd");
  const std::string db = test::tempPath("milk.bpdb"), by_auto = test::tempPath("milk_auto.json"), by_m = test::tempPath("milk_m.json");
  ASSERT_EQ(runCli(fmt::format("train --model {} --out {} --units m --points 1000", model, db)).code, 0);
  CliRun run = runCli(fmt::format("detect --model {} --scene {} --out {}", db, scene, by_auto));
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("reading it in metres"), std::string::npos) << run.err;
  ASSERT_EQ(runCli(fmt::format("detect --model {} --scene {} --units m --out {}", db, scene, by_m)).code, 0);
  const auto auto_json = nlohmann::json::parse(test::readAll(by_auto)), m_json = nlohmann::json::parse(test::readAll(by_m));
  ASSERT_GE(auto_json["detections"].size(), 1u);
  EXPECT_EQ(auto_json["detections"], m_json["detections"]);
  run = runCli(fmt::format("detect --model {} --scene {} --units mm", db, scene));
  EXPECT_EQ(run.code, 0) << run.out;
  EXPECT_NE(run.err.find("--units m"), std::string::npos) << run.err;
}

TEST(DetectCli, BadInputExitsTwoWithOneLine) {
  REQUIRE_DATA("pcl_milk/milk.pcd");
  const std::string cut = test::tempPath("cut.pcd");
  const std::string bytes = test::readAll(dataPath("pcl_milk/milk.pcd"));
  test::writeAll(cut, bytes.substr(0, bytes.size() / 2));
  CliRun run = runCli(fmt::format("detect --model {} --scene {}", capDatabase(), cut));
  EXPECT_EQ(run.code, 2);
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_NE(run.err.find("truncated"), std::string::npos) << run.err;
  run = runCli(fmt::format("detect --model {} --scene {} --r -3", capDatabase(), dataPath("pcl_milk/milk.pcd")));
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("r (sampling radius)"), std::string::npos) << run.err;
  const std::string params = test::tempPath("params.json");
  test::writeAll(params, R"({"e_gmax": 2.0, "radius": 3})");
  run = runCli(fmt::format("detect --model {} --scene {} --params {}", capDatabase(), dataPath("pcl_milk/milk.pcd"), params));
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("unknown parameter 'radius'"), std::string::npos) << run.err;
  const std::string corrupt = test::tempPath("corrupt.bpdb");
  std::string db = test::readAll(capDatabase());
  db[db.size() / 2] ^= 1;
  test::writeAll(corrupt, db);
  run = runCli(fmt::format("detect --model {} --scene {}", corrupt, dataPath("pcl_milk/milk.pcd")));
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("checksum"), std::string::npos) << run.err;
  run = runCli(fmt::format("detect --model {} --scene {}", capDatabase(), test::tempPath("depth.png")));
  EXPECT_EQ(run.code, 2);
  run = runCli(fmt::format("detect --model {} --scene {} --threads -2", capDatabase(), dataPath("pcl_milk/milk.pcd")));
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("--threads"), std::string::npos) << run.err;
}

// `binpose check` reads a simulated scene's ground_truth.json: each copy's true pose is judged,
// and the caps the scan shows well stand; a pose file it cannot use is one line and exit 2.
TEST(CheckCli, GroundTruthPosesAreJudgedAndBadPosesRefused) {
  const std::string dir = test::tempPath("check_bin");
  ASSERT_EQ(runCli(fmt::format("simulate --model builtin:cap --instances 6 --seed 5 --out {}", dir)).code, 0);
  const std::string out = test::tempPath("checks.json");
  CliRun run = runCli(
      fmt::format("check --model {} --scene {}/depth.png --intrinsics {}/camera.json --poses {}/ground_truth.json --out {}",
                  capDatabase(), dir, dir, dir, out));
  ASSERT_EQ(run.code, 0) << run.out;
  const auto checks = nlohmann::json::parse(test::readAll(out))["checks"];
  const auto truth = nlohmann::json::parse(test::readAll(dir + "/ground_truth.json"))["instances"];
  ASSERT_EQ(checks.size(), truth.size());
  int standing = 0, well_visible = 0;
  for (std::size_t i = 0; i < checks.size(); ++i) {
    if (truth[i]["visib_fract"].get<double>() < 0.9) continue;
    ++well_visible;
    standing += checks[i]["as_found"] == "none" || checks[i]["as_laid"] == "none";
    EXPECT_GT(checks[i]["score"].get<double>(), 0.5) << "copy " << i;
  }
  EXPECT_GE(well_visible, 2);
  EXPECT_EQ(standing, well_visible);
  // The same poses from BOP's scene_gt.json (cam_R_m2c, cam_t_m2c), the same verdicts.
  const std::string bop_out = test::tempPath("checks_bop.json");
  run = runCli(fmt::format("check --model {} --scene {}/depth.png --intrinsics {}/camera.json --poses {}/scene_gt.json --obj-id 1 --out {}",
                           capDatabase(), dir, dir, dir, bop_out));
  ASSERT_EQ(run.code, 0) << run.out;
  const auto bop_checks = nlohmann::json::parse(test::readAll(bop_out))["checks"];
  ASSERT_EQ(bop_checks.size(), checks.size());
  for (std::size_t i = 0; i < checks.size(); ++i) {
    EXPECT_NEAR(bop_checks[i]["score"].get<double>(), checks[i]["score"].get<double>(), 1e-3) << "copy " << i;
    EXPECT_EQ(bop_checks[i]["as_found"], checks[i]["as_found"]) << "copy " << i;
  }
  const std::string scene = fmt::format("--scene {}/depth.png --intrinsics {}/camera.json", dir, dir);
  const std::string bad = test::tempPath("bad_poses.json");
  for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
           {R"({"poses": [[[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 500], [0, 0, 0, 1]]]})", "not a rotation"},
           {R"({"poses": [[[1, 0, 0], [0, 1, 0], [0, 0, 1]]]})", "not 4 numbers"},
           {R"({"pose": []})", "no \"poses\""},
           {R"({"poses": [[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, "x"]]]})", "not a finite number"},
           {"{\"poses\": [", "not a JSON object"},
           {R"({"0": [{"cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1]}]})", "cam_t_m2c"}}) {
    test::writeAll(bad, text);
    run = runCli(fmt::format("check --model {} {} --poses {}", capDatabase(), scene, bad));
    EXPECT_EQ(run.code, 2) << text;
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_NE(run.err.find(message), std::string::npos) << run.err;
  }
}

TEST(DetectCli, ParametersFromJsonAndPreset) {
  const std::string params = test::tempPath("params.json");
  test::writeAll(params, R"({"e_gmax": 2.25, "C_n": 9, "use_symmetry": false})");
  const std::string scene = test::tempPath("flat.ply");
  Points flat;
  for (int i = 0; i < 50; ++i)
    for (int j = 0; j < 50; ++j) flat.emplace_back(float(i), float(j), 500.0f);
  writePly(scene, flat);
  const std::string out = test::tempPath("p.json");
  const CliRun run = runCli(fmt::format("detect --model {} --scene {} --preset thesis --params {} --c-n 10 --out {}",
                                        capDatabase(), scene, params, out));
  ASSERT_EQ(run.code, 0) << run.out;
  const auto p = nlohmann::json::parse(test::readAll(out))["params"];
  EXPECT_DOUBLE_EQ(p["e_gmax"].get<double>(), 2.25);  // from the file
  EXPECT_EQ(p["C_n"].get<int>(), 10);                 // the command line wins over the file
  EXPECT_FALSE(p["use_symmetry"].get<bool>());
  EXPECT_EQ(p["pipeline"].get<std::string>(), "thesis");  // the preset
  EXPECT_FALSE(p["refine"].get<bool>());
}

// The BOP loop closed on a fresh machine: `binpose simulate --bop` builds a dataset, `binpose
// bop` detects its targets into a BOP19 CSV, and `binpose eval` scores that CSV exactly as it
// scores `binpose detect`'s JSON on the same images with the same database.
TEST(BopCli, SimulatedDatasetScoresAsDetectDoes) {
  const std::string root = test::tempPath("bop");
  std::filesystem::remove_all(root);
  for (int scene = 1; scene <= 2; ++scene) {
    const CliRun sim = runCli(fmt::format("simulate --instances 5 --seed {} --out {}/flat{} --bop {}/ds --scene-id {}",
                                          20 + scene, root, scene, root, scene));
    ASSERT_EQ(sim.code, 0) << sim.out;
  }
  const auto targets = nlohmann::json::parse(test::readAll(root + "/ds/test_targets_bop19.json"));
  ASSERT_EQ(targets.size(), 2u);
  EXPECT_EQ(targets[0]["inst_count"].get<int>(), 5);
  const CliRun bop = runCli(fmt::format("bop --dataset {0}/ds --out {0}/results.csv", root));
  ASSERT_EQ(bop.code, 0) << bop.out;
  EXPECT_NE(bop.err.find("2/2 images"), std::string::npos) << "progress";
  const std::string csv = test::readAll(root + "/results.csv");
  EXPECT_EQ(csv.rfind("scene_id,im_id,obj_id,score,R,t,time\n", 0), 0u);
  for (int scene = 1; scene <= 2; ++scene) {
    const std::string images = fmt::format("{}/ds/test/{:06}", root, scene);
    ASSERT_EQ(runCli(fmt::format("detect --model {0}/binpose_models/obj_000001.bpdb --scene {1}/depth/000000.png "
                                 "--intrinsics {1}/scene_camera.json --image-id 0 --max-instances 5 --out {0}/r.json",
                                 root, images)).code, 0);
    const std::string flat = fmt::format("{}/flat{}", root, scene);
    ASSERT_EQ(runCli(fmt::format("eval --truth {} --result {}/r.json --model builtin:cap --out {}/json_eval.json", flat, root, root)).code, 0);
    const CliRun csv_eval = runCli(fmt::format("eval --truth {} --result {}/results.csv --scene-id {} --model builtin:cap --out {}/csv_eval.json",
                                               flat, root, scene, root));
    ASSERT_EQ(csv_eval.code, 0) << csv_eval.out;
    const auto a = nlohmann::json::parse(test::readAll(root + "/json_eval.json"));
    const auto b = nlohmann::json::parse(test::readAll(root + "/csv_eval.json"));
    EXPECT_GT(a["matched"].get<int>(), 0) << "scene " << scene;
    for (const char* key : {"matched", "detections", "recall", "precision"}) EXPECT_EQ(a[key], b[key]) << key;
    for (const char* key : {"mean_centroid_error_mm", "mean_angle_error_deg", "mean_add_s_mm"})
      EXPECT_NEAR(a[key].get<double>(), b[key].get<double>(), 1e-3) << key;
  }
  const CliRun several = runCli(fmt::format("eval --truth {0}/flat1 --result {0}/results.csv --model builtin:cap", root));
  EXPECT_EQ(several.code, 2);
  EXPECT_NE(several.err.find("--scene-id"), std::string::npos) << several.err;
  test::writeAll(root + "/bad.csv", "scene_id,im_id,obj_id,score,R,t,time\n1,0,1,0.5,1 0 0 0 1 0 0 0,0 0 0,-1\n");
  const CliRun bad = runCli(fmt::format("eval --truth {0}/flat1 --result {0}/bad.csv --model builtin:cap", root));
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("line 2: 8 values where 9 belong"), std::string::npos) << bad.err;
  const CliRun missing = runCli(fmt::format("bop --dataset {0}/nothing --out {0}/x.csv", root));
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("test_targets_bop19.json: no such file"), std::string::npos) << missing.err;
}
