"""The nodes ``workzone-ros evaluate faults`` fuzzes (:func:`targets`): per node its inputs
(topic parameter, message type, a good message for any stamp; :class:`Input`), its output and
the check that the output is right (:class:`Target`).  The good inputs show one work-zone sign
seen by the camera and the LiDAR.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable

import numpy as np

__all__ = ['Input', 'Target', 'targets']


# --- the good inputs ---------------------------------------------------------------------

@lru_cache(maxsize=None)
def _scene() -> dict:
    """The good inputs every target is fed: one work-zone sign seen by camera and LiDAR."""
    from workzone_ros.core.lidar_clustering import SIZED_CANDIDATE_DTYPE
    from workzone_ros.core.pointcloud import make_points
    from workzone_ros.nodes.conversions import CameraInfoData
    from workzone_ros.sim.signart import over, sign_face
    from workzone_ros.sim.world import DEFAULT_CAMERA

    rng = np.random.default_rng(0)
    frame = np.clip(rng.normal(110, 12, (240, 320, 3)), 0, 255).astype(np.float32)
    frame[60:120, 200:260] = over(sign_face('road_work_ahead', 60), frame[60:120, 200:260])
    sign = (25.0, -7.0, 0.8)                      # lidar frame
    yy, zz = np.meshgrid(np.linspace(sign[1] - 0.6, sign[1] + 0.6, 16),
                         np.linspace(sign[2] - 0.6, sign[2] + 0.6, 6))
    gx, gy = rng.uniform(3, 60, 3000), rng.uniform(-15, 15, 3000)
    cloud = make_points(
        x=np.concatenate([np.full(yy.size, sign[0]), gx]).astype(np.float32),
        y=np.concatenate([yy.ravel(), gy]).astype(np.float32),
        z=np.concatenate([zz.ravel(), np.full(gx.size, -1.95)]).astype(np.float32),
        intensity=np.concatenate([np.full(yy.size, 220.0), np.full(gx.size, 6.0)])
        .astype(np.float32))
    cands = np.zeros(1, SIZED_CANDIDATE_DTYPE)
    cands['x'], cands['y'], cands['z'] = sign
    cands['radius'], cands['intensity'], cands['count'], cands['id'] = 0.6, 220.0, 96, 1
    cands['half_w'], cands['half_h'] = 0.6, 0.6
    cam = DEFAULT_CAMERA
    info = CameraInfoData(320, 240, [cam.fx / 2, 0, 160, 0, cam.fy / 2, 120, 0, 0, 1],
                          cam.dist)
    return dict(frame=np.clip(frame, 0, 255).astype(np.uint8), cloud=cloud, cands=cands,
                info=info, box=(200.0, 60.0, 60.0, 60.0))


def _header(stamp: Any, frame_id: str = 'camera') -> Any:
    from workzone_ros import interfaces as I
    from workzone_ros.nodes.conversions import stamp_to_time
    return I.Header(stamp=stamp_to_time(stamp), frame_id=frame_id)


def _box() -> Any:
    from workzone_ros.interfaces import Box
    x, y, w, h = _scene()['box']
    return Box(x=x, y=y, w=w, h=h)


def _string(payload: Any) -> Any:
    from workzone_ros.nodes.conversions import payload_to_string
    return payload_to_string(payload)


def _good_points(stamp):
    from workzone_ros.nodes.conversions import array_to_pointcloud2
    return array_to_pointcloud2(_scene()['cloud'], stamp=stamp, frame_id='lidar')


def _good_candidates(stamp):
    from workzone_ros.nodes.conversions import array_to_pointcloud2
    return array_to_pointcloud2(_scene()['cands'], stamp=stamp, frame_id='lidar')


def _good_odom(stamp):
    from nav_msgs.msg import Odometry

    from workzone_ros.nodes.conversions import make_header
    msg = Odometry(header=make_header(stamp=stamp, frame_id='odom'), child_frame_id='base_link')
    msg.pose.pose.orientation.w = 1.0
    return msg


def _good_image(stamp):
    from workzone_ros.nodes.conversions import numpy_to_image
    return numpy_to_image(_scene()['frame'], 'bgr8', stamp=stamp, frame_id='camera')


def _good_compressed(stamp):
    from workzone_ros.nodes.conversions import numpy_to_compressed
    return numpy_to_compressed(_scene()['frame'], 'jpeg', stamp=stamp, frame_id='camera')


def _good_info(stamp):
    from workzone_ros.nodes.conversions import numpy_to_camera_info
    return numpy_to_camera_info(_scene()['info'], stamp=stamp, frame_id='camera')


def _good_rois(stamp):
    from workzone_ros import interfaces as I
    roi = I.Roi(candidate_id=1, box=_box(), center=(230.0, 90.0), range_m=26.0, radius_m=0.6,
                position=(7.0, -0.8, 25.0), intensity=220.0, points=96)
    return _string(I.Rois(header=_header(stamp), rois=[roi], lidar_stamp=_header(stamp).stamp))


def _good_detections(stamp):
    from workzone_ros import interfaces as I
    det = I.Detection(box=_box(), confidence=0.9, color='orange', kind='warning')
    return _string(I.Detections(header=_header(stamp), detections=[det], channelizers=0))


def _good_tracks(stamp):
    from workzone_ros import interfaces as I
    track = I.Track(track_id=1, box=_box(), source='detection', age=5, hits=5,
                    similarity=0.95, confidence=0.9, kind='warning')
    return _string(I.Tracks(header=_header(stamp), tracks=[track]))


def _good_signs(stamp):
    from workzone_ros import interfaces as I
    sign = I.Sign(box=_box(), class_key='road_work_ahead', code='W20-1', category='workzone',
                  score=0.95, track_id=3, probabilities={'road_work_ahead': 0.95},
                  distance_m=80.0, distance_source='size')
    return _string(I.Signs(header=_header(stamp), signs=[sign]))


def _good_state(stamp):
    from workzone_ros import interfaces as I
    return _string(I.WorkzoneState(header=_header(stamp), active=False, likelihood=0.8,
                                   phase='approaching'))


# --- the targets --------------------------------------------------------------------------

@dataclass(frozen=True)
class Input:
    """One subscription of a target: the parameter naming its topic, type and good input."""

    param: str
    kind: str                       # 'points', 'image', 'compressed', 'info', 'odom', 'json'
    good: Callable[[Any], Any]
    latched: bool = False           # the node subscribes transient local

    @property
    def msg_type(self) -> type:
        """The message class."""
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
        from std_msgs.msg import String
        return {'points': PointCloud2, 'image': Image, 'compressed': CompressedImage,
                'info': CameraInfo, 'odom': Odometry, 'json': String}[self.kind]


def _iou(a: Any, b: tuple) -> float:
    from workzone_ros.interfaces import Box
    return a.iou(Box(x=b[0], y=b[1], w=b[2], h=b[3]))


def _check_candidates(out, ref) -> bool:
    if not len(out):
        return False
    got = np.stack([out['x'], out['y'], out['z']], 1)
    want = np.array([ref['x'][0], ref['y'][0], ref['z'][0]]) if ref is not None \
        else np.array([25.0, -7.0, 0.8])
    return bool(np.min(np.linalg.norm(got - want, axis=1)) < 0.3)


def _check_rois(out, ref) -> bool:
    if not out.rois:
        return False
    if ref is None:
        return True
    c, r = np.array(out.rois[0].center), np.array(ref.rois[0].center)
    return len(out.rois) == len(ref.rois) and bool(np.linalg.norm(c - r) < 2.0)


def _check_boxes(items: Callable) -> Callable:
    def check(out, ref) -> bool:
        return any(_iou(x.box, _scene()['box']) > 0.5 for x in items(out))
    return check


def _check_signs(out, ref) -> bool:
    hits = [s for s in out.signs if _iou(s.box, _scene()['box']) > 0.5]
    return bool(hits) and (ref is None or hits[0].class_key == ref.signs[0].class_key)


@dataclass(frozen=True)
class Target:
    """A node under test: its parameters, its inputs (publish order), its output."""

    name: str
    node: str
    inputs: tuple[Input, ...]
    output: tuple[str, str, Callable]      # (param, payload class name or 'points', check)
    params: tuple = ()
    fuzz: tuple = ()                       # the input kinds fuzzed (empty: all)

    def topic(self, param: str) -> str:
        """The absolute topic of a topic parameter (each target in its own namespace)."""
        return f'/faults/{self.name}/{param.replace("_topic", "")}'


_IMAGE = Input('image_topic', 'image', _good_image)
_COMPRESSED = Input('image_topic', 'compressed', _good_compressed)
_INFO = Input('camera_info_topic', 'info', _good_info)


def _targets() -> dict[str, Target]:
    odom = Input('odom_topic', 'odom', _good_odom)
    out = {
        'lidar_cluster': Target('lidar_cluster', 'lidar_cluster', (
            odom, Input('points_topic', 'points', _good_points)),
            ('candidates_topic', 'points', _check_candidates),
            (('persistence_k', 1), ('persistence_n', 1))),
        'projector': Target('projector', 'projector', (
            _INFO, odom, Input('candidates_topic', 'points', _good_candidates), _IMAGE),
            ('rois_topic', 'Rois', _check_rois), (
                ('lidar_to_camera', [float(v) for v in _lidar_to_camera()]),)),
        'color_detector': Target('color_detector', 'color_detector', (
            _INFO, Input('rois_topic', 'json', _good_rois), _IMAGE),
            ('detections_topic', 'Detections', _check_boxes(lambda o: o.detections))),
        'tracker': Target('tracker', 'tracker', (
            _IMAGE, Input('detections_topic', 'json', _good_detections)),
            ('tracks_topic', 'Tracks', _check_boxes(lambda o: o.tracks))),
        'classifier': Target('classifier', 'classifier', (
            _INFO, Input('state_topic', 'json', _good_state, latched=True),
            Input('rois_topic', 'json', _good_rois), _IMAGE,
            Input('input_topic', 'json', _good_tracks)),
            ('signs_topic', 'Signs', _check_signs), (('min_size', 10),)),
        'fusion': Target('fusion', 'fusion', (
            odom, _INFO, Input('lidar_topic', 'points', _good_candidates),
            Input('detections_topic', 'json', _good_detections),
            Input('signs_topic', 'json', _good_signs)),
            ('state_topic', 'WorkzoneState', lambda o, r: o.phase == 'approaching')),
    }
    for name in ('projector', 'color_detector', 'tracker', 'classifier'):
        t = out[name]
        out[f'{name}/compressed'] = dataclasses.replace(
            t, name=f'{name}_compressed', params=t.params + (('compressed', True),),
            fuzz=('compressed',),           # its other inputs are the raw target's
            inputs=tuple(_COMPRESSED if i is _IMAGE else i for i in t.inputs))
    return out


def _lidar_to_camera() -> np.ndarray:
    from workzone_ros.sim.world import LIDAR_TO_CAMERA
    return LIDAR_TO_CAMERA.ravel()


@lru_cache(maxsize=None)
def targets() -> dict[str, Target]:
    """Name -> :class:`Target` (``<node>/compressed``: the node reading CompressedImage)."""
    return _targets()
