// ICP refinement against synthetic views with exact ground truth.
#include <binpose/model.hpp>
#include <binpose/refine.hpp>
#include <binpose/pixel_neighbours.hpp>
#include <binpose/planes.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>

#include "synthetic.hpp"
#include "test_util.hpp"

namespace binpose {
namespace {

struct Case {
  Mesh mesh;
  OrientedModel model;
  Pose truth;
  PointCloud scan;
};

Case view(const Mesh& mesh, const Vec3& tilt_axis) {
  Case c{mesh, prepareModel(mesh, ModelParams{}), Pose::Identity(), {}};
  c.truth.linear() = Eigen::AngleAxisf(0.6f, tilt_axis.normalized()).toRotationMatrix();
  c.truth.translation() = Vec3(5, -8, 480);
  c.scan = test::renderCopies(mesh, {c.truth}, test::SyntheticView{}, [](std::size_t, const Vec3&) { return true; });
  return c;
}

Pose refine(const Case& c, const Pose& start) {
  const PointGrid grid(c.scan.points);
  return refinePose(start, c.model.points, c.model.normals, c.scan.points, grid, IcpParams{});
}

/// The floor z = 500 mm seen from the origin, a point every `step` mm over |x|, |y| <= `half`,
/// but where a 60 x 40 mm face at depth `face_z` hides it (|x| <= 30, |y| <= 20): the scan, and
/// the floor as a background plane whose extent is its points (holes up to `hole` mm).
struct FloorAround {
  Points scan;
  Plane plane{-Vec3::UnitZ(), -500.0f, {}};  // its normal towards the sensor
};
FloorAround floorAround(float face_z, float half, float step, float hole) {
  FloorAround f;
  std::vector<std::uint32_t> floor;
  for (float x = -half; x <= half; x += step)
    for (float y = -half; y <= half; y += step) {
      const bool face = std::abs(x) <= 30 && std::abs(y) <= 20;
      if (!face) floor.push_back(static_cast<std::uint32_t>(f.scan.size()));
      f.scan.emplace_back(x, y, face ? face_z : 500.0f);
    }
  f.plane.extent = std::make_shared<const PlaneFootprint>(f.scan, floor, f.plane, 3.0f, hole);
  return f;
}

/// `pose` moved by `t` (mm) and turned by `angle` (rad) about `axis` through the part's origin.
Pose perturbed(const Pose& pose, const Vec3& t, float angle, const Vec3& axis) {
  Pose p = pose;
  p.linear() = pose.linear() * Eigen::AngleAxisf(angle, axis.normalized()).toRotationMatrix();
  p.translation() += t;
  return p;
}

/// The cap's model, and six caps dropped into the bin (`seed`) as the default sensor sees them.
std::pair<OrientedModel, SimulatedScene> capsDropped(std::uint64_t seed) {
  const Mesh cap = makeCap();
  const BinParams bin;
  return {prepareModel(cap, ModelParams{}), renderBin(cap, dropIntoBin(cap, 6, bin, 1.0f, seed), bin, SensorParams{}, 3)};
}

double angleDeg(const Eigen::Matrix3f& a, const Eigen::Matrix3f& b) {
  return test::deg(Eigen::AngleAxisf(a.transpose() * b).angle());
}

TEST(Refine, ConvergesToTheTruthFromAMillimetreAndTwoDegreesOff) {
  const Case c = view(builtinPart("box"), Vec3(1, 2, 0.5f));
  const Pose start = perturbed(c.truth, Vec3(0.7f, -0.5f, 0.6f), 0.035f, Vec3(1, 1, 0));
  const Pose r = refine(c, start);
  EXPECT_LT((r.translation() - c.truth.translation()).norm(), 0.05);
  EXPECT_LT(angleDeg(r.linear(), c.truth.linear()), 0.1);
}

// A body of revolution fixes its axis but not its spin about it: ICP must find the axis and
// leave the spin where the start put it, not drift along the free direction on noise.
TEST(Refine, BodyOfRevolutionFindsItsAxisAndKeepsItsSpin) {
  const Case c = view(makeCap(), Vec3(1, -1, 0));
  const float spin = 0.5f;  // rad about the cap's axis (+z in the model)
  const Pose spun = perturbed(c.truth, Vec3::Zero(), spin, Vec3::UnitZ());
  const Pose start = perturbed(spun, Vec3(0.6f, 0.5f, -0.5f), 0.035f, Vec3(1, 0, 0));
  const Pose r = refine(c, start);
  const Vec3 axis = r.linear() * Vec3::UnitZ(), true_axis = c.truth.linear() * Vec3::UnitZ();
  EXPECT_LT(test::deg(std::acos(std::min(1.0f, axis.dot(true_axis)))), 0.1);
  // The part's origin lies on its axis: its position is fixed whatever the spin.
  EXPECT_LT((r.translation() - c.truth.translation()).norm(), 0.05);
  // Spin left: the angle between the refined and the spun start's orientations.
  EXPECT_LT(angleDeg(r.linear(), spun.linear()), 0.5);
}

// A part posed flush with the bin's floor is supported by every floor point under it; with the
// floor given as background it is not supported at all.
TEST(Evidence, TheBinsPlanesDoNotSupportAPart) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  PointCloud floor;  // the plane z = 500 mm, seen from the origin
  for (float x = -100; x <= 100; x += 0.5f)
    for (float y = -100; y <= 100; y += 0.5f) floor.points.emplace_back(x, y, 500.0f);
  const PointGrid grid(floor.points);
  Pose flush = Pose::Identity();  // the box's -z face (facing the sensor) in the floor
  flush.translation() = Vec3(10, -5, 510);
  const auto score = [&](std::vector<Plane> background) {
    SceneEvidence evidence(floor.points, grid, Vec3::Zero());
    evidence.setBackground(std::move(background), 1.0f);
    return evidence.evaluate(flush, box.points, box.normals, 1.0f, box.sample_radius).score();
  };
  EXPECT_GT(score({}), 0.8f);
  EXPECT_LT(score({Plane{Vec3::UnitZ(), 500.0f, {}}}), 0.05f);
  // A plane elsewhere changes nothing.
  EXPECT_GT(score({Plane{Vec3::UnitX(), 300.0f, {}}}), 0.8f);
}

// A scan 3 mm between points (a sensor far away, or of few pixels) and a 60 x 40 mm face of
// model points 1 mm apart laid on it: only a third of the face's points have a scan point within
// the 1 mm tolerance, though the pose is right. With the sampling's slack along the surface
// (0.75 spacings) every one is supported; the same face 3 mm in front of the scan or tilted
// by 10 degrees across it, no more than before.
TEST(Evidence, ASparseScanSupportsARightPoseAlongItsSurface) {
  Points scan;
  for (float x = -150; x <= 150; x += 3)
    for (float y = -150; y <= 150; y += 3) scan.emplace_back(x, y, 500.0f);
  Points face, normals;
  for (float x = -30; x <= 30; x += 1)
    for (float y = -20; y <= 20; y += 1) {
      face.emplace_back(x + 0.4f, y + 0.7f, 0.0f);
      normals.push_back(-Vec3::UnitZ());  // towards the sensor at the origin
    }
  const PointGrid grid(scan);
  SceneEvidence evidence(scan, grid, Vec3::Zero());
  const auto share = [&](const Pose& pose) {
    const Evidence e = evidence.evaluate(pose, face, normals, 1.0f, 0.0f);
    return float(e.supported) / float(e.facing);
  };
  Pose flush = Pose::Identity();
  flush.translation() = Vec3(0, 0, 500);
  Pose in_front = flush;
  in_front.translation().z() = 497;
  Pose tilted = flush;
  tilted.linear() = Eigen::AngleAxisf(10.0f * float(M_PI) / 180.0f, Vec3::UnitY()).toRotationMatrix();
  const float sparse = share(flush), front = share(in_front), tilt = share(tilted);
  EXPECT_LT(sparse, 0.5f);
  evidence.setLateralSlack(0.75f * 3.0f);
  EXPECT_GT(share(flush), 0.99f);
  EXPECT_EQ(share(in_front), front);
  EXPECT_EQ(front, 0.0f);
  EXPECT_LT(share(tilted), 0.25f);  // only the band where the tilted face crosses the scan
  EXPECT_GT(share(tilted), tilt);
}

// A box lying on the floor hides the floor beneath it; the same box stood on end and sunk half
// into that hidden floor is hidden there too (the free-space test sees the box's top first),
// but lies inside the floor that the scan shows all around it.
TEST(Evidence, APoseSunkIntoTheFloorIsToldFromOneLyingOnIt) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  const auto [scan, plane] = floorAround(480.0f, 150.0f, 1.0f, box.diameter);  // the box's top at 480 mm
  const PointGrid grid(scan);
  SceneEvidence evidence(scan, grid, Vec3::Zero());
  evidence.setBackground({plane}, 1.0f);
  const PreparedModel model(box.points, box.normals);
  const auto share = [&](const Pose& pose) { return evidence.sinking(pose, model, 3.0f, box.diameter / 2).share(); };
  Pose lying = Pose::Identity();
  lying.translation() = Vec3(0, 0, 490);
  Pose on_end = lying;  // its 60 mm side along the line of sight, its middle in the floor
  on_end.linear() = Eigen::AngleAxisf(float(M_PI) / 2, Vec3::UnitY()).toRotationMatrix();
  on_end.translation() = Vec3(0, 0, 500);
  EXPECT_EQ(share(lying), 0.0f);
  EXPECT_GT(share(on_end), 0.3f);
  // Off the floor's edge nothing is known of what lies behind it.
  on_end.translation() = Vec3(300, 0, 500);
  EXPECT_EQ(share(on_end), 0.0f);
}

// A box off to the side of the sensor shows it its top and one side face. Laid with its top in a
// larger surface (a table no background plane fits), its side face lies behind that surface's
// plane, where the scan shows the plane in front of it; standing on a floor, that face is seen.
TEST(Evidence, APoseSunkBehindItsOwnFaceIsToldFromOneStanding) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  const PreparedModel model(box.points, box.normals);
  Pose pose = Pose::Identity();  // top z = 490, x in [170, 230], y in [-20, 20]; side x = 170
  pose.translation() = Vec3(200, 0, 500);
  const Plane top{-Vec3::UnitZ(), -490.0f, {}};  // its normal towards the sensor
  const auto judge = [&](const Points& scan) {
    const PointGrid grid(scan);
    const SceneEvidence evidence(scan, grid, Vec3::Zero());
    return evidence.sunkBehind(top, pose, model, 1.0f, box.sample_radius);
  };
  Points table, standing;
  for (float x = 100.25f; x < 300; x += 0.5f)
    for (float y = -59.75f; y < 60; y += 0.5f) {
      const bool under = x >= 170 && x <= 230 && std::abs(y) <= 20;
      table.emplace_back(x, y, 490.0f);
      standing.emplace_back(x, y, under ? 490.0f : 510.0f);  // the floor 20 mm behind the top
    }
  for (float y = -19.75f; y < 20; y += 0.5f)
    for (float z = 490.25f; z < 510; z += 0.5f) standing.emplace_back(170.0f, y, z);  // the side face
  const Sinking sunk = judge(table), stood = judge(standing);
  // The side face is 800 of the 3200 mm^2 facing the sensor, seen at 71 degrees (sparser in the
  // self-occlusion test's cells), less its 2 mm next to the top; the rule's limit is a tenth.
  EXPECT_GT(sunk.points, 1000);
  EXPECT_GT(sunk.share(), 0.1f);
  EXPECT_LT(sunk.share(), 0.3f);
  EXPECT_GT(stood.points, 1000);
  EXPECT_LT(stood.share(), 0.02f);  // a few side points where the range image's cell holds the top's rim
}

// The share of what the scan should show that it supports: high for a right pose two thirds
// hidden behind a plate (its score is low), low for a pose mostly beyond the scan's edge that
// meets the scan only in its last sixth (its score would pass min_score).
TEST(Evidence, VisibleSupportTellsAHiddenPartFromAPassingPose) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  Pose hidden = Pose::Identity();  // near face z = 490, x in [-30, 30], y in [-20, 20]
  hidden.translation() = Vec3(0, 0, 500);
  PointCloud scan;
  for (float x = -59.75f; x < 60; x += 0.5f)
    for (float y = -39.75f; y < 40; y += 0.5f) {
      if (x < 10) scan.points.emplace_back(x * 0.8f, y * 0.8f, 400.0f);  // a plate in front, hiding x < 10
      else if (x <= 30 && std::abs(y) <= 20) scan.points.emplace_back(x, y, 490.0f);  // the box's face it leaves
    }
  const PointGrid grid(scan.points);
  const SceneEvidence evidence(scan.points, grid, Vec3::Zero());
  const Evidence behind = evidence.evaluate(hidden, box.points, box.normals, 1.0f, box.sample_radius);
  EXPECT_LT(behind.score(), 0.45f);
  EXPECT_GT(behind.visibleSupport(), 0.9f);

  PointCloud edge;  // a surface z = 490 that the scan shows up to x = 0 only
  for (float x = -99.75f; x < 0; x += 0.5f)
    for (float y = -39.75f; y < 40; y += 0.5f) edge.points.emplace_back(x, y, 490.0f);
  const PointGrid edge_grid(edge.points);
  const SceneEvidence at_edge(edge.points, edge_grid, Vec3::Zero());
  Pose passing = hidden;  // x in [-10, 50]: a sixth of its face on the scan
  passing.translation().x() = 20;
  const Evidence outside = at_edge.evaluate(passing, box.points, box.normals, 1.0f, box.sample_radius);
  EXPECT_GT(outside.score(), 0.15f);
  EXPECT_LT(outside.visibleSupport(), 0.3f);
}

// A box's near face laid on a larger surface of the scan (the top of a bigger box) is supported
// wherever it lies, and scores as if it were there; past its outline the scan goes on along the
// same plane. The same box lying on a floor 50 mm behind, or with a plate in front beyond one of
// its edges, has an outline the scan drops from or rises to: none continued.
TEST(Evidence, OutlineTellsAFaceLaidOnALargerSurface) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  const PreparedModel model(box.points, box.normals);
  Pose pose = Pose::Identity();  // near face z = 490, x in [-30, 30], y in [-20, 20]
  pose.translation() = Vec3(0, 0, 500);
  const auto judge = [&](const PointCloud& scan) {
    const PointGrid grid(scan.points);
    const SceneEvidence evidence(scan.points, grid, Vec3::Zero());
    return std::pair{evidence.evaluate(pose, model, 1.0f, box.sample_radius), evidence.outline(pose, model, 1.0f, box.sample_radius)};
  };
  PointCloud larger, on_floor, beside_plate;
  for (float x = -99.75f; x < 100; x += 0.5f)
    for (float y = -59.75f; y < 60; y += 0.5f) {
      const bool face = std::abs(x) <= 30 && std::abs(y) <= 20;
      larger.points.emplace_back(x, y, 490.0f);
      on_floor.points.emplace_back(x, y, face ? 490.0f : 540.0f);
      beside_plate.points.emplace_back(x, y, face ? 490.0f : x > 30 ? 450.0f : 540.0f);
    }
  const auto [laid, laid_outline] = judge(larger);
  EXPECT_GT(laid.score(), 0.9f);
  EXPECT_GT(laid_outline.judged, 50);
  EXPECT_GT(laid_outline.share(), 0.9f);
  EXPECT_EQ(laid_outline.dropped, 0);  // nothing falls away around it
  for (const PointCloud* scan : {&on_floor, &beside_plate}) {
    const auto [right, right_outline] = judge(*scan);
    EXPECT_GT(right.score(), 0.9f);
    EXPECT_GT(right_outline.judged, 30);
    EXPECT_EQ(right_outline.continued, 0);
  }
  // Off the floor, the scan falls away behind the whole outline; beside the plate (in front,
  // past the edge x = 30), behind the rest of it.
  const OutlineEvidence floor_outline = judge(on_floor).second, plate_outline = judge(beside_plate).second;
  EXPECT_EQ(floor_outline.dropped, floor_outline.judged);
  EXPECT_GT(plate_outline.droppedShare(), 0.5f);
  EXPECT_LT(plate_outline.droppedShare(), 0.9f);
}

// A plate of 3 mm sheet lying on the floor: past its outline the floor lies 3 mm behind its face,
// within the outline's band (two tolerances of 2 mm), as the surface of a larger plate would. For
// a pose laid on one face (`on_bin`) the floor, a background plane that the plate stands clear
// of, counts as dropped: the bin it lies on. A plate flush with the floor (its face in it) is not
// clear of it, and its outline still continues.
TEST(Evidence, OutlineOfAThinPlateOnTheFloorDropsToTheBin) {
  const OrientedModel plate = prepareModel(makeBox(Vec3(60, 40, 3), 4), ModelParams{});  // centred
  const PreparedModel model(plate.points, plate.normals);
  const auto [scan, plane] = floorAround(497.0f, 100.0f, 0.5f, plate.diameter);  // the plate's face at 497 mm
  const PointGrid grid(scan);
  SceneEvidence evidence(scan, grid, Vec3::Zero());
  evidence.setBackground({plane}, 1.0f);
  Pose lying = Pose::Identity();
  lying.translation() = Vec3(0, 0, 498.5f);
  const OutlineEvidence judged = evidence.outline(lying, model, 2.0f, plate.sample_radius);
  const OutlineEvidence on_bin = evidence.outline(lying, model, 2.0f, plate.sample_radius, true);
  EXPECT_GT(judged.judged, 30);
  EXPECT_GT(judged.share(), 0.9f);
  EXPECT_EQ(on_bin.judged, judged.judged);
  EXPECT_LT(on_bin.share(), 0.05f);
  EXPECT_GT(on_bin.droppedShare(), 0.95f);
  EXPECT_EQ(on_bin.continued + on_bin.dropped, on_bin.judged);

  const Points flat = floorAround(500.0f, 100.0f, 0.5f, plate.diameter).scan;  // the floor alone, the plate's face laid in it
  const PointGrid flat_grid(flat);
  SceneEvidence floor_only(flat, flat_grid, Vec3::Zero());
  floor_only.setBackground({plane}, 1.0f);
  Pose flush = lying;
  flush.translation().z() = 501.5f;
  const OutlineEvidence in_floor = floor_only.outline(flush, model, 2.0f, plate.sample_radius, true);
  EXPECT_GT(in_floor.judged, 30);
  EXPECT_GT(in_floor.share(), 0.9f);
}

// A box standing beside the line of sight, as a sensor sees it: its near face only, and the
// floor far behind where the box does not hide it. Two of its side faces face the sensor, but
// at 82-84 degrees, nearly edge-on: a sensor drops such surface, so that they are neither seen
// nor contradicted, and count against the score; the score without grazing points leaves them
// out.
TEST(Evidence, GrazingPointsAreCountedApart) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  Pose pose = Pose::Identity();
  pose.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // 60 along x, 20 along y, 40 deep (z)
  pose.translation() = Vec3(88, 68, 500);        // near face z = 480: x in [58, 118], y in [58, 78]
  PointCloud scan;
  for (float x = 58.25f; x < 118; x += 0.5f)  // the near face
    for (float y = 58.25f; y < 78; y += 0.5f) scan.points.emplace_back(x, y, 480.0f);
  const auto shadowed = [](float u, float v) {  // the box's outline, in tangent units
    return u >= 58.0f / 520 && u <= 118.0f / 480 && v >= 58.0f / 520 && v <= 78.0f / 480;
  };
  for (float x = -100; x <= 250; x += 1.0f)  // the floor, z = 600
    for (float y = -100; y <= 250; y += 1.0f)
      if (!shadowed(x / 600, y / 600)) scan.points.emplace_back(x, y, 600.0f);
  const PointGrid grid(scan.points);
  SceneEvidence evidence(scan.points, grid, Vec3::Zero());
  const Evidence all = evidence.evaluate(pose, box.points, box.normals, 1.0f, box.sample_radius);
  EXPECT_EQ(all.grazing, 0);  // no grazing angle set: 90 degrees
  EXPECT_FLOAT_EQ(all.scoreWithoutGrazing(), all.score());
  evidence.setGrazingAngle(80.0f);
  const Evidence e = evidence.evaluate(pose, box.points, box.normals, 1.0f, box.sample_radius);
  EXPECT_EQ(e.facing, all.facing);
  EXPECT_FLOAT_EQ(e.score(), all.score());
  // The side faces (800 + 2400 mm^2 against the near face's 1200), less what the near face
  // hides in the model's z-buffer (its cells of two sample spacings cover most of their sliver).
  EXPECT_GT(e.grazing, e.facing / 8);
  EXPECT_LT(e.grazing_supported, e.grazing / 4);  // only where they meet the near face
  EXPECT_LT(e.score(), 0.8f);
  EXPECT_GT(e.scoreWithoutGrazing(), 0.95f);
  // The side faces lie at 83-84 degrees: at 85 none of them is grazing.
  evidence.setGrazingAngle(85.0f);
  EXPECT_EQ(evidence.evaluate(pose, box.points, box.normals, 1.0f, box.sample_radius).grazing, 0);
}

// The scan spacing's sample from the depth image's pixel neighbours: the same range image, so
// the same verdicts, point for point, as with the grid alone.
TEST(SceneEvidence, PixelNeighboursGiveTheSameEvidenceAsTheGrid) {
  const auto [model, scene] = capsDropped(5);
  const PixelNeighbours pixels(scene.cloud);
  ASSERT_TRUE(pixels.usable());
  const PointGrid grid(scene.cloud.points);
  const SceneEvidence by_grid(scene.cloud.points, grid, scene.cloud.viewpoint);
  const SceneEvidence by_pixels(scene.cloud.points, grid, scene.cloud.viewpoint, &pixels);
  int contradicted = 0;
  for (const SimulatedInstance& instance : scene.instances)
    for (const float shift : {0.0f, 4.0f}) {  // the true pose, and one a few mm in front of it
      Pose pose = instance.pose;
      pose.translation() -= shift * pose.translation().normalized();
      std::vector<std::uint32_t> a, b;
      const Evidence e = by_grid.evaluate(pose, model.points, model.normals, 1.0f, model.sample_radius, &a);
      const Evidence f = by_pixels.evaluate(pose, model.points, model.normals, 1.0f, model.sample_radius, &b);
      EXPECT_EQ(e.facing, f.facing);
      EXPECT_EQ(e.supported, f.supported);
      EXPECT_EQ(e.contradicted, f.contradicted);
      EXPECT_EQ(a, b);
      contradicted += e.contradicted;
    }
  EXPECT_GT(contradicted, 0);  // the range image was asked
}

// ICP asks the depth image's pixels first for each model point's nearest scan point: the same
// pairs, so the same steps and the same pose, bit for bit, as with the grid alone.
TEST(Refine, PixelNeighboursGiveTheSamePoseAsTheGrid) {
  const auto [model, scene] = capsDropped(7);
  const PixelNeighbours pixels(scene.cloud);
  ASSERT_TRUE(pixels.usable());
  const PointGrid grid(scene.cloud.points);
  const PreparedModel prepared(model.points, model.normals);
  int moved = 0;
  for (const SimulatedInstance& instance : scene.instances)
    for (const float off : {0.0f, 1.5f, 4.0f}) {  // from the truth, and from poses a few mm and degrees off it
      const Pose start = perturbed(instance.pose, Vec3(off, -0.5f * off, 0.7f * off), 0.02f * off, Vec3(1, 2, 0));
      IcpParams icp;
      icp.viewpoint = scene.cloud.viewpoint;
      std::vector<Pose> by_grid, by_pixels;
      icp.path = &by_grid;
      const Pose a = refinePose(start, prepared, scene.cloud.points, grid, icp);
      icp.path = &by_pixels;
      icp.pixels = &pixels;
      const Pose b = refinePose(start, prepared, scene.cloud.points, grid, icp);
      EXPECT_EQ(by_grid.size(), by_pixels.size());
      EXPECT_TRUE(a.matrix() == b.matrix()) << "start " << off << " mm off";
      moved += !(a.matrix() == start.matrix());
    }
  EXPECT_GT(moved, 6);  // ICP ran its steps
}

// A model made ready once (PreparedModel) holds its centre and reach as ICP linearises about
// them, and refuses points without normals.
TEST(PreparedModel, CentreReachAndBadInput) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  const PreparedModel prepared(box.points, box.normals);
  Vec3 centre = Vec3::Zero();
  for (const Vec3& p : box.points) centre += p;
  centre /= float(box.points.size());
  EXPECT_LT((prepared.centre() - centre).norm(), 1e-3f);
  EXPECT_NEAR(prepared.reach(), std::sqrt(30.0 * 30 + 20 * 20 + 10 * 10), 0.5);  // a corner of the box
  EXPECT_EQ(prepared.points().size(), box.points.size());
  Points fewer = box.normals;
  fewer.pop_back();
  EXPECT_THROW(PreparedModel(box.points, fewer), Error);
}

}  // namespace
}  // namespace binpose
