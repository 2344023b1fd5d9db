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
