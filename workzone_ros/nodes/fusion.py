"""``fusion`` node: ``/workzone/signs`` (+ ``/odom``) -> ``/workzone/state`` for a planner.

Thin wrapper around :class:`workzone_ros.core.fusion.WorkzoneFusion` (Seo et al. III.C:
discounted temporal voting per tracked sign, Gaussian propagation of the classification
confidence -- causal, over metres travelled when odometry is present -- and a state machine
``unknown -> none -> approaching -> inside -> leaving -> none``).

Publishes ``/workzone/state`` (``WorkzoneState``; reliable, transient local, depth 1: a
planner that joins late gets the current state at once) on every frame of signs, and at
``publish_rate_hz`` while no signs arrive; ``/workzone/active`` (Bool, transient local) and
``/workzone/likelihood`` (Float32).  It starts in ``unknown`` and says so until evidence
builds: a restarted fusion never publishes a false ``none``.  Inputs that go quiet (the signs
chain, the camera, the LiDAR, odometry) are listed in ``stale_inputs``; the state then
degrades visibly, it never goes silently to ``none``.  A stamp that jumps backwards (a
looping bag) resets the fusion's memory (counted in ``/diagnostics``); a frame repeated or
up to 2 s out of order is dropped with its reason instead.  The stale list is checked at
10 Hz and a change of it is published at once (not at the next ``publish_rate_hz`` tick), so
a lost input shows in the state at most 0.1 s after its limit: ``stale_periods`` times the
90th percentile of its own recent arrival intervals, between ``stale_min_s`` and
``stale_after_s`` (:mod:`workzone_ros.core.liveness`: a 15 Hz camera is stale after 0.25 s,
a sign chain that a loaded machine slows down does not flicker in and out of the list).  With
``use_sim_time`` the state waits for ``/clock`` (nothing is stamped with time 0).
"""
from __future__ import annotations

import collections
import json
import os
import time
from pathlib import Path
from typing import Any, Optional

import msgspec
import numpy as np
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, PointCloud2
from std_msgs.msg import Bool, Float32, String

from workzone_ros import interfaces as I
from workzone_ros.core.fusion import FusionConfig, WorkzoneFusion
from workzone_ros.core.liveness import InputLiveness, LivenessConfig
from workzone_ros.core.odometry import TravelledDistance
from workzone_ros.nodes import conversions as conv
from workzone_ros.nodes.base import ConfigError, InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.params import params_from_dataclass

__all__ = ['FusionNode', 'NODE_CLASS', 'main']

#: signs older than the last fused frame by more than this are a time jump (a looping bag:
#: the memory resets); by less, a repeated or reordered frame (dropped, counted)
JUMP_BACK_NS = 2_000_000_000
#: how often the stale inputs are checked (a change is published at once)
STALE_CHECK_S = 0.1


#: One parameter per FusionConfig field: default, description and range from its knob().
_CORE_PARAMS = params_from_dataclass(FusionConfig)


def _check_candidates(msg: PointCloud2) -> None:
    """A candidates cloud must parse (the LiDAR chain is alive only if it does)."""
    arr = conv.pointcloud2_to_array(msg)
    missing = [f for f in ('x', 'y', 'z') if f not in (arr.dtype.names or ())]
    if missing:
        raise InputError(f'candidates cloud has no {"/".join(missing)} field')


def config_from_params(params: Any) -> FusionConfig:
    """The core configuration from the node's ``params`` (ValueError when invalid)."""
    return FusionConfig(**{p.attr: getattr(params, p.attr) for p in _CORE_PARAMS})


class FusionNode(WorkzoneNode):
    """Work-zone state fusion (see the module docstring)."""

    PARAMS = (
        Param('signs_topic', '/workzone/signs', 'input Signs payloads', read_only=True),
        Param('odom_topic', '/odom', 'odometry: evidence propagates over metres travelled '
              '(empty: over time)', read_only=True),
        Param('detections_topic', '/workzone/detections', "the colour stage's channelizing "
              'device counts (empty: none)', read_only=True),
        Param('camera_info_topic', '/camera/camera_info', 'camera liveness (stale_inputs)',
              read_only=True),
        Param('lidar_topic', '/workzone/lidar/candidates', 'LiDAR liveness: the LiDAR chain '
              'publishes a candidates cloud per scan (stale_inputs; empty: none)',
              read_only=True),
        Param('state_topic', '/workzone/state', 'output WorkzoneState', read_only=True),
        Param('active_topic', '/workzone/active', 'output Bool', read_only=True),
        Param('likelihood_topic', '/workzone/likelihood', 'output Float32', read_only=True),
        Param('publish_rate_hz', 2.0, 'state re-published at this rate while no signs '
              'arrive', min=0.1, max=100.0),
        Param('stale_after_s', 1.0, 'an input seen before and silent for longer is stale '
              '(the longest limit)', min=0.05, max=60.0),
        Param('stale_min_s', 0.25, 'an input is never stale sooner than this after its last '
              'message', min=0.01, max=60.0),
        Param('stale_periods', 2.0, "between the two: this many times the 90th percentile of "
              "the input's own recent arrival intervals", min=0.1, max=100.0),
        Param('resume_file', '', 'where the phase is checkpointed, so that a fusion '
              'restarted mid-zone stays unknown (never a false none) until evidence rebuilds '
              '(empty: $WORKZONE_RUN_DIR/<node>_phase.json when the launcher sets it)',
              read_only=True),
    ) + _CORE_PARAMS
    INPUT_TOPICS = ('signs_topic', 'odom_topic', 'detections_topic', 'camera_info_topic',
                    'lidar_topic')

    def __init__(self, **kwargs: Any) -> None:
        """Create the node; raises ConfigError on an invalid fusion configuration."""
        super().__init__('fusion', **kwargs)
        p = self.params
        try:
            self._fusion = WorkzoneFusion(config_from_params(p))
        except ValueError as exc:
            self.destroy_node()
            raise ConfigError(f'fusion configuration: {exc}') from None
        self._odom = TravelledDistance()
        self._odom_seen = False
        self._channelizers: collections.OrderedDict[int, int] = collections.OrderedDict()
        self._liveness = InputLiveness(self._liveness_config())
        self._last_publish = 0.0
        self._last_stamp: Optional[I.Time] = None
        self._signs_ns: Optional[int] = None
        self._latency_ms: collections.deque = collections.deque(maxlen=500)
        self._state_pub = self.reliable_publisher(String, p.state_topic, depth=1,
                                                  transient_local=True)
        self._active_pub = self.reliable_publisher(Bool, p.active_topic, depth=1,
                                                   transient_local=True)
        self._likelihood_pub = self.reliable_publisher(Float32, p.likelihood_topic)
        self._signs_sub = self.reliable_subscription(String, p.signs_topic, self._on_signs)
        self._odom_sub = (self.reliable_subscription(Odometry, p.odom_topic, self._on_odom,
                                                     depth=50) if p.odom_topic else None)
        self._det_sub = (self.reliable_subscription(String, p.detections_topic,
                                                    self._on_detections)
                         if p.detections_topic else None)
        self._info_sub = (self.sensor_subscription(
            CameraInfo, p.camera_info_topic, self._seen('camera', conv.camera_info_to_numpy),
            depth=1) if p.camera_info_topic else None)
        self._lidar_sub = (self.reliable_subscription(
            PointCloud2, p.lidar_topic, self._seen('lidar', _check_candidates), depth=5)
            if p.lidar_topic else None)
        self._published_stale: tuple[str, ...] = ()
        self._timer = self.create_timer(min(STALE_CHECK_S, 1.0 / p.publish_rate_hz),
                                        self._on_timer)
        self._resume_path = self._resume_file()
        self._saved_phase: Optional[str] = None
        self._resume()
        if self.clock_running():        # else the first timer tick after /clock publishes
            self._publish(self._fusion.tick(self._now_time(), stale_inputs=()))

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Apply a new fusion configuration (the memory is kept when the core allows)."""
        self._liveness.config = self._liveness_config()
        try:
            cfg = config_from_params(self.params)
        except ValueError as exc:
            self.get_logger().error(f'fusion configuration not applied: {exc}')
            return
        self._fusion.config = cfg

    # --- restart ----------------------------------------------------------------------------

    def _resume_file(self) -> Optional[Path]:
        if self.params.resume_file:
            return Path(self.params.resume_file)
        run_dir = os.environ.get('WORKZONE_RUN_DIR')
        return Path(run_dir) / f'{self.get_name()}_phase.json' if run_dir else None

    def _resume(self) -> None:
        """After a restart inside a zone: unknown, and no none until evidence rebuilds."""
        if self._resume_path is None or not self._resume_path.is_file():
            return
        try:
            phase = json.loads(self._resume_path.read_text()).get('phase')
        except (OSError, ValueError, AttributeError) as exc:
            self.get_logger().warning(f'{self._resume_path}: unreadable checkpoint ({exc})')
            return
        if phase in ('approaching', 'inside', 'leaving'):
            self._fusion.hold_none(f'restarted while {phase}')
            self.get_logger().warning(f'restarted while {phase}: unknown until the evidence '
                                      'rebuilds (no none before an END sign or the timeout)')

    def _checkpoint(self, phase: str) -> None:
        if self._resume_path is None or phase == self._saved_phase or phase == 'unknown':
            return
        try:
            tmp = self._resume_path.with_suffix('.tmp')
            tmp.write_text(json.dumps({'phase': phase}))
            tmp.replace(self._resume_path)
            self._saved_phase = phase
        except OSError as exc:
            self.warn_throttled('checkpoint', f'cannot checkpoint the phase: {exc}')

    # --- inputs ---------------------------------------------------------------------------

    def _seen(self, name: str, check):
        """A liveness callback: a message that ``check`` accepts shows the input is alive (a
        malformed one raises ConversionError: dropped with its reason, not a sign of life)."""
        def callback(msg: Any) -> None:
            check(msg)
            self._liveness.seen(name, time.monotonic())
        return callback

    def _stale(self) -> list[str]:
        return self._liveness.stale(time.monotonic())

    def _liveness_config(self) -> LivenessConfig:
        p = self.params         # the parameters' ranges make every combination valid
        return LivenessConfig(min_s=min(p.stale_min_s, p.stale_after_s),
                              max_s=p.stale_after_s, periods=p.stale_periods)

    def _on_odom(self, msg: Odometry) -> None:
        pos = msg.pose.pose.position
        stamp = conv.stamp_to_time(msg.header.stamp).to_sec()
        try:
            self._odom.update(stamp, float(pos.x), float(pos.y))
        except ValueError as exc:
            raise InputError(str(exc)) from None
        self._odom_seen = True
        self._liveness.seen('odom', time.monotonic())

    def _on_detections(self, msg: String) -> None:
        dets = conv.string_to_payload(msg, I.Detections)
        if dets.channelizers is not None:
            self._channelizers[dets.header.stamp.to_ns()] = dets.channelizers
            while len(self._channelizers) > 60:
                self._channelizers.popitem(last=False)

    def _on_signs(self, msg: String) -> None:
        signs = conv.string_to_payload(msg, I.Signs)
        ns = signs.header.stamp.to_ns()
        last = self._signs_ns
        if last is not None and last - JUMP_BACK_NS <= ns <= last:
            # a repeated or reordered frame is not a looping bag: it must not wipe the memory
            raise InputError(f'signs stamped {ns * 1e-9:.3f} are not after the last fused '
                             f'frame ({last * 1e-9:.3f}): repeated or out of order')
        self._signs_ns = ns
        self._liveness.seen('signs', time.monotonic())
        resets = self._fusion.resets
        state = self._fusion.update(
            signs, odom_distance_m=self._odom.distance_m if self._odom_seen else None,
            channelizers=self._channelizers.pop(ns, None), stale_inputs=self._stale())
        if self._fusion.resets != resets:
            self.get_logger().info('time jumped back: fusion memory reset')
            self._channelizers.clear()
            self._last_stamp = None         # the state's stamps restart with the new time
        self._publish(state)
        if self.clock_running():
            lag = self.get_clock().now().nanoseconds - ns
            self._latency_ms.append(lag * 1e-6)

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """A looping bag (seen on odometry or the camera): the state restarts at ``unknown``
        with an empty memory, its stamps restart with the new time."""
        self._fusion.reset()
        self._fusion.resets += 1
        # where the vehicle is now is not known: no none before evidence (END or timeout)
        self._fusion.hold_none('the time jumped back (a looping bag?)')
        self._channelizers.clear()
        self._odom = TravelledDistance()
        self._odom_seen = False
        self._signs_ns = None
        self._last_stamp = None
        self.get_logger().info('time jumped back: fusion memory reset, state unknown')

    def _on_timer(self) -> None:
        if not self.clock_running():
            return                      # use_sim_time and no /clock yet: the base says so
        changed = tuple(self._stale()) != self._published_stale
        if not changed and \
                time.monotonic() - self._last_publish < 0.9 / self.params.publish_rate_hz:
            return
        state = self._fusion.tick(self._now_time(),
                                  odom_distance_m=self._odom.distance_m if self._odom_seen
                                  else None, stale_inputs=self._stale())
        self._publish(state)

    def _now_time(self) -> I.Time:
        ns = self.get_clock().now().nanoseconds
        if self._last_stamp is not None and ns < self._last_stamp.to_ns():
            return self._last_stamp
        return I.Time.from_ns(ns)

    def _publish(self, state: I.WorkzoneState) -> None:
        if self._last_stamp is not None and state.header.stamp.to_ns() < \
                self._last_stamp.to_ns():
            # a late frame after a timer tick: a planner never sees the stamps go back
            state = msgspec.structs.replace(state, header=msgspec.structs.replace(
                state.header, stamp=self._last_stamp))
        self._last_stamp = state.header.stamp
        self._published_stale = tuple(state.stale_inputs)
        self._state_pub.publish(conv.payload_to_string(state))
        self._active_pub.publish(Bool(data=bool(state.active)))
        self._likelihood_pub.publish(Float32(data=float(state.likelihood)))
        self._last_publish = time.monotonic()
        self._checkpoint(state.phase)

    def extra_diagnostics(self) -> list[tuple[str, str]]:
        """Resets, ignored class keys, odometry glitches and the stamp-to-state latency."""
        lat = np.asarray(self._latency_ms, dtype=float)
        return [
            ('fusion resets (time jumped back)', str(self._fusion.resets)),
            ('unknown class keys ignored', str(self._fusion.unknown_classes)),
            ('odometry steps rejected', str(self._odom.rejected)),
            ('stamp to state latency p50 ms',
             f'{np.percentile(lat, 50):.1f}' if lat.size else ''),
            ('stamp to state latency p99 ms',
             f'{np.percentile(lat, 99):.1f}' if lat.size else ''),
        ]


NODE_CLASS = FusionNode


def main(args: Optional[list[str]] = None) -> int:
    """Entry point ``fusion``."""
    return run_node(FusionNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
