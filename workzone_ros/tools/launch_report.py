"""The launcher's ``--report``: counts and rates of the graph's ``/workzone/*`` outputs, drops
from ``/diagnostics`` and a coarse recall against ``/groundtruth/signs``
(:class:`ReportCollector`).
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any

__all__ = ['LEAN_KEY', 'ReportCollector']

_REPORT_TYPES = {
    '/workzone/lidar/candidates': 'sensor_msgs/msg/PointCloud2',
    '/workzone/rois': 'std_msgs/msg/String',
    '/workzone/detections': 'std_msgs/msg/String',
    '/workzone/tracks': 'std_msgs/msg/String',
    '/workzone/signs': 'std_msgs/msg/String',
    '/workzone/state': 'std_msgs/msg/String',
    '/workzone/active': 'std_msgs/msg/Bool',
    '/workzone/likelihood': 'std_msgs/msg/Float32',
}
#: the colour detector's ``/diagnostics`` key of its frames measured lean
#: (``color_detector.LEAN_KEY``)
LEAN_KEY = 'frames measured lean (behind the camera)'
#: payload list field that makes a frame "non-empty" for the coarse recall
_LIST_FIELD = {'/workzone/detections': 'detections', '/workzone/tracks': 'tracks',
               '/workzone/signs': 'signs', '/groundtruth/signs': 'signs'}


@dataclass
class _TopicCount:
    msgtype: str
    count: int = 0
    first: float = 0.0
    last: float = 0.0
    payload_errors: int = 0
    nonempty_stamps: set = field(default_factory=set)
    publishers: int = 0          # most publishers seen on the topic during the run

    def hit(self) -> None:
        now = time.monotonic()
        if not self.count:
            self.first = now
        self.count += 1
        self.last = now

    @property
    def rate(self) -> float:
        span = self.last - self.first
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


class ReportCollector:
    """Subscribes to the graph's outputs and summarises them (``--report``)."""

    def __init__(self, node) -> None:
        """Create the subscriptions on ``node`` (an rclpy node of the launcher)."""
        self.node = node
        self.topics: dict[str, _TopicCount] = {}
        self.diag: dict[str, dict[str, Any]] = {}
        self._lock = threading.Lock()
        for topic, msgtype in _REPORT_TYPES.items():
            self._subscribe(topic, msgtype)
        self._subscribe('/groundtruth/signs', 'std_msgs/msg/String')
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import QoSProfile
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                 QoSProfile(depth=100))
        self._scan_timer = node.create_timer(1.0, self.scan_graph)

    def _subscribe(self, topic: str, msgtype: str) -> None:
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        from workzone_ros.tools.player import SENSOR_TYPES, message_class
        try:
            cls = message_class(msgtype)
        except ImportError:
            return
        entry = self.topics[topic] = _TopicCount(msgtype)
        sensor = msgtype in SENSOR_TYPES
        qos = QoSProfile(depth=10 if sensor else 100,
                         reliability=ReliabilityPolicy.BEST_EFFORT if sensor
                         else ReliabilityPolicy.RELIABLE)
        parse = msgtype == 'std_msgs/msg/String'

        def callback(msg, topic=topic, entry=entry, parse=parse) -> None:
            with self._lock:
                entry.hit()
            if parse:
                self._on_payload(topic, entry, msg.data)

        self.node.create_subscription(cls, topic, callback, qos, raw=not parse)

    def _on_payload(self, topic: str, entry: _TopicCount, text: str) -> None:
        from workzone_ros.interfaces import PayloadError, decode_any
        try:
            payload = decode_any(text)
        except PayloadError:
            with self._lock:
                entry.payload_errors += 1
            return
        name = _LIST_FIELD.get(topic)
        if name and getattr(payload, name, None):
            with self._lock:
                entry.nonempty_stamps.add(payload.header.stamp.to_ns())

    def _on_diag(self, msg) -> None:
        with self._lock:
            for status in msg.status:
                drops = {}
                for kv in status.values:
                    if kv.key.startswith('stamp to state latency') \
                            or kv.key.endswith((' skipped while busy', ' messages')) \
                            or kv.key in ('frames detected', LEAN_KEY):
                        self.diag.setdefault(status.name, {'worst': 0})[kv.key] = kv.value
                    if kv.key.endswith(' dropped'):
                        try:
                            drops[kv.key[: -len(' dropped')]] = int(kv.value)
                        except ValueError:
                            pass
                level = status.level
                level = level[0] if isinstance(level, (bytes, bytearray)) else int(level)
                entry = self.diag.setdefault(status.name, {'worst': 0})
                entry.update(drops=drops, message=status.message,
                             worst=max(entry['worst'], level))

    def scan_graph(self) -> None:
        """Subscribe (count only) to any new ``/workzone/*`` topic seen in the graph."""
        try:
            names = self.node.get_topic_names_and_types()
        except Exception:  # noqa: BLE001 - graph queries fail during shutdown
            return
        for topic, types in names:
            if topic.startswith('/workzone/') and topic not in self.topics and types:
                self._subscribe(topic, types[0])
        with self._lock:
            for topic, entry in self.topics.items():
                try:
                    entry.publishers = max(entry.publishers, self.node.count_publishers(topic))
                except Exception:  # noqa: BLE001 - graph queries fail during shutdown
                    return

    def render(self, header: str) -> str:
        """The report text (several lines)."""
        with self._lock:
            lines = [header, f'  {"topic":<30} {"msgs":>7} {"Hz":>7}  notes']
            for topic in sorted(self.topics):
                e = self.topics[topic]
                if topic.startswith('/groundtruth/') and not e.count:
                    continue
                note = f'{e.payload_errors} invalid payload(s)' if e.payload_errors else ''
                if not e.count:
                    note = 'no messages' if e.publishers else 'no publisher (node not in this run)'
                lines.append(f'  {topic:<30} {e.count:>7} {e.rate:>7.2f}  {note}'.rstrip())
            if self.diag:
                parts = []
                for name in sorted(self.diag):
                    d = self.diag[name]
                    total = sum(d['drops'].values())
                    worst = {0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE'}.get(d['worst'], '?')
                    detail = ', '.join(f'{t} {n}' for t, n in d['drops'].items() if n)
                    parts.append(f'{name} {total}' + (f' ({detail})' if detail else '')
                                 + (f' worst {worst}' if d['worst'] else ''))
                lines.append('  dropped inputs (diagnostics): ' + '; '.join(parts))
            else:
                lines.append('  dropped inputs (diagnostics): no /diagnostics received')
            for name, d in sorted(self.diag.items()):
                for key, value in d.items():
                    if not key.endswith(' skipped while busy') or not int(value or 0):
                        continue
                    topic = key[:-len(' skipped while busy')]
                    total = int(value) + int(d.get(f'{topic} messages', 0) or 0)
                    lines.append(f'  {name}: {value} of {total} frames on {topic} skipped while '
                                 'busy (its input queue was full)')
                if int(d.get(LEAN_KEY, 0) or 0):
                    lines.append(f'  {name}: {d[LEAN_KEY]} of {d.get("frames detected", "?")} '
                                 'frames measured lean (it had fallen behind the camera)')
                lat = [f"{k.rsplit(' ', 2)[1]} {v} ms" for k, v in d.items()
                       if k.startswith('stamp to state latency') and v]
                if lat:
                    lines.append(f'  {name}: sensor stamp to /workzone/state ' + ', '.join(lat))
            gt = self.topics.get('/groundtruth/signs')
            if gt is not None and gt.count:
                truth = gt.nonempty_stamps
                text = f'  ground truth: {gt.count} frames, {len(truth)} with signs'
                for topic in ('/workzone/detections', '/workzone/tracks', '/workzone/signs'):
                    out = self.topics.get(topic)
                    if out is not None and out.count and truth:
                        hit = len(truth & out.nonempty_stamps)
                        text += (f'; with {topic.rsplit("/", 1)[1]} {hit} '
                                 f'({100.0 * hit / len(truth):.1f} %)')
                lines.append(text)
            return '\n'.join(lines)
