"""Sign inventory: core merging / positioning on synthetic sightings, and a generated bag.

The core tests place signs in a straight-road world, move the ego along x, and make the
sightings a perfect camera would see (boxes from the standard face size, distances from the
box height) with chosen distance errors.  The end-to-end test writes a 3 s synthetic bag
with two work-zone signs and runs ``workzone-ros inventory`` on it (LiDAR and camera only).
"""
from __future__ import annotations

import csv
import json
import math

import cv2
import numpy as np
import pytest

from workzone_ros.core import signs as catalogue
from workzone_ros.core.inventory import (
    InventoryConfig,
    Sighting,
    build_inventory,
    camera_in_base,
    crop_quality,
    locate,
    match_candidate,
)
from workzone_ros.core.projection import CameraModel, euler_matrix
from workzone_ros.core.sign_distance import distance_from_size, face_box_height_m
from workzone_ros.interfaces import Box, Sign

K = np.array([[554.26, 0.0, 320.0], [0.0, 554.26, 240.0], [0.0, 0.0, 1.0]])
DIST = np.array([-0.08, 0.02, 0.0005, -0.0003, 0.0])
CAM = CameraModel(640, 480, K, DIST)
#: the projector defaults (config/workzone.yaml): LiDAR 1.95 m up, camera 1.45 m up, 0.6 ahead
L2C = np.array([[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, -0.5], [1.0, 0.0, 0.0, -0.6],
                [0.0, 0.0, 0.0, 1.0]])
BASE_CAMERA = camera_in_base(L2C, euler_matrix((1.0, 0.0, 1.95), (0.0, 0.0, 0.0)))
FPS = 15.0


def odom(x: float) -> np.ndarray:
    """odom <- base for an ego at (x, 0) heading +x."""
    t = np.eye(4)
    t[0, 3] = x
    return t


def to_camera(world, ego_x: float) -> np.ndarray:
    t = np.linalg.inv(odom(ego_x) @ BASE_CAMERA)
    return t[:3, :3] @ np.asarray(world, float) + t[:3, 3]


def sighting(world, ego_x: float, k: int, track, key='road_work_ahead', bag='a',
             scale: float = 1.0, mile=None, lidar: bool = False, score: float = 0.9):
    """What a camera at ``ego_x`` sees of a sign centred at ``world`` (frame ``k``)."""
    p = to_camera(world, ego_x)
    uv, _ = cv2.projectPoints(p.reshape(1, 1, 3), np.zeros(3), np.zeros(3), K, DIST)
    u, v = uv.reshape(2)
    c = catalogue.get(key)
    h = face_box_height_m(key) * K[1, 1] / p[2]
    w = (c.width_m * math.sqrt(2) if c.shape == 'diamond' else c.width_m) * K[0, 0] / p[2]
    box = Box(x=float(u - w / 2), y=float(v - h / 2), w=float(w), h=float(h))
    dist = distance_from_size(box, key, K[1, 1]) * scale
    sign = Sign(box=box, class_key=key, code=c.code, category=c.category, score=score,
                track_id=track, distance_m=dist, distance_source='size', mile=mile)
    return Sighting(int(1e9 + k * 1e9 / FPS), sign, bag,
                    lidar_point=tuple(p) if lidar else None, image_size=(640, 480))


def inventory(sightings, cfg=InventoryConfig(), ego=None):
    ego = ego or {}
    located = [locate(s, CAM, BASE_CAMERA, odom(ego[id(s)]), cfg) for s in sightings]
    return build_inventory(sightings, located, cfg)


def drive(world, xs, k0, track, **kw):
    """Sightings of one sign from ego positions ``xs``; returns (sightings, ego map)."""
    out = [sighting(world, x, k0 + j, track, **kw) for j, x in enumerate(xs)]
    return out, {id(s): x for s, x in zip(out, xs)}


# --- positioning ----------------------------------------------------------------------------

def test_camera_position_from_distance_and_ray():
    world = np.array([60.0, -9.75, 2.95])
    s = sighting(world, 12.0, 0, 1)
    got = locate(s, CAM, BASE_CAMERA, odom(12.0))
    assert got.source == 'camera'
    assert np.linalg.norm(got.xyz - world) < 0.05          # distortion undone, ray x depth
    assert got.sigma_m == pytest.approx(0.5 + 0.1 * np.linalg.norm(to_camera(world, 12.0)))
    far = locate(sighting(world, 12.0, 0, 1, scale=1.1), CAM, BASE_CAMERA, odom(12.0))
    assert np.linalg.norm(far.xyz - world) == pytest.approx(0.1 * 48.0, rel=0.05)
    assert locate(s, CAM, BASE_CAMERA, None) is None        # no odometry: no position


def test_lidar_point_is_used_when_there_is_one():
    world = np.array([60.0, -9.75, 2.95])
    s = sighting(world, 30.0, 0, 1, scale=1.3, lidar=True)
    got = locate(s, CAM, BASE_CAMERA, odom(30.0))
    assert got.source == 'lidar' and got.sigma_m == InventoryConfig().lidar_sigma_m
    assert np.allclose(got.xyz, world, atol=1e-9)
    assert got.height_m == pytest.approx(2.95)


def test_match_candidate_in_box_and_range():
    box = Box(x=100.0, y=100.0, w=40.0, h=40.0)
    uv = np.array([[300.0, 300.0], [125.0, 118.0], [121.0, 121.0], [np.nan, np.nan]])
    xyz = np.array([[0, 0, 30.0], [0, 0, 80.0], [0, 0, 31.0], [0, 0, 30.0]])
    assert match_candidate(box, uv, xyz, 30.0) == 2          # the one at the sign's range
    assert match_candidate(box, uv, xyz, 80.0) == 1
    assert match_candidate(box, uv, xyz, None) == 2          # nearest to the box centre
    assert match_candidate(box, uv[:1], xyz[:1], 30.0) is None
    assert match_candidate(box, np.zeros((0, 2)), np.zeros((0, 3))) is None


def test_crop_quality_prefers_large_uncut_boxes():
    size = (640, 480)
    small = crop_quality(Box(x=300, y=200, w=20, h=20), 0.9, size)
    big = crop_quality(Box(x=300, y=200, w=60, h=60), 0.9, size)
    cut = crop_quality(Box(x=600, y=200, w=40, h=60), 0.9, size)
    assert big > small > cut


# --- merging --------------------------------------------------------------------------------

def test_two_tracks_of_one_sign_merge():
    world = np.array([60.0, -9.75, 2.95])
    a, ea = drive(world, np.arange(0.0, 12.0, 1.5), 0, 1, scale=1.06)
    b, eb = drive(world, np.arange(20.0, 40.0, 1.5), 20, 2, scale=0.96)   # lost, found again
    rows = inventory(a + b, ego={**ea, **eb})
    assert len(rows) == 1
    r = rows[0]
    assert r.frames == len(a) + len(b) and r.source == 'camera'
    assert r.class_key == 'road_work_ahead' and r.category == 'workzone'
    assert np.linalg.norm(r.xyz - world) < 1.5
    assert r.first_ns == a[0].stamp_ns and r.last_ns == b[-1].stamp_ns
    assert r.best == len(a) + len(b) - 1            # the closest (largest) uncut box


def test_two_signs_20m_apart_stay_apart():
    s1, s2 = np.array([60.0, -9.75, 2.95]), np.array([80.0, -9.75, 2.95])
    out, ego = [], {}
    for world, track, scale, k0 in ((s1, 1, 1.08, 0), (s2, 2, 0.93, 40)):
        xs = np.arange(world[0] - 60.0, world[0] - 15.0, 2.0)
        got, e = drive(world, xs, k0, track, scale=scale, key='lane_shift_left')
        out += got
        ego.update(e)
    rows = inventory(out, ego=ego)
    assert len(rows) == 2
    pos = sorted(rows, key=lambda r: r.xyz[0])
    assert np.linalg.norm(pos[0].xyz - s1) < 3.0 and np.linalg.norm(pos[1].xyz - s2) < 3.0


def test_same_sign_in_two_bags_is_one_row():
    world = np.array([60.0, -9.75, 2.95])
    a, ea = drive(world, np.arange(10.0, 40.0, 2.0), 0, 7, bag='monday', lidar=True)
    b, eb = drive(world, np.arange(5.0, 45.0, 1.5), 0, 7, bag='tuesday', scale=1.1)
    rows = inventory(a + b, ego={**ea, **eb})
    assert len(rows) == 1
    r = rows[0]
    assert r.bags == ['monday', 'tuesday'] and r.source == 'lidar'
    assert np.linalg.norm(r.xyz - world) < 1e-6
    assert r.first_ns == a[0].stamp_ns and r.last_ns == a[-1].stamp_ns   # the first bag's


def test_two_signs_in_one_frame_never_merge():
    """Two signs of one class side by side (2.5 m apart: well within the camera's gate),
    tracked together: two rows."""
    s1, s2 = np.array([60.0, -9.2, 2.95]), np.array([60.0, -11.7, 2.95])
    xs = np.arange(20.0, 44.0, 2.0)
    a, ea = drive(s1, xs, 0, 1, key='right_lane_ends')
    b, eb = drive(s2, xs, 0, 2, key='right_lane_ends', scale=1.05)
    assert len(inventory(a + b, ego={**ea, **eb})) == 2


def test_untracked_general_sightings_merge_with_mile_number():
    world = np.array([120.0, -8.8, 2.4])
    xs = np.arange(80.0, 112.0, 2.0)
    miles = [123] * (len(xs) - 3) + [128, None, None]
    out, ego = [], {}
    for k, (x, m) in enumerate(zip(xs, miles)):
        s = sighting(world, x, k, None, key='mile_marker', scale=1.0 + 0.05 * (-1) ** k, mile=m)
        out.append(s)
        ego[id(s)] = x
    rows = inventory(out, ego=ego)
    assert len(rows) == 1
    assert rows[0].category == 'general' and rows[0].mile == 123
    assert np.linalg.norm(rows[0].xyz - world) < 1.5


def test_single_frames_and_signs_under_the_road_are_dropped():
    world = np.array([60.0, -9.75, 2.95])
    once = sighting(world, 20.0, 0, 5)
    under, eu = drive(np.array([40.0, -2.0, -3.0]), np.arange(0.0, 10.0, 2.0), 10, 6)
    rows = inventory([once] + under, ego={id(once): 20.0, **eu})
    assert rows == []
    assert len(inventory([once], InventoryConfig(min_frames=1), {id(once): 20.0})) == 1


# --- end to end on a generated bag ----------------------------------------------------------

SCENARIO = """
name: inventory_two
description: two work-zone signs right ahead, for the inventory test
duration: 3.0
weather: spring_sunny
ego: {speed: 15.0, lane: right}
signs:
  - {class: road_work_ahead, s: 40, tilt_deg: 0, fade: 0}
  - {class: lane_shift_left, s: 62, tilt_deg: 0, fade: 0}
distractors: {vehicles: 0, orange_vehicles: 0, yellow_vehicles: 0, cones: 0, drums: 0,
              general_signs: 0, mile_markers: false}
lidar: {model: vlp16}
"""


@pytest.fixture(scope='module')
def spec(tmp_path_factory):
    path = tmp_path_factory.mktemp('inventory') / 'two.yaml'
    path.write_text(SCENARIO)
    return path


@pytest.fixture(scope='module')
def bag(spec):
    from workzone_ros.sim.scenario import load_scenario
    from workzone_ros.sim.writer import SynthOptions, write_bag
    out = spec.parent / 'two_bag'
    write_bag(load_scenario(str(spec)), out, SynthOptions(seed=1, workers=0), progress=None)
    return out


def _signs_in_scene(spec) -> dict:
    """The scenario's signs in the world (= odom) frame, from the simulator."""
    from workzone_ros.sim.scenario import build_scene, load_scenario
    scene = build_scene(load_scenario(str(spec), 1), 1)[0]
    return {s.class_key: np.asarray(s.center, float) for s in scene.signs}


def test_inventory_of_a_generated_bag(bag, spec, tmp_path, capsys):
    from workzone_ros.tools.inventory import COLUMNS, main
    truth = _signs_in_scene(spec)
    out = tmp_path / 'signs.csv'
    rc = main([str(bag), '-o', str(out), '--geojson', str(tmp_path / 'signs.geojson'),
               '--crops', str(tmp_path / 'crops'), '--score', '--no-general',
               '--json', str(tmp_path / 'score.json')])
    assert rc == 0
    rows = list(csv.DictReader(out.open()))
    assert tuple(rows[0].keys()) == COLUMNS
    work = [r for r in rows if r['category'] == 'workzone']
    assert sorted(r['class_key'] for r in work) == ['lane_shift_left', 'road_work_ahead']
    for r in work:
        xyz = np.array([float(r['x_m']), float(r['y_m']), float(r['z_m'])])
        assert r['position_source'] == 'lidar'
        assert np.linalg.norm(xyz - truth[r['class_key']]) < 0.5
        assert (tmp_path / 'crops').exists() and r['best_crop'].endswith('.png')
        assert cv2.imread(r['best_crop']) is not None
        assert 0.0 <= float(r['first_seen_s']) <= float(r['last_seen_s']) <= 3.0
    s = json.loads((tmp_path / 'score.json').read_text())['score']['workzone']
    assert s['gt_signs'] == s['sighted'] == s['found_once'] == 2
    assert s['duplicated'] == 0 and s['false_rows'] == 0
    assert s['error_lidar_m']['median'] < 0.5
    geo = json.loads((tmp_path / 'signs.geojson').read_text())
    assert len(geo['features']) == len(rows)

    # camera only: the same two rows, placed by the monocular distance
    out2 = tmp_path / 'camera.csv'
    assert main([str(bag), '-o', str(out2), '--no-lidar', '--no-general']) == 0
    work = [r for r in csv.DictReader(out2.open()) if r['category'] == 'workzone']
    assert sorted(r['class_key'] for r in work) == ['lane_shift_left', 'road_work_ahead']
    for r in work:
        xyz = np.array([float(r['x_m']), float(r['y_m']), float(r['z_m'])])
        assert r['position_source'] == 'camera'
        assert np.linalg.norm(xyz - truth[r['class_key']]) < 3.0
    assert 'signs from 1 bag(s)' in capsys.readouterr().out


def test_bad_bags_are_one_line_errors(bag, tmp_path, capsys):
    from workzone_ros.bagio import BagWriter, open_reader
    from workzone_ros.tools.inventory import main
    no_camera = tmp_path / 'no_camera'
    with open_reader(bag) as r, BagWriter(no_camera) as w:
        w.add_topic('/odom', r.topics['/odom'].msgtype)
        for m in r.messages(['/odom']):
            w.write('/odom', m.timestamp_ns, m.rawdata)
    corrupt = tmp_path / 'corrupt'
    corrupt.mkdir()
    (corrupt / 'corrupt_0.mcap').write_bytes(b'\x89MCAP0\r\n' + b'garbage' * 50)
    rc = main([str(tmp_path / 'missing'), str(no_camera), str(corrupt), '-o',
               str(tmp_path / 'x.csv'), '--no-general'])
    assert rc == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith(
        str(tmp_path))]
    assert len(err) == 3
    assert 'no such bag' in err[0] and 'no camera images' in err[1]
    assert 'corrupt' in err[2] or 'cannot read' in err[2]
