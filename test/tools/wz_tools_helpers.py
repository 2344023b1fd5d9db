"""Helpers for the tool tests: small bags in tmp_path, a private rclpy context, spinning.

Bags carry ``/chatter`` (std_msgs/String ``'0'``, ``'1'``, ... every 50 ms from T0), a tiny
``/camera/image_raw`` and one transient-local ``/workzone/state``.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from workzone_ros import bagio

T0 = 1_700_000_000_000_000_000
PERIOD_NS = 50_000_000
N_CHATTER = 21            # 1.0 s of bag time
REPO = Path(__file__).resolve().parents[2]
FIXTURES = Path(__file__).resolve().parent


def write_ros2_bag(path: Path, storage: str = 'mcap', n: int = N_CHATTER) -> Path:
    """A rosbag2 bag written with :class:`workzone_ros.bagio.BagWriter`."""
    ts = bagio.typestore()
    String = ts.types['std_msgs/msg/String']
    Image = ts.types['sensor_msgs/msg/Image']
    Header = ts.types['std_msgs/msg/Header']
    Time = ts.types['builtin_interfaces/msg/Time']
    with bagio.BagWriter(path, storage=storage) as bag:
        bag.add_topic('/chatter', 'std_msgs/msg/String')
        bag.add_topic('/camera/image_raw', 'sensor_msgs/msg/Image', qos='sensor')
        bag.add_topic('/workzone/state', 'std_msgs/msg/String', qos='transient_local')
        bag.write('/workzone/state', T0, String(data='{"state": 1}'))
        for i in range(n):
            t = T0 + i * PERIOD_NS
            bag.write('/chatter', t, String(data=str(i)))
            if i % 5 == 0:
                img = Image(header=Header(stamp=Time(sec=t // 10**9, nanosec=t % 10**9),
                                          frame_id='camera'),
                            height=2, width=3, encoding='bgr8', is_bigendian=0, step=9,
                            data=np.arange(18, dtype=np.uint8))
                bag.write('/camera/image_raw', t, img)
    return path


def write_ros1_bag(path: Path, n: int = N_CHATTER) -> Path:
    """A ROS 1 bag written with rosbags' rosbag1 Writer and the Noetic typestore."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS1_NOETIC)
    String = ts.types['std_msgs/msg/String']
    Image = ts.types['sensor_msgs/msg/Image']
    Header = ts.types['std_msgs/msg/Header']
    Time = ts.types['builtin_interfaces/msg/Time']
    with Writer(path) as bag:
        chatter = bag.add_connection('/chatter', 'std_msgs/msg/String', typestore=ts)
        image = bag.add_connection('/camera/image_raw', 'sensor_msgs/msg/Image', typestore=ts)
        state = bag.add_connection('/workzone/state', 'std_msgs/msg/String', typestore=ts,
                                   latching=1)
        bag.write(state, T0, ts.serialize_ros1(String(data='{"state": 1}'),
                                               'std_msgs/msg/String'))
        for i in range(n):
            t = T0 + i * PERIOD_NS
            bag.write(chatter, t, ts.serialize_ros1(String(data=str(i)), 'std_msgs/msg/String'))
            if i % 5 == 0:
                img = Image(header=Header(seq=i, stamp=Time(sec=t // 10**9, nanosec=t % 10**9),
                                          frame_id='camera'),
                            height=2, width=3, encoding='bgr8', is_bigendian=0, step=9,
                            data=np.arange(18, dtype=np.uint8))
                bag.write(image, t, ts.serialize_ros1(img, 'sensor_msgs/msg/Image'))
    return path


@pytest.fixture
def ros_context():
    """A private, initialised rclpy Context (no signal handlers), shut down afterwards."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    ctx = Context()
    rclpy.init(context=ctx, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)


def spin_until(executor, predicate, timeout: float) -> bool:
    """Spin ``executor`` with spin_once(0.1) until ``predicate()`` or the deadline."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        executor.spin_once(timeout_sec=0.1)
    return predicate()


def cli_env(**extra: str) -> dict[str, str]:
    """Environment for CLI subprocesses: this session's DDS isolation + the fixtures path."""
    env = dict(os.environ)
    paths = [str(FIXTURES), str(REPO)]
    if env.get('PYTHONPATH'):
        paths.append(env['PYTHONPATH'])
    env['PYTHONPATH'] = os.pathsep.join(paths)
    env['PYTHONUNBUFFERED'] = '1'
    env.update(extra)
    return env


def run_cli(*args: str, timeout: float = 60.0, **kwargs) -> subprocess.CompletedProcess:
    """Run ``workzone-ros ARGS`` as a subprocess and capture its output."""
    return subprocess.run([sys.executable, '-m', 'workzone_ros.cli', *args], cwd=REPO,
                          env=cli_env(), capture_output=True, text=True, timeout=timeout,
                          **kwargs)


def write_launch_bag(path: Path, frames: int = 12) -> Path:
    """Images at 10 Hz with ``/groundtruth/signs`` per frame (a sign in 2 of every 3)."""
    from workzone_ros.interfaces import Box, GtSign, GtSigns, Header, Time, encode
    ts = bagio.typestore()
    String = ts.types['std_msgs/msg/String']
    Image = ts.types['sensor_msgs/msg/Image']
    RHeader = ts.types['std_msgs/msg/Header']
    RTime = ts.types['builtin_interfaces/msg/Time']
    sign = GtSign(sign_id=1, class_key='road_work_ahead', code='W20-1', category='workzone',
                  box=Box(x=1.0, y=1.0, w=5.0, h=5.0), distance_m=30.0, visible_fraction=1.0)
    with bagio.BagWriter(path) as bag:
        bag.add_topic('/camera/image_raw', 'sensor_msgs/msg/Image', qos='sensor')
        bag.add_topic('/groundtruth/signs', 'std_msgs/msg/String')
        for i in range(frames):
            t = T0 + i * 100_000_000
            img = Image(header=RHeader(stamp=RTime(sec=t // 10**9, nanosec=t % 10**9),
                                       frame_id='camera'),
                        height=2, width=3, encoding='bgr8', is_bigendian=0, step=9,
                        data=np.zeros(18, np.uint8))
            bag.write('/camera/image_raw', t, img)
            gt = GtSigns(header=Header(stamp=Time.from_ns(t), frame_id='camera'),
                         signs=[sign] if i % 3 else [])
            bag.write('/groundtruth/signs', t, String(data=encode(gt)))
    return path


class LineReader:
    """Collects a subprocess's stdout lines in a thread; wait for patterns with a deadline."""

    def __init__(self, proc: subprocess.Popen) -> None:
        import threading
        self.proc = proc
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        for line in self.proc.stdout:
            with self._cond:
                self.lines.append(line.rstrip('\n'))
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def wait_for(self, predicate, timeout: float):
        """The first line for which ``predicate(line)`` is true, or None at the deadline."""
        deadline = time.monotonic() + timeout
        seen = 0
        with self._cond:
            while True:
                for line in self.lines[seen:]:
                    if predicate(line):
                        return line
                seen = len(self.lines)
                left = deadline - time.monotonic()
                if left <= 0 or (self.proc.poll() is not None and not self._thread.is_alive()):
                    return None
                self._cond.wait(min(left, 0.1))

    def text(self) -> str:
        """Everything read so far."""
        with self._cond:
            return '\n'.join(self.lines)


def start_cli(*args: str) -> subprocess.Popen:
    """Start ``workzone-ros ARGS`` with merged, line-buffered text output."""
    return subprocess.Popen([sys.executable, '-m', 'workzone_ros.cli', *args], cwd=REPO,
                            env=cli_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, bufsize=1)


def pid_alive(pid: int) -> bool:
    """Whether ``pid`` exists and is not a zombie."""
    try:
        with open(f'/proc/{pid}/stat') as fh:
            return fh.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False


def wait_gone(pids, timeout: float) -> bool:
    """True once none of ``pids`` is alive (zombies count as gone), False at the deadline."""
    deadline = time.monotonic() + timeout
    while any(pid_alive(p) for p in pids):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True
