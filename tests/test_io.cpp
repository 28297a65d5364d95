// Readers on the real files of ../shared/data and on broken files.
#include <binpose/geometry.hpp>
#include <binpose/io.hpp>
#include <binpose/scan_file.hpp>

#include "pinhole_fit.hpp"
#include "test_util.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>

using namespace binpose;
using test::dataPath;
using test::errorOf;

namespace {
void expectUnitOrZero(const Points& normals, bool allow_zero = false) {
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const float len = normals[i].norm();
    if (allow_zero && len == 0.0f) continue;
    ASSERT_NEAR(len, 1.0f, 1e-5f) << "normal " << i;
  }
}

/// Cuts a file to a fraction of its length in a temporary copy.
std::string truncatedCopy(const std::string& path, double fraction, const std::string& name) {
  const std::string bytes = test::readAll(path);
  const std::string out = test::tempPath(name);
  test::writeAll(out, bytes.substr(0, static_cast<std::size_t>(bytes.size() * fraction)));
  return out;
}

template <typename T>
void putBig(std::string& s, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (std::size_t i = 0; i < sizeof(T); ++i) s.push_back(b[sizeof(T) - 1 - i]);
}
template <typename T>
void putLittle(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
}  // namespace

// ---- PLY ------------------------------------------------------------------------------------

TEST(PlyReader, UwaModelAsciiWithNonUnitNormals) {
  REQUIRE_DATA("uwa/parasaurolophus_6700.ply");
  const Mesh mesh = readPlyMesh(dataPath("uwa/parasaurolophus_6700.ply"));
  EXPECT_EQ(mesh.vertices.size(), 6700u);  // shared/data/uwa/README_source.md
  EXPECT_EQ(mesh.faces.size(), 9140u);
  ASSERT_TRUE(mesh.hasNormals());
  expectUnitOrZero(mesh.normals, true);  // file normals have median length 3.6: normalised here
  Vec3 lo, hi;
  ASSERT_TRUE(bounds(mesh.vertices, lo, hi));
  // extents from an independent Python parse of the file
  EXPECT_NEAR(lo.x(), -55.1494, 1e-3); EXPECT_NEAR(hi.x(), 174.851, 1e-3);
  EXPECT_NEAR(lo.y(), -191.326, 1e-3); EXPECT_NEAR(hi.y(), 71.3345, 1e-3);
  EXPECT_NEAR(lo.z(), -686.019, 1e-3); EXPECT_NEAR(hi.z(), -582.992, 1e-3);
}

TEST(PlyReader, UwaSceneAsciiHasUnitNormals) {
  REQUIRE_DATA("uwa/rs1_normals.ply");
  const PointCloud scene = readPlyCloud(dataPath("uwa/rs1_normals.ply"));
  EXPECT_EQ(scene.size(), 114373u);
  ASSERT_TRUE(scene.hasNormals());
  expectUnitOrZero(scene.normals);
  Vec3 lo, hi;
  bounds(scene.points, lo, hi);
  EXPECT_GT(lo.z(), -760.0f);  // README: z from about -750 to -570 mm
  EXPECT_LT(hi.z(), -560.0f);
}

TEST(PlyReader, IpdPartsBinaryMatchModelsInfo) {
  REQUIRE_DATA("ipd_parts/models/models_info.json");
  const auto info = nlohmann::json::parse(test::readAll(dataPath("ipd_parts/models/models_info.json")));
  // Vertex counts and minima from an independent Python (struct) parse of the files; the
  // min_* of models_info.json do not match these files (obj 1 is off by a whole size), its
  // size_* do.
  struct Expected { const char* id; std::size_t vertices; double min[3]; };
  const Expected parts[] = {{"0", 1796, {-19.0504, -38.1040, -28.5803}},
                            {"1", 366, {-38.1056, -38.1047, -28.5772}},
                            {"4", 3092, {-25.4000, -25.4000, -25.4000}},
                            {"8", 4668, {-28.5278, -14.9650, -28.4101}},
                            {"10", 16259, {-42.0120, -38.3407, -18.1500}}};
  for (const Expected& e : parts) {
    const std::string file = fmt::format("ipd_parts/models/obj_{:06d}.ply", std::stoi(e.id));
    const Mesh mesh = readPlyMesh(dataPath(file));
    EXPECT_EQ(mesh.vertices.size(), e.vertices) << file;
    ASSERT_TRUE(mesh.hasNormals()) << file;
    expectUnitOrZero(mesh.normals, true);
    Vec3 lo, hi;
    bounds(mesh.vertices, lo, hi);
    const auto& m = info[e.id];
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(lo[k], e.min[k], 1e-3) << file;
    EXPECT_NEAR(hi.x() - lo.x(), m["size_x"].get<double>(), 1e-3) << file;
    EXPECT_NEAR(hi.y() - lo.y(), m["size_y"].get<double>(), 1e-3) << file;
    EXPECT_NEAR(hi.z() - lo.z(), m["size_z"].get<double>(), 1e-3) << file;
  }
}

// A depth image saved as a PLY in its camera's frame (points only, holes dropped) is read back as
// the depth image: the pixel lattice of its points' x / z and y / z gives its focal lengths, its
// pixels and the camera at the origin. The same points moved 5 mm sideways lie on no lattice.
TEST(PlyReader, DepthImageSavedAsPlyGetsItsPixelsBack) {
  constexpr float kF = 550.0f, kCx = 99.5f, kCy = 74.5f;
  Points pts;
  std::vector<std::int32_t> pixels;
  for (int v = 0; v < 150; ++v)
    for (int u = 0; u < 200; ++u) {
      if ((u * 7 + v * 3) % 11 == 0) continue;  // holes
      const float z = 700.0f + 0.3f * float(u) + 2.0f * std::sin(0.1f * float(v));
      pts.emplace_back((float(u) - kCx) / kF * z, (float(v) - kCy) / kF * z, z);
      pixels.push_back(v * 200 + u);
    }
  const std::string path = test::tempPath("image.ply");
  writePly(path, pts);
  const PointCloud back = readPlyCloud(path);
  ASSERT_TRUE(back.organized());
  EXPECT_NEAR(back.fx, kF, 1e-3f);
  EXPECT_NEAR(back.fy, kF, 1e-3f);
  EXPECT_NEAR(back.cx, kCx, 1e-3f);
  EXPECT_NEAR(back.cy, kCy, 1e-3f);
  EXPECT_EQ(back.width, 200);
  EXPECT_EQ(back.height, 150);
  EXPECT_TRUE(back.has_viewpoint);
  ASSERT_EQ(back.pixel, pixels);  // every point on its own pixel, in pixel order
  // A depth SDK's cloud of every pixel, (0, 0, 0) at the holes (isMeasured): the same image.
  Points every(200 * 150, Vec3::Zero());
  for (std::size_t i = 0; i < pts.size(); ++i) every[std::size_t(pixels[i])] = pts[i];
  writePly(path, every);
  const PointCloud holes = readPlyCloud(path);
  ASSERT_TRUE(holes.organized());
  EXPECT_NEAR(holes.fx, kF, 1e-3f);
  EXPECT_EQ(holes.pixel, pixels);
  EXPECT_EQ(holes.points, back.points);
  Points moved = pts;
  for (Vec3& p : moved) p += Vec3(5.0f, 0.0f, 0.0f);
  writePly(path, moved);
  const PointCloud elsewhere = readPlyCloud(path);
  EXPECT_FALSE(elsewhere.organized());
  EXPECT_EQ(elsewhere.fx, 0.0f);
}

TEST(PlyReader, RoundTripAllThreeEncodings) {
  Rng rng(3);
  Points pts, nrm;
  for (int i = 0; i < 500; ++i) {
    pts.emplace_back(float(rng.uniform() * 100 - 50), float(rng.uniform() * 100), float(-rng.uniform() * 700));
    Vec3 n(float(rng.uniform() - 0.5), float(rng.uniform() - 0.5), float(rng.uniform() - 0.5));
    nrm.push_back(n.normalized());
  }
  for (const PlyFormat format : {PlyFormat::Ascii, PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian}) {
    const std::string path = test::tempPath(fmt::format("rt{}.ply", int(format)));
    writePly(path, pts, nrm, {}, format);
    const PointCloud back = readPlyCloud(path);
    ASSERT_EQ(back.size(), pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      EXPECT_NEAR((back.points[i] - pts[i]).norm(), 0.0f, 1e-4f);
      EXPECT_NEAR((back.normals[i] - nrm[i]).norm(), 0.0f, 1e-5f);
    }
  }
}

TEST(PlyReader, BigEndianDoublesExtraPropertiesQuadsAndMetres) {
  // Hand-made: double coordinates, an extra uchar property, an extra element, a quad face.
  std::string s = "ply\nformat binary_big_endian 1.0\ncomment hand made\nelement vertex 4\n"
                  "property double x\nproperty double y\nproperty uchar quality\nproperty double z\n"
                  "element camera 1\nproperty float fov\n"
                  "element face 1\nproperty list uchar uint vertex_indices\nend_header\n";
  const double v[4][3] = {{0, 0, 0}, {0.001, 0, 0}, {0.001, 0.002, 0}, {0, 0.002, 0.0005}};
  for (const auto& p : v) {
    putBig(s, p[0]); putBig(s, p[1]); putBig<std::uint8_t>(s, 7); putBig(s, p[2]);
  }
  putBig(s, 1.5f);
  putBig<std::uint8_t>(s, 4);
  for (std::uint32_t i = 0; i < 4; ++i) putBig(s, i);
  const std::string path = test::tempPath("be.ply");
  test::writeAll(path, s);
  const Mesh mesh = readPlyMesh(path, unitScale(Units::Metres));
  ASSERT_EQ(mesh.vertices.size(), 4u);
  EXPECT_FALSE(mesh.hasNormals());
  EXPECT_NEAR(mesh.vertices[2].x(), 1.0f, 1e-6);
  EXPECT_NEAR(mesh.vertices[2].y(), 2.0f, 1e-6);
  EXPECT_NEAR(mesh.vertices[3].z(), 0.5f, 1e-6);
  ASSERT_EQ(mesh.faces.size(), 2u);  // the quad, fan-triangulated
  EXPECT_EQ(mesh.faces[1], Eigen::Vector3i(0, 2, 3));
}

TEST(PlyReader, ZeroNormalIsMissing) {
  const std::string path = test::tempPath("zero.ply");
  test::writeAll(path,
                 "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                 "property float nx\nproperty float ny\nproperty float nz\nend_header\n"
                 "0 0 1 0 0 0\n1 0 0 0 0 5\n");
  const PointCloud c = readPlyCloud(path);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.normals[0], Vec3::Zero());
  EXPECT_EQ(c.normals[1], Vec3(0, 0, 1));
}

TEST(PlyReader, BrokenFilesGiveOneLineErrors) {
  REQUIRE_DATA("ipd_parts/models/obj_000001.ply");
  const std::string cut = truncatedCopy(dataPath("ipd_parts/models/obj_000001.ply"), 0.5, "cut.ply");
  EXPECT_NE(errorOf([&] { readPlyMesh(cut); }).find("truncated"), std::string::npos);
  const std::string cut_ascii = truncatedCopy(dataPath("uwa/parasaurolophus_6700.ply"), 0.3, "cut_ascii.ply");
  const std::string e = errorOf([&] { readPlyMesh(cut_ascii); });
  EXPECT_NE(e.find(cut_ascii), std::string::npos) << "the error names the file";
  EXPECT_NE(e.find("truncated"), std::string::npos);
  EXPECT_EQ(e.find('\n'), std::string::npos) << "one line";

  const std::string header = test::tempPath("header.ply");
  test::writeAll(header, "plx\nformat ascii 1.0\nend_header\n");
  EXPECT_NE(errorOf([&] { readPlyCloud(header); }).find("not a PLY file"), std::string::npos);
  test::writeAll(header, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                         "property float z\n");
  EXPECT_NE(errorOf([&] { readPlyCloud(header); }).find("end_header"), std::string::npos);
  test::writeAll(header, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float64x x\nend_header\n1\n");
  EXPECT_NE(errorOf([&] { readPlyCloud(header); }).find("unknown PLY property type"), std::string::npos);

  const std::string nan = test::tempPath("nan.ply");
  test::writeAll(nan,
                 "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                 "0 0 1\nnan 1 0\n1 1 0\n3 0 1 2\n");
  EXPECT_NE(errorOf([&] { readPlyMesh(nan); }).find("non-finite"), std::string::npos);
  EXPECT_EQ(readPlyCloud(nan).size(), 2u);  // a scan drops the NaN point instead

  const std::string bad_face = test::tempPath("badface.ply");
  test::writeAll(bad_face, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                           "0 0 0\n1 0 0\n1 1 0\n3 0 1 7\n");
  EXPECT_NE(errorOf([&] { readPlyMesh(bad_face); }).find("refers to vertex 7"), std::string::npos);
  const std::string word = test::tempPath("word.ply");
  test::writeAll(word, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                       "end_header\n0 zero 0\n");
  EXPECT_NE(errorOf([&] { readPlyCloud(word); }).find("bad number 'zero'"), std::string::npos);
  EXPECT_NE(errorOf([&] { readPlyCloud(test::tempPath("absent.ply")); }).find("no such file"), std::string::npos);
}

// ---- ASCII point files ------------------------------------------------------------------------

namespace {
/// `cloud` as text, one point a line: `header` first (when not empty), then x y z (nx ny nz) and
/// `extra` columns, split by `sep`.
std::string asText(const PointCloud& cloud, const std::string& header, const std::string& sep, bool normals,
                   const std::string& extra = "") {
  std::string text = header.empty() ? "" : header + "\n";
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3& p = cloud.points[i];
    text += fmt::format("{:.6f}{}{:.6f}{}{:.6f}", p.x(), sep, p.y(), sep, p.z());
    if (normals) {
      const Vec3& n = cloud.normals[i];
      text += fmt::format("{}{:.6f}{}{:.6f}{}{:.6f}", sep, n.x(), sep, n.y(), sep, n.z());
    }
    text += extra.empty() ? "\n" : sep + extra + "\n";
  }
  return text;
}

void expectSameCloud(const PointCloud& a, const PointCloud& b, bool normals) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(b.hasNormals(), normals);
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_LT((a.points[i] - b.points[i]).norm(), 1e-4f) << "point " << i;
    if (normals) {
      ASSERT_LT((a.normals[i] - b.normals[i]).norm(), 1e-5f) << "normal " << i;
    }
  }
}
}  // namespace

TEST(XyzReader, RealScanAsCsvXyzAndPtsReadsAsItsPly) {
  REQUIRE_DATA("uwa/rs1_normals.ply");
  const PointCloud ply = readPlyCloud(dataPath("uwa/rs1_normals.ply"));
  const std::string csv = test::tempPath("rs1.csv");
  test::writeAll(csv, asText(ply, "X,Y,Z,Nx,Ny,Nz,Intensity", ",", true, "0.5"));
  expectSameCloud(ply, readCloud(csv), true);
  // Columns by name wherever they stand; a header as a comment (CloudCompare's "//X,Y,Z").
  const std::string named = test::tempPath("rs1_named.txt");
  std::string text = "// intensity;x;y;z\n";
  for (const Vec3& p : ply.points) text += fmt::format("7;{:.6f};{:.6f};{:.6f}\n", p.x(), p.y(), p.z());
  test::writeAll(named, text);
  expectSameCloud(ply, readCloud(named), false);
  // x y z r g b: the colours are no normals. In metres, with Leica's point count first.
  PointCloud metres = ply;
  for (Vec3& p : metres.points) p /= 1000.0f;
  const std::string pts = test::tempPath("rs1.pts");
  test::writeAll(pts, fmt::format("{}\n", ply.size()) + asText(metres, "", " ", false, "200 120 31"));
  const PointCloud back = readCloud(pts, unitScale(Units::Metres));
  ASSERT_EQ(back.size(), ply.size());
  EXPECT_FALSE(back.hasNormals());
  for (std::size_t i = 0; i < ply.size(); i += 97) ASSERT_LT((back.points[i] - ply.points[i]).norm(), 2e-3f);
  const ModelFile model = readModelFile(csv);
  EXPECT_FALSE(model.is_mesh);
  EXPECT_EQ(model.cloud.size(), ply.size());
}

TEST(XyzReader, DepthImageSavedAsXyzGetsItsPixelsBack) {
  constexpr float kF = 550.0f, kCx = 99.5f, kCy = 74.5f;
  PointCloud image;
  std::vector<std::int32_t> pixels;
  std::string text;  // every pixel, a hole as NaN or as (0, 0, 0) as depth SDKs write them
  for (int v = 0; v < 150; ++v)
    for (int u = 0; u < 200; ++u) {
      if ((u * 7 + v * 3) % 11 == 0) {
        text += (u % 2 == 0) ? "nan nan nan\n" : "0 0 0\n";
        continue;
      }
      const float z = 700.0f + 0.3f * float(u) + 2.0f * std::sin(0.1f * float(v));
      image.points.emplace_back((float(u) - kCx) / kF * z, (float(v) - kCy) / kF * z, z);
      pixels.push_back(v * 200 + u);
      text += fmt::format("{:.6f} {:.6f} {:.6f}\n", image.points.back().x(), image.points.back().y(), z);
    }
  const std::string path = test::tempPath("image.xyz");
  test::writeAll(path, "# a depth image, every pixel\n" + text);
  const PointCloud back = readXyz(path);
  ASSERT_TRUE(back.organized());
  EXPECT_NEAR(back.fx, kF, 1e-2f);
  EXPECT_NEAR(back.cx, kCx, 1e-2f);
  EXPECT_EQ(back.width, 200);
  EXPECT_EQ(back.pixel, pixels);
  expectSameCloud(image, back, false);
}

TEST(XyzReader, BrokenFilesGiveOneLineErrors) {
  const std::string path = test::tempPath("broken.xyz");
  const auto errorFor = [&](const std::string& text) {
    test::writeAll(path, text);
    return errorOf([&] { readXyz(path); });
  };
  EXPECT_NE(errorFor("1 2 3\n4 5 6\n7 eight 9\n").find("line 3: '7 eight 9' is not a row of numbers"), std::string::npos);
  EXPECT_NE(errorFor("1 2 3\n4 5\n").find("line 2: 2 values, 3 expected"), std::string::npos);
  EXPECT_NE(errorFor("# nothing but comments\n\n").find("no point"), std::string::npos);
  EXPECT_NE(errorFor("a,b,c\n1,2,3\n").find("names no x, y and z"), std::string::npos);
  EXPECT_NE(errorFor("x y z nx ny nz\n1 2 3 0 0 1\n1 2 3\n").find("line 3: 3 values, 6 expected"), std::string::npos);
  EXPECT_NE(errorFor("1 2 inf\n").find("line 1: a coordinate is out of range"), std::string::npos);
  EXPECT_NE(errorFor("1 2 1e300\n").find("out of range"), std::string::npos);
  const std::string e = errorFor("1 2 3\nx\ty\n");
  EXPECT_NE(e.find(path), std::string::npos) << "the error names the file";
  EXPECT_EQ(e.find('\n'), std::string::npos) << "one line";
  EXPECT_NE(errorOf([&] { readXyz(test::tempPath("absent.xyz")); }).find("no such file"), std::string::npos);
  // Units in the header's names, a value left out (no measurement), a final comma.
  test::writeAll(path, "\"X [mm]\", \"Y [mm]\", \"Z [mm]\"\n1.5, 2, 3,\n4,,6\n7, 8, 9\n");
  const PointCloud csv = readXyz(path);
  ASSERT_EQ(csv.size(), 2u);
  EXPECT_EQ(csv.points[0], Vec3(1.5f, 2, 3));
  EXPECT_EQ(csv.points[1], Vec3(7, 8, 9));
  test::writeAll(path, "x y z nx ny nz\n1 2 3 0 0 0\n4 5 6 0 3 4\n");  // a zero normal is missing
  const PointCloud c = readXyz(path);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.normals[0], Vec3::Zero());
  EXPECT_NEAR((c.normals[1] - Vec3(0, 0.6f, 0.8f)).norm(), 0.0f, 1e-6f);
}

// ---- PCD ------------------------------------------------------------------------------------

TEST(PcdReader, MilkSceneBinaryCompressedOrganized) {
  REQUIRE_DATA("pcl_milk/milk_cartoon_all_small_clorox.pcd");
  const PointCloud scene = readPcd(dataPath("pcl_milk/milk_cartoon_all_small_clorox.pcd"), unitScale(Units::Metres));
  EXPECT_EQ(scene.width, 640);
  EXPECT_EQ(scene.height, 480);
  EXPECT_EQ(scene.size(), 241407u);  // README: 241407 finite of 307200
  ASSERT_EQ(scene.pixel.size(), scene.size());
  Vec3 lo, hi;
  bounds(scene.points, lo, hi);
  EXPECT_NEAR(lo.z(), 500.0f, 10.0f);  // README: z 0.50-2.06 m
  EXPECT_NEAR(hi.z(), 2060.0f, 10.0f);
  // organized: a pixel's ray passes through its point (x/z grows with the column)
  const std::size_t a = 1000, b = scene.size() - 1000;
  EXPECT_LT(scene.pixel[a], scene.pixel[b]);
}

// An OpenNI frame's PCD gives its pixels but not its camera: the pinhole its points lie on is
// fitted (a Kinect's 525 px focal length, the image's centre), and the frame is then read as a
// depth image. The same points moved out of the camera's frame lie on no pinhole's rays.
TEST(PcdReader, OrganizedFrameGetsThePinholeItsPointsLieOn) {
  REQUIRE_DATA("pcl_milk/milk_cartoon_all_small_clorox.pcd");
  const PointCloud scene = readPcd(dataPath("pcl_milk/milk_cartoon_all_small_clorox.pcd"), unitScale(Units::Metres));
  EXPECT_NEAR(scene.fx, 525.0f, 0.01f);
  EXPECT_NEAR(scene.fy, 525.0f, 0.01f);
  EXPECT_NEAR(scene.cx, 319.5f, 0.01f);
  EXPECT_NEAR(scene.cy, 239.5f, 0.01f);
  PointCloud moved = scene;
  moved.fx = moved.fy = moved.cx = moved.cy = 0.0f;
  for (Vec3& p : moved.points) p += Vec3(5.0f, 0.0f, 0.0f);  // 5 mm sideways
  EXPECT_FALSE(fitPinhole(moved));
  EXPECT_EQ(moved.fx, 0.0f);
  PointCloud again = scene;  // intrinsics already known: kept
  again.fx = 600.0f;
  EXPECT_FALSE(fitPinhole(again));
  EXPECT_EQ(again.fx, 600.0f);
}

TEST(PcdReader, MilkModelIsASubsetOfTheScene) {
  REQUIRE_DATA("pcl_milk/milk.pcd");
  const PointCloud milk = readPcd(dataPath("pcl_milk/milk.pcd"), 1000.0);
  EXPECT_EQ(milk.size(), 13704u);
  EXPECT_FALSE(milk.organized());
  EXPECT_FALSE(milk.hasNormals());
}

TEST(PcdReader, BunnyAsciiWithNormals) {
  REQUIRE_DATA("pcl_milk/bun0.pcd");
  const PointCloud bunny = readPcd(dataPath("pcl_milk/bun0.pcd"), 1000.0);
  EXPECT_EQ(bunny.size(), 397u);
  ASSERT_TRUE(bunny.hasNormals());
  expectUnitOrZero(bunny.normals);
  EXPECT_NEAR(bunny.points[0].x(), 5.4215998f, 1e-4f);  // first data line of the file, in mm
  EXPECT_NEAR(bunny.points[0].z(), 40.748999f, 1e-4f);
}

TEST(PcdReader, BinaryWithExtraFieldsAndNaN) {
  std::string s =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb label\nSIZE 4 4 8 4 2\nTYPE F F F F U\n"
      "COUNT 1 1 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA binary\n";
  const float xy[4][2] = {{1, 2}, {NAN, 0}, {0, 0}, {4, 5}};
  const double z[4] = {3, 0, 0, 6};
  for (int i = 0; i < 4; ++i) {
    putLittle(s, xy[i][0]); putLittle(s, xy[i][1]); putLittle(s, z[i]);
    putLittle(s, 0.25f); putLittle<std::uint16_t>(s, 9);
  }
  const std::string path = test::tempPath("bin.pcd");
  test::writeAll(path, s);
  const PointCloud c = readPcd(path);
  ASSERT_EQ(c.size(), 2u);  // the NaN point and the origin (a pixel without a depth) are dropped
  EXPECT_EQ(c.points[1], Vec3(4, 5, 6));
  test::writeAll(path, s.substr(0, s.size() - 5));
  EXPECT_NE(errorOf([&] { readPcd(path); }).find("truncated"), std::string::npos);
}

TEST(PcdReader, BrokenFiles) {
  REQUIRE_DATA("pcl_milk/milk.pcd");
  const std::string cut = truncatedCopy(dataPath("pcl_milk/milk.pcd"), 0.6, "cut.pcd");
  EXPECT_NE(errorOf([&] { readPcd(cut); }).find("truncated"), std::string::npos);
  std::string bytes = test::readAll(dataPath("pcl_milk/milk.pcd"));
  bytes[bytes.size() / 2] ^= 0x77;  // corrupt the LZF stream
  bytes[bytes.size() / 2 + 1] ^= 0x33;
  const std::string corrupt = test::tempPath("corrupt.pcd");
  test::writeAll(corrupt, bytes);
  // LZF has no checksum: a corrupt stream either fails to decode or decodes to garbage of the
  // right size; the reader must never crash or read out of bounds (ASan checks that).
  try {
    readPcd(corrupt);
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(corrupt), std::string::npos);
  }
  const std::string header = test::tempPath("header.pcd");
  test::writeAll(header, "VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n");
  EXPECT_NE(errorOf([&] { readPcd(header); }).find("SIZE has 2 entries"), std::string::npos);
  test::writeAll(header, "VERSION 0.7\nFIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n");
  EXPECT_NE(errorOf([&] { readPcd(header); }).find("lacks an x"), std::string::npos);
  test::writeAll(header, "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nPOINTS 2\nDATA ascii\n1 2 3\n4 5\n");
  EXPECT_NE(errorOf([&] { readPcd(header); }).find("truncated"), std::string::npos);
  test::writeAll(header, "hello world\n");
  EXPECT_NE(errorOf([&] { readPcd(header); }).find("PCD"), std::string::npos);
}

// ---- Meshes via assimp ----------------------------------------------------------------------

TEST(MeshReader, ObjFilesOfCommon3d) {
  REQUIRE_DATA("models_common3d/fandisk.obj");
  const Mesh fandisk = readMesh(dataPath("models_common3d/fandisk.obj"));
  EXPECT_EQ(fandisk.faces.size(), 12946u);  // README: 6475 v, 12946 f
  EXPECT_EQ(fandisk.vertices.size(), 6475u);
  const Mesh bunny = readMesh(dataPath("models_common3d/stanford-bunny.obj"), unitScale(Units::Metres));
  EXPECT_EQ(bunny.faces.size(), 69451u);
  Vec3 lo, hi;
  bounds(bunny.vertices, lo, hi);
  const Vec3 extent = hi - lo;  // README: 0.156 x 0.154 x 0.121 m
  EXPECT_NEAR(extent.x(), 156.0f, 1.0f);
  EXPECT_NEAR(extent.y(), 154.0f, 1.0f);
  EXPECT_NEAR(extent.z(), 121.0f, 1.0f);
}

TEST(MeshReader, StlAndErrors) {
  const std::string stl = test::tempPath("tet.stl");
  test::writeAll(stl, "solid t\n"
                      "facet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 10 0\nvertex 10 0 0\nendloop\nendfacet\n"
                      "facet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 10 0 0\nvertex 0 0 10\nendloop\nendfacet\n"
                      "facet normal -1 0 0\nouter loop\nvertex 0 0 0\nvertex 0 0 10\nvertex 0 10 0\nendloop\nendfacet\n"
                      "facet normal 1 1 1\nouter loop\nvertex 10 0 0\nvertex 0 10 0\nvertex 0 0 10\nendloop\nendfacet\n"
                      "endsolid t\n");
  const Mesh tet = readMesh(stl);
  EXPECT_EQ(tet.faces.size(), 4u);
  EXPECT_EQ(tet.vertices.size(), 4u);  // shared corners joined
  const std::string junk = test::tempPath("junk.obj");
  test::writeAll(junk, "this is not a mesh\n");
  EXPECT_NE(errorOf([&] { readMesh(junk); }).find(junk), std::string::npos);
}

// A scan saved as an OBJ of vertices alone (a point cloud tool's export) is a scan, not an error;
// as a model it is still no mesh.
TEST(MeshReader, ObjOfVerticesAloneIsAScan) {
  REQUIRE_DATA("uwa/rs1_normals.ply");
  const PointCloud ply = readPlyCloud(dataPath("uwa/rs1_normals.ply"));
  std::string text = "# vertices only\n";
  for (const Vec3& p : ply.points) text += fmt::format("v {:.6f} {:.6f} {:.6f}\n", p.x(), p.y(), p.z());
  const std::string obj = test::tempPath("rs1_points.obj");
  test::writeAll(obj, text);
  const PointCloud back = readCloud(obj);
  ASSERT_EQ(back.size(), ply.size());
  for (std::size_t i = 0; i < ply.size(); ++i) ASSERT_LT((back.points[i] - ply.points[i]).norm(), 1e-4f) << i;
  EXPECT_NE(errorOf([&] { readMesh(obj); }).find("mesh has no triangles"), std::string::npos);
}

// OFF is read by binpose (assimp's importer is not safe on crafted files): comments, counts on
// their own line, extra values per vertex, a quad split in two, metres to millimetres.
TEST(MeshReader, OffWithCommentsQuadsAndMetres) {
  const std::string off = test::tempPath("box.off");
  test::writeAll(off, "OFF # a unit square and a triangle over it\n"
                      "\n5 3 0\n"
                      "0 0 0\n0.01 0 0 255 0 0\n0.01 0.01 0\n0 0.01 0\n0.005 0.005 0.01\n"
                      "4 0 1 2 3\n3 0 1 4 0.5 0.5 0.5\n3 2 3 4\n");
  const Mesh mesh = readMesh(off, unitScale(Units::Metres));
  ASSERT_EQ(mesh.vertices.size(), 5u);
  ASSERT_EQ(mesh.faces.size(), 4u);  // the quad fans into (0 1 2) and (0 2 3)
  EXPECT_EQ(mesh.faces[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_TRUE(mesh.vertices[4].isApprox(Vec3(5, 5, 10)));
  const std::pair<std::string, std::string> broken[] = {
      {"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 7\n", "face 0 refers to vertex 7 of 4"},
      {"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n5 0 1 2\n", "face 0 lists 5 vertices but gives 3"},
      {"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n", "truncated"},
      {"OFF\n4 1 0\n0 0 0\n1 nan 0\n0 1 0\n0 0 1\n3 0 1 2\n", "bad coordinate"},
      {"OFF\n4 1 0\n0 0 0\n1 5e69 0\n0 1 0\n0 0 1\n3 0 1 2\n", "out of range"},  // a double, not a float
      {"OFF\n1e30 1 0\n", "vertex count"},
      {"PLY\n", "no OFF keyword"},
  };
  for (const auto& [text, why] : broken) {
    test::writeAll(off, text);
    const std::string message = errorOf([&] { readMesh(off); });
    EXPECT_NE(message.find(why), std::string::npos) << why << ": " << message;
    EXPECT_EQ(message.rfind(off, 0), 0u) << message;
  }
}

// ---- Depth images and intrinsics ------------------------------------------------------------

TEST(DepthReader, PlaneBackProjectsExactly) {
  Intrinsics k;
  k.fx = 600; k.fy = 610; k.cx = 31.5; k.cy = 23.5; k.depth_scale = 0.1;  // raw units of 0.1 mm
  const int w = 64, h = 48;
  std::vector<std::uint16_t> depth(w * h);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) depth[v * w + u] = static_cast<std::uint16_t>(5000 + 10 * u + 3 * v);
  depth[5] = 0;  // a hole
  const std::string path = test::tempPath("depth.png");
  writeDepthPng(path, depth, w, h);
  const PointCloud c = readDepthPng(path, k);
  ASSERT_EQ(c.size(), std::size_t(w * h - 1));
  EXPECT_EQ(c.width, w);
  for (std::size_t i = 0; i < c.size(); ++i) {
    const int u = c.pixel[i] % w, v = c.pixel[i] / w;
    const double z = (5000 + 10 * u + 3 * v) * 0.1;
    ASSERT_NEAR(c.points[i].z(), z, 1e-3);
    ASSERT_NEAR(c.points[i].x(), (u - 31.5) * z / 600, 1e-3);
    ASSERT_NEAR(c.points[i].y(), (v - 23.5) * z / 610, 1e-3);
  }
  test::writeAll(path, test::readAll(path).substr(0, 60));
  EXPECT_NE(errorOf([&] { readDepthPng(path, k); }).find("PNG"), std::string::npos);
  k.width = 10; k.height = 10;
  writeDepthPng(path, depth, w, h);
  EXPECT_NE(errorOf([&] { readDepthPng(path, k); }).find("intrinsics say 10x10"), std::string::npos);
}

TEST(DepthReader, IntrinsicsFiles) {
  REQUIRE_DATA("ipd_parts/camera_photoneo.json");
  const Intrinsics k = readIntrinsics(dataPath("ipd_parts/camera_photoneo.json"));
  EXPECT_DOUBLE_EQ(k.fx, 2320.26);
  EXPECT_DOUBLE_EQ(k.cy, 805.064);
  EXPECT_DOUBLE_EQ(k.depth_scale, 0.1);
  EXPECT_EQ(k.width, 2064);
  const std::string scene = test::tempPath("scene_camera.json");
  test::writeAll(scene, R"({"0": {"cam_K": [500, 0, 320, 0, 501, 240, 0, 0, 1], "depth_scale": 0.5},
                            "7": {"cam_K": [700, 0, 300, 0, 701, 200, 0, 0, 1], "depth_scale": 1.0}})");
  EXPECT_DOUBLE_EQ(readIntrinsics(scene).fx, 500);
  EXPECT_DOUBLE_EQ(readIntrinsics(scene, "7").fy, 701);
  EXPECT_DOUBLE_EQ(readIntrinsics(scene, "7").cy, 200);
  EXPECT_NE(errorOf([&] { readIntrinsics(scene, "3"); }).find("no entry for image '3'"), std::string::npos);
  test::writeAll(scene, R"({"fx": -1, "fy": 500, "cx": 1, "cy": 1})");
  EXPECT_NE(errorOf([&] { readIntrinsics(scene); }).find("positive"), std::string::npos);
  test::writeAll(scene, "{not json");
  EXPECT_NE(errorOf([&] { readIntrinsics(scene); }).find("not a JSON object"), std::string::npos);
}

TEST(DepthReader, CameraFilesOfOtherTools) {
  const std::string path = test::tempPath("camera_other.json");
  const auto read = [&](const std::string& text) {
    test::writeAll(path, text);
    return readIntrinsics(path);
  };
  const auto expectCamera = [](const Intrinsics& k, int width) {
    EXPECT_DOUBLE_EQ(k.fx, 615.5);
    EXPECT_DOUBLE_EQ(k.fy, 616.25);
    EXPECT_DOUBLE_EQ(k.cx, 321.75);
    EXPECT_DOUBLE_EQ(k.cy, 238.5);
    EXPECT_EQ(k.width, width);
  };
  // Open3D's PinholeCameraIntrinsic (column-major).
  expectCamera(read(R"({"width": 640, "height": 480, "intrinsic_matrix": [615.5, 0, 0, 0, 616.25, 0, 321.75, 238.5, 1]})"), 640);
  // ROS CameraInfo (row-major K; k in ROS 2) and OpenCV's FileStorage matrix.
  expectCamera(read(R"({"width": 640, "height": 480, "K": [615.5, 0, 321.75, 0, 616.25, 238.5, 0, 0, 1]})"), 640);
  expectCamera(read(R"({"k": [[615.5, 0, 321.75], [0, 616.25, 238.5], [0, 0, 1]]})"), 0);
  expectCamera(read(R"({"camera_matrix": {"type_id": "opencv-matrix", "rows": 3, "cols": 3, "dt": "d",
                         "data": [615.5, 0, 321.75, 0, 616.25, 238.5, 0, 0, 1]}})"),
               0);
  // RealSense's names for the principal point.
  expectCamera(read(R"({"fx": 615.5, "fy": 616.25, "ppx": 321.75, "ppy": 238.5, "width": 640})"), 640);
  EXPECT_NE(errorOf([&] { read(R"({"K": [615.5, 0, 321.75, 1, 616.25, 238.5, 5, 0, 1]})"); }).find("no camera matrix"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { read(R"({"K": [615.5, 0, 321.75, 0, 616.25]})"); }).find("K must hold 9 numbers"), std::string::npos);
  EXPECT_NE(errorOf([&] { read(R"({"K": [615.5, 0, "x", 0, 616.25, 238.5, 0, 0, 1]})"); }).find("9 numbers"), std::string::npos);
}

TEST(Units, ParseAndScale) {
  EXPECT_EQ(unitScale(parseUnits("m")), 1000.0);
  EXPECT_EQ(unitScale(parseUnits("mm")), 1.0);
  EXPECT_EQ(unitScale(parseUnits("cm")), 10.0);
  EXPECT_EQ(unitScale(parseUnits("in")), 25.4);
  EXPECT_THROW(parseUnits("ft"), Error);
}

TEST(ScanFile, DepthImageByItsCameraFileItsUnitGuessedFromThePart) {
  REQUIRE_DATA("icbin_mixed/depth/0000.png");
  const std::string png = dataPath("icbin_mixed/depth/0000.png"), camera = dataPath("icbin_mixed/camera.json");
  const LoadedScan mm = loadScan({png, camera, "", "auto"}, 136.0f);
  EXPECT_FALSE(mm.guessed_metres);
  // The camera file giving metres a unit (depth_scale 0.001, as RealSense's SDK reports it).
  nlohmann::json j = nlohmann::json::parse(test::readAll(camera));
  j["depth_scale"] = 0.001;
  const std::string in_metres = test::tempPath("camera_m.json");
  test::writeAll(in_metres, j.dump());
  const LoadedScan guessed = loadScan({png, in_metres, "", "auto"}, 136.0f);
  EXPECT_TRUE(guessed.guessed_metres);
  ASSERT_EQ(guessed.cloud.size(), mm.cloud.size());
  for (std::size_t i = 0; i < mm.cloud.size(); i += 997) ASSERT_NEAR(guessed.cloud.points[i].z(), mm.cloud.points[i].z(), 1e-3f);
  EXPECT_NEAR(loadScan({png, in_metres, "", "mm"}, 136.0f).cloud.points[0].z(), mm.cloud.points[0].z() / 1000.0f, 1e-6f);
  EXPECT_NE(errorOf([&] { loadScan({png, "", "", "auto"}, 136.0f); }).find("needs its camera's intrinsics"), std::string::npos);
  // The extension in capitals, as some cameras' software writes it, is a depth image too.
  const std::string upper = test::tempPath("depth_upper.PNG");
  std::filesystem::copy_file(png, upper, std::filesystem::copy_options::overwrite_existing);
  EXPECT_EQ(loadScan({upper, camera, "", "auto"}, 136.0f).cloud.size(), mm.cloud.size());
  EXPECT_NE(errorOf([&] { loadScan({upper, "", "", "auto"}, 136.0f); }).find("needs its camera's intrinsics"), std::string::npos);
  EXPECT_NE(errorOf([&] { loadScan({png, camera, "", "km"}, 136.0f); }).find("'mm', 'cm', 'm' or 'in'"), std::string::npos);
}
