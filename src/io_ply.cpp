// PLY reader and writer (ascii, binary little- and big-endian).
#include "io_detail.hpp"
#include "pinhole_fit.hpp"

#include <binpose/io.hpp>

#include <array>
#include <cmath>
#include <fstream>
#include <optional>

namespace binpose {
namespace {

using detail::fail;
using detail::Scalar;

struct Property {
  std::string name;
  Scalar type = Scalar::Float32;
  bool is_list = false;
  Scalar count_type = Scalar::UInt8;
};

struct Element {
  std::string name;
  std::size_t count = 0;
  std::vector<Property> properties;
};

struct Header {
  PlyFormat format = PlyFormat::Ascii;
  std::vector<Element> elements;
  std::size_t body_offset = 0;
};

std::optional<Scalar> plyScalar(std::string_view name) {
  if (name == "char" || name == "int8") return Scalar::Int8;
  if (name == "uchar" || name == "uint8") return Scalar::UInt8;
  if (name == "short" || name == "int16") return Scalar::Int16;
  if (name == "ushort" || name == "uint16") return Scalar::UInt16;
  if (name == "int" || name == "int32") return Scalar::Int32;
  if (name == "uint" || name == "uint32") return Scalar::UInt32;
  if (name == "float" || name == "float32") return Scalar::Float32;
  if (name == "double" || name == "float64") return Scalar::Float64;
  return std::nullopt;
}

Scalar requireScalar(const std::string& path, std::string_view name) {
  const auto type = plyScalar(name);
  if (!type) fail(path, fmt::format("unknown PLY property type '{}'", name));
  return *type;
}

/// The most elements of one kind a PLY header may claim (the body is checked against the
/// claim before anything is allocated).
constexpr std::size_t kMostElements = (std::size_t{1} << 31) - 1;
/// The longest list a PLY element may hold.
constexpr double kMostListLength = 1e6;

/// The body holds at least what the header claims: per element its fixed scalars and list
/// counts (binary), or two bytes a value (ascii).
void checkBodyLength(const std::string& path, const Header& header, std::size_t body_size) {
  std::size_t least = 0;
  for (const Element& e : header.elements) {
    std::size_t per = 0;
    for (const Property& p : e.properties)
      per += header.format == PlyFormat::Ascii ? 2 : static_cast<std::size_t>(detail::scalarSize(p.is_list ? p.count_type : p.type));
    least += detail::checkedMul(e.count, per, path, "PLY data size");
    if (least > body_size + 1)
      fail(path, fmt::format("file is truncated ({} bytes of data, the header needs at least {})", body_size, least));
  }
}

Header parseHeader(const std::string& path, const std::string& bytes) {
  if (bytes.compare(0, 3, "ply") != 0 || bytes.size() < 4 || (bytes[3] != '\n' && bytes[3] != '\r'))
    fail(path, "not a PLY file (first line is not 'ply')");
  Header header;
  bool have_format = false;
  std::size_t pos = 0;
  while (true) {
    const std::size_t eol = bytes.find('\n', pos);
    if (eol == std::string::npos) fail(path, "PLY header has no 'end_header' line");
    std::string_view line(bytes.data() + pos, eol - pos);
    pos = eol + 1;
    const auto words = detail::splitWords(line);
    if (words.empty() || words[0] == "comment" || words[0] == "obj_info" || words[0] == "ply") continue;
    if (words[0] == "end_header") break;
    if (words[0] == "format") {
      if (words.size() < 2) fail(path, "PLY 'format' line has no format");
      if (words[1] == "ascii") header.format = PlyFormat::Ascii;
      else if (words[1] == "binary_little_endian") header.format = PlyFormat::BinaryLittleEndian;
      else if (words[1] == "binary_big_endian") header.format = PlyFormat::BinaryBigEndian;
      else fail(path, fmt::format("unknown PLY format '{}'", words[1]));
      have_format = true;
    } else if (words[0] == "element") {
      if (words.size() != 3) fail(path, fmt::format("malformed PLY element line '{}'", line));
      for (const Element& e : header.elements)
        if (e.name == words[1] && (e.name == "vertex" || e.name == "face"))
          fail(path, fmt::format("PLY file has two '{}' elements", e.name));
      header.elements.push_back({std::string(words[1]), detail::parseCount(path, words[2], "PLY element count", kMostElements), {}});
    } else if (words[0] == "property") {
      if (header.elements.empty()) fail(path, "PLY property before any element");
      Property prop;
      if (words.size() == 5 && words[1] == "list") {
        prop.is_list = true;
        prop.count_type = requireScalar(path, words[2]);
        prop.type = requireScalar(path, words[3]);
        prop.name = words[4];
      } else if (words.size() == 3) {
        prop.type = requireScalar(path, words[1]);
        prop.name = words[2];
      } else {
        fail(path, fmt::format("malformed PLY property line '{}'", line));
      }
      header.elements.back().properties.push_back(prop);
    } else {
      fail(path, fmt::format("unknown PLY header keyword '{}'", words[0]));
    }
  }
  if (!have_format) fail(path, "PLY header has no 'format' line");
  header.body_offset = pos;
  checkBodyLength(path, header, bytes.size() - pos);
  return header;
}

/// Sequential reader of the body's values, ascii tokens or binary scalars.
class BodyReader {
 public:
  BodyReader(const std::string& path, const std::string& bytes, const Header& header)
      : path_(path), bytes_(bytes), pos_(header.body_offset), format_(header.format) {}

  /// Next value as a list's length: a whole number in [0, kMostListLength], else an error.
  std::size_t listLength(Scalar type, const char* what) {
    const double n = next(type, what);
    if (!(n >= 0 && n <= kMostListLength) || n != std::floor(n)) fail(path_, fmt::format("invalid list length {} in {}", n, what));
    return static_cast<std::size_t>(n);
  }

  /// Next value as double; `what` names the value for the truncation message.
  double next(Scalar type, const char* what) {
    if (format_ == PlyFormat::Ascii) return nextAscii(what);
    const auto n = static_cast<std::size_t>(detail::scalarSize(type));
    if (pos_ + n > bytes_.size()) truncated(what);
    const double v = detail::readScalar(bytes_.data() + pos_, type, format_ == PlyFormat::BinaryBigEndian);
    pos_ += n;
    return v;
  }

 private:
  double nextAscii(const char* what) {
    while (pos_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
    const std::size_t start = pos_;
    while (pos_ < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[pos_]))) ++pos_;
    if (pos_ == start) truncated(what);
    double v = 0;
    const std::string_view token(bytes_.data() + start, pos_ - start);
    if (!detail::parseNumber(token, v)) fail(path_, fmt::format("bad number '{}' in {}", token, what));
    return v;
  }
  [[noreturn]] void truncated(const char* what) const {
    fail(path_, fmt::format("file is truncated (ends inside {})", what));
  }

  const std::string& path_;
  const std::string& bytes_;
  std::size_t pos_;
  PlyFormat format_;
};

struct PlyData {
  Points points;
  Points normals;  // empty when the file has none
  std::vector<Eigen::Vector3i> faces;
  bool has_faces = false;
};

int findProperty(const Element& e, std::initializer_list<const char*> names) {
  for (std::size_t i = 0; i < e.properties.size(); ++i)
    for (const char* n : names)
      if (e.properties[i].name == n && !e.properties[i].is_list) return static_cast<int>(i);
  return -1;
}

void readVertices(const std::string& path, const Element& e, BodyReader& body, double scale, PlyData& out) {
  const std::array<int, 3> xyz{findProperty(e, {"x"}), findProperty(e, {"y"}), findProperty(e, {"z"})};
  const std::array<int, 3> nrm{findProperty(e, {"nx", "normal_x"}), findProperty(e, {"ny", "normal_y"}),
                               findProperty(e, {"nz", "normal_z"})};
  if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) fail(path, "PLY vertex element lacks x, y or z");
  const bool has_normals = nrm[0] >= 0 && nrm[1] >= 0 && nrm[2] >= 0;
  out.points.resize(e.count);
  if (has_normals) out.normals.resize(e.count);
  std::vector<double> row(e.properties.size());
  for (std::size_t v = 0; v < e.count; ++v) {
    for (std::size_t p = 0; p < e.properties.size(); ++p) {
      const Property& prop = e.properties[p];
      if (prop.is_list) {
        const std::size_t n = body.listLength(prop.count_type, "a vertex list");
        for (std::size_t k = 0; k < n; ++k) body.next(prop.type, "a vertex list");
      } else {
        row[p] = body.next(prop.type, "the vertex data");
      }
    }
    out.points[v] = Vec3(float(row[xyz[0]] * scale), float(row[xyz[1]] * scale), float(row[xyz[2]] * scale));
    if (has_normals) {
      Vec3 n{float(row[nrm[0]]), float(row[nrm[1]]), float(row[nrm[2]])};
      if (!normalizeSafe(n)) n.setZero();  // a zero normal is a missing normal
      out.normals[v] = n;
    }
  }
}

void readFaces(const std::string& path, const Element& e, BodyReader& body, PlyData& out) {
  int list = -1;
  for (std::size_t i = 0; i < e.properties.size(); ++i)
    if (e.properties[i].is_list && (e.properties[i].name == "vertex_indices" || e.properties[i].name == "vertex_index"))
      list = static_cast<int>(i);
  if (list < 0) fail(path, "PLY face element has no vertex_indices list");
  out.has_faces = true;
  out.faces.reserve(std::min<std::size_t>(e.count, std::size_t{1} << 20));  // grows with the data actually read
  const auto n_vertices = static_cast<double>(out.points.size());
  std::vector<int> polygon;
  for (std::size_t f = 0; f < e.count; ++f) {
    for (std::size_t p = 0; p < e.properties.size(); ++p) {
      const Property& prop = e.properties[p];
      if (!prop.is_list) { body.next(prop.type, "the face data"); continue; }
      const std::size_t n = body.listLength(prop.count_type, "the face data");
      polygon.clear();
      if (static_cast<int>(p) != list) {  // another list (texture coordinates, say): skipped
        for (std::size_t k = 0; k < n; ++k) body.next(prop.type, "the face data");
        continue;
      }
      for (std::size_t k = 0; k < n; ++k) {
        const double idx = body.next(prop.type, "the face data");
        if (idx < 0 || idx >= n_vertices || idx != std::floor(idx))
          fail(path, fmt::format("face {} refers to vertex {} of {}", f, idx, out.points.size()));
        polygon.push_back(static_cast<int>(idx));
      }
      for (std::size_t k = 2; k < polygon.size(); ++k)  // fan triangulation of polygons
        out.faces.emplace_back(polygon[0], polygon[k - 1], polygon[k]);
    }
  }
}

PlyData readPly(const std::string& path, double scale) {
  const std::string bytes = detail::readFileBytes(path);
  const Header header = parseHeader(path, bytes);
  BodyReader body(path, bytes, header);
  PlyData data;
  bool have_vertices = false;
  for (const Element& e : header.elements) {
    if (e.name == "vertex") {
      readVertices(path, e, body, scale, data);
      have_vertices = true;
    } else if (e.name == "face" && have_vertices) {
      readFaces(path, e, body, data);
    } else if (!e.properties.empty()) {  // any other element: read past it (one without
                                         // properties holds no data, whatever its count)
      for (std::size_t i = 0; i < e.count; ++i)
        for (const Property& prop : e.properties) {
          const std::size_t n = prop.is_list ? body.listLength(prop.count_type, e.name.c_str()) : 1;
          for (std::size_t k = 0; k < n; ++k) body.next(prop.type, e.name.c_str());
        }
    }
  }
  if (!have_vertices) fail(path, "PLY file has no vertex element");
  return data;
}

template <typename T>
void writeValue(std::ofstream& out, T v, PlyFormat format) {
  if (format == PlyFormat::Ascii) {
    out << v;
    return;
  }
  char bytes[sizeof(T)];
  std::memcpy(bytes, &v, sizeof(T));
  if ((format == PlyFormat::BinaryBigEndian) != (std::endian::native == std::endian::big))
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  out.write(bytes, sizeof(T));
}

Mesh toMesh(const std::string& path, PlyData&& data) {
  for (std::size_t i = 0; i < data.points.size(); ++i)
    if (!data.points[i].allFinite()) fail(path, fmt::format("vertex {} has a non-finite coordinate", i));
  if (data.faces.empty()) fail(path, "PLY file has no faces (a mesh was expected)");
  Mesh mesh;
  mesh.vertices = std::move(data.points);
  mesh.faces = std::move(data.faces);
  mesh.normals = std::move(data.normals);
  return mesh;
}

PointCloud toCloud(PlyData&& data) {
  PointCloud cloud;
  cloud.points.reserve(data.points.size());
  const bool normals = !data.normals.empty();
  for (std::size_t i = 0; i < data.points.size(); ++i) {
    if (!isMeasured(data.points[i])) continue;  // NaN or the origin: a pixel without a depth
    cloud.points.push_back(data.points[i]);
    if (normals) cloud.normals.push_back(data.normals[i]);
  }
  return cloud;
}

}  // namespace

Mesh readPlyMesh(const std::string& path, double scale) { return toMesh(path, readPly(path, scale)); }

PointCloud readPlyCloud(const std::string& path, double scale) {
  PointCloud cloud = toCloud(readPly(path, scale));
  fitPixelLattice(cloud);  // a depth image saved in its camera's frame
  return cloud;
}

ModelFile readModelFile(const std::string& path, double scale) {
  ModelFile file;
  const std::string ext = detail::extensionOf(path);
  if (ext == "pcd") {
    file.cloud = readPcd(path, scale);
  } else if (isXyzPath(path)) {
    file.cloud = readXyz(path, scale);
  } else if (ext == "ply") {
    PlyData data = readPly(path, scale);
    file.is_mesh = !data.faces.empty();
    if (file.is_mesh) file.mesh = toMesh(path, std::move(data));
    else file.cloud = toCloud(std::move(data));
  } else {
    file.is_mesh = true;
    file.mesh = readMesh(path, scale);
  }
  return file;
}

void writePly(const std::string& path, const Points& points, const Points& normals,
              const std::vector<Eigen::Vector3i>& faces, PlyFormat format) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error(fmt::format("{}: cannot write file", path));
  const bool with_normals = normals.size() == points.size() && !normals.empty();
  const char* format_name = format == PlyFormat::Ascii ? "ascii"
                            : format == PlyFormat::BinaryLittleEndian ? "binary_little_endian"
                                                                      : "binary_big_endian";
  out << "ply\nformat " << format_name << " 1.0\ncomment binpose\nelement vertex " << points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n";
  if (with_normals) out << "property float nx\nproperty float ny\nproperty float nz\n";
  if (!faces.empty()) out << "element face " << faces.size() << "\nproperty list uchar int vertex_indices\n";
  out << "end_header\n";
  out.precision(9);
  const char* sep = format == PlyFormat::Ascii ? " " : "";
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (int k = 0; k < 3; ++k) { writeValue(out, points[i][k], format); out << sep; }
    if (with_normals)
      for (int k = 0; k < 3; ++k) { writeValue(out, normals[i][k], format); out << sep; }
    if (format == PlyFormat::Ascii) out << '\n';
  }
  for (const auto& f : faces) {
    if (format == PlyFormat::Ascii) {
      out << "3 " << f[0] << ' ' << f[1] << ' ' << f[2] << '\n';
    } else {
      writeValue(out, static_cast<std::uint8_t>(3), format);
      for (int k = 0; k < 3; ++k) writeValue(out, static_cast<std::int32_t>(f[k]), format);
    }
  }
  if (!out) throw Error(fmt::format("{}: write failed", path));
}

}  // namespace binpose
