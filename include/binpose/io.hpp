#pragma once
// Readers and writers for scans and models (issue 2). Every reader converts to millimetres by
// `scale` (1 for files in mm, 1000 for files in metres) and throws binpose::Error with a
// one-line message naming the file and the problem on any malformed or truncated input.
#include <binpose/types.hpp>

#include <string>

namespace binpose {

/// Length unit of a file on disk.
enum class Units { Millimetres, Centimetres, Metres, Inches };
/// Factor from `units` to millimetres.
double unitScale(Units units);
/// Parses "mm", "cm", "m" or "in" (throws on anything else).
Units parseUnits(const std::string& text);
/// A scan spanning less than this share of a part's diameter cannot hold it: read in millimetres,
/// it is one in metres.
inline constexpr float kLeastScanShareOfPart = 0.5f;

/// PLY (ascii, binary_little_endian, binary_big_endian). Vertices x,y,z (float or double),
/// optional nx,ny,nz (normalised; a zero normal marks the file's normals as unusable), optional
/// faces (polygons fan-triangulated). Other elements and properties are skipped.
Mesh readPlyMesh(const std::string& path, double scale = 1.0);
/// PLY as a point cloud (faces ignored).
PointCloud readPlyCloud(const std::string& path, double scale = 1.0);

/// PCD v0.5-0.7: DATA ascii, binary or binary_compressed (LZF); organized or not. Points with a
/// non-finite coordinate are dropped; normal_x/y/z are read when present.
PointCloud readPcd(const std::string& path, double scale = 1.0);

/// ASCII point cloud, one point a line (.xyz, .txt, .csv, .asc, .pts): columns split by commas or
/// semicolons (an empty field is a value left out: NaN), else by spaces and tabs; '#', '%' and
/// "//" lines are comments. A header line (or a comment before the data) naming x, y, z (and nx,
/// ny, nz; "X [mm]" names x) sets the columns; without one x y z come first, and columns 4-6 are
/// normals when every row holds a unit vector there (so "x y z r g b" keeps no normals). A first
/// line of one number (a .pts point count) is skipped; points with a NaN coordinate or at (0, 0,
/// 0) are dropped as points without a measurement.
PointCloud readXyz(const std::string& path, double scale = 1.0);

/// OFF (Geomview): "OFF", the vertex and face counts, x y z per vertex (further values ignored),
/// then n i_1 .. i_n per face (fan-triangulated; colour values after them ignored).
Mesh readOffMesh(const std::string& path, double scale = 1.0);

/// Triangle mesh by extension: .ply by readPlyMesh, .off by readOffMesh, others (.stl, .obj, ...)
/// by assimp.
Mesh readMesh(const std::string& path, double scale = 1.0);

/// Whether readXyz reads this file (by its extension).
bool isXyzPath(const std::string& path);

/// Whether a file is a TIFF (by its extension): a depth map (readDepthTiff) or a point map
/// (readTiffPointMap).
bool isTiffPath(const std::string& path);

/// Any scan as a point cloud, by extension: .ply, .pcd, an ASCII point file (readXyz), a TIFF point
/// map (readTiffPointMap), or a mesh format (its vertices; an OBJ of vertices alone too). Points at
/// NaN or the origin are dropped.
PointCloud readCloud(const std::string& path, double scale = 1.0);

/// A model file: a mesh when it has faces (`mesh` set), otherwise a point cloud.
struct ModelFile {
  bool is_mesh = false;
  Mesh mesh;
  PointCloud cloud;
};
/// .ply with faces and mesh formats give a mesh; .pcd, ASCII point files and .ply without faces a
/// cloud.
ModelFile readModelFile(const std::string& path, double scale = 1.0);

/// Pinhole intrinsics of a depth sensor. depth_scale converts a raw depth value to millimetres
/// (BOP convention: depth_mm = raw * depth_scale).
struct Intrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double depth_scale = 1.0;
  int width = 0, height = 0;  ///< 0 when the file does not say
};

/// BOP `camera.json` ({fx, fy, cx, cy, depth_scale, width, height}; cx, cy also as RealSense's ppx,
/// ppy; or the 3 x 3 camera matrix as ROS's K or k, OpenCV's camera_matrix, Open3D's column-major
/// intrinsic_matrix, 9 numbers, 3 rows or {"data": [9]}) or `scene_camera.json`
/// ({"<image id>": {"cam_K": [9 values], "depth_scale": s}}; `image_id` picks the entry, the
/// first one when empty).
Intrinsics readIntrinsics(const std::string& path, const std::string& image_id = "");

/// 16-bit grayscale PNG depth image into an organized cloud in the camera frame (mm); pixels
/// with depth 0 are dropped.
PointCloud readDepthPng(const std::string& path, const Intrinsics& intrinsics);
/// TIFF depth map (.tif, .tiff; one value a pixel: 16- or 32-bit integer, 32- or 64-bit float; in
/// strips, any compression libtiff reads), as industrial 3-D cameras' software exports it, into an
/// organized cloud in the camera frame (mm: value * depth_scale); pixels at 0, below it, NaN or
/// infinite are dropped. A file of several pages gives its first.
PointCloud readDepthTiff(const std::string& path, const Intrinsics& intrinsics);
/// TIFF point map: x, y, z (a fourth value ignored) as 32- or 64-bit floats each pixel, in the
/// camera's frame (mm times `scale`), into an organized cloud whose pinhole is fitted to its pixels'
/// rays; pixels at NaN or the origin are dropped.
PointCloud readTiffPointMap(const std::string& path, double scale = 1.0);
/// The cloud of a depth image already in memory (row-major, width*height raw values).
PointCloud depthToCloud(const std::vector<std::uint16_t>& depth, int width, int height,
                        const Intrinsics& intrinsics);
/// The same for a depth image of floats (a depth SDK's array): value * depth_scale mm; values at
/// or below 0, NaN, infinite or beyond 100 km are no measurement.
PointCloud depthToCloud(const std::vector<float>& depth, int width, int height, const Intrinsics& intrinsics);
/// An organized point map (width * height points, row-major, in the camera's frame, mm) as a cloud:
/// points at NaN or the origin dropped, each kept one's pixel noted, and the pinhole fitted to its
/// pixels' rays where they lie on them (as a depth image's do).
PointCloud pointMapToCloud(const Points& xyz, int width, int height);
/// Writes a 16-bit grayscale PNG (used by tests and the simulator).
void writeDepthPng(const std::string& path, const std::vector<std::uint16_t>& depth, int width,
                   int height);

enum class PlyFormat { Ascii, BinaryLittleEndian, BinaryBigEndian };
/// Writes vertices (and normals when present) and, if given, faces.
void writePly(const std::string& path, const Points& points, const Points& normals = {},
              const std::vector<Eigen::Vector3i>& faces = {}, PlyFormat format = PlyFormat::BinaryLittleEndian);

}  // namespace binpose
