"""``evaluate lidar scan`` / ``sensors``: a user's single scan explained, and the sweep."""
import numpy as np
import pytest

from workzone_ros.tools import eval_lidar
from workzone_ros.tools.eval_lidar_sensors import encode, print_table, sweep
from workzone_ros.tools.lidar_report import ScanFormatError, load_scan


def _kitti_bin(path, scale=1 / 255):
    """A KITTI-style .bin: a sign 20 m ahead, 6 m right, reflectance 0-1, and a road."""
    rng = np.random.default_rng(0)
    yy, zz = np.meshgrid(np.linspace(-6.6, -5.4, 30), np.linspace(0.4, 1.4, 12))
    sign = np.column_stack([np.full(yy.size, 20.0), yy.ravel(), zz.ravel(),
                            np.full(yy.size, 230.0 * scale)])
    road = np.column_stack([rng.uniform(3, 50, 4000), rng.uniform(-10, 10, 4000),
                            np.full(4000, -1.73), np.full(4000, 10 * scale)])
    np.vstack([sign, road]).astype('<f4').tofile(path)


def test_a_single_kitti_scan_is_explained(tmp_path, capsys):
    f = tmp_path / 'scan.bin'
    _kitti_bin(f)
    assert eval_lidar.main(['scan', str(f), '--set', 'lidar_in_base=[0, 0, 1.73, 0, 0, 0]']) == 0
    out = capsys.readouterr().out
    assert 'reflectance 0-1' in out and 'x255' in out
    assert '1.73 m above the road' in out
    assert 'CANDIDATE' in out and 'candidates: 1' in out
    assert 'publishes nothing' in out                 # persistence 2 of 3 on one scan


def test_a_scan_that_finds_nothing_says_where_the_points_went(tmp_path, capsys):
    f = tmp_path / 'scan.bin'
    _kitti_bin(f)
    assert eval_lidar.main(['scan', str(f), '--set', 'intensity_scale=1.0']) == 0
    out = capsys.readouterr().out
    assert 'candidates: 0 -- no point reached min_intensity' in out


def test_bad_input_is_a_one_line_error(tmp_path, capsys):
    f = tmp_path / 'scan.bin'
    np.zeros(5, '<f4').tofile(f)
    assert eval_lidar.main(['scan', str(f)]) == 2
    err = capsys.readouterr().err
    assert 'multiple of 4' in err and err.count('\n') == 1
    _kitti_bin(f)
    assert eval_lidar.main(['scan', str(f), '--set', 'z_min=-1.7']) == 2
    assert 'min_point_height' in capsys.readouterr().err
    with pytest.raises(ScanFormatError):
        load_scan(str(tmp_path / 'scan.las'))


def test_encodings_and_axes_of_a_simulated_scan():
    from workzone_ros.core.pointcloud import make_points
    pts = make_points(x=np.array([10.0], np.float32), y=np.array([-2.0], np.float32),
                      z=np.array([0.5], np.float32), intensity=np.array([204.0], np.float32),
                      ring=np.array([3], np.uint16))
    right = encode(pts, 'unit', -np.pi / 2)             # x right, y forward
    assert (right['x'][0], right['y'][0]) == pytest.approx((2.0, 10.0), abs=1e-5)
    assert right['intensity'][0] == pytest.approx(0.8)
    assert encode(pts, 'uint16', 0.0)['intensity'].dtype == np.uint16


def test_sensors_sweep_runs_on_a_short_drive(capsys):
    from workzone_ros.core.lidar_clustering import ClusterParams
    rows = sweep([('left', 1355)], 4.0, ['vlp16'], [1.95], ['unit'], ['x-right'],
                 ClusterParams(), log=lambda *_: None)
    assert len(rows) == 1 and rows[0]['scans'] > 30
    assert rows[0]['fp'] == 0
    print_table(rows)
    assert 'vlp16' in capsys.readouterr().out
