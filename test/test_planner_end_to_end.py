"""A planner's view, end to end: the launcher replays a short work-zone bag through every node
(real processes, real DDS) and an rclpy subscriber reads ``/workzone/state`` as a planner does.

It must see ``none -> approaching -> inside -> leaving -> none`` with the zone's lane closure,
a subscriber that joins late must get the current state at once, and a fusion node killed
mid-zone and restarted by the launcher must publish ``unknown`` -- never a false ``none`` --
until the evidence rebuilds.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from workzone_ros.interfaces import WorkzoneState, decode

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / 'test' / 'data' / 'scenarios' / 'short_zone.yaml'
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
BAG_T0 = 1_700_000_000          # the simulator's first stamp (s)
ZONE_END_S = 26.8               # the ego passes END ROAD WORK (scene ground truth)


def _cli(*args):
    return [sys.executable, '-m', 'workzone_ros.cli', *args]


@pytest.fixture(scope='module')
def zone_bag(tmp_path_factory):
    out = tmp_path_factory.mktemp('planner') / 'short_zone'
    res = subprocess.run(_cli('synth', '--scenario', str(SCENE), '--compressed', '-q', '-o',
                              str(out)), cwd=REPO, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    return out


class Planner:
    """An rclpy subscriber of /workzone/state in its own context and thread."""

    def __init__(self, name: str) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.states: list[tuple[float, WorkzoneState]] = []
        self._lock = threading.Lock()
        self.subscribe(self.states)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def subscribe(self, into: list) -> None:
        def on_state(msg):
            with self._lock:
                into.append((time.monotonic(), decode(msg.data, WorkzoneState)))
        self.node.create_subscription(String, '/workzone/state', on_state, LATCHED)

    def _spin(self):
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def phases(self) -> list[str]:
        with self._lock:
            out = []
            for _, s in self.states:
                if not out or out[-1] != s.phase:
                    out.append(s.phase)
            return out

    def close(self):
        self._stop.set()
        self._thread.join(2)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _wait(cond, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.05)
    return False


def _bag_s(state: WorkzoneState) -> float:
    return state.header.stamp.to_sec() - BAG_T0


def _launch(bag: Path, lines: list[str]) -> subprocess.Popen:
    proc = subprocess.Popen(_cli('launch', '--bag', str(bag), '--rate', '1.0', '--quiet-play',
                                 '--log-file', ''), cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, bufsize=1,
                            env=dict(os.environ))
    threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()
    return proc


def test_a_planner_sees_the_zone_come_and_go_and_a_late_planner_gets_it_at_once(zone_bag):
    planner = Planner('planner')
    lines: list[str] = []
    proc = _launch(zone_bag, lines)
    try:
        assert _wait(lambda: 'inside' in planner.phases(), 120), (planner.phases(),
                                                                 ''.join(lines[-40:]))
        late: list = []
        planner.subscribe(late)
        assert _wait(lambda: late, 5), 'a late subscriber got no state'
        assert late[0][1].phase in ('inside', 'leaving')
        assert proc.wait(120) == 0, ''.join(lines[-60:])
    finally:
        if proc.poll() is None:
            proc.kill()
        planner.close()
    phases = [p for p in planner.phases() if p != 'unknown']
    assert phases == ['none', 'approaching', 'inside', 'leaving', 'none'], (
        planner.phases(), ''.join(lines[-40:]))
    states = [s for _, s in planner.states]
    inside = [s for s in states if s.phase == 'inside']
    assert all(s.active for s in inside) and inside[0].lanes_closed == ['right']
    assert inside[-1].speed_limit_mph == 45, [s.speed_limit_mph for s in inside][-3:]
    assert any(e.class_key == 'work_zone_begin' for e in inside[0].evidence)
    begin = _bag_s(inside[0])
    assert 14.2 <= begin <= 16.2, begin                  # truth: the begin sign at 15.2 s
    final = states[-1]
    assert final.phase == 'none' and not final.active and final.lanes_closed == []
    assert _bag_s(next(s for s in states if s.phase == 'none'
                       and _bag_s(s) > 20)) >= ZONE_END_S - 1.0


def test_a_killed_fusion_restarts_unknown_and_never_claims_a_false_none(zone_bag):
    planner = Planner('planner_kill')
    lines: list[str] = []
    proc = _launch(zone_bag, lines)
    try:
        assert _wait(lambda: any(s.phase == 'inside' for _, s in planner.states), 120), \
            ''.join(lines[-40:])
        pid = next(int(m.group(1)) for line in list(lines)
                   if (m := re.search(r'started fusion \(pid (\d+)\)', line)))
        killed_at = time.monotonic()
        os.kill(pid, signal.SIGKILL)
        assert proc.wait(120) == 0, ''.join(lines[-60:])
    finally:
        if proc.poll() is None:
            proc.kill()
        planner.close()
    assert any('fusion exited (signal SIGKILL); restart #1' in line for line in lines)
    after = [s for t, s in planner.states if t > killed_at]
    assert after and after[0].phase == 'unknown', [s.phase for s in after][:5]
    early_none = [_bag_s(s) for s in after if s.phase == 'none' and _bag_s(s) < ZONE_END_S - 1]
    assert not early_none, f'false none at bag time {early_none[:3]}'
