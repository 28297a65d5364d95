// ASCII point clouds, one point a line (.xyz, .txt, .csv, .asc, .pts): what laser-scanner and
// point-cloud tools (CloudCompare, MeshLab, a line scanner's export) write when no PLY is asked.
// Columns split by commas or semicolons, else by spaces and tabs; x y z first unless a header
// names them.
#include "io_detail.hpp"
#include "pinhole_fit.hpp"

#include <binpose/io.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <string>
#include <vector>

namespace binpose {
namespace {

/// A normal column's row counts as a unit vector within this of length 1 (files round to a few
/// digits); columns 4-6 are taken for normals only when every row holds one (or zeros).
constexpr double kUnitSlack = 0.02;

/// Columns of x, y, z and of a normal's three (-1 when absent).
struct Columns {
  std::array<int, 3> xyz{0, 1, 2};
  std::array<int, 3> normal{-1, -1, -1};
};

std::string_view trimmed(std::string_view field) {
  const std::size_t first = field.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  return field.substr(first, field.find_last_not_of(" \t\r") - first + 1);
}

/// A line's fields: split at commas and semicolons when it holds any (each field trimmed, an
/// empty one kept: a value left out), else at spaces and tabs.
std::vector<std::string_view> fieldsOf(std::string_view line) {
  std::vector<std::string_view> fields;
  if (line.find_first_of(",;") != std::string_view::npos) {
    std::size_t start = 0;
    for (std::size_t end; (end = line.find_first_of(",;", start)) != std::string_view::npos; start = end + 1)
      fields.push_back(trimmed(line.substr(start, end - start)));
    if (!trimmed(line.substr(start)).empty()) fields.push_back(trimmed(line.substr(start)));  // not after a final comma
    return fields;
  }
  return detail::splitWords(line);
}

bool isComment(std::string_view line) {
  const std::size_t at = line.find_first_not_of(" \t");
  return line[at] == '#' || line[at] == '%' || line.substr(at, 2) == "//";
}

std::string lower(std::string_view text) {
  std::string out(text);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

/// The column named one of `names` in a header row, else -1.
int columnNamed(const std::vector<std::string_view>& header, std::initializer_list<const char*> names) {
  for (std::size_t c = 0; c < header.size(); ++c) {
    std::string_view field = header[c];
    while (!field.empty() && (field.front() == '"' || field.front() == '\'')) field.remove_prefix(1);
    const std::string word = lower(field.substr(0, field.find_first_of(" \t([\"'")));  // "X [mm]": x
    for (const char* name : names)
      if (word == name) return static_cast<int>(c);
  }
  return -1;
}

/// Columns from a header row that names them (x, y, z required; nx, ny, nz optional).
Columns columnsFromHeader(const std::string& path, const std::vector<std::string_view>& header) {
  Columns cols;
  cols.xyz = {columnNamed(header, {"x", "point_x"}), columnNamed(header, {"y", "point_y"}),
              columnNamed(header, {"z", "point_z"})};
  if (cols.xyz[0] < 0 || cols.xyz[1] < 0 || cols.xyz[2] < 0) detail::fail(path, "the header line names no x, y and z columns");
  cols.normal = {columnNamed(header, {"nx", "normal_x", "normalx"}), columnNamed(header, {"ny", "normal_y", "normaly"}),
                 columnNamed(header, {"nz", "normal_z", "normalz"})};
  if (cols.normal[0] < 0 || cols.normal[1] < 0 || cols.normal[2] < 0) cols.normal = {-1, -1, -1};
  return cols;
}

/// The data rows' numbers, flat: row i holds values[starts[i]] to values[starts[i + 1]].
struct Rows {
  std::vector<double> values;
  std::vector<std::size_t> starts{0};
  std::vector<std::size_t> line_numbers;  // for error messages
  std::vector<std::string_view> header;   // empty when the file has none
  std::size_t size() const { return line_numbers.size(); }
  std::size_t width(std::size_t i) const { return starts[i + 1] - starts[i]; }
  const double* row(std::size_t i) const { return values.data() + starts[i]; }
};

/// A comment's text after its marker ('#', '%' or "//").
std::string_view commentText(std::string_view line) {
  line.remove_prefix(std::min(line.size(), line.find_first_not_of(" \t")));
  line.remove_prefix(line.substr(0, 2) == "//" ? 2 : 1);
  return line;
}

/// Whether a comment's fields name the columns (CloudCompare's "//X,Y,Z,R,G,B", "# x y z nx ny nz").
bool namesColumns(const std::vector<std::string_view>& fields) {
  return columnNamed(fields, {"x"}) >= 0 && columnNamed(fields, {"y"}) >= 0 && columnNamed(fields, {"z"}) >= 0;
}

/// The numbers of one line appended to `rows`; false (nothing appended) when a field is not one.
bool appendNumbers(const std::vector<std::string_view>& fields, Rows& rows) {
  const std::size_t start = rows.values.size();
  for (const std::string_view field : fields) {
    double value = std::numeric_limits<double>::quiet_NaN();     // an empty field: no measurement
    if (!field.empty() && !detail::parseNumber(field, value)) {  // "nan" parses as NaN too
      rows.values.resize(start);
      return false;
    }
    rows.values.push_back(value);
  }
  return true;
}

/// Every data row as numbers. One line naming the columns before the data is a header (also
/// as a "//" comment); a first line of a single count (Leica's .pts) is skipped.
Rows readRows(const std::string& path, std::string_view text) {
  Rows rows;
  std::size_t at = 0, line_number = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(at, end - at);
    at = end + 1;
    ++line_number;
    const bool before_data = rows.size() == 0;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    if (isComment(line)) {
      if (!before_data || !rows.header.empty()) continue;
      const auto fields = fieldsOf(commentText(line));
      if (namesColumns(fields)) rows.header = fields;
      continue;
    }
    const auto fields = fieldsOf(line);
    if (!appendNumbers(fields, rows)) {
      if (!before_data || !rows.header.empty())
        detail::fail(path, fmt::format("line {}: '{}' is not a row of numbers", line_number, line.substr(0, 60)));
      rows.header = fields;
      continue;
    }
    if (before_data && rows.header.empty() && fields.size() == 1) {  // a point count
      rows.values.clear();
      continue;
    }
    rows.starts.push_back(rows.values.size());
    rows.line_numbers.push_back(line_number);
  }
  return rows;
}

/// Whether columns 3-5 hold a unit vector (or zeros: no normal) on every row.
bool unitColumns(const Rows& rows) {
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows.width(i) < 6) return false;
    const double* r = rows.row(i);
    const double n = std::sqrt(r[3] * r[3] + r[4] * r[4] + r[5] * r[5]);
    if (std::isnan(n)) continue;  // a point without a measurement
    if (n != 0.0 && std::abs(n - 1.0) > kUnitSlack) return false;
  }
  return true;
}

Vec3 pointOf(const std::string& path, const double* row, const std::array<int, 3>& cols, std::size_t line_number, double scale) {
  Vec3 out;
  for (int k = 0; k < 3; ++k) {
    const double v = row[cols[static_cast<std::size_t>(k)]] * scale;
    if (std::isinf(v) || std::abs(v) > double(std::numeric_limits<float>::max()))
      detail::fail(path, fmt::format("line {}: a coordinate is out of range", line_number));
    out[k] = static_cast<float>(v);  // NaN stays NaN: a point without a measurement
  }
  return out;
}

}  // namespace

PointCloud readXyz(const std::string& path, double scale) {
  const std::string bytes = detail::readFileBytes(path);
  const Rows rows = readRows(path, bytes);
  if (rows.size() == 0) detail::fail(path, "no point in the file (one 'x y z' line per point)");
  Columns cols = rows.header.empty() ? Columns{} : columnsFromHeader(path, rows.header);
  if (rows.header.empty() && unitColumns(rows)) cols.normal = {3, 4, 5};
  int widest = 0;
  for (const int c : cols.xyz) widest = std::max(widest, c);
  for (const int c : cols.normal) widest = std::max(widest, c);
  const bool with_normals = cols.normal[0] >= 0;
  PointCloud cloud;
  cloud.points.reserve(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const std::size_t line = rows.line_numbers[i];
    if (rows.width(i) <= static_cast<std::size_t>(widest))
      detail::fail(path, fmt::format("line {}: {} values, {} expected", line, rows.width(i), widest + 1));
    const Vec3 p = pointOf(path, rows.row(i), cols.xyz, line, scale);
    if (!isMeasured(p)) continue;  // NaN or the origin: a pixel without a depth
    cloud.points.push_back(p);
    if (!with_normals) continue;
    Vec3 n = pointOf(path, rows.row(i), cols.normal, line, 1.0);
    if (!normalizeSafe(n)) n.setZero();  // a zero normal is a missing normal
    cloud.normals.push_back(n);
  }
  fitPixelLattice(cloud);  // a depth image saved in its camera's frame
  return cloud;
}

}  // namespace binpose
