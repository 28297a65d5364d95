// PCD reader: DATA ascii, binary and binary_compressed (LZF), organized or not.
#include "io_detail.hpp"
#include "pinhole_fit.hpp"

#include <binpose/io.hpp>

#include <array>
#include <cmath>
#include <lzf.h>

namespace binpose {
namespace {

using detail::fail;
using detail::Scalar;

struct Field {
  std::string name;
  int size = 4;
  char type = 'F';
  int count = 1;
  std::size_t offset = 0;  ///< byte offset within one point record
  Scalar scalar = Scalar::Float32;
};

enum class Encoding { Ascii, Binary, BinaryCompressed };

struct PcdHeader {
  std::vector<Field> fields;
  std::size_t width = 0, height = 1, points = 0;
  std::size_t point_size = 0;
  Encoding encoding = Encoding::Ascii;
  std::size_t body_offset = 0;
  Vec3 viewpoint = Vec3::Zero();
};

Scalar pcdScalar(const std::string& path, char type, int size) {
  if (type == 'F' && size == 4) return Scalar::Float32;
  if (type == 'F' && size == 8) return Scalar::Float64;
  if (type == 'I' && size == 1) return Scalar::Int8;
  if (type == 'I' && size == 2) return Scalar::Int16;
  if (type == 'I' && size == 4) return Scalar::Int32;
  if (type == 'U' && size == 1) return Scalar::UInt8;
  if (type == 'U' && size == 2) return Scalar::UInt16;
  if (type == 'U' && size == 4) return Scalar::UInt32;
  fail(path, fmt::format("unsupported PCD field type {}{}", type, size));
}

/// The most points, and the most values of one field, a PCD header may claim: beyond what a
/// sensor gives, and the body is checked against the claim before anything is allocated.
constexpr std::size_t kMostPoints = (std::size_t{1} << 31) - 1;
constexpr std::size_t kMostCount = std::size_t{1} << 16;

std::size_t parseCount(const std::string& path, std::string_view word, const char* what, std::size_t most = kMostPoints) {
  return detail::parseCount(path, word, fmt::format("PCD {}", what).c_str(), most);
}

void checkFieldList(const std::string& path, const PcdHeader& h, std::size_t n, const char* key) {
  if (n != h.fields.size()) fail(path, fmt::format("PCD {} has {} entries for {} fields", key, n, h.fields.size()));
}

PcdHeader parseHeader(const std::string& path, const std::string& bytes) {
  PcdHeader h;
  std::size_t pos = 0;
  bool have_data = false, have_points = false, have_width = false;
  while (!have_data) {
    const std::size_t eol = bytes.find('\n', pos);
    if (eol == std::string::npos) fail(path, "not a PCD file (no DATA line in the header)");
    const std::string_view line(bytes.data() + pos, eol - pos);
    pos = eol + 1;
    const auto w = detail::splitWords(line);
    if (w.empty() || w[0].front() == '#' || w[0] == "VERSION") continue;
    if (w[0] == "FIELDS") {
      for (std::size_t i = 1; i < w.size(); ++i) h.fields.push_back({std::string(w[i])});
    } else if (w[0] == "SIZE") {
      checkFieldList(path, h, w.size() - 1, "SIZE");
      for (std::size_t i = 1; i < w.size(); ++i) h.fields[i - 1].size = int(parseCount(path, w[i], "SIZE", 8));
    } else if (w[0] == "TYPE") {
      checkFieldList(path, h, w.size() - 1, "TYPE");
      for (std::size_t i = 1; i < w.size(); ++i) h.fields[i - 1].type = w[i].empty() ? '?' : w[i][0];
    } else if (w[0] == "COUNT") {
      checkFieldList(path, h, w.size() - 1, "COUNT");
      for (std::size_t i = 1; i < w.size(); ++i) h.fields[i - 1].count = int(parseCount(path, w[i], "COUNT", kMostCount));
    } else if (w[0] == "WIDTH" && w.size() == 2) {
      h.width = parseCount(path, w[1], "WIDTH");
      have_width = true;
    } else if (w[0] == "HEIGHT" && w.size() == 2) {
      h.height = parseCount(path, w[1], "HEIGHT");
    } else if (w[0] == "POINTS" && w.size() == 2) {
      h.points = parseCount(path, w[1], "POINTS");
      have_points = true;
    } else if (w[0] == "VIEWPOINT" && w.size() == 8) {
      for (int k = 0; k < 3; ++k) {
        double v = 0;
        if (!detail::parseNumber(w[1 + k], v)) fail(path, "bad VIEWPOINT in PCD header");
        h.viewpoint[k] = float(v);
      }
    } else if (w[0] == "DATA" && w.size() == 2) {
      if (w[1] == "ascii") h.encoding = Encoding::Ascii;
      else if (w[1] == "binary") h.encoding = Encoding::Binary;
      else if (w[1] == "binary_compressed") h.encoding = Encoding::BinaryCompressed;
      else fail(path, fmt::format("unknown PCD DATA encoding '{}'", w[1]));
      have_data = true;
    } else {
      fail(path, fmt::format("unknown PCD header line '{}'", line));
    }
  }
  if (h.fields.empty()) fail(path, "PCD header has no FIELDS");
  if (!have_width) fail(path, "PCD header has no WIDTH");
  const std::size_t pixels = detail::checkedMul(h.width, h.height, path, "PCD WIDTH x HEIGHT");
  if (!have_points) h.points = pixels;
  if (h.points != pixels) fail(path, fmt::format("PCD POINTS {} != WIDTH*HEIGHT {}", h.points, pixels));
  if (h.points > kMostPoints) fail(path, fmt::format("PCD POINTS {} is more than this reader allows", h.points));
  for (Field& f : h.fields) {
    if (f.count < 1) fail(path, fmt::format("PCD field '{}' has COUNT {}", f.name, f.count));
    f.scalar = pcdScalar(path, f.type, f.size);
    f.offset = h.point_size;
    h.point_size += static_cast<std::size_t>(f.size) * static_cast<std::size_t>(f.count);  // at most 8 x 2^16 a field
    if (h.point_size > (std::size_t{1} << 30)) fail(path, "PCD point record too large");
  }
  h.body_offset = pos;
  return h;
}

int fieldIndex(const PcdHeader& h, const char* name) {
  for (std::size_t i = 0; i < h.fields.size(); ++i)
    if (h.fields[i].name == name) return static_cast<int>(i);
  return -1;
}

/// LZF expands at most this many times (a 3-byte back-reference gives at most 264 bytes).
constexpr std::size_t kMostLzfRatio = 88;

/// The body is as long as the header says, before anything is allocated: binary, n records;
/// ascii, at least two bytes a value; binary_compressed, a block whose raw size is n records and
/// which the data can hold.
void checkBodyLength(const std::string& path, const PcdHeader& h, std::size_t n, const char* body, std::size_t body_size) {
  const std::size_t record_bytes = detail::checkedMul(n, h.point_size, path, "PCD data size");
  if (h.encoding == Encoding::Binary) {
    if (body_size < record_bytes)
      fail(path, fmt::format("file is truncated ({} bytes of data for {} points of {} bytes)", body_size, n, h.point_size));
  } else if (h.encoding == Encoding::Ascii) {
    std::size_t values = 0;
    for (const Field& f : h.fields) values += static_cast<std::size_t>(f.count);
    if (detail::checkedMul(n, values, path, "PCD value count") > body_size / 2 + 1)
      fail(path, fmt::format("file is truncated ({} bytes of text for {} points)", body_size, n));
  } else {
    if (body_size < 8) fail(path, "file is truncated (no compressed block header)");
    const auto compressed = static_cast<std::size_t>(detail::readScalar(body, Scalar::UInt32, false));
    const auto raw_size = static_cast<std::size_t>(detail::readScalar(body + 4, Scalar::UInt32, false));
    if (raw_size != record_bytes)
      fail(path, fmt::format("compressed block holds {} bytes, header implies {}", raw_size, record_bytes));
    if (compressed > body_size - 8)
      fail(path, fmt::format("file is truncated ({} of {} compressed bytes)", body_size - 8, compressed));
    if (raw_size > kMostLzfRatio * compressed + 8)
      fail(path, fmt::format("corrupt binary_compressed PCD ({} compressed bytes cannot hold {})", compressed, raw_size));
  }
}

/// All values of the wanted fields (x,y,z[,nx,ny,nz]) per point, as doubles.
std::vector<double> decodeBody(const std::string& path, const std::string& bytes, const PcdHeader& h,
                               const std::vector<int>& wanted) {
  const std::size_t n = h.points, m = wanted.size();
  const char* body = bytes.data() + h.body_offset;
  const std::size_t body_size = bytes.size() - h.body_offset;
  checkBodyLength(path, h, n, body, body_size);  // before anything sized by the header is allocated
  std::vector<double> values(n * m);
  if (h.encoding == Encoding::Ascii) {
    std::vector<std::string_view> tokens;
    std::size_t pos = h.body_offset;
    std::size_t per_point = 0;
    std::vector<std::size_t> first_token(h.fields.size());  // token index of each field's first value
    for (std::size_t f = 0; f < h.fields.size(); ++f) {
      first_token[f] = per_point;
      per_point += static_cast<std::size_t>(h.fields[f].count);
    }
    for (std::size_t p = 0; p < n; ++p) {
      tokens.clear();
      while (tokens.size() < per_point) {
        while (pos < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[pos]))) ++pos;
        const std::size_t start = pos;
        while (pos < bytes.size() && !std::isspace(static_cast<unsigned char>(bytes[pos]))) ++pos;
        if (pos == start) fail(path, fmt::format("file is truncated (point {} of {})", p, n));
        tokens.emplace_back(bytes.data() + start, pos - start);
      }
      for (std::size_t k = 0; k < m; ++k) {
        const std::size_t t = first_token[wanted[k]];
        if (!detail::parseNumber(tokens[t], values[p * m + k]))
          fail(path, fmt::format("bad number '{}' at point {}", tokens[t], p));
      }
    }
    return values;
  }
  if (h.encoding == Encoding::Binary) {
    for (std::size_t p = 0; p < n; ++p)
      for (std::size_t k = 0; k < m; ++k) {
        const Field& f = h.fields[wanted[k]];
        values[p * m + k] = detail::readScalar(body + p * h.point_size + f.offset, f.scalar, false);
      }
    return values;
  }
  // binary_compressed: u32 compressed size, u32 raw size, LZF data; raw layout is one array per field.
  const auto compressed = static_cast<std::size_t>(detail::readScalar(body, Scalar::UInt32, false));
  const auto raw_size = static_cast<std::size_t>(detail::readScalar(body + 4, Scalar::UInt32, false));
  std::vector<char> raw(raw_size);
  if (raw_size > 0) {
    const unsigned out = lzf_decompress(body + 8, static_cast<unsigned>(compressed), raw.data(),
                                        static_cast<unsigned>(raw_size));
    if (out != raw_size) fail(path, "corrupt LZF data in binary_compressed PCD");
  }
  for (std::size_t k = 0; k < m; ++k) {
    const Field& f = h.fields[wanted[k]];
    const std::size_t stride = static_cast<std::size_t>(f.size) * static_cast<std::size_t>(f.count);
    const char* column = raw.data() + f.offset * n;  // fields are stored one after another
    for (std::size_t p = 0; p < n; ++p) values[p * m + k] = detail::readScalar(column + p * stride, f.scalar, false);
  }
  return values;
}

}  // namespace

PointCloud readPcd(const std::string& path, double scale) {
  const std::string bytes = detail::readFileBytes(path);
  const PcdHeader h = parseHeader(path, bytes);
  std::vector<int> wanted{fieldIndex(h, "x"), fieldIndex(h, "y"), fieldIndex(h, "z")};
  if (wanted[0] < 0 || wanted[1] < 0 || wanted[2] < 0) fail(path, "PCD file lacks an x, y or z field");
  const std::array<int, 3> nrm{fieldIndex(h, "normal_x"), fieldIndex(h, "normal_y"), fieldIndex(h, "normal_z")};
  const bool has_normals = nrm[0] >= 0 && nrm[1] >= 0 && nrm[2] >= 0;
  if (has_normals) wanted.insert(wanted.end(), nrm.begin(), nrm.end());
  const std::vector<double> values = decodeBody(path, bytes, h, wanted);

  PointCloud cloud;
  cloud.viewpoint = h.viewpoint * float(scale);
  // PCD's VIEWPOINT: the origin is also its default, which PCL keeps when it moves a cloud into
  // another frame; only another position says where the sensor was.
  cloud.has_viewpoint = cloud.viewpoint != Vec3::Zero();
  if (h.height > 1) {
    cloud.width = static_cast<int>(h.width);
    cloud.height = static_cast<int>(h.height);
  }
  const std::size_t m = wanted.size();
  cloud.points.reserve(h.points);
  for (std::size_t p = 0; p < h.points; ++p) {
    const double* v = &values[p * m];
    const Vec3 point(float(v[0] * scale), float(v[1] * scale), float(v[2] * scale));
    if (!isMeasured(point)) continue;  // NaN or the origin: a pixel without a depth
    cloud.points.push_back(point);
    if (cloud.organized()) cloud.pixel.push_back(static_cast<std::int32_t>(p));
    if (has_normals) {
      Vec3 n{float(v[3]), float(v[4]), float(v[5])};
      if (!normalizeSafe(n)) n.setZero();
      cloud.normals.push_back(n);
    }
  }
  fitPinhole(cloud);  // an OpenNI or ROS frame: its points on their pixels' rays
  return cloud;
}

}  // namespace binpose
