"""The launcher's supervisor (:class:`Launcher`): one process per node (or every node in one
in-process executor), restarts with backoff, the crash-loop and signal rules, the bag replay
and the end-of-run report and score.  The behaviour is described in the docstring of
:mod:`workzone_ros.tools.launcher` (``workzone-ros launch``).
"""
from __future__ import annotations

import argparse
import collections
import ctypes
import importlib
import os
import signal
import subprocess
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Optional, TextIO

from workzone_ros.tools.launch_nodes import (
    _RUNNER,
    LaunchError,
    NodeSpec,
    _has_main_block,
    _ros_args,
)
from workzone_ros.tools.launch_report import ReportCollector
from workzone_ros.tools.player import LATE_S

__all__ = ['EXIT_BAG', 'EXIT_CRASH_LOOP', 'Launcher']

EXIT_BAG = 2
EXIT_CRASH_LOOP = 3
_TICK_S = 0.05
_KILL_AFTER_S = 3.0        # SIGINT -> SIGKILL; + reaping stays well inside 5 s
_PR_SET_PDEATHSIG = 1


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
        # node name -> its last /diagnostics values (its inputs' matching, before playing)
        self._node_inputs: dict[str, dict[str, str]] = {}
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
        if self.reader is not None:
            # each node's inputs as it sees them: the bag plays once they are matched
            from diagnostic_msgs.msg import DiagnosticArray
            from rclpy.qos import QoSProfile
            self._node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                           QoSProfile(depth=100))
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
        return now - self._settle[1] >= 0.5 and self._inputs_matched()

    def _on_diag(self, msg) -> None:
        for status in msg.status:
            self._node_inputs[status.name] = {kv.key: kv.value for kv in status.values}

    def _inputs_matched(self) -> bool:
        """Every launched node has said (``/diagnostics``) that each of its subscriptions is
        matched with every publisher of the topic this process sees: a reliable, volatile
        topic keeps nothing for a subscription matched late, so the frames published before
        would be lost to it (the tracker missed the demo's first 9 detections once).  A node
        that publishes no ``/diagnostics`` (not a workzone node) is not waited for."""
        reporting = {i.node_name for i in
                     self._node.get_publishers_info_by_topic('/diagnostics')}
        for spec in self.specs:
            values = self._node_inputs.get(spec.name)
            if values is None and spec.name in reporting:
                return False
            for key, value in list((values or {}).items()):
                if key.endswith(' publishers matched') and 0 <= int(value) < \
                        self._node.count_publishers(key[:-len(' publishers matched')]):
                    return False            # (-1: a topic the node does not subscribe)
        return True

    def _start_player(self) -> None:
        from workzone_ros.tools.player import BagPlayer
        # every subscription the graph has (the player's own publishers match them one by
        # one: one matched is not all)
        wait_for = {t: n for t in sorted(self.reader.topics)
                    if (n := self._node.count_subscribers(t)) > 0}
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
            head = (f'== report: {self.reader.path} {st.bag_s:.1f} s of bag at rate '
                    f'{self.args.rate:g}, {st.published} messages played, wall {wall:.1f} s')
            if st.late:
                head += (f'\n  player: {st.late} messages sent over {LATE_S * 1e3:.0f} ms late '
                         f'(worst {st.late_max_s * 1e3:.0f} ms): the player was kept from '
                         'running and then sent them in a burst, which can overflow the '
                         "nodes' queues (skips counted while it lasted are the player's)")
            return head
        return f'== report: live graph, wall {wall:.1f} s'
