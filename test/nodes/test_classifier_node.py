"""The ``classifier`` node with real topics: a sign crop arriving on a topic is classified, a
frame with no tracks still publishes an empty ``Signs``, a box too small is ``unknown`` with
its reason, and the debug image comes out."""
from __future__ import annotations

import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image
from std_msgs.msg import String

from workzone_ros.core import classifier as core
from workzone_ros.interfaces import Box, Header, Signs, Time, Track, Tracks, decode, encode
from workzone_ros.nodes.classifier import ClassifierNode
from workzone_ros.nodes.conversions import numpy_to_image, time_to_stamp
from workzone_ros.sim.signart import drum_texture, over, sign_face

KEYS = ('road_work_ahead', 'end_road_work', 'background')


def _grey(rng, shape):
    return np.clip(rng.normal(110, 12, shape), 0, 255).astype(np.float32)


def _sign_crop(key, size, rng):
    face = sign_face(key, size)
    pad = max(2, size // 8)
    h, w = face.shape[:2]
    bg = _grey(rng, (h + 2 * pad, w + 2 * pad, 3))
    bg[pad:pad + h, pad:pad + w] = over(face, bg[pad:pad + h, pad:pad + w])
    return np.clip(bg, 0, 255).astype(np.uint8)


def _background_crop(size, rng):
    import cv2
    if rng.random() < 0.5:
        return cv2.resize(np.asarray(drum_texture()), (size, int(size * 1.4)))
    return _grey(rng, (size, size, 3)).astype(np.uint8)


@pytest.fixture(scope='module')
def model_path(tmp_path_factory):
    rng = np.random.default_rng(1)
    crops, labels = [], []
    for _ in range(14):
        for key in KEYS:
            size = int(rng.integers(40, 90))
            crops.append(_background_crop(size, rng) if key == 'background'
                         else _sign_crop(key, size, rng))
            labels.append(key)
    clf = core.fit(crops, labels, KEYS, cv=2, seed=0)
    path = tmp_path_factory.mktemp('model') / 'tiny.npz'
    core.save_model(clf, path)
    return path


def _frame(rng):
    img = _grey(rng, (240, 320, 3))
    face = sign_face('road_work_ahead', 60)
    img[80:140, 200:260] = over(face, img[80:140, 200:260])
    return np.clip(img, 0, 255).astype(np.uint8)


def test_tracks_on_a_topic_become_signs_and_an_empty_frame_an_empty_list(ros, model_path):
    node = ros.add(ClassifierNode(context=ros.context, parameter_overrides=[
        Parameter('model_path', value=str(model_path)), Parameter('min_size', value=10)]))
    peer = ros.add(rclpy.create_node('classifier_test_peer', context=ros.context))
    img_pub = peer.create_publisher(Image, '/camera/image_raw',
                                    QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    trk_pub = peer.create_publisher(String, '/workzone/tracks', 10)
    got: list[Signs] = []
    debug: list[Image] = []
    peer.create_subscription(String, '/workzone/signs',
                             lambda m: got.append(decode(m.data, Signs)), 10)
    peer.create_subscription(Image, '/workzone/debug_image', debug.append,
                             QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT))
    assert ros.spin_until(lambda: img_pub.get_subscription_count() > 0
                          and trk_pub.get_subscription_count() > 0
                          and node.count_subscribers('/workzone/signs') > 0)
    rng = np.random.default_rng(5)
    for k, tracks in enumerate((
            [Track(track_id=7, box=Box(x=200, y=80, w=60, h=60), source='detection', age=3,
                   hits=3, similarity=1.0),
             Track(track_id=8, box=Box(x=20, y=200, w=6, h=6), source='tracking', age=1,
                   hits=1, similarity=0.9)],
            [])):
        t = Time(sec=50, nanosec=k * 66_666_667)
        header = Header(stamp=t, frame_id='camera')
        img = numpy_to_image(_frame(rng), 'bgr8', stamp=time_to_stamp(t), frame_id='camera')
        img_pub.publish(img)
        trk_pub.publish(String(data=encode(Tracks(header=header, tracks=tracks))))
        assert ros.spin_until(lambda k=k: len(got) > k), f'no Signs for frame {k}'
    first, second = got
    by_id = {s.track_id: s for s in first.signs}
    assert by_id[7].class_key == 'road_work_ahead' and by_id[7].code == 'W20-1'
    assert by_id[7].category == 'workzone' and by_id[7].score > 0.5
    assert set(by_id[7].probabilities) == set(KEYS)
    # 60 px box of a 1.70 m diamond box on a 60 deg, 320 px camera: ~7.9 m
    assert by_id[7].distance_source == 'size' and 6.0 < by_id[7].distance_m < 10.0
    assert by_id[8].class_key == 'unknown' and 'min_size' in by_id[8].reason
    assert second.signs == [] and second.header.stamp == Time(sec=50, nanosec=66_666_667)
    assert ros.spin_until(lambda: debug, timeout=5)
    assert (debug[0].width, debug[0].height) == (320, 240)


def test_a_missing_model_is_a_one_line_configuration_error(ros, tmp_path):
    from workzone_ros.nodes.base import ConfigError
    with pytest.raises(ConfigError) as err:
        ClassifierNode(context=ros.context, parameter_overrides=[
            Parameter('model_path', value=str(tmp_path / 'missing.npz'))])
    assert 'missing.npz' in str(err.value) and '\n' not in str(err.value)


@pytest.mark.parametrize('general', [True, False])
def test_a_stop_sign_on_the_frame_is_published_as_a_general_sign(ros, model_path, general):
    """General signs come from the whole frame (no track needed) with category ``general``;
    ``general_signs: false`` publishes none and never loads the recogniser."""
    node = ros.add(ClassifierNode(context=ros.context, parameter_overrides=[
        Parameter('model_path', value=str(model_path)), Parameter('general_signs', value=general),
        Parameter('general_every', value=1)]))
    assert (node._general is None) == (not general)
    peer = ros.add(rclpy.create_node('classifier_general_peer', context=ros.context))
    img_pub = peer.create_publisher(Image, '/camera/image_raw',
                                    QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    trk_pub = peer.create_publisher(String, '/workzone/tracks', 10)
    got: list[Signs] = []
    peer.create_subscription(String, '/workzone/signs',
                             lambda m: got.append(decode(m.data, Signs)), 10)
    assert ros.spin_until(lambda: img_pub.get_subscription_count() > 0
                          and trk_pub.get_subscription_count() > 0
                          and node.count_subscribers('/workzone/signs') > 0)
    rng = np.random.default_rng(6)
    img = np.clip(rng.normal(0, 6, (240, 320, 3)) + (70, 120, 80), 0, 255).astype(np.float32)
    img[70:120, 220:270] = over(sign_face('stop', 50), img[70:120, 220:270])
    t = Time(sec=60)
    img_pub.publish(numpy_to_image(np.clip(img, 0, 255).astype(np.uint8), 'bgr8',
                                   stamp=time_to_stamp(t), frame_id='camera'))
    trk_pub.publish(String(data=encode(Tracks(header=Header(stamp=t, frame_id='camera'),
                                              tracks=[]))))
    assert ros.spin_until(lambda: got), 'no Signs'
    general_found = [s for s in got[0].signs if s.category == 'general']
    if general:
        assert [s.class_key for s in general_found] == ['stop'], got[0].signs
        assert general_found[0].box.iou(Box(x=220, y=70, w=50, h=50)) > 0.5
    else:
        assert general_found == []
