#include "io_detail.hpp"

#include <binpose/io.hpp>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>

namespace binpose {

bool normalizeSafe(Vec3& n) {
  const float len = n.norm();
  if (!std::isfinite(len) || len < 1e-12f) return false;
  n /= len;
  return true;
}

double unitScale(Units units) {
  switch (units) {
    case Units::Centimetres:
      return 10.0;
    case Units::Metres:
      return 1000.0;
    case Units::Inches:
      return 25.4;
    case Units::Millimetres:
      break;
  }
  return 1.0;
}

Units parseUnits(const std::string& text) {
  if (text == "mm") return Units::Millimetres;
  if (text == "cm") return Units::Centimetres;
  if (text == "m") return Units::Metres;
  if (text == "in") return Units::Inches;
  throw Error(fmt::format("units: expected 'mm', 'cm', 'm' or 'in', got '{}'", text));
}

bool isXyzPath(const std::string& path) {
  const std::string ext = detail::extensionOf(path);
  return ext == "xyz" || ext == "txt" || ext == "csv" || ext == "asc" || ext == "pts";
}

PointCloud readCloud(const std::string& path, double scale) {
  const std::string ext = detail::extensionOf(path);
  if (ext == "ply") return readPlyCloud(path, scale);
  if (ext == "pcd") return readPcd(path, scale);
  if (isXyzPath(path)) return readXyz(path, scale);
  if (isTiffPath(path)) return readTiffPointMap(path, scale);
  Mesh mesh = detail::readMeshFile(path, scale);  // a scan saved as a mesh, or as vertices alone
  if (!mesh.faces.empty()) detail::weldChecked(path, mesh);
  PointCloud cloud;
  for (const Vec3& p : mesh.vertices)
    if (isMeasured(p)) cloud.points.push_back(p);  // NaN or the origin: a pixel without a depth
  if (cloud.empty()) detail::fail(path, "no point in the file");
  return cloud;
}

namespace detail {

namespace {

/// The longest message a reader gives (it may quote a token of the file).
constexpr std::size_t kMostMessageChars = 300;

/// `message` on one printable line: control bytes a file's token may carry (a newline in a PNG
/// chunk's name, say) written as \xNN, and the text cut at kMostMessageChars.
std::string oneLine(const std::string& message) {
  std::string line;
  for (const char c : message) {
    if (line.size() >= kMostMessageChars) return line + "...";
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) line += fmt::format("\\x{:02x}", byte);
    else line += c;
  }
  return line;
}

}  // namespace

void fail(const std::string& path, const std::string& message) {
  throw Error(fmt::format("{}: {}", path, oneLine(message)));
}

std::string readFileBytes(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) fail(path, "no such file");
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) fail(path, "cannot open file");
  // One read into a buffer of the file's size: a string stream's growing buffer copied a
  // 15-40 MB database several times over (12-15 % of a detect run's wall time).
  const std::streamoff size = in.tellg();
  if (size < 0) fail(path, "cannot read file");
  if (size == 0) fail(path, "file is empty");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.seekg(0);
  if (!in.read(bytes.data(), size)) fail(path, "read failed (the file changed while read?)");
  return bytes;
}

std::string extensionOf(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty() && ext.front() == '.') ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

std::vector<std::string_view> splitWords(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const std::size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

bool parseNumber(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec == std::errc::result_out_of_range) {  // denormals and overflow: take what strtod gives
    value = std::strtod(std::string(token).c_str(), nullptr);
    return true;
  }
  return ec == std::errc() && end == token.data() + token.size();
}

std::size_t jsonDepth(std::string_view text) {
  std::size_t depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '{' || c == '[') {
      deepest = std::max(deepest, ++depth);
    } else if ((c == '}' || c == ']') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

std::size_t parseCount(const std::string& path, std::string_view token, const char* what, std::size_t max) {
  std::uint64_t v = 0;
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (ec != std::errc() || end != token.data() + token.size())
    fail(path, fmt::format("{} '{}' is not a whole number", what, token));
  if (v > max) fail(path, fmt::format("{} {} is more than this reader allows ({})", what, v, max));
  return static_cast<std::size_t>(v);
}

int scalarSize(Scalar type) {
  switch (type) {
    case Scalar::Int8: case Scalar::UInt8: return 1;
    case Scalar::Int16: case Scalar::UInt16: return 2;
    case Scalar::Int32: case Scalar::UInt32: case Scalar::Float32: return 4;
    case Scalar::Float64: return 8;
  }
  return 0;
}

}  // namespace detail
}  // namespace binpose
