// Synthetic bins: Bullet drops the parts, Embree renders the depth sensor (thesis 7.1.2).
#include <binpose/simulation.hpp>

#include "sensor_effects.hpp"

#include <binpose/geometry.hpp>
#include <binpose/sampling.hpp>
#include <binpose/shapes.hpp>

#include <BulletCollision/CollisionShapes/btShapeHull.h>
#include <btBulletDynamicsCommon.h>
#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

namespace binpose {
namespace {

/// A projector ray that meets something this much short of the surface point is shadowed, mm.
constexpr float kShadowTolerance = 0.5f;
constexpr float kMetres = 0.001f;  // Bullet works best near metre scale: it simulates in metres
/// Copies less visible than this are not a BOP target (the toolkit's visib_fract threshold).
constexpr float kTargetVisibility = 0.1f;

btVector3 toBt(const Vec3& v) { return btVector3(v.x() * kMetres, v.y() * kMetres, v.z() * kMetres); }

/// The bin's floor and walls as boxes (centre, size) in the world frame; walls `height` tall and
/// `w` thick, growing outwards.
std::vector<std::pair<Vec3, Vec3>> binBoxes(const BinParams& bin, float height, float w) {
  const Vec3 in = bin.inner;
  return {{Vec3(0, 0, -w / 2), Vec3(in.x() + 2 * w, in.y() + 2 * w, w)},
          {Vec3(in.x() / 2 + w / 2, 0, height / 2), Vec3(w, in.y() + 2 * w, height)},
          {Vec3(-in.x() / 2 - w / 2, 0, height / 2), Vec3(w, in.y() + 2 * w, height)},
          {Vec3(0, in.y() / 2 + w / 2, height / 2), Vec3(in.x(), w, height)},
          {Vec3(0, -in.y() / 2 - w / 2, height / 2), Vec3(in.x(), w, height)}};
}

/// Embree scene of triangle meshes; geometry ids in order of addition.
class RayScene {
 public:
  RayScene() : device_(rtcNewDevice("threads=1")), scene_(rtcNewScene(device_)) {}
  ~RayScene() {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
  }
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  void add(const Mesh& mesh, const Pose& pose) {
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.vertices.size()));
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
      const Vec3 p = pose * mesh.vertices[i];
      v[3 * i] = p.x(); v[3 * i + 1] = p.y(); v[3 * i + 2] = p.z();
    }
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                               3 * sizeof(unsigned), mesh.faces.size()));
    for (std::size_t f = 0; f < mesh.faces.size(); ++f)
      for (int k = 0; k < 3; ++k) idx[3 * f + k] = static_cast<unsigned>(mesh.faces[f][k]);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene_, g);
    rtcReleaseGeometry(g);
  }
  void commit() { rtcCommitScene(scene_); }

  struct Hit {
    float t = INFINITY;
    unsigned geometry = RTC_INVALID_GEOMETRY_ID;
    Vec3 normal = Vec3::Zero();
  };
  /// First hit of the ray from the origin along dir (t > 0: the point t dir).
  Hit cast(const Vec3& dir) const { return castFrom(Vec3::Zero(), dir); }
  /// First hit of the ray from `origin` along dir.
  Hit castFrom(const Vec3& origin, const Vec3& dir) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh{};
    rh.ray.org_x = origin.x(); rh.ray.org_y = origin.y(); rh.ray.org_z = origin.z();
    rh.ray.dir_x = dir.x(); rh.ray.dir_y = dir.y(); rh.ray.dir_z = dir.z();
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = INFINITY;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &context, &rh);
    Hit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    hit.t = rh.ray.tfar;
    hit.geometry = rh.hit.geomID;
    hit.normal = Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
    return hit;
  }

 private:
  RTCDevice device_;
  RTCScene scene_;
};

nlohmann::json matrixJson(const Pose& pose) {
  nlohmann::json rows = nlohmann::json::array();
  const Eigen::Matrix4f T = pose.matrix();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  return rows;
}

Pose poseFromJson(const nlohmann::json& rows) {
  Eigen::Matrix4f T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = rows.at(r).at(c).get<float>();
  Pose pose = Pose::Identity();
  pose.matrix() = T;
  return pose;
}

void writeJson(const std::string& path, const nlohmann::json& j) {
  std::ofstream out(path);
  out << j.dump(1) << "\n";
  if (!out) throw Error(fmt::format("{}: cannot write", path));
}

/// The ray from the camera through image point (u, v), px (dir.z = 1, so a hit's t is its depth),
/// and what it meets first.
struct SensorRay {
  Vec3 dir;
  RayScene::Hit hit;
  /// |cos| of the angle between the ray and the surface it meets.
  [[nodiscard]] float cosIncidence() const { return std::abs(hit.normal.dot(dir)) / (hit.normal.norm() * dir.norm()); }
  /// True when it meets a surface the sensor sees: at less than the grazing angle.
  [[nodiscard]] bool seen(float cos_grazing) const {
    return hit.geometry != RTC_INVALID_GEOMETRY_ID && cosIncidence() >= cos_grazing;
  }
};

SensorRay castThrough(const RayScene& rays, const SensorParams& sensor, double u, double v) {
  const Vec3 dir(float((u - sensor.cx) / sensor.fx), float((v - sensor.cy) / sensor.fy), 1.0f);
  return {dir, rays.cast(dir)};
}

/// The convex hull of the mesh's vertices about `centroid`, as Bullet collides it; `radius`: the
/// largest distance of a vertex from the centroid.
std::unique_ptr<btConvexHullShape> convexHull(const Mesh& mesh, const Vec3& centroid, float& radius) {
  btConvexHullShape raw;
  for (const Vec3& v : mesh.vertices) {
    raw.addPoint(toBt(v - centroid), false);
    radius = std::max(radius, (v - centroid).norm());
  }
  raw.setMargin(0.0005f);  // Bullet's default margin (0.04 units) would be 4 cm here
  raw.recalcLocalAabb();
  btShapeHull hull(&raw);
  hull.buildHull(raw.getMargin());
  auto part = std::make_unique<btConvexHullShape>(reinterpret_cast<const btScalar*>(hull.getVertexPointer()), hull.numVertices());
  part->setMargin(0.0005f);
  return part;
}

/// A settled body's pose as the model's (the body frame is the model frame shifted by the centroid), mm.
Pose modelPose(const btRigidBody& body, const Vec3& centroid) {
  const btTransform& t = body.getWorldTransform();
  const btQuaternion r = t.getRotation();
  Pose body_pose = Pose::Identity();
  body_pose.linear() = Eigen::Quaternionf(float(r.w()), float(r.x()), float(r.y()), float(r.z())).toRotationMatrix();
  body_pose.translation() = Vec3(float(t.getOrigin().x()), float(t.getOrigin().y()), float(t.getOrigin().z())) / kMetres;
  return body_pose * Eigen::Translation3f(-centroid);
}

/// The pixels the mesh at `pose` (camera frame) would cover with nothing in front, seen at less
/// than the sensor's grazing angle.
int pixelsCovered(const Mesh& mesh, const Pose& pose, const SensorParams& sensor, float cos_grazing) {
  const int W = sensor.width, H = sensor.height;
  RayScene alone;
  alone.add(mesh, pose);
  alone.commit();
  double u0 = W, v0 = H, u1 = -1, v1 = -1;
  for (const Vec3& vertex : mesh.vertices) {
    const Vec3 p = pose * vertex;
    if (p.z() <= 0) continue;
    const double u = sensor.fx * p.x() / p.z() + sensor.cx, v = sensor.fy * p.y() / p.z() + sensor.cy;
    u0 = std::min(u0, u); u1 = std::max(u1, u); v0 = std::min(v0, v); v1 = std::max(v1, v);
  }
  int covered = 0;
  for (int v = std::max(0, int(std::floor(v0))); v <= std::min(H - 1, int(std::ceil(v1))); ++v)
    for (int u = std::max(0, int(std::floor(u0))); u <= std::min(W - 1, int(std::ceil(u1))); ++u) {
      covered += castThrough(alone, sensor, u, v).seen(cos_grazing);
    }
  return covered;
}

/// The ideal sensor's depth at pixel (u, v), mm (0: none): Gaussian noise of noise_sigma at
/// 500 mm, growing with range^2. `geometry`: what the ray hit.
float idealPixel(const RayScene& rays, const SensorParams& sensor, std::uint64_t seed, int u, int v, float cos_grazing,
                 unsigned& geometry) {
  const SensorRay ray = castThrough(rays, sensor, u, v);
  if (!ray.seen(cos_grazing)) return 0.0f;
  const RayScene::Hit& hit = ray.hit;
  const std::size_t pixel = static_cast<std::size_t>(v) * sensor.width + u;
  Rng rng(seed * 0x9E3779B97F4A7C15ull + pixel);  // per pixel: same image whatever the threads
  const float z = hit.t;  // dir.z = 1, so t is the depth
  geometry = hit.geometry;
  return z + sensor.noise_sigma * (z / 500.0f) * (z / 500.0f) * rng.gaussian();
}

/// A modelled sensor's depth at pixel (u, v), mm (0: none; sensor_model.hpp): the ray jittered
/// by the lateral noise, dropped where the projector cannot see the surface, axial noise by
/// range and angle, then the disparity's quantisation.
float modelledPixel(const RayScene& rays, const SensorParams& sensor, std::uint64_t seed, int u, int v, float cos_grazing,
                    unsigned& geometry) {
  const SensorModel& m = sensor.model;
  const std::size_t pixel = static_cast<std::size_t>(v) * sensor.width + u;
  Rng rng(seed * 0x9E3779B97F4A7C15ull + pixel);
  const double du = m.lateral_px * rng.gaussian(), dv = m.lateral_px * rng.gaussian();
  const SensorRay ray = castThrough(rays, sensor, u + du, v + dv);
  if (!ray.seen(cos_grazing)) return 0.0f;
  const RayScene::Hit& hit = ray.hit;
  const Vec3& dir = ray.dir;
  const float z = hit.t;
  if (m.baseline > 0) {  // the projector's view of the point: anything nearer on the way casts a shadow
    const Vec3 projector(m.baseline, 0.0f, 0.0f), to = dir * z - projector;
    const float reach = to.norm();
    if (rays.castFrom(projector, to / reach).t < reach - kShadowTolerance) return 0.0f;
  }
  const float theta = std::acos(std::min(1.0f, ray.cosIncidence()));
  geometry = hit.geometry;
  return quantisedDepth(m, z + axialSigma(m, z, theta) * rng.gaussian(), sensor.fx);
}

}  // namespace

std::vector<Pose> dropIntoBin(const Mesh& mesh, int count, const BinParams& bin, float settle_seconds, std::uint64_t seed) {
  if (count < 0 || count > 1000) throw Error(fmt::format("instances must lie in [0, 1000], got {}", count));
  if (!(bin.inner.minCoeff() > 0) || !(bin.wall > 0)) throw Error("bin dimensions must be positive");
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
  world.setGravity(btVector3(0, 0, -9.81f));
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btRigidBody>> bodies;
  std::vector<std::unique_ptr<btDefaultMotionState>> states;

  // The part: the convex hull of its vertices about its centroid (Bullet's centre of mass).
  const Vec3 centroid = surfaceCentroid(mesh);
  float radius = 0;
  const auto part = convexHull(mesh, centroid, radius);
  const btScalar mass = 0.02f;
  btVector3 inertia(0, 0, 0);
  part->calculateLocalInertia(mass, inertia);

  // Walls taller than the pile, so that nothing falls out while the parts settle.
  const float wall_height = bin.inner.z() + 2.5f * radius * static_cast<float>(count + 2);  // generous
  // Thick physics-only walls and floor: a falling part must not tunnel through in one step.
  for (const auto& [centre, size] : binBoxes(bin, wall_height, std::max(bin.wall, 200.0f))) {
    shapes.push_back(std::make_unique<btBoxShape>(toBt(size / 2)));
    btRigidBody::btRigidBodyConstructionInfo info(0, nullptr, shapes.back().get());
    info.m_startWorldTransform.setOrigin(toBt(centre));
    info.m_friction = 0.6f;
    bodies.push_back(std::make_unique<btRigidBody>(info));
    world.addRigidBody(bodies.back().get());
  }
  Rng rng(seed);
  // Spawn in layers of a grid of cells 2.1 radii wide, jittered, from just above the floor up.
  const float cell = 2.1f * radius;
  const int nx = std::max(1, static_cast<int>(bin.inner.x() / cell)), ny = std::max(1, static_cast<int>(bin.inner.y() / cell));
  std::vector<btRigidBody*> parts;
  for (int i = 0; i < count; ++i) {
    const Eigen::Quaternionf q = rng.rotation();
    const int slot = i % (nx * ny), layer = i / (nx * ny);
    const float jitter = 0.05f * radius;
    const Vec3 at(cell * (float(slot % nx) - 0.5f * float(nx - 1)) + float(rng.uniform() - 0.5) * jitter,
                  cell * (float(slot / nx) - 0.5f * float(ny - 1)) + float(rng.uniform() - 0.5) * jitter,
                  radius * (1.2f + 2.2f * float(layer)) + float(rng.uniform()) * radius);
    btTransform start;
    start.setRotation(btQuaternion(q.x(), q.y(), q.z(), q.w()));
    start.setOrigin(toBt(at));
    states.push_back(std::make_unique<btDefaultMotionState>(start));
    btRigidBody::btRigidBodyConstructionInfo info(mass, states.back().get(), part.get(), inertia);
    info.m_friction = 0.5f;
    info.m_restitution = 0.1f;
    info.m_linearDamping = 0.05f;
    info.m_angularDamping = 0.1f;
    bodies.push_back(std::make_unique<btRigidBody>(info));
    bodies.back()->setActivationState(DISABLE_DEACTIVATION);
    world.addRigidBody(bodies.back().get());
    parts.push_back(bodies.back().get());
  }
  const float dt = 1.0f / 240.0f;
  const int steps = static_cast<int>(settle_seconds / dt);
  for (int s = 0; s < steps; ++s) world.stepSimulation(dt, 1, dt);

  std::vector<Pose> poses;
  for (btRigidBody* body : parts) poses.push_back(modelPose(*body, centroid));
  for (auto& body : bodies) world.removeRigidBody(body.get());
  return poses;
}

SimulatedScene renderBin(const Mesh& mesh, const std::vector<Pose>& world_poses, const BinParams& bin,
                         const SensorParams& sensor, std::uint64_t seed) {
  if (sensor.width < 1 || sensor.height < 1 || sensor.width * sensor.height > 50'000'000 || !(sensor.fx > 0) || !(sensor.fy > 0))
    throw Error("sensor resolution and focal lengths must be positive");
  if (!(sensor.distance > bin.inner.z())) throw Error("the sensor must be above the bin's rim");
  SimulatedScene out;
  // Camera above the bin centre looking down: x right, y down, z into the bin.
  out.camera_from_world = Pose::Identity();
  out.camera_from_world.linear() = Eigen::Vector3f(1, -1, -1).asDiagonal();
  out.camera_from_world.translation() = Vec3(0, 0, sensor.distance);
  RayScene rays;
  for (const Pose& p : world_poses) rays.add(mesh, out.camera_from_world * p);
  for (const auto& [centre, size] : binBoxes(bin, bin.inner.z(), bin.wall))
    rays.add(makeBox(size), out.camera_from_world * Eigen::Translation3f(centre));
  rays.commit();

  out.intrinsics = {sensor.fx, sensor.fy, sensor.cx, sensor.cy, sensor.depth_scale, sensor.width, sensor.height};
  const int W = sensor.width, H = sensor.height;
  const float cos_grazing = std::cos(sensor.grazing_deg * float(M_PI) / 180.0f);
  std::vector<float> depth(static_cast<std::size_t>(W) * H, 0.0f);  // mm; 0: no return
  std::vector<unsigned> seen(depth.size(), RTC_INVALID_GEOMETRY_ID);
  tbb::parallel_for(0, H, [&](int v) {
    for (int u = 0; u < W; ++u) {
      const std::size_t pixel = static_cast<std::size_t>(v) * W + u;
      depth[pixel] = sensor.model.kind == SensorKind::Ideal ? idealPixel(rays, sensor, seed, u, v, cos_grazing, seen[pixel])
                                                            : modelledPixel(rays, sensor, seed, u, v, cos_grazing, seen[pixel]);
    }
  });
  applyEdgeEffects(depth, W, H, sensor.model, seed);
  applyMultipath(depth, W, H, sensor.model);
  out.depth.assign(depth.size(), 0);
  std::vector<int> owner(out.depth.size(), -1);
  for (std::size_t pixel = 0; pixel < depth.size(); ++pixel) {
    if (seen[pixel] == RTC_INVALID_GEOMETRY_ID) continue;
    const double raw = std::round(depth[pixel] / sensor.depth_scale);
    if (raw < 1 || raw > 65535) continue;
    out.depth[pixel] = static_cast<std::uint16_t>(raw);
    if (seen[pixel] < world_poses.size()) owner[pixel] = static_cast<int>(seen[pixel]);
  }
  out.cloud = depthToCloud(out.depth, W, H, out.intrinsics);

  // Visible fraction: even samples of the surface, each visible if the ray to it hits it first.
  const auto samples = sampleSurfaceUniform(mesh, 4000, seed ^ 0x5EEDull);
  out.instances.resize(world_poses.size());
  for (std::size_t i = 0; i < world_poses.size(); ++i) {
    SimulatedInstance& inst = out.instances[i];
    inst.pose = out.camera_from_world * world_poses[i];
    int visible = 0;
    for (const SurfacePoint& s : samples) {
      const Vec3 p = inst.pose * s.point;
      if (p.z() <= 0) continue;
      const double u = sensor.fx * p.x() / p.z() + sensor.cx, v = sensor.fy * p.y() / p.z() + sensor.cy;
      if (u < -0.5 || v < -0.5 || u > W - 0.5 || v > H - 0.5) continue;
      const RayScene::Hit hit = rays.cast(p);
      if (hit.geometry == i && std::abs(hit.t - 1.0f) * p.norm() < 0.05f) ++visible;
    }
    inst.visible_fraction = static_cast<float>(visible) / static_cast<float>(samples.size());
  }
  for (const int o : owner)
    if (o >= 0) ++out.instances[static_cast<std::size_t>(o)].visible_pixels;
  // BOP's visib_fract: visible pixels over the pixels the instance would cover with nothing in front.
  for (SimulatedInstance& inst : out.instances) {
    const int covered = pixelsCovered(mesh, inst.pose, sensor, cos_grazing);
    inst.visib_fract = covered == 0 ? 0.0f : static_cast<float>(inst.visible_pixels) / static_cast<float>(covered);
  }
  return out;
}

SimulatedScene simulateBin(const Mesh& mesh, const SimulationParams& params) {
  const auto poses = dropIntoBin(mesh, params.instances, params.bin, params.settle_seconds, params.seed);
  return renderBin(mesh, poses, params.bin, params.sensor, params.seed);
}

namespace {

/// BOP's per-scene files for image 0: scene_gt.json, scene_gt_info.json, scene_camera.json.
struct BopSceneFiles {
  nlohmann::json gt, info, camera;
};

BopSceneFiles bopSceneFiles(const SimulatedScene& scene, int obj_id) {
  nlohmann::json gt = nlohmann::json::array(), info = nlohmann::json::array();
  for (const SimulatedInstance& inst : scene.instances) {
    const Eigen::Matrix3f R = inst.pose.linear();  // BOP: row-major
    const Vec3 t = inst.pose.translation();
    gt.push_back({{"cam_R_m2c", {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)}},
                  {"cam_t_m2c", {t.x(), t.y(), t.z()}}, {"obj_id", obj_id}});
    info.push_back({{"visib_fract", inst.visib_fract}, {"px_count_visib", inst.visible_pixels}});
  }
  const Intrinsics& k = scene.intrinsics;
  nlohmann::json camera{{"cam_K", {k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0}}, {"depth_scale", k.depth_scale}};
  return {{{"0", gt}}, {{"0", info}}, {{"0", camera}}};
}

/// The JSON of `path`, or `fallback` when there is no such file.
nlohmann::json jsonOr(const std::string& path, nlohmann::json fallback) {
  if (!std::filesystem::exists(path)) return fallback;
  std::ifstream in(path);
  auto j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded() || j.type() != fallback.type()) throw Error(fmt::format("{}: not the JSON this file should hold", path));
  return j;
}

}  // namespace

void writeScene(const std::string& dir, const SimulatedScene& scene, const std::string& model_name,
                const std::string& model_info) {
  std::filesystem::create_directories(dir);
  const Intrinsics& k = scene.intrinsics;
  const bool imaged = !scene.depth.empty();  // a thesis-style scene is a cloud without a camera
  if (imaged) {
    writeDepthPng(dir + "/depth.png", scene.depth, k.width, k.height);
    writeJson(dir + "/camera.json", {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"depth_scale", k.depth_scale},
                                     {"width", k.width}, {"height", k.height}});
  }
  writePly(dir + "/scene.ply", scene.cloud.points);
  nlohmann::json gt{{"model", model_name}, {"units", "mm"}, {"camera_from_world", matrixJson(scene.camera_from_world)}};
  gt["instances"] = nlohmann::json::array();
  for (const SimulatedInstance& inst : scene.instances)
    gt["instances"].push_back({{"pose", matrixJson(inst.pose)}, {"visible_fraction", inst.visible_fraction},
                               {"visible_pixels", inst.visible_pixels}, {"visib_fract", inst.visib_fract}});
  writeJson(dir + "/ground_truth.json", gt);
  const BopSceneFiles bop = bopSceneFiles(scene, 1);
  writeJson(dir + "/scene_gt.json", bop.gt);
  writeJson(dir + "/scene_gt_info.json", bop.info);
  if (imaged) writeJson(dir + "/scene_camera.json", bop.camera);
  if (!model_info.empty()) writeJson(dir + "/models_info.json", {{"1", nlohmann::json::parse(model_info)}});
}

void writeBopScene(const std::string& dataset, int scene_id, int obj_id, const SimulatedScene& scene, const Mesh& mesh,
                   const std::string& model_info) {
  if (scene.depth.empty()) throw Error(fmt::format("{}: a BOP scene needs a depth image (not a thesis-style cloud)", dataset));
  const std::string models = dataset + "/models", id = fmt::format("{:06}", obj_id);
  const std::string dir = fmt::format("{}/test/{:06}", dataset, scene_id);
  std::filesystem::create_directories(models);
  std::filesystem::create_directories(dir + "/depth");
  writePly(models + "/obj_" + id + ".ply", mesh.vertices, {}, mesh.faces);
  nlohmann::json info = jsonOr(models + "/models_info.json", nlohmann::json::object());
  info[std::to_string(obj_id)] = nlohmann::json::parse(model_info);
  writeJson(models + "/models_info.json", info);
  writeDepthPng(dir + "/depth/000000.png", scene.depth, scene.intrinsics.width, scene.intrinsics.height);
  const BopSceneFiles bop = bopSceneFiles(scene, obj_id);
  writeJson(dir + "/scene_gt.json", bop.gt);
  writeJson(dir + "/scene_gt_info.json", bop.info);
  writeJson(dir + "/scene_camera.json", bop.camera);
  // The target: the copies at least 10 % visible (BOP's own rule for its targets), at least one.
  const auto seen = std::count_if(scene.instances.begin(), scene.instances.end(),
                                  [](const SimulatedInstance& i) { return i.visib_fract >= kTargetVisibility; });
  nlohmann::json targets = jsonOr(dataset + "/test_targets_bop19.json", nlohmann::json::array());
  nlohmann::json kept = nlohmann::json::array();
  for (const auto& t : targets)
    if (!(t.value("scene_id", -1) == scene_id && t.value("obj_id", -1) == obj_id)) kept.push_back(t);
  kept.push_back({{"im_id", 0}, {"inst_count", std::max<long>(1, seen)}, {"obj_id", obj_id}, {"scene_id", scene_id}});
  writeJson(dataset + "/test_targets_bop19.json", kept);
}

std::string defaultModelInfo(const std::string& model_name, const Mesh& mesh) {
  nlohmann::json info{{"diameter", diameter(mesh.vertices)}, {"symmetries_discrete", nlohmann::json::array()},
                      {"symmetries_continuous", nlohmann::json::array()}};
  if (model_name == "builtin:cap" || model_name == "builtin:sphere")  // bodies of revolution about z
    info["symmetries_continuous"].push_back({{"axis", {0, 0, 1}}, {"offset", {0, 0, 0}}});
  return info.dump();
}

GroundTruth readGroundTruth(const std::string& dir) {
  const std::string path = dir + "/ground_truth.json";
  std::ifstream in(path);
  if (!in) throw Error(fmt::format("{}: no ground truth here (run binpose simulate)", path));
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded() || !j.contains("instances")) throw Error(fmt::format("{}: not a binpose ground truth file", path));
  GroundTruth gt;
  gt.model = j.value("model", "");
  try {
    for (const auto& inst : j["instances"]) {
      SimulatedInstance s;
      s.pose = poseFromJson(inst.at("pose"));
      s.visible_fraction = inst.value("visible_fraction", 0.0f);
      s.visible_pixels = inst.value("visible_pixels", 0);
      s.visib_fract = inst.value("visib_fract", 0.0f);
      gt.instances.push_back(s);
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(fmt::format("{}: malformed instance ({})", path, e.what()));
  }
  return gt;
}

}  // namespace binpose
