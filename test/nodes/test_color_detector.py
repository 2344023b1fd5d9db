"""color_detector node over real topics: image (+ ROIs) in, stamped Detections out."""
import time

import cv2
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import String

from workzone_ros import interfaces
from workzone_ros.core import color_model as cm
from workzone_ros.interfaces import Box, Roi, Rois
from workzone_ros.nodes.base import ConfigError
from workzone_ros.nodes.color_detector import LEAN_KEY, ColorDetectorNode
from workzone_ros.nodes.conversions import (
    CameraInfoData,
    make_header,
    numpy_to_camera_info,
    numpy_to_image,
    payload_to_string,
)

ORANGE = (0, 110, 245)


def _frame(sign=True):
    img = np.empty((480, 640, 3), np.uint8)
    img[:240] = (205, 175, 150)
    img[240:] = (85, 88, 84)
    if sign:
        pts = np.array([[420, 110], [460, 150], [420, 190], [380, 150]], np.int32)
        cv2.fillConvexPoly(img, pts, ORANGE)
        inner = np.array([[420, 114], [456, 150], [420, 186], [384, 150]], np.int32)
        cv2.polylines(img, [inner], True, (22, 22, 22), 2)            # border and legend:
        cv2.putText(img, 'RW', (404, 157), cv2.FONT_HERSHEY_DUPLEX, 0.6, (22, 22, 22), 2)
    return img


@pytest.fixture
def model_path(tmp_path):
    path = tmp_path / 'color_orange.npz'
    cm.save_model(cm.default_model(), path)        # Cahail et al. ranges: no training needed
    return str(path)


def _node(ros, model_path, **params):
    overrides = [Parameter('model_path', value=model_path), Parameter('use_prior', value=False)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    return ros.add(ColorDetectorNode(context=ros.context, parameter_overrides=overrides,
                                     diagnostics_period_s=0.2))


def test_image_in_detections_out_with_and_without_rois(ros, model_path):
    _node(ros, model_path, image_topic='t/image', rois_topic='t/rois',
          detections_topic='t/dets')
    peer = ros.add(rclpy.create_node('peer', context=ros.context))
    img_pub = peer.create_publisher(Image, 't/image', QoSProfile(
        depth=5, reliability=ReliabilityPolicy.RELIABLE))
    rois_pub = peer.create_publisher(String, 't/rois', 10)
    got = []
    peer.create_subscription(String, 't/dets', got.append, 10)

    # 1. no LiDAR at all: colour alone
    h1 = make_header(stamp=interfaces.Time(sec=10, nanosec=5), frame_id='camera')
    msg1 = numpy_to_image(_frame(), 'bgr8', h1)
    assert ros.spin_until(lambda: got, each=lambda: img_pub.publish(msg1))
    d = interfaces.decode(got[-1].data, interfaces.Detections)
    assert d.header.stamp == interfaces.Time(sec=10, nanosec=5)
    assert d.header.frame_id == 'camera'
    assert len(d.detections) == 1 and d.detections[0].sources == ['color']
    assert d.detections[0].box.iou(Box(380, 110, 81, 81)) > 0.8

    # 2. ROIs with the exact image stamp arrive first: the detection is LiDAR-supported
    t2 = interfaces.Time(sec=11, nanosec=0)
    roi = Roi(candidate_id=42, box=Box(370, 100, 100, 100), center=(420, 150), range_m=30.0,
              radius_m=0.6, position=(2.0, -1.0, 30.0))
    rois_pub.publish(payload_to_string(Rois(header=interfaces.Header(stamp=t2), rois=[roi])))
    ros.spin_until(lambda: False, timeout=0.5)
    msg2 = numpy_to_image(_frame(), 'bgr8', make_header(stamp=t2))

    def fused():
        ds = [interfaces.decode(m.data, interfaces.Detections) for m in got]
        return [x for x in ds if x.header.stamp == t2 and x.detections
                and x.detections[0].sources == ['color', 'lidar']]
    assert ros.spin_until(lambda: fused(), each=lambda: img_pub.publish(msg2))
    assert fused()[0].detections[0].roi_id == 42

    # 3. an empty frame gives an empty Detections, not silence
    t3 = interfaces.Time(sec=12, nanosec=0)
    msg3 = numpy_to_image(_frame(sign=False), 'bgr8', make_header(stamp=t3))

    def empty():
        ds = [interfaces.decode(m.data, interfaces.Detections) for m in got]
        return [x for x in ds if x.header.stamp == t3]
    assert ros.spin_until(lambda: empty(), each=lambda: img_pub.publish(msg3))
    assert empty()[0].detections == []


def test_bad_rois_are_dropped_not_fatal(ros, model_path):
    node = _node(ros, model_path, image_topic='u/image', rois_topic='u/rois',
                 detections_topic='u/dets')
    peer = ros.add(rclpy.create_node('peer2', context=ros.context))
    rois_pub = peer.create_publisher(String, 'u/rois', 10)
    assert ros.spin_until(lambda: any(s.dropped for s in node.topic_stats().values()),
                          each=lambda: rois_pub.publish(String(data='{"schema": "nope"}')))


def test_missing_model_file_is_a_config_error(ros, tmp_path):
    with pytest.raises(ConfigError, match='does not exist'):
        _node(ros, str(tmp_path / 'missing.npz'))


def test_live_parameter_change_rebuilds_detector(ros, model_path):
    node = _node(ros, model_path)
    assert node.set_parameters([Parameter('method', value='hsv')])[0].successful
    assert node._detector.config.method == 'hsv'
    assert not node.set_parameters([Parameter('method', value='cnn')])[0].successful
    assert node._detector.config.blur_fit
    assert node.set_parameters([Parameter('blur_fit', value=False)])[0].successful
    assert not node._detector.config.blur_fit
    assert node._detector.config.outline_evidence
    assert node.set_parameters([Parameter('outline_evidence', value=False)])[0].successful
    assert not node._detector.config.outline_evidence
    assert node._detector.config.rect_needs_edges
    assert node.set_parameters([Parameter('rect_needs_edges', value=False)])[0].successful
    assert not node._detector.config.rect_needs_edges
    assert node._detector.config.v_hysteresis == 0.65
    assert node.set_parameters([Parameter('v_hysteresis', value=0.0)])[0].successful
    assert node._detector.config.v_hysteresis == 0.0
    assert not node.set_parameters([Parameter('v_hysteresis', value=1.5)])[0].successful
    assert node._detector.config.grow_level == 0.85
    assert node.set_parameters([Parameter('grow_level', value=0.0)])[0].successful
    assert node._detector.config.grow_level == 0.0
    assert not node.set_parameters([Parameter('grow_level', value=-0.1)])[0].successful


def test_image_waits_for_late_rois(ros, model_path):
    """The projector publishes an image's ROIs after the image: the node holds the image
    (bounded by rois_wait) and the detection is LiDAR-supported."""
    node = _node(ros, model_path, image_topic='w/image', rois_topic='w/rois',
                 detections_topic='w/dets', rois_wait=2.0)
    peer = ros.add(rclpy.create_node('peer3', context=ros.context))
    img_pub = peer.create_publisher(Image, 'w/image', QoSProfile(
        depth=5, reliability=ReliabilityPolicy.RELIABLE))
    rois_pub = peer.create_publisher(String, 'w/rois', 10)
    got = []
    peer.create_subscription(String, 'w/dets', got.append, 10)
    assert ros.spin_until(lambda: node.count_publishers('w/rois') > 0
                          and img_pub.get_subscription_count() > 0
                          and rois_pub.get_subscription_count() > 0)
    t = interfaces.Time(sec=20, nanosec=0)
    img_pub.publish(numpy_to_image(_frame(), 'bgr8', make_header(stamp=t)))
    assert ros.spin_until(lambda: node._pending, timeout=5.0)       # held, not processed
    sent = time.monotonic()
    ros.spin_until(lambda: False, timeout=0.1)                       # ROIs 100 ms later
    assert not got
    roi = Roi(candidate_id=5, box=Box(370, 100, 100, 100), center=(420, 150), range_m=30.0,
              radius_m=0.6, position=(2.0, -1.0, 30.0))
    rois_pub.publish(payload_to_string(Rois(header=interfaces.Header(stamp=t), rois=[roi])))
    assert ros.spin_until(lambda: got, timeout=5.0)
    assert time.monotonic() - sent < 2.0                  # on ROI arrival, not on expiry
    d = interfaces.decode(got[-1].data, interfaces.Detections)
    assert d.header.stamp == t and len(d.detections) == 1
    assert 'lidar' in d.detections[0].sources and d.detections[0].roi_id == 5

    # ROIs that never come: the image goes on colour alone once rois_wait expires
    node.set_parameters([Parameter('rois_wait', value=0.3)])
    t2 = interfaces.Time(sec=21, nanosec=0)
    img_pub.publish(numpy_to_image(_frame(), 'bgr8', make_header(stamp=t2)))

    def late():
        ds = [interfaces.decode(m.data, interfaces.Detections) for m in got]
        return [x for x in ds if x.header.stamp == t2]
    assert ros.spin_until(lambda: late(), timeout=5.0)
    assert late()[0].detections[0].sources == ['color']
    # /diagnostics says how each held image's wait ended
    figures = dict(node.extra_diagnostics())
    assert figures['images held: matched'] == '1' and figures['images held: expired'] == '1'


def test_no_rois_publisher_means_no_wait(ros, model_path):
    node = _node(ros, model_path, image_topic='v/image', rois_topic='v/rois',
                 detections_topic='v/dets', rois_wait=5.0)
    peer = ros.add(rclpy.create_node('peer4', context=ros.context))
    img_pub = peer.create_publisher(Image, 'v/image', QoSProfile(
        depth=5, reliability=ReliabilityPolicy.RELIABLE))
    got = []
    peer.create_subscription(String, 'v/dets', got.append, 10)
    msg = numpy_to_image(_frame(), 'bgr8', make_header(stamp=interfaces.Time(sec=3)))
    start = time.monotonic()
    assert ros.spin_until(lambda: got, timeout=4.0, each=lambda: img_pub.publish(msg))
    assert time.monotonic() - start < 4.0 and not node._pending


def test_camera_info_decides_whether_the_model_prior_applies(ros, tmp_path):
    """The model's fixed-camera prior applies to its own camera's frames only: CameraInfo
    of the training camera keeps it, another lens at the same 640x480 size does not, and an
    invalid CameraInfo is dropped with the last valid intrinsics kept."""
    path = tmp_path / 'cam.npz'
    cam = dict(width=640, height=480, fx=554.3, fy=554.3, cx=320.0, cy=240.0)
    cm.save_model(cm.default_model(metadata={'camera': cam}), path)
    node = _node(ros, str(path), use_prior=True, camera_info_topic='c/info')
    peer = ros.add(rclpy.create_node('peer_info', context=ros.context))
    pub = peer.create_publisher(CameraInfo, 'c/info', 10)

    def info(fx):
        return numpy_to_camera_info(CameraInfoData(640, 480, np.array(
            [[fx, 0, 320.0], [0, fx, 240.0], [0, 0, 1]])))

    assert node._detector.same_camera(640, 480)            # no CameraInfo yet: by size
    assert ros.spin_until(lambda: node._intrinsics is not None,
                          each=lambda: pub.publish(info(554.3)))
    assert node._detector.same_camera(640, 480)
    assert ros.spin_until(lambda: not node._detector.same_camera(640, 480),
                          each=lambda: pub.publish(info(320.0)))     # a wide-angle lens
    # a live parameter change keeps the camera
    assert node.set_parameters([Parameter('threshold', value=0.6)])[0].successful
    assert not node._detector.same_camera(640, 480)
    bad = info(320.0)
    bad.k = [0.0] * 9
    assert ros.spin_until(lambda: any(s.dropped for s in node.topic_stats().values()),
                          each=lambda: pub.publish(bad))
    assert node._intrinsics[0] == 320.0


def test_proposals_on_another_camera_reach_the_classifier_flagged(ros, model_path):
    """With ``rules: auto``, a frame of another camera than the colour model's gets the
    recall-first candidates (flagged ``proposal``) and no rule-checked detections; the
    payload's channelizer count is then unknown (None), not a stale number."""
    _node(ros, model_path, image_topic='p/image', detections_topic='p/dets', rules='auto')
    peer = ros.add(rclpy.create_node('peer', context=ros.context))
    pub = peer.create_publisher(Image, 'p/image', QoSProfile(
        depth=5, reliability=ReliabilityPolicy.RELIABLE))
    got = []
    peer.create_subscription(String, 'p/dets', got.append, 10)
    img = cv2.resize(_frame(), (722, 406))               # a phone clip's frame size
    msg = numpy_to_image(img, 'bgr8', make_header(stamp=interfaces.Time(sec=3, nanosec=0)))
    assert ros.spin_until(lambda: got, each=lambda: pub.publish(msg))
    d = interfaces.decode(got[-1].data, interfaces.Detections)
    assert d.detections and all(x.proposal for x in d.detections)
    assert max(x.box.iou(Box(429, 93, 90, 68)) for x in d.detections) > 0.5
    assert d.channelizers is None


def _detections_of(ros, img, **params):
    """A node with ``params`` and the Detections payload it publishes for one image."""
    node = _node(ros, params.pop('model_path'), image_topic='q/image',
                 detections_topic='q/dets', **params)
    peer = ros.add(rclpy.create_node('peer', context=ros.context))
    pub = peer.create_publisher(Image, 'q/image', QoSProfile(
        depth=5, reliability=ReliabilityPolicy.RELIABLE))
    got = []
    peer.create_subscription(String, 'q/dets', got.append, 10)
    msg = numpy_to_image(img, 'bgr8', make_header(stamp=interfaces.Time(sec=3, nanosec=0)))
    assert ros.spin_until(lambda: got, each=lambda: pub.publish(msg))
    return node, interfaces.decode(got[-1].data, interfaces.Detections)


def _patched_frame():
    frame = _frame()
    frame[300:360, 80:130] = ORANGE                 # an orange patch no shape rule boxes
    return frame


def test_by_default_another_camera_gets_proposals_beside_the_rule_checked_detections(
        ros, model_path):
    """With the defaults, a frame of another camera than the colour model's gets the rule-
    checked detection of its sign (not flagged; the rules measured lean beside the proposals,
    which is not counted as falling behind) and proposals elsewhere, never a proposal
    repeating the detection's box."""
    node, d = _detections_of(ros, cv2.resize(_patched_frame(), (722, 406)),
                             model_path=model_path)
    figures = dict(node.extra_diagnostics())
    assert figures[LEAN_KEY] == '0' and node._detector.lean
    assert figures['stages'] == 'rules (lean) + proposals'
    rules = [x for x in d.detections if not x.proposal]
    assert len(rules) == 1 and rules[0].box.iou(Box(429, 93, 90, 68)) > 0.5
    assert any(x.proposal for x in d.detections)
    assert all(x.box.iou(rules[0].box) < 0.5 for x in d.detections if x.proposal)
    assert d.channelizers is not None


@pytest.mark.parametrize('mode,flagged', [('auto', False), ('on', True)])
def test_the_models_own_camera_gets_proposals_only_when_asked(ros, model_path, mode, flagged):
    """On the colour model's own camera (its frame size here) the rule-based detector alone
    runs unless ``proposals`` is on."""
    node, d = _detections_of(ros, _patched_frame(), model_path=model_path, proposals=mode)
    assert dict(node.extra_diagnostics())['stages'] == (
        'rules (lean) + proposals' if flagged else 'rules')
    assert any(not x.proposal for x in d.detections)
    assert any(x.proposal for x in d.detections) == flagged


def test_a_boolean_proposals_value_is_a_one_line_error_that_says_to_quote_it(ros, model_path):
    with pytest.raises(ConfigError, match="proposals must be one of 'auto', 'on', 'off'.*quote"):
        _node(ros, model_path, proposals=True)


def test_a_camera_that_publishes_only_jpeg_works_without_configuration(ros, model_path):
    """``compressed`` left false: no raw image comes, so the compressed stream is used, and
    ``/diagnostics`` says so; a raw stream, once it flows, wins."""
    from sensor_msgs.msg import CompressedImage

    from workzone_ros.nodes.conversions import numpy_to_compressed
    node = _node(ros, model_path, image_topic='j/image', detections_topic='j/dets')
    peer = ros.add(rclpy.create_node('peer', context=ros.context))
    qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
    cpub = peer.create_publisher(CompressedImage, 'j/image/compressed', qos)
    got = []
    peer.create_subscription(String, 'j/dets', got.append, 10)
    msg = numpy_to_compressed(_frame(), 'jpeg', 95,
                              make_header(stamp=interfaces.Time(sec=4, nanosec=0)))
    assert ros.spin_until(lambda: got, each=lambda: cpub.publish(msg))
    d = interfaces.decode(got[-1].data, interfaces.Detections)
    assert len(d.detections) == 1
    values = {kv.key: kv.value for kv in node.diagnostic_status().values}
    assert values['image transport'] == 'compressed (no raw images)'
    rpub = peer.create_publisher(Image, 'j/image', qos)
    raw = numpy_to_image(_frame(), 'bgr8', make_header(stamp=interfaces.Time(sec=5, nanosec=0)))
    assert ros.spin_until(lambda: node._image_transport == 'raw',
                          each=lambda: (rpub.publish(raw), cpub.publish(msg)))


@pytest.mark.parametrize('queue,stamps', [(1, [3]), (3, [1, 2, 3])])
def test_frames_that_arrive_while_busy_are_queued_not_skipped(ros, model_path, queue, stamps):
    """Three frames arrive while the detector is busy (the executor does not spin): with
    ``image_queue`` 3 every one is detected in order, with 1 only the newest is."""
    _node(ros, model_path, image_topic='q/image', rois_topic='', detections_topic='q/dets',
          image_queue=queue)
    peer = ros.add(rclpy.create_node('peer', context=ros.context))
    img_pub = peer.create_publisher(Image, 'q/image', 10)
    got = []
    peer.create_subscription(String, 'q/dets', got.append, 10)
    assert ros.spin_until(lambda: img_pub.get_subscription_count() > 0)
    for sec in (1, 2, 3):
        h = make_header(stamp=interfaces.Time(sec=sec, nanosec=0), frame_id='camera')
        img_pub.publish(numpy_to_image(_frame(), 'bgr8', h))
    time.sleep(0.5)                     # delivered into the subscription's queue meanwhile
    ros.spin_until(lambda: len(got) >= 3, timeout=3.0)
    heads = [interfaces.decode(m.data, interfaces.Detections).header.stamp.sec for m in got]
    assert heads == stamps


@pytest.mark.parametrize('lean_behind,lean', [(1.0, 3), (0.0, 0)])
def test_frames_that_waited_behind_the_camera_are_measured_lean(ros, model_path, lean_behind,
                                                               lean):
    """Frames detected as they come are measured in full; three that arrive while the
    detector is busy wait several frame intervals in its queue and are measured lean
    (``lean_behind`` 1), or in full all the same (0); ``/diagnostics`` counts them."""
    node = _node(ros, model_path, image_topic='l/image', rois_topic='', detections_topic='l/dets',
                 image_queue=5, lean_behind=lean_behind)
    peer = ros.add(rclpy.create_node('peer', context=ros.context))
    img_pub = peer.create_publisher(Image, 'l/image', 10)
    got = []
    peer.create_subscription(String, 'l/dets', got.append, 10)
    assert ros.spin_until(lambda: img_pub.get_subscription_count() > 0)

    def publish(sec):
        h = make_header(stamp=interfaces.Time(sec=sec, nanosec=0), frame_id='camera')
        img_pub.publish(numpy_to_image(_frame(), 'bgr8', h))

    for sec in (1, 2, 3, 4):                # in time: each detected before the next comes
        publish(sec)
        assert ros.spin_until(lambda: len(got) == sec)
        time.sleep(0.05)
    assert node._lean_frames == 0
    for sec in (5, 6, 7):                   # the detector busy: they wait in its queue
        publish(sec)
        time.sleep(0.05)
    time.sleep(0.2)
    assert ros.spin_until(lambda: len(got) == 7)
    values = {kv.key: kv.value for kv in node.diagnostic_status().values}
    assert values[LEAN_KEY] == str(lean) and values['frames detected'] == '7'
