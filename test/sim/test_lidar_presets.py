"""LiDAR sensor presets (sim/lidar.py LIDAR_PRESETS) and the scenario's ``lidar:`` key."""
from __future__ import annotations

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from workzone_ros.core.pointcloud import FieldSpec, cloud_view
from workzone_ros.interfaces import GtLidar, decode
from workzone_ros.sim.lidar import (
    DEFAULT_PRESET,
    LIDAR_PRESETS,
    LidarError,
    LidarModel,
    cast_scan,
    lidar_preset,
)
from workzone_ros.sim.scenario import (
    LidarSpec,
    ScenarioError,
    list_scenarios,
    load_scenario,
    parse_scenario,
)
from workzone_ros.sim.world import LIDAR_IN_BASE, Pose, Road, Scene
from workzone_ros.sim.writer import SynthOptions, _World

H = float(LIDAR_IN_BASE[2])
STORE = get_typestore(Stores.ROS2_JAZZY)

# Datasheet values at 10 Hz: beams, lowest and highest elevation (deg), azimuth step (deg),
# range (m), rays per revolution.
DATASHEET = {
    'hdl64': (64, -24.8, 2.0, 0.17, 120.0, 2118 * 64),
    'hdl32': (32, -30.67, 10.67, 0.16, 100.0, 2250 * 32),
    'vlp16': (16, -15.0, 15.0, 0.2, 100.0, 1800 * 16),
}


def _empty_road_scan(model: LidarModel):
    scene = Scene('test', 0, Road([(2000, 0.0)]))
    return cast_scan(scene, 0.0, lambda t: Pose(np.array([0.0, 0.0, H]), 0.0), model)


def test_default_stays_the_hdl64e():
    assert DEFAULT_PRESET == 'hdl64'
    assert LIDAR_PRESETS['hdl64'] == LidarModel() == lidar_preset()
    assert LidarSpec().sensor() == LidarModel()
    spec = parse_scenario({}, 'x')
    assert spec.lidar == LidarSpec('hdl64', None) and spec.lidar.sensor() == LidarModel()


@pytest.mark.parametrize('name', sorted(DATASHEET))
def test_preset_geometry(name):
    beams, lo, hi, az, rng, rays = DATASHEET[name]
    m = LIDAR_PRESETS[name]
    assert m.n_beams == beams and m.rate_hz == 10.0
    el = np.degrees(m.elevations())
    assert el.size == beams
    assert el[0] == pytest.approx(lo) and el[-1] == pytest.approx(hi)
    assert np.allclose(np.diff(el), (hi - lo) / (beams - 1))         # uniform, ring 0 lowest
    assert m.azimuth_res_deg == pytest.approx(az) and m.max_range == rng
    assert m.n_columns * m.n_beams == rays


def test_vertical_spacing_matches_the_datasheets():
    assert np.diff(np.degrees(LIDAR_PRESETS['hdl32'].elevations()))[0] == pytest.approx(
        1.333, abs=1e-3)
    assert np.diff(np.degrees(LIDAR_PRESETS['vlp16'].elevations()))[0] == pytest.approx(2.0)


@pytest.mark.parametrize('name', sorted(DATASHEET))
def test_points_per_scan_on_an_empty_road(name):
    """Only the downward beams whose ground hit lies within range return, once per column."""
    m = LIDAR_PRESETS[name]
    el = m.elevations()
    with np.errstate(divide='ignore'):
        r = np.where(el < 0, H / np.sin(-el), np.inf)
    hits = np.flatnonzero((r >= m.min_range) & (r <= m.max_range))
    expected = hits.size * m.n_columns * (1.0 - m.dropout)
    scan = _empty_road_scan(m)
    n = scan.points.shape[0]
    assert abs(n - expected) < 4 * np.sqrt(expected * m.dropout) + 0.002 * expected, (n, expected)
    assert set(np.unique(scan.points['ring']).tolist()) == set(hits.tolist())
    assert scan.points['ring'].max() < m.n_beams


def test_sparser_presets_write_fewer_points():
    n = {k: _empty_road_scan(LIDAR_PRESETS[k]).points.shape[0] for k in ('hdl64', 'vlp16')}
    assert n['vlp16'] < n['hdl64'] / 4


def test_max_range_override():
    m = lidar_preset('vlp16', 60.0)
    assert m.max_range == 60.0 and m.n_beams == 16
    assert lidar_preset('hdl64', 120.0) is LIDAR_PRESETS['hdl64']
    scan = _empty_road_scan(m)
    assert np.hypot(scan.points['x'], scan.points['y']).max() <= 60.5
    with pytest.raises(LidarError, match='unknown lidar model'):
        lidar_preset('hdl128')
    with pytest.raises(LidarError):
        lidar_preset('vlp16', 0.5)            # not beyond min_range


def test_scenario_lidar_key():
    spec = parse_scenario({'lidar': {'model': 'vlp16', 'max_range': 80}}, 'x')
    assert spec.lidar == LidarSpec('vlp16', 80.0)
    assert spec.lidar.sensor() == lidar_preset('vlp16', 80.0)
    assert parse_scenario({'lidar': {'model': 'hdl32'}}, 'x').lidar.sensor() == \
        LIDAR_PRESETS['hdl32']


@pytest.mark.parametrize('lidar, needle', [
    ({'model': 'hdl128'}, "model must be one of hdl64, hdl32, vlp16, got 'hdl128'"),
    ({'model': 'vlp16', 'range': 50}, "unknown key 'range'; allowed: model, max_range"),
    ({'max_range': 2}, 'max_range must be in [5.0, 300.0], got 2'),
    ({'max_range': 'far'}, "max_range must be a number, got 'far'"),
    ('vlp16', 'must be a mapping, got str'),
])
def test_scenario_lidar_errors_are_one_line(lidar, needle):
    with pytest.raises(ScenarioError) as exc:
        parse_scenario({'lidar': lidar}, 'x')
    msg = str(exc.value)
    assert '\n' not in msg and msg.startswith('scenario x: lidar: ') and needle in msg, msg


def test_library_lidars():
    # The demo carries a VLP-16 (small `make demo` bags); every other scenario the HDL-64E.
    assert load_scenario('demo').lidar.model == 'vlp16'
    for name in list_scenarios():
        if name not in ('demo', 'random'):
            assert load_scenario(name).lidar == LidarSpec(), name
    assert load_scenario('random', 3).lidar == LidarSpec()


def _cloud(data: bytes) -> np.ndarray:
    msg = STORE.deserialize_cdr(data, 'sensor_msgs/msg/PointCloud2')
    fields = [FieldSpec(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    return cloud_view(np.asarray(msg.data), fields, msg.point_step, msg.width, msg.height,
                      msg.row_step, bool(msg.is_bigendian))


def test_writer_casts_with_the_scenarios_lidar():
    spec = load_scenario('demo').with_overrides(duration=0.5)
    world = _World(spec, SynthOptions(workers=0))
    out = dict((key, data) for _, key, data in world.scan(0, 0.05))
    pts = _cloud(out['points'])
    assert pts['ring'].max() == 15 and 10_000 < pts.shape[0] <= 1800 * 16
    gt = decode(STORE.deserialize_cdr(out['gt_lidar'], 'std_msgs/msg/String').data, GtLidar)
    assert all(max(s.indices) < pts.shape[0] for s in gt.signs)
