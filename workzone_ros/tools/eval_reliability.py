"""``workzone-ros evaluate reliability``: the live graph under time jumps, kills, lost sensors
and load, with a JSON report (docs/reliability.md has the measured numbers).

Each scenario is one real ``workzone-ros launch --bag BAG`` (every node in its own process,
the launcher restarting dead ones) watched from this process by a recorder node that keeps
every output of every stage (``/workzone/lidar/candidates``, ``rois``, ``detections``,
``tracks``, ``signs``, ``state``), ``/diagnostics`` and ``/clock``, each with its wall
arrival time and its bag stamp.  A first run with nothing done is the **reference**: an
output is *correct* when it equals the reference's output for the same camera frame (same
count of candidates / ROIs / detections / tracks, same work-zone sign classes), a state when
its phase is one the reference held within ``--tolerance`` s of its stamp.

Scenarios (``--only``, comma-separated):

* ``loop``: ``--loop`` for 1.5 passes: after the jump back, the time from the jump to
  ``unknown`` and to the first correct state of the second pass, correct states per pass;
* ``kill``: for each node, SIGKILL it at ``--kill-at`` s of bag time; the launcher restarts
  it; kill -> restarted, -> first output, -> first correct output of that node, -> the state
  correct again; false ``none`` states during the gap; when a downstream node first
  reported the gap in ``/diagnostics``;
* ``cut``: the camera, the LiDAR and odometry withheld for ``--cut-s`` s each (``launch
  --cut``); cut -> the state lists the stale input, return -> no longer listed and the state
  correct; correct states during the cut, new zones claimed without a camera;
* ``load``: replay at 2x and 4x, and at 1x next to a CPU-heavy process pinned to the same
  cores; per node: drops, frames skipped while busy, processing p99, the stamp -> state
  latency, and the launcher's ``--score`` of the demo's events;
* ``soak``: ``--loop`` for ``--soak-s`` s; the RSS of every process every 10 s (target:
  flat).

Timings on a shared machine are noisy: the report gives what was measured, per run.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from workzone_ros.tools.launch_report import LEAN_KEY

__all__ = ['Recorder', 'GraphRun', 'main', 'rss_mb', 'SCENARIOS']

SCENARIOS = ('loop', 'kill', 'cut', 'load', 'soak')
NODES = ('lidar_cluster', 'projector', 'color_detector', 'tracker', 'classifier', 'fusion')
#: the output topic of each node (what "its first output" is measured on)
OUTPUT = {'lidar_cluster': '/workzone/lidar/candidates', 'projector': '/workzone/rois',
          'color_detector': '/workzone/detections', 'tracker': '/workzone/tracks',
          'classifier': '/workzone/signs', 'fusion': '/workzone/state'}
#: cut topic -> the name the fusion lists in ``stale_inputs``
CUTS = {'/camera': 'camera', '/lidar': 'lidar', '/odom': 'odom'}
ZONE_PHASES = ('approaching', 'inside', 'leaving')
_STARTED = re.compile(r'^\[launch\] started (\S+) \(pid (\d+)\)')
_CUT = re.compile(r'^\[play\] cut (\S+) (at|over at) ([\d.]+) s')
_EVENT = re.compile(r'^\s{3}(\S.*?)\s{2,}([ox])/(\d+)/')
_ACC = re.compile(r'phase accuracy ([\d.]+)')


# --- recording --------------------------------------------------------------------------------

@dataclass
class Out:
    """One output message: wall arrival (monotonic), bag stamp (ns) and its summary."""

    wall: float
    stamp: int
    value: Any


class Recorder:
    """Every output of the graph, ``/diagnostics`` and ``/clock``, in a private context."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        self.ctx = Context()
        rclpy.init(context=self.ctx, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('workzone_reliability', context=self.ctx,
                                      start_parameter_services=False)
        self.lock = threading.Lock()
        self.outputs: dict[str, list[Out]] = {t: [] for t in OUTPUT.values()}
        self.diag: list[tuple[float, str, int, str, dict]] = []
        self.clock_ns = 0
        self.clock_wall = 0.0
        self._subscribe()
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _subscribe(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import (
            DurabilityPolicy,
            QoSProfile,
            ReliabilityPolicy,
            qos_profile_sensor_data,
        )
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import PointCloud2
        from std_msgs.msg import String
        rel = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        n = self.node
        n.create_subscription(PointCloud2, OUTPUT['lidar_cluster'], self._on_cands, rel)
        for name in ('projector', 'color_detector', 'tracker', 'classifier'):
            topic = OUTPUT[name]
            n.create_subscription(String, topic,
                                  lambda m, t=topic: self._on_payload(t, m.data), rel)
        n.create_subscription(String, OUTPUT['fusion'],
                              lambda m: self._on_payload(OUTPUT['fusion'], m.data), latched)
        n.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                              QoSProfile(depth=100))
        n.create_subscription(Clock, '/clock', self._on_clock, qos_profile_sensor_data)

    def _spin(self) -> None:
        while not self._stop.is_set() and self.ctx.ok():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:  # noqa: BLE001 - shutting down
                return

    def reset(self) -> None:
        """Forget everything recorded (between runs)."""
        with self.lock:
            for v in self.outputs.values():
                v.clear()
            self.diag.clear()
            self.clock_ns = 0

    def close(self) -> None:
        """Stop spinning and shut the context down."""
        import rclpy
        self._stop.set()
        self._thread.join(2.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)

    def _on_clock(self, msg) -> None:
        ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        with self.lock:
            self.clock_ns, self.clock_wall = ns, time.monotonic()

    def _on_cands(self, msg) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with self.lock:
            self.outputs[OUTPUT['lidar_cluster']].append(
                Out(time.monotonic(), stamp, int(msg.width) * int(msg.height)))

    def _on_payload(self, topic: str, text: str) -> None:
        from workzone_ros.interfaces import PayloadError, decode_any
        wall = time.monotonic()
        try:
            p = decode_any(text)
        except PayloadError:
            return
        value: Any
        if hasattr(p, 'phase'):
            value = (p.phase, tuple(p.stale_inputs))
        elif hasattr(p, 'signs'):
            value = tuple(sorted(s.class_key for s in p.signs if s.category == 'workzone'))
        elif hasattr(p, 'tracks'):
            value = len(p.tracks)
        elif hasattr(p, 'detections'):
            value = len(p.detections)
        else:
            value = len(getattr(p, 'rois', ()))
        with self.lock:
            self.outputs[topic].append(Out(wall, p.header.stamp.to_ns(), value))

    def _on_diag(self, msg) -> None:
        wall = time.monotonic()
        with self.lock:
            for st in msg.status:
                level = st.level[0] if isinstance(st.level, (bytes, bytearray)) \
                    else int(st.level)
                self.diag.append((wall, st.name, level, st.message,
                                  {kv.key: kv.value for kv in st.values}))

    def snapshot(self) -> tuple[dict[str, list[Out]], list]:
        """Copies of the outputs and the diagnostics."""
        with self.lock:
            return {k: list(v) for k, v in self.outputs.items()}, list(self.diag)


# --- one launcher run ------------------------------------------------------------------------

class GraphRun:
    """``workzone-ros launch --bag ...`` as a subprocess, its lines time-stamped."""

    def __init__(self, bag: str, params: Optional[str], extra: list[str],
                 log: Any = None) -> None:
        cmd = [sys.executable, '-m', 'workzone_ros.cli', 'launch', '--bag', bag, '--report',
               '--quiet-play', '--log-file', '', *extra]
        if params:
            cmd += ['--params', params]
        self.cmd = cmd
        self.lines: list[tuple[float, str]] = []
        self.pids: dict[str, int] = {}
        self.started: list[tuple[float, str, int]] = []
        self._cond = threading.Condition()
        self._log = log
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, bufsize=1, env=dict(os.environ,
                                                                    PYTHONUNBUFFERED='1'))
        self.t0 = time.monotonic()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            now = time.monotonic()
            line = line.rstrip('\n')
            m = _STARTED.match(line)
            with self._cond:
                self.lines.append((now, line))
                if m:
                    self.pids[m.group(1)] = int(m.group(2))
                    self.started.append((now, m.group(1), int(m.group(2))))
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def wait(self, timeout: float) -> Optional[int]:
        """The exit code, or None (then the run is stopped with SIGINT, then killed)."""
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.stop()
            return None

    def stop(self) -> None:
        """SIGINT, then SIGKILL after 10 s."""
        if self.proc.poll() is None:
            self.proc.send_signal(2)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self._thread.join(2.0)

    def text(self) -> str:
        """Everything the launcher printed."""
        with self._cond:
            return '\n'.join(line for _, line in self.lines)

    def matching(self, regex: re.Pattern) -> list[tuple[float, re.Match]]:
        """(wall, match) of every line matching ``regex``."""
        with self._cond:
            return [(t, m) for t, line in self.lines if (m := regex.match(line))]


def wait_bag_time(rec: Recorder, run: GraphRun, start_ns: int, seconds: float,
                  timeout: float = 180.0) -> Optional[float]:
    """Wait until ``/clock`` reaches ``seconds`` of bag time; the wall time then, or None."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and run.proc.poll() is None:
        with rec.lock:
            ns = rec.clock_ns
        if ns and ns - start_ns >= seconds * 1e9:
            return time.monotonic()
        time.sleep(0.01)
    return None


def rss_mb(pid: int) -> Optional[float]:
    """Resident memory of ``pid`` in MB (None when it is gone)."""
    try:
        with open(f'/proc/{pid}/status') as f:
            for line in f:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


# --- scoring against the reference -----------------------------------------------------------

class Reference:
    """The outputs of the undisturbed run, by stamp (the phases as a timeline)."""

    def __init__(self, outputs: dict[str, list[Out]], tolerance_s: float) -> None:
        self.by_stamp = {t: {o.stamp: o.value for o in v} for t, v in outputs.items()}
        states = sorted((o.stamp, o.value[0]) for o in outputs[OUTPUT['fusion']])
        self.state_t = [s for s, _ in states]
        self.state_p = [p for _, p in states]
        self.tol = int(tolerance_s * 1e9)

    def phases_near(self, stamp: int) -> set[str]:
        """The reference phases within the tolerance of ``stamp``."""
        import bisect
        lo = bisect.bisect_right(self.state_t, stamp - self.tol) - 1
        hi = bisect.bisect_right(self.state_t, stamp + self.tol)
        return set(self.state_p[max(lo, 0):hi])

    def phase_at(self, stamp: int) -> Optional[str]:
        """The reference phase at ``stamp`` (the newest state at or before it)."""
        import bisect
        k = bisect.bisect_right(self.state_t, stamp) - 1
        return self.state_p[k] if k >= 0 else None

    def state_ok(self, out: Out) -> bool:
        """The phase is one the reference held near this stamp."""
        return out.value[0] in self.phases_near(out.stamp)

    def output_ok(self, topic: str, out: Out) -> Optional[bool]:
        """Equal to the reference's output for the same frame (None: no reference)."""
        if topic == OUTPUT['fusion']:
            return self.state_ok(out)
        ref = self.by_stamp.get(topic, {})
        return None if out.stamp not in ref else ref[out.stamp] == out.value


def _first(outs: list[Out], after: float, pred=lambda o: True) -> Optional[Out]:
    return next((o for o in outs if o.wall > after and pred(o)), None)


def _r(x: Optional[float], nd: int = 2) -> Optional[float]:
    return None if x is None else round(x, nd)


def state_recovery(states: list[Out], ref: Reference, t0: float, t_end: float,
                   start_ns: int = 0) -> dict:
    """After ``t0``: wrong states, false ``none``, when the state was right for good, and the
    timeline (bag s, phase, stale inputs) of what a planner saw."""
    window = [o for o in states if t0 < o.wall <= t_end]
    wrong = [o for o in window if not ref.state_ok(o)]
    false_none = [o for o in window if o.value[0] == 'none'
                  and ref.phases_near(o.stamp) & set(ZONE_PHASES)
                  and 'none' not in ref.phases_near(o.stamp)]
    out = {'states': len(window), 'wrong': len(wrong), 'false_none': len(false_none),
           'unknown': sum(o.value[0] == 'unknown' for o in window),
           'with_stale': sum(bool(o.value[1]) for o in window)}
    seen, last = [], None
    for o in window:
        if o.value != last:
            seen.append((round((o.stamp - start_ns) / 1e9, 2), o.value[0], list(o.value[1])))
            last = o.value
    out['timeline'] = seen[:40]
    if not wrong:
        out['correct_again_s'] = 0.0
    else:
        after = _first(window, wrong[-1].wall, ref.state_ok)
        out['correct_again_s'] = None if after is None else _r(after.wall - t0)
    return out


# --- scenarios -------------------------------------------------------------------------------

@dataclass
class Campaign:
    """Shared settings and the recorder of every run."""

    bag: str
    params: Optional[str]
    rate: float
    tolerance_s: float
    log: Any
    rec: Recorder = field(init=False)
    start_ns: int = 0
    duration_s: float = 0.0
    ref: Optional[Reference] = None

    def __post_init__(self) -> None:
        from workzone_ros.bagio import open_reader
        reader = open_reader(self.bag)
        self.start_ns, self.duration_s = reader.start_time, reader.duration / 1e9
        reader.close()
        self.rec = Recorder()

    def run(self, extra: list[str], during=None, timeout: Optional[float] = None) -> dict:
        """One launcher run; ``during(run)`` acts on it while it plays."""
        self.rec.reset()
        run = GraphRun(self.bag, self.params, ['--rate', f'{self.rate:g}', *extra])
        self.log(f'  $ {" ".join(run.cmd[2:])}')
        acts = None
        try:
            if during is not None:
                acts = during(run)
            code = run.wait(timeout or 120 + 2.5 * self.duration_s / max(self.rate, 0.25))
        finally:
            run.stop()
        outputs, diag = self.rec.snapshot()
        return {'run': run, 'code': code, 'outputs': outputs, 'diag': diag, 'acts': acts}

    def reference(self) -> dict:
        """The undisturbed run (also kept as the reference)."""
        self.log('reference run (nothing done)')
        res = self.run(['--state', '--score', '/tmp/workzone_reliability_score'])
        self.ref = Reference(res['outputs'], self.tolerance_s)
        states = res['outputs'][OUTPUT['fusion']]
        timeline, last = [], None
        for o in states:
            if o.value[0] != last:
                timeline.append((round((o.stamp - self.start_ns) / 1e9, 2), o.value[0]))
                last = o.value[0]
        return {'exit_code': res['code'], 'timeline': timeline,
                'outputs': {t: len(v) for t, v in res['outputs'].items()},
                'score': parse_score(res['run'].text()),
                'load': load_figures(res['diag'])}

    # -- the loop: a looping bag --
    def loop(self) -> dict:
        """1.5 passes with ``--loop``: the jump back resets every node."""
        self.log('loop: --loop, 1.5 passes')
        res = self.run(['--loop', '--duration', f'{1.5 * self.duration_s / self.rate:.0f}'])
        outs = res['outputs']
        states = outs[OUTPUT['fusion']]
        jump = next((b for a, b in zip(states, states[1:])
                     if b.stamp < a.stamp - 2_000_000_000), None)
        report: dict[str, Any] = {'exit_code': res['code']}
        if jump is None:
            report['error'] = 'no jump back seen in the states'
            return report
        t_jump = jump.wall
        first_unknown = _first(states, t_jump - 1e-3, lambda o: o.value[0] == 'unknown')
        report['jump_to_unknown_s'] = _r(first_unknown.wall - t_jump) if first_unknown else None
        second = [o for o in states if o.wall >= t_jump]
        first_pass = [o for o in states if o.wall < t_jump]
        report['first_pass_states_correct'] = _frac(first_pass, self.ref.state_ok)
        report['second_pass_states_correct'] = _frac(second, self.ref.state_ok)
        # phase after the jump, first zone phase of the second pass vs the reference
        report['second_pass_timeline'] = _timeline(second, self.start_ns)
        per_node = {}
        for node, topic in OUTPUT.items():
            after = [o for o in outs[topic] if o.wall >= t_jump]
            oks = [self.ref.output_ok(topic, o) for o in after]
            oks = [x for x in oks if x is not None]
            per_node[node] = {'outputs_after_jump': len(after),
                              'equal_to_reference': _r(sum(oks) / len(oks), 3) if oks
                              else None}
        report['nodes_after_jump'] = per_node
        report['time_jumps_counted'] = {name: vals.get('time jumps back')
                                        for _, name, _, _, vals in res['diag'][-60:]}
        report['exceptions'] = res['run'].text().count('Traceback')
        return report

    # -- kills: SIGKILL a node, the launcher restarts it --
    def kill(self, node: str, at_s: float) -> dict:
        """SIGKILL ``node`` at ``at_s`` s of bag time; measure its and the state's recovery."""
        self.log(f'kill {node} at {at_s:g} s of bag time')

        def during(run: GraphRun):
            t = wait_bag_time(self.rec, run, self.start_ns, at_s)
            pid = run.pids.get(node)
            if t is None or pid is None:
                return None
            os.kill(pid, 9)
            return (time.monotonic(), pid)

        res = self.run(['--dds-profile', 'none'], during)
        report: dict[str, Any] = {'node': node, 'kill_at_s': at_s, 'exit_code': res['code']}
        if res['acts'] is None:
            report['error'] = 'the node was not killed (bag too short or node not started)'
            return report
        t_kill, pid = res['acts']
        run = res['run']
        restart = next((t for t, n, p in run.started if n == node and p != pid and t > t_kill),
                       None)
        topic = OUTPUT[node]
        outs = res['outputs'][topic]
        after = restart if restart is not None else t_kill
        first = _first(outs, after)
        first_ok = _first(outs, after, lambda o: self.ref.output_ok(topic, o) is True)
        report['restarted_s'] = _r(restart - t_kill) if restart else None
        report['first_output_s'] = _r(first.wall - t_kill) if first else None
        report['first_correct_output_s'] = _r(first_ok.wall - t_kill) if first_ok else None
        report['state'] = state_recovery(res['outputs'][OUTPUT['fusion']], self.ref, t_kill,
                                         t_kill + 60.0, self.start_ns)
        report['gap_in_diagnostics_s'] = _r(gap_reported(res['diag'], node, topic, t_kill))
        report['exceptions'] = run.text().count('Traceback')
        return report

    # -- lost sensors: an input withheld for a while --
    def cut(self, cuts: list[tuple[str, float]], seconds: float) -> dict:
        """Withhold each topic for ``seconds`` from its start; staleness and recovery."""
        spec = [f'{topic}:{start:g}:{seconds:g}' for topic, start in cuts]
        self.log('cut: ' + ', '.join(spec))
        args = []
        for s in spec:
            args += ['--cut', s]
        res = self.run(args)
        run, outs = res['run'], res['outputs']
        states = outs[OUTPUT['fusion']]
        signs = outs[OUTPUT['classifier']]
        events = run.matching(_CUT)
        report: dict[str, Any] = {'exit_code': res['code'], 'cuts': []}
        for topic, start in cuts:
            name = CUTS[topic]
            t_on = next((t for t, m in events if m.group(1) == topic and m.group(2) == 'at'),
                        None)
            t_off = next((t for t, m in events if m.group(1) == topic and m.group(2) != 'at'),
                         None)
            item: dict[str, Any] = {'topic': topic, 'start_s': start, 'seconds': seconds}
            if t_on is None or t_off is None:
                item['error'] = 'cut not seen in the player output'
                report['cuts'].append(item)
                continue
            listed = _first(states, t_on, lambda o, n=name: n in o.value[1])
            item['stale_listed_after_s'] = _r(listed.wall - t_on) if listed else None
            cleared = _first(states, t_off, lambda o, n=name: n not in o.value[1])
            item['stale_cleared_after_return_s'] = _r(cleared.wall - t_off) if cleared \
                else None
            during = [o for o in states if t_on <= o.wall <= t_off]
            item['states_during'] = len(during)
            item['states_correct_during'] = _frac(during, self.ref.state_ok)
            item['false_none_during'] = sum(
                o.value[0] == 'none' and 'none' not in self.ref.phases_near(o.stamp)
                for o in during)
            base = next((o.value[0] for o in reversed(states) if o.wall <= t_on), None)
            item['phase_at_cut'] = base
            item['new_zone_phases_during'] = sorted(
                {o.value[0] for o in during if o.value[0] in ZONE_PHASES} - {base})
            item['signs_during'] = sum(t_on <= o.wall <= t_off for o in signs)
            rec = state_recovery(states, self.ref, t_off, t_off + 15.0, self.start_ns)
            item['state_correct_again_after_return_s'] = rec['correct_again_s']
            report['cuts'].append(item)
        report['exceptions'] = run.text().count('Traceback')
        return report

    # -- load: faster replay, a busy neighbour --
    def load(self, rate: float, hog: int = 0) -> dict:
        """One run at ``rate`` (optionally next to ``hog`` busy processes on our cores)."""
        self.log(f'load: rate {rate:g}' + (f' with {hog} CPU hog(s)' if hog else ''))
        hogs = []
        cores = sorted(os.sched_getaffinity(0))
        for _ in range(hog):
            hogs.append(subprocess.Popen(
                [sys.executable, '-c', 'import os, sys\n'
                 f'os.sched_setaffinity(0, {cores!r})\nwhile True: pass']))
        saved, self.rate = self.rate, rate
        try:
            res = self.run(['--state', '--score', '/tmp/workzone_reliability_score'])
        finally:
            self.rate = saved
            for h in hogs:
                h.kill()
                h.wait()
        outs = res['outputs']
        states = outs[OUTPUT['fusion']]
        return {'rate': rate, 'hogs': hog, 'cores': cores, 'exit_code': res['code'],
                'score': parse_score(res['run'].text()),
                'states_correct': _frac(states, self.ref.state_ok),
                'outputs': {n: len(outs[t]) for n, t in OUTPUT.items()},
                'nodes': load_figures(res['diag']),
                'exceptions': res['run'].text().count('Traceback')}

    # -- soak: memory over a long loop --
    def soak(self, seconds: float, every_s: float = 10.0) -> dict:
        """``--loop`` for ``seconds``; RSS of every process every ``every_s``."""
        self.log(f'soak: --loop for {seconds:g} s, RSS every {every_s:g} s')

        def during(run: GraphRun):
            samples = []
            t0 = time.monotonic()
            while run.proc.poll() is None:
                pids = dict(run.pids, launcher=run.proc.pid)
                samples.append((round(time.monotonic() - t0, 1),
                                {n: _r(rss_mb(p), 1) for n, p in pids.items()}))
                time.sleep(every_s)
            return samples

        res = self.run(['--loop', '--duration', f'{seconds:g}'], during,
                       timeout=seconds + 120)
        samples = res['acts'] or []
        report: dict[str, Any] = {'seconds': seconds, 'exit_code': res['code'],
                                  'samples': len(samples)}
        per = {}
        names = sorted({n for _, s in samples for n in s})
        for name in names:
            series = [(t, s.get(name)) for t, s in samples if s.get(name) is not None]
            warm = [(t, v) for t, v in series if t >= 60.0] or series
            if len(warm) < 2:
                continue
            first, last = warm[0][1], warm[-1][1]
            per[name] = {'rss_mb_at_60s': first, 'rss_mb_end': last,
                         'growth_mb': _r(last - first, 1),
                         'max_mb': max(v for _, v in series),
                         'slope_mb_per_10min': _r(_slope(warm) * 600.0, 1)}
        report['rss'] = per
        report['restarts'] = sum(1 for _, n, _ in res['run'].started) - len(names) + 1
        report['loops'] = len(re.findall(r'time jumped back', res['run'].text()))
        report['exceptions'] = res['run'].text().count('Traceback')
        return report


def _slope(series: list[tuple[float, float]]) -> float:
    import numpy as np
    t = np.array([a for a, _ in series])
    v = np.array([b for _, b in series])
    return float(np.polyfit(t, v, 1)[0]) if len(t) > 1 and np.ptp(t) > 0 else 0.0


def _frac(outs: list[Out], pred) -> Optional[float]:
    return _r(sum(bool(pred(o)) for o in outs) / len(outs), 3) if outs else None


def _timeline(states: list[Out], start_ns: int) -> list:
    out, last = [], None
    for o in states:
        if o.value[0] != last:
            out.append((round((o.stamp - start_ns) / 1e9, 2), o.value[0]))
            last = o.value[0]
    return out


def gap_reported(diag: list, node: str, topic: str, t0: float) -> Optional[float]:
    """Seconds from ``t0`` to the first WARN of another node naming ``topic`` (or, for a
    camera-chain node, the fusion listing a stale input)."""
    for wall, name, level, message, _ in diag:
        if wall > t0 and name != node and level >= 1 and topic in message:
            return wall - t0
    return None


def load_figures(diag: list) -> dict:
    """Per node, from its last ``/diagnostics``: drops, skipped frames, processing p99 (and
    the colour detector's frames measured lean)."""
    last: dict[str, dict] = {}
    for _, name, _, _, values in diag:
        last[name] = values
    out = {}
    for name, values in sorted(last.items()):
        def num(key: str) -> float:
            try:
                return float(values.get(key) or 0)
            except ValueError:
                return 0.0
        topics = [k[:-len(' messages')] for k in values if k.endswith(' messages')]
        p99 = {t: values.get(f'{t} processing p99 ms') for t in topics
               if values.get(f'{t} processing p99 ms')}
        out[name] = {
            'messages': int(sum(num(f'{t} messages') for t in topics)),
            'dropped': int(sum(num(f'{t} dropped') for t in topics)),
            'skipped_while_busy': int(sum(num(f'{t} skipped while busy') for t in topics)),
            'processing_p99_ms': {t: float(v) for t, v in p99.items()},
        }
        if values.get(LEAN_KEY):
            out[name]['measured_lean'] = int(num(LEAN_KEY))
        if values.get('stamp to state latency p99 ms'):
            out[name]['stamp_to_state_p99_ms'] = float(values['stamp to state latency p99 ms'])
    return out


def parse_score(text: str) -> dict:
    """The launcher's ``--score`` block: phase accuracy and each event found or missed."""
    events = {}
    acc = None
    for line in text.splitlines():
        m = _EVENT.match(line)
        if m:
            events[m.group(1).strip()] = m.group(2) == 'o'
        a = _ACC.search(line)
        if a and acc is None:
            acc = float(a.group(1))
    return {'phase_accuracy': acc, 'events_found': sum(events.values()),
            'events': len(events), 'missed': sorted(k for k, v in events.items() if not v)}


# --- CLI -------------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    """The ``workzone-ros evaluate reliability`` argument parser."""
    p = argparse.ArgumentParser(prog='workzone-ros evaluate reliability',
                                description=__doc__.split('\n')[0])
    p.add_argument('--bag', default='bags/demo', help='a synthetic bag with ground truth '
                   '(default: bags/demo, `make demo` writes it)')
    p.add_argument('--params', metavar='FILE', help='params file for the launcher')
    p.add_argument('--only', default='loop,kill,cut,load', metavar='A,B',
                   help=f'scenarios among {", ".join(SCENARIOS)} (default: all but soak)')
    p.add_argument('--nodes', default=','.join(NODES), metavar='A,B', help='nodes to kill')
    p.add_argument('--kill-at', type=float, default=14.0, metavar='S',
                   help='kill each node at S s of bag time (14: approaching the demo zone)')
    p.add_argument('--cuts', default='/camera:6,/lidar:18,/odom:30', metavar='T:S,...',
                   help='topics to withhold and when (bag s)')
    p.add_argument('--cut-s', type=float, default=5.0, metavar='S', help='cut length (5 s)')
    p.add_argument('--rates', default='2,4', metavar='R,R', help='load: replay rates')
    p.add_argument('--hog', type=int, default=1, metavar='N',
                   help='load: busy processes pinned to our cores for the 1x run (0: none)')
    p.add_argument('--soak-s', type=float, default=600.0, metavar='S', help='soak length')
    p.add_argument('--tolerance', type=float, default=0.5, metavar='S',
                   help='a state is correct when the reference held its phase within S s')
    p.add_argument('--domain', type=int, metavar='ID', help='ROS_DOMAIN_ID of the runs '
                   '(default: a private one from the process id, localhost discovery)')
    p.add_argument('--json', metavar='FILE', help='write the report here')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Run the campaign; returns 0, or 2 for an unusable bag."""
    args = build_parser().parse_args(argv)
    only = [s.strip() for s in args.only.split(',') if s.strip()]
    bad = [s for s in only if s not in SCENARIOS]
    if bad:
        print(f'workzone-ros evaluate reliability: error: unknown scenario {bad[0]!r}',
              file=sys.stderr)
        return 2
    if not Path(args.bag).exists():
        print(f'workzone-ros evaluate reliability: error: bag not found: {args.bag} '
              '(`make demo` writes bags/demo)', file=sys.stderr)
        return 2

    def log(text: str) -> None:
        print(f'[reliability] {text}', flush=True)

    # a private DDS domain: another graph on this machine (a demo, a test) must not mix in
    os.environ['ROS_DOMAIN_ID'] = str(args.domain if args.domain is not None
                                      else 101 + os.getpid() % 100)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

    camp = Campaign(args.bag, args.params, 1.0, args.tolerance, log)
    report: dict[str, Any] = {'bag': args.bag, 'params': args.params,
                              'cores': len(os.sched_getaffinity(0))}

    def save() -> None:
        if args.json:
            Path(args.json).write_text(json.dumps(report, indent=1))

    t0 = time.monotonic()
    try:
        report['reference'] = camp.reference()
        log(f'reference: {json.dumps(report["reference"]["timeline"])}')
        save()
        if 'loop' in only:
            report['loop'] = camp.loop()
            log(json.dumps(report['loop']))
            save()
        if 'kill' in only:
            report['kill'] = []
            for node in [n.strip() for n in args.nodes.split(',') if n.strip()]:
                report['kill'].append(camp.kill(node, args.kill_at))
                log(json.dumps(report['kill'][-1]))
                save()
        if 'cut' in only:
            cuts = []
            for item in args.cuts.split(','):
                topic, _, start = item.rpartition(':')
                cuts.append((topic, float(start)))
            report['cut'] = camp.cut(cuts, args.cut_s)
            log(json.dumps(report['cut']))
            save()
        if 'load' in only:
            report['load'] = []
            for rate in [float(r) for r in args.rates.split(',') if r.strip()]:
                report['load'].append(camp.load(rate))
                log(json.dumps(report['load'][-1]))
                save()
            if args.hog:
                report['load'].append(camp.load(1.0, hog=args.hog))
                log(json.dumps(report['load'][-1]))
                save()
        if 'soak' in only:
            report['soak'] = camp.soak(args.soak_s)
            log(json.dumps(report['soak']))
            save()
    finally:
        camp.rec.close()
        report['wall_s'] = round(time.monotonic() - t0, 1)
        save()
    return 0


if __name__ == '__main__':
    sys.exit(main())
