"""The synthetic bag: determinism, read-back, and ground truth that agrees with the sensors."""
from __future__ import annotations

import collections
import filecmp

import cv2
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from workzone_ros.core.pointcloud import FieldSpec, cloud_view
from workzone_ros.interfaces import GtLidar, GtSigns, GtWorkzone, decode
from workzone_ros.sim import cli
from workzone_ros.sim.scenario import build_scene, load_scenario
from workzone_ros.sim.world import LIDAR_TO_CAMERA, rot_zyx
from workzone_ros.sim.writer import (
    EPOCH_NS,
    SynthError,
    SynthOptions,
    frame_times,
    scan_times,
    write_bag,
)

SCENARIO = """
name: tiny
description: signs right ahead, for tests
duration: 1.6
weather: spring_sunny
ego: {speed: 22.4, lane: middle}
workzone: {taper_s: 480, length: 300, speed_limit: 45}
signs:
  - {class: stop, s: 50, side: side_road}
  - {class: speed_limit, s: 75, speed_value: 65, tilt_deg: 0, fade: 0}
distractors: {vehicles: 0, orange_vehicles: 0, yellow_vehicles: 0, cones: 1, drums: 1,
              general_signs: 0, mile_markers: false}
"""


@pytest.fixture(scope='module')
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp('sim')
    path = root / 'tiny.yaml'
    path.write_text(SCENARIO)
    return path


@pytest.fixture(scope='module')
def bag(tiny, tmp_path_factory):
    out = tmp_path_factory.mktemp('bag_a') / 'tiny_bag'
    write_bag(load_scenario(str(tiny)), out, SynthOptions(seed=3, workers=0), progress=None)
    return out


def _messages(path):
    """topic -> [(log time ns, deserialized message)], read with rosbags alone."""
    out = collections.defaultdict(list)
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([path], default_typestore=store) as reader:
        for conn, t, raw in reader.messages():
            out[conn.topic].append((t, reader.deserialize(raw, conn.msgtype)))
    return out


def test_timing_helpers():
    assert len(frame_times(60.0)) == 900
    assert len(scan_times(60.0, 50.0)) == 600
    assert scan_times(1.0, 50.0)[0] == pytest.approx(0.05)


def test_deterministic_and_worker_independent(tiny, bag, tmp_path):
    again = tmp_path / 'x' / 'tiny_bag'
    write_bag(load_scenario(str(tiny)), again, SynthOptions(seed=3, workers=2), progress=None)
    names = sorted(p.name for p in bag.iterdir())
    assert names == sorted(p.name for p in again.iterdir()) == ['metadata.yaml',
                                                                  'tiny_bag.mcap']
    for name in names:
        assert filecmp.cmp(bag / name, again / name, shallow=False), name
    other = tmp_path / 'y' / 'tiny_bag'
    write_bag(load_scenario(str(tiny)), other, SynthOptions(seed=4, duration=0.4, workers=0),
              progress=None)
    assert not filecmp.cmp(bag / 'tiny_bag.mcap', other / 'tiny_bag.mcap', shallow=False)


def test_bag_reads_back(bag):
    msgs = _messages(bag)
    n_frames = len(frame_times(1.6))
    assert len(msgs['/camera/image_raw']) == n_frames == 24
    assert len(msgs['/camera/camera_info']) == n_frames
    assert len(msgs['/groundtruth/signs']) == n_frames
    assert len(msgs['/lidar/points']) == len(msgs['/groundtruth/lidar']) == 16
    assert len(msgs['/odom']) == 80
    assert len(msgs['/groundtruth/workzone']) == 2
    assert len(msgs['/tf_static']) == 1
    stamps = [t for t, _ in msgs['/camera/image_raw']]
    assert stamps[0] == EPOCH_NS and np.allclose(np.diff(stamps), 1e9 / 15, atol=1)
    scans = [t for t, _ in msgs['/lidar/points']]
    assert np.allclose(np.diff(scans), 1e8, atol=1) and scans[0] == EPOCH_NS + 50_000_000
    odom = [t for t, _ in msgs['/odom']]
    assert np.allclose(np.diff(odom), 2e7, atol=1)
    for t, m in msgs['/camera/image_raw']:
        ns = m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec
        assert ns == t and m.encoding == 'bgr8' and (m.height, m.width) == (480, 640)
    _, info = msgs['/camera/camera_info'][0]
    assert info.distortion_model == 'plumb_bob' and len(info.d) == 5
    _, cloud = msgs['/lidar/points'][0]
    assert [f.name for f in cloud.fields] == ['x', 'y', 'z', 'intensity', 'ring']
    assert cloud.header.frame_id == 'lidar' and cloud.width > 50_000
    _, od = msgs['/odom'][10]
    assert od.header.frame_id == 'odom' and od.child_frame_id == 'base_link'
    assert od.twist.twist.linear.x == pytest.approx(22.4, rel=0.01)
    # ground truth decodes and is stamped like its sensor message
    for (t, m), (ti, _) in zip(msgs['/groundtruth/signs'], msgs['/camera/image_raw']):
        gt = decode(m.data, GtSigns)
        assert gt.header.stamp.to_ns() == t == ti and gt.weather == 'spring_sunny'
    wz = [decode(m.data, GtWorkzone) for _, m in msgs['/groundtruth/workzone']]
    assert wz[0].scenario == 'tiny' and wz[0].seed == 3
    assert np.allclose(np.array(wz[0].extrinsics.matrix), LIDAR_TO_CAMERA)
    r, p, y = wz[0].extrinsics.rpy
    assert np.allclose(rot_zyx(y, p, r), LIDAR_TO_CAMERA[:3, :3])
    # only W20-1 (30 m ahead) is passed within 1.6 s; the zone itself is further on
    assert [(e.kind, e.x_m) for e in wz[0].events] == [('zone_approaching', 30.0)]
    assert wz[0].begin_t is None and wz[1].header.stamp.to_ns() == EPOCH_NS + 1_600_000_000
    meta = (bag / 'metadata.yaml').read_text()
    assert 'transient_local' in meta


def test_sign_corners_project_onto_gt_boxes(tiny, bag):
    msgs = _messages(bag)
    spec = load_scenario(str(tiny))
    scene, ego, _ = build_scene(spec, 3)
    signs = {s.object_id: s for s in scene.signs}
    _, info = msgs['/camera/camera_info'][0]
    K, D = np.array(info.k).reshape(3, 3), np.array(info.d)
    T = np.array(decode(msgs['/groundtruth/workzone'][0][1].data, GtWorkzone).extrinsics.matrix)
    checked = 0
    for t_ns, m in msgs['/groundtruth/signs']:
        t = (t_ns - EPOCH_NS) / 1e9
        lidar = ego.lidar_pose(t)
        for g in decode(m.data, GtSigns).signs:
            b = g.box
            if g.visible_fraction < 0.9 or min(b.w, b.h) < 8 or b.x < 2 or b.x2 > 638:
                continue
            corners = lidar.to_body(signs[g.sign_id].corners())
            cam = corners @ T[:3, :3].T + T[:3, 3]
            uv, _ = cv2.projectPoints(cam.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, D)
            uv = uv.reshape(-1, 2)
            proj = (uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max())
            ix = max(0.0, min(b.x2, proj[2]) - max(b.x, proj[0]))
            iy = max(0.0, min(b.y2, proj[3]) - max(b.y, proj[1]))
            union = b.area + (proj[2] - proj[0]) * (proj[3] - proj[1]) - ix * iy
            assert ix * iy / union > 0.7, (g, proj)
            checked += 1
    assert checked >= 10


def test_lidar_gt_points_on_sign_faces(tiny, bag):
    msgs = _messages(bag)
    scene, _, _ = build_scene(load_scenario(str(tiny)), 3)
    signs = {s.object_id: s for s in scene.signs}
    hits = 0
    for (t, cloud), (tg, m) in zip(msgs['/lidar/points'], msgs['/groundtruth/lidar']):
        assert t == tg
        fields = [FieldSpec(f.name, f.offset, f.datatype, f.count) for f in cloud.fields]
        pts = cloud_view(cloud.data, fields, cloud.point_step, cloud.width, cloud.height,
                         cloud.row_step)
        xyz = np.stack([pts['x'], pts['y'], pts['z']], 1).astype(float)
        for g in decode(m.data, GtLidar).signs:
            idx = np.array(g.indices)
            if idx.size < 5:
                continue
            sp = signs[g.sign_id]
            p = xyz[idx]
            assert np.median(pts['intensity'][idx]) > 150
            half_diag = np.hypot(sp.width, sp.height) / 2
            assert np.linalg.norm(p - np.array(g.center), axis=1).max() < half_diag + 0.3
            # on a plane (within range noise and the spin's motion)
            q = p - p.mean(0)
            assert np.linalg.svd(q, compute_uv=False)[-1] / np.sqrt(len(q)) < 0.1
            hits += 1
    assert hits >= 10


def test_cli(tiny, tmp_path, capsys):
    out = tmp_path / 'cli_bag'
    assert cli.main(['--scenario', str(tiny), '--duration', '0.3', '--workers', '0', '-q',
                     '-o', str(out)]) == 0
    assert (out / 'metadata.yaml').exists()
    capsys.readouterr()
    assert cli.main(['--scenario', str(tiny), '--duration', '0.3', '-o', str(out)]) == 2
    assert '--overwrite' in capsys.readouterr().err
    assert cli.main(['--scenario', 'nope', '-o', str(tmp_path / 'n')]) == 2
    err = capsys.readouterr().err
    assert 'unknown scenario' in err and err.count('\n') == 1
    with pytest.raises(SystemExit) as exc:
        cli.main(['--scenario', 'demo', '--seed', '-4', '-o', str(tmp_path / 'n')])
    assert exc.value.code == 2
    (tmp_path / 'notabag').mkdir()
    (tmp_path / 'notabag' / 'precious.txt').write_text('x')
    assert cli.main(['--scenario', str(tiny), '--duration', '0.3', '--overwrite', '-o',
                     str(tmp_path / 'notabag')]) == 2
    assert (tmp_path / 'notabag' / 'precious.txt').exists()
    assert cli.main(['list']) == 0
    listing = capsys.readouterr().out
    assert 'paper_a' in listing and 'demo' in listing and 'random' in listing


def test_compressed_and_errors(tiny, tmp_path):
    out = tmp_path / 'c'
    write_bag(load_scenario(str(tiny)), out, SynthOptions(seed=1, duration=0.3, workers=0,
                                                          compressed=True), progress=None)
    msgs = _messages(out)
    assert '/camera/image_raw' not in msgs
    _, m = msgs['/camera/image_raw/compressed'][0]
    img = cv2.imdecode(np.asarray(m.data, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (480, 640, 3) and 'jpeg' in m.format
    with pytest.raises(SynthError, match='latency'):
        write_bag(load_scenario(str(tiny)), tmp_path / 'd',
                  SynthOptions(duration=0.3, workers=0, latency_ms=150), progress=None)


def test_exports(tiny, tmp_path):
    from workzone_ros.sim.writer import export_crops, export_pixels
    spec = load_scenario(str(tiny)).with_overrides(duration=3.0)
    counts = export_crops(tmp_path / 'crops', [spec], seed=0, per_class=3, size=32,
                          progress=None)
    assert counts.get('stop', 0) >= 1 and counts.get('background', 0) >= 1
    index = (tmp_path / 'crops' / 'index.csv').read_text().splitlines()
    assert len(index) == 1 + sum(counts.values())
    crop = cv2.imread(str(tmp_path / 'crops' / index[1].split(',')[0]))
    assert crop.shape == (32, 32, 3)
    n = export_pixels(tmp_path / 'px', [spec], seed=0, frames=3, progress=None)
    assert n == 3
    masks = sorted((tmp_path / 'px' / 'masks').glob('*.png'))
    assert len(masks) == 3 and any(cv2.imread(str(p), 0).max() == 255 for p in masks)


def test_a_background_crop_never_shows_a_sign():
    """A drum or a vehicle in front of a sign is not a background example (its crop would
    teach the classifier that the sign is background)."""
    from types import SimpleNamespace

    from workzone_ros.sim.writer import _holds_sign
    sign = SimpleNamespace(box=(100, 100, 40, 40))
    assert _holds_sign((110, 110, 60, 80), [sign])          # covers most of the face
    assert not _holds_sign((136, 100, 60, 80), [sign])      # grazes its edge (10 %)
    assert not _holds_sign((300, 100, 60, 80), [sign])
