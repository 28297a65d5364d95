// The `binpose` Python module (pybind11): train a model, detect it in a cloud or a depth image.
// Arrays are read in place where their layout allows; the GIL is released while detecting. Every
// binpose::Error (a bad file, value or array) becomes a ValueError with the CLI's message.
#include <binpose/detector.hpp>
#include <binpose/geometry.hpp>
#include <binpose/io.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/params.hpp>
#include <binpose/scan_file.hpp>
#include <binpose/shapes.hpp>
#include <binpose/viewpoint.hpp>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <optional>

namespace py = pybind11;
using namespace binpose;

namespace {

template <class T>
Points rowsOf(const py::array& a) {
  const auto rows = a.unchecked<T, 2>();
  Points out(static_cast<std::size_t>(rows.shape(0)));
  for (py::ssize_t i = 0; i < rows.shape(0); ++i) out[i] = Vec3(float(rows(i, 0)), float(rows(i, 1)), float(rows(i, 2)));
  return out;
}

/// An N x 3 array's rows as float points (binpose's own layout: one copy, read in place from a
/// float32 or float64 array of any strides; other number types converted first); `what` names it.
Points pointsOf(const py::handle& object, const char* what) {
  if (!py::isinstance<py::array>(object) && (!py::isinstance<py::sequence>(object) || py::isinstance<py::str>(object)))
    throw Error(fmt::format("{} must be an N x 3 array, got {}", what, std::string(py::str(py::type::of(object)))));
  py::array a = py::array::ensure(object);
  if (!a || a.ndim() != 2 || a.shape(1) != 3) throw Error(fmt::format("{} must be an N x 3 array", what));
  if (py::isinstance<py::array_t<float>>(a)) return rowsOf<float>(a);
  if (!py::isinstance<py::array_t<double>>(a)) {
    const char kind = a.dtype().kind();
    if (kind != 'f' && kind != 'i' && kind != 'u') throw Error(fmt::format("{} must hold numbers, got dtype {}", what, std::string(py::str(a.dtype()))));
    a = py::array_t<double, py::array::forcecast>::ensure(a);
  }
  return rowsOf<double>(a);
}

/// The (x, y, z) of a viewpoint, mm.
Vec3 viewpointOf(const py::handle& object) {
  py::array a = py::array::ensure(object);
  if (!a || a.size() != 3) throw Error("viewpoint must be three numbers (x, y, z), mm");
  const Vec3 v = pointsOf(a.reshape({1, 3}), "viewpoint")[0];
  if (!v.allFinite()) throw Error("viewpoint must be finite");
  return v;
}

/// Points as a new N x 3 float32 array.
py::array_t<float> arrayOf(const Points& points) {
  py::array_t<float> out({static_cast<py::ssize_t>(points.size()), py::ssize_t{3}});
  auto m = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int k = 0; k < 3; ++k) m(py::ssize_t(i), k) = points[i][k];
  return out;
}

/// A trained model, shared by the detectors made from it (they refer to it).
struct Database {
  std::shared_ptr<const ModelDatabase> db;
};

Database train(const py::object& model, int points, const std::string& units) {
  ModelParams params;
  params.num_points = points;
  const double scale = unitScale(parseUnits(units));
  OrientedModel oriented;
  if (py::isinstance<py::str>(model)) {
    const ModelFile file = readModelOrBuiltin(model.cast<std::string>(), scale);
    oriented = file.is_mesh ? prepareModel(file.mesh, params) : prepareModel(file.cloud, params);
  } else if (py::isinstance<py::tuple>(model) && py::len(model) == 2) {
    const py::tuple pair = model.cast<py::tuple>();
    Mesh mesh;
    mesh.vertices = pointsOf(pair[0], "vertices");
    for (Vec3& v : mesh.vertices) v *= float(scale);
    for (const Vec3& f : pointsOf(pair[1], "faces")) {
      const Eigen::Vector3i face = f.cast<int>();
      if (!(face.cast<float>() == f) || (face.array() < 0).any() || (face.array() >= int(mesh.vertices.size())).any())
        throw Error(fmt::format("faces must be whole indices into the {} vertices", mesh.vertices.size()));
      mesh.faces.push_back(face);
    }
    for (const Vec3& v : mesh.vertices)
      if (!v.allFinite()) throw Error("vertices must be finite");
    oriented = prepareModel(mesh, params);
  } else {
    throw Error("model must be a file path, builtin:NAME, or a tuple (vertices N x 3, faces M x 3)");
  }
  const QuantizationParams quantization = defaultQuantization(oriented.diameter);
  return {std::make_shared<const ModelDatabase>(ModelDatabase::build(std::move(oriented), quantization))};
}

/// A detection as Python sees it: the pose as a 4 x 4 array (model -> scan, mm).
struct PyDetection {
  py::array_t<double> pose;
  float score = 0;
  int correspondences = 0;
  float fit_rms_mm = 0;
};

/// The detections, best first, with the stage timings (ms) and what the scan measured.
struct PyResult {
  std::vector<PyDetection> detections;
  py::dict timing_ms;
  float noise_mm = 0;
  float least_score = 0;
  std::size_t scene_points = 0;
  std::size_t flying_points = 0;
  int pixel_stride = 1;
};

/// A pose as a 4 x 4 array.
py::array_t<double> matrixOf(const Pose& pose) {
  py::array_t<double> out({4, 4});
  const Eigen::Matrix4f T = pose.matrix();
  auto m = out.mutable_unchecked<2>();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) m(i, j) = T(i, j);
  return out;
}

PyResult toPython(const DetectionResult& r) {
  PyResult out;
  for (const Detection& d : r.detections) out.detections.push_back({matrixOf(d.pose), d.score, d.correspondences, d.rms});
  out.timing_ms["preprocess"] = r.timing.preprocess_ms;
  out.timing_ms["vote"] = r.timing.vote_ms;
  out.timing_ms["match"] = r.timing.match_ms;
  out.timing_ms["refine"] = r.timing.refine_ms;
  out.timing_ms["total"] = r.timing.total_ms;
  out.noise_mm = r.noise_mm;
  out.least_score = r.least_score;
  out.scene_points = r.scene_points;
  out.flying_points = r.flying_points;
  out.pixel_stride = r.pixel_stride;
  return out;
}

/// Python keyword values as the JSON object applyJson reads (the names of DetectionParams).
std::string paramsJson(const py::kwargs& kwargs) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, value] : kwargs) {
    const std::string name = py::str(key);
    if (py::isinstance<py::bool_>(value)) j[name] = value.cast<bool>();
    else if (py::isinstance<py::int_>(value)) j[name] = value.cast<long long>();
    else if (py::isinstance<py::float_>(value)) j[name] = value.cast<double>();
    else if (py::isinstance<py::str>(value)) j[name] = value.cast<std::string>();
    else if (name == "viewpoint") {
      const Vec3 v = viewpointOf(value);
      j[name] = {v.x(), v.y(), v.z()};
    } else
      throw Error(fmt::format("parameters: '{}' has a value of type {}", name, std::string(py::str(py::type::of(value)))));
  }
  return j.dump();
}

/// A detector of one database: the preset scaled to the model, then the user's values. It is
/// rebuilt when a call gives another viewpoint (the detector's normals face it).
class PyDetector {
 public:
  PyDetector(const Database& database, const std::string& preset, const py::kwargs& kwargs) : db_(database.db) {
    params_ = scaledToModel(presetByName(preset), db_->model().diameter);
    applyJson(params_, paramsJson(kwargs), "parameters");
    validate(params_);
    viewpoint_given_ = kwargs.contains("viewpoint");
    detector_ = std::make_unique<Detector>(*db_, params_);
  }

  PyResult detect(const py::object& points, const py::object& normals, const py::object& viewpoint) {
    return run(cloudOf(points, normals), viewpoint);
  }

  PyResult detectDepth(const py::object& depth, double fx, double fy, double cx, double cy, double depth_scale) {
    return run(depthCloud(depth, fx, fy, cx, cy, depth_scale), py::none());
  }

  PyResult detectFile(const std::string& path, const std::string& intrinsics, const std::string& image_id,
                      const std::string& units, const py::object& viewpoint) {
    const LoadedScan scan = loadScan({path, intrinsics, image_id, units}, db_->model().diameter);
    if (scan.guessed_metres) {
      const std::string text = fmt::format(
          "{} spans {:.3g} units, less than half the model's {:.3g} mm: read in metres (units='mm' keeps millimetres)", path,
          scan.extent_in_file_units, db_->model().diameter);
      if (PyErr_WarnEx(PyExc_UserWarning, text.c_str(), 1) < 0) throw py::error_already_set();
    }
    return run(scan.cloud, viewpoint);
  }

  py::list check(const py::object& points, const py::object& poses, const py::object& viewpoint) {
    return checked(cloudOf(points, py::none()), posesOf(poses), viewpoint);
  }

  py::list checkDepth(const py::object& depth, double fx, double fy, double cx, double cy, const py::object& poses,
                      double depth_scale) {
    return checked(depthCloud(depth, fx, fy, cx, cy, depth_scale), posesOf(poses), py::none());
  }

  [[nodiscard]] py::dict params() const { return py::module_::import("json").attr("loads")(toJson(params_)); }

 private:
  /// Points spanning less than half the model's diameter cannot hold the part: most likely
  /// metres (binpose works in millimetres), as many sensors' software gives them.
  void warnIfMetres(const PointCloud& scan) const {
    const float extent = boundsDiagonal(scan.points), diameter = db_->model().diameter;
    if (extent <= 0 || extent >= kLeastScanShareOfPart * diameter) return;
    const std::string text =
        fmt::format("the points span {:.3g} but the model is {:.3g} mm across: are they in metres? (binpose works in millimetres)", extent, diameter);
    if (PyErr_WarnEx(PyExc_UserWarning, text.c_str(), 1) < 0) throw py::error_already_set();  // warnings set to errors
  }

  /// Drops the rows without a measurement (isMeasured: NaN, or the origin as a depth SDK's point
  /// cloud gives a pixel without a depth) and those with a non-finite normal.
  static void dropUnmeasured(PointCloud& scan) {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < scan.points.size(); ++i) {
      if (!isMeasured(scan.points[i]) || (scan.hasNormals() && !scan.normals[i].allFinite())) continue;
      scan.points[kept] = scan.points[i];
      if (scan.hasNormals()) scan.normals[kept] = scan.normals[i];
      ++kept;
    }
    scan.points.resize(kept);
    if (!scan.normals.empty()) scan.normals.resize(kept);
  }

  /// The scan of N x 3 `points` (and `normals`, or None), mm, its rows without a measurement
  /// dropped; or of an H x W x 3 point map (a depth SDK's organized cloud), kept organized as a
  /// depth image is. A warning where they look like metres.
  PointCloud cloudOf(const py::object& points, const py::object& normals) const {
    py::array map = py::isinstance<py::array>(points) ? py::array(points) : py::array();
    if (map && map.ndim() == 3 && map.shape(2) == 3) {
      if (!normals.is_none()) throw Error("normals are not taken with an H x W x 3 point map (they are fitted to it)");
      const int height = int(map.shape(0)), width = int(map.shape(1));
      PointCloud scan = pointMapToCloud(pointsOf(map.reshape({py::ssize_t(-1), py::ssize_t(3)}), "points"), width, height);
      warnIfMetres(scan);
      return scan;
    }
    PointCloud scan;
    scan.points = pointsOf(points, "points");
    if (!normals.is_none()) {
      scan.normals = pointsOf(normals, "normals");
      if (scan.normals.size() != scan.points.size())
        throw Error(fmt::format("normals has {} rows for {} points", scan.normals.size(), scan.points.size()));
    }
    dropUnmeasured(scan);
    warnIfMetres(scan);
    return scan;
  }

  /// An H x W depth image: uint16 as a depth PNG holds, or floats as depth SDKs give (NaN, 0 or
  /// below: no measurement); value * depth_scale mm.
  static PointCloud depthCloud(const py::object& depth, double fx, double fy, double cx, double cy, double depth_scale) {
    const py::array a = py::isinstance<py::array>(depth) ? py::array(depth) : py::array();
    const char kind = a ? a.dtype().kind() : '?';
    if (!a || a.ndim() != 2 || (kind != 'u' && kind != 'i' && kind != 'f'))
      throw Error("depth must be an H x W numpy array of numbers (uint16 as a depth PNG holds, or floats)");
    Intrinsics camera;
    camera.fx = fx, camera.fy = fy, camera.cx = cx, camera.cy = cy, camera.depth_scale = depth_scale;
    const int height = int(a.shape(0)), width = int(a.shape(1));
    if (kind == 'u' && a.itemsize() == 2) {
      const auto image = py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>::ensure(a);
      return depthToCloud(std::vector<std::uint16_t>(image.data(), image.data() + image.size()), width, height, camera);
    }
    const auto image = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
    return depthToCloud(std::vector<float>(image.data(), image.data() + image.size()), width, height, camera);
  }

  /// An N x 4 x 4 array (or a sequence of 4 x 4 ones) as rigid poses, else an error naming the pose.
  static std::vector<Pose> posesOf(const py::object& poses) {
    const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(poses);
    if (!a || a.ndim() != 3 || a.shape(1) != 4 || a.shape(2) != 4)
      throw Error("poses must be an N x 4 x 4 array (model -> scan, mm)");
    std::vector<Pose> out;
    const auto m = a.unchecked<3>();
    for (py::ssize_t k = 0; k < a.shape(0); ++k) {
      Pose pose = Pose::Identity();
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
          if (!std::isfinite(m(k, r, c))) throw Error(fmt::format("poses[{}] holds a value that is not finite", k));
          (c < 3 ? pose.linear()(r, c) : pose.translation()(r)) = static_cast<float>(m(k, r, c));
        }
      if (!isRotation(pose.linear())) throw Error(fmt::format("poses[{}]: its 3 x 3 part is not a rotation", k));
      out.push_back(pose);
    }
    return out;
  }

  /// Detector::check's verdicts as dicts: refined (4 x 4), moved_mm, score, visible_support,
  /// as_found and as_laid (Refusal's names).
  py::list checked(const PointCloud& scan, const std::vector<Pose>& poses, const py::object& viewpoint) {
    useViewpoint(scan, viewpoint);
    std::vector<PoseCheck> checks;
    {
      py::gil_scoped_release released;
      checks = detector_->check(scan, poses);
    }
    py::list out;
    for (const PoseCheck& c : checks) {
      py::dict d;
      d["refined"] = matrixOf(c.refined);
      d["moved_mm"] = c.moved_mm;
      d["score"] = c.score;
      d["visible_support"] = c.visible_support;
      d["as_found"] = refusalName(c.as_found);
      d["as_laid"] = refusalName(c.as_laid);
      out.append(d);
    }
    return out;
  }

  /// `viewpoint` None: the detector's own, else the scan's (a depth image's camera, a PCD's
  /// VIEWPOINT), else the origin when it can have seen the points, else a guess from them
  /// (guessViewpoint), as the CLI.
  void useViewpoint(const PointCloud& scan, const py::object& viewpoint) {
    std::optional<Vec3> wanted;
    if (!viewpoint.is_none()) wanted = viewpointOf(viewpoint);
    else if (scan.has_viewpoint && !viewpoint_given_)
      wanted = scan.viewpoint;
    else if (!viewpoint_given_)
      wanted = guessViewpoint(scan.points).viewpoint;
    if (wanted && *wanted != params_.viewpoint) {
      params_.viewpoint = *wanted;
      detector_ = std::make_unique<Detector>(*db_, params_);
    }
  }

  PyResult run(const PointCloud& scan, const py::object& viewpoint) {
    useViewpoint(scan, viewpoint);
    DetectionResult result;
    {
      py::gil_scoped_release released;
      result = detector_->detect(scan);
    }
    return toPython(result);
  }

  std::shared_ptr<const ModelDatabase> db_;
  DetectionParams params_;
  bool viewpoint_given_ = false;  ///< the constructor's keywords hold a viewpoint
  std::unique_ptr<Detector> detector_;
};

}  // namespace

PYBIND11_MODULE(binpose, m) {
  m.doc() = "binpose: find every copy of a known rigid part in a 3D scan and its 6D pose (mm).";
  m.attr("__version__") = BINPOSE_VERSION;
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  py::class_<Database>(m, "Database", "A model's feature database (train or load_database).")
      .def("save", [](const Database& d, const std::string& path) { d.db->save(path); }, py::arg("path"),
           "Writes the database (.bpdb).")
      .def_property_readonly("diameter", [](const Database& d) { return d.db->model().diameter; },
                             "The model's diameter, mm.")
      .def_property_readonly("points", [](const Database& d) { return d.db->model().points.size(); },
                             "The model's points n_M.")
      .def_property_readonly("model_points", [](const Database& d) { return arrayOf(d.db->model().points); },
                             "The model's points, n_M x 3, mm.")
      .def_property_readonly("model_normals", [](const Database& d) { return arrayOf(d.db->model().normals); },
                             "Their unit normals (out of the part), n_M x 3.");
  m.def("train", &train, py::arg("model"), py::arg("points") = 4000, py::arg("units") = "mm",
        "Trains on a mesh or cloud file, builtin:NAME, or (vertices N x 3, faces M x 3) arrays.");
  m.def("load_database", [](const std::string& path) { return Database{std::make_shared<const ModelDatabase>(ModelDatabase::load(path))}; },
        py::arg("path"), "Loads a database written by train().save() or `binpose train`.");

  py::class_<PyDetection>(m, "Detection", "One found copy of the model.")
      .def_readonly("pose", &PyDetection::pose, "4 x 4 model -> scan transform, mm")
      .def_readonly("score", &PyDetection::score, "verification score in [-1, 1]")
      .def_readonly("correspondences", &PyDetection::correspondences, "clique size |C|")
      .def_readonly("fit_rms_mm", &PyDetection::fit_rms_mm, "residual of the clique's fit, mm")
      .def("__repr__", [](const PyDetection& d) {
        const auto p = d.pose.unchecked<2>();
        return fmt::format("<Detection score={:.3f} t=({:.1f}, {:.1f}, {:.1f}) mm>", d.score, p(0, 3), p(1, 3), p(2, 3));
      });
  py::class_<PyResult>(m, "Result", "The detections, best first (a sequence), with timing_ms.")
      .def("__len__", [](const PyResult& r) { return r.detections.size(); })
      .def("__getitem__", [](const PyResult& r, std::size_t i) {
        if (i >= r.detections.size()) throw py::index_error();
        return r.detections[i];
      })
      .def("__iter__", [](const PyResult& r) { return py::make_iterator(r.detections.begin(), r.detections.end()); },
           py::keep_alive<0, 1>())
      .def_readonly("detections", &PyResult::detections)
      .def_readonly("timing_ms", &PyResult::timing_ms, "preprocess, vote, match, refine, total (ms)")
      .def_readonly("noise_mm", &PyResult::noise_mm, "the scan's noise measured on it, mm (1 sigma)")
      .def_readonly("least_score", &PyResult::least_score, "the least score reported: min_score, raised on a rough scan")
      .def_readonly("scene_points", &PyResult::scene_points)
      .def_readonly("flying_points", &PyResult::flying_points,
                    "the scan's points dropped as flying pixels, between two surfaces at a depth edge")
      .def_readonly("pixel_stride", &PyResult::pixel_stride,
                    "a depth image's pixels used: every pixel_stride-th of every pixel_stride-th row (2 or 4 where "
                    "each depth is copied over a block of pixels: registered to a sharper camera)");

  m.def(
      "guess_viewpoint",
      [](const py::object& points) {
        Points scan = pointsOf(points, "points");
        std::erase_if(scan, [](const Vec3& p) { return !isMeasured(p); });
        ViewpointGuess g;
        {
          py::gil_scoped_release released;
          g = guessViewpoint(scan);
        }
        py::dict out;
        out["viewpoint"] = py::make_tuple(g.viewpoint.x(), g.viewpoint.y(), g.viewpoint.z());
        out["moved"] = g.moved;
        out["hidden"] = g.hidden;
        out["origin_hidden"] = g.assumed_hidden;
        return out;
      },
      py::arg("points"),
      "The sensor origin of a scan (N x 3, mm) that does not give it: the origin when it can have seen the scan, "
      "else a guess from the scan (z up). A dict: viewpoint (x, y, z) mm, moved, hidden and origin_hidden (the share "
      "of points each cannot see).");
  py::class_<PyDetector>(m, "Detector", "Finds every copy of a database's model in scans.")
      .def(py::init<const Database&, const std::string&, const py::kwargs&>(), py::arg("database"), py::arg("preset") = "default",
           "preset: default or thesis; keyword parameters by DetectionParams's names (r, eta, e_gmax, C_n, ...), "
           "in mm, replacing the preset's values scaled to the model.")
      .def("detect", &PyDetector::detect, py::arg("points"), py::arg("normals") = py::none(), py::arg("viewpoint") = py::none(),
           "points: N x 3 array in mm (rows of NaN or exactly (0, 0, 0), a pixel without a depth, are dropped), or an "
           "H x W x 3 point map in the camera's frame (a depth SDK's organized cloud: read as a depth image); normals: N x 3 "
           "or None; viewpoint: (x, y, z) mm (None: the constructor's, else the "
           "origin when it can have seen the points, else guess_viewpoint's).")
      .def("detect_depth", &PyDetector::detectDepth, py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
           py::arg("depth_scale") = 1.0,
           "depth: H x W array, uint16 (as a depth PNG) or float (NaN, 0 or below: no depth); depth_mm = value * depth_scale.")
      .def("detect_file", &PyDetector::detectFile, py::arg("path"), py::arg("intrinsics") = "", py::arg("image_id") = "",
           py::arg("units") = "auto", py::arg("viewpoint") = py::none(),
           "A scan file read as `binpose detect --scene` reads it: PLY, PCD, ASCII points, a TIFF point map, a mesh's "
           "vertices, or a depth image (16-bit PNG, TIFF) with intrinsics (a BOP camera.json or scene_camera.json, "
           "image_id its entry). units: 'mm', 'cm', 'm', 'in', or 'auto' (mm, unless the scan spans less than half the model: m, "
           "with a warning). The file's viewpoint is used where it gives one.")
      .def("check", &PyDetector::check, py::arg("points"), py::arg("poses"), py::arg("viewpoint") = py::none(),
           "Why a part known to lie somewhere is or is not found: each of poses (N x 4 x 4, model -> scan, mm) refined "
           "and judged as detect judges its own. A list of dicts: refined (4 x 4), moved_mm, score, visible_support, "
           "as_found and as_laid (the first test refusing it: score, visible_support, sunk, behind_face, outline; "
           "none: it stands).")
      .def("check_depth", &PyDetector::checkDepth, py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
           py::arg("poses"), py::arg("depth_scale") = 1.0, "check on a depth image (as detect_depth).")
      .def_property_readonly("params", &PyDetector::params, "The values the detector runs with (absolute units).");
}
