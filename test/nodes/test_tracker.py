"""Tests of the ``tracker`` node with real topics (private rclpy context, DDS isolation)."""
from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image
from std_msgs.msg import String

from workzone_ros.core.track import TrackerConfig
from workzone_ros.interfaces import (
    Box,
    Detection,
    Detections,
    Header,
    Sign,
    Signs,
    Time,
    Tracks,
    decode,
    encode,
)
from workzone_ros.nodes.conversions import numpy_to_image, time_to_stamp
from workzone_ros.nodes.tracker import EVALUATION_ONLY, TrackerNode

W, H = 640, 480


def _background():
    rng = np.random.default_rng(0)
    small = rng.integers(60, 180, (H // 8, W // 8, 3)).astype(np.uint8)
    bg = cv2.GaussianBlur(cv2.resize(small, (W, H)), (0, 0), 3)
    hsv = cv2.cvtColor(bg, cv2.COLOR_BGR2HSV)
    hsv[..., 1] //= 3
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)


def _frame(bg, i):
    """An orange diamond (black border, legend) moving right and growing; returns img, box."""
    img = bg.copy()
    cx, cy, size = 280 + 4 * i, 220 - i, 50 * 1.02 ** i
    s = size / 2
    pts = np.array([[cx, cy - s], [cx + s, cy], [cx, cy + s], [cx - s, cy]]) - 0.5
    p = np.round(pts * 16).astype(np.int32)
    cv2.fillConvexPoly(img, p, (0, 110, 245), cv2.LINE_AA, 4)
    cv2.polylines(img, [p], True, (20, 20, 20), 2, cv2.LINE_AA, 4)
    cv2.putText(img, 'WORK', (int(cx - s / 2), int(cy + 5)), cv2.FONT_HERSHEY_SIMPLEX,
                size / 120, (20, 20, 20), 2, cv2.LINE_AA)
    return img, (cx - s, cy - s, size, size)


def _iou(b, g):
    iw = min(b.x + b.w, g[0] + g[2]) - max(b.x, g[0])
    ih = min(b.y + b.h, g[1] + g[3]) - max(b.y, g[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    return iw * ih / (b.w * b.h + g[2] * g[3] - iw * ih)


def _run(ros, overrides, frames=12, detect=lambda i: i < 3, detections_first=False,
         each=None):
    """Frames through the node; ``each(node, peer, i, tracks)`` runs after frame i's tracks."""
    node = ros.add(TrackerNode(context=ros.context, parameter_overrides=overrides))
    peer = ros.add(rclpy.create_node('tracker_test_peer', context=ros.context))
    img_pub = peer.create_publisher(Image, '/camera/image_raw',
                                    QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    det_pub = peer.create_publisher(String, '/workzone/detections', 10)
    got: dict[int, Tracks] = {}
    peer.create_subscription(String, '/workzone/tracks',
                             lambda m: got.__setitem__(decode(m.data, Tracks).header.stamp
                                                       .to_ns(), decode(m.data, Tracks)), 10)
    assert ros.spin_until(lambda: img_pub.get_subscription_count() > 0
                          and det_pub.get_subscription_count() > 0
                          and node.count_publishers('/workzone/tracks') > 0)
    assert ros.spin_until(lambda: node.count_subscribers('/workzone/tracks') > 0)
    bg = _background()
    gts = {}
    for i in range(frames):
        img, gt = _frame(bg, i)
        t = Time(sec=100 + i // 15, nanosec=(i % 15) * 66_666_666)
        gts[t.to_ns()] = (i, gt)
        header = Header(stamp=t, frame_id='camera')
        dets = Detections(header=header, detections=[
            Detection(box=Box(x=gt[0], y=gt[1], w=gt[2], h=gt[3]), confidence=0.9)
        ] if detect(i) else [])
        image = numpy_to_image(img, 'bgr8', stamp=time_to_stamp(t), frame_id='camera')
        pubs = [lambda: det_pub.publish(String(data=encode(dets))),
                lambda: img_pub.publish(image)]
        for p in (pubs if detections_first else pubs[::-1]):
            p()
        assert ros.spin_until(lambda: t.to_ns() in got), f'no tracks for frame {i}'
        if each is not None:
            each(node, peer, i, got[t.to_ns()])
    return node, got, gts


def test_tracker_node_runs_on_detector_misses(ros):
    node, got, gts = _run(ros, [])
    assert len(got) == len(gts)
    for ns, tracks in got.items():
        i, gt = gts[ns]
        assert tracks.header.frame_id == 'camera'
        assert len(tracks.tracks) == 1, f'frame {i}'
        tr = tracks.tracks[0]
        assert tr.track_id == 1
        assert tr.source == ('detection' if i < 3 else 'tracking')
        assert tr.hits == min(i + 1, 3) and tr.age == i + 1
        assert _iou(tr.box, gt) > 0.75, f'frame {i}: {tr.box} vs {gt}'
        assert 0.75 <= tr.similarity <= 1.0


def test_tracker_node_detections_before_images_and_missed_frames(ros):
    node, got, gts = _run(ros, [], frames=8, detect=lambda i: i % 2 == 0,
                          detections_first=True)
    assert len(got) == len(gts)
    for ns, tracks in got.items():
        i, gt = gts[ns]
        assert len(tracks.tracks) == 1, f'frame {i}'
        tr = tracks.tracks[0]
        assert tr.track_id == 1                            # the id survives a missed frame
        assert tr.source == ('detection' if i % 2 == 0 else 'tracking')
        assert _iou(tr.box, gt) > 0.75, f'frame {i}: {tr.box} vs {gt}'


def test_tracker_node_has_no_evaluation_switches(ros):
    node = ros.add(TrackerNode(context=ros.context))
    for name in ('mode', 'method', 'association'):
        assert not node.has_parameter(name)
    assert node.params.iou_gate == TrackerConfig().iou_gate


def _malformed_is_dropped(ros, node, topic, peer_name):
    """Publish a payload of another schema on ``topic`` until ``node`` counts it dropped,
    with the reason."""
    peer = ros.add(rclpy.create_node(peer_name, context=ros.context))
    pub = peer.create_publisher(String, topic, 10)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0)
    assert ros.spin_until(lambda: (pub.publish(String(data='{"schema": "nope"}')),
                                   node.topic_stats()[topic].dropped >= 1)[1])
    assert 'schema' in node.topic_stats()[topic].last_drop_reason


def test_tracker_node_drops_malformed_detections(ros):
    node = ros.add(TrackerNode(context=ros.context))
    _malformed_is_dropped(ros, node, '/workzone/detections', 'tracker_bad_peer')


def test_tracker_node_parameters_are_the_tracker_config(ros):
    """Every TrackerConfig field but the evaluation's switches is a node parameter (default,
    description, range from its knob); out-of-range changes are rejected and accepted ones
    reach the tracker."""
    node = ros.add(TrackerNode(context=ros.context))
    core = TrackerConfig()
    for f in dataclasses.fields(TrackerConfig):
        if f.name in EVALUATION_ONLY:
            continue
        want = 0.0 if f.name == 'min_approach_speed' else getattr(core, f.name)  # node: off
        got = getattr(node.params, f.name)
        assert got == want, f.name
        desc = node.describe_parameter(f.name)
        assert desc.description.startswith(f.metadata['doc']), f.name
    assert dataclasses.replace(node._tracker.config, min_approach_speed=10.0) == core

    def reason(name, value):
        result = node.set_parameters([Parameter(name, value=value)])[0]
        return None if result.successful else result.reason

    assert 'out of range' in reason('min_similarity', 1.5)
    assert 'out of range' in reason('hue_bins', 1)
    assert reason('min_similarity', 0.6) is None and reason('max_lost_frames', 4) is None
    assert node._tracker.config.min_similarity == 0.6
    assert node._tracker.config.max_lost_frames == 4


@pytest.mark.parametrize('answer', ['sign', 'unknown', 'background'])
def test_tracker_node_runs_on_its_own_only_on_tracks_the_classifier_confirmed(ros, answer):
    """One detection (frame 0), then none: the classifier's Signs for frame 0 on
    ``/workzone/signs`` confirm the track (a work-zone sign with its id: published while it
    runs on its own), say nothing on it (``unknown``, a box too small: one detection is not
    enough) or reject it (no sign for its id: the classifier did not publish a background
    answer; not published until a new detection)."""
    def classify(node, peer, i, tracks):
        if i:
            return
        pub = peer.create_publisher(String, '/workzone/signs', 10)
        assert ros.spin_until(lambda: pub.get_subscription_count() > 0)
        [tr] = tracks.tracks
        signs = {'sign': [Sign(box=tr.box, class_key='road_work_ahead', code='W20-1',
                               category='workzone', score=0.9, track_id=tr.track_id)],
                 'unknown': [Sign(box=tr.box, class_key='unknown', code='-',
                                  category='unknown', score=0.0, track_id=tr.track_id)],
                 'background': []}[answer]
        pub.publish(String(data=encode(Signs(header=tracks.header, signs=signs))))
        assert ros.spin_until(lambda: node._tracker._verdicts.active)
        assert node.counts == {'confirmed': int(answer == 'sign'),
                               'rejected': int(answer == 'background')}

    node, got, gts = _run(ros, [], frames=5, detect=lambda i: i == 0, each=classify)
    alone = {gts[ns][0]: [t.source for t in tr.tracks] for ns, tr in got.items()}
    assert alone[0] == ['detection']
    for i in range(1, 5):
        assert alone[i] == (['tracking'] if answer == 'sign' else []), (i, alone)
    assert node._tracker.active_ids == [1]


def test_tracker_node_drops_malformed_signs_and_can_do_without_them(ros):
    """A malformed Signs payload is dropped and counted, never a crash; ``signs_topic``
    empty: no subscription (the previous rule)."""
    node = ros.add(TrackerNode(context=ros.context))
    _malformed_is_dropped(ros, node, '/workzone/signs', 'tracker_bad_signs_peer')
    assert not node._tracker._verdicts.active
    quiet = ros.add(TrackerNode(context=ros.context, namespace='quiet',
                                parameter_overrides=[Parameter('signs_topic', value='')]))
    assert quiet._signs_sub is None and '/quiet/workzone/signs' not in quiet.topic_stats()


def test_tracker_node_counts_detections_it_cannot_pair_with_an_image(ros):
    """Detections that come more than ``image_buffer`` images late, or whose image never
    came, are dropped with the reason (``/diagnostics``), not lost silently; the frames that
    pair are tracked."""
    node = ros.add(TrackerNode(context=ros.context, parameter_overrides=[
        Parameter('image_buffer', value=2)]))
    peer = ros.add(rclpy.create_node('tracker_late_peer', context=ros.context))
    img_pub = peer.create_publisher(Image, '/camera/image_raw',
                                    QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    det_pub = peer.create_publisher(String, '/workzone/detections', 10)
    got = []
    peer.create_subscription(String, '/workzone/tracks', got.append, 10)
    assert ros.spin_until(lambda: img_pub.get_subscription_count() > 0
                          and det_pub.get_subscription_count() > 0
                          and node.count_subscribers('/workzone/tracks') > 0)
    bg = _background()
    stamps = [Time(sec=100, nanosec=i * 66_666_666) for i in range(6)]
    dets = [Detections(header=Header(stamp=t, frame_id='camera')) for t in stamps]

    def stats(topic):
        return node.topic_stats()[topic]

    for i in (0, 1, 2, 3):                  # four images; the ring keeps the last two
        image = numpy_to_image(_frame(bg, i)[0], 'bgr8', stamp=time_to_stamp(stamps[i]))
        img_pub.publish(image)
        assert ros.spin_until(lambda: stats('/camera/image_raw').messages == i + 1)
    det_pub.publish(String(data=encode(dets[0])))       # its image left the ring
    assert ros.spin_until(lambda: stats('/workzone/detections').dropped == 1)
    assert 'left the buffer' in stats('/workzone/detections').last_drop_reason
    det_pub.publish(String(data=encode(dets[4])))       # its image never comes
    det_pub.publish(String(data=encode(dets[5])))
    img_pub.publish(numpy_to_image(_frame(bg, 5)[0], 'bgr8', stamp=time_to_stamp(stamps[5])))
    assert ros.spin_until(lambda: len(got) == 1)
    assert decode(got[0].data, Tracks).header.stamp == stamps[5]
    assert stats('/workzone/detections').dropped == 2
    assert 'no image' in stats('/workzone/detections').last_drop_reason
