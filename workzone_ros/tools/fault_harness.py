"""One node under test for ``workzone-ros evaluate faults``: the node with its real
subscriptions, fed by a peer node over real topics in a private rclpy context
(:class:`Harness`, :class:`PrivateRos`), and what one malformed message did to it
(:class:`Outcome`).
"""
from __future__ import annotations

import importlib
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

from workzone_ros.tools.fault_targets import Input, Target

__all__ = ['T_FAULT_S', 'T_RECOVER_S', 'GOOD_EVERY_S', 'Outcome', 'PrivateRos', 'Harness']

T_FAULT_S = 5.0          # wait for the malformed message to be taken
T_RECOVER_S = 8.0        # wait for a good output after it
GOOD_EVERY_S = 0.25      # a new good frame while waiting


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
