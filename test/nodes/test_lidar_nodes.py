"""Node tests for lidar_cluster and projector with real topics (private context, DDS).

A hand-made cloud with one sign, CameraInfo and images go in on real topics; candidates and
``Rois`` come out.  Also: bad input is dropped with a reason and the nodes keep running; a
projector without CameraInfo says so instead of guessing.
"""
from dataclasses import replace

import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import String

from workzone_ros import interfaces
from workzone_ros.core.pointcloud import make_points
from workzone_ros.nodes.conversions import (
    CameraInfoData,
    array_to_pointcloud2,
    numpy_to_camera_info,
    numpy_to_image,
    pointcloud2_to_array,
)
from workzone_ros.nodes.lidar_cluster import LidarClusterNode
from workzone_ros.nodes.projector import ProjectorNode
from workzone_ros.sim.world import DEFAULT_CAMERA, LIDAR_TO_CAMERA

NS = 'lidartest'
FAST = dict(diagnostics_period_s=0.2, silent_input_warn_s=5.0)
SIGN = (25.0, -7.0, 0.8)
SMALL_CAMERA = replace(DEFAULT_CAMERA, width=160, height=120, fx=138.6, fy=138.6, cx=80.0,
                       cy=60.0)


def _sign_cloud(with_intensity=True):
    x, y0, z0 = SIGN
    yy, zz = np.meshgrid(np.linspace(y0 - 0.6, y0 + 0.6, 16), np.linspace(z0 - 0.6, z0 + 0.6, 6))
    rng = np.random.default_rng(0)
    gx, gy = rng.uniform(3, 60, 3000), rng.uniform(-15, 15, 3000)
    xs = np.concatenate([np.full(yy.size, x), gx]).astype(np.float32)
    ys = np.concatenate([yy.ravel(), gy]).astype(np.float32)
    zs = np.concatenate([zz.ravel(), np.full(gx.size, -1.95)]).astype(np.float32)
    if not with_intensity:
        return make_points(x=xs, y=ys, z=zs)
    inten = np.concatenate([np.full(yy.size, 220.0), np.full(gx.size, 6.0)]).astype(np.float32)
    return make_points(x=xs, y=ys, z=zs, intensity=inten)


def _topics():
    return dict(points=f'/{NS}/points', cands=f'/{NS}/candidates', image=f'/{NS}/image',
                info=f'/{NS}/camera_info', rois=f'/{NS}/rois', odom=f'/{NS}/odom')


def _camera_io(io, t):
    """Image and CameraInfo publishers on ``io`` for the small test camera (small frames:
    best-effort images arrive reliably), its CameraInfo message and a black frame."""
    cam = SMALL_CAMERA
    pub_img = io.create_publisher(Image, t['image'], 10)
    pub_info = io.create_publisher(CameraInfo, t['info'], 10)
    info = numpy_to_camera_info(CameraInfoData(cam.width, cam.height, cam.K, cam.D))
    return pub_img, pub_info, info, np.zeros((cam.height, cam.width, 3), np.uint8)


def _nodes(ros, t, info=True):
    ros.add(LidarClusterNode(context=ros.context, parameter_overrides=[
        Parameter('points_topic', value=t['points']),
        Parameter('candidates_topic', value=t['cands']),
        Parameter('odom_topic', value=''),
        Parameter('persistence_k', value=1),
        Parameter('persistence_n', value=1)], **FAST))
    proj = ros.add(ProjectorNode(context=ros.context, parameter_overrides=[
        Parameter('candidates_topic', value=t['cands']),
        Parameter('image_topic', value=t['image']),
        Parameter('camera_info_topic', value=t['info']),
        Parameter('rois_topic', value=t['rois']),
        Parameter('odom_topic', value=''),
        Parameter('lidar_to_camera', value=[float(v) for v in LIDAR_TO_CAMERA.ravel()])],
        **FAST))
    return proj


def test_cloud_camera_info_image_in_candidates_and_rois_out(ros):
    t = _topics()
    _nodes(ros, t)
    io = ros.add(rclpy.create_node('io', context=ros.context))
    pub_pts = io.create_publisher(PointCloud2, t['points'], 10)
    pub_img, pub_info, info, frame = _camera_io(io, t)
    got_cands, got_rois = [], []
    io.create_subscription(PointCloud2, t['cands'], got_cands.append, 10)
    io.create_subscription(String, t['rois'], got_rois.append, 10)
    cam = SMALL_CAMERA
    cloud = _sign_cloud()
    state = {'k': 0}

    def each():
        k = state['k']
        state['k'] += 1
        stamp = interfaces.Time.from_ns(1_700_000_000_000_000_000 + k * 100_000_000)
        pub_info.publish(info)
        pub_img.publish(numpy_to_image(frame, 'bgr8', stamp=stamp, frame_id='camera'))
        pub_pts.publish(array_to_pointcloud2(cloud, stamp=stamp, frame_id='lidar'))

    assert ros.spin_until(lambda: got_rois and got_cands, each=each), \
        (len(got_cands), len(got_rois))
    arr = pointcloud2_to_array(got_cands[0])
    assert set(arr.dtype.names) == {'x', 'y', 'z', 'radius', 'intensity', 'count', 'id',
                                   'half_w', 'half_h', 'dz'}
    assert len(arr) == 1 and arr['count'][0] == 96
    assert (arr['x'][0], arr['y'][0], arr['z'][0]) == pytest.approx(SIGN, abs=0.05)
    rois = interfaces.decode(got_rois[0].data, interfaces.Rois)
    assert rois.lidar_stamp is not None
    # Paired within the slop (0.1 s); usually the same stamp, unless a message was lost.
    assert abs(rois.header.stamp.to_ns() - rois.lidar_stamp.to_ns()) <= 100_000_000
    assert len(rois.rois) == 1
    roi = rois.rois[0]
    # The sign centre by hand: camera frame = LIDAR_TO_CAMERA @ SIGN, pinhole + distortion.
    from workzone_ros.core.projection import CameraModel, project_points
    uv = project_points(np.array([SIGN]), LIDAR_TO_CAMERA,
                        CameraModel(cam.width, cam.height, cam.K, cam.D)).uv[0]
    assert roi.center == pytest.approx(tuple(uv), abs=0.5)
    assert roi.box.x < uv[0] < roi.box.x + roi.box.w and roi.box.y < uv[1] < roi.box.y + roi.box.h


def test_bad_inputs_are_dropped_with_a_reason_and_no_camera_info_is_reported(ros):
    t = _topics()
    proj = _nodes(ros, t)
    cluster = ros.nodes[0]
    io = ros.add(rclpy.create_node('io2', context=ros.context))
    pub_pts = io.create_publisher(PointCloud2, t['points'], 10)
    pub_img = io.create_publisher(Image, t['image'], 10)
    frame = np.zeros((120, 160, 3), np.uint8)
    bad = _sign_cloud(with_intensity=False)
    good = _sign_cloud()
    state = {'k': 0}

    def each():
        k = state['k']
        state['k'] += 1
        stamp = interfaces.Time.from_ns(1_700_000_000_000_000_000 + k * 100_000_000)
        pub_pts.publish(array_to_pointcloud2(bad if k % 2 == 0 else good, stamp=stamp))
        pub_img.publish(numpy_to_image(frame, 'bgr8', stamp=stamp))

    points_topic = cluster.resolve_topic_name(t['points'])
    image_topic = proj.resolve_topic_name(t['image'])

    def dropped():
        stats = cluster.topic_stats().get(points_topic)
        pstats = proj.topic_stats().get(image_topic)
        return stats is not None and stats.dropped > 0 and pstats is not None \
            and pstats.dropped > 0

    assert ros.spin_until(dropped, each=each)
    assert 'intensity' in cluster.topic_stats()[points_topic].last_drop_reason
    assert 'CameraInfo' in proj.topic_stats()[image_topic].last_drop_reason
    status = proj.diagnostic_status()
    assert 'no CameraInfo' in status.message and status.level != b'\x00'


def test_images_before_the_first_camera_info_are_held_not_dropped(ros):
    """A replay's first images can beat its first CameraInfo: within the projector's grace
    period they are held and projected once it comes; nothing is dropped."""
    t = _topics()
    proj = _nodes(ros, t)
    io = ros.add(rclpy.create_node('io_hold', context=ros.context))
    pub_pts = io.create_publisher(PointCloud2, t['points'], 10)
    pub_img, pub_info, info, frame = _camera_io(io, t)
    got_rois = []
    io.create_subscription(String, t['rois'], got_rois.append, 10)
    cloud = _sign_cloud()
    base = 1_700_000_000_000_000_000
    state = {'k': 0}

    def each():
        k = state['k']
        state['k'] += 1
        stamp = interfaces.Time.from_ns(base + k * 100_000_000)
        pub_img.publish(numpy_to_image(frame, 'bgr8', stamp=stamp, frame_id='camera'))
        pub_pts.publish(array_to_pointcloud2(cloud, stamp=stamp, frame_id='lidar'))

    image_topic = proj.resolve_topic_name(t['image'])
    assert ros.spin_until(lambda: len(proj._held) > 0, each=each)
    first_held = proj._held[0][0].header.stamp
    pub_info.publish(info)
    assert ros.spin_until(lambda: proj._camera is not None and got_rois,
                          each=lambda: pub_info.publish(info))
    stamps = {interfaces.decode(m.data, interfaces.Rois).header.stamp.to_ns() for m in got_rois}
    assert interfaces.Time(first_held.sec, first_held.nanosec).to_ns() in stamps
    assert proj.topic_stats()[image_topic].dropped == 0 and not proj._held


def test_bad_extrinsics_are_reported_not_guessed(ros):
    t = _topics()
    proj = ros.add(ProjectorNode(context=ros.context, parameter_overrides=[
        Parameter('candidates_topic', value=t['cands']),
        Parameter('lidar_to_camera', value=[1.0, 2.0, 3.0])], **FAST))
    status = proj.diagnostic_status()
    assert 'lidar_to_camera' in status.message


def test_nearest_policy_gives_every_image_the_nearest_scan_and_reuses_scans(ros):
    # 15 Hz images, 10 Hz candidate sets stamped 50 ms after the frames (the simulator's
    # timing), published a little after their stamp: every image gets ROIs, from the set
    # whose forward time (stamp + half a spin) is nearest; sets serve several images.
    from workzone_ros.core.lidar_clustering import CANDIDATE_DTYPE
    t = _topics()
    ros.add(ProjectorNode(context=ros.context, parameter_overrides=[
        Parameter('candidates_topic', value=t['cands']),
        Parameter('image_topic', value=t['image']),
        Parameter('camera_info_topic', value=t['info']),
        Parameter('rois_topic', value=t['rois']),
        Parameter('odom_topic', value=''),
        Parameter('sync_policy', value='nearest'),
        Parameter('lidar_to_camera', value=[float(v) for v in LIDAR_TO_CAMERA.ravel()])],
        **FAST))
    io = ros.add(rclpy.create_node('io3', context=ros.context))
    pub_cands = io.create_publisher(PointCloud2, t['cands'], 10)
    pub_img, pub_info, info, frame = _camera_io(io, t)
    got = []
    io.create_subscription(String, t['rois'], got.append, 50)
    cands = np.zeros(1, CANDIDATE_DTYPE)
    cands[0] = (*SIGN, 0.6, 200.0, 96, 1)
    t0 = 1_700_000_000_000_000_000
    ms = 1_000_000
    # Arrival order: a set is published after the images up to ~100 ms past its stamp.
    images = [round(k * 1000 / 15) for k in range(16)]
    sets = [50 + 100 * j for j in range(10)]
    events = sorted([(s, 'i') for s in images] + [(s + 100, 'c') for s in sets])
    state = {'k': 0}

    def each():
        pub_info.publish(info)
        if state['k'] < len(events) and ros.nodes[0]._camera is not None:
            when, kind = events[state['k']]
            state['k'] += 1
            if kind == 'i':
                pub_img.publish(numpy_to_image(frame, 'bgr8', stamp=interfaces.Time.from_ns(
                    t0 + when * ms), frame_id='camera'))
            else:
                pub_cands.publish(array_to_pointcloud2(cands, stamp=interfaces.Time.from_ns(
                    t0 + (when - 100) * ms), frame_id='lidar'))

    def done():
        return state['k'] >= len(events) and len(got) >= 8

    assert ros.spin_until(done, each=each), (state['k'], len(got))
    pairs = {}
    for msg in got:
        r = interfaces.decode(msg.data, interfaces.Rois)
        pairs[(r.header.stamp.to_ns() - t0) // ms] = (r.lidar_stamp.to_ns() - t0) // ms
        assert len(r.rois) == 1
    for img, used in pairs.items():
        nearest = min(sets, key=lambda s: (abs(s + 50 - img), s))
        assert used == nearest and abs(img - used - 50) <= 100
    assert len(set(pairs.values())) < len(pairs)        # some scan served two images


def test_single_scan_user_is_told_why_nothing_is_published(ros):
    """Default persistence (2 of 3): one scan gives a candidate that is held, and the node
    says so in /diagnostics; a second scan publishes it."""
    t = _topics()
    node = ros.add(LidarClusterNode(context=ros.context, parameter_overrides=[
        Parameter('points_topic', value=t['points']),
        Parameter('candidates_topic', value=t['cands']),
        Parameter('odom_topic', value='')], **FAST))
    io = ros.add(rclpy.create_node('io_single', context=ros.context))
    pub_pts = io.create_publisher(PointCloud2, t['points'], 10)
    got = []
    io.create_subscription(PointCloud2, t['cands'], got.append, 10)
    stamp = interfaces.Time.from_ns(1_700_000_000_000_000_000)
    assert ros.spin_until(lambda: got, each=lambda: None if node._stream.scans else
                          pub_pts.publish(array_to_pointcloud2(_sign_cloud(), stamp=stamp)))
    assert len(pointcloud2_to_array(got[0])) == 0
    values = dict((v.key, v.value) for v in node.diagnostic_status().values)
    assert 'held for persistence' in values['why nothing published']
    assert values['last scan held for persistence'].startswith('1 ')
    assert values['last scan bright in height band'] == '96'
    node._stream.process(_sign_cloud())                # the same sign again: confirmed
    assert node._stream.why_nothing() == ''


def test_bad_and_renamed_parameters_are_one_line_errors(ros):
    from workzone_ros.nodes.base import ConfigError
    t = _topics()
    with pytest.raises(ConfigError, match='lidar_in_base needs 6 values'):
        LidarClusterNode(context=ros.context, parameter_overrides=[
            Parameter('points_topic', value=t['points']),
            Parameter('lidar_in_base', value=[1.0, 0.0, 1.95])], **FAST)
    node = ros.add(LidarClusterNode(context=ros.context, parameter_overrides=[
        Parameter('points_topic', value=t['points']),
        Parameter('z_min', value=-1.7)], **FAST))
    assert any('min_point_height' in line for line in node.renamed_params)
    bad = node.set_parameters([Parameter('min_point_height', value=12.0)])[0]
    assert not bad.successful and 'max_point_height' in bad.reason
    ok = node.set_parameters([Parameter('lidar_in_base',
                                        value=[0.0, 0.0, 1.84, 0.0, 0.0, -1.5708])])[0]
    assert ok.successful and node._stream.params.mount.height == pytest.approx(1.84)
