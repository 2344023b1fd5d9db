"""``projector`` node: candidates + image + CameraInfo (+ odom) -> ``/workzone/rois``
(after Cahail et al.).

Thin wrapper around :mod:`workzone_ros.core.sync` and :mod:`workzone_ros.core.projection`:

* candidates and images are matched by stamp (``sync_policy``):

  - ``nearest`` (default): every image gets the candidate set nearest in time within the
    ``slop`` (a set may serve several images), waiting at most ``max_wait`` for a later scan
    when that one could be nearer (:class:`~workzone_ros.core.sync.NearestSync`); with
    ``sync_forward_time`` a set's time is when the spin looks along the camera axis;
  - ``approximate``: the message_filters ApproximateTime policy (``slop``, ``queue_size``,
    ``age_penalty``): one-to-one pairs, so with a 15 Hz camera and a 10 Hz LiDAR about a
    third of the images get no ROIs;
  - ``latest``: the seed's "last cloud received" baseline (no slop);
* candidates are moved from the scan time (per candidate firing time of the spin) to the
  image time with odometry poses, whatever the gap the pairing left (image before or after
  the scan), then projected with the CameraInfo intrinsics and distortion and the configured
  LiDAR->camera extrinsics;
* one ``Rois`` payload per matched image, stamped with the image stamp and carrying the
  LiDAR stamp used and whether the motion was compensated; optionally the crops.

No CameraInfo yet, unusable extrinsics, or candidates with no image within the slop: the
input is dropped with a clear reason in ``/diagnostics`` and the log; nothing is guessed.
"""
from __future__ import annotations

import collections
import time
from typing import Any, Optional

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
from std_msgs.msg import String

from workzone_ros import interfaces
from workzone_ros.core.lidar_rois import size_rois
from workzone_ros.core.projection import (
    CameraModel,
    ProjectionError,
    RoiParams,
    candidates_to_rois,
    euler_matrix,
    extrinsics_from_list,
    forward_time_offset,
)
from workzone_ros.core.sync import (
    ApproximateTimeSync,
    LatestSync,
    NearestSync,
    PoseBuffer,
    SyncError,
)
from workzone_ros.nodes.base import InputError, Param, WorkzoneNode, run_node
from workzone_ros.nodes.conversions import (
    camera_info_to_numpy,
    compressed_image_size,
    compressed_to_numpy,
    header_to_payload,
    image_to_numpy,
    numpy_to_image,
    payload_to_string,
    pointcloud2_to_array,
    stamp_to_time,
)
from workzone_ros.nodes.params import image_params

__all__ = ['ProjectorNode', 'NODE_CLASS', 'main']

_R = RoiParams()
_SIM_EXTRINSICS = [0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, -0.5, 1.0, 0.0, 0.0, -0.6,
                   0.0, 0.0, 0.0, 1.0]
IMAGE, CANDS = 0, 1


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class ProjectorNode(WorkzoneNode):
    """Synchronise, compensate, project, crop (Cahail et al. s2 and its future work)."""

    PARAMS = (
        Param('candidates_topic', '/workzone/lidar/candidates', 'input candidates',
              read_only=True),
        *image_params('; the size then comes from CameraInfo'),
        Param('camera_info_topic', '/camera/camera_info', 'input CameraInfo', read_only=True),
        Param('odom_topic', '/odom', 'odometry for ego-motion compensation ("" = off)',
              read_only=True),
        Param('rois_topic', '/workzone/rois', 'output Rois payload', read_only=True),
        Param('crops_topic', '', 'optional crops for viewing ("" = off)', read_only=True),
        Param('lidar_to_camera', _SIM_EXTRINSICS,
              'LiDAR -> camera, row-major 4x4 (or top 3x4): X_cam = T @ X_lidar'),
        Param('lidar_in_base', [1.0, 0.0, 1.95, 0.0, 0.0, 0.0],
              'lidar pose in base_link: x y z roll pitch yaw (for odometry)'),
        Param('sync_policy', 'nearest', 'nearest (each image: the candidate set nearest in '
              'time within the slop, sets reused), approximate (message_filters '
              'ApproximateTime, one-to-one) or latest (the baseline of Cahail et al.: the last '
              'cloud received)',
              choices=('nearest', 'approximate', 'latest')),
        Param('slop', 0.1, 'maximum stamp difference image <-> candidates, s', min=0.0,
              max=10.0),
        Param('queue_size', 5, 'messages kept per input by the synchroniser', min=1,
              max=100),
        Param('age_penalty', 0.1, 'ApproximateTime age penalty', min=0.0, max=100.0),
        Param('max_wait', 0.15, 'nearest: how long an image may wait (image clock) for a '
              'later scan that could be nearer, s; 0 = never wait', min=0.0, max=5.0),
        Param('sync_forward_time', True, 'nearest: match the time the spin looks forward '
              '(along the camera axis: stamp + half a spin with spin_timing) instead of the '
              'cloud stamp'),
        Param('compensate', True, 'ego-motion compensation with odometry'),
        Param('spin_timing', _R.spin_timing, 'the cloud stamp is the start of the spin: '
              'time each candidate by its azimuth'),
        Param('lidar_rate_hz', _R.lidar_rate_hz, 'spin rate for spin_timing', min=0.1,
              max=100.0),
        Param('max_odom_extrapolation', 0.1, 'extrapolate odometry at most this far, s',
              min=0.0, max=5.0),
        Param('crop_margin', _R.margin, 'crop half-size = margin * max(radius, '
              'crop_min_radius) ...', min=0.1, max=20.0),
        Param('crop_min_radius', _R.min_radius, '... smallest sign radius assumed, m',
              min=0.0, max=10.0),
        Param('crop_pad_m', _R.pad_m, '... plus this many metres (calibration, sync)',
              min=0.0, max=10.0),
        Param('crop_pad_px', _R.pad_px, '... plus this many pixels', min=0.0, max=1000.0),
        Param('crop_min_px', _R.min_px, 'smallest crop side, px', min=0.0, max=10000.0),
        Param('crop_max_px', _R.max_px, 'largest crop side, px (0 = no cap)', min=0.0,
              max=100000.0),
    )
    INPUT_TOPICS = ('candidates_topic', 'image_topic', 'camera_info_topic', 'odom_topic')
    #: wall seconds an image may wait for the first CameraInfo before it is dropped
    INFO_GRACE_S = 2.0

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('projector', **kwargs)
        self._camera: Optional[CameraModel] = None
        self._extrinsics: Optional[np.ndarray] = None
        self._extrinsics_error = ''
        self._poses = PoseBuffer()
        self._image_stamps: collections.deque = collections.deque(maxlen=64)
        self._counts = collections.Counter()
        # images (with their candidates) that came before the first CameraInfo: held for
        # INFO_GRACE_S and projected when it comes (a replay's first image can beat it)
        self._held: collections.deque = collections.deque(maxlen=64)
        self._waiting_since: Optional[float] = None
        self._configure()
        self._rois_pub = self.reliable_publisher(String, self.params.rois_topic)
        self._crops_pub = self.sensor_publisher(Image, self.params.crops_topic) \
            if self.params.crops_topic else None
        self._info_sub = self.reliable_subscription(CameraInfo, self.params.camera_info_topic,
                                                    self._on_info, depth=1)
        self._cand_sub = self.reliable_subscription(PointCloud2, self.params.candidates_topic,
                                                    self._on_candidates, depth=5)
        self._image_sub = self.image_subscription(self.params.image_topic, self._on_image,
                                                  self.params.compressed, depth=5)
        self._odom_sub = self.reliable_subscription(
            Odometry, self.params.odom_topic, self._on_odom, depth=50) \
            if self.params.odom_topic and self.params.compensate else None

    # --- configuration -------------------------------------------------------------------

    def _configure(self) -> None:
        p = self.params
        try:
            self._extrinsics = extrinsics_from_list(p.lidar_to_camera)
            self._extrinsics_error = ''
        except ProjectionError as exc:
            self._extrinsics = None
            self._extrinsics_error = f'unusable lidar_to_camera parameter: {exc}'
            self.get_logger().error(self._extrinsics_error + ' -- no ROIs until it is fixed')
        lb = list(p.lidar_in_base) + [0.0] * 6
        self._base_to_lidar = euler_matrix(tuple(lb[:3]), tuple(lb[3:6]))
        self._poses.max_extrapolation_ns = int(p.max_odom_extrapolation * 1e9)
        self._roi_params = RoiParams(
            margin=p.crop_margin, min_radius=p.crop_min_radius, pad_px=p.crop_pad_px,
            min_px=p.crop_min_px, max_px=p.crop_max_px, pad_m=p.crop_pad_m,
            spin_timing=p.spin_timing, lidar_rate_hz=p.lidar_rate_hz)
        self._slop_ns = int(p.slop * 1e9)
        self._sync = ApproximateTimeSync(2, p.queue_size, self._slop_ns, p.age_penalty)
        self._latest = LatestSync()
        offset = forward_time_offset(self._roi_params) if p.sync_forward_time else 0
        self._nearest = NearestSync(self._slop_ns, int(1e9 / p.lidar_rate_hz),
                                    int(p.max_wait * 1e9), offset,
                                    history=max(p.queue_size, 2),
                                    max_pending=max(p.queue_size, 2))

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Apply live changes (the synchroniser restarts empty)."""
        self._configure()

    def on_time_jump(self, old_ns: int, new_ns: int) -> None:
        """A looping bag: the synchronisers, the poses and the held images restart empty
        (stored by stamp, the old pass's would outrank or discard the new one's)."""
        self._poses = PoseBuffer()
        self._image_stamps.clear()
        self._held.clear()
        self._configure()
        self._counts['time jumps (synchroniser reset)'] += 1

    # --- inputs --------------------------------------------------------------------------

    def _on_info(self, msg: CameraInfo) -> None:
        self._camera = CameraModel.from_info(camera_info_to_numpy(msg))
        while self._held:
            self._project(*self._held.popleft())

    def _on_odom(self, msg: Odometry) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        try:
            self._poses.add(_ns(msg.header.stamp), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
        except SyncError as exc:
            raise InputError(f'odometry: {exc}') from None

    def _on_candidates(self, msg: PointCloud2) -> None:
        arr = pointcloud2_to_array(msg)
        missing = [f for f in ('x', 'y', 'z', 'radius') if f not in (arr.dtype.names or ())]
        if missing:
            raise InputError(f'candidates cloud has no {"/".join(missing)} field')
        multi = [f for f in arr.dtype.names if arr.dtype[f].shape]
        if multi:
            raise InputError(f'candidates field {", ".join(multi)} must hold one value per '
                             f'candidate')
        stamp = _ns(msg.header.stamp)
        cands = (msg.header, arr.copy())
        if self.params.sync_policy == 'latest':
            self._latest.add_cloud(stamp, cands)
            return
        if self.params.sync_policy == 'nearest':
            self._emit(self._nearest.add_candidates(stamp, cands))
            return
        if self._image_stamps and max(self._image_stamps) > stamp + self._slop_ns:
            # Images newer than the slop window arrived: its own image will not come.
            nearest = min(abs(stamp - t) for t in self._image_stamps)
            if nearest > self._slop_ns:
                self._counts['unmatched candidates'] += 1
                raise InputError(
                    f'no image within slop {self.params.slop:.3f} s of the candidates stamped '
                    f'{stamp * 1e-9:.3f} (nearest image {nearest * 1e-9:.3f} s away): clocks '
                    f'out of sync or images lost')
        for _, (image, c) in self._sync.add(CANDS, stamp, cands):
            self._project(image, c)

    def _on_image(self, msg: Any) -> None:
        # checked on arrival (a view, or the JPEG/PNG header: nothing is decoded), so a
        # malformed image is dropped with its reason instead of getting ROIs
        if isinstance(msg, CompressedImage):
            compressed_image_size(msg)
        else:
            image_to_numpy(msg)
        stamp = _ns(msg.header.stamp)
        self._image_stamps.append(stamp)
        if self.params.sync_policy == 'latest':
            got = self._latest.add_image(stamp)
            if got is not None:
                self._project(msg, got[1])
            return
        if self.params.sync_policy == 'nearest':
            self._emit(self._nearest.add_image(stamp, msg))
            return
        for _, (image, c) in self._sync.add(IMAGE, stamp, msg):
            self._project(image, c)

    # --- output --------------------------------------------------------------------------

    def _emit(self, decided: list) -> None:
        """Project the images the nearest-time synchroniser decided."""
        for img_ns, image, _, cands in decided:
            if cands is None:
                if self._ready():             # else the missing calibration is the reason
                    # A sync miss, not an invalid input: counted in /diagnostics, not dropped.
                    self._counts['images without candidates within slop'] += 1
                    self.warn_throttled(
                        'no candidates', f'no candidates within slop {self.params.slop:.3f} s '
                        f'of the image stamped {img_ns * 1e-9:.3f}: LiDAR late, lost or clocks '
                        f'out of sync (the image gets no ROIs)')
                continue
            self._project(image, cands)

    def _lidar_pose(self, t_ns: int) -> Optional[np.ndarray]:
        base = self._poses.at(t_ns)
        return None if base is None else base @ self._base_to_lidar

    def _ready(self, hold: Optional[tuple] = None) -> bool:
        """CameraInfo and extrinsics are there; else drop the image with the reason.

        For the first ``INFO_GRACE_S`` (wall) after an image first finds no CameraInfo, the
        image is not dropped: ``hold`` (image, candidates) is kept to be projected when the
        CameraInfo comes (a replay's first image can arrive before it).
        """
        topic = self._image_sub.topic_name
        if self._camera is None and self._extrinsics is not None:
            now = time.monotonic()
            if self._waiting_since is None:
                self._waiting_since = now
            if now - self._waiting_since <= self.INFO_GRACE_S:
                self._counts['held for CameraInfo'] += 1
                if hold is not None:
                    self._held.append(hold)
                return False
        if self._camera is None:
            reason = (f'no CameraInfo received on {self.params.camera_info_topic}: cannot '
                      f'project (intrinsics are never guessed)')
            for _ in range(len(self._held) + 1):
                self._counts['no camera info'] += 1
                self.drop(topic, reason)
            self._held.clear()
            return False
        if self._extrinsics is None:
            self._counts['no extrinsics'] += 1
            self.drop(topic, self._extrinsics_error)
            return False
        return True

    def _project(self, image: Any, cands: tuple) -> None:
        topic = self.image_topic_of(image)
        if not self._ready(hold=(image, cands)):
            return
        size = (compressed_image_size(image) if isinstance(image, CompressedImage)
                else (int(image.width), int(image.height)))
        if size != (self._camera.width, self._camera.height):
            self.drop(topic, f'image {size[0]}x{size[1]} does not match CameraInfo '
                             f'{self._camera.width}x{self._camera.height}')
            return
        header, arr = cands
        img_ns, lidar_ns = _ns(image.header.stamp), _ns(header.stamp)
        pose_fn = self._lidar_pose if self._odom_sub is not None else None
        rois, compensated = candidates_to_rois(arr, lidar_ns, img_ns, self._camera,
                                               self._extrinsics, pose_fn, self._roi_params)
        rois = size_rois(rois, arr, self._camera)     # each measured sign's own size
        if pose_fn is not None and len(arr) and not compensated:
            self._counts['not compensated (no odometry at those times)'] += 1
            self.warn_throttled('odom', f'no odometry around {img_ns * 1e-9:.3f} s: ROIs are '
                                        f'not motion compensated (flagged in the payload)')
        payload = interfaces.Rois(header=header_to_payload(image.header), rois=rois,
                                  lidar_stamp=stamp_to_time(header.stamp),
                                  motion_compensated=bool(compensated and len(arr)))
        self._rois_pub.publish(payload_to_string(payload))
        self._counts['rois published'] += 1
        if self._crops_pub is not None and rois:
            frame = (compressed_to_numpy(image) if isinstance(image, CompressedImage)
                     else image_to_numpy(image, 'bgr8'))
            for r in rois:
                b = r.box
                x0, y0 = int(b.x), int(b.y)
                crop = frame[y0:int(np.ceil(b.y + b.h)), x0:int(np.ceil(b.x + b.w))]
                if crop.size:
                    self._crops_pub.publish(numpy_to_image(
                        np.ascontiguousarray(crop), 'bgr8', image.header,
                        frame_id=f'{image.header.frame_id}/roi_{r.candidate_id}'))

    def diagnostic_status(self) -> DiagnosticStatus:
        """Base status plus calibration state and projection counters."""
        status = super().diagnostic_status()
        problems = []
        if self._camera is None:
            problems.append(f'no CameraInfo on {self.params.camera_info_topic} yet')
        if self._extrinsics is None:
            problems.append(self._extrinsics_error)
        if problems:
            level = ord(status.level) if isinstance(status.level, bytes) else int(status.level)
            if level < ord(DiagnosticStatus.WARN):
                status.level = DiagnosticStatus.WARN
            status.message = '; '.join(problems + ([status.message]
                                                   if status.message != 'ok' else []))
        status.values = list(status.values) + [
            KeyValue(key=k, value=str(v)) for k, v in sorted(self._counts.items())]
        return status


NODE_CLASS = ProjectorNode


def main(args: Optional[list[str]] = None) -> int:
    """Console entry point ``projector``."""
    return run_node(ProjectorNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
