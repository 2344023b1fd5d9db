"""Every subscription of every node, fuzzed with malformed messages on its
real topic (a few hypothesis examples per topic; ``workzone-ros evaluate faults`` runs the
full campaign).  Each message: no crash, no internal error, a one-line reason when dropped,
and the next good frame processed normally; ``/diagnostics`` shows the drop counter and the
reason.  Stamps: a repeated and an out-of-order stamp are counted, never fatal."""
from __future__ import annotations

import array
import json
import struct

import numpy as np
from hypothesis import HealthCheck, given, settings

from workzone_ros.tools.eval_faults import stamp_faults
from workzone_ros.tools.fault_messages import Fault, faults_for

EXAMPLES = 3          # per topic; deterministic (derandomized)


def _assert_ok(o):
    assert o.delivered, f'{o.topic}: {o.fault} never reached the node'
    assert not o.crash, f'{o.topic}: {o.fault} -> crash {o.crash}'
    assert not o.internal_error, f'{o.topic}: {o.fault} -> {o.internal_error}'
    assert all(r and '\n' not in r for r in o.dropped), o.dropped
    assert o.recovered, f'{o.topic}: no right output on good input after {o.fault}'


def test_every_subscription_survives_malformed_messages(harness):
    for topic in harness.fuzzed:
        inp = harness.topics[topic]

        @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                  suppress_health_check=list(HealthCheck))
        @given(fault=faults_for(inp.msg_type, inp.good))
        def malformed(fault):
            _assert_ok(harness.try_fault(topic, fault))

        malformed()
        assert harness.diagnostics_agree(topic), \
            f'/diagnostics does not show the drops of {topic}'


def test_repeated_and_out_of_order_stamps_are_counted_not_fatal(harness):
    for topic in harness.fuzzed:
        for o in stamp_faults(harness, topic):
            _assert_ok(o)
            assert not o.resets, f'{topic}: a {o.kind} reset the memory'
            if harness.topics[topic].kind != 'json':       # a header: the base counts it
                assert o.stamps_counted == 1, (topic, o.kind, o.stamps_counted)


# --- the messages that found a bug, kept as explicit cases --------------------------------

def _fault(kind, edit):
    """A Fault: the target's good message of ``kind`` changed by ``edit(msg)``."""
    def make(good):
        def build(stamp):
            msg = good(stamp)
            edit(msg)
            return msg
        return Fault(kind, (), build)
    return make


def _bytes(msg, data):
    msg.data = array.array('B', data)


def _bomb(msg):
    """A 30000 x 30000 JPEG in a few hundred bytes (OpenCV allocated 2.7 GB for it)."""
    b = bytearray(msg.data)
    i = b.find(b'\xff\xc0')
    b[i + 5:i + 9] = struct.pack('>HH', 30000, 30000)
    _bytes(msg, bytes(b))


def _json(**change):
    def edit(msg):
        doc = json.loads(msg.data)
        for path, value in change.items():
            node = doc
            keys = path.split('__')
            for k in keys[:-1]:
                node = node[k]
            node[keys[-1]] = value
        msg.data = json.dumps(doc)
    return edit


BOMB = ('image/compressed', _fault('huge declared size', _bomb),
        'declares a 30000x30000 image')
GARBAGE_JPEG = ('image/compressed', _fault('garbage', lambda m: _bytes(m, b'\xff\xd8garbage')),
                'no image size in its header')
TRUNCATED = ('image', _fault('truncated data', lambda m: _bytes(m, bytes(m.data)[:1000])),
             'Image data has 1000 bytes')
BAD_NANOSEC = _fault('stamp nanosec', lambda m: setattr(m.header.stamp, 'nanosec', 10 ** 9))


def _field(name, **values):
    def edit(msg):
        for f in msg.fields:
            if f.name == name:
                for k, v in values.items():
                    setattr(f, k, v)
    return edit


def _intensity(value):
    """Every 4th point's intensity ``value`` (x, y, z, intensity float32)."""
    def edit(msg):
        pts = np.frombuffer(bytes(msg.data), np.float32).reshape(-1, 4).copy()
        pts[::4, 3] = value
        _bytes(msg, pts.tobytes())
    return edit


def _huge_point_step(msg):
    msg.point_step = 2 ** 32 - 1
#: target -> (topic, the message, the reason it must be dropped with; None: accepted)
FOUND = {
    # compressed images: decoded (and so allocated) whatever size the header declared
    'color_detector_compressed': [BOMB, GARBAGE_JPEG],
    'tracker_compressed': [BOMB],
    'classifier_compressed': [BOMB],
    # tracker, classifier: a malformed image was buffered unchecked, never counted
    'tracker': [TRUNCATED],
    'classifier': [TRUNCATED],
    # projector: malformed images got ROIs; compressed ones were never compared with the
    # CameraInfo size
    'projector': [TRUNCATED, ('image', _fault('encoding', lambda m: setattr(m, 'encoding', '')),
                              "Image encoding '' is not supported"),
                  # kept, then the next image was dropped: "The truth value of an array..."
                  ('candidates', _fault('count', _field('radius', count=2)),
                   'must hold one value per candidate'),
                  # "dimension does not fit into a C int"
                  ('candidates', _fault('count', _field('id', count=2 ** 32 - 1)),
                   'does not fit in point_step')],
    'projector_compressed': [('image/compressed', _fault('huge declared size', _bomb),
                              'image 30000x30000 does not match CameraInfo 320x240')],
    'lidar_cluster': [
        # an invalid header stamp was used as a time (+4.3 s for nanosec 2^32-1)
        ('points', BAD_NANOSEC, 'stamp nanosec 1000000000 is outside'),
        ('odom', BAD_NANOSEC, 'stamp nanosec 1000000000 is outside'),
        # x with 3 values per point: "matmul: Input operand 1 has a mismatch"
        ('points', _fault('count', _field('x', count=3)), 'must hold one value per point'),
        # numpy cannot make the dtype: "integer won't fit into a C int"
        ('points', _fault('point_step', _huge_point_step), 'point_step 4294967295 is out'),
        # one scan with FLT_MAX intensities, or with 0-65535 values (byte-swapped floats),
        # turned the learned scale down for good: no candidate ever again
        ('points', _fault('NaN/inf values', _intensity(3.4e38)), None),
        ('points', _fault('intensity 0-65535', _intensity(1000.0)), None)],
    'fusion': [
        # liveness inputs took any message as a sign of life
        ('camera_info', _fault('K zero', lambda m: setattr(m, 'k', [0.0] * 9)), 'K is zero'),
        ('lidar', _fault('width past the data', lambda m: setattr(m, 'width', m.width + 5)),
         'row_step'),
        # a signs stamp beyond int32 (no ROS time) was accepted
        ('signs', _fault('stamp out of range', _json(header__stamp__sec=2 ** 40)),
         '$.header.stamp.sec'),
        # a stamp in 2038, then the present again: the state's stamps stayed in 2038
        ('signs', _fault('far future stamp', _json(header__stamp__sec=2 ** 31 - 1)), None),
    ],
}


def test_the_messages_that_found_bugs(harness):
    for suffix, make, reason in FOUND.get(harness.target.name, []):
        topic = next(t for t in harness.topics if t.endswith('/' + suffix))
        o = harness.try_fault(topic, make(harness.topics[topic].good))
        _assert_ok(o)
        if reason is None:
            assert not o.dropped, o.dropped
        else:
            assert any(reason in r for r in o.dropped), (topic, o.dropped)
