"""Tests of workzone_ros.nodes.base with real rclpy nodes over DDS (private contexts)."""
import array
import dataclasses

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image

from workzone_ros.nodes.base import ConfigError, InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.conversions import ConversionError, image_to_numpy, numpy_to_image

FAST = dict(diagnostics_period_s=0.2, silent_input_warn_s=0.6)


class ProbeNode(WorkzoneNode):
    """A tiny node: converts images from a sensor topic and keeps their shapes."""

    PARAMS = (
        Param('image_topic', 'probe/image', 'input image topic'),
        Param('threshold', 0.5, 'a score threshold', min=0.0, max=1.0),
        Param('count', 3, 'an integer', min=1, max=10),
        Param('mode', 'fast', 'a mode', choices=('fast', 'slow')),
        Param('frame', 'camera', 'fixed at start-up', read_only=True),
        Param('gains', [1.0, 2.0], 'a float list'),
    )
    INPUT_TOPICS = ('image_topic',)

    def __init__(self, **kwargs):
        super().__init__('probe', **kwargs)
        self.shapes = []
        self._image_sub = self.sensor_subscription(Image, self.params.image_topic,
                                                   self._on_image)

    def _on_image(self, msg):
        img = image_to_numpy(msg)
        if img.shape[1] == 13:
            raise KeyError('unlucky width')          # a bug in the node, not bad input
        self.shapes.append(img.shape)


def _values(status: DiagnosticStatus) -> dict:
    return {kv.key: kv.value for kv in status.values}


def _bad_image(kind):
    msg = Image(height=4, width=5, encoding='bgr8', step=15)
    if kind == 'short':
        msg.data = array.array('B', bytes(59))
    else:
        msg.encoding = 'yuv422'
        msg.data = array.array('B', bytes(60))
    return msg


def test_bad_input_is_counted_and_good_input_processed(ros):
    node = ros.add(ProbeNode(context=ros.context, **FAST))
    peer = ros.node('peer')
    pub = peer.create_publisher(Image, 'probe/image', 10)
    diags = []
    peer.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0)

    good = numpy_to_image(np.zeros((4, 6, 3), 'uint8'))
    buggy = numpy_to_image(np.zeros((2, 13, 3), 'uint8'))

    def publish():
        stats = node.topic_stats()['/probe/image']
        if stats.dropped < 3:
            for msg in (_bad_image('short'), _bad_image('encoding'), buggy):
                pub.publish(msg)
        elif not node.shapes:
            pub.publish(good)

    assert ros.spin_until(lambda: node.shapes, each=publish), 'good image never processed'
    assert node.shapes[0] == (4, 6, 3)

    def reported():
        for d in diags:
            for s in d.status:
                v = _values(s)
                if s.name == 'probe' and int(v.get('/probe/image dropped', 0)) >= 3:
                    return s
        return None

    assert ros.spin_until(lambda: reported() is not None)
    status = reported()
    values = _values(status)
    assert status.hardware_id == 'workzone_ros'
    assert int(values['/probe/image messages']) >= 4
    assert values['/probe/image publishers'] == '1'
    assert values['/probe/image publishers matched'] == '1'    # its own subscription's view
    assert values['/probe/image processing p99 ms'] != ''
    assert float(values['/probe/image age of last input s']) < 5.0
    warned = [s for d in diags for s in d.status if s.level == DiagnosticStatus.WARN]
    assert warned and 'dropped on /probe/image' in warned[0].message
    reasons = {node.topic_stats()['/probe/image'].last_drop_reason, values[
        '/probe/image last drop reason']}
    assert any('step*height' in r or 'not supported' in r or 'internal error: KeyError' in r
               for r in reasons)
    # the node survived an internal error; it is counted with its type
    assert node._traceback_logged == {'/probe/image:KeyError'}
    # after a quiet period with good input the level returns to OK
    diags.clear()
    assert ros.spin_until(lambda: any(s.level == DiagnosticStatus.OK
                                      for d in diags for s in d.status),
                          each=lambda: pub.publish(good))


def test_explicit_drop_and_throttled_warning(ros):
    node = ros.add(ProbeNode(context=ros.context, **FAST))
    for _ in range(5):
        node.drop('probe/image', 'camera_info missing')
    stats = node.topic_stats()['/probe/image']
    assert (stats.dropped, stats.last_drop_reason) == (5, 'camera_info missing')
    assert node._throttle._suppressed['drop:/probe/image:camera_info missing'] == 4
    assert isinstance(ConversionError('x'), InputError)


def test_parameter_validation_on_set(ros):
    node = ros.add(ProbeNode(context=ros.context, **FAST))
    assert node.params.threshold == 0.5 and node.params.gains == (1.0, 2.0)

    def reason(name, value):
        result = node.set_parameters([Parameter(name, value=value)])[0]
        return None if result.successful else result.reason

    # ranges are checked by rclpy from the descriptor, then by the base (ints for floats)
    assert 'threshold out of range Min: 0.0, Max: 1.0' in reason('threshold', 1.5)
    assert 'threshold = 2 is above the maximum 1.0' in reason('threshold', 2)
    assert 'count out of range. Min: 1, Max: 10' in reason('count', 0)
    assert 'Wrong parameter type' in reason('count', 2.5)
    assert "'medium' is not one of 'fast', 'slow'" in reason('mode', 'medium')
    assert 'must be float' in reason('threshold', 'high')
    assert 'read-only' in reason('frame', 'base_link')
    assert reason('threshold', 1) is None              # an int is fine for a float
    assert node.params.threshold == 1.0 and isinstance(node.params.threshold, float)
    assert reason('gains', [3, 4]) is None
    assert node.params.gains == (3.0, 4.0)
    assert node.params.count == 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        node.params.count = 4                            # frozen
    desc = node.describe_parameter('threshold')
    assert desc.floating_point_range[0].to_value == 1.0 and 'threshold' in desc.description


def test_invalid_override_fails_start_up(ros):
    with pytest.raises(ConfigError, match='above the maximum'):
        ProbeNode(context=ros.context, parameter_overrides=[Parameter('threshold', value=7.0)])


def test_params_file_undeclared_keys_are_reported(ros, tmp_path):
    path = tmp_path / 'params.yaml'
    path.write_text(
        'probe:\n'
        '  ros__parameters:\n'
        '    threshold: 0.7\n'
        '    treshold: 0.8\n'
        '    nested:\n'
        '      key: 1\n'
        '/**:\n'
        '  ros__parameters:\n'
        '    use_sim_time: false\n'
        '    global_thing: 1\n'
        'other_node:\n'
        '  ros__parameters:\n'
        '    not_ours: 1\n')
    node = ros.add(ProbeNode(context=ros.context,
                             cli_args=['--ros-args', '--params-file', str(path)],
                             parameter_overrides=[Parameter('bogus', value=1)], **FAST))
    assert node.params.threshold == 0.7
    text = '\n'.join(node.config_warnings)
    assert "'treshold' is not a parameter of node /probe; it is ignored (did you mean " \
           "'threshold'?)" in text
    assert str(path) in text
    assert "'nested.key'" in text and "'global_thing'" in text and "'bogus'" in text
    assert 'not_ours' not in text and 'use_sim_time' not in text
    assert len(node.config_warnings) == 4


def test_qos_mismatch_is_diagnosed(ros):
    class Listener(WorkzoneNode):
        def __init__(self, **kwargs):
            super().__init__('listener', **kwargs)
            self.got = []
            self.reliable_subscription(Image, 'qos/image', self.got.append)

    node = ros.add(Listener(context=ros.context, **FAST))
    peer = ros.node('qos_peer')
    best_effort = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub = peer.create_publisher(Image, 'qos/image', best_effort)
    diags = []
    peer.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    msg = numpy_to_image(np.zeros((2, 2, 3), 'uint8'))

    def mismatch():
        return [s for d in diags for s in d.status
                if s.name == 'listener' and 'QoS mismatch?' in s.message]

    assert ros.spin_until(mismatch, each=lambda: pub.publish(msg))
    status = mismatch()[0]
    assert status.level == DiagnosticStatus.WARN
    assert status.message == 'publisher(s) on /qos/image but nothing received: QoS mismatch?'
    assert _values(status)['/qos/image publishers'] == '1'
    assert _values(status)['/qos/image messages'] == '0' and not node.got


def test_silent_compatible_publisher_is_not_called_a_qos_mismatch(ros):
    """A publisher with compatible QoS that has sent nothing yet (a replay that has not
    started) is reported as silent, not as a QoS mismatch."""
    class Listener(WorkzoneNode):
        def __init__(self, **kwargs):
            super().__init__('quiet_listener', **kwargs)
            self.reliable_subscription(Image, 'qos/quiet', lambda m: None)

    ros.add(Listener(context=ros.context, **FAST))
    peer = ros.node('quiet_peer')
    peer.create_publisher(Image, 'qos/quiet', QoSProfile(depth=5))
    diags = []
    peer.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)

    def silent():
        return [s for d in diags for s in d.status
                if s.name == 'quiet_listener' and 'nothing received' in s.message]

    assert ros.spin_until(silent)
    status = silent()[0]
    assert status.level == DiagnosticStatus.WARN
    assert 'QoS mismatch' not in status.message
    assert 'nothing received yet (their QoS is compatible' in status.message


def test_run_node_exit_codes():
    def bad_config():
        raise ConfigError('threshold = 7 is above the maximum 1.0')

    assert run_node(bad_config, args=['probe']) == 2
    assert not rclpy.ok()

    class Interrupted(WorkzoneNode):
        def __init__(self):
            super().__init__('interrupted')
            self.create_timer(0.01, self._stop)

        def _stop(self):
            raise KeyboardInterrupt

    assert run_node(Interrupted, args=['interrupted']) == 0
    assert not rclpy.ok()


def test_frames_a_busy_node_never_saw_are_counted(ros):
    """A sensor subscription keeps the newest frames: the ones that never arrived show as
    gaps in the stamps and are reported apart from invalid input."""
    node = ros.add(ProbeNode(context=ros.context, **FAST))
    peer = ros.node('peer')
    pub = peer.create_publisher(Image, 'probe/image', 10)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0)
    sent = [k for k in range(30) if k % 5 != 4]          # every 5th frame never arrives
    for k in sent:
        msg = numpy_to_image(np.zeros((4, 6, 3), 'uint8'))
        msg.header.stamp.sec, msg.header.stamp.nanosec = 100 + k // 10, (k % 10) * 100_000_000
        pub.publish(msg)
        ros.spin_until(lambda n=len(node.shapes): len(node.shapes) > n, timeout=2.0)
    values = _values(node.diagnostic_status())
    assert values['/probe/image skipped while busy'] == '5'
    assert values['/probe/image dropped'] == '0'
