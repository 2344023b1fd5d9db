"""What the launcher's console shows: a planner's view of the graph, the rest in a log file.

* :class:`Console` writes every line of every node to a log file and, on the console, folds
  each node's start-up configuration block (one line per parameter, about 200 lines for the
  whole graph) into one line, unless ``--verbose``.
* :class:`StateWatcher` subscribes to ``/workzone/state`` as a planner would (reliable,
  transient local) and prints one line per change of what a planner acts on -- phase, speed
  limit, lanes, stale inputs -- with the evidence behind it, as it happens.  It keeps every
  state it saw for the end-of-run summary.
"""
from __future__ import annotations

import re
import threading
import time
from pathlib import Path
from typing import Any, Callable, Optional, TextIO

__all__ = ['Console', 'StateWatcher', 'describe_state', 'default_log_path']

_CONFIG_HEAD = re.compile(r'configuration of (/\S+):\s*$')
_CONFIG_LINE = re.compile(r'^\s{2}\S+ = ')


def default_log_path() -> Path:
    """``~/.ros/log/workzone_launch_<date>-<time>-<pid>.log`` (ROS's log folder)."""
    import os
    stamp = time.strftime('%Y%m%d-%H%M%S')
    folder = Path(os.environ.get('ROS_LOG_DIR') or Path.home() / '.ros' / 'log')
    return folder / f'workzone_launch_{stamp}-{os.getpid()}.log'


class Console:
    """Line-atomic output: the console (filtered) and a log file (everything).

    Args:
        stream: the console.
        log_path: the log file (None: no file).
        verbose: show the configuration blocks on the console too.
    """

    def __init__(self, stream: TextIO, log_path: Optional[Path] = None,
                 verbose: bool = False) -> None:
        self._stream = stream
        self._lock = threading.Lock()
        self.verbose = verbose
        self.log_path = log_path
        self._file: Optional[TextIO] = None
        if log_path is not None:
            try:
                log_path.parent.mkdir(parents=True, exist_ok=True)
                self._file = open(log_path, 'a', buffering=1)  # noqa: SIM115 - closed in close()
            except OSError:
                self.log_path = None
        self._in_config: dict[str, int] = {}     # node -> parameter lines folded so far

    def __call__(self, prefix: str, text: str) -> None:
        """Write ``[prefix] text`` to the log file, and to the console unless folded."""
        line = f'[{prefix}] {text}\n'
        with self._lock:
            if self._file is not None:
                try:
                    self._file.write(line)
                except (OSError, ValueError):
                    pass
            if not self._show(prefix, text):
                return
            try:
                self._stream.write(line)
                self._stream.flush()
            except (OSError, ValueError):
                pass

    def _show(self, prefix: str, text: str) -> bool:
        if self.verbose:
            return True
        if prefix in self._in_config:
            if _CONFIG_LINE.match(text):
                self._in_config[prefix] += 1
                return False
            del self._in_config[prefix]
        if _CONFIG_HEAD.search(text):
            self._in_config[prefix] = 0
            where = f' (in {self.log_path})' if self.log_path else ''
            self._stream.write(f'[{prefix}] configuration logged{where}; --verbose shows '
                               'it here\n')
            return False
        return True

    def close(self) -> None:
        """Close the log file."""
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None


def _fmt_lanes(state: Any) -> str:
    parts = []
    if state.lane_shift != 'none':
        parts.append(f'shift {state.lane_shift}')
    if state.lanes_closed:
        parts.append('closed ' + '+'.join(state.lanes_closed))
    return ', '.join(parts) or '-'


def describe_state(state: Any) -> str:
    """One line: phase, speed limit, lanes, stale inputs and the newest evidence."""
    speed = f'{state.speed_limit_mph} mph' if state.speed_limit_mph is not None else (
        'unread' if 'speed_limit_value' in state.unknowns else '-')
    text = (f'{state.phase.upper():<11} p={state.likelihood:.2f}  speed {speed:<7} '
            f'lanes {_fmt_lanes(state)}')
    if state.stale_inputs:
        text += f'  STALE {",".join(state.stale_inputs)}'
    if state.evidence:
        ev = sorted(state.evidence, key=lambda e: e.stamp.to_ns())[-3:]
        text += '  evidence: ' + ', '.join(
            f'{e.class_key}' + (f'#{e.track_id}' if e.track_id is not None else '')
            + (f'@{e.distance_m:.0f}m' if e.distance_m is not None else '') for e in ev)
    return text


def _key(state: Any) -> tuple:
    return (state.phase, state.speed_limit_mph, state.lane_shift, tuple(state.lanes_closed),
            tuple(state.stale_inputs), 'speed_limit_value' in state.unknowns)


class StateWatcher:
    """A planner-like subscriber that prints state changes and keeps every state.

    Args:
        node: an rclpy node of the launcher.
        say: ``say(prefix, text)`` printer.
        topic: the state topic.
        t0_ns: bag start stamp, so times print relative to it (None: absolute seconds).
    """

    def __init__(self, node: Any, say: Callable[[str, str], None],
                 topic: str = '/workzone/state', t0_ns: Optional[int] = None) -> None:
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String
        self._say = say
        self._t0 = t0_ns
        self._last: Optional[tuple] = None
        self._lock = threading.Lock()
        self.states: list = []
        self.invalid = 0
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(String, topic, self._on_state, qos)

    def _on_state(self, msg: Any) -> None:
        from workzone_ros.interfaces import PayloadError, WorkzoneState, decode
        try:
            state = decode(msg.data, WorkzoneState)
        except PayloadError:
            with self._lock:
                self.invalid += 1
            return
        with self._lock:
            self.states.append(state)
            key = _key(state)
            if key == self._last:
                return
            self._last = key
        ns = state.header.stamp.to_ns()
        if self._t0 is not None and ns < self._t0:
            when = 't=  start  '          # published before the replay's clock began
        else:
            t = (ns - self._t0) * 1e-9 if self._t0 is not None else ns * 1e-9
            when = f't={t:7.2f} s'
        self._say('state', f'{when}  {describe_state(state)}')
