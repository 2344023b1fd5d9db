"""The ``fusion`` node with real topics: unknown at start, approaching on advance warning signs,
latched state for a late planner, bad payloads counted, a looping bag resets the memory."""
from __future__ import annotations

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, String

from workzone_ros.interfaces import Box, Header, Sign, Signs, Time, WorkzoneState, decode, encode
from workzone_ros.nodes.fusion import FusionNode

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _signs(k: int, key: str | None = 'road_work_ahead', t0: int = 100) -> str:
    stamp = Time.from_ns(t0 * 10**9 + k * 66_666_667)
    signs = []
    if key:
        signs.append(Sign(box=Box(x=400, y=200, w=20 + k, h=20 + k), class_key=key,
                          code='W20-1', category='workzone', score=0.95, track_id=3,
                          probabilities={key: 0.95, 'background': 0.05},
                          distance_m=max(5.0, 120.0 - 2.0 * k), distance_source='size'))
    return encode(Signs(header=Header(stamp=stamp, frame_id='camera'), signs=signs))


def _planner(ros, name, states):
    peer = ros.add(rclpy.create_node(name, context=ros.context))
    peer.create_subscription(String, '/workzone/state',
                             lambda m: states.append(decode(m.data, WorkzoneState)), LATCHED)
    return peer


def test_state_starts_unknown_then_approaching_and_a_late_planner_gets_it_at_once(ros):
    node = ros.add(FusionNode(context=ros.context, parameter_overrides=[]))
    states: list[WorkzoneState] = []
    active: list[bool] = []
    peer = _planner(ros, 'planner', states)
    peer.create_subscription(Bool, '/workzone/active', lambda m: active.append(m.data), LATCHED)
    pub = peer.create_publisher(String, '/workzone/signs', 10)
    assert ros.spin_until(lambda: states and pub.get_subscription_count() > 0)
    assert states[0].phase == 'unknown' and not states[0].active
    k = 0

    def feed():
        nonlocal k
        pub.publish(String(data=_signs(k)))
        k += 1
    assert ros.spin_until(lambda: states[-1].phase == 'approaching', timeout=20, each=feed), \
        [s.phase for s in states][-5:]
    assert any(e.class_key == 'road_work_ahead' for e in states[-1].evidence)
    assert ros.spin_until(lambda: active and active[-1] == states[-1].active)
    # a planner that joins now receives the current state at once
    late: list[WorkzoneState] = []
    _planner(ros, 'late_planner', late)
    assert ros.spin_until(lambda: late, timeout=10)
    assert late[0].phase == 'approaching'
    assert node.count_subscribers('/workzone/signs') >= 0


def test_bad_payloads_are_counted_and_a_backwards_stamp_resets_to_unknown(ros):
    node = ros.add(FusionNode(context=ros.context, parameter_overrides=[]))
    states: list[WorkzoneState] = []
    peer = _planner(ros, 'planner2', states)
    pub = peer.create_publisher(String, '/workzone/signs', 10)
    assert ros.spin_until(lambda: states and pub.get_subscription_count() > 0)
    k = 0

    def feed():
        nonlocal k
        pub.publish(String(data=_signs(k, t0=200)))
        k += 1
    assert ros.spin_until(lambda: states[-1].phase == 'approaching', timeout=20, each=feed)
    pub.publish(String(data='{"schema": "workzone_ros/Signs/9", "header": {}}'))
    pub.publish(String(data='not json'))
    stats = next(s for t, s in node.topic_stats().items() if t.endswith('/workzone/signs'))
    assert ros.spin_until(lambda: node.topic_stats()['/workzone/signs'].dropped >= 2)
    assert stats.topic == '/workzone/signs'
    # the bag loops: an earlier stamp with nothing in view -> memory reset, never a false none
    n = len(states)
    pub.publish(String(data=_signs(0, key=None, t0=100)))
    assert ros.spin_until(lambda: len(states) > n)
    assert states[-1].phase == 'unknown', states[-1].phase
    values = {kv.key: kv.value for kv in node.diagnostic_status().values}
    assert values['fusion resets (time jumped back)'] == '1'
