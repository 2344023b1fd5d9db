"""Tests for core/lidar_stream.py (the node's state over scans) and core/lidar_rois.py."""
import numpy as np
import pytest

from workzone_ros.core.lidar_clustering import ClusterParams, candidates_to_array
from workzone_ros.core.lidar_rois import size_rois
from workzone_ros.core.lidar_stream import LidarStream
from workzone_ros.core.pointcloud import make_points
from workzone_ros.core.projection import CameraModel, candidates_to_rois
from workzone_ros.sim.world import DEFAULT_CAMERA, LIDAR_TO_CAMERA


def _cloud(scale=1.0, dtype=np.float32, sign=True):
    rng = np.random.default_rng(0)
    n = 3000
    xs, ys = rng.uniform(3, 60, n), rng.uniform(-12, 12, n)
    zs, inten = np.full(n, -1.95), np.full(n, 8.0)
    if sign:
        yy, zz = np.meshgrid(np.linspace(-8.6, -7.4, 30), np.linspace(0.2, 1.2, 10))
        xs = np.concatenate([xs, np.full(yy.size, 25.0)])
        ys = np.concatenate([ys, yy.ravel()])
        zs = np.concatenate([zs, zz.ravel()])
        inten = np.concatenate([inten, np.full(yy.size, 220.0)])
    return make_points(x=xs.astype(np.float32), y=ys.astype(np.float32),
                       z=zs.astype(np.float32), intensity=(inten * scale).astype(dtype))


def test_reflectance_scale_is_learned_and_logged_once():
    st = LidarStream(ClusterParams())
    out = st.process(_cloud(1 / 255))
    assert any('reflectance 0-1' in line for line in out.info)
    assert len(out.candidates) == 1 and not out.candidates.confirmed[0]
    assert any('held for persistence' in line for line in out.info)
    again = st.process(_cloud(1 / 255))
    assert again.info == [] and again.candidates.confirmed[0]
    assert st.why_nothing() == ''
    keys = dict(st.status())
    assert keys['intensity scale'].startswith('x255') and keys['last scan published'] == '1'


def test_nothing_bright_for_n_scans_warns_with_the_observed_range():
    st = LidarStream(ClusterParams(), silent_scans=3)
    outs = [st.process(_cloud(1 / 65535 * 100, np.float32)) for _ in range(3)]
    # Floats up to 0.34: taken as reflectance 0-1, scaled x255: nothing reaches 120.
    assert outs[0].warnings == [] and outs[1].warnings == []
    assert 'no point reached min_intensity 120' in outs[2].warnings[0]
    assert 'intensity_scale' in outs[2].warnings[0]
    assert 'no point reached min_intensity' in st.why_nothing()


def test_reasons_in_status_when_clusters_are_rejected():
    st = LidarStream(ClusterParams(min_top_height=5.0), k=1, n=1)
    st.process(_cloud())
    status = dict(st.status())
    assert status['last scan rejected'] == 'too_low 1'
    assert 'all rejected: 1 too_low' in status['why nothing published']


def test_rois_sized_by_the_cluster_and_the_minimum_kept_for_sparse_ones():
    st = LidarStream(ClusterParams(), k=1, n=1)
    out = st.process(_cloud())
    arr = candidates_to_array(out.candidates)
    assert arr['half_w'][0] > 0 and out.candidates.rows[0] == 10     # ten rows: measured
    cam = CameraModel(DEFAULT_CAMERA.width, DEFAULT_CAMERA.height, DEFAULT_CAMERA.K,
                      DEFAULT_CAMERA.D)
    rois, _ = candidates_to_rois(arr, 0, 0, cam, LIDAR_TO_CAMERA)
    arr['half_w'] = arr['half_h'] = arr['dz'] = 0.0
    assert size_rois(rois, arr, cam) == rois                    # not measured: kept
    arr['half_w'], arr['half_h'], arr['dz'] = 0.7, 0.55, 0.0
    sized = size_rois(rois, arr, cam)
    depth = rois[0].position[2]
    want = 2 * ((0.7 + 0.15) * cam.fx / depth + 6.0)
    assert sized[0].box.w == pytest.approx(want, abs=0.5) and sized[0].box.w < rois[0].box.w
    assert sized[0].center == rois[0].center
    arr['dz'] = 0.5                                              # cut by the top ring
    up = size_rois(rois, arr, cam)[0]
    assert up.box.y + up.box.h / 2 == pytest.approx(
        rois[0].center[1] - 0.5 * cam.fy / depth, abs=0.5)
    assert size_rois(rois, np.asarray(arr[['x', 'y', 'z', 'radius', 'id']]), cam) == rois
