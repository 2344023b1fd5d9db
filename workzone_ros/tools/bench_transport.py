"""``workzone-ros bench transport``: what moving sensor data between processes costs.

1. A publisher child process sends a 640x480 bgr8 Image at 15 Hz and a 130k-point
   PointCloud2 (x, y, z, intensity float32 + ring uint16) at 10 Hz; this process subscribes
   with the sensor-data QoS, as the nodes do.  Figures: received rate, latency p50/p99 (the
   header stamp is the wall time at publish; receive time in the callback, so serialization,
   transport and deserialization are included), CPU of both processes in the window.
2. The bag player (a child process) replays a generated bag of the same streams at 1x and as
   fast as possible.  Figures: messages published / received, achieved speed, MB/s, schedule
   error p50/p99 at 1x (receive time vs the bag's timing), player CPU.

CPU is read from ``/proc/<pid>/stat`` (children) and ``time.process_time`` (this process)
over the measuring window only, so start-up is not counted.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Optional

import numpy as np

__all__ = ['add_arguments', 'run']

IMAGE_TOPIC = '/bench/image'
POINTS_TOPIC = '/bench/points'
WIDTH, HEIGHT = 640, 480
IMAGE_HZ, POINTS_HZ = 15.0, 10.0
_CLK_TCK = os.sysconf('SC_CLK_TCK')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``workzone-ros bench transport``."""
    parser.add_argument('--seconds', type=float, default=5.0,
                        help='measuring window of the two-process test (5)')
    parser.add_argument('--points', type=int, default=130_000, help='points per cloud')
    parser.add_argument('--bag-seconds', type=float, default=3.0,
                        help='length of the generated bag for the player test (3)')
    parser.add_argument('--no-player', action='store_true', help='skip the player test')
    parser.add_argument('--default-transport', action='store_true',
                        help="Fast DDS defaults instead of the launcher's profile (shared "
                        'memory with 32 MB segments, the default here as in the launcher)')
    parser.add_argument('--reliable', action='store_true',
                        help='subscribe reliable instead of the sensor-data (best effort) QoS')


# --- helpers -------------------------------------------------------------------------------

def _proc_cpu_s(pid: int) -> Optional[float]:
    """utime + stime of a process in seconds (None once it is gone)."""
    try:
        with open(f'/proc/{pid}/stat') as fh:
            fields = fh.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / _CLK_TCK
    except (OSError, IndexError, ValueError):
        return None


def _pct(values, q: float) -> Optional[float]:
    return round(float(np.percentile(values, q)), 3) if len(values) else None


def _cloud_points(n: int) -> np.ndarray:
    from workzone_ros.core.pointcloud import make_points
    rng = np.random.default_rng(0)
    return make_points(x=rng.uniform(-50, 50, n).astype(np.float32),
                       y=rng.uniform(-50, 50, n).astype(np.float32),
                       z=rng.uniform(-2, 5, n).astype(np.float32),
                       intensity=rng.uniform(0, 255, n).astype(np.float32),
                       ring=(np.arange(n) % 64).astype(np.uint16))


def _child_env() -> dict[str, str]:
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return env


def _start_child(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-m', 'workzone_ros.tools.bench_transport', *args],
                            env=_child_env(), stdout=subprocess.PIPE, text=True,
                            start_new_session=True)


def _stop_child(proc: subprocess.Popen, timeout: float = 5.0) -> None:
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()


class _Receiver:
    """Subscriptions in this process that record receive time, stamp and size."""

    def __init__(self, node, reliable: bool = False) -> None:
        from rclpy.qos import QoSProfile, qos_profile_sensor_data
        from sensor_msgs.msg import Image, PointCloud2
        qos = QoSProfile(depth=10) if reliable else qos_profile_sensor_data
        self.rx: dict[str, list[tuple[int, int, int]]] = {IMAGE_TOPIC: [], POINTS_TOPIC: []}
        self.recording = True
        node.create_subscription(Image, IMAGE_TOPIC,
                                 lambda m: self._on(IMAGE_TOPIC, m), qos)
        node.create_subscription(PointCloud2, POINTS_TOPIC,
                                 lambda m: self._on(POINTS_TOPIC, m), qos)

    def _on(self, topic: str, msg) -> None:
        now = time.time_ns()
        if self.recording:
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            self.rx[topic].append((now, stamp, len(msg.data)))

    def reset(self) -> None:
        for v in self.rx.values():
            v.clear()


def _spin_for(executor, seconds: float, until=None) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end and not (until and until()):
        executor.spin_once(timeout_sec=0.05)


# --- children ------------------------------------------------------------------------------

def _child_publish(points: int) -> int:
    """Publish Image at 15 Hz and PointCloud2 at 10 Hz until SIGINT (stamps = wall time)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import QoSProfile
    from sensor_msgs.msg import Image, PointCloud2, PointField

    from workzone_ros.core.pointcloud import dtype_to_fields
    rclpy.init()
    node = rclpy.create_node('bench_transport_pub')
    qos = QoSProfile(depth=10)
    img_pub = node.create_publisher(Image, IMAGE_TOPIC, qos)
    pts_pub = node.create_publisher(PointCloud2, POINTS_TOPIC, qos)
    img = Image(width=WIDTH, height=HEIGHT, encoding='bgr8', step=WIDTH * 3)
    img.header.frame_id = 'camera'
    img.data = np.random.default_rng(1).integers(0, 255, WIDTH * HEIGHT * 3,
                                                 dtype=np.uint8).tobytes()
    cloud_arr = _cloud_points(points)
    cloud = PointCloud2(height=1, width=points, is_bigendian=False,
                        point_step=cloud_arr.dtype.itemsize,
                        row_step=cloud_arr.dtype.itemsize * points, is_dense=True)
    cloud.header.frame_id = 'lidar'
    cloud.fields = [PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
                    for f in dtype_to_fields(cloud_arr.dtype)]
    cloud.data = cloud_arr.tobytes()

    def stamp(msg) -> None:
        t = time.time_ns()
        msg.header.stamp.sec, msg.header.stamp.nanosec = t // 10**9, t % 10**9

    def pub_image() -> None:
        stamp(img)
        img_pub.publish(img)

    def pub_cloud() -> None:
        stamp(cloud)
        pts_pub.publish(cloud)

    node.create_timer(1.0 / IMAGE_HZ, pub_image)
    node.create_timer(1.0 / POINTS_HZ, pub_cloud)
    print('ready', flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _child_play(bag: str, rate: float) -> int:
    """Replay ``bag`` with BagPlayer and print its stats as one JSON line."""
    from workzone_ros.tools.player import BagPlayer
    player = BagPlayer(bag, rate=rate, wait_for=[IMAGE_TOPIC, POINTS_TOPIC], wait_timeout=20.0,
                       clock_hz=100.0)
    signal.signal(signal.SIGINT, lambda *_: player.stop())
    stats = player.run()
    print(json.dumps({'published': stats.published, 'wall_s': stats.wall_s,
                      'bag_s': stats.bag_s, 'cpu_s': stats.cpu_s}), flush=True)
    return 0


def _write_bag(path: Path, seconds: float, points: int) -> int:
    from workzone_ros.bagio import BagWriter, typestore
    ts = typestore()
    Image = ts.types['sensor_msgs/msg/Image']
    PointCloud2 = ts.types['sensor_msgs/msg/PointCloud2']
    PointField = ts.types['sensor_msgs/msg/PointField']
    Header = ts.types['std_msgs/msg/Header']
    Time = ts.types['builtin_interfaces/msg/Time']
    from workzone_ros.core.pointcloud import dtype_to_fields
    pts = _cloud_points(points)
    fields = [PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
              for f in dtype_to_fields(pts.dtype)]
    pixels = np.random.default_rng(1).integers(0, 255, WIDTH * HEIGHT * 3, dtype=np.uint8)
    raw_pts = pts.view(np.uint8)
    t0 = 1_700_000_000_000_000_000
    events = [(int(i * 1e9 / IMAGE_HZ), 'i') for i in range(int(seconds * IMAGE_HZ))]
    events += [(int(i * 1e9 / POINTS_HZ), 'p') for i in range(int(seconds * POINTS_HZ))]
    with BagWriter(path) as bag:
        bag.add_topic(IMAGE_TOPIC, 'sensor_msgs/msg/Image', qos='sensor')
        bag.add_topic(POINTS_TOPIC, 'sensor_msgs/msg/PointCloud2', qos='sensor')
        for dt, kind in sorted(events):
            t = t0 + dt
            header = Header(stamp=Time(sec=t // 10**9, nanosec=t % 10**9), frame_id='x')
            if kind == 'i':
                bag.write(IMAGE_TOPIC, t, Image(header=header, height=HEIGHT, width=WIDTH,
                                                encoding='bgr8', is_bigendian=0, step=WIDTH * 3,
                                                data=pixels))
            else:
                bag.write(POINTS_TOPIC, t, PointCloud2(
                    header=header, height=1, width=points, fields=fields, is_bigendian=False,
                    point_step=pts.dtype.itemsize, row_step=pts.dtype.itemsize * points,
                    data=raw_pts, is_dense=True))
    return len(events)


# --- the benchmark -------------------------------------------------------------------------

def _stream_figures(rx: list[tuple[int, int, int]], window_s: float, nominal_hz: float
                    ) -> dict[str, Any]:
    lat = np.array([(r - s) / 1e6 for r, s, _ in rx]) if rx else np.zeros(0)
    return {'received': len(rx), 'rate_hz': round(len(rx) / window_s, 2),
            'nominal_hz': nominal_hz, 'latency_ms_p50': _pct(lat, 50),
            'latency_ms_p99': _pct(lat, 99),
            'msg_bytes': rx[0][2] if rx else None}


def _two_process(executor, receiver: _Receiver, seconds: float, points: int) -> dict[str, Any]:
    child = _start_child('--child-publish', '--points', str(points))
    try:
        ok = child.stdout.readline().strip() == 'ready'
        _spin_for(executor, 20.0, lambda: all(receiver.rx.values()))
        if not ok or not all(receiver.rx.values()):
            return {'error': 'publisher child did not deliver within 20 s'}
        _spin_for(executor, 0.5)                       # warm-up
        receiver.reset()
        cpu_child0, cpu_self0 = _proc_cpu_s(child.pid), time.process_time()
        t0 = time.monotonic()
        _spin_for(executor, seconds)
        window = time.monotonic() - t0
        cpu_child1, cpu_self1 = _proc_cpu_s(child.pid), time.process_time()
        receiver.recording = False
    finally:
        _stop_child(child)
        receiver.recording = True
    return {
        'window_s': round(window, 2),
        'image_640x480_bgr8': _stream_figures(receiver.rx[IMAGE_TOPIC], window, IMAGE_HZ),
        f'pointcloud2_{points}': _stream_figures(receiver.rx[POINTS_TOPIC], window, POINTS_HZ),
        'cpu_percent_publisher': None if cpu_child0 is None or cpu_child1 is None
        else round(100 * (cpu_child1 - cpu_child0) / window, 1),
        'cpu_percent_subscriber': round(100 * (cpu_self1 - cpu_self0) / window, 1),
    }


def _player_run(executor, receiver: _Receiver, bag: Path, rate: float, total: int
                ) -> dict[str, Any]:
    receiver.reset()
    child = _start_child('--child-play', str(bag), '--rate', str(rate))
    out = ''
    try:
        _spin_for(executor, 120.0, lambda: child.poll() is not None)
        _spin_for(executor, 0.3)                       # the last messages in flight
        out = child.stdout.read() if child.stdout else ''
    finally:
        _stop_child(child)
    try:
        stats = json.loads(out.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return {'error': f'player child failed (exit {child.returncode})'}
    rx = sorted(receiver.rx[IMAGE_TOPIC] + receiver.rx[POINTS_TOPIC])
    nbytes = sum(b for _, _, b in rx)
    span = (rx[-1][0] - rx[0][0]) / 1e9 if len(rx) > 1 else 0.0
    fig: dict[str, Any] = {
        'rate': 'max' if rate == 0 else rate,
        'bag_messages': total, 'published': stats['published'], 'received': len(rx),
        'bag_s': round(stats['bag_s'], 3), 'wall_s': round(stats['wall_s'], 3),
        'speed_x': round(stats['bag_s'] / stats['wall_s'], 2) if stats['wall_s'] else None,
        'published_msgs_per_s': round(stats['published'] / stats['wall_s'], 1)
        if stats['wall_s'] else None,
        'received_MB_per_s': round(nbytes / 1e6 / span, 1) if span else None,
        'cpu_percent_player': round(100 * stats['cpu_s'] / stats['wall_s'], 1)
        if stats['wall_s'] else None,
    }
    if rate > 0 and rx:
        r0, s0 = rx[0][0], rx[0][1]
        err = np.array([abs((r - r0) / 1e6 - (s - s0) / 1e6 / rate) for r, s, _ in rx])
        fig['schedule_error_ms_p50'] = _pct(err, 50)
        fig['schedule_error_ms_p99'] = _pct(err, 99)
    return fig


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Run the benchmark; returns the figures (also printed by ``workzone-ros bench``)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    if not getattr(args, 'default_transport', False):
        from workzone_ros.tools.launcher import apply_dds_profile
        apply_dds_profile('shm')
    figures: dict[str, Any] = {'machine': {'cpus': os.cpu_count(),
                                           'loadavg_1min': round(os.getloadavg()[0], 2)}}
    ctx = Context()
    rclpy.init(context=ctx, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bench_transport_sub', context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    receiver = _Receiver(node, reliable=args.reliable)
    figures['subscriber_qos'] = 'reliable' if args.reliable else 'sensor_data (best effort)'
    figures['fastdds_profile'] = os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE', 'default')
    try:
        print(f'two processes: image {IMAGE_HZ:g} Hz + {args.points}-point cloud '
              f'{POINTS_HZ:g} Hz for {args.seconds:g} s ...', file=sys.stderr, flush=True)
        figures['two_process'] = _two_process(executor, receiver, args.seconds, args.points)
        if not args.no_player:
            with tempfile.TemporaryDirectory(prefix='wz_bench_') as tmp:
                bag = Path(tmp) / 'bag'
                print(f'writing a {args.bag_seconds:g} s bag ...', file=sys.stderr, flush=True)
                total = _write_bag(bag, args.bag_seconds, args.points)
                figures['bag_mb'] = round(sum(f.stat().st_size for f in bag.iterdir()) / 1e6,
                                          1)
                for rate in (1.0, 0.0):
                    print(f'player at {"max" if rate == 0 else "1x"} ...', file=sys.stderr,
                          flush=True)
                    key = 'player_max' if rate == 0 else 'player_1x'
                    figures[key] = _player_run(executor, receiver, bag, rate, total)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    return figures


def _child_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser()
    p.add_argument('--child-publish', action='store_true')
    p.add_argument('--child-play', metavar='BAG')
    p.add_argument('--rate', type=float, default=1.0)
    p.add_argument('--points', type=int, default=130_000)
    a = p.parse_args(argv)
    if a.child_publish:
        return _child_publish(a.points)
    if a.child_play:
        return _child_play(a.child_play, a.rate)
    p.error('child mode needed')
    return 2


if __name__ == '__main__':
    sys.exit(_child_main(sys.argv[1:]))
