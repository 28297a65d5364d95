"""The Python module against ground truth: training from arrays, a simulated bin of caps (the
CLI's simulator, exact poses), the CLI's own answers on the same image, and bad input."""
import json
import os
import subprocess
import warnings

import numpy as np
import pytest
from PIL import Image

import binpose

CLI = os.environ.get("BINPOSE_CLI", "binpose")


def box(lx, ly, lz):
    """A closed box centred on the origin: 8 vertices, 12 outward triangles."""
    v = np.array([[x, y, z] for x in (-lx / 2, lx / 2) for y in (-ly / 2, ly / 2) for z in (-lz / 2, lz / 2)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], dtype=np.int64)
    return v, f


@pytest.fixture(scope="module")
def caps(tmp_path_factory):
    """A simulated bin of 6 caps (ideal sensor), a cap database trained here and saved."""
    folder = tmp_path_factory.mktemp("bin")
    subprocess.run([CLI, "simulate", "--instances", "6", "--seed", "5", "--out", str(folder)], check=True,
                   stdout=subprocess.DEVNULL)
    db = binpose.train("builtin:cap", points=2000)
    db.save(str(folder / "cap.bpdb"))
    camera = json.loads((folder / "camera.json").read_text())
    truth = json.loads((folder / "ground_truth.json").read_text())["instances"]
    depth = np.array(Image.open(folder / "depth.png")).astype(np.uint16)  # PIL reads 16-bit grey as int32
    return folder, db, camera, truth, depth


def ply_points(path):
    """The x, y, z of a binary little-endian PLY whose vertices hold three floats first."""
    data = path.read_bytes()
    head, body = data.split(b"end_header\n", 1)
    lines = head.decode().splitlines()
    count = int(next(l for l in lines if l.startswith("element vertex")).split()[2])
    props = [l for l in lines if l.startswith("property")]
    assert "binary_little_endian" in head.decode() and props[0].split()[1] == "float"
    stride = 4 * len(props)  # every property a float or a 4-byte value
    return np.frombuffer(body[:count * stride], np.float32).reshape(count, len(props))[:, :3].astype(np.float64)


def nearest_truth(pose, truth):
    """The ground-truth instance nearest the pose's position, and the distance to it (mm)."""
    distances = [np.linalg.norm(np.array(t["pose"])[:3, 3] - pose[:3, 3]) for t in truth]
    return truth[int(np.argmin(distances))], min(distances)


def test_train_from_arrays_and_save_load(tmp_path):
    vertices, faces = box(40.0, 30.0, 20.0)
    db = binpose.train((vertices, faces), points=500)
    assert db.points == 500
    assert db.diameter == pytest.approx(np.sqrt(40 ** 2 + 30 ** 2 + 20 ** 2), rel=0.05)
    in_metres = binpose.train((vertices / 1000.0, faces.astype(np.int32)), points=500, units="m")
    assert in_metres.diameter == pytest.approx(db.diameter, rel=1e-4)
    db.save(str(tmp_path / "box.bpdb"))
    loaded = binpose.load_database(str(tmp_path / "box.bpdb"))
    assert (loaded.points, loaded.diameter) == (db.points, db.diameter)


def test_detect_depth_finds_the_simulated_caps(caps):
    _, db, camera, truth, depth = caps
    assert depth.dtype == np.uint16
    result = binpose.Detector(db).detect_depth(depth, camera["fx"], camera["fy"], camera["cx"], camera["cy"],
                                               camera["depth_scale"])
    assert result.timing_ms["total"] > 0
    found = set()
    for d in result:
        assert d.pose.shape == (4, 4)
        assert np.allclose(d.pose[:3, :3] @ d.pose[:3, :3].T, np.eye(3), atol=1e-4)
        t, distance = nearest_truth(d.pose, truth)
        assert distance < 3.0, f"a detection {distance:.1f} mm from every cap"
        # the cap is a body of revolution about its z axis: the axes must agree
        axis_error = np.degrees(np.arccos(np.clip(d.pose[:3, 2] @ np.array(t["pose"])[:3, 2], -1, 1)))
        assert axis_error < 5.0
        found.add(id(t))
    # every detection is right and distinct; how many of the bin's caps are found is the
    # benchmark's matter (bench/), not the binding's
    assert len(found) == len(result) >= 3


def test_same_answers_as_the_cli(caps):
    """detect_depth on the image and detect_file on its PNG and camera file give the CLI's poses."""
    folder, db, camera, _, depth = caps
    out = folder / "cli.json"
    subprocess.run([CLI, "detect", "--model", str(folder / "cap.bpdb"), "--scene", str(folder / "depth.png"),
                    "--intrinsics", str(folder / "camera.json"), "--out", str(out)], check=True,
                   stdout=subprocess.DEVNULL)
    cli = json.loads(out.read_text())["detections"]
    ours = binpose.Detector(db).detect_depth(depth, camera["fx"], camera["fy"], camera["cx"], camera["cy"],
                                             camera["depth_scale"])
    from_file = binpose.Detector(db).detect_file(str(folder / "depth.png"), intrinsics=str(folder / "camera.json"))
    assert len(ours) == len(from_file) == len(cli) > 0
    for d, f, c in zip(ours, from_file, cli):
        assert np.allclose(d.pose, np.array(c["pose"]), atol=1e-3)
        assert np.allclose(f.pose, np.array(c["pose"]), atol=1e-3)
        assert d.score == pytest.approx(c["score"], abs=1e-6)


def test_detect_file_reads_scans_as_the_cli_does(caps):
    """A depth PNG needs its camera file; the bin as an XYZ file in metres is read in metres, with
    a warning, and gives the same caps as its PLY."""
    folder, db, _, truth, _ = caps
    with pytest.raises(ValueError, match="needs its camera's intrinsics"):
        binpose.Detector(db).detect_file(str(folder / "depth.png"))
    ply = binpose.Detector(db).detect_file(str(folder / "scene.ply"))
    points = ply_points(folder / "scene.ply")
    np.savetxt(folder / "scene_m.xyz", points / 1000.0, fmt="%.7f")
    with pytest.warns(UserWarning, match="read in metres"):
        metres = binpose.Detector(db).detect_file(str(folder / "scene_m.xyz"))
    assert len(metres) == len(ply) >= 3
    for d in metres:
        assert nearest_truth(d.pose, truth)[1] < 3.0


def test_float_depth_and_point_map_find_the_depth_pngs_caps(caps):
    """The bin's depth as depth SDKs give it: floats in mm with NaN holes, and an H x W x 3 point
    map (its pinhole fitted to its rays): the same points, the same answer from both, and the
    same caps as from the 16-bit image (the float points differ from its by 1e-5 mm, which moves
    the noise estimate by 2 % and the scores a little)."""
    _, db, camera, truth, depth = caps
    k = (camera["fx"], camera["fy"], camera["cx"], camera["cy"])
    png = binpose.Detector(db).detect_depth(depth, *k, camera["depth_scale"])
    z = np.where(depth > 0, depth * camera["depth_scale"], np.nan).astype(np.float32)
    rows, cols = np.mgrid[0:depth.shape[0], 0:depth.shape[1]]
    xyz = np.dstack([(cols - k[2]) * z / k[0], (rows - k[3]) * z / k[1], z]).astype(np.float32)
    floats, point_map = binpose.Detector(db).detect_depth(z, *k), binpose.Detector(db).detect(xyz)
    assert floats.scene_points == point_map.scene_points == png.scene_points
    assert point_map.noise_mm == pytest.approx(floats.noise_mm, rel=1e-6)
    assert [d.score for d in point_map] == pytest.approx([d.score for d in floats], abs=1e-4)
    assert len(floats) == len(png) >= 3
    for d in floats:
        assert min(np.linalg.norm(d.pose[:3, 3] - p.pose[:3, 3]) for p in png) < 1.0
        assert nearest_truth(d.pose, truth)[1] < 3.0


def test_flying_pixels_at_a_step_are_dropped(caps):
    """A step from 700 to 760 mm whose column at the step reads a mix of the two on every other
    row: those 24 pixels lie on neither surface and are dropped; the surfaces' pixels stay."""
    _, db, _, _, _ = caps
    depth = np.full((48, 64), 7600, np.uint16)
    depth[:, :32] = 7000
    depth[0::2, 32] = 7300
    result = binpose.Detector(db).detect_depth(depth, 550.0, 550.0, 31.5, 23.5, 0.1)
    assert result.scene_points == 48 * 64
    assert result.flying_points == 24


def test_detect_depth_thins_pixels_that_share_their_noise(caps):
    """A depth image whose pixels repeat over 2 x 2 blocks (one registered to a camera with twice
    its pixels) has neighbours that share their noise: one pixel of each block is used."""
    _, db, _, _, _ = caps
    rng = np.random.default_rng(3)
    rows, cols = np.mgrid[0:240, 0:320]
    native = (7600 + 2 * cols + rows + rng.normal(0, 13, (240, 320))).astype(np.uint16)  # 0.1 mm units
    dense = np.repeat(np.repeat(native, 2, axis=0), 2, axis=1)
    assert binpose.Detector(db).detect_depth(dense, 1100.0, 1100.0, 319.5, 239.5, 0.1).pixel_stride == 2
    assert binpose.Detector(db).detect_depth(native, 550.0, 550.0, 159.5, 119.5, 0.1).pixel_stride == 1


def test_detect_points_drops_rows_without_a_measurement(caps):
    _, db, camera, truth, depth = caps
    rows, cols = np.nonzero(depth)
    z = depth[rows, cols] * camera["depth_scale"]
    points = np.stack([(cols - camera["cx"]) * z / camera["fx"], (rows - camera["cy"]) * z / camera["fy"], z], axis=1)
    detector = binpose.Detector(db, max_instances=3)
    result = detector.detect(points.astype(np.float32))
    assert 0 < len(result) <= 3
    for d in result:
        assert nearest_truth(d.pose, truth)[1] < 3.0
    with_nan = np.vstack([points, [[np.nan, 0, 0], [0, np.inf, 1]]])
    again = detector.detect(with_nan, viewpoint=(0, 0, 0))
    assert [d.pose.tolist() for d in again] == [d.pose.tolist() for d in detector.detect(points)]
    # A depth SDK's point cloud (RealSense's, say): a row for every pixel, (0, 0, 0) where the
    # pixel has no depth. Those rows hold no measurement and are dropped.
    all_rows, all_cols = np.mgrid[0 : depth.shape[0], 0 : depth.shape[1]]
    z_all = depth * camera["depth_scale"]
    every_pixel = np.stack([(all_cols - camera["cx"]) * z_all / camera["fx"],
                            (all_rows - camera["cy"]) * z_all / camera["fy"], z_all], axis=-1).reshape(-1, 3)
    assert (every_pixel == 0).all(axis=1).sum() > 1000
    sdk = detector.detect(every_pixel.astype(np.float32))
    assert [d.pose.tolist() for d in sdk] == [d.pose.tolist() for d in detector.detect(points.astype(np.float32))]
    assert len(detector.detect(np.zeros((0, 3)))) == 0


def test_points_in_metres_warn(caps):
    """binpose works in millimetres: the caps' scan given in metres spans less than half a cap,
    so detect() warns, and finds nothing; in millimetres it warns not."""
    _, db, camera, _, depth = caps
    rows, cols = np.nonzero(depth)
    z = depth[rows, cols] * camera["depth_scale"]
    points = np.stack([(cols - camera["cx"]) * z / camera["fx"], (rows - camera["cy"]) * z / camera["fy"], z], axis=1)
    detector = binpose.Detector(db, max_instances=1)
    with pytest.warns(UserWarning, match="metres"):
        assert len(detector.detect(points / 1000.0)) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(detector.detect(points)) == 1


def test_guess_viewpoint_of_a_scan_in_a_world_frame(caps):
    """The caps' scan in the camera frame keeps its origin; turned into the bin's world frame
    (z up, the camera 500 mm above the floor) it gets a viewpoint above the bin, and detection
    from it finds caps where they are."""
    folder, db, camera, truth, depth = caps
    rows, cols = np.nonzero(depth)
    z = depth[rows, cols] * camera["depth_scale"]
    points = np.stack([(cols - camera["cx"]) * z / camera["fx"], (rows - camera["cy"]) * z / camera["fy"], z], axis=1)
    kept = binpose.guess_viewpoint(points)
    assert not kept["moved"] and kept["viewpoint"] == (0.0, 0.0, 0.0) and kept["origin_hidden"] < 0.05
    camera_from_world = np.array(json.loads((folder / "ground_truth.json").read_text())["camera_from_world"])
    world_from_camera = np.linalg.inv(camera_from_world)
    world = points @ world_from_camera[:3, :3].T + world_from_camera[:3, 3]
    guess = binpose.guess_viewpoint(world)
    assert guess["moved"] and guess["hidden"] < 0.05 < guess["origin_hidden"]
    sensor = world_from_camera[:3, 3]
    centre = world.mean(axis=0)
    direction = (np.array(guess["viewpoint"]) - centre) / np.linalg.norm(np.array(guess["viewpoint"]) - centre)
    assert direction @ ((sensor - centre) / np.linalg.norm(sensor - centre)) > np.cos(np.radians(15))
    result = binpose.Detector(db).detect(world, viewpoint=guess["viewpoint"])
    assert len(result) >= 3
    for d in result:
        in_camera = camera_from_world @ d.pose
        assert nearest_truth(in_camera, truth)[1] < 3.0
    # without a viewpoint, detect() guesses as the CLI does; from the origin, which sees a
    # quarter of the scan from behind, it finds fewer to within a millimetre
    guessed = binpose.Detector(db).detect(world)
    assert [d.pose.tolist() for d in guessed] == [d.pose.tolist() for d in result]
    assert sum(nearest_truth(camera_from_world @ d.pose, truth)[1] < 1.0 for d in result) == len(result)
    from_origin = binpose.Detector(db).detect(world, viewpoint=(0, 0, 0))
    right = sum(nearest_truth(camera_from_world @ d.pose, truth)[1] < 1.0 for d in from_origin)
    assert right < len(result)


def test_check_judges_the_true_poses(caps):
    """The caps' true poses stand where the scan shows them well, and a pose lifted 60 mm towards
    the sensor, into the free space over the bin, is refused by its score."""
    _, db, camera, truth, depth = caps
    poses = np.array([t["pose"] for t in truth])
    lifted = poses.copy()
    for p in lifted:
        p[:3, 3] -= 60.0 * p[:3, 3] / np.linalg.norm(p[:3, 3])  # the sensor is at the origin
    detector = binpose.Detector(db)
    intrinsics = (camera["fx"], camera["fy"], camera["cx"], camera["cy"])
    at_truth = detector.check_depth(depth, *intrinsics, poses, depth_scale=camera["depth_scale"])
    above = detector.check_depth(depth, *intrinsics, lifted, depth_scale=camera["depth_scale"])
    assert len(at_truth) == len(above) == len(truth)
    well_seen = [c for c, t in zip(at_truth, truth) if t["visib_fract"] > 0.9]
    assert len(well_seen) >= 3
    for c in well_seen:
        assert "none" in (c["as_found"], c["as_laid"]), c
        assert c["score"] > 0.5 and c["moved_mm"] < 2.0, c
        assert c["refined"].shape == (4, 4)
    for c in above:
        assert c["as_found"] == "score" and c["score"] < 0.15, c
    with pytest.raises(ValueError, match="N x 4 x 4"):
        detector.check_depth(depth, *intrinsics, np.eye(4))
    bent = poses[:1].copy()
    bent[0, 0, 0] = 2.0
    with pytest.raises(ValueError, match="not a rotation"):
        detector.check_depth(depth, *intrinsics, bent)


def test_bad_input_raises_value_error(tmp_path):
    vertices, faces = box(40.0, 30.0, 20.0)
    db = binpose.train((vertices, faces), points=300)
    with pytest.raises(ValueError, match="unknown parameter 'foo'"):
        binpose.Detector(db, foo=1)
    with pytest.raises(ValueError, match="r"):
        binpose.Detector(db, r=-1.0)
    with pytest.raises(ValueError, match="preset"):
        binpose.Detector(db, preset="fastest")
    detector = binpose.Detector(db)
    with pytest.raises(ValueError, match="N x 3"):
        detector.detect(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="N x 3"):
        detector.detect("not an array")
    with pytest.raises(ValueError, match="numbers"):
        detector.detect(np.array([["a", "b", "c"]]))
    with pytest.raises(ValueError, match="normals"):
        detector.detect(np.zeros((5, 3)), normals=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="H x W numpy array of numbers"):
        detector.detect_depth(np.zeros((4, 4, 2), np.float32), 500, 500, 2, 2)
    with pytest.raises(ValueError, match="H x W numpy array of numbers"):
        detector.detect_depth(np.zeros((4, 4), np.complex64), 500, 500, 2, 2)
    with pytest.raises(ValueError, match="point map"):
        detector.detect(np.zeros((4, 4, 3)), normals=np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="viewpoint"):
        detector.detect(np.zeros((5, 3)), viewpoint=(0, 1))
    with pytest.raises(ValueError, match="whole indices"):
        binpose.train((vertices, faces + 100))
    with pytest.raises(ValueError, match="no such file"):
        binpose.load_database(str(tmp_path / "missing.bpdb"))
    corrupt = tmp_path / "corrupt.bpdb"
    db.save(str(corrupt))
    corrupt.write_bytes(corrupt.read_bytes()[:-9])
    with pytest.raises(ValueError, match="corrupt|truncated"):
        binpose.load_database(str(corrupt))
    with pytest.raises(ValueError, match="missing.ply"):
        binpose.train(str(tmp_path / "missing.ply"))
