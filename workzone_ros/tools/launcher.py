"""``workzone-ros launch``: run the node graph, optionally replaying a bag, with a report.

What ``ros2 launch`` would do for this package, without the ROS CLI:

* every node in its own process (``python -m workzone_ros.nodes.<name> --ros-args
  --params-file FILE -r __node:=<name> [-p use_sim_time:=true]``), in its own process group,
  its output prefixed ``[name] ``;
* a node that dies is restarted with exponential backoff (0.5, 1, 2, 4 ... s, capped); one
  that dies more than ``--max-restarts`` times within ``--restart-window`` seconds stops
  everything (exit code 3, naming the node).  A node exiting with code 2 (configuration
  error, see ``nodes.base.run_node``) is not restarted: exit code 3 at once;
* ``--bag``: the bag is checked before any node starts (exit 2 with one line if unusable),
  replayed in-process once the nodes are up (``/clock``, ``use_sim_time``), and the launcher
  exits 0 after the bag and a short drain;
* SIGINT / SIGTERM: SIGINT to every child group, SIGKILL after a deadline, all gone within
  5 s; children also get SIGKILL from the kernel if the launcher itself is killed;
* ``--loop`` replays the bag over and over (time jumps back at each pass; ``--duration``
  ends the run), ``--cut TOPIC:START:DURATION`` withholds a topic for a window of bag time
  (a lost sensor; see ``workzone-ros play``), ``--duration S`` stops after S s of playing;
* ``--single-process``: every node class (``NODE_CLASS``) in one executor in this process;
* ``--report``: counts and rates of the ``/workzone/*`` outputs, drops from ``/diagnostics``
  and, with ``/groundtruth/signs`` in the bag, frames with ground-truth signs vs frames with
  detections / tracks / signs (a coarse recall).

Node names: ``lidar_cluster`` (module ``workzone_ros.nodes.lidar_cluster``), a dotted module
path (``pkg.my_node``, node name ``my_node``), or ``alias=module`` for a second instance.
"""
from __future__ import annotations

import argparse
import collections
import ctypes
import importlib
import importlib.util
import os
import signal
import subprocess
import sys
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, TextIO

__all__ = ['PLANNED_NODES', 'NodeSpec', 'Launcher', 'ReportCollector', 'default_params_file',
           'resolve_nodes', 'fastdds_shm_profile', 'apply_dds_profile', 'main']

#: Nodes launched by default when their module exists, in data-flow order.
PLANNED_NODES = ('lidar_cluster', 'projector', 'color_detector', 'tracker', 'classifier',
                 'fusion')
PACKAGE = 'workzone_ros'
EXIT_BAG = 2
EXIT_CRASH_LOOP = 3
_TICK_S = 0.05
_KILL_AFTER_S = 3.0        # SIGINT -> SIGKILL; + reaping stays well inside 5 s
_PR_SET_PDEATHSIG = 1

# Runs a node module's main() when the module has no ``if __name__ == '__main__'`` block.
_RUNNER = ('import importlib, sys; m = sys.argv[1]; sys.argv = [m] + sys.argv[2:]; '
           'sys.exit(importlib.import_module(m).main(sys.argv) or 0)')


# Fast DDS participant profile: shared memory with 32 MB segments (+ UDP for everything else).
# The default 512 kB segment sends images and clouds over fragmented UDP, where best-effort
# (sensor-data) subscribers lose most of them (compare ``workzone-ros bench transport``
# with and without ``--default-transport``).
_SHM_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>workzone_shm</transport_id>
      <type>SHM</type>
      <segment_size>{segment}</segment_size>
    </transport_descriptor>
    <transport_descriptor>
      <transport_id>workzone_udp</transport_id>
      <type>UDPv4</type>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="workzone_participant" is_default_profile="true">
    <rtps>
      <userTransports>
        <transport_id>workzone_shm</transport_id>
        <transport_id>workzone_udp</transport_id>
      </userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
    </rtps>
  </participant>
</profiles>
"""


def fastdds_shm_profile(segment_mb: int = 32) -> Path:
    """Write (once) the large-segment shared-memory Fast DDS profile; returns its path."""
    import tempfile
    text = _SHM_PROFILE.format(segment=int(segment_mb) * 1024 * 1024)
    path = Path(tempfile.gettempdir()) / f'workzone_fastdds_shm_{os.getuid()}_{segment_mb}.xml'
    if not path.is_file() or path.read_text() != text:
        tmp = path.with_suffix(f'.{os.getpid()}.tmp')
        tmp.write_text(text)
        tmp.replace(path)
    return path


def apply_dds_profile(choice: str) -> Optional[str]:
    """Set ``FASTRTPS_DEFAULT_PROFILES_FILE`` for this process and its children.

    Must run before rclpy creates a participant in this process.

    Args:
        choice: ``'shm'`` (built-in large-segment profile, unless the user already set a
            profile file), ``'none'``, or the path of a Fast DDS XML file.

    Returns:
        The profile file in effect, or None.
    """
    current = os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE')
    if choice == 'none':
        return current
    if 'fastrtps' not in os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp'):
        return current
    if choice == 'shm':
        if current:
            return current
        path = str(fastdds_shm_profile())
    else:
        if not Path(choice).is_file():
            raise LaunchError(f'Fast DDS profile not found: {choice}')
        path = str(Path(choice).resolve())
    os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = path
    return path


class LaunchError(Exception):
    """A launch configuration problem (bad node name, missing params file)."""


@dataclass(frozen=True)
class NodeSpec:
    """One node to run: its ROS node name and its Python module."""

    name: str
    module: str


def default_params_file() -> Optional[Path]:
    """``config/workzone.yaml`` next to the package (source checkout) or in the share dir."""
    from workzone_ros.resources import config_path
    path = config_path('workzone.yaml')
    return path if path.is_file() else None


def _module_exists(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def resolve_nodes(text: Optional[str]) -> list[NodeSpec]:
    """Parse ``--nodes`` (default: every planned node whose module exists).

    Raises:
        LaunchError: a node whose module cannot be found, or a duplicate name.
    """
    if text is None:
        return [NodeSpec(n, f'{PACKAGE}.nodes.{n}') for n in PLANNED_NODES
                if _module_exists(f'{PACKAGE}.nodes.{n}')]
    specs: list[NodeSpec] = []
    for item in (s.strip() for s in text.split(',')):
        if not item or item == 'none':
            continue
        alias, _, target = item.rpartition('=')
        module = target if '.' in target else f'{PACKAGE}.nodes.{target}'
        name = alias or target.rsplit('.', 1)[-1]
        if not _module_exists(module):
            raise LaunchError(f'node {item!r}: module {module} not found')
        if any(s.name == name for s in specs):
            raise LaunchError(f'node name {name!r} given twice (use alias=module)')
        specs.append(NodeSpec(name, module))
    return specs


def _has_main_block(module: str) -> bool:
    try:
        spec = importlib.util.find_spec(module)
        origin = spec.origin if spec else None
        return bool(origin) and '__main__' in Path(origin).read_text(errors='replace')
    except (ImportError, ValueError, OSError):
        return False


def _declares(module: str, param: str) -> bool:
    """True when the node class of ``module`` declares the parameter ``param``."""
    try:
        cls = getattr(importlib.import_module(module), 'NODE_CLASS', None)
    except Exception:  # noqa: BLE001 - the node's own start reports import problems
        return False
    return any(p.name == param for p in getattr(cls, 'PARAMS', ()))


def _ros_args(spec: NodeSpec, params: Path, sim_time: bool, log_level: Optional[str],
              compressed: bool = False) -> list[str]:
    args = ['--ros-args', '--params-file', str(params), '-r', f'__node:={spec.name}']
    if sim_time:
        args += ['-p', 'use_sim_time:=true']
    if compressed and _declares(spec.module, 'compressed'):
        args += ['-p', 'compressed:=true']
    if log_level:
        args += ['--log-level', log_level]
    return args


def _signal_name(code: int) -> str:
    if code < 0:
        try:
            return f'signal {signal.Signals(-code).name}'
        except ValueError:
            return f'signal {-code}'
    return f'code {code}'


def _set_pdeathsig(parent: int) -> None:
    """In the child before exec: die with the launcher, even if it is SIGKILLed."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except Exception:  # noqa: BLE001 - best effort (non-Linux)
        pass
    if os.getppid() != parent:  # the launcher died before prctl took effect
        os._exit(1)


class _Child:
    """One node process and its restart bookkeeping."""

    def __init__(self, spec: NodeSpec) -> None:
        self.spec = spec
        self.proc: Optional[subprocess.Popen] = None
        self.reader: Optional[threading.Thread] = None
        self.crashes: collections.deque[float] = collections.deque()
        self.restart_at: Optional[float] = None
        self.restarts = 0
        self.pids: list[int] = []

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None


# --- report ----------------------------------------------------------------------------------

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
                            or kv.key.endswith((' skipped while busy', ' messages')):
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
                                 'busy (it keeps the newest)')
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


# --- the launcher ----------------------------------------------------------------------------

class Launcher:
    """Supervises node processes (or one in-process executor), the bag and the report."""

    def __init__(self, args: argparse.Namespace, specs: list[NodeSpec], params: Path,
                 out: TextIO = sys.stdout) -> None:
        """Prepare; nothing starts until :meth:`run`."""
        self.args = args
        self.specs = specs
        self.params = params
        from workzone_ros.tools.launch_console import Console, default_log_path
        log_file = getattr(args, 'log_file', None)
        log_path = None if log_file == '' else Path(log_file) if log_file \
            else default_log_path()
        self.say = Console(out, log_path, verbose=bool(getattr(args, 'verbose', True)))
        self.state_watcher = None
        self.children = [_Child(s) for s in specs]
        self._stop = threading.Event()
        self._stop_reason = ''
        self._signals = 0
        self.exit_code = 0
        self.reader = None
        self._ctx = None
        self._node = None
        self._executor = None
        self._spin_thread: Optional[threading.Thread] = None
        self._player = None
        self._player_thread: Optional[threading.Thread] = None
        self._player_error: Optional[str] = None
        self.report: Optional[ReportCollector] = None
        self.recorder = None
        self.score_result: Optional[dict] = None
        self._inproc_nodes: list = []
        self._run_dir: Optional[str] = None
        self._t_start = time.monotonic()
        self._play_t0: Optional[float] = None

    def log(self, text: str) -> None:
        """One ``[launch]`` line."""
        self.say('launch', text)

    # -- signals --------------------------------------------------------------------------

    def _on_signal(self, signum, frame) -> None:  # noqa: ARG002
        self._signals += 1
        if self._signals == 1:
            self._stop_reason = signal.Signals(signum).name
            self._stop.set()
        else:  # a second Ctrl-C: do not wait for graceful exits
            for child in self.children:
                self._kill_group(child, signal.SIGKILL)

    # -- processes ------------------------------------------------------------------------

    def _command(self, spec: NodeSpec) -> list[str]:
        ros = _ros_args(spec, self.params, bool(self.args.bag), self.args.log_level,
                        self._compressed_bag())
        if _has_main_block(spec.module):
            return [sys.executable, '-m', spec.module, *ros]
        return [sys.executable, '-c', _RUNNER, spec.module, *ros]

    def _compressed_bag(self) -> bool:
        """The bag has JPEG images and no raw ones: image nodes read ``.../compressed``."""
        topics = set(self.reader.topics) if self.reader is not None else set()
        return '/camera/image_raw/compressed' in topics and '/camera/image_raw' not in topics

    def _spawn(self, child: _Child) -> None:
        # one folder per launch: a restarted node finds what its previous run left (the
        # fusion's phase checkpoint), a new launch starts clean
        if self._run_dir is None:
            import tempfile
            self._run_dir = tempfile.mkdtemp(prefix='workzone_run_')
        env = dict(os.environ, PYTHONUNBUFFERED='1', WORKZONE_RUN_DIR=self._run_dir)
        for var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS',
                    'NUMBA_NUM_THREADS'):
            env.setdefault(var, '1')      # one thread per node process (--nodes sets more)
        if sys.stdout.isatty():
            env.setdefault('RCUTILS_COLORIZED_OUTPUT', '1')
        parent = os.getpid()
        proc = subprocess.Popen(
            self._command(child.spec), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, env=env, start_new_session=True,
            preexec_fn=lambda: _set_pdeathsig(parent))  # noqa: PLW1509 - see _set_pdeathsig
        child.proc = proc
        child.pids.append(proc.pid)
        child.restart_at = None
        child.reader = threading.Thread(target=self._pump, args=(child.spec.name, proc),
                                        daemon=True, name=f'out-{child.spec.name}')
        child.reader.start()
        self.log(f'started {child.spec.name} (pid {proc.pid}): {child.spec.module}')

    def _pump(self, name: str, proc: subprocess.Popen) -> None:
        assert proc.stdout is not None
        for raw in iter(proc.stdout.readline, b''):
            self.say(name, raw.decode(errors='replace').rstrip('\r\n'))
        proc.stdout.close()

    def _kill_group(self, child: _Child, sig: int) -> None:
        if child.proc is not None and child.proc.poll() is None:
            try:
                os.killpg(child.proc.pid, sig)
            except (ProcessLookupError, PermissionError):
                pass

    def _supervise(self, now: float) -> None:
        """Restart dead nodes with backoff; stop everything on a crash loop."""
        for child in self.children:
            if child.proc is None:
                if child.restart_at is not None and now >= child.restart_at:
                    self._spawn(child)
                continue
            code = child.proc.poll()
            if code is None:
                continue
            name = child.spec.name
            child.proc.wait()
            if child.reader is not None:
                child.reader.join(0.5)
            child.proc = None
            if code == 2:
                self.log(f'{name} exited with a configuration error (code 2); not restarting')
                self._fail(f'node {name} has a configuration error')
                return
            child.crashes.append(now)
            while child.crashes and now - child.crashes[0] > self.args.restart_window:
                child.crashes.popleft()
            if len(child.crashes) > self.args.max_restarts:
                self.log(f'{name} exited ({_signal_name(code)}) {len(child.crashes)} times in '
                         f'{self.args.restart_window:g} s; giving up')
                self._fail(f'node {name} keeps crashing')
                return
            delay = min(self.args.backoff_cap, 0.5 * 2 ** (len(child.crashes) - 1))
            child.restarts += 1
            child.restart_at = now + delay
            self.log(f'{name} exited ({_signal_name(code)}); restart #{child.restarts} in '
                     f'{delay:g} s')

    def _fail(self, reason: str) -> None:
        self.exit_code = EXIT_CRASH_LOOP
        self._stop_reason = reason
        self._stop.set()

    def _shutdown_children(self) -> None:
        alive = [c for c in self.children if c.alive]
        for child in alive:
            self._kill_group(child, signal.SIGINT)
        deadline = time.monotonic() + _KILL_AFTER_S
        while any(c.alive for c in alive) and time.monotonic() < deadline:
            time.sleep(_TICK_S)
        for child in alive:
            if child.alive:
                self.log(f'{child.spec.name} did not stop after SIGINT; SIGKILL')
                self._kill_group(child, signal.SIGKILL)
        for child in self.children:
            if child.proc is not None:
                try:
                    child.proc.wait(timeout=1.0)
                except subprocess.TimeoutExpired:
                    pass
                # the group may hold stragglers the node started; they go too
                try:
                    os.killpg(child.proc.pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
            if child.reader is not None:
                child.reader.join(0.5)

    # -- rclpy side (report, bag, single-process) ---------------------------------------------

    def _need_rclpy(self) -> bool:
        return bool(self.args.bag or self.args.report or self.args.single_process
                    or getattr(self.args, 'state', False) or getattr(self.args, 'score', None))

    def _start_rclpy(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        self._ctx = Context()
        init_args = ['workzone-launch']
        if self.args.log_level:
            init_args += ['--ros-args', '--log-level', self.args.log_level]
        rclpy.init(args=init_args, context=self._ctx,
                   signal_handler_options=SignalHandlerOptions.NO)
        self._node = rclpy.create_node('workzone_launch', context=self._ctx,
                                       start_parameter_services=False)
        if self.args.report:
            self.report = ReportCollector(self._node)
        if getattr(self.args, 'score', None) and self.reader is not None:
            from workzone_ros.tools.live_score import LiveRecorder
            self.recorder = LiveRecorder(self._node)
        if getattr(self.args, 'state', False) and any(s.name == 'fusion' for s in self.specs):
            from workzone_ros.tools.launch_console import StateWatcher
            t0 = self.reader.start_time if self.reader is not None else None
            self.state_watcher = StateWatcher(self._node, self.say, t0_ns=t0)
        if self.args.single_process:
            # One thread: rclpy's MultiThreadedExecutor under the GIL lost three quarters of
            # the camera frames here (15 of 38 processed at half rate); a single-threaded
            # executor kept up with every frame at full rate.
            self._executor = SingleThreadedExecutor(context=self._ctx)
            for spec in self.specs:
                try:
                    self._inproc_nodes.append(self._make_inproc_node(spec))
                except LaunchError:
                    raise
                except Exception as exc:  # noqa: BLE001 - ConfigError, import errors, ...
                    self.log(f'{spec.name} failed to start: {type(exc).__name__}: {exc}')
                    self._fail(f'node {spec.name} failed to start')
                    return
                self.log(f'created {spec.name} in-process ({spec.module})')
            for node in self._inproc_nodes:
                self._executor.add_node(node)
        else:
            self._executor = SingleThreadedExecutor(context=self._ctx)
        self._executor.add_node(self._node)
        self._spin_thread = threading.Thread(target=self._spin, daemon=True, name='spin')
        self._spin_thread.start()

    def _make_inproc_node(self, spec: NodeSpec):
        module = importlib.import_module(spec.module)
        cls = getattr(module, 'NODE_CLASS', None)
        if cls is None:
            raise LaunchError(f'{spec.module} has no NODE_CLASS; cannot run --single-process')
        cli = _ros_args(spec, self.params, bool(self.args.bag), None, self._compressed_bag())
        return cls(context=self._ctx, cli_args=cli)

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException
        try:
            while self._ctx.ok() and not self._stop.is_set():
                self._executor.spin_once(timeout_sec=0.1)
        except ExternalShutdownException:
            pass
        except Exception:  # noqa: BLE001 - an exception escaped a node callback
            self.log('exception in the executor:\n' + traceback.format_exc().rstrip())
            self._fail('an in-process node raised')

    def _stop_rclpy(self) -> None:
        import rclpy
        if self._player is not None:
            self._player.stop()
        if self._player_thread is not None:
            self._player_thread.join(3.0)
        if self._spin_thread is not None:
            self._spin_thread.join(2.0)
        for node in self._inproc_nodes:
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001 - shutting down anyway
                pass
        if self._executor is not None:
            self._executor.shutdown(timeout_sec=1.0)
        if self._node is not None:
            self._node.destroy_node()
        if self._ctx is not None:
            rclpy.try_shutdown(context=self._ctx)

    def _graph_ready(self) -> bool:
        """All launched nodes visible, the bag topics' subscriber counts and the graph's own
        topics' (``/workzone/...``: node to node) endpoint counts settled."""
        try:
            names = set(self._node.get_node_names())
            counts = tuple(self._node.count_subscribers(t) for t in sorted(self.reader.topics))
            inner = sorted(t for t, _ in self._node.get_topic_names_and_types()
                           if t.startswith('/workzone/'))
            counts += tuple((self._node.count_publishers(t), self._node.count_subscribers(t))
                            for t in inner)
        except Exception:  # noqa: BLE001 - graph not available yet
            return False
        if any(s.name not in names for s in self.specs if not self.args.single_process):
            self._settle = None
            return False
        now = time.monotonic()
        if getattr(self, '_settle', None) is None or self._settle[0] != counts:
            self._settle = (counts, now)
            return False
        return now - self._settle[1] >= 0.5

    def _start_player(self) -> None:
        from workzone_ros.tools.player import BagPlayer
        wait_for = [t for t in sorted(self.reader.topics)
                    if self._node.count_subscribers(t) > 0]
        self._player = BagPlayer(self.reader, rate=self.args.rate, context=self._ctx,
                                 node_name='workzone_player', quiet=self.args.quiet_play,
                                 wait_for=wait_for, wait_timeout=5.0,
                                 loop=bool(getattr(self.args, 'loop', False)),
                                 cuts=getattr(self.args, 'cuts', ()),
                                 log=lambda text: self.say('play', text.removeprefix('[play] ')))
        self._play_t0 = time.monotonic()
        self.log(f'playing {self.reader.summary()} at rate {self.args.rate:g}')

        def play() -> None:
            try:
                self._player.run()
            except Exception as exc:  # noqa: BLE001 - BagError mid-file, rclpy errors
                self._player_error = str(exc)

        self._player_thread = threading.Thread(target=play, daemon=True, name='player')
        self._player_thread.start()

    # -- main loop ------------------------------------------------------------------------

    def run(self) -> int:
        """Run until the bag is done, a signal arrives, or a node crash-loops."""
        signal.signal(signal.SIGINT, self._on_signal)
        signal.signal(signal.SIGTERM, self._on_signal)
        if self.args.bag:
            from workzone_ros.bagio import BagError, open_reader
            try:
                self.reader = open_reader(self.args.bag)
            except BagError as exc:
                print(f'workzone-ros launch: error: {exc}', file=sys.stderr)
                return EXIT_BAG
        if self._compressed_bag():
            self.log('the bag has compressed images only: image nodes read '
                     '/camera/image_raw/compressed')
        names = ', '.join(s.name for s in self.specs) or 'none'
        mode = 'in one process' if self.args.single_process else 'one process each'
        self.log(f'nodes: {names} ({mode}); params {self.params}')
        if getattr(self.args, 'dds_profile_file', None):
            self.log(f'Fast DDS profile {self.args.dds_profile_file}')
        try:
            if not self.args.single_process:
                for child in self.children:
                    self._spawn(child)
            if self._need_rclpy():
                self._start_rclpy()
            self._loop()
        except LaunchError as exc:
            self.log(f'error: {exc}')
            self.exit_code = EXIT_BAG
        except Exception:  # noqa: BLE001 - report, then clean up children regardless
            self.log('launcher failure:\n' + traceback.format_exc().rstrip())
            self.exit_code = 1
        finally:
            self._stop.set()  # ends the spin thread before the context goes
            if self._stop_reason:
                self.log(f'stopping ({self._stop_reason})')
            if self._player is not None:
                self._player.stop()
            self._shutdown_children()
            if self._ctx is not None:
                self._stop_rclpy()
            if self.report is not None:
                print(self.report.render(self._report_header()), flush=True)
            if self.recorder is not None and not self._player_error:
                self._score()
            if self.reader is not None:
                self.reader.close()
        if self._player_error and not self.exit_code:
            print(f'workzone-ros launch: error: {self._player_error}', file=sys.stderr)
            self.exit_code = EXIT_BAG
        if self._run_dir is not None:
            import shutil
            shutil.rmtree(self._run_dir, ignore_errors=True)
        if self.say.log_path is not None:
            self.log(f'full log: {self.say.log_path}')
        self.log(f'exit code {self.exit_code}')
        self.say.close()
        return self.exit_code

    def _score(self) -> None:
        from workzone_ros.tools.live_score import score_live
        try:
            self.score_result = score_live(self.args.bag, self.recorder, self.args.score)
            if self.score_result is None:
                self.log('no /groundtruth/workzone in the bag: nothing to score')
        except Exception as exc:  # noqa: BLE001 - a scoring problem never hides the run
            self.log(f'scoring failed: {type(exc).__name__}: {exc}')

    def _loop(self) -> None:
        state = 'waiting' if self.reader is not None else 'running'
        wait_deadline = time.monotonic() + self.args.ready_timeout
        drain_until = 0.0
        duration = getattr(self.args, 'duration', None)
        while not self._stop.is_set():
            now = time.monotonic()
            self._supervise(now)
            if self._stop.is_set():
                break
            if duration and state in ('playing', 'running') and \
                    now - (self._play_t0 or self._t_start) >= duration:
                self._stop_reason = f'--duration {duration:g} s'
                break
            if state == 'waiting':
                if self._graph_ready() or now > wait_deadline:
                    if now > wait_deadline:
                        self.log(f'nodes not all up after {self.args.ready_timeout:g} s; '
                                 'playing anyway')
                    self._start_player()
                    state = 'playing'
            elif state == 'playing' and not self._player_thread.is_alive():
                if self._player_error:
                    self._stop_reason = 'bag error'
                    break
                state, drain_until = 'draining', now + self.args.drain
                self.log(f'bag finished; draining {self.args.drain:g} s')
            elif state == 'draining' and now >= drain_until:
                self._stop_reason = 'bag done'
                break
            time.sleep(_TICK_S)

    def _report_header(self) -> str:
        wall = time.monotonic() - self._t_start
        if self.reader is not None and self._player is not None:
            st = self._player.stats
            return (f'== report: {self.reader.path} {st.bag_s:.1f} s of bag at rate '
                    f'{self.args.rate:g}, {st.published} messages played, wall {wall:.1f} s')
        return f'== report: live graph, wall {wall:.1f} s'


def build_parser() -> argparse.ArgumentParser:
    """The ``workzone-ros launch`` argument parser."""
    p = argparse.ArgumentParser(prog='workzone-ros launch', description=__doc__.split('\n')[0])
    p.add_argument('--params', metavar='FILE', help='ROS params YAML (default: '
                   'config/workzone.yaml of the package)')
    p.add_argument('--bag', metavar='PATH', help='replay this bag with /clock and use_sim_time')
    p.add_argument('--rate', type=float, default=1.0, help='bag replay rate (0 = max)')
    p.add_argument('--nodes', metavar='A,B', help='comma-separated node names or modules '
                   f'(default: those of {", ".join(PLANNED_NODES)} that exist)')
    p.add_argument('--single-process', action='store_true',
                   help='all nodes in one executor in this process')
    p.add_argument('--report', action='store_true', help='print an output report at the end')
    p.add_argument('--log-level', metavar='L',
                   choices=['debug', 'info', 'warn', 'error', 'fatal'], help='node log level')
    p.add_argument('--max-restarts', type=int, default=5, metavar='N',
                   help='give up on a node that dies more than N times in the window (5)')
    p.add_argument('--restart-window', type=float, default=60.0, metavar='S',
                   help='crash-counting window in seconds (60)')
    p.add_argument('--backoff-cap', type=float, default=8.0, metavar='S',
                   help='longest restart delay (8 s)')
    p.add_argument('--drain', type=float, default=2.0, metavar='S',
                   help='seconds to keep running after the bag ends (2)')
    p.add_argument('--ready-timeout', type=float, default=30.0, metavar='S',
                   help='longest wait for the nodes before playing the bag (30)')
    p.add_argument('--loop', action='store_true', help='replay the bag over and over (the '
                   'time jumps back at each pass; --duration ends the run)')
    p.add_argument('--cut', action='append', default=[], metavar='TOPIC:START:DURATION',
                   help='withhold TOPIC (and the topics under it) from the nodes for DURATION '
                   's from START s of bag time, on every pass (repeatable): a lost sensor')
    p.add_argument('--duration', type=float, metavar='S', help='stop (exit 0) after S s of '
                   'playing the bag (or of running, without a bag)')
    p.add_argument('--quiet-play', action='store_true', help='no bag progress lines')
    p.add_argument('--state', action='store_true', help='print /workzone/state changes as a '
                   'planner sees them (phase, speed limit, lanes, evidence)')
    p.add_argument('--score', metavar='DIR', help='with a synthetic bag: score the '
                   "published states against the bag's ground truth at the end (Table IV) "
                   'and write DIR/README.md with the timeline')
    p.add_argument('--verbose', action='store_true', help="show every node's start-up "
                   'configuration on the console (always in the log file)')
    p.add_argument('--log-file', metavar='FILE', help='where every line goes (default: '
                   "~/.ros/log/workzone_launch_<time>.log; '' = none)")
    p.add_argument('--dds-profile', default='shm', metavar='shm|none|FILE',
                   help='Fast DDS profile for every process: shm = shared memory with 32 MB '
                   'segments so large images/clouds are not fragmented over UDP (default; '
                   'an already set FASTRTPS_DEFAULT_PROFILES_FILE wins), none, or an XML file')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros launch``; returns the exit code."""
    args = build_parser().parse_args(argv)
    if args.rate < 0:
        print('workzone-ros launch: error: --rate must be >= 0', file=sys.stderr)
        return EXIT_BAG
    from workzone_ros.tools.player import parse_cut
    try:
        args.cuts = [parse_cut(c) for c in args.cut]
    except ValueError as exc:
        print(f'workzone-ros launch: error: {exc}', file=sys.stderr)
        return EXIT_BAG
    if args.duration is not None and not args.duration > 0:
        print('workzone-ros launch: error: --duration must be > 0', file=sys.stderr)
        return EXIT_BAG
    params = Path(args.params) if args.params else default_params_file()
    if params is None or not params.is_file():
        print(f'workzone-ros launch: error: params file not found: '
              f'{params or "config/workzone.yaml"}', file=sys.stderr)
        return EXIT_BAG
    try:
        specs = resolve_nodes(args.nodes)
        args.dds_profile_file = apply_dds_profile(args.dds_profile)
    except LaunchError as exc:
        print(f'workzone-ros launch: error: {exc}', file=sys.stderr)
        return EXIT_BAG
    if not args.bag and not specs:
        print('workzone-ros launch: error: no nodes to launch', file=sys.stderr)
        return EXIT_BAG
    return Launcher(args, specs, params.resolve()).run()


if __name__ == '__main__':
    sys.exit(main())
