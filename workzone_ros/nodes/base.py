"""The shared node base: parameters, QoS helpers, input accounting and ``/diagnostics``.

Every workzone_ros node subclasses :class:`WorkzoneNode` and declares a ``PARAMS`` table of
:class:`Param`.  The base then

* declares them with descriptors (description, numeric range, string choices, read-only),
  reads them into the frozen ``self.params`` and logs the effective configuration in one block;
* warns about parameters given to this node (params file section, ``/**`` wildcard, ``-p``,
  ``parameter_overrides``) that no ``Param`` declares -- ROS ignores them silently;
* validates live changes (``ros2 param set``) and rejects them with a reason (a parameter
  used only at start-up, such as a topic, is declared ``read_only``);
* wraps every subscription made through its QoS helpers so a bad message is counted, logged
  once per reason per 5 s and dropped, and the node never dies on input (DESIGN.md,
  principle 4);
* publishes a ``diagnostic_msgs/DiagnosticArray`` on ``/diagnostics`` at 1 Hz with message,
  drop, age, publisher-count and processing-time figures per input topic, and detects the
  classic QoS mismatch (publishers exist, nothing arrives) and an input that stopped (its
  upstream killed, a sensor lost);
* notices a time jump backwards in the inputs' stamps (a looping bag, a restarted replay)
  and calls :meth:`WorkzoneNode.on_time_jump` once per jump, so each node resets what it
  keeps by stamp (counted in ``/diagnostics``);
* with ``use_sim_time`` and no ``/clock`` yet, says so once in the log and in
  ``/diagnostics`` (:meth:`WorkzoneNode.clock_running`) instead of stamping time 0.

Usage::

    class Detector(WorkzoneNode):
        PARAMS = (Param('image_topic', '/camera/image_raw', 'input image', read_only=True),
                  Param('threshold', 0.5, 'score threshold', min=0.0, max=1.0))
        INPUT_TOPICS = ('image_topic',)

        def __init__(self, **kwargs):
            super().__init__('detector', **kwargs)
            self.sensor_subscription(Image, self.params.image_topic, self._on_image)

    def main(args=None):
        return run_node(Detector, args)
"""
from __future__ import annotations

import collections
import dataclasses
import difflib
import math
import sys
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Optional

import numpy as np
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    SetParametersResult,
)
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_check_compatible,
)

from workzone_ros.core.sync import FrameGaps
from workzone_ros.nodes.conversions import InputError
from workzone_ros.nodes.params import (
    ConfigError,
    Param,
    params_files,
    section_matches,
    yaml_sections,
)

__all__ = ['Param', 'WorkzoneNode', 'run_node', 'InputError', 'ConfigError', 'TopicStats',
           'TIME_JUMP_NS']

HARDWARE_ID = 'workzone_ros'
_TIMING_WINDOW = 200            # processing times kept per topic for p50/p99
#: an input stamp older than the newest one seen by more than this is a time jump backwards
#: (a looping bag): the node resets; by less, a late or repeated message (counted only)
TIME_JUMP_NS = 2_000_000_000
#: wall seconds after a jump during which the other inputs' jumps are the same one
JUMP_SETTLE_S = 2.0

# Arguments rclpy.init() got in run_node(), for finding --params-file in the global args.
_GLOBAL_ARGS: Optional[list[str]] = None


class _Throttle:
    """Per-key rate limiting with a count of what was suppressed."""

    def __init__(self) -> None:
        self._last: dict[str, float] = {}
        self._suppressed: collections.Counter = collections.Counter()
        self._lock = threading.Lock()

    def __call__(self, key: str, period_s: float) -> Optional[int]:
        """None when the line must be suppressed, else how many were suppressed before it."""
        now = time.monotonic()
        with self._lock:
            last = self._last.get(key)
            if last is not None and now - last < period_s:
                self._suppressed[key] += 1
                return None
            self._last[key] = now
            return self._suppressed.pop(key, 0)


@dataclass
class TopicStats:
    """What the base knows about one input topic (wall-clock times from ``time.monotonic``)."""

    topic: str
    created: float
    subscription: Any = None
    messages: int = 0
    dropped: int = 0
    dropped_in_period: int = 0
    last_drop_reason: str = ''
    last_arrival: Optional[float] = None
    last_stamp: Any = None
    #: header stamps equal to / older than the previous message's on this topic (a replayed
    #: or reordered message; the node decides what to do with it, never dies on it)
    stamps_repeated: int = 0
    stamps_out_of_order: int = 0
    publishers_since: Optional[float] = None
    #: frames a latest-only sensor subscription never delivered (overwritten while busy)
    gaps: Optional[FrameGaps] = None
    times_s: collections.deque = dataclasses.field(
        default_factory=lambda: collections.deque(maxlen=_TIMING_WINDOW))


class WorkzoneNode(Node):
    """Base class of every workzone_ros node (see the module docstring).

    Attributes:
        PARAMS: the subclass's parameter table.
        INPUT_TOPICS: names of parameters that hold input topic names; they appear in
            ``/diagnostics`` even before (or without) a subscription through the helpers.
        params: frozen dataclass of the current parameter values (attribute per ``Param``).
        config_warnings: every configuration warning logged at start-up (for tests/tools).
    """

    PARAMS: tuple[Param, ...] = ()
    INPUT_TOPICS: tuple[str, ...] = ()

    def __init__(self, node_name: str, *, diagnostics_period_s: float = 1.0,
                 silent_input_warn_s: float = 3.0, **kwargs: Any) -> None:
        """Create the node, declare and read parameters, start the diagnostics timer.

        Args:
            node_name: the node's default name (remappable with ``__node:=``).
            diagnostics_period_s: period of ``/diagnostics`` (tests use a shorter one).
            silent_input_warn_s: WARN when a topic has publishers but no message for longer.
            **kwargs: passed to ``rclpy.node.Node`` (``parameter_overrides``, ``cli_args``,
                ``context``, ``namespace``, ...).

        Raises:
            ConfigError: an invalid ``PARAMS`` table or an invalid parameter value at start-up.
        """
        super().__init__(node_name, **kwargs)
        self._diag_period_s = float(diagnostics_period_s)
        self._silent_warn_s = float(silent_input_warn_s)
        self._throttle = _Throttle()
        self._stats_lock = threading.Lock()
        self._topic_stats: dict[str, TopicStats] = {}
        self._traceback_logged: set[str] = set()
        #: of the message being handled: when the middleware received it (system clock ns,
        #: 0 when not reported) and how long it then waited in its subscription's queue (s)
        self.input_received_ns, self.input_wait_s = 0, 0.0
        self.config_warnings: list[str] = []
        self._param_table: dict[str, Param] = {}
        self._cli_args = list(kwargs.get('cli_args') or [])
        self._use_global_args = kwargs.get('use_global_arguments', True)

        self.add_on_set_parameters_callback(self._validate_parameters)
        try:
            self._check_param_table()
            self._declare_params()
        except ConfigError:
            self.destroy_node()
            raise
        self.add_post_set_parameters_callback(self._parameters_set)
        self._warn_undeclared()
        self._log_configuration()

        self._jump: Optional[list] = None   # [wall, new stamp, newest since] of the last jump
        self.time_jumps = 0
        self._clock_waiting_since: Optional[float] = None
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self._wall_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._diag_timer = self.create_timer(self._diag_period_s, self._publish_diagnostics,
                                             clock=self._wall_clock)
        if self._sim_time():
            self._clock_timer = self.create_timer(0.1, self._check_clock,
                                                  clock=self._wall_clock)
            self._check_clock()

    # --- time -----------------------------------------------------------------------------

    def _sim_time(self) -> bool:
        return self.has_parameter('use_sim_time') and \
            bool(self.get_parameter('use_sim_time').value)

    def clock_running(self) -> bool:
        """False while ``use_sim_time`` is on and no ``/clock`` has come yet (time 0).

        A node must not stamp or age anything with its clock then: it waits (the base logs
        it once and ``/diagnostics`` says ``waiting for /clock``).
        """
        return not self._sim_time() or self.get_clock().now().nanoseconds > 0

    def _check_clock(self) -> None:
        if self.clock_running():
            if self._clock_waiting_since is not None:
                self.get_logger().info(
                    f'/clock is running (waited '
                    f'{time.monotonic() - self._clock_waiting_since:.1f} s)')
            self._clock_waiting_since = None
            self.destroy_timer(self._clock_timer)
            return
        if self._clock_waiting_since is None:
            self._clock_waiting_since = time.monotonic()
            self.get_logger().warning('use_sim_time is true and no /clock yet: waiting for it '
                                      '(nothing is stamped from the clock until it comes)')

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """Hook: the inputs' stamps jumped back from ``old_ns`` to ``new_ns`` (a looping bag).

        Called once per jump, before the callback of the message that showed it.  Nodes
        reset here whatever they keep by stamp (buffers, synchronisers, pose histories,
        tracks); the base already logged the jump and counts it in ``/diagnostics``.
        """

    def _note_stamp(self, ns: int, jumped_from: Optional[int]) -> Optional[str]:
        """``'jump'`` for a new time jump, ``'late'`` for a message from before the last one.

        ``jumped_from`` is the previous stamp of the same topic when this one is older by
        more than ``TIME_JUMP_NS`` (per topic: a CameraInfo stamped 0 next to live images is
        no jump).  The other inputs follow within ``JUMP_SETTLE_S``: the same jump, not a new
        one; a message of the old pass still in flight then is ``'late'``.
        """
        now = time.monotonic()
        j = self._jump
        if j is not None and now - j[0] < JUMP_SETTLE_S:
            if ns > j[2] + TIME_JUMP_NS:
                return 'late'
            j[2] = max(j[2], ns)
            return None
        if jumped_from is None:
            return None
        self._jump = [now, ns, ns]
        self.time_jumps += 1
        return 'jump'


    # --- parameters -----------------------------------------------------------------------

    def _check_param_table(self) -> None:
        attrs = set()
        for p in self.PARAMS:
            if p.name in self._param_table:
                raise ConfigError(f'{type(self).__name__}.PARAMS declares {p.name!r} twice')
            if not p.attr.isidentifier() or p.attr in attrs:
                raise ConfigError(f'parameter name {p.name!r} cannot be an attribute')
            p.kind()
            reason = p.check(p.default)
            if reason:
                raise ConfigError(f'{type(self).__name__}.PARAMS default invalid: {reason}')
            self._param_table[p.name] = p
            attrs.add(p.attr)
        self._params_cls = dataclasses.make_dataclass(
            f'{type(self).__name__}Params', [(p.attr, Any) for p in self.PARAMS], frozen=True)

    def _declare_params(self) -> None:
        overrides = getattr(self, '_parameter_overrides', {})
        for p in self.PARAMS:
            if p.name in overrides:
                reason = p.check(overrides[p.name].value)
                if reason:
                    raise ConfigError(f'node {self.get_fully_qualified_name()}: {reason}')
        try:
            self.declare_parameters('', [(p.name, p.default, p.descriptor())
                                         for p in self.PARAMS])
        except Exception as exc:  # noqa: BLE001 - rclpy raises several unrelated types
            raise ConfigError(f'node {self.get_fully_qualified_name()}: {exc}') from None
        self.params = self._read_params({})

    def _read_params(self, changed: dict[str, Any]) -> Any:
        values = {}
        for p in self.PARAMS:
            value = changed[p.name] if p.name in changed else self.get_parameter(p.name).value
            values[p.attr] = p.normalise(value)
        return self._params_cls(**values)

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for param in parameters:
            spec = self._param_table.get(param.name)
            if spec is None:
                continue
            if param.type_ == Parameter.Type.NOT_SET:
                return SetParametersResult(successful=False,
                                           reason=f'{param.name} cannot be unset')
            reason = spec.check(param.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _parameters_set(self, parameters: list[Parameter]) -> None:
        if not hasattr(self, 'params'):
            return              # the declaration itself
        changed = {p.name: p.value for p in parameters if p.name in self._param_table}
        if not changed:
            return
        self.params = self._read_params(changed)
        self.get_logger().info('parameters changed: ' + ', '.join(
            f'{k} = {getattr(self.params, self._param_table[k].attr)!r}' for k in changed))
        self.on_parameters_changed(changed)

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Hook for subclasses: called after ``self.params`` took accepted new values."""

    def _log_configuration(self) -> None:
        overrides = set(getattr(self, '_parameter_overrides', {}))
        lines = [f'configuration of {self.get_fully_qualified_name()}:']
        for p in self.PARAMS:
            value = getattr(self.params, p.attr)
            mark = '' if p.name not in overrides else '   (set)'
            lines.append(f'  {p.name} = {value!r}{mark}')
        if self.has_parameter('use_sim_time'):
            lines.append(f'  use_sim_time = {self.get_parameter("use_sim_time").value!r}')
        self.get_logger().info('\n'.join(lines))

    def _warn_undeclared(self) -> None:
        declared = set(self._param_table) | {'use_sim_time', 'start_type_description_service'}
        known = sorted(self._param_table)
        reported: set[str] = set()

        def hint(key: str) -> str:
            close = difflib.get_close_matches(key, known, n=1)
            return f' (did you mean {close[0]!r}?)' if close else ''

        files = params_files(self._cli_args)
        if self._use_global_args:
            global_args = _GLOBAL_ARGS if _GLOBAL_ARGS is not None else (
                sys.argv if self.context is rclpy.utilities.get_default_context() else [])
            files += params_files(global_args)
        fqn = self.get_fully_qualified_name()
        for path in files:
            try:
                with open(path, encoding='utf-8') as f:
                    doc = yaml.safe_load(f) or {}
            except (OSError, yaml.YAMLError) as exc:
                self._config_warning(f'cannot read params file {path}: {exc}')
                continue
            for section, params in yaml_sections(doc):
                if not section_matches(section, fqn):
                    continue
                for key in params:
                    if key in declared or key in reported:
                        continue
                    reported.add(key)
                    self._config_warning(
                        f'params file {path}: {section}: {key!r} is not a parameter of node '
                        f'{fqn}; it is ignored{hint(key)}')
        # Everything rcl resolved for this node (-p, files, parameter_overrides=...).
        for key in sorted(getattr(self, '_parameter_overrides', {})):
            if key not in declared and key not in reported:
                reported.add(key)
                self._config_warning(f'parameter override {key!r} is not a parameter of node '
                                     f'{fqn}; it is ignored{hint(key)}')

    def _config_warning(self, text: str) -> None:
        self.config_warnings.append(text)
        self.get_logger().warning(text)

    # --- QoS helpers ----------------------------------------------------------------------

    #: seconds without a raw image after which an image node takes the compressed stream
    RAW_IMAGE_TIMEOUT_S = 2.0

    def image_subscription(self, topic: str, callback: Callable[[Any], None],
                           compressed: bool, depth: int = 5) -> Any:
        """Subscribe to a camera the way image_transport users expect.

        ``compressed`` true: ``<topic>/compressed`` (sensor_msgs/CompressedImage) only.
        Otherwise the raw ``topic`` and, as a fallback, ``<topic>/compressed``: a compressed
        frame is passed to ``callback`` only while no raw frame has arrived for
        ``RAW_IMAGE_TIMEOUT_S`` (a bag or a vehicle that records JPEG only works without
        configuration; with both published, raw wins).  ``/diagnostics`` says which stream
        is in use (``image transport``).  Returns the primary subscription.
        """
        from sensor_msgs.msg import CompressedImage, Image
        ctopic = topic.rstrip('/') + '/compressed'
        self._image_transport = 'none yet'
        if compressed:
            def on_compressed_only(msg: Any) -> None:
                self._image_transport = 'compressed'
                callback(msg)
            return self.sensor_subscription(CompressedImage, ctopic, on_compressed_only,
                                            depth=depth)
        last_raw = [-math.inf]

        def on_raw(msg: Any) -> None:
            last_raw[0] = time.monotonic()
            self._image_transport = 'raw'
            callback(msg)

        def on_fallback(msg: Any) -> None:
            if time.monotonic() - last_raw[0] < self.RAW_IMAGE_TIMEOUT_S:
                return                                  # raw frames are flowing: raw wins
            self._image_transport = 'compressed (no raw images)'
            callback(msg)

        self._compressed_fallback_sub = self.sensor_subscription(
            CompressedImage, ctopic, on_fallback, depth=depth)
        return self.sensor_subscription(Image, topic, on_raw, depth=depth)

    def image_topic_of(self, msg: Any) -> str:
        """The resolved topic an image of :meth:`image_subscription` came from."""
        topic = self._image_sub.topic_name
        if type(msg).__name__ == 'CompressedImage' and not topic.endswith('/compressed'):
            return topic + '/compressed'
        return topic

    def sensor_subscription(self, msg_type: type, topic: str, callback: Callable[[Any], None],
                            depth: int = 5) -> Any:
        """Subscribe with the sensor-data profile (best effort, keep last ``depth``).

        Best effort subscriptions connect to reliable and best-effort publishers alike.
        """
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                         reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)
        return self._subscribe(msg_type, topic, callback, qos, count_gaps=True)

    def reliable_subscription(self, msg_type: type, topic: str,
                              callback: Callable[[Any], None], depth: int = 10,
                              transient_local: bool = False) -> Any:
        """Subscribe reliably (optionally transient local, to get a latched last message)."""
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if transient_local
                         else DurabilityPolicy.VOLATILE)
        return self._subscribe(msg_type, topic, callback, qos)

    def reliable_publisher(self, msg_type: type, topic: str, depth: int = 10,
                           transient_local: bool = False) -> Any:
        """Publisher for outputs: reliable, optionally transient local (latched)."""
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if transient_local
                         else DurabilityPolicy.VOLATILE)
        return self.create_publisher(msg_type, topic, qos)

    def sensor_publisher(self, msg_type: type, topic: str, depth: int = 5) -> Any:
        """Publisher with the sensor-data profile (best effort, keep last ``depth``)."""
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                         reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)
        return self.create_publisher(msg_type, topic, qos)

    def _subscribe(self, msg_type: type, topic: str, callback: Callable[[Any], None],
                   qos: QoSProfile, count_gaps: bool = False) -> Any:
        stats = self._stats_for(self.resolve_topic_name(topic))
        if count_gaps and stats.gaps is None:
            stats.gaps = FrameGaps()

        def wrapped(msg: Any, info: Any) -> None:
            arrival = time.monotonic()
            t0 = time.perf_counter()
            received = int((info or {}).get('received_timestamp') or 0)
            self.input_received_ns = received
            self.input_wait_s = max(0.0, (time.time_ns() - received) * 1e-9) if received else 0.0
            header = getattr(msg, 'header', None)
            with self._stats_lock:
                stats.messages += 1
                stats.last_arrival = arrival
                stamp = getattr(header, 'stamp', None)
                bad_stamp = None           # an invalid stamp: dropped below, not counted here
                if stamp is not None and not 0 <= stamp.nanosec < 1_000_000_000:
                    bad_stamp, stamp = stamp, None
                previous = stats.last_stamp
                jump = None
                if stamp is not None:
                    stats.last_stamp = stamp
                    ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
                    jumped_from = None
                    if previous is not None:
                        before = int(previous.sec) * 1_000_000_000 + int(previous.nanosec)
                        jumped_from = before if ns < before - TIME_JUMP_NS else None
                        stats.stamps_repeated += ns == before
                        stats.stamps_out_of_order += ns < before
                    if stats.gaps is not None:
                        stats.gaps.add(ns)
                    jump = self._note_stamp(ns, jumped_from)
            try:
                if bad_stamp is not None:
                    raise InputError(f'stamp nanosec {bad_stamp.nanosec} is outside [0, 1e9)')
                if jump == 'late':
                    raise InputError('stamped before the time jumped back (still in flight '
                                     'from before the jump)')
                if jump == 'jump':
                    self.get_logger().info(
                        f'time jumped back {(before - ns) * 1e-9:.1f} s on {stats.topic} '
                        '(a looping bag?): buffers reset')
                    self.on_time_jump(before, ns)
                callback(msg)
            except InputError as exc:
                self.drop(stats.topic, str(exc))
            except Exception as exc:  # noqa: BLE001 - the node must survive any message
                reason = f'internal error: {type(exc).__name__}: {exc}'
                key = f'{stats.topic}:{type(exc).__name__}'
                if key not in self._traceback_logged:
                    self._traceback_logged.add(key)
                    self.get_logger().error(f'{stats.topic}: {reason}\n'
                                            f'{traceback.format_exc().rstrip()}')
                self.drop(stats.topic, reason)
            finally:
                elapsed = time.perf_counter() - t0
                with self._stats_lock:
                    stats.times_s.append(elapsed)

        sub = self.create_subscription(msg_type, topic, wrapped, qos)
        stats.subscription = sub
        stats.created = time.monotonic()
        return sub

    def _stats_for(self, topic: str) -> TopicStats:
        with self._stats_lock:
            stats = self._topic_stats.get(topic)
            if stats is None:
                stats = self._topic_stats[topic] = TopicStats(topic, time.monotonic())
            return stats

    # --- input accounting -----------------------------------------------------------------

    def drop(self, topic: str, reason: str) -> None:
        """Count one invalid input on ``topic`` and log it (rate limited per reason).

        Args:
            topic: the input topic (as subscribed; relative names are resolved).
            reason: one line saying what was wrong.
        """
        if topic not in self._topic_stats:
            try:
                topic = self.resolve_topic_name(topic)
            except Exception:  # noqa: BLE001 - an unresolvable name is still a useful key
                pass
        stats = self._stats_for(topic)
        with self._stats_lock:
            stats.dropped += 1
            stats.dropped_in_period += 1
            stats.last_drop_reason = reason
        self.warn_throttled(f'drop:{topic}:{reason}', f'dropped message on {topic}: {reason}')

    def warn_throttled(self, key: str, text: str, period_s: float = 5.0) -> None:
        """Log ``text`` as a warning at most once per ``period_s`` per ``key``.

        The next line logged for a key says how many were suppressed since the last one.
        """
        suppressed = self._throttle(key, period_s)
        if suppressed is None:
            return
        if suppressed:
            text += f' ({suppressed} similar suppressed in the last {period_s:g} s)'
        self.get_logger().warning(text)

    def topic_stats(self) -> dict[str, TopicStats]:
        """A snapshot copy of the per-topic input statistics (keyed by resolved topic)."""
        with self._stats_lock:
            return {k: dataclasses.replace(v, times_s=collections.deque(v.times_s))
                    for k, v in self._topic_stats.items()}

    # --- diagnostics ----------------------------------------------------------------------

    def _input_topics(self) -> list[str]:
        for name in self.INPUT_TOPICS:
            value = getattr(self.params, name.replace('.', '_'), None)
            if isinstance(value, str) and value:
                try:
                    self._stats_for(self.resolve_topic_name(value))
                except Exception:  # noqa: BLE001 - an invalid name is reported elsewhere
                    pass
        return sorted(self._topic_stats)

    def diagnostic_status(self) -> DiagnosticStatus:
        """This node's current ``DiagnosticStatus`` (what the 1 Hz timer publishes)."""
        now = time.monotonic()
        level, problems, values = DiagnosticStatus.OK, [], []
        for topic in self._input_topics():
            stats = self._topic_stats[topic]
            try:
                publishers = self.count_publishers(topic)
            except Exception:  # noqa: BLE001 - graph queries fail during shutdown
                publishers = -1
            with self._stats_lock:
                dropped_now, stats.dropped_in_period = stats.dropped_in_period, 0
                messages, dropped = stats.messages, stats.dropped
                repeated, out_of_order = stats.stamps_repeated, stats.stamps_out_of_order
                reason, arrival = stats.last_drop_reason, stats.last_arrival
                times = np.fromiter(stats.times_s, dtype=float)
            age = None if arrival is None else now - arrival
            if publishers <= 0:
                stats.publishers_since = None
            elif stats.publishers_since is None:
                stats.publishers_since = now
            stamp = stats.last_stamp
            values += [
                (f'{topic} messages', str(messages)),
                (f'{topic} dropped', str(dropped)),
                (f'{topic} last drop reason', reason),
                (f'{topic} age of last input s', 'never' if age is None else f'{age:.3f}'),
                (f'{topic} last stamp', '' if stamp is None
                 else f'{stamp.sec}.{stamp.nanosec:09d}'),
                (f'{topic} stamps repeated', str(repeated)),
                (f'{topic} stamps out of order', str(out_of_order)),
                (f'{topic} publishers', str(publishers)),
                (f'{topic} publishers matched', str(stats.subscription.get_publisher_count()
                                                    if stats.subscription is not None else -1)),
                (f'{topic} processing p50 ms',
                 f'{np.percentile(times, 50) * 1e3:.3f}' if times.size else ''),
                (f'{topic} processing p99 ms',
                 f'{np.percentile(times, 99) * 1e3:.3f}' if times.size else ''),
            ]
            if stats.gaps is not None:
                # frames that arrived while the node was busy and were overwritten (keep
                # last): they never reached the callback, so only the stamps' gaps tell
                values.append((f'{topic} skipped while busy', str(stats.gaps.skipped)))
            if dropped_now:
                level = DiagnosticStatus.WARN
                problems.append(f'{dropped_now} message(s) dropped on {topic}: {reason}')
            # silence counts from the later of the last message and the publishers' appearance
            silent_since = max(arrival if arrival is not None else -math.inf,
                               stats.publishers_since if stats.publishers_since is not None
                               else math.inf)
            if stats.subscription is not None and publishers == 0 and age is not None \
                    and age > self._silent_warn_s:
                # it was flowing and its publisher is gone (a killed upstream node, a lost
                # driver): a gap, not a configuration problem
                level = DiagnosticStatus.WARN
                text = f'no message on {topic} for {age:.1f} s and no publisher left'
                self.warn_throttled(f'silent:{topic}', text)
                problems.append(text)
            if stats.subscription is not None and publishers > 0 \
                    and now - silent_since > self._silent_warn_s:
                level = DiagnosticStatus.WARN
                if arrival is None:
                    detail = self._qos_detail(stats)
                    if detail:
                        text = f'publisher(s) on {topic} but nothing received: QoS mismatch?'
                    else:
                        # compatible QoS: the upstream has published nothing yet (a replay
                        # that has not started, an upstream waiting for its own input)
                        text = (f'publisher(s) on {topic} but nothing received yet (their QoS '
                                'is compatible: is the upstream publishing?)')
                    self.warn_throttled(f'silent:{topic}', text + detail)
                else:
                    text = f'publisher(s) on {topic} but no message for {age:.1f} s'
                    self.warn_throttled(f'silent:{topic}', text)
                problems.append(text)
        transport = getattr(self, '_image_transport', None)
        if transport is not None:
            values.append(('image transport', transport))
        values.append(('time jumps back', str(self.time_jumps)))
        if not self.clock_running():
            level = DiagnosticStatus.WARN
            problems.append('use_sim_time is true and no /clock yet: waiting for it')
        try:
            values += list(self.extra_diagnostics())
        except Exception as exc:  # noqa: BLE001 - a subclass's figures never kill diagnostics
            values.append(('extra diagnostics failed', str(exc)))
        status = DiagnosticStatus(level=level, name=self.get_name(), hardware_id=HARDWARE_ID,
                                  message='; '.join(problems) if problems else 'ok')
        status.values = [KeyValue(key=k, value=v) for k, v in values]
        return status

    def extra_diagnostics(self) -> list[tuple[str, str]]:
        """Node-specific ``(key, value)`` figures appended to ``/diagnostics`` (override)."""
        return []

    def _qos_detail(self, stats: TopicStats) -> str:
        sub = stats.subscription
        if sub is None:
            return ''
        try:
            infos = self.get_publishers_info_by_topic(stats.topic)
            sub_qos = sub.qos_profile
            bad = [i for i in infos if qos_check_compatible(i.qos_profile, sub_qos)[0].name
                   == 'ERROR']
        except Exception:  # noqa: BLE001 - the detail is best effort
            return ''
        if not bad:
            return ''
        return (f' ({len(bad)} publisher(s) offer '
                f'{_rel(bad[0].qos_profile)}/{_dur(bad[0].qos_profile)}, this subscription '
                f'asks {_rel(sub_qos)}/{_dur(sub_qos)})')

    def _publish_diagnostics(self) -> None:
        try:
            msg = DiagnosticArray()
            # system time while a simulated clock has not started (never time 0)
            clock = self.get_clock() if self.clock_running() else Clock()
            msg.header.stamp = clock.now().to_msg()
            msg.status = [self.diagnostic_status()]
            self._diag_pub.publish(msg)
        except Exception as exc:  # noqa: BLE001 - diagnostics must never kill the node
            self.warn_throttled('diagnostics', f'diagnostics failed: {exc}')


def _rel(qos: QoSProfile) -> str:
    return ReliabilityPolicy(int(qos.reliability)).name.lower()


def _dur(qos: QoSProfile) -> str:
    return DurabilityPolicy(int(qos.durability)).name.lower()


def _one_thread() -> None:
    """One OpenCV and one BLAS/OpenMP thread per node process: the graph runs one process per
    node on a few cores, where each library's own thread pool only adds contention (the
    launcher also sets the variables before the interpreter starts; a node started on its
    own gets the limit here, after numpy loaded)."""
    try:
        import cv2
        cv2.setNumThreads(1)
    except ImportError:
        pass
    try:
        from threadpoolctl import threadpool_limits
        threadpool_limits(1)
    except ImportError:             # scikit-learn's dependency; absent only in odd installs
        pass


def run_node(node_factory: Callable[[], Node], args: Optional[list[str]] = None) -> int:
    """The Jazzy ``main()``: init, build the node, spin, shut down cleanly.

    Args:
        node_factory: builds the node (usually the node class).
        args: command line (``sys.argv`` when None).

    Returns:
        Process exit code: 0 on a normal or Ctrl-C shutdown, 2 on a configuration error, 1 on
        any other failure.
    """
    global _GLOBAL_ARGS
    _GLOBAL_ARGS = list(args) if args is not None else list(sys.argv)
    _one_thread()
    missing = [f for f in params_files(_GLOBAL_ARGS) if not Path(f).is_file()]
    if missing:
        print(f'configuration error: params file not found: {missing[0]}', file=sys.stderr)
        return 2
    try:
        rclpy.init(args=args)
    except Exception as exc:  # noqa: BLE001 - RCLError: an unparsable params file or argument
        text = ' '.join(str(exc).split())
        print(f'configuration error: {text}', file=sys.stderr)
        return 2
    node = None
    code = 0
    try:
        node = node_factory()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ConfigError as exc:
        print(f'configuration error: {exc}', file=sys.stderr)
        code = 2
    except Exception:  # noqa: BLE001 - report and exit non-zero
        traceback.print_exc()
        code = 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
