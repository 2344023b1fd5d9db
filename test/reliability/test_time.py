"""Time: a looping bag's jump back resets every node's buffers and the output
goes on; the fusion restarts at ``unknown``; ``use_sim_time`` without ``/clock`` waits and
says so."""
from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import String

from workzone_ros import interfaces
from workzone_ros.core.sync import NearestSync, PoseBuffer
from workzone_ros.interfaces import WorkzoneState, decode
from workzone_ros.nodes.base import Param, WorkzoneNode
from workzone_ros.nodes.conversions import (
    CameraInfoData,
    array_to_pointcloud2,
    numpy_to_camera_info,
    numpy_to_image,
)
from workzone_ros.nodes.fusion import FusionNode
from workzone_ros.nodes.projector import ProjectorNode
from workzone_ros.sim.world import DEFAULT_CAMERA, LIDAR_TO_CAMERA

T0 = 1_700_000_000_000_000_000
FAST = dict(diagnostics_period_s=0.2, silent_input_warn_s=5.0)


def test_the_synchroniser_and_pose_buffer_of_a_looping_bag_need_the_reset():
    """Why the nodes reset: stored by stamp, the first pass starves the second."""
    sync = NearestSync(100_000_000, 100_000_000, 150_000_000, history=5, max_pending=5)
    poses = PoseBuffer()
    for k in range(10):
        sync.add_candidates(T0 + k * 100_000_000, 'first pass')
        sync.add_image(T0 + k * 100_000_000)
        poses.add(T0 + k * 100_000_000, (k, 0, 0), (0, 0, 0, 1))
    back = T0 - 40_000_000_000
    got = []
    for k in range(5):
        sync.add_candidates(back + k * 100_000_000, 'second pass')
        got += sync.add_image(back + k * 100_000_000)
        poses.add(back + k * 100_000_000, (k, 0, 0), (0, 0, 0, 1))
    assert [g[3] for g in got] == [None] * 5          # no image gets its scan
    assert poses.at(back + 200_000_000) is None       # the new poses were pruned as old


def _camera_msgs():
    cam = DEFAULT_CAMERA
    w, h, f = 160, 120, 138.6
    K = np.array([[f, 0, 80.0], [0, f, 60.0], [0, 0, 1]])
    info = numpy_to_camera_info(CameraInfoData(w, h, K, np.zeros(5)))
    return cam, info, np.zeros((h, w, 3), np.uint8)


def _candidates(stamp):
    from workzone_ros.core.pointcloud import make_points
    one = dict(x=np.array([25.0], np.float32), y=np.array([-7.0], np.float32),
               z=np.array([0.8], np.float32), radius=np.array([0.6], np.float32),
               intensity=np.array([220.0], np.float32), count=np.array([40], np.uint32),
               id=np.array([1], np.uint32))
    return array_to_pointcloud2(make_points(**one), stamp=stamp, frame_id='lidar')


def test_projector_keeps_projecting_after_the_time_jumps_back(ros):
    ns = 'jump'
    proj = ros.add(ProjectorNode(context=ros.context, parameter_overrides=[
        Parameter('candidates_topic', value=f'/{ns}/candidates'),
        Parameter('image_topic', value=f'/{ns}/image'),
        Parameter('camera_info_topic', value=f'/{ns}/camera_info'),
        Parameter('rois_topic', value=f'/{ns}/rois'),
        Parameter('odom_topic', value=f'/{ns}/odom'),
        Parameter('lidar_to_camera', value=[float(v) for v in LIDAR_TO_CAMERA.ravel()])],
        **FAST))
    io = ros.node('jump_io')
    pub_c = io.create_publisher(PointCloud2, f'/{ns}/candidates', 10)
    pub_i = io.create_publisher(Image, f'/{ns}/image', 10)
    pub_info = io.create_publisher(CameraInfo, f'/{ns}/camera_info', 10)
    pub_odom = io.create_publisher(Odometry, f'/{ns}/odom', 50)
    rois = []
    io.create_subscription(String, f'/{ns}/rois',
                           lambda m: rois.append(decode(m.data, interfaces.Rois)), 50)
    _, info, frame = _camera_msgs()
    state = {'t': T0, 'turn': 0}

    def frame_pair():
        state['turn'] += 1
        if state['turn'] % 5:
            return              # spin_once runs one callback: let the node keep up
        t = state['t']
        stamp = interfaces.Time.from_ns(t)
        pub_info.publish(info)
        odom = Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = t // 10**9, t % 10**9
        odom.pose.pose.orientation.w = 1.0
        pub_odom.publish(odom)
        pub_c.publish(_candidates(stamp))
        pub_i.publish(numpy_to_image(frame, 'bgr8', stamp=stamp, frame_id='camera'))
        state['t'] += 100_000_000

    assert ros.spin_until(lambda: len(rois) >= 8, each=frame_pair, timeout=20), len(rois)
    assert ros.spin_until(lambda: False, each=frame_pair, timeout=0.5) is False
    state['t'] = T0 - 40_000_000_000                      # the bag starts over
    n = len(rois)

    def second_pass():
        return [r for r in rois[n:] if r.header.stamp.to_ns() < T0 - 30_000_000_000
                and r.rois]

    assert ros.spin_until(lambda: len(second_pass()) >= 5, each=frame_pair, timeout=20), \
        (len(rois) - n, proj.topic_stats())
    assert proj.time_jumps == 1
    assert proj._poses.span()[1] < T0                    # the new pass's poses are kept


def _signs(t_ns, key='road_work_ahead', k=0):
    from workzone_ros.interfaces import Box, Header, Sign, Signs, Time, encode
    sign = Sign(box=Box(x=400, y=200, w=20 + k, h=20 + k), class_key=key, code='W20-1',
                category='workzone', score=0.95, track_id=3,
                probabilities={key: 0.95, 'background': 0.05},
                distance_m=max(5.0, 120.0 - 2.0 * k), distance_source='size')
    return encode(Signs(header=Header(stamp=Time.from_ns(t_ns), frame_id='camera'),
                        signs=[sign]))


def test_fusion_restarts_unknown_at_the_jump_before_any_sign(ros):
    ros.add(FusionNode(context=ros.context, parameter_overrides=[
        Parameter('signs_topic', value='/jumpf/signs'),
        Parameter('odom_topic', value='/jumpf/odom'),
        Parameter('state_topic', value='/jumpf/state'),
        Parameter('camera_info_topic', value=''), Parameter('lidar_topic', value=''),
        Parameter('detections_topic', value='')], **FAST))
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    io = ros.node('jumpf_io')
    pub_s = io.create_publisher(String, '/jumpf/signs', 10)
    pub_o = io.create_publisher(Odometry, '/jumpf/odom', 50)
    states = []
    io.create_subscription(String, '/jumpf/state',
                           lambda m: states.append(decode(m.data, WorkzoneState)),
                           QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE,
                                      durability=DurabilityPolicy.TRANSIENT_LOCAL))
    state = {'t': T0, 'k': 0, 'signs': True}

    def feed():
        t = state['t']
        odom = Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = t // 10**9, t % 10**9
        odom.pose.pose.position.x = 2.0 * state['k']
        odom.pose.pose.orientation.w = 1.0
        pub_o.publish(odom)
        if state['signs']:
            pub_s.publish(String(data=_signs(t, k=state['k'])))
        state['t'] += 66_666_667
        state['k'] += 1

    assert ros.spin_until(lambda: states and states[-1].phase == 'approaching', each=feed,
                          timeout=20)
    state.update(t=T0 - 40_000_000_000, k=0, signs=False)    # loop; nothing in view yet
    n = len(states)
    assert ros.spin_until(lambda: any(s.phase == 'unknown' for s in states[n:]), each=feed,
                          timeout=10)
    after = states[n:]
    first_unknown = next(i for i, s in enumerate(after) if s.phase == 'unknown')
    assert all(s.phase != 'none' for s in after)              # never a false none
    assert 'time jumped back' in after[first_unknown].reason


class _Clocked(WorkzoneNode):
    PARAMS = (Param('topic', 'clocked/in', 'input'),)

    def __init__(self, **kwargs):
        super().__init__('clocked', **kwargs)


def test_sim_time_without_clock_waits_and_says_so(ros):
    node = ros.add(_Clocked(context=ros.context, diagnostics_period_s=0.2,
                            parameter_overrides=[Parameter('use_sim_time', value=True)]))
    fusion = ros.add(FusionNode(context=ros.context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('state_topic', value='/simt/state'),
        Parameter('signs_topic', value='/simt/signs')], **FAST))
    io = ros.node('simt_io')
    diags, states = [], []
    io.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 50)
    io.create_subscription(String, '/simt/state',
                           lambda m: states.append(decode(m.data, WorkzoneState)), 10)
    waiting = lambda: [s for d in diags for s in d.status  # noqa: E731
                       if s.name in ('clocked', 'fusion') and 'no /clock yet' in s.message]
    assert ros.spin_until(lambda: {s.name for s in waiting()} == {'clocked', 'fusion'})
    assert all(d.header.stamp.sec > 0 for d in diags)       # never stamped time 0
    assert not node.clock_running() and not states           # the state waits for /clock
    clock = io.create_publisher(Clock, '/clock', 10)
    msg = Clock()
    msg.clock.sec = 1_700_000_000

    def tick():
        msg.clock.nanosec = (msg.clock.nanosec + 50_000_000) % 1_000_000_000
        clock.publish(msg)

    assert ros.spin_until(lambda: states, each=tick, timeout=10)
    assert node.clock_running() and fusion.clock_running()
    assert states[0].phase == 'unknown' and states[0].header.stamp.sec == 1_700_000_000
