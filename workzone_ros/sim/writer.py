"""Write a synthetic work-zone run as a rosbag2 (MCAP), plus training-data exports.

Topics (bag time starts at :data:`EPOCH_NS`, 1700000000 s; every stamp is deterministic):

============================== ================================ ======= =====================
topic                          type                             rate    frame
============================== ================================ ======= =====================
/camera/image_raw              sensor_msgs/Image bgr8           15 Hz   camera (optical)
/camera/image_raw/compressed   sensor_msgs/CompressedImage jpeg 15 Hz   (with ``compressed``)
/camera/camera_info            sensor_msgs/CameraInfo           15 Hz   camera
/lidar/points                  sensor_msgs/PointCloud2          10 Hz   lidar
/odom                          nav_msgs/Odometry                50 Hz   odom -> base_link
/tf_static                     tf2_msgs/TFMessage               once    base_link -> sensors
/groundtruth/signs             std_msgs/String ``GtSigns``      15 Hz   like the image
/groundtruth/lidar             std_msgs/String ``GtLidar``      10 Hz   like the cloud
/groundtruth/workzone          std_msgs/String ``GtWorkzone``   2       start and end
============================== ================================ ======= =====================

Timing: camera frame ``k`` is exposed at ``k / 15`` s and stamped with that time.  The LiDAR
clock is offset from the camera's by ``latency_ms`` (default 50 ms): scan ``j`` starts its
spin at ``latency + j / 10`` s and is stamped with that start time, so scans are never
synchronised with frames and a consumer must match them by time and compensate ego motion.
Points are in the lidar frame at their own firing time (sim/lidar.py), cast with the scenario's
``lidar:`` preset (HDL-64E unless it names another).  The odom frame is the simulator's world
frame.  Every pose comes from the scenario's ego trajectory, so odometry, LiDAR motion and the
camera follow its speed profile (slow-down, stop-and-go): the odom twist is ds/dt along the
route, zero while the ego stands.

Rendering and ray casting run in a pool of worker processes; every task is a pure function of
(scenario, seed, index), results are consumed in order, and the bag is byte-identical for the
same scenario, seed and options.
"""
from __future__ import annotations

import csv
import math
import multiprocessing as mp
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterable, Iterator, Optional

import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.core.pointcloud import dtype_to_fields
from workzone_ros.interfaces import (
    Box as GtBox,
)
from workzone_ros.interfaces import (
    Extrinsics,
    GtLidar,
    GtLidarSign,
    GtObject,
    GtSign,
    GtSigns,
    GtWorkzone,
    Header,
    Time,
    encode,
)
from workzone_ros.sim.scenario import FPS, LaneVehicle, ScenarioSpec, build_scene
from workzone_ros.sim.world import (
    BASE_TO_CAMERA_ROT,
    CAMERA_IN_BASE,
    DEFAULT_CAMERA,
    LIDAR_IN_BASE,
    LIDAR_TO_CAMERA,
    Pose,
    Scene,
)

__all__ = [
    'EPOCH_NS', 'LIDAR_HZ', 'ODOM_HZ', 'TOPICS', 'SynthError', 'SynthOptions', 'BagSummary',
    'write_bag', 'lidar_scene', 'frame_times', 'scan_times', 'quaternion_from_rpy',
    'rpy_from_matrix', 'export_crops',
    'export_pixels', 'SensorMessages',
]

EPOCH_NS = 1_700_000_000 * 10 ** 9
LIDAR_HZ = 10
ODOM_HZ = 50
TOPICS = {
    'image': '/camera/image_raw',
    'compressed': '/camera/image_raw/compressed',
    'camera_info': '/camera/camera_info',
    'points': '/lidar/points',
    'odom': '/odom',
    'tf_static': '/tf_static',
    'gt_signs': '/groundtruth/signs',
    'gt_lidar': '/groundtruth/lidar',
    'gt_workzone': '/groundtruth/workzone',
}
CAMERA_FRAME, LIDAR_FRAME, BASE_FRAME, ODOM_FRAME = 'camera', 'lidar', 'base_link', 'odom'


class SynthError(RuntimeError):
    """The synthetic bag or export cannot be written (one line)."""


@dataclass(frozen=True)
class SynthOptions:
    """How to write a run.

    Attributes:
        seed: scenario seed (placements, jitter, sensor noise).
        duration: override the scenario duration (s).
        speed: override the ego speed (m/s).
        compressed: write JPEG CompressedImage instead of raw Image.
        jpeg_quality: JPEG quality with ``compressed``.
        latency_ms: offset of the LiDAR clock after the camera clock.
        workers: worker processes for rendering and ray casting (0 = in this process).
        storage: ``mcap`` or ``sqlite3``.
    """

    seed: int = 0
    duration: Optional[float] = None
    speed: Optional[float] = None
    compressed: bool = False
    jpeg_quality: int = 90
    latency_ms: float = 50.0
    workers: int = 2
    storage: str = 'mcap'


@dataclass
class BagSummary:
    """What :func:`write_bag` wrote."""

    path: Path
    frames: int
    scans: int
    odom: int
    seconds: float
    bytes: int
    counts: dict


def _ns(t: float) -> int:
    return EPOCH_NS + int(round(t * 1e9))


def frame_times(duration: float) -> np.ndarray:
    """Camera exposure times (s): ``k / 15`` for every ``k / 15 < duration``."""
    n = int(math.ceil(duration * FPS - 1e-9))
    return np.arange(n) / FPS


def scan_times(duration: float, latency_ms: float) -> np.ndarray:
    """LiDAR spin start times (s): ``latency + j / 10`` while they are ``< duration``."""
    lat = latency_ms / 1000.0
    n = max(int(math.ceil((duration - lat) * LIDAR_HZ - 1e-9)), 0)
    return lat + np.arange(n) / LIDAR_HZ


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float,
                                                                          float]:
    """(x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def rpy_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) with R = Rz(yaw) Ry(pitch) Rx(roll); yaw = 0 at gimbal lock."""
    sp = -float(R[2, 0])
    if abs(sp) > 1.0 - 1e-9:                  # pitch = +-90 deg: only roll -+ yaw is defined
        pitch = math.copysign(math.pi / 2, sp)
        roll = math.atan2(-R[0, 1], -R[0, 2]) if sp < 0 else math.atan2(R[0, 1], R[0, 2])
        return (round(roll, 12), round(pitch, 12), 0.0)
    return (round(math.atan2(R[2, 1], R[2, 2]), 12), round(math.asin(sp), 12),
            round(math.atan2(R[1, 0], R[0, 0]), 12))


def _quat_from_matrix(R: np.ndarray) -> tuple[float, float, float, float]:
    w = math.sqrt(max(0.0, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + R[0, 0] - R[1, 1] - R[2, 2])) / 2,
                      R[2, 1] - R[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - R[0, 0] + R[1, 1] - R[2, 2])) / 2,
                      R[0, 2] - R[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - R[0, 0] - R[1, 1] + R[2, 2])) / 2,
                      R[1, 0] - R[0, 1])
    return x, y, z, w


# --- messages -------------------------------------------------------------------------------

class SensorMessages:
    """rosbags ROS 2 Jazzy message builders and CDR serialisation.

    Shared with ``workzone-ros bag-from-video`` (tools/bag_from_video.py): images, JPEG
    images and CameraInfo of any :class:`~workzone_ros.sim.world.CameraModel` and frame id.
    """

    def __init__(self) -> None:
        from workzone_ros.bagio import typestore
        self.store = typestore()
        self.T = self.store.types

    def ser(self, msg, msgtype: str) -> bytes:
        return bytes(self.store.serialize_cdr(msg, msgtype))

    def header(self, t_ns: int, frame: str):
        T = self.T
        return T['std_msgs/msg/Header'](
            stamp=T['builtin_interfaces/msg/Time'](sec=t_ns // 10 ** 9,
                                                   nanosec=t_ns % 10 ** 9), frame_id=frame)

    def image(self, t_ns: int, img: np.ndarray, frame: str = CAMERA_FRAME) -> bytes:
        h, w = img.shape[:2]
        msg = self.T['sensor_msgs/msg/Image'](
            header=self.header(t_ns, frame), height=h, width=w, encoding='bgr8',
            is_bigendian=0, step=w * 3, data=np.ascontiguousarray(img).reshape(-1))
        return self.ser(msg, 'sensor_msgs/msg/Image')

    def compressed(self, t_ns: int, jpeg: bytes, frame: str = CAMERA_FRAME) -> bytes:
        msg = self.T['sensor_msgs/msg/CompressedImage'](
            header=self.header(t_ns, frame), format='bgr8; jpeg compressed bgr8',
            data=np.frombuffer(jpeg, dtype=np.uint8))
        return self.ser(msg, 'sensor_msgs/msg/CompressedImage')

    def camera_info(self, t_ns: int, cam=DEFAULT_CAMERA, frame: str = CAMERA_FRAME) -> bytes:
        T = self.T
        K = cam.K
        P = np.zeros((3, 4))
        P[:, :3] = K
        msg = T['sensor_msgs/msg/CameraInfo'](
            header=self.header(t_ns, frame), height=cam.height, width=cam.width,
            distortion_model='plumb_bob', d=np.array(cam.D, dtype=np.float64),
            k=K.reshape(-1).astype(np.float64), r=np.eye(3).reshape(-1),
            p=P.reshape(-1), binning_x=0, binning_y=0,
            roi=T['sensor_msgs/msg/RegionOfInterest'](x_offset=0, y_offset=0, height=0,
                                                      width=0, do_rectify=False))
        return self.ser(msg, 'sensor_msgs/msg/CameraInfo')

    def cloud(self, t_ns: int, points: np.ndarray) -> bytes:
        T = self.T
        fields = [T['sensor_msgs/msg/PointField'](name=f.name, offset=f.offset,
                                                  datatype=f.datatype, count=f.count)
                  for f in dtype_to_fields(points.dtype)]
        step = points.dtype.itemsize
        msg = T['sensor_msgs/msg/PointCloud2'](
            header=self.header(t_ns, LIDAR_FRAME), height=1, width=int(points.shape[0]),
            fields=fields, is_bigendian=False, point_step=step,
            row_step=step * int(points.shape[0]),
            data=np.ascontiguousarray(points).view(np.uint8).reshape(-1), is_dense=True)
        return self.ser(msg, 'sensor_msgs/msg/PointCloud2')

    def string(self, text: str) -> bytes:
        return self.ser(self.T['std_msgs/msg/String'](data=text), 'std_msgs/msg/String')

    def _pose(self, position, quat):
        T = self.T
        return T['geometry_msgs/msg/Pose'](
            position=T['geometry_msgs/msg/Point'](x=float(position[0]), y=float(position[1]),
                                                  z=float(position[2])),
            orientation=T['geometry_msgs/msg/Quaternion'](x=quat[0], y=quat[1], z=quat[2],
                                                          w=quat[3]))

    def odom(self, t_ns: int, pose: Pose, lin: np.ndarray, ang: np.ndarray) -> bytes:
        T = self.T
        cov_p = np.diag([0.01, 0.01, 0.01, 1e-4, 1e-4, 1e-4]).reshape(-1)
        cov_t = np.diag([0.01, 0.01, 0.01, 1e-4, 1e-4, 1e-4]).reshape(-1)
        v3 = T['geometry_msgs/msg/Vector3']
        msg = T['nav_msgs/msg/Odometry'](
            header=self.header(t_ns, ODOM_FRAME), child_frame_id=BASE_FRAME,
            pose=T['geometry_msgs/msg/PoseWithCovariance'](
                pose=self._pose(pose.position, quaternion_from_rpy(pose.roll, pose.pitch,
                                                                   pose.yaw)),
                covariance=cov_p),
            twist=T['geometry_msgs/msg/TwistWithCovariance'](
                twist=T['geometry_msgs/msg/Twist'](
                    linear=v3(x=float(lin[0]), y=float(lin[1]), z=float(lin[2])),
                    angular=v3(x=float(ang[0]), y=float(ang[1]), z=float(ang[2]))),
                covariance=cov_t))
        return self.ser(msg, 'nav_msgs/msg/Odometry')

    def tf_static(self, t_ns: int) -> bytes:
        T = self.T
        v3 = T['geometry_msgs/msg/Vector3']
        out = []
        for child, trans, R in ((LIDAR_FRAME, LIDAR_IN_BASE, np.eye(3)),
                                (CAMERA_FRAME, CAMERA_IN_BASE, BASE_TO_CAMERA_ROT.T)):
            q = _quat_from_matrix(R)
            out.append(T['geometry_msgs/msg/TransformStamped'](
                header=self.header(t_ns, BASE_FRAME), child_frame_id=child,
                transform=T['geometry_msgs/msg/Transform'](
                    translation=v3(x=float(trans[0]), y=float(trans[1]), z=float(trans[2])),
                    rotation=T['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2],
                                                               w=q[3]))))
        return self.ser(T['tf2_msgs/msg/TFMessage'](transforms=out), 'tf2_msgs/msg/TFMessage')


# --- the world, per process -----------------------------------------------------------------

def lidar_scene(scene: Scene, t0: float) -> Scene:
    """The scene for a spin starting at ``t0``: lane-following vehicles become straight movers.

    The ray caster moves a box along its yaw from its t = 0 pose; a vehicle that follows a
    curved lane is therefore replaced by the straight mover tangent to it at ``t0``.
    """
    if not any(isinstance(o, LaneVehicle) and o.speed for o in scene.objects):
        return scene
    objs = []
    for o in scene.objects:
        if isinstance(o, LaneVehicle) and o.speed:
            b = o.at(t0)
            fwd = np.array([math.cos(b.yaw), math.sin(b.yaw), 0.0])
            objs.append(replace(b, center=b.center - fwd * b.speed * t0))
        else:
            objs.append(o)
    return replace(scene, objects=objs)


class _World:
    """Scene, ego, renderer and message builders of one run (one per process)."""

    def __init__(self, spec: ScenarioSpec, opts: SynthOptions):
        import cv2
        cv2.setNumThreads(1)
        self.spec, self.opts = spec, opts
        self.scene, self.ego, self.events = build_scene(spec, opts.seed)
        self.msgs = SensorMessages()
        self._renderer = None

    @property
    def renderer(self):
        if self._renderer is None:
            from workzone_ros.sim.camera import CameraRenderer
            self._renderer = CameraRenderer(self.scene, DEFAULT_CAMERA, seed=self.opts.seed)
        return self._renderer

    def frame(self, k: int, t: float) -> list[tuple[int, str, bytes]]:
        import cv2
        res = self.renderer.render(t, self.ego.base_pose(t), k)
        t_ns = _ns(t)
        out = []
        if self.opts.compressed:
            ok, buf = cv2.imencode('.jpg', res.image,
                                   [cv2.IMWRITE_JPEG_QUALITY, int(self.opts.jpeg_quality)])
            if not ok:
                raise SynthError(f'JPEG encoding of frame {k} failed')
            out.append((t_ns, 'compressed', self.msgs.compressed(t_ns, buf.tobytes())))
        else:
            out.append((t_ns, 'image', self.msgs.image(t_ns, res.image)))
        out.append((t_ns, 'camera_info', self.msgs.camera_info(t_ns)))
        out.append((t_ns, 'gt_signs', self.msgs.string(encode(self.gt_signs(t_ns, res)))))
        return out

    def gt_signs(self, t_ns: int, res) -> GtSigns:
        signs = []
        for h in sorted(res.signs, key=lambda h: h.sign_id):
            c = catalogue.get(h.class_key)
            signs.append(GtSign(sign_id=int(h.sign_id), class_key=c.key, code=c.code,
                                category=c.category, box=GtBox(*map(float, h.box)),
                                distance_m=round(float(h.distance_m), 3),
                                visible_fraction=round(min(max(float(h.visible_fraction),
                                                               0.0), 1.0), 4)))
        objs = [GtObject(object_id=int(o.object_id), kind=str(o.kind),
                         box=GtBox(*map(float, o.box)), distance_m=round(float(o.distance_m), 3))
                for o in sorted(res.distractors, key=lambda o: o.object_id)
                if not str(o.kind).startswith('tree')]           # foliage is not a distractor
        return GtSigns(header=Header(stamp=Time.from_ns(t_ns), frame_id=CAMERA_FRAME),
                       signs=signs, distractors=objs, weather=self.scene.weather)

    def scan(self, j: int, t0: float) -> list[tuple[int, str, bytes]]:
        from workzone_ros.sim.lidar import cast_scan
        model = self.spec.lidar.sensor()
        sc = cast_scan(lidar_scene(self.scene, t0), t0, self.ego.lidar_pose, model,
                       seed=self.opts.seed, scan_index=j)
        t_ns = _ns(t0)
        by_id = {s.object_id: s for s in self.scene.signs}
        gts = []
        for sid in sorted(sc.sign_hits):
            sp = by_id.get(sid)
            if sp is None:
                continue
            gts.append(GtLidarSign(sign_id=int(sid), class_key=sp.class_key,
                                   center=self.sign_center_in_lidar(sp, t0, model),
                                   indices=[int(i) for i in sc.sign_hits[sid]]))
        gt = GtLidar(header=Header(stamp=Time.from_ns(t_ns), frame_id=LIDAR_FRAME), signs=gts)
        return [(t_ns, 'points', self.msgs.cloud(t_ns, sc.points)),
                (t_ns, 'gt_lidar', self.msgs.string(encode(gt)))]

    def sign_center_in_lidar(self, sp, t0: float, model) -> tuple[float, float, float]:
        """Face centre in the lidar frame at the time the spin sweeps over it."""
        spin = 1.0 / model.rate_hz
        t = t0 + spin / 2
        for _ in range(2):
            p = self.ego.lidar_pose(t).to_body(np.asarray(sp.center, float))
            frac = ((math.pi - math.atan2(p[1], p[0])) / (2 * math.pi)) % 1.0
            t = t0 + frac * spin
        p = self.ego.lidar_pose(t).to_body(np.asarray(sp.center, float))
        return (round(float(p[0]), 4), round(float(p[1]), 4), round(float(p[2]), 4))

    def run(self, task: tuple[str, int, float]) -> list[tuple[int, str, bytes]]:
        kind, i, t = task
        return self.frame(i, t) if kind == 'frame' else self.scan(i, t)


_WORLD: Optional[_World] = None


def _init_worker(spec: ScenarioSpec, opts: SynthOptions) -> None:
    global _WORLD
    _WORLD = _World(spec, opts)


def _run_task(task):
    assert _WORLD is not None
    return _WORLD.run(task)


def _results(spec: ScenarioSpec, opts: SynthOptions, tasks: list,
             world: _World) -> Iterator[list]:
    if opts.workers <= 0 or len(tasks) < 8:
        for task in tasks:
            yield world.run(task)
        return
    ctx = mp.get_context('spawn')
    with ctx.Pool(opts.workers, initializer=_init_worker, initargs=(spec, opts)) as pool:
        yield from pool.imap(_run_task, tasks, chunksize=1)


# --- the bag --------------------------------------------------------------------------------

def _check_out(out: Path, overwrite: bool) -> None:
    if out.exists():
        if not overwrite:
            raise SynthError(f'{out} exists (use --overwrite)')
        if not out.is_dir() or not ((out / 'metadata.yaml').exists() or not any(out.iterdir())):
            raise SynthError(f'{out} exists and is not a bag directory; not deleting it')


def _gt_workzone(world: _World, duration: float, t_ns: int) -> GtWorkzone:
    events = [e for e in world.events if 0.0 <= e.t <= duration]
    begin = next((e for e in events if e.kind == 'zone_begin'), None)
    end = next((e for e in events if e.kind == 'zone_end'), None)
    tr = LIDAR_TO_CAMERA[:3, 3]
    return GtWorkzone(
        header=Header(stamp=Time.from_ns(t_ns), frame_id=ODOM_FRAME), scenario=world.spec.name,
        seed=int(world.opts.seed), begin_t=begin.t if begin else None,
        begin_x_m=begin.x_m if begin else None, end_t=end.t if end else None,
        end_x_m=end.x_m if end else None, events=events,
        extrinsics=Extrinsics(translation=tuple(round(float(x), 9) for x in tr),
                              rpy=rpy_from_matrix(LIDAR_TO_CAMERA[:3, :3]),
                              matrix=[[round(float(x), 9) for x in row]
                                      for row in LIDAR_TO_CAMERA]),
        weather=world.scene.weather)


def _progress_printer(stream=sys.stderr) -> Callable[[str], None]:
    def emit(line: str) -> None:
        print(line, file=stream, flush=True)
    return emit


def _open_bag_writer(tmp: Path, opts: SynthOptions):
    """A :class:`~workzone_ros.bagio.BagWriter` at ``tmp`` with the synth topics added."""
    from workzone_ros.bagio import BagWriter

    bag = BagWriter(tmp, storage=opts.storage)
    image_key = 'compressed' if opts.compressed else 'image'
    types = {'image': 'sensor_msgs/msg/Image',
             'compressed': 'sensor_msgs/msg/CompressedImage',
             'camera_info': 'sensor_msgs/msg/CameraInfo',
             'points': 'sensor_msgs/msg/PointCloud2', 'odom': 'nav_msgs/msg/Odometry',
             'tf_static': 'tf2_msgs/msg/TFMessage', 'gt_signs': 'std_msgs/msg/String',
             'gt_lidar': 'std_msgs/msg/String', 'gt_workzone': 'std_msgs/msg/String'}
    qos = {'tf_static': 'transient_local', 'gt_workzone': 'transient_local'}
    for key in (image_key, 'camera_info', 'points', 'odom', 'tf_static', 'gt_signs',
                'gt_lidar', 'gt_workzone'):
        bag.add_topic(TOPICS[key], types[key], qos=qos.get(key, 'reliable'))
    return bag


class _OdomFlusher:
    """Writes the odometry messages due up to a time, in order, each once."""

    def __init__(self, world: _World, odom_t: np.ndarray,
                 put: Callable[[int, str, bytes], None]) -> None:
        self.world, self.odom_t, self.put = world, odom_t, put
        self.oi = 0

    def __call__(self, upto_ns: int) -> None:
        world, odom_t = self.world, self.odom_t
        while self.oi < len(odom_t) and _ns(odom_t[self.oi]) <= upto_ns:
            t = float(odom_t[self.oi])
            lin, ang = world.ego.twist(t)
            o_ns = _ns(t)
            self.put(o_ns, 'odom', world.msgs.odom(o_ns, world.ego.base_pose(t), lin, ang))
            self.oi += 1


def _write_results(spec: ScenarioSpec, opts: SynthOptions, tasks: list, world: _World,
                   put: Callable[[int, str, bytes], None], flush_odom: _OdomFlusher,
                   n_frames: int, n_scans: int, started: float,
                   progress: Optional[Callable[[str], None]]) -> None:
    """Write the rendered frames and scans in time order (odometry interleaved), reporting
    progress about every 2 s."""
    done_f = done_s = 0
    last = started
    for result in _results(spec, opts, tasks, world):
        flush_odom(result[0][0])
        for t_ns, key, data in result:
            put(t_ns, key, data)
        if result[0][1] == 'points':
            done_s += 1
        else:
            done_f += 1
        now = time.monotonic()
        if progress is not None and now - last >= 2.0:
            last = now
            frac = (done_f + done_s) / max(len(tasks), 1)
            el = now - started
            eta = f'{el / frac - el:.0f} s' if frac >= 0.03 else '?'
            progress(f'synth {spec.name}: frames {done_f}/{n_frames}, scans '
                     f'{done_s}/{n_scans}, {el:.0f} s elapsed, ETA {eta}')


def _schedule(duration: float, latency_ms: float):
    """Camera frame times, LiDAR scan times, odometry times, the render tasks in write order
    and the bag's end stamp (ns)."""
    frames, scans = frame_times(duration), scan_times(duration, latency_ms)
    odom_t = np.arange(int(math.ceil(duration * ODOM_HZ - 1e-9))) / ODOM_HZ
    tasks = sorted([('frame', k, float(t)) for k, t in enumerate(frames)]
                   + [('scan', j, float(t)) for j, t in enumerate(scans)],
                   key=lambda x: (x[2], x[0] == 'scan'))
    end_ns = _ns(max(duration, frames[-1] if len(frames) else 0.0))
    return frames, scans, odom_t, tasks, end_ns


def _write_all(bag, spec: ScenarioSpec, opts: SynthOptions, world: _World, tasks: list,
               odom_t: np.ndarray, end_ns: int, n_frames: int, n_scans: int, started: float,
               progress: Optional[Callable[[str], None]]) -> None:
    """Write every message of the run: static transforms and work-zone ground truth, then
    frames, scans and odometry in time order, then the closing ground truth."""
    msgs, duration = world.msgs, spec.duration

    def put(t_ns: int, key: str, data: bytes) -> None:
        bag.write(TOPICS[key], t_ns, data)

    t0_ns = _ns(0.0)
    put(t0_ns, 'tf_static', msgs.tf_static(t0_ns))
    put(t0_ns, 'gt_workzone', msgs.string(encode(_gt_workzone(world, duration, t0_ns))))
    flush_odom = _OdomFlusher(world, odom_t, put)
    _write_results(spec, opts, tasks, world, put, flush_odom, n_frames, n_scans, started,
                   progress)
    flush_odom(end_ns)
    put(end_ns, 'gt_workzone', msgs.string(encode(_gt_workzone(world, duration, end_ns))))


def write_bag(spec: ScenarioSpec, out: str | Path, opts: SynthOptions = SynthOptions(),
              overwrite: bool = False,
              progress: Optional[Callable[[str], None]] = _progress_printer()) -> BagSummary:
    """Render, ray-cast and write one scenario run as a rosbag2.

    Args:
        spec: the scenario (``opts.duration`` / ``opts.speed`` override it).
        out: bag directory to create.
        opts: seed, duration, compression, latency, workers.
        overwrite: replace an existing bag directory (never anything else).
        progress: called with a status line about every 2 s (None: silent).

    Returns:
        A summary with counts, size and wall time.

    Raises:
        SynthError: output exists, cannot be written, or bad options.
        ScenarioError: the scenario cannot be built.
    """
    from workzone_ros.bagio import BagError

    started = time.monotonic()
    out = Path(out)
    _check_out(out, overwrite)
    if opts.latency_ms < 0 or opts.latency_ms >= 1000.0 / LIDAR_HZ:
        raise SynthError(f'latency must be in [0, {1000 // LIDAR_HZ}) ms, got {opts.latency_ms}')
    spec = spec.with_overrides(opts.duration, opts.speed)
    world = _World(spec, opts)
    frames, scans, odom_t, tasks, end_ns = _schedule(spec.duration, opts.latency_ms)

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp_root = Path(tempfile.mkdtemp(prefix=f'.{out.name}.', dir=out.parent))
    tmp = tmp_root / out.name
    try:
        bag = _open_bag_writer(tmp, opts)
        _write_all(bag, spec, opts, world, tasks, odom_t, end_ns, len(frames), len(scans),
                   started, progress)
        counts = dict(bag.counts)
        bag.close()
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BagError as exc:
        raise SynthError(str(exc)) from None
    finally:
        shutil.rmtree(tmp_root, ignore_errors=True)
    size = sum(p.stat().st_size for p in out.iterdir() if p.is_file())
    return BagSummary(out, len(frames), len(scans), len(odom_t), time.monotonic() - started,
                      size, counts)


# --- training-data exports ------------------------------------------------------------------

def _sign_times(world: _World, dist_lo: float, dist_hi: float, n: int,
                keys: Optional[Iterable[str]] = None) -> list[tuple[float, int]]:
    """Times when the ego is ``dist_lo``..``dist_hi`` m before each sign (n per sign)."""
    road, ego = world.scene.road, world.ego
    out = []
    for sp in world.scene.signs:
        if keys is not None and sp.class_key not in keys:
            continue
        s_sign = float(road.to_frenet(np.array([sp.center[0]]), np.array([sp.center[1]]))[0][0])
        for dist in np.linspace(dist_hi, dist_lo, n):
            t = float(ego.t_at(s_sign - dist))
            if 0.0 <= t <= world.spec.duration:
                out.append((t, sp.object_id))
    return out


def _jitter_box(box, rng: np.random.Generator, lo: float = 0.10, hi: float = 0.20):
    """Shift and scale a box by 10-20 % (random sign), like a detector's localisation."""
    x, y, w, h = box
    amt = lambda: float(rng.uniform(lo, hi)) * (1 if rng.random() < 0.5 else -1)  # noqa: E731
    scale = 1.0 + amt()
    cx, cy = x + w / 2 + amt() * w, y + h / 2 + amt() * h
    side = max(w, h) * scale
    return cx - side / 2, cy - side / 2, side, side


def _crop(img: np.ndarray, box, size: int) -> Optional[np.ndarray]:
    import cv2
    x, y, w, h = box
    if w < 6 or h < 6:
        return None
    H, W = img.shape[:2]
    x0, y0, x1, y1 = int(round(x)), int(round(y)), int(round(x + w)), int(round(y + h))
    pad = max(0, -x0, -y0, x1 - W, y1 - H)
    if pad:
        img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_REFLECT)
        x0, y0, x1, y1 = x0 + pad, y0 + pad, x1 + pad, y1 + pad
    patch = img[y0:y1, x0:x1]
    if patch.size == 0:
        return None
    return cv2.resize(patch, (size, size), interpolation=cv2.INTER_AREA)


def _holds_sign(box, signs, share: float = 0.3) -> bool:
    """Whether ``box`` (x, y, w, h) covers at least ``share`` of some visible sign's face."""
    x, y, w, h = (float(v) for v in box)
    for sign in signs:
        sx, sy, sw, sh = (float(v) for v in sign.box)
        iw = min(x + w, sx + sw) - max(x, sx)
        ih = min(y + h, sy + sh) - max(y, sy)
        if iw > 0 and ih > 0 and sw * sh > 0 and iw * ih >= share * sw * sh:
            return True
    return False


def export_crops(out_dir: str | Path, specs: list[ScenarioSpec], seed: int = 0,
                 per_class: int = 50, size: int = 64,
                 progress: Optional[Callable[[str], None]] = _progress_printer()) -> dict:
    """Sign crops per class and background crops, with detector-like box jitter.

    Writes ``out_dir/<class_key>/<scenario>_<frame>_<id>.png`` and ``out_dir/index.csv``.

    Args:
        out_dir: output directory (created).
        specs: scenarios to render from (the library gives every class).
        seed: scenario seed and jitter seed.
        per_class: crops per class at most.
        size: crop side in pixels.
        progress: status callback.

    Returns:
        Class key -> number of crops written.
    """
    import cv2
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng([seed, 0xc409])
    counts: dict[str, int] = {}
    rows = []
    for spec in specs:
        world = _World(spec, SynthOptions(seed=seed, workers=0))
        by_id = {s.object_id: s for s in world.scene.signs}
        plan = sorted({round(t * FPS) for t, _ in _sign_times(world, 12.0, 90.0, 6)})
        for k in plan:
            t = k / FPS
            if all(counts.get(key, 0) >= per_class for key in catalogue.BY_KEY):
                break
            res = world.renderer.render(t, world.ego.base_pose(t), k)
            items = [(h.class_key, h.sign_id, h.box) for h in res.signs
                     if h.visible_fraction > 0.6 and min(h.box[2], h.box[3]) >= 8
                     and h.sign_id in by_id]
            # a drum or vehicle in front of a sign is no background example: its crop shows
            # the sign (a third of a sign's face inside it is too much)
            items += [('background', o.object_id, o.box) for o in res.distractors
                      if min(o.box[2], o.box[3]) >= 8 and not _holds_sign(o.box, res.signs)]
            # foliage / roadside patches away from every sign
            for _ in range(2):
                side = float(rng.uniform(20, 80))
                bx = (float(rng.uniform(0, 640 - side)), float(rng.uniform(120, 330)), side,
                      side)
                if all(GtBox(*bx).iou(GtBox(*map(float, h.box))) == 0 for h in res.signs):
                    items.append(('background', -1, bx))
            for key, oid, box in items:
                if counts.get(key, 0) >= per_class:
                    continue
                jb = _jitter_box(box, rng) if oid >= 0 else box
                patch = _crop(res.image, jb, size)
                if patch is None:
                    continue
                name = f'{spec.name}_{k:05d}_{oid if oid >= 0 else "bg"}_{counts.get(key, 0)}.png'
                (out / key).mkdir(exist_ok=True)
                cv2.imwrite(str(out / key / name), patch)
                counts[key] = counts.get(key, 0) + 1
                c = catalogue.get(key)
                rows.append([f'{key}/{name}', key, c.code, c.category, spec.name, seed, k, oid,
                             *[round(float(v), 1) for v in box],
                             *[round(float(v), 1) for v in jb]])
        if progress is not None:
            progress(f'crops {spec.name}: ' + ', '.join(f'{k} {v}' for k, v in
                                                         sorted(counts.items())))
    with open(out / 'index.csv', 'w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(['path', 'class_key', 'code', 'category', 'scenario', 'seed', 'frame',
                    'object_id', 'box_x', 'box_y', 'box_w', 'box_h', 'crop_x', 'crop_y',
                    'crop_w', 'crop_h'])
        w.writerows(rows)
    return counts


def export_pixels(out_dir: str | Path, specs: list[ScenarioSpec], seed: int = 0,
                  frames: int = 100,
                  progress: Optional[Callable[[str], None]] = _progress_printer(),
                  camera_jitter: bool = True) -> int:
    """Images and pixel masks of the work-zone (orange) sign faces, for colour-model training.

    Writes ``images/<name>.png``, ``masks/<name>.png`` (255 on work-zone sign faces, from the
    renderer's per-pixel labels) and ``index.csv``.  Frames are spread over the moments
    work-zone signs are 15-150 m ahead, plus some frames without any.  With
    ``camera_jitter`` each frame's vehicle pose is raised by -0.3..+0.5 m and pitched by
    +/-3 degrees (other vehicles, other mounts: the horizon and the signs' image rows move),
    so a model's spatial prior is not tied to our camera.

    Returns:
        Number of frames written.
    """
    import cv2
    out = Path(out_dir)
    (out / 'images').mkdir(parents=True, exist_ok=True)
    (out / 'masks').mkdir(parents=True, exist_ok=True)
    per = max(1, int(math.ceil(frames / max(len(specs), 1))))
    rows, n = [], 0
    for spec in specs:
        world = _World(spec, SynthOptions(seed=seed, workers=0))
        wz_ids = {s.object_id for s in world.scene.signs
                  if catalogue.get(s.class_key).category == 'workzone'}
        cand = sorted({round(t * FPS) for t, _ in _sign_times(
            world, 15.0, 150.0, 8, catalogue.WORKZONE_KEYS)})
        total = max(frame_times(spec.duration).size, 1)
        n_sign = min(len(cand), int(round(per * 0.8)))
        pick = [cand[int(i)] for i in np.linspace(0, len(cand) - 1, n_sign)] if n_sign else []
        pick += [int(i) for i in np.linspace(0, total - 1, per - len(pick))]
        for k in sorted(set(pick)):
            if n >= frames:
                break
            t = k / FPS
            pose = world.ego.base_pose(t)
            if camera_jitter:
                jr = np.random.default_rng([seed, k, 7703])
                lift = jr.uniform(-0.3, 0.5)
                pose = replace(pose, position=pose.position + [0.0, 0.0, lift],
                               pitch=pose.pitch + math.radians(jr.uniform(-3.0, 3.0)))
            res = world.renderer.render(t, pose, k)
            mask = np.isin(res.label, list(wz_ids)).astype(np.uint8) * 255
            name = f'{spec.name}_{seed}_{k:05d}'
            cv2.imwrite(str(out / 'images' / f'{name}.png'), res.image)
            cv2.imwrite(str(out / 'masks' / f'{name}.png'), mask)
            rows.append([f'images/{name}.png', f'masks/{name}.png', spec.name, seed, k,
                         spec.weather, int(mask.astype(bool).sum())])
            n += 1
        if progress is not None:
            progress(f'pixels {spec.name}: {n} frames')
    with open(out / 'index.csv', 'w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(['image', 'mask', 'scenario', 'seed', 'frame', 'weather', 'sign_pixels'])
        w.writerows(rows)
    return n
