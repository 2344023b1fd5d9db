"""``workzone-ros evaluate faults``: fuzz every subscription of every node (issue 37, item 1).

Each node runs with its real subscriptions on real topics, in a private rclpy context (a
unique ROS_DOMAIN_ID and localhost discovery), next to a peer node that feeds it.  After a
warm-up on good input (the reference output), for every subscription, malformed messages
drawn by hypothesis (:mod:`workzone_ros.tools.fault_messages`) are published one at a time,
each followed by good frames (every input of the node, freshly stamped) until the node's
output is right again.  Per message it records:

* crash: an exception that escaped to the executor (it would end the node's process), a
  callback stuck for longer than ``--hang-s``, or, with the default process isolation, the
  node's process dying (a segfault, out of memory);
* dropped, with the reason the node gave (``internal error: ...`` reasons are bugs: the node
  survived, but did not say what was wrong with the input), or accepted as usable input;
* recovered: the output for a good frame after it matched the reference, and how many good
  frames that took (target: the first).

And per subscription, that ``/diagnostics`` reports the node's drop counter and last reason.
Duplicate and out-of-order stamps (item 2) are tried too: each is counted in
``/diagnostics``, and the next good frame is processed normally.

Usage::

    workzone-ros evaluate faults [--examples 40] [--nodes lidar_cluster,fusion,...]
        [--json faults.json] [--in-process] [--hang-s 10]
"""
from __future__ import annotations

import argparse
import collections
import dataclasses
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Callable, Optional

import numpy as np

__all__ = ['targets', 'Harness', 'Outcome', 'fuzz_topic', 'stamp_faults', 'summarise',
           'main']

T_FAULT_S = 5.0          # wait for the malformed message to be taken
T_RECOVER_S = 8.0        # wait for a good output after it
GOOD_EVERY_S = 0.25      # a new good frame while waiting


# --- the good inputs ---------------------------------------------------------------------

@lru_cache(maxsize=None)
def _scene() -> dict:
    """The good inputs every target is fed: one work-zone sign seen by camera and LiDAR."""
    from workzone_ros.core.lidar_clustering import SIZED_CANDIDATE_DTYPE
    from workzone_ros.core.pointcloud import make_points
    from workzone_ros.nodes.conversions import CameraInfoData
    from workzone_ros.sim.signart import over, sign_face
    from workzone_ros.sim.world import DEFAULT_CAMERA

    rng = np.random.default_rng(0)
    frame = np.clip(rng.normal(110, 12, (240, 320, 3)), 0, 255).astype(np.float32)
    frame[60:120, 200:260] = over(sign_face('road_work_ahead', 60), frame[60:120, 200:260])
    sign = (25.0, -7.0, 0.8)                      # lidar frame
    yy, zz = np.meshgrid(np.linspace(sign[1] - 0.6, sign[1] + 0.6, 16),
                         np.linspace(sign[2] - 0.6, sign[2] + 0.6, 6))
    gx, gy = rng.uniform(3, 60, 3000), rng.uniform(-15, 15, 3000)
    cloud = make_points(
        x=np.concatenate([np.full(yy.size, sign[0]), gx]).astype(np.float32),
        y=np.concatenate([yy.ravel(), gy]).astype(np.float32),
        z=np.concatenate([zz.ravel(), np.full(gx.size, -1.95)]).astype(np.float32),
        intensity=np.concatenate([np.full(yy.size, 220.0), np.full(gx.size, 6.0)])
        .astype(np.float32))
    cands = np.zeros(1, SIZED_CANDIDATE_DTYPE)
    cands['x'], cands['y'], cands['z'] = sign
    cands['radius'], cands['intensity'], cands['count'], cands['id'] = 0.6, 220.0, 96, 1
    cands['half_w'], cands['half_h'] = 0.6, 0.6
    cam = DEFAULT_CAMERA
    info = CameraInfoData(320, 240, [cam.fx / 2, 0, 160, 0, cam.fy / 2, 120, 0, 0, 1],
                          cam.dist)
    return dict(frame=np.clip(frame, 0, 255).astype(np.uint8), cloud=cloud, cands=cands,
                info=info, box=(200.0, 60.0, 60.0, 60.0))


def _header(stamp: Any, frame_id: str = 'camera') -> Any:
    from workzone_ros import interfaces as I
    from workzone_ros.nodes.conversions import stamp_to_time
    return I.Header(stamp=stamp_to_time(stamp), frame_id=frame_id)


def _box() -> Any:
    from workzone_ros.interfaces import Box
    x, y, w, h = _scene()['box']
    return Box(x=x, y=y, w=w, h=h)


def _string(payload: Any) -> Any:
    from workzone_ros.nodes.conversions import payload_to_string
    return payload_to_string(payload)


def _good_points(stamp):
    from workzone_ros.nodes.conversions import array_to_pointcloud2
    return array_to_pointcloud2(_scene()['cloud'], stamp=stamp, frame_id='lidar')


def _good_candidates(stamp):
    from workzone_ros.nodes.conversions import array_to_pointcloud2
    return array_to_pointcloud2(_scene()['cands'], stamp=stamp, frame_id='lidar')


def _good_odom(stamp):
    from nav_msgs.msg import Odometry

    from workzone_ros.nodes.conversions import make_header
    msg = Odometry(header=make_header(stamp=stamp, frame_id='odom'), child_frame_id='base_link')
    msg.pose.pose.orientation.w = 1.0
    return msg


def _good_image(stamp):
    from workzone_ros.nodes.conversions import numpy_to_image
    return numpy_to_image(_scene()['frame'], 'bgr8', stamp=stamp, frame_id='camera')


def _good_compressed(stamp):
    from workzone_ros.nodes.conversions import numpy_to_compressed
    return numpy_to_compressed(_scene()['frame'], 'jpeg', stamp=stamp, frame_id='camera')


def _good_info(stamp):
    from workzone_ros.nodes.conversions import numpy_to_camera_info
    return numpy_to_camera_info(_scene()['info'], stamp=stamp, frame_id='camera')


def _good_rois(stamp):
    from workzone_ros import interfaces as I
    roi = I.Roi(candidate_id=1, box=_box(), center=(230.0, 90.0), range_m=26.0, radius_m=0.6,
                position=(7.0, -0.8, 25.0), intensity=220.0, points=96)
    return _string(I.Rois(header=_header(stamp), rois=[roi], lidar_stamp=_header(stamp).stamp))


def _good_detections(stamp):
    from workzone_ros import interfaces as I
    det = I.Detection(box=_box(), confidence=0.9, color='orange', kind='warning')
    return _string(I.Detections(header=_header(stamp), detections=[det], channelizers=0))


def _good_tracks(stamp):
    from workzone_ros import interfaces as I
    track = I.Track(track_id=1, box=_box(), source='detection', age=5, hits=5,
                    similarity=0.95, confidence=0.9, kind='warning')
    return _string(I.Tracks(header=_header(stamp), tracks=[track]))


def _good_signs(stamp):
    from workzone_ros import interfaces as I
    sign = I.Sign(box=_box(), class_key='road_work_ahead', code='W20-1', category='workzone',
                  score=0.95, track_id=3, probabilities={'road_work_ahead': 0.95},
                  distance_m=80.0, distance_source='size')
    return _string(I.Signs(header=_header(stamp), signs=[sign]))


def _good_state(stamp):
    from workzone_ros import interfaces as I
    return _string(I.WorkzoneState(header=_header(stamp), active=False, likelihood=0.8,
                                   phase='approaching'))


# --- the targets --------------------------------------------------------------------------

@dataclass(frozen=True)
class Input:
    """One subscription of a target: the parameter naming its topic, type and good input."""

    param: str
    kind: str                       # 'points', 'image', 'compressed', 'info', 'odom', 'json'
    good: Callable[[Any], Any]
    latched: bool = False           # the node subscribes transient local

    @property
    def msg_type(self) -> type:
        """The message class."""
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
        from std_msgs.msg import String
        return {'points': PointCloud2, 'image': Image, 'compressed': CompressedImage,
                'info': CameraInfo, 'odom': Odometry, 'json': String}[self.kind]


def _iou(a: Any, b: tuple) -> float:
    from workzone_ros.interfaces import Box
    return a.iou(Box(x=b[0], y=b[1], w=b[2], h=b[3]))


def _check_candidates(out, ref) -> bool:
    if not len(out):
        return False
    got = np.stack([out['x'], out['y'], out['z']], 1)
    want = np.array([ref['x'][0], ref['y'][0], ref['z'][0]]) if ref is not None \
        else np.array([25.0, -7.0, 0.8])
    return bool(np.min(np.linalg.norm(got - want, axis=1)) < 0.3)


def _check_rois(out, ref) -> bool:
    if not out.rois:
        return False
    if ref is None:
        return True
    c, r = np.array(out.rois[0].center), np.array(ref.rois[0].center)
    return len(out.rois) == len(ref.rois) and bool(np.linalg.norm(c - r) < 2.0)


def _check_boxes(items: Callable) -> Callable:
    def check(out, ref) -> bool:
        return any(_iou(x.box, _scene()['box']) > 0.5 for x in items(out))
    return check


def _check_signs(out, ref) -> bool:
    hits = [s for s in out.signs if _iou(s.box, _scene()['box']) > 0.5]
    return bool(hits) and (ref is None or hits[0].class_key == ref.signs[0].class_key)


@dataclass(frozen=True)
class Target:
    """A node under test: its parameters, its inputs (publish order), its output."""

    name: str
    node: str
    inputs: tuple[Input, ...]
    output: tuple[str, str, Callable]      # (param, payload class name or 'points', check)
    params: tuple = ()
    fuzz: tuple = ()                       # the input kinds fuzzed (empty: all)

    def topic(self, param: str) -> str:
        """The absolute topic of a topic parameter (each target in its own namespace)."""
        return f'/faults/{self.name}/{param.replace("_topic", "")}'


_IMAGE = Input('image_topic', 'image', _good_image)
_COMPRESSED = Input('image_topic', 'compressed', _good_compressed)
_INFO = Input('camera_info_topic', 'info', _good_info)


def _targets() -> dict[str, Target]:
    odom = Input('odom_topic', 'odom', _good_odom)
    out = {
        'lidar_cluster': Target('lidar_cluster', 'lidar_cluster', (
            odom, Input('points_topic', 'points', _good_points)),
            ('candidates_topic', 'points', _check_candidates),
            (('persistence_k', 1), ('persistence_n', 1))),
        'projector': Target('projector', 'projector', (
            _INFO, odom, Input('candidates_topic', 'points', _good_candidates), _IMAGE),
            ('rois_topic', 'Rois', _check_rois), (
                ('lidar_to_camera', [float(v) for v in _lidar_to_camera()]),)),
        'color_detector': Target('color_detector', 'color_detector', (
            _INFO, Input('rois_topic', 'json', _good_rois), _IMAGE),
            ('detections_topic', 'Detections', _check_boxes(lambda o: o.detections))),
        'tracker': Target('tracker', 'tracker', (
            _IMAGE, Input('detections_topic', 'json', _good_detections)),
            ('tracks_topic', 'Tracks', _check_boxes(lambda o: o.tracks))),
        'classifier': Target('classifier', 'classifier', (
            _INFO, Input('state_topic', 'json', _good_state, latched=True),
            Input('rois_topic', 'json', _good_rois), _IMAGE,
            Input('input_topic', 'json', _good_tracks)),
            ('signs_topic', 'Signs', _check_signs), (('min_size', 10),)),
        'fusion': Target('fusion', 'fusion', (
            odom, _INFO, Input('lidar_topic', 'points', _good_candidates),
            Input('detections_topic', 'json', _good_detections),
            Input('signs_topic', 'json', _good_signs)),
            ('state_topic', 'WorkzoneState', lambda o, r: o.phase == 'approaching')),
    }
    for name in ('projector', 'color_detector', 'tracker', 'classifier'):
        t = out[name]
        out[f'{name}/compressed'] = dataclasses.replace(
            t, name=f'{name}_compressed', params=t.params + (('compressed', True),),
            fuzz=('compressed',),           # its other inputs are the raw target's
            inputs=tuple(_COMPRESSED if i is _IMAGE else i for i in t.inputs))
    return out


def _lidar_to_camera() -> np.ndarray:
    from workzone_ros.sim.world import LIDAR_TO_CAMERA
    return LIDAR_TO_CAMERA.ravel()


@lru_cache(maxsize=None)
def targets() -> dict[str, Target]:
    """Name -> :class:`Target` (``<node>/compressed``: the node reading CompressedImage)."""
    return _targets()


# --- one node under test ------------------------------------------------------------------

@dataclass
class Outcome:
    """What one malformed message did."""

    target: str
    topic: str
    kind: str
    fault: str
    delivered: bool = False
    dropped: list = field(default_factory=list)       # reasons given on this topic
    dropped_elsewhere: list = field(default_factory=list)   # (topic, reason) on other topics
    stamps_counted: int = 0                           # repeated / out-of-order stamps counted
    resets: int = 0                                   # memory resets it caused (fusion)
    crash: str = ''
    internal_error: str = ''
    recovered: bool = False
    good_frames: int = 0                              # good frames until the output was right
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        """No crash, no internal error, a one-line reason when dropped, and recovered."""
        return (not self.crash and not self.internal_error and self.recovered
                and all(r and '\n' not in r for r in self.dropped))


class PrivateRos:
    """A private context and executor (what test/nodes/conftest.py's ``ros`` fixture is)."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes: list = []

    def add(self, node):
        """Add ``node`` to the executor (destroyed by :meth:`close`)."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def node(self, name: str):
        """A plain helper node."""
        import rclpy
        return self.add(rclpy.create_node(name, context=self.context))

    def close(self) -> None:
        """Shut the executor down, destroy the nodes and the context."""
        import rclpy
        self.executor.shutdown()
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)


class Harness:
    """One node of a :class:`Target` fed by a peer over real topics.

    Args:
        target: what to run.
        ros: an object with ``context``, ``executor``, ``add(node)``, ``node(name)`` and
            ``close()`` (a test's ``ros`` fixture); a :class:`PrivateRos` when None.
        hang_s: a single callback running longer than this counts as a crash (a hang).
    """

    def __init__(self, target: Target, ros: Any = None, hang_s: float = 10.0) -> None:
        from rclpy.parameter import Parameter
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String
        self.target = target
        self.ros = ros if ros is not None else PrivateRos()
        self._own_ros = ros is None
        self.hang_s = hang_s
        self.crashes: list[str] = []
        self.drops: list[tuple[str, str]] = []
        self._last_ns = 0
        self.good_frames = 0
        self.last_good_ns = 0
        cls = importlib.import_module(f'workzone_ros.nodes.{target.node}').NODE_CLASS
        params = {i.param: target.topic(i.param) for i in target.inputs}
        out_param, out_kind, self._check = target.output
        params[out_param] = target.topic(out_param)
        if target.node == 'classifier':             # its second output
            params['debug_image_topic'] = target.topic('debug_image_topic')
        params.update(dict(target.params))
        self.node = self.ros.add(cls(
            context=self.ros.context, diagnostics_period_s=0.2, silent_input_warn_s=600.0,
            parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]))
        self._instrument()
        self.peer = self.ros.node(f'faults_peer_{target.name}')
        self.topics: dict[str, Input] = {}
        self._pubs: dict[str, Any] = {}
        for inp in target.inputs:
            topic = target.topic(inp.param) + ('/compressed' if inp.kind == 'compressed'
                                               else '')
            self.topics[topic] = inp
            qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL if inp.latched
                             else DurabilityPolicy.VOLATILE)
            self._pubs[topic] = self.peer.create_publisher(inp.msg_type, topic, qos)
        #: the topics fuzzed
        self.fuzzed = [t for t, i in self.topics.items()
                       if not target.fuzz or i.kind in target.fuzz]
        self.outputs: list[tuple[int, Any]] = []
        out_type = String if out_kind != 'points' else Input('', 'points', None).msg_type
        self.peer.create_subscription(out_type, target.topic(out_param),
                                      self._on_output(out_kind), 50)
        from diagnostic_msgs.msg import DiagnosticArray
        self.diagnostics: list = []
        self.peer.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 50)
        self.reference: Any = None

    # -- plumbing --

    def _instrument(self) -> None:
        """Record every drop (topic, reason) the node reports, as it reports it."""
        node, original = self.node, self.node.drop

        def drop(topic: str, reason: str) -> None:
            try:
                topic = node.resolve_topic_name(topic)
            except Exception:  # noqa: BLE001 - keep the name as given
                pass
            self.drops.append((topic, reason))
            original(topic, reason)
        node.drop = drop

    def _on_output(self, kind: str) -> Callable:
        from workzone_ros import interfaces as I
        from workzone_ros.nodes.conversions import pointcloud2_to_array

        def callback(msg: Any) -> None:
            if kind == 'points':
                st = msg.header.stamp
                self.outputs.append((st.sec * 10 ** 9 + st.nanosec,
                                     pointcloud2_to_array(msg).copy()))
            else:
                payload = I.decode(msg.data, getattr(I, kind))
                self.outputs.append((payload.header.stamp.to_ns(), payload))
        return callback

    def _on_diag(self, msg: Any) -> None:
        for status in msg.status:
            if status.name == self.node.get_name():
                self.diagnostics.append({kv.key: kv.value for kv in status.values})
        del self.diagnostics[:-5]

    def spin_until(self, condition: Callable[[], bool], timeout: float,
                   each: Optional[Callable[[], None]] = None) -> bool:
        """Spin (recording what escapes a callback, and hangs) until ``condition()``."""
        deadline = time.monotonic() + timeout
        while True:
            if each is not None:
                each()
            t0 = time.monotonic()
            try:
                self.ros.executor.spin_once(timeout_sec=0.02)
            except Exception as exc:  # noqa: BLE001 - this is what the campaign looks for
                self.crashes.append(f'{type(exc).__name__}: {exc}'[:300])
            if time.monotonic() - t0 > self.hang_s:
                self.crashes.append(f'a callback ran for {time.monotonic() - t0:.1f} s')
            if condition():
                return True
            if time.monotonic() > deadline:
                return False

    def stamp(self) -> Any:
        """A fresh stamp: the wall clock, strictly increasing (live input)."""
        from builtin_interfaces.msg import Time
        ns = max(self._last_ns + 1_000_000, time.time_ns())
        self._last_ns = ns
        return Time(sec=ns // 10 ** 9, nanosec=ns % 10 ** 9)

    def messages(self, topic: str) -> int:
        """Messages the node has taken on ``topic``."""
        stats = self.node.topic_stats().get(topic)
        return 0 if stats is None else stats.messages

    def publish_frame(self, stamp: Any = None) -> int:
        """Publish one good frame (every input, in order); returns its stamp in ns."""
        stamp = stamp or self.stamp()
        for topic, inp in self.topics.items():
            self._pubs[topic].publish(inp.good(stamp))
        self.last_good_ns = stamp.sec * 10 ** 9 + stamp.nanosec
        return self.last_good_ns

    # -- the campaign steps --

    def start(self, timeout: float = 30.0) -> None:
        """Wait for discovery, then for a right output on good input (the reference).

        Raises:
            RuntimeError: the node never produced the expected output on good input.
        """
        ok = self.spin_until(lambda: all(p.get_subscription_count() > 0
                                         for p in self._pubs.values()), timeout)
        if not ok:
            raise RuntimeError(f'{self.target.name}: the node never subscribed')
        got = self.recover(timeout)
        if got is None:
            raise RuntimeError(f'{self.target.name}: no right output on good input; last '
                               f'outputs {self.outputs[-2:]}, drops {self.drops[-3:]}')
        self.reference = got

    def recover(self, timeout: float = T_RECOVER_S) -> Any:
        """Good frames until the output for one of them is right; returns that output."""
        sent: list[int] = []
        last = [0.0]
        self.outputs.clear()

        def each() -> None:
            if time.monotonic() - last[0] >= GOOD_EVERY_S:
                sent.append(self.publish_frame())
                last[0] = time.monotonic()

        def right() -> bool:
            return any(ns in sent and self._check(out, self.reference)
                       for ns, out in self.outputs)
        if not self.spin_until(right, timeout, each):
            return None
        self.good_frames = len(sent)
        return next(out for ns, out in self.outputs if ns in sent
                    and self._check(out, self.reference))

    def try_fault(self, topic: str, fault: Any) -> Outcome:
        """Publish one malformed message on ``topic``, then good frames until recovery."""
        out = Outcome(self.target.name, topic, fault.kind, str(fault)[:400])
        t0 = time.monotonic()
        try:
            msg = fault.build(self.stamp())
        except Exception:  # noqa: BLE001 - a combination of steps that makes no message
            from hypothesis import reject
            reject()
        n_drops, n_crashes, before = len(self.drops), len(self.crashes), self.messages(topic)
        counted, resets = self._stamps_counted(topic), self._resets()
        try:
            self._pubs[topic].publish(msg)
        except Exception:  # noqa: BLE001 - rclpy refuses it: no node can receive it
            from hypothesis import reject
            reject()
        out.delivered = self.spin_until(lambda: self.messages(topic) > before, T_FAULT_S)
        self.spin_until(lambda: False, 0.05)          # whatever it set off
        out.recovered = self.recover() is not None
        out.good_frames = self.good_frames if out.recovered else 0
        out.dropped = [r for t, r in self.drops[n_drops:] if t == topic]
        out.dropped_elsewhere = [(t, r) for t, r in self.drops[n_drops:] if t != topic][:3]
        out.stamps_counted = self._stamps_counted(topic) - counted
        out.resets = self._resets() - resets
        internal = [r for _, r in self.drops[n_drops:] if r.startswith('internal error')]
        out.internal_error = internal[0][:300] if internal else ''
        out.crash = '; '.join(self.crashes[n_crashes:])[:300]
        out.seconds = time.monotonic() - t0
        return out

    def _stamps_counted(self, topic: str) -> int:
        stats = self.node.topic_stats().get(topic)
        return 0 if stats is None else stats.stamps_repeated + stats.stamps_out_of_order

    def _resets(self) -> int:
        fusion = getattr(self.node, '_fusion', None)
        return int(getattr(fusion, 'resets', 0))

    def diagnostics_agree(self, topic: str, timeout: float = 5.0) -> bool:
        """``/diagnostics`` shows this topic's drop counter and, after a drop, its reason."""
        def agree() -> bool:
            stats = self.node.topic_stats()[topic]
            for values in self.diagnostics[-2:]:
                if values.get(f'{topic} dropped') == str(stats.dropped) and (
                        stats.dropped == 0 or values.get(f'{topic} last drop reason')):
                    return True
            return False
        self.diagnostics.clear()
        return self.spin_until(agree, timeout)

    def close(self) -> None:
        """Destroy the node, the peer and (when owned) the context."""
        if self._own_ros:
            self.ros.close()


# --- stamps (item 2) ----------------------------------------------------------------------

def stamp_faults(h: Harness, topic: str) -> list[Outcome]:
    """A good message with the stamp of the last one, then one 0.5 s older: each must be
    counted (``<topic> stamps repeated`` / ``stamps out of order``), never fatal."""
    from builtin_interfaces.msg import Time

    from workzone_ros.tools.fault_messages import Fault
    inp = h.topics[topic]
    outcomes = []
    for kind, back_ns in (('duplicate stamp', 0), ('out-of-order stamp', 500_000_000)):
        ns = h.last_good_ns - back_ns          # the last good frame's stamp, or before it
        stamp = Time(sec=ns // 10 ** 9, nanosec=ns % 10 ** 9)
        outcomes.append(h.try_fault(topic, Fault(kind, (), lambda _s, t=stamp: inp.good(t))))
    return outcomes


# --- hypothesis ---------------------------------------------------------------------------

def fuzz_topic(h: Harness, topic: str, examples: int, seed: Optional[int] = None,
               progress: Optional[Callable[[Outcome], None]] = None) -> list[Outcome]:
    """``examples`` malformed messages drawn by hypothesis, each tried on ``topic``."""
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed

    from workzone_ros.tools.fault_messages import faults_for
    inp = h.topics[topic]
    outcomes: list[Outcome] = []

    @settings(max_examples=examples, derandomize=seed is None, database=None, deadline=None,
              phases=[Phase.generate], suppress_health_check=list(HealthCheck))
    @given(faults_for(inp.msg_type, inp.good))
    def run(fault):
        o = h.try_fault(topic, fault)
        outcomes.append(o)
        if progress is not None:
            progress(o)
    if seed is not None:
        run = hseed(seed)(run)
    run()
    return outcomes


def run_target(name: str, examples: int, seed: Optional[int] = None, hang_s: float = 10.0,
               progress: Optional[Callable[[dict], None]] = None) -> dict:
    """The campaign on one target: per topic, its outcomes and the diagnostics check."""
    h = Harness(targets()[name], hang_s=hang_s)
    result = {'target': name, 'node': h.target.node, 'topics': {}}
    try:
        h.start()
        for topic in h.fuzzed:
            if progress:
                progress({'topic': topic, 'start': True})
            outcomes = fuzz_topic(h, topic, examples, seed,
                                  lambda o: progress and progress(dataclasses.asdict(o)))
            stamps = stamp_faults(h, topic)
            for o in stamps:
                if progress:
                    progress(dataclasses.asdict(o))
            result['topics'][topic] = {
                'outcomes': [dataclasses.asdict(o) for o in outcomes],
                'stamps': [dataclasses.asdict(o) for o in stamps],
                'diagnostics_agree': h.diagnostics_agree(topic)}
    finally:
        h.close()
    return result


# --- report -------------------------------------------------------------------------------

def summarise(result: dict) -> list[dict]:
    """One row per (target, topic): tried, dropped, crashes, recovery, stamps."""
    rows = []
    for topic, r in result['topics'].items():
        outs = r['outcomes']
        n = len(outs)
        rows.append({
            'node': result['target'], 'topic': topic, 'tried': n,
            'delivered': sum(o['delivered'] for o in outs),
            'dropped': sum(bool(o['dropped']) for o in outs),
            'dropped_elsewhere_only': sum(bool(o['dropped_elsewhere'] and not o['dropped'])
                                          for o in outs),
            'internal_errors': sum(bool(o['internal_error']) for o in outs),
            'crashes': sum(bool(o['crash']) for o in outs) + r.get('process_crashes', 0),
            'recovered_pct': 100.0 * sum(o['recovered'] for o in outs) / n if n else 0.0,
            'max_good_frames': max((o['good_frames'] for o in outs), default=0),
            'stamps_ok': all(o['recovered'] and not o['crash'] and not o['resets']
                             for o in r.get('stamps', ())),
            'stamps_counted': sum(bool(o['stamps_counted'] or o['dropped'])
                                  for o in r.get('stamps', ())),
            'diagnostics_agree': r.get('diagnostics_agree', False),
            'kinds': dict(collections.Counter(o['kind'] for o in outs)),
            'failures': [o for o in outs if not (o['recovered'] and not o['crash']
                                                 and not o['internal_error'])][:5],
        })
    return rows


def _table(rows: list[dict]) -> str:
    head = ('| node | topic | tried | dropped | internal errors | crashes | recovered | '
            'good frames (max) | stamps | diagnostics |')
    lines = [head, '|' + '---|' * 10]
    for r in rows:
        lines.append(f"| {r['node']} | `{r['topic'].split('/', 3)[-1]}` | {r['tried']} | "
                     f"{r['dropped']} | {r['internal_errors']} | {r['crashes']} | "
                     f"{r['recovered_pct']:.0f} % | {r['max_good_frames']} | "
                     f"{'ok' if r['stamps_ok'] else 'FAIL'}, {r['stamps_counted']}/2 counted | "
                     f"{'ok' if r['diagnostics_agree'] else 'FAIL'} |")
    return '\n'.join(lines)


def _child(name: str, args: argparse.Namespace) -> dict:
    """Run one target in its own process: a node that dies takes only this run with it."""
    with tempfile.TemporaryDirectory() as tmp:
        progress, out = os.path.join(tmp, 'progress.jsonl'), os.path.join(tmp, 'result.json')
        cmd = [sys.executable, '-m', 'workzone_ros.tools.eval_faults', '--target', name,
               '--examples', str(args.examples), '--hang-s', str(args.hang_s),
               '--result', out, '--progress', progress]
        if args.seed is not None:
            cmd += ['--seed', str(args.seed)]
        t0 = time.monotonic()
        proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True, timeout=args.timeout)
        if proc.returncode == 0 and os.path.exists(out):
            with open(out) as f:
                result = json.load(f)
            result['seconds'] = time.monotonic() - t0
            return result
        # the process died: what it had done, and the message it died on
        result = {'target': name, 'node': targets()[name].node, 'topics': {},
                  'died': f'exit {proc.returncode}: {proc.stderr.strip()[-300:]}'}
        topic = None
        if os.path.exists(progress):
            with open(progress) as f:
                for line in f:
                    item = json.loads(line)
                    if item.get('start'):
                        topic = item['topic']
                        result['topics'][topic] = {'outcomes': [], 'stamps': []}
                    elif topic:
                        result['topics'][topic]['outcomes'].append(item)
        if topic:
            result['topics'][topic]['process_crashes'] = 1
        return result


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros evaluate faults``."""
    ap = argparse.ArgumentParser(prog='workzone-ros evaluate faults', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--examples', type=int, default=40, help='malformed messages per topic')
    ap.add_argument('--nodes', default='', help='comma-separated targets (default: all): '
                    + ', '.join(_TARGET_NAMES))
    ap.add_argument('--seed', type=int, default=None,
                    help='hypothesis seed (default: derandomized, the same messages each run)')
    ap.add_argument('--json', default='', help='write the results here')
    ap.add_argument('--in-process', action='store_true',
                    help='run every target in this process (a segfault ends the run)')
    ap.add_argument('--hang-s', type=float, default=10.0,
                    help='a callback running longer counts as a crash')
    ap.add_argument('--timeout', type=float, default=3600.0, help='per target, s')
    ap.add_argument('--target', help=argparse.SUPPRESS)
    ap.add_argument('--result', help=argparse.SUPPRESS)
    ap.add_argument('--progress', help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    try:
        import hypothesis  # noqa: F401
    except ImportError:
        print("evaluate faults needs hypothesis: pip install -e '.[test]'", file=sys.stderr)
        return 2
    _isolate()
    if args.target:                               # the child of _child()
        with open(args.progress, 'a') as prog:
            def progress(item: dict) -> None:
                prog.write(json.dumps(item) + '\n')
                prog.flush()
            result = run_target(args.target, args.examples, args.seed, args.hang_s, progress)
        with open(args.result, 'w') as f:
            json.dump(result, f)
        return 0
    names = [n.strip() for n in args.nodes.split(',') if n.strip()] or list(_TARGET_NAMES)
    unknown = [n for n in names if n not in _TARGET_NAMES]
    if unknown:
        print(f'unknown target(s) {", ".join(unknown)}; known: {", ".join(_TARGET_NAMES)}',
              file=sys.stderr)
        return 2
    results, t0 = [], time.monotonic()
    for name in names:
        print(f'[faults] {name} ...', flush=True)
        results.append(run_target(name, args.examples, args.seed, args.hang_s)
                       if args.in_process else _child(name, args))
    rows = [row for r in results for row in summarise(r)]
    print(_table(rows))
    for r in results:
        if r.get('died'):
            print(f"[faults] {r['target']}: the node's process died ({r['died']})")
    for row in rows:
        for o in row['failures']:
            print(f"[faults] {row['node']} {row['topic']}: {o['fault']} -> crash "
                  f"{o['crash'] or '-'}; internal {o['internal_error'] or '-'}; recovered "
                  f"{o['recovered']}; dropped {o['dropped'][:1]}")
    total = sum(r['tried'] for r in rows)
    crashes = sum(r['crashes'] for r in rows)
    print(f'[faults] {total} malformed messages on {len(rows)} subscriptions, {crashes} '
          f'crash(es), {time.monotonic() - t0:.0f} s')
    if args.json:
        with open(args.json, 'w') as f:
            json.dump({'examples': args.examples, 'seed': args.seed, 'rows': rows,
                       'results': results}, f, indent=1)
    bad = crashes or any(r['recovered_pct'] < 100 or r['internal_errors'] for r in rows)
    return 1 if bad else 0


_TARGET_NAMES = ('lidar_cluster', 'projector', 'projector/compressed', 'color_detector',
                 'color_detector/compressed', 'tracker', 'tracker/compressed', 'classifier',
                 'classifier/compressed', 'fusion')


def _isolate() -> None:
    """A DDS domain of our own, localhost only (as the test session does)."""
    os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_STATIC_PEERS', None)
    os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')


if __name__ == '__main__':
    raise SystemExit(main())
