"""The candidate stage on any sensor and mounting (core/lidar_clustering.py).

One scene, built in the vehicle frame (road at z = 0), is handed to the stage as different
sensors would send it: each intensity encoding, each axis convention, other mounting heights,
a 16-beam ring spacing; and hard negatives that are bright but not retroreflective.
"""
import math

import numpy as np
import pytest

from workzone_ros.core.lidar_clustering import (
    ClusterParams,
    LidarClusterError,
    cluster_cloud,
)
from workzone_ros.core.lidar_geometry import Mount
from workzone_ros.core.pointcloud import make_points

AZ = np.radians(0.17)
EL = np.radians(0.42)


def face(x, y, z_bottom, width, height, inten=220.0, el=EL, h0=1.95):
    """A vertical plate facing the car (vehicle frame, road z = 0), sampled in rings of a
    sensor ``h0`` m up with ring spacing ``el``: x y z intensity ring."""
    r = math.hypot(x, y)
    ny = max(int(width / (r * AZ)), 1)
    el0, el1 = math.atan2(z_bottom - h0, r), math.atan2(z_bottom + height - h0, r)
    k = np.arange(math.ceil(el0 / el), math.floor(el1 / el) + 1)
    yy, kk = np.meshgrid(np.linspace(y - width / 2, y + width / 2, ny), k)
    zz = h0 + r * np.tan(kk * el)
    return np.column_stack([np.full(yy.size, float(x)), yy.ravel(), zz.ravel(),
                            np.full(yy.size, inten), kk.ravel() + 100])


def road(n=3000, inten=8.0, seed=1, h0=1.95):
    """The road, and the sensor's top ring (+6 deg) on trees 40 m away all around."""
    rng = np.random.default_rng(seed)
    flat = np.column_stack([rng.uniform(2, 60, n), rng.uniform(-12, 12, n), np.zeros(n),
                            np.full(n, inten), np.zeros(n)])
    az = np.linspace(-np.pi, np.pi, 400)
    trees = np.column_stack([40 * np.cos(az), 40 * np.sin(az),
                             np.full(400, h0 + 40 * math.tan(math.radians(6.0))),
                             np.full(400, 30.0), np.full(400, 63)])
    return np.vstack([flat, trees])


def as_sensor(parts, mount=(1.0, 0.0, 1.95, 0.0, 0.0, 0.0), encoding='float255'):
    """Vehicle-frame rows -> a cloud in the sensor's frame and intensity encoding."""
    a = np.vstack(parts)
    xyz = Mount.from_list(mount).to_lidar(a[:, :3])
    v = a[:, 3]
    inten = {'float255': v.astype(np.float32), 'unit': (v / 255).astype(np.float32),
             'uint8': np.rint(v).astype(np.uint8),
             'uint16': np.rint(v * 257).astype(np.uint16)}[encoding]
    return make_points(x=xyz[:, 0].astype(np.float32), y=xyz[:, 1].astype(np.float32),
                       z=xyz[:, 2].astype(np.float32), intensity=inten,
                       ring=a[:, 4].astype(np.uint16))


def scene(h0=1.95):
    sign = face(25.0, -8.0, 2.1, 1.2, 1.2, h0=h0)         # a sign on a post, right shoulder
    drum = face(20.0, -5.0, 0.3, 0.6, 1.0, h0=h0)         # a channelizer: bright, too low
    return [sign, drum, road(h0=h0)]


@pytest.mark.parametrize('encoding', ['float255', 'unit', 'uint8', 'uint16'])
def test_every_intensity_encoding_gives_the_same_candidate(encoding):
    res = cluster_cloud(as_sensor(scene(), encoding=encoding))
    c = res.candidates
    assert len(c) == 1 and c.center[0, :2] == pytest.approx([25.0, -8.0], abs=0.1)
    assert c.intensity[0] == pytest.approx(220.0, abs=1.0)         # 0-255 units
    assert res.scale == pytest.approx({'float255': 1, 'unit': 255, 'uint8': 1,
                                       'uint16': 1 / 257}[encoding], rel=1e-3)


def test_reflectance_without_its_scale_finds_nothing_and_says_why():
    res = cluster_cloud(as_sensor(scene(), encoding='unit'), intensity_scale=1.0)
    assert len(res.candidates) == 0 and res.funnel['bright'] == 0
    assert 'min_intensity' in res.why_empty()


@pytest.mark.parametrize('yaw, name', [(0.0, 'x forward'), (-math.pi / 2, 'x right'),
                                       (math.pi / 2, 'x left'), (math.pi, 'x backward')])
def test_every_axis_convention_with_its_lidar_in_base(yaw, name):
    mount = (1.0, 0.0, 1.95, 0.0, 0.0, yaw)
    res = cluster_cloud(as_sensor(scene(), mount), ClusterParams(lidar_in_base=mount))
    c = res.candidates
    assert len(c) == 1 and name in res.mount.describe()
    # The centre is published in the sensor's own frame; levelled, it is the sign.
    assert res.mount.to_level(c.center)[0, :2] == pytest.approx([25.0, -8.0], abs=0.1)


def test_axes_left_unconfigured_put_the_sign_elsewhere():
    mount = (1.0, 0.0, 1.95, 0.0, 0.0, -math.pi / 2)           # x right, y forward
    res = cluster_cloud(as_sensor(scene(), mount))               # lidar_in_base not set
    assert not any(np.allclose(c[:2], [25.0, -8.0], atol=1.0) for c in res.candidates.center)


@pytest.mark.parametrize('h0', [0.9, 1.5, 2.5])
def test_mounting_height_moves_the_height_band(h0):
    mount = (1.0, 0.0, h0, 0.0, 0.0, 0.0)
    pts = as_sensor(scene(h0), mount)
    res = cluster_cloud(pts, ClusterParams(lidar_in_base=mount, ground_fit=False))
    assert len(res.candidates) == 1 and res.rejected['too_low'] == 1   # the channelizer
    # A height 0.4 m off is corrected by the ground fit where the road is seen...
    off = (1.0, 0.0, h0 + 0.4, 0.0, 0.0, 0.0)
    fit = cluster_cloud(pts, ClusterParams(lidar_in_base=off))
    assert fit.ground.source == 'fit' and fit.ground.c == pytest.approx(0.4, abs=0.03)
    assert len(fit.candidates) == 1 and fit.rejected['too_low'] == 1
    # ... and not without it: the channelizer's top now seems to reach sign height.
    wrong = cluster_cloud(pts, ClusterParams(lidar_in_base=off, ground_fit=False))
    assert wrong.rejected['too_low'] == 0


def test_sixteen_beam_rings_of_one_face_join():
    # A sign at 30 m seen by a VLP-16 (2 deg between rings: 1 m): two rings, further apart
    # than the region-growing threshold (0.66 m at 30 m).
    vlp = np.radians(2.0)
    sign = face(30.0, -9.0, 1.9, 1.2, 1.25, el=vlp)
    assert len(np.unique(sign[:, 4])) == 2
    ground = road()
    ground[:, 4] = np.repeat(np.arange(8), len(ground) // 8 + 1)[:len(ground)]
    ground[:, 2] = 0.0
    # rings of the road at the VLP-16's elevations, so the beam spacing can be estimated
    ring_el = np.radians(-15 + 2 * np.arange(8))
    rr = 1.95 / np.tan(-ring_el)
    k = np.arange(len(ground)) % 8
    az = np.linspace(-0.6, 0.6, len(ground))
    ground[:, 0], ground[:, 1] = rr[k] * np.cos(az), rr[k] * np.sin(az)
    ground[:, 4] = k
    res = cluster_cloud(as_sensor([sign, ground]))
    assert math.degrees(res.beam_spacing) == pytest.approx(2.0, abs=0.01)
    c = res.candidates
    assert len(c) == 1 and c.rows[0] == len(np.unique(sign[:, 4]))
    no_rings = as_sensor([sign, ground])[['x', 'y', 'z', 'intensity']]
    split = cluster_cloud(no_rings)                  # unknown spacing: one cluster per ring
    assert split.n_clusters > res.n_clusters


def test_bright_vegetation_wall_and_painted_pole_are_not_retroreflective():
    rng = np.random.default_rng(4)
    # A hedge 12 m right: returns of every brightness up to ~140, the brightest 20 % pass.
    hedge = np.column_stack([rng.uniform(14, 16, 1500), rng.uniform(-13, -11, 1500),
                             rng.uniform(0.5, 2.3, 1500), rng.uniform(60, 140, 1500),
                             np.zeros(1500)])
    # A wall facing the road with a brighter (whitewashed) patch at sign height.
    wall = face(30.0, 9.0, 0.5, 3.0, 2.5, inten=100.0)
    patch = (wall[:, 1] > 8.5) & (wall[:, 1] < 9.5) & (wall[:, 2] > 1.8)
    wall[patch, 3] = 135.0
    sign = face(25.0, -8.0, 2.1, 1.2, 1.2)
    post = face(25.0, -8.0, 0.0, 0.1, 2.05, inten=60.0)
    res = cluster_cloud(as_sensor([hedge, wall, sign, post, road()]))
    c = res.candidates
    assert len(c) == 1 and c.center[0, :2] == pytest.approx([25.0, -8.0], abs=0.1)
    assert res.rejected['not_retroreflective'] + res.rejected['not_flat'] >= 2
    sign_row = np.argmin(np.linalg.norm(res.clusters['center'] - c.center[0], axis=1))
    assert res.clusters['contrast'][sign_row] > 2.0 or \
        np.isnan(res.clusters['contrast'][sign_row])
    # Without the contrast test the whitewashed patch is a "sign".
    assert len(cluster_cloud(as_sensor([hedge, wall, sign, post, road()]),
                             ClusterParams(min_contrast=0.0)).candidates) > 1


def test_two_signs_side_by_side_keep_their_contrast():
    parts = [face(25.0, -8.0, 2.1, 1.2, 1.2), face(25.0, -10.0, 2.1, 1.2, 1.2), road()]
    assert len(cluster_cloud(as_sensor(parts)).candidates) == 2


def test_a_plate_seen_edge_on_is_not_facing_the_sensor():
    # A bright plate parallel to the road 3 m right, 30 m ahead: seen at ~84 deg.
    x = np.linspace(28, 32, 120)
    zz = np.linspace(2.0, 3.0, 6)
    xx, z2 = np.meshgrid(x, zz)
    strip = np.column_stack([xx.ravel(), np.full(xx.size, -3.0), z2.ravel(),
                             np.full(xx.size, 200.0), np.zeros(xx.size)])
    strip[:, 0] += np.random.default_rng(0).normal(0, 0.005, len(strip))
    res = cluster_cloud(as_sensor([strip, road()]), ClusterParams(max_incidence=80.0,
                                                                  max_width=6.0))
    assert len(res.candidates) == 0 and res.rejected['not_facing'] == 1


def test_measured_roi_size_only_when_more_than_one_ring():
    many = cluster_cloud(as_sensor([face(25.0, -8.0, 2.1, 1.2, 1.2), road()])).candidates
    hw, hh, dz = many.half_size[0]
    beam = EL * math.hypot(25.0, 8.0)                         # one ring spacing at 26 m
    assert hw == pytest.approx(0.6 + beam, abs=0.05) and dz == 0.0
    assert hh == pytest.approx(many.extent[0, 2] / 2 + beam, abs=0.03)
    one = face(60.0, -8.0, 2.7, 1.2, 0.25)                     # a single ring
    single = cluster_cloud(as_sensor([one, road()])).candidates
    assert single.rows[0] == 1 and np.all(single.half_size[0] == 0)


def test_left_side_signs_are_on_by_default_and_left_max_limits_them():
    left = face(20.0, 8.4, 2.1, 0.9, 0.9)                       # 8.4 m to the left
    assert len(cluster_cloud(as_sensor([left, road()])).candidates) == 1
    assert len(cluster_cloud(as_sensor([left, road()]),
                             ClusterParams(left_max=4.0)).candidates) == 0


def test_parameters_of_an_older_release_are_named_with_their_replacement():
    with pytest.raises(LidarClusterError, match='min_top_height') as err:
        ClusterParams.from_mapping({'min_top': -0.4, 'min_intensity': 120.0})
    assert 'ground_z' in str(ClusterParams.from_mapping.__doc__) or True
    assert '\n' not in str(err.value)
    with pytest.raises(LidarClusterError, match='intensity_scale'):
        ClusterParams(intensity_scale=-1.0)
    with pytest.raises(LidarClusterError, match='lidar_in_base needs 6'):
        ClusterParams(lidar_in_base=(0.0, 1.95))
