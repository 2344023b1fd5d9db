"""The synthetic world shared by the camera renderer and the LiDAR ray caster.

Frames (all right-handed, metres, radians):
- world: x east-ish along the start of the route, y left, z up; the ground is the plane z = 0.
- route (Frenet): arc length ``s`` along the road centre line (the centre of the middle lane)
  and lateral offset ``d`` (left positive).  Lane centres at d = +3.7 (left), 0 (middle),
  -3.7 (right); the paved lanes span |d| <= 5.55; a 3 m right shoulder and a 1.5 m left
  shoulder; grass beyond; a tree line far out.
- base_link: on the ground under the rear axle, x forward, y left, z up.
- lidar: base_link axes, mounted at LIDAR_IN_BASE.
- camera: optical frame (x right, y down, z forward), mounted at CAMERA_IN_BASE.
  LIDAR_TO_CAMERA equals the ``projector.lidar_to_camera`` default in config/workzone.yaml.

Objects are plain dataclasses with their geometry in the world frame; the scenario builder
(sim/scenario.py) makes them, the renderer and the ray caster only read them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    'LANE_WIDTH', 'LANE_CENTERS', 'ROAD_HALF_WIDTH', 'RIGHT_SHOULDER', 'LEFT_SHOULDER',
    'SIGN_LATERAL', 'SIGN_BOTTOM_HEIGHT', 'LIDAR_IN_BASE', 'CAMERA_IN_BASE', 'LIDAR_TO_CAMERA',
    'BASE_TO_CAMERA_ROT', 'CameraModel', 'DEFAULT_CAMERA', 'Material', 'MATERIALS', 'Road',
    'SignPanel', 'Cylinder', 'Cone', 'Box', 'Quad', 'Pose', 'Scene', 'rot_zyx',
]

LANE_WIDTH = 3.7
LANE_CENTERS = {'left': 3.7, 'middle': 0.0, 'right': -3.7}
ROAD_HALF_WIDTH = 1.5 * LANE_WIDTH           # 5.55 m: outer edge lines
RIGHT_SHOULDER = 3.0
LEFT_SHOULDER = 1.5
SIGN_LATERAL = -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 1.2)   # right-shoulder sign posts
SIGN_BOTTOM_HEIGHT = 2.1                     # bottom of the sign face above the road (MUTCD)

LIDAR_IN_BASE = np.array([1.0, 0.0, 1.95])
CAMERA_IN_BASE = np.array([1.6, 0.0, 1.45])
#: base_link axes -> camera optical axes (x right = -y, y down = -z, z forward = x).
BASE_TO_CAMERA_ROT = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
#: LiDAR -> camera 4x4 (X_cam = T @ X_lidar); the lidar has base_link axes.
LIDAR_TO_CAMERA = np.eye(4)
LIDAR_TO_CAMERA[:3, :3] = BASE_TO_CAMERA_ROT
LIDAR_TO_CAMERA[:3, 3] = BASE_TO_CAMERA_ROT @ (LIDAR_IN_BASE - CAMERA_IN_BASE)


@dataclass(frozen=True)
class CameraModel:
    """Pinhole camera with plumb_bob distortion (k1, k2, p1, p2, k3), as in CameraInfo."""

    width: int = 640
    height: int = 480
    fx: float = 554.26           # 60 deg horizontal field of view
    fy: float = 554.26
    cx: float = 320.0
    cy: float = 240.0
    dist: tuple[float, float, float, float, float] = (-0.08, 0.02, 0.0005, -0.0003, 0.0)

    @property
    def K(self) -> np.ndarray:  # noqa: N802 - the usual name
        """3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def D(self) -> np.ndarray:  # noqa: N802
        """Distortion coefficients (plumb_bob order)."""
        return np.array(self.dist, dtype=float)


DEFAULT_CAMERA = CameraModel()


@dataclass(frozen=True)
class Material:
    """Surface appearance: base colour (BGR, 0-255) and LiDAR reflectivity (0-1).

    Retroreflective materials return high intensity at any incidence angle; others fall
    off with the cosine of the incidence angle.
    """

    name: str
    bgr: tuple[int, int, int]
    reflectivity: float
    retroreflective: bool = False


MATERIALS: dict[str, Material] = {m.name: m for m in (
    Material('asphalt', (72, 72, 74), 0.07),
    Material('lane_paint', (215, 218, 220), 0.35),
    Material('lane_paint_yellow', (60, 190, 215), 0.35),
    Material('shoulder', (96, 98, 100), 0.09),
    Material('grass', (55, 115, 70), 0.12),
    Material('snow', (235, 235, 240), 0.30),
    Material('tree', (40, 78, 45), 0.15),
    Material('dry_grass', (92, 148, 176), 0.15),       # tan: hue near the sign's orange
    Material('brick', (62, 78, 150), 0.20),
    Material('siding_beige', (150, 178, 200), 0.30),
    Material('siding_tan', (105, 140, 175), 0.25),
    Material('guardrail', (175, 178, 180), 0.30),
    Material('concrete', (160, 162, 165), 0.20),
    Material('sign_sheeting', (200, 200, 200), 0.95, True),   # colour comes from sign art
    Material('sign_back', (150, 152, 155), 0.20),
    Material('post', (120, 122, 125), 0.20),
    Material('drum_orange', (20, 100, 245), 0.25),
    Material('drum_band', (235, 235, 235), 0.90, True),
    Material('cone_orange', (10, 90, 250), 0.25),
    Material('vehicle_paint', (110, 110, 110), 0.15),
    Material('vehicle_orange', (10, 120, 240), 0.15),
    Material('vehicle_yellow', (30, 200, 235), 0.15),
    Material('glass', (60, 50, 45), 0.05),
    Material('plate', (230, 230, 230), 0.85, True),
    Material('tail_reflector', (30, 30, 200), 0.80, True),
)}


def rot_zyx(yaw: float, pitch: float = 0.0, roll: float = 0.0) -> np.ndarray:
    """Rotation matrix R = Rz(yaw) @ Ry(pitch) @ Rx(roll) (body -> world)."""
    cy, sy, cp, sp, cr, sr = (np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch),
                              np.cos(roll), np.sin(roll))
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr]])


class Road:
    """Road centre line from a curvature profile, sampled every ``step`` metres.

    Args:
        segments: ``[(length_m, curvature_1_per_m), ...]``; curvature 0 is straight,
            positive curves left.  Gentle highway curves are |curvature| <= 1/1000.
        step: sampling step in metres.
    """

    def __init__(self, segments: list[tuple[float, float]], step: float = 0.5):
        lengths = np.array([max(float(L), 0.0) for L, _ in segments])
        total = float(lengths.sum())
        self.step = step
        self.s = np.arange(0.0, total + step, step)
        kappa = np.zeros_like(self.s)
        edges = np.concatenate([[0.0], np.cumsum(lengths)])
        for i, (_, k) in enumerate(segments):
            kappa[(self.s >= edges[i]) & (self.s < edges[i + 1])] = k
        self.heading = np.concatenate([[0.0], np.cumsum(kappa[:-1] * step)])
        self.x = np.concatenate([[0.0], np.cumsum(np.cos(self.heading[:-1]) * step)])
        self.y = np.concatenate([[0.0], np.cumsum(np.sin(self.heading[:-1]) * step)])
        self.length = float(self.s[-1])
        self._tree = None

    def pose_at(self, s, d=0.0):
        """World (x, y, heading) of the point at arc length ``s`` and lateral offset ``d``.

        Vectorised over ``s`` and ``d``.
        """
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        h = np.interp(s, self.s, self.heading)
        x = np.interp(s, self.s, self.x) - np.sin(h) * d
        y = np.interp(s, self.s, self.y) + np.cos(h) * d
        return x, y, h

    def to_frenet(self, x, y):
        """Arc length and lateral offset of world points (vectorised, nearest sample)."""
        from scipy.spatial import cKDTree
        if self._tree is None:
            self._tree = cKDTree(np.column_stack([self.x, self.y]))
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        _, i = self._tree.query(np.column_stack([x.ravel(), y.ravel()]))
        h = self.heading[i]
        dx, dy = x.ravel() - self.x[i], y.ravel() - self.y[i]
        along = np.cos(h) * dx + np.sin(h) * dy
        d = -np.sin(h) * dx + np.cos(h) * dy
        return (self.s[i] + along).reshape(x.shape), d.reshape(x.shape)


@dataclass
class Pose:
    """A body pose in the world: position and roll / pitch / yaw (R = Rz Ry Rx)."""

    position: np.ndarray
    yaw: float
    pitch: float = 0.0
    roll: float = 0.0

    @property
    def R(self) -> np.ndarray:  # noqa: N802
        """Body -> world rotation."""
        return rot_zyx(self.yaw, self.pitch, self.roll)

    def to_world(self, p_body: np.ndarray) -> np.ndarray:
        """Transform (N, 3) or (3,) body points to the world."""
        return np.asarray(p_body) @ self.R.T + self.position

    def to_body(self, p_world: np.ndarray) -> np.ndarray:
        """Transform (N, 3) or (3,) world points to the body frame."""
        return (np.asarray(p_world) - self.position) @ self.R


@dataclass
class SignPanel:
    """A flat sign face on a post.

    ``center`` is the face centre in the world; the face normal points along ``yaw`` (towards
    the traffic it faces: oncoming ego traffic means yaw = road heading + pi).  ``tilt``
    rotates the face in its plane (slightly rotated signs); ``fade`` in [0, 1] washes out the
    art.  ``width``/``height`` is the bounding rectangle of the face (a diamond's is its
    point-to-point size: side * sqrt(2)).  Corners are TL, TR, BR, BL seen from the front.
    """

    object_id: int
    class_key: str
    center: np.ndarray
    yaw: float
    width: float
    height: float
    tilt: float = 0.0
    fade: float = 0.0
    speed_value: int | None = None       # for speed-limit signs: the number on the face
    material: str = 'sign_sheeting'

    @property
    def normal(self) -> np.ndarray:
        """Unit normal of the front face."""
        return np.array([np.cos(self.yaw), np.sin(self.yaw), 0.0])

    def corners(self) -> np.ndarray:
        """(4, 3) world corners TL, TR, BR, BL of the bounding rectangle, seen from the front."""
        right = np.array([-np.sin(self.yaw), np.cos(self.yaw), 0.0])   # viewer's right
        up = np.array([0.0, 0.0, 1.0])
        c, s_ = np.cos(self.tilt), np.sin(self.tilt)
        r2, u2 = c * right + s_ * up, -s_ * right + c * up
        hw, hh = self.width / 2, self.height / 2
        return np.array([self.center - hw * r2 + hh * u2, self.center + hw * r2 + hh * u2,
                         self.center + hw * r2 - hh * u2, self.center - hw * r2 - hh * u2])


@dataclass
class Cylinder:
    """A vertical cylinder: posts, drums (with horizontal bands), tree trunks.

    ``bands`` is ``[(z0, z1, material), ...]`` relative to the base; the body material
    covers the rest.
    """

    object_id: int
    kind: str
    base: np.ndarray
    radius: float
    height: float
    material: str
    bands: list[tuple[float, float, str]] = field(default_factory=list)


@dataclass
class Cone:
    """A traffic cone standing on the ground (vertical axis)."""

    object_id: int
    kind: str
    base: np.ndarray
    radius: float
    height: float
    material: str = 'cone_orange'
    bands: list[tuple[float, float, str]] = field(default_factory=list)


@dataclass
class Box:
    """An oriented box (vehicles, trucks, barriers) moving along its yaw at ``speed``.

    ``center`` is the centre of the bottom face at t = 0.  A vehicle seen from behind has its
    rear face at ``center - length/2 * forward``; ``plate`` puts a retroreflective plate
    there, ``rear_material`` colours the rear face (e.g. an orange truck).
    """

    object_id: int
    kind: str
    center: np.ndarray
    length: float
    width: float
    height: float
    yaw: float
    material: str
    speed: float = 0.0
    plate: bool = True
    rear_material: str | None = None

    def at(self, t: float) -> 'Box':
        """The box at time ``t`` (s) after the start."""
        fwd = np.array([np.cos(self.yaw), np.sin(self.yaw), 0.0])
        return Box(self.object_id, self.kind, self.center + fwd * self.speed * t, self.length,
                   self.width, self.height, self.yaw, self.material, self.speed, self.plate,
                   self.rear_material)


@dataclass
class Quad:
    """A planar quadrilateral (guardrail segment, tree-line billboard, overpass face)."""

    object_id: int
    kind: str
    corners: np.ndarray      # (4, 3) world
    material: str


@dataclass
class Scene:
    """Everything static about one scenario run, built by sim/scenario.py.

    ``objects`` holds every non-sign object (posts, drums, cones, vehicles, guardrails, tree
    line...); ``signs`` the sign faces (their posts are Cylinders in ``objects``).  Vehicles
    move with :meth:`Box.at`.  ``weather`` is a preset name understood by the renderer:
    ``winter_overcast``, ``spring_sunny``, ``spring_rain`` or ``dusk``.
    """

    name: str
    seed: int
    road: Road
    signs: list[SignPanel] = field(default_factory=list)
    objects: list = field(default_factory=list)
    weather: str = 'spring_sunny'
    ground_cover: str = 'grass'            # 'grass', 'dry_grass' or 'snow' beyond the shoulders
    overpasses: list[float] = field(default_factory=list)   # arc lengths of overpass shadows

    def objects_at(self, t: float) -> list:
        """Objects with moving vehicles advanced to time ``t``."""
        return [o.at(t) if isinstance(o, Box) and o.speed else o for o in self.objects]
