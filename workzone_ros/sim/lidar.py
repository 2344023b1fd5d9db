"""LiDAR ray caster: a spinning multi-beam sensor (HDL-64E-like by default) against the world.

Sensor presets (:data:`LIDAR_PRESETS`, chosen per scenario with ``lidar: {model: ...}``;
:func:`lidar_preset`).  Datasheet values at 10 Hz (single return); the beams are spread
uniformly over the vertical field of view, as the HDL-32E and VLP-16 really are (the real
HDL-64E's two laser blocks are slightly non-uniform; the simulator keeps them uniform):

========= ====== ================= ======== ============= ========= ================== ========
preset    beams  vertical (deg)    spacing  azimuth (deg) max range rays / scan        points
========= ====== ================= ======== ============= ========= ================== ========
``hdl64`` 64     +2.0 .. -24.8     0.43 deg 0.17          120 m     2118 x 64 = 135.6k ~129k
``hdl32`` 32     +10.67 .. -30.67  1.33 deg 0.16          100 m     2250 x 32 = 72.0k  ~64k
``vlp16`` 16     +15.0 .. -15.0    2.0 deg  0.2           100 m     1800 x 16 = 28.8k  ~21k
========= ====== ================= ======== ============= ========= ================== ========

(points: mean per scan on the ``demo`` road, 18 bytes each: 2.3, 1.1 and 0.38 MB a scan.)

Velodyne HDL-64E (S2): 26.9 deg vertical FOV (+2 .. -24.9), 0.09 deg azimuth at 5 Hz, about
1.3M points/s, 120 m; the default :class:`LidarModel` (the simulator's sensor since the
start: every ``hdl64`` bag is unchanged).  HDL-32E: +10.67 .. -30.67 deg (41.33 deg, 1.33 deg
apart), 0.08-0.33 deg azimuth at 5-20 Hz (0.16 deg at 10 Hz), about 695k points/s, 80-100 m,
+/-2 cm.  VLP-16 (Puck): +/-15 deg (2 deg apart), 0.1-0.4 deg azimuth at 5-20 Hz (0.2 deg at
10 Hz), about 300k points/s, 100 m, +/-3 cm (``range_noise_m`` 0.03).  Beams pointing above
the horizon mostly return nothing on a highway (sky), so a scan holds fewer points than rays.
Every preset is mounted where the HDL-64E is (``LIDAR_IN_BASE``, 1.95 m above the road).

Conventions (the scenario builder, the bag writer and the ground truth rely on them):

- **Beams and rings.**  ``n_beams`` elevation angles spread uniformly over
  ``[fov_down_deg, fov_up_deg]``; ``ring`` 0 is the *lowest* beam (most negative elevation) and
  ``n_beams - 1`` the highest, as in the ROS velodyne driver's ``ring`` field.
- **Spin.**  ``n_columns = round(360 / azimuth_res_deg)`` columns per revolution.  The head
  turns clockwise seen from above (like a Velodyne): column ``c`` fires at azimuth
  ``pi - 2 pi c / n_columns`` in the lidar frame (atan2(y, x), x forward, y left) and at time
  ``t0 + c / n_columns / rate_hz``.  The scan therefore starts and ends behind the vehicle
  (the seam is where it matters least) and the forward column fires half a spin after ``t0``.
- **Motion (no deskew).**  The sensor pose is sampled from ``lidar_pose_at`` at a few knots
  across the spin and interpolated per column.  Each point is expressed in the lidar frame *at
  its own firing time*, like a raw driver that does not deskew: at 22 m/s a static object
  ahead appears about 1.1 m closer than it was at ``t0``.  Moving boxes move during the spin too.
- **Misses are omitted** (no NaN points): sky, returns beyond ``max_range`` or closer than
  ``min_range``, and random dropouts.  Points are ordered by firing time (column-major, rings
  ascending within a column).  The ego vehicle's own body is not modelled.
- **Object ids.**  ``object_ids`` is the ``object_id`` of the primitive hit; -1 for the ground
  and for background objects whose ``kind`` starts with ``tree`` (tree lines, trunks).  A sign's
  back face reports the sign's id, but ``sign_hits`` lists only points on the *front* face,
  inside its real shape (diamond, octagon, triangle, rectangle).
- **Ground.**  The plane z = 0, with its material from the road's Frenet coordinates:
  asphalt over |d| <= 5.55 m, 0.15 m lane lines centred at d = +/-1.85 (dashed: paint where
  ``s mod 12 < 3``, i.e. 3 m dash / 9 m gap) and solid edge lines centred at d = +/-5.55 (white
  right, yellow left), shoulders, then the scene's ground cover (grass or snow).
- **Intensity** (0-255, float32).  Retroreflective materials (sign sheeting, drum bands,
  plates, tail reflectors) return ``255 * reflectivity * (0.85 + 0.15 cos i)`` times a mild
  range loss ``1 - 0.25 (r / max_range)^2``: about 200-245 (hard negatives included); a faded
  sign loses up to 30 %.  Others return ``255 * reflectivity * (0.2 + 0.8 cos i)`` times
  ``1 / (1 + (r / 80)^2)`` (asphalt ~5, lane paint ~30, grass ~10, guardrail ~70, orange drum
  body ~60).  ``i`` is the incidence angle.  Gaussian noise: 5 % multiplicative plus 1.0.
- **Vehicles** (boxes with ``plate``) carry a 0.31 x 0.15 m plate, laterally centred on the
  rear face, 0.45-0.60 m high, and two 0.12 x 0.10 m tail reflectors 0.2 m in from the sides,
  0.85-0.95 m high; the rear face uses ``rear_material`` when set.
- **Randomness** (range noise, dropouts, intensity noise) comes from a generator seeded with
  ``(seed, scan_index)``: the same inputs give identical arrays.

The caster caches per-model ray tables and an object table per road, whose rows are reused
for the same object instances (identity): a scene rebuilt per scan with a few objects
replaced costs only those rows.  Do not mutate objects in place between calls; replace them.
Only ``Box.speed`` motion is modelled, as in :meth:`Scene.objects_at` (the writer replaces
lane-following vehicles by straight movers per scan).

Speed: objects are culled before intersection.  Each object's azimuth interval (columns) and
elevation interval (beams) as seen from the sensor over the whole spin are computed for all
objects at once, and only the rays in that window are tested, vectorised.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..core.pointcloud import make_points
from ..core.signs import BY_KEY
from .world import (
    LEFT_SHOULDER,
    MATERIALS,
    RIGHT_SHOULDER,
    ROAD_HALF_WIDTH,
    Box,
    Cone,
    Cylinder,
    Pose,
    Quad,
    Road,
    Scene,
    SignPanel,
)

__all__ = ['LidarError', 'LidarModel', 'LIDAR_PRESETS', 'DEFAULT_PRESET', 'Scan', 'cast_scan',
           'lidar_preset', 'sign_shape_contains']


class LidarError(ValueError):
    """An invalid LiDAR model or a scene object the caster cannot intersect."""


@dataclass(frozen=True)
class LidarModel:
    """A spinning multi-beam LiDAR (defaults: Velodyne HDL-64E at 10 Hz).

    Attributes:
        n_beams: number of lasers (rings), at most 65535.
        fov_up_deg: elevation of the highest beam.
        fov_down_deg: elevation of the lowest beam (ring 0).
        azimuth_res_deg: azimuth step between columns.
        rate_hz: revolutions per second.
        max_range: farthest return in metres.
        min_range: nearest return in metres.
        range_noise_m: standard deviation of the Gaussian range noise.
        dropout: probability that a return is randomly lost.
    """

    n_beams: int = 64
    fov_up_deg: float = 2.0
    fov_down_deg: float = -24.8        # HDL-64E: vertical angles spread over +2 .. -24.8
    azimuth_res_deg: float = 0.17      # ~2118 columns x 64 = ~135k rays
    rate_hz: float = 10.0
    max_range: float = 120.0
    min_range: float = 1.0
    range_noise_m: float = 0.02
    dropout: float = 0.02              # random point dropout probability

    def __post_init__(self) -> None:
        if not 1 <= self.n_beams <= 65535:
            raise LidarError(f'n_beams must be in 1..65535, got {self.n_beams}')
        if self.n_beams > 1 and not self.fov_down_deg < self.fov_up_deg:
            raise LidarError(f'fov_down_deg ({self.fov_down_deg}) must be below fov_up_deg '
                             f'({self.fov_up_deg})')
        if not 0.01 <= self.azimuth_res_deg <= 10.0:
            raise LidarError(f'azimuth_res_deg must be in 0.01..10, got {self.azimuth_res_deg}')
        if self.rate_hz <= 0 or not 0 <= self.min_range < self.max_range:
            raise LidarError('need rate_hz > 0 and 0 <= min_range < max_range')
        if self.range_noise_m < 0 or not 0 <= self.dropout < 1:
            raise LidarError('need range_noise_m >= 0 and 0 <= dropout < 1')

    @property
    def n_columns(self) -> int:
        """Columns (firings per beam) in one revolution."""
        return max(int(round(360.0 / self.azimuth_res_deg)), 1)

    def elevations(self) -> np.ndarray:
        """Beam elevations in radians, ascending: index = ring (ring 0 is the lowest)."""
        return np.radians(np.linspace(self.fov_down_deg, self.fov_up_deg, self.n_beams))

    def azimuths(self) -> np.ndarray:
        """Column azimuths in radians in the lidar frame (clockwise spin from the rear)."""
        return np.pi - 2.0 * np.pi * np.arange(self.n_columns) / self.n_columns


#: Sensor presets by name (see the module docstring for the datasheet values).
LIDAR_PRESETS: dict[str, LidarModel] = {
    'hdl64': LidarModel(),
    'hdl32': LidarModel(n_beams=32, fov_up_deg=10.67, fov_down_deg=-30.67, azimuth_res_deg=0.16,
                        max_range=100.0),
    'vlp16': LidarModel(n_beams=16, fov_up_deg=15.0, fov_down_deg=-15.0, azimuth_res_deg=0.2,
                        max_range=100.0, range_noise_m=0.03),
}
DEFAULT_PRESET = 'hdl64'


def lidar_preset(name: str = DEFAULT_PRESET, max_range: float | None = None) -> LidarModel:
    """The sensor of a preset, optionally with a shorter (or longer) ``max_range``.

    Args:
        name: a key of :data:`LIDAR_PRESETS` (``hdl64``, ``hdl32``, ``vlp16``).
        max_range: farthest return in metres (None: the preset's datasheet range).

    Raises:
        LidarError: unknown preset or a ``max_range`` not above the preset's ``min_range``.
    """
    try:
        model = LIDAR_PRESETS[name]
    except (KeyError, TypeError):
        raise LidarError(f'unknown lidar model {name!r}; known: '
                         f'{", ".join(LIDAR_PRESETS)}') from None
    if max_range is None or float(max_range) == model.max_range:
        return model
    return replace(model, max_range=float(max_range))


@dataclass
class Scan:
    """One revolution of the LiDAR.

    Attributes:
        points: structured array with fields x, y, z, intensity (float32) and ring (uint16),
            in the lidar frame at each point's firing time (no deskew); misses are omitted.
        object_ids: int32 per point, the ``object_id`` of the object hit, -1 for the ground
            and the tree line.
        sign_hits: sign ``object_id`` -> int64 indices into ``points`` of the returns on the
            sign's front face.  Signs without returns are absent.
    """

    points: np.ndarray
    object_ids: np.ndarray
    sign_hits: dict[int, np.ndarray]


# --------------------------------------------------------------------------------------------
# Materials and sign shapes

_MAT_NAMES = list(MATERIALS)
_MAT = {name: i for i, name in enumerate(_MAT_NAMES)}
_REFL = np.array([MATERIALS[n].reflectivity for n in _MAT_NAMES])
_REFL32 = _REFL.astype(np.float32)
_RETRO = np.array([MATERIALS[n].retroreflective for n in _MAT_NAMES])

_PAINT_HALF_WIDTH = 0.075        # 6 in (0.15 m) lines
_DASH_LINE_D = 1.5 * 3.7 - 3.7   # 1.85 m: lane boundaries between the three lanes
_DASH_PERIOD, _DASH_LENGTH = 12.0, 3.0     # the dash is a quarter of the period

_SHAPES = {'diamond', 'rectangle', 'square', 'octagon', 'triangle', 'circle'}


def _mat_index(name: str) -> int:
    try:
        return _MAT[name]
    except KeyError:
        raise LidarError(f'unknown material {name!r}; known: {", ".join(_MAT_NAMES)}') from None


def _sign_shape(sign: SignPanel) -> str:
    entry = BY_KEY.get(sign.class_key)
    shape = entry.shape if entry is not None else 'rectangle'
    return shape if shape in _SHAPES else 'rectangle'


def sign_shape_contains(shape: str, u: np.ndarray, v: np.ndarray, half_w: float,
                        half_h: float) -> np.ndarray:
    """Whether face coordinates lie inside a sign's real shape.

    The shape is inscribed in the sign's bounding rectangle: a diamond is the rhombus through
    the edge midpoints, an octagon the regular octagon whose sides touch the rectangle, a
    triangle (yield) points down, a circle is the inscribed ellipse.

    Args:
        shape: ``diamond``, ``rectangle``, ``square``, ``octagon``, ``triangle`` or ``circle``.
        u: coordinates towards the viewer's right, from the face centre (m).
        v: coordinates upwards in the face plane, from the face centre (m).
        half_w: half the bounding rectangle's width.
        half_h: half the bounding rectangle's height.

    Returns:
        Boolean array shaped like ``u``.
    """
    a, b = np.abs(u) / half_w, np.abs(v) / half_h
    if shape == 'diamond':
        return a + b <= 1.0
    if shape == 'octagon':
        return (a <= 1.0) & (b <= 1.0) & (a + b <= np.sqrt(2.0))
    if shape == 'triangle':
        return (v <= half_h) & (a <= (v / half_h + 1.0) / 2.0)
    if shape == 'circle':
        return a * a + b * b <= 1.0
    return (a <= 1.0) & (b <= 1.0)


# --------------------------------------------------------------------------------------------
# Ray table (per model) and object table (per scene)

@dataclass(frozen=True)
class _Rays:
    n_cols: int
    n_beams: int
    elev: np.ndarray       # (nb,) ascending
    local: np.ndarray      # (nc * nb, 3) unit directions in the lidar frame, column-major
    col_frac: np.ndarray   # (nc,) firing time as a fraction of the spin
    ring: np.ndarray       # (nc * nb,) uint16
    lx: np.ndarray         # (nc * nb,) float32 components of ``local``
    ly: np.ndarray
    lz: np.ndarray


@functools.lru_cache(maxsize=8)
def _ray_table(model: LidarModel) -> _Rays:
    elev, az = model.elevations(), model.azimuths()
    nc, nb = az.size, elev.size
    ce, se = np.cos(elev), np.sin(elev)
    local = np.empty((nc, nb, 3))
    local[..., 0] = np.cos(az)[:, None] * ce[None, :]
    local[..., 1] = np.sin(az)[:, None] * ce[None, :]
    local[..., 2] = se[None, :]
    local = local.reshape(-1, 3)
    ring = np.tile(np.arange(nb, dtype=np.uint16), nc)
    lx, ly, lz = (np.ascontiguousarray(local[:, i], dtype=np.float32) for i in range(3))
    for arr in (elev, local, ring, lx, ly, lz):
        arr.setflags(write=False)
    return _Rays(nc, nb, elev, local, np.arange(nc) / nc, ring, lx, ly, lz)


_SIGN, _CYL, _CONE, _BOX, _QUAD = range(5)
_FADE_LOSS = 0.3         # a fully faded sign (fade = 1) keeps 70 % of its retroreflection


@dataclass
class _Table:
    """Culling data for every object of a scene (signs first, then ``scene.objects``)."""

    objs: list
    kinds: np.ndarray      # (n,) type code
    ids: np.ndarray        # (n,) reported object id (-1 for background)
    hull: np.ndarray       # (n, 8, 3) bounding points at t = 0
    vel: np.ndarray        # (n, 3) velocity (boxes)
    foot: np.ndarray       # (n, 4, 2) convex footprint at t = 0
    zmin: np.ndarray
    zmax: np.ndarray
    centre: np.ndarray     # (n, 3) bounding-sphere centre at t = 0
    radius: np.ndarray
    extra: list            # per object: precomputed intersection data
    face_gain: np.ndarray  # (n,) intensity factor of sign faces (worn sheeting when faded)
    road: Road
    road_cos: np.ndarray
    road_sin: np.ndarray


def _square(cx: float, cy: float, r: float) -> np.ndarray:
    return np.array([[cx - r, cy - r], [cx + r, cy - r], [cx + r, cy + r], [cx - r, cy + r]])


def _fill_row(t: _Table, i: int, o) -> tuple:
    """Write object ``o``'s culling data into row ``i`` of ``t``; return its intersection data."""
    t.ids[i] = -1 if str(getattr(o, 'kind', '')).startswith('tree') else int(o.object_id)
    t.vel[i] = 0.0
    t.face_gain[i] = 1.0
    hull, foot = t.hull[i], t.foot[i]
    if isinstance(o, SignPanel):
        t.kinds[i] = _SIGN
        cr = o.corners()
        hull[:4], hull[4:] = cr, cr
        foot[:] = cr[:, :2]
        right = np.array([-np.sin(o.yaw), np.cos(o.yaw), 0.0])
        up = np.array([0.0, 0.0, 1.0])
        c, s_ = np.cos(o.tilt), np.sin(o.tilt)
        r2, u2 = c * right + s_ * up, -s_ * right + c * up     # as SignPanel.corners()
        t.face_gain[i] = 1.0 - _FADE_LOSS * float(o.fade)
        return (np.asarray(o.center, float), o.normal, r2, u2, _sign_shape(o),
                _mat_index(o.material), _mat_index('sign_back'), o.width / 2, o.height / 2)
    if isinstance(o, (Cylinder, Cone)):
        t.kinds[i] = _CYL if isinstance(o, Cylinder) else _CONE
        b = np.asarray(o.base, float)
        sq = _square(b[0], b[1], o.radius)
        hull[:4, :2], hull[4:, :2] = sq, sq
        hull[:4, 2], hull[4:, 2] = b[2], b[2] + o.height
        foot[:] = sq
        bands = [(float(z0), float(z1), _mat_index(m)) for z0, z1, m in o.bands]
        return (b, float(o.radius), float(o.height), _mat_index(o.material), bands)
    if isinstance(o, Box):
        t.kinds[i] = _BOX
        fwd = np.array([np.cos(o.yaw), np.sin(o.yaw), 0.0])
        left = np.array([-np.sin(o.yaw), np.cos(o.yaw), 0.0])
        c0 = np.asarray(o.center, float)
        k = 0
        for sz in (0.0, o.height):
            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                hull[k] = c0 + sx * o.length / 2 * fwd + sy * o.width / 2 * left
                hull[k, 2] = c0[2] + sz
                k += 1
        foot[:] = hull[:4, :2]
        t.vel[i] = fwd * o.speed
        rear = o.rear_material or o.material
        return (c0, fwd, left, np.array([o.length / 2, o.width / 2, o.height]),
                _mat_index(o.material), _mat_index(rear), bool(o.plate))
    if isinstance(o, Quad):
        t.kinds[i] = _QUAD
        cr = np.asarray(o.corners, float)
        hull[:4], hull[4:] = cr, cr
        foot[:] = cr[:, :2]
        nrm = np.cross(cr[2] - cr[0], cr[3] - cr[1])     # diagonals: robust for quads
        nrm = nrm / max(np.linalg.norm(nrm), 1e-12)
        e1 = cr[1] - cr[0] - np.dot(cr[1] - cr[0], nrm) * nrm
        e1 = e1 / max(np.linalg.norm(e1), 1e-12)
        e2 = np.cross(nrm, e1)
        poly = np.stack([(cr - cr[0]) @ e1, (cr - cr[0]) @ e2], axis=1)
        nxt = np.roll(poly, -1, axis=0)
        if np.sum(poly[:, 0] * nxt[:, 1] - nxt[:, 0] * poly[:, 1]) < 0:
            poly = poly[::-1].copy()
        edges = np.roll(poly, -1, axis=0) - poly
        return (cr[0], nrm, e1, e2, poly, edges, _mat_index(o.material))
    raise LidarError(f'cannot ray-cast object of type {type(o).__name__} '
                     f'(id {getattr(o, "object_id", "?")})')


def _build_table(scene: Scene, prev: _Table | None = None) -> _Table:
    """Build the object table, reusing the rows of ``prev`` whose object is the same one."""
    objs = list(scene.signs) + list(scene.objects)
    n = len(objs)
    road = scene.road
    if prev is not None and len(prev.objs) == n and prev.road is road:
        t = _Table(objs, prev.kinds.copy(), prev.ids.copy(), prev.hull.copy(), prev.vel.copy(),
                   prev.foot.copy(), prev.zmin, prev.zmax, prev.centre, prev.radius,
                   list(prev.extra), prev.face_gain.copy(), road, prev.road_cos, prev.road_sin)
        rows = [i for i, (a, b) in enumerate(zip(objs, prev.objs)) if a is not b]
    else:
        t = _Table(objs, np.zeros(n, np.int8), np.zeros(n, np.int32), np.zeros((n, 8, 3)),
                   np.zeros((n, 3)), np.zeros((n, 4, 2)), None, None, None, None, [None] * n,
                   np.ones(n, np.float32), road, np.cos(road.heading), np.sin(road.heading))
        rows = range(n)
    for i in rows:
        t.extra[i] = _fill_row(t, i, objs[i])
    t.zmin, t.zmax = t.hull[..., 2].min(axis=1), t.hull[..., 2].max(axis=1)
    t.centre = t.hull.mean(axis=1)
    t.radius = np.linalg.norm(t.hull - t.centre[:, None, :], axis=2).max(axis=1)
    return t


#: Last object table per road (a strong reference: object identities stay valid).
_TABLES: dict[int, _Table] = {}
_MAX_TABLES = 4


def _table_for(scene: Scene) -> _Table:
    """The scene's object table, cached per road.

    A scene rebuilt for each scan with a few objects replaced (the writer swaps lane-following
    vehicles for straight movers) only recomputes the replaced rows: rows are reused for the
    *same* objects (identity), so objects must not be mutated in place between calls.
    """
    objs = list(scene.signs) + list(scene.objects)
    prev = _TABLES.get(id(scene.road))
    if prev is not None and prev.road is not scene.road:
        prev = None
    if prev is not None and len(prev.objs) == len(objs) and all(
            a is b for a, b in zip(prev.objs, objs)):
        return prev
    table = _build_table(scene, prev)
    _TABLES.pop(id(scene.road), None)
    while len(_TABLES) >= _MAX_TABLES:
        _TABLES.pop(next(iter(_TABLES)))
    _TABLES[id(scene.road)] = table
    return table


# --------------------------------------------------------------------------------------------
# Intersections: each takes block rays (origins O (m, 3), unit directions D (m, 3), firing
# times T (m,)) and returns (t, material, cos_incidence, front) with t = inf for misses.

def _hit_sign(ex, O, D, T):
    centre, normal, r2, u2, shape, mat_front, mat_back, half_w, half_h = ex
    denom = D @ normal
    with np.errstate(divide='ignore', invalid='ignore'):
        t = ((centre - O) @ normal) / denom
    p = O + t[:, None] * D - centre
    inside = sign_shape_contains(shape, p @ r2, p @ u2, half_w, half_h)
    ok = inside & (t > 0) & (np.abs(denom) > 1e-9)
    t = np.where(ok, t, np.inf)
    front = denom < 0
    mat = np.where(front, mat_front, mat_back)
    return t, mat, np.abs(denom), front


def _band_materials(hz, side, body, bands):
    mat = np.full(hz.shape, body, dtype=np.int16)
    for z0, z1, m in bands:
        mat[side & (hz >= z0) & (hz < z1)] = m
    return mat


def _hit_cylinder(ex, O, D, T):
    base, r, h, body, bands = ex
    ox, oy = O[:, 0] - base[0], O[:, 1] - base[1]
    dx, dy, dz = D[:, 0], D[:, 1], D[:, 2]
    a = dx * dx + dy * dy
    b = ox * dx + oy * dy
    c = ox * ox + oy * oy - r * r
    disc = b * b - a * c
    with np.errstate(divide='ignore', invalid='ignore'):
        ts = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        zs = O[:, 2] + ts * dz - base[2]
        side_ok = (disc >= 0) & (a > 1e-12) & (ts > 0) & (zs >= 0) & (zs <= h)
        tc = (base[2] + h - O[:, 2]) / dz
    px, py = ox + tc * dx, oy + tc * dy
    cap_ok = (dz < -1e-9) & (tc > 0) & (px * px + py * py <= r * r)
    ts = np.where(side_ok, ts, np.inf)
    tc = np.where(cap_ok, tc, np.inf)
    side = ts <= tc
    t = np.minimum(ts, tc)
    hx, hy = ox + ts * dx, oy + ts * dy
    with np.errstate(invalid='ignore'):
        cos_side = np.abs(hx * dx + hy * dy) / r
    cosi = np.where(side, cos_side, np.abs(dz))
    mat = _band_materials(np.where(side, zs, h), side, body, bands)
    return t, mat, cosi, np.zeros(t.shape, bool)


def _hit_cone(ex, O, D, T):
    base, r, h, body, bands = ex
    k2 = (r / h) ** 2
    ox, oy = O[:, 0] - base[0], O[:, 1] - base[1]
    w0 = base[2] + h - O[:, 2]            # apex height above the origin
    dx, dy, dz = D[:, 0], D[:, 1], D[:, 2]
    # (ox + t dx)^2 + (oy + t dy)^2 = k2 (w0 - t dz)^2, with w = w0 - t dz in [0, h]
    a = dx * dx + dy * dy - k2 * dz * dz
    b = ox * dx + oy * dy + k2 * w0 * dz
    c = ox * ox + oy * oy - k2 * w0 * w0
    disc = b * b - a * c
    sq = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        a_safe = np.where(np.abs(a) > 1e-12, a, np.nan)
        t1, t2 = (-b - sq) / a_safe, (-b + sq) / a_safe
        t_lin = -c / (2 * b)                       # a ~ 0: the ray parallel to the slope
    t_lin = np.where(np.isnan(a_safe), t_lin, np.nan)
    best = np.full(a.shape, np.inf)
    for tt in (t1, t2, t_lin):
        w = w0 - tt * dz
        with np.errstate(invalid='ignore'):
            ok = (disc >= 0) & (tt > 0) & (w >= 0) & (w <= h)
        best = np.where(ok & (tt < best), tt, best)
    fin = np.isfinite(best)
    tb = np.where(fin, best, 0.0)
    hx, hy, hw = ox + tb * dx, oy + tb * dy, w0 - tb * dz
    n = np.stack([hx, hy, k2 * hw], axis=1)
    nn = np.linalg.norm(n, axis=1)
    with np.errstate(invalid='ignore', divide='ignore'):
        cosi = np.abs(np.einsum('ij,ij->i', n, D)) / nn
    cosi = np.nan_to_num(cosi, nan=1.0)
    mat = _band_materials(h - hw, fin, body, bands)
    return best, mat, cosi, np.zeros(best.shape, bool)


_PLATE = (0.155, 0.45, 0.60)            # half width, z range of a US plate (12 x 6 in)
_REFLECTOR = (0.06, 0.85, 0.95)         # half width, z range of the tail reflectors


def _hit_box(ex, O, D, T, vel):
    c0, fwd, left, half, body, rear, plate = ex
    rel = O - c0 - T[:, None] * vel
    lo = np.stack([rel @ fwd, rel @ left, rel[:, 2]], axis=1)
    ld = np.stack([D @ fwd, D @ left, D[:, 2]], axis=1)
    bmin = np.array([-half[0], -half[1], 0.0])
    bmax = np.array([half[0], half[1], half[2]])
    with np.errstate(divide='ignore', invalid='ignore'):
        inv = 1.0 / np.where(np.abs(ld) > 1e-12, ld, 1e-12)
    ta, tb = (bmin - lo) * inv, (bmax - lo) * inv
    tlo, thi = np.minimum(ta, tb), np.maximum(ta, tb)
    axis = np.argmax(tlo, axis=1)
    tnear = tlo[np.arange(lo.shape[0]), axis]
    tfar = thi.min(axis=1)
    ok = (tnear <= tfar) & (tnear > 0)
    t = np.where(ok, tnear, np.inf)
    comp = ld[np.arange(lo.shape[0]), axis]
    cosi = np.abs(comp)
    rear_face = (axis == 0) & (comp > 0)
    mat = np.where(rear_face, rear, body).astype(np.int16)
    if plate:
        p = lo + np.where(ok, tnear, 0.0)[:, None] * ld
        y, z = p[:, 1], p[:, 2]
        on_plate = rear_face & (np.abs(y) <= _PLATE[0]) & (z >= _PLATE[1]) & (z <= _PLATE[2])
        ry = half[1] - 0.2
        on_refl = rear_face & (np.abs(np.abs(y) - ry) <= _REFLECTOR[0]) & \
            (z >= _REFLECTOR[1]) & (z <= _REFLECTOR[2])
        mat[on_plate] = _MAT['plate']
        mat[on_refl] = _MAT['tail_reflector']
    return t, mat, cosi, np.zeros(t.shape, bool)


def _hit_quad(ex, O, D, T):
    c0, nrm, e1, e2, poly, edges, mat_i = ex
    denom = D @ nrm
    rel = O - c0
    with np.errstate(divide='ignore', invalid='ignore'):
        t = -(rel @ nrm) / denom
        pu = rel @ e1 + t * (D @ e1)
        pv = rel @ e2 + t * (D @ e2)
        inside = (t > 0) & (np.abs(denom) > 1e-9)
        for k in range(4):       # counter-clockwise polygon: inside is left of every edge
            inside &= edges[k, 0] * (pv - poly[k, 1]) - edges[k, 1] * (pu - poly[k, 0]) >= -1e-9
    t = np.where(inside, t, np.inf)
    return t, np.full(t.shape, mat_i, np.int16), np.abs(denom), np.zeros(t.shape, bool)


# --------------------------------------------------------------------------------------------
# Culling

_MARGIN_COLS = 2


def _rot_batch(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Vectorised world.rot_zyx: (n,) angles -> (n, 3, 3) body -> world rotations."""
    cy, sy, cp, sp, cr, sr = (np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch),
                              np.cos(roll), np.sin(roll))
    R = np.empty(yaw.shape + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def _windows(table: _Table, cand: np.ndarray, tk: np.ndarray, pos_k: np.ndarray,
             R_k: np.ndarray, tilt: float, rays: _Rays):
    """Column and beam windows of the candidate objects over the spin.

    Returns:
        (col_lo, col_hi, full, b_lo, b_hi, dmin) per candidate; columns ``col_lo..col_hi``
        (inclusive, modulo n_cols) unless ``full``; beams ``b_lo..b_hi - 1``; ``dmin`` a lower
        bound of the object's distance from the sensor during the spin.
    """
    nc = rays.n_cols
    hull = table.hull[cand][None] + table.vel[cand][None, :, None, :] * tk[:, None, None, None]
    rel = hull - pos_k[:, None, None, :]                          # (K, m, 8, 3)
    loc = np.einsum('kmpi,kij->kmpj', rel, R_k)
    az = np.arctan2(loc[..., 1], loc[..., 0])
    u = ((np.pi - az) / (2 * np.pi) * nc) % nc                    # column coordinate
    u = np.sort(u.transpose(1, 0, 2).reshape(cand.size, -1), axis=1)
    gaps = np.concatenate([np.diff(u, axis=1), (u[:, :1] + nc - u[:, -1:])], axis=1)
    j = np.argmax(gaps, axis=1)
    P = u.shape[1]
    rows = np.arange(cand.size)
    wrap = j == P - 1
    start = np.where(wrap, u[:, 0], u[rows, np.minimum(j + 1, P - 1)])
    end = np.where(wrap, u[:, -1], u[rows, j] + nc)
    full = (end - start) > nc / 2
    col_lo = np.floor(start).astype(int) - _MARGIN_COLS
    col_hi = np.ceil(end).astype(int) + _MARGIN_COLS
    # Elevation: nearest / farthest horizontal distance to the (moving) footprint.
    foot = table.foot[cand][None] + table.vel[cand][None, :, None, :2] * tk[:, None, None, None]
    q = pos_k[:, None, None, :2]                                  # (K, 1, 1, 2)
    a, b = foot, np.roll(foot, -1, axis=2)
    ab = b - a
    L2 = np.maximum((ab * ab).sum(-1), 1e-12)
    s = np.clip(((q - a) * ab).sum(-1) / L2, 0.0, 1.0)
    seg = np.linalg.norm(a + s[..., None] * ab - q, axis=-1)     # (K, m, 4)
    cross = ab[..., 0] * (q - a)[..., 1] - ab[..., 1] * (q - a)[..., 0]
    inside = (cross >= 0).all(-1) | (cross <= 0).all(-1)
    hmin = np.where(inside, 0.0, seg.min(-1))                     # (K, m)
    hmax = np.linalg.norm(foot - q, axis=-1).max(-1)
    zhi = table.zmax[cand][None] - pos_k[:, 2:3]
    zlo = table.zmin[cand][None] - pos_k[:, 2:3]
    el_hi = np.where(zhi > 0, np.arctan2(zhi, hmin), np.arctan2(zhi, hmax)).max(0)
    el_lo = np.where(zlo < 0, np.arctan2(zlo, hmin), np.arctan2(zlo, hmax)).min(0)
    spacing = (rays.elev[-1] - rays.elev[0]) / max(rays.n_beams - 1, 1)
    margin = tilt + 0.5 * spacing + 1e-3
    b_lo = np.searchsorted(rays.elev, el_lo - margin)
    b_hi = np.searchsorted(rays.elev, el_hi + margin, side='right')
    dz = np.maximum(np.maximum(zlo, -zhi), 0.0)
    dmin = np.sqrt(hmin * hmin + dz * dz).min(0)
    step = np.linalg.norm(np.diff(pos_k, axis=0), axis=1).max() if len(pos_k) > 1 else 0.0
    return col_lo, col_hi, full, b_lo, b_hi, dmin - step - 0.05


# --------------------------------------------------------------------------------------------
# Ground

def _frenet_local(road: Road, cos_h: np.ndarray, sin_h: np.ndarray, x: np.ndarray,
                  y: np.ndarray, s0: float) -> tuple[np.ndarray, np.ndarray]:
    """Frenet (s, d) of points within a few hundred metres of arc length ``s0``.

    Starts from the tangent at ``s0`` and refines once against the road sample nearest to the
    guess (for |curvature| <= 1/1000 the along-track error is a few centimetres at 30 m from
    the centre line, the lateral error well under a millimetre).
    """
    n = road.s.size
    i0 = int(np.clip(round(s0 / road.step), 0, n - 1))
    s = road.s[i0] + cos_h[i0] * (x - road.x[i0]) + sin_h[i0] * (y - road.y[i0])
    i = np.clip(np.rint(s / road.step).astype(np.int64), 0, n - 1)
    dx, dy = x - road.x.take(i), y - road.y.take(i)
    ch, sh = cos_h.take(i), sin_h.take(i)
    return road.s.take(i) + ch * dx + sh * dy, ch * dy - sh * dx


_LUT_STEP, _LUT_HALF = 0.025, 200.0      # lateral material table: 2.5 cm bins over |d| < 200 m


@functools.lru_cache(maxsize=4)
def _lateral_lut(cover: str) -> np.ndarray:
    """Ground material by lateral bin and dash phase: ``lut[2 * bin + dash_on]``."""
    d = (np.arange(int(2 * _LUT_HALF / _LUT_STEP)) + 0.5) * _LUT_STEP - _LUT_HALF
    base = np.full(d.shape, _MAT[cover if cover in ('snow', 'dry_grass') else 'grass'],
                   dtype=np.int16)
    base[(d >= -(ROAD_HALF_WIDTH + RIGHT_SHOULDER)) & (d <= ROAD_HALF_WIDTH + LEFT_SHOULDER)] = \
        _MAT['shoulder']
    ad = np.abs(d)
    base[ad <= ROAD_HALF_WIDTH] = _MAT['asphalt']
    edge = np.abs(ad - ROAD_HALF_WIDTH) <= _PAINT_HALF_WIDTH
    base[edge & (d < 0)] = _MAT['lane_paint']
    base[edge & (d > 0)] = _MAT['lane_paint_yellow']
    on = base.copy()
    on[np.abs(ad - _DASH_LINE_D) <= _PAINT_HALF_WIDTH] = _MAT['lane_paint']
    lut = np.stack([base, on], axis=1).ravel()
    lut.setflags(write=False)
    return lut


def _ground_materials(scene: Scene, table: _Table, x: np.ndarray, y: np.ndarray,
                      s0: float) -> np.ndarray:
    s, d = _frenet_local(scene.road, table.road_cos, table.road_sin, x, y, s0)
    lut = _lateral_lut(scene.ground_cover)
    nbin = lut.size // 2
    i = np.clip(((d + _LUT_HALF) * (2.0 / _LUT_STEP)).astype(np.int64), 0, 2 * nbin - 2)
    i &= ~1
    # Dash phase: paint where s mod 12 < 3, i.e. floor(s / 3) mod 4 == 0 (s offset to stay > 0).
    quarter = ((s + 100 * _DASH_PERIOD) * (1.0 / _DASH_LENGTH)).astype(np.int64)
    i += (quarter & 3) == 0
    return lut.take(i)


# --------------------------------------------------------------------------------------------
# The caster

_KNOTS = 9


def cast_scan(scene: Scene, t0: float, lidar_pose_at: Callable[[float], Pose],
              model: LidarModel = LidarModel(), seed: int = 0, scan_index: int = 0) -> Scan:
    """Ray-cast one revolution of the LiDAR against the scene.

    Args:
        scene: the world (road, signs, objects; boxes move with :meth:`Box.at`).
        t0: scan start time in seconds (scene time); column ``c`` fires at
            ``t0 + c / n_columns / rate_hz``.
        lidar_pose_at: pose of the lidar frame in the world at a time; sampled at a few knots
            across the spin and interpolated per column.
        model: the sensor.
        seed: randomness seed (with ``scan_index``).
        scan_index: index of the scan in the run; the noise differs per scan.

    Returns:
        The scan: points in the lidar frame at each point's firing time (see module
        docstring), object ids and the sign-face point indices.

    Raises:
        LidarError: an object type or material the caster does not know.
    """
    rays = _ray_table(model)
    table = _table_for(scene)
    nc, nb = rays.n_cols, rays.n_beams
    spin = 1.0 / model.rate_hz

    # Sensor pose per column, interpolated from knots.
    tk = t0 + np.linspace(0.0, spin, _KNOTS)
    poses = [lidar_pose_at(float(t)) for t in tk]
    pos_k = np.array([np.asarray(p.position, float) for p in poses])
    ang_k = np.array([[p.yaw, p.pitch, p.roll] for p in poses], dtype=float)
    ang_k[:, 0] = np.unwrap(ang_k[:, 0])
    tc = t0 + rays.col_frac * spin
    pos_c = np.stack([np.interp(tc, tk, pos_k[:, i]) for i in range(3)], axis=1)
    ang_c = [np.interp(tc, tk, ang_k[:, i]) for i in range(3)]
    R_c = _rot_batch(*ang_c)                                   # (nc, 3, 3)
    R_k = _rot_batch(ang_k[:, 0], ang_k[:, 1], ang_k[:, 2])
    L = rays.local.reshape(nc, nb, 3)
    D = np.matmul(L, R_c.transpose(0, 2, 1)).reshape(-1, 3)   # world directions (N, 3)
    N = D.shape[0]

    # Ground plane z = 0.
    oz = np.repeat(pos_c[:, 2], nb)
    dz = D[:, 2]
    t_best = np.full(N, np.inf)
    down = dz < -1e-9
    t_best[down] = -oz[down] / dz[down]
    code = np.full(N, -1, dtype=np.int32)                      # index into table.objs
    mat = np.zeros(N, dtype=np.int16)
    cosi = np.abs(dz)
    front = np.zeros(N, dtype=bool)

    # Objects: cull by range, then by azimuth / elevation window.
    n_obj = len(table.objs)
    if n_obj:
        travel = float(np.linalg.norm(pos_k[-1] - pos_k[0]))
        ctr = table.centre + table.vel * t0
        reach = (model.max_range + table.radius + travel
                 + np.linalg.norm(table.vel, axis=1) * spin + 1.0)
        cand = np.flatnonzero(np.linalg.norm(ctr - pos_k[0], axis=1) < reach)
    else:
        cand = np.zeros(0, dtype=int)
    if cand.size:
        tilt = float(np.max(np.abs(ang_k[:, 1]) + np.abs(ang_k[:, 2])))
        col_lo, col_hi, full, b_lo, b_hi, dmin = _windows(
            table, cand, tk, pos_k, R_k, tilt, rays)
        all_cols = np.arange(nc)
        for j in np.argsort(dmin, kind='stable'):      # near first: occluders prune the rest
            if b_hi[j] <= b_lo[j] or dmin[j] > model.max_range:
                continue
            oi = cand[j]
            cols = all_cols if full[j] else np.arange(col_lo[j], col_hi[j] + 1) % nc
            idx = (cols[:, None] * nb + np.arange(b_lo[j], b_hi[j])[None, :]).ravel()
            idx = idx[t_best[idx] > dmin[j]]            # rays already stopped nearer
            if not idx.size:
                continue
            col_of = idx // nb
            O_b, D_b = np.take(pos_c, col_of, axis=0), np.take(D, idx, axis=0)
            T_b = tc.take(col_of)
            kind, ex = table.kinds[oi], table.extra[oi]
            if kind == _SIGN:
                t, m, ci, fr = _hit_sign(ex, O_b, D_b, T_b)
            elif kind == _CYL:
                t, m, ci, fr = _hit_cylinder(ex, O_b, D_b, T_b)
            elif kind == _CONE:
                t, m, ci, fr = _hit_cone(ex, O_b, D_b, T_b)
            elif kind == _BOX:
                t, m, ci, fr = _hit_box(ex, O_b, D_b, T_b, table.vel[oi])
            else:
                t, m, ci, fr = _hit_quad(ex, O_b, D_b, T_b)
            better = t < t_best[idx]
            if not better.any():
                continue
            k = idx[better]
            t_best[k] = t[better]
            code[k] = oi
            mat[k] = m[better]
            cosi[k] = ci[better]
            front[k] = fr[better]

    # Returns in range, then random dropouts.
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, int(scan_index) & 0xFFFFFFFF])
    valid = (t_best >= model.min_range) & (t_best <= model.max_range)
    keep = np.flatnonzero(valid)
    keep = keep[rng.random(keep.size) >= model.dropout]
    t_k, code_k = t_best[keep], code[keep]
    mat_k, cos_k = mat[keep], np.minimum(cosi[keep], 1.0)

    ground = code_k < 0
    if ground.any():
        gi = keep[ground]
        col_g = gi // nb
        D_g, t_g = np.take(D, gi, axis=0), t_k[ground]
        gx = pos_c[:, 0].take(col_g) + t_g * D_g[:, 0]
        gy = pos_c[:, 1].take(col_g) + t_g * D_g[:, 1]
        road = scene.road
        s0 = float(road.s[np.argmin((road.x - pos_k[0, 0]) ** 2 + (road.y - pos_k[0, 1]) ** 2)])
        mat_k[ground] = _ground_materials(scene, table, gx, gy, s0)

    n = keep.size
    r = t_k.astype(np.float32)
    if model.range_noise_m:
        r += np.float32(model.range_noise_m) * rng.standard_normal(n, dtype=np.float32)
    refl = _REFL32.take(mat_k)
    cos_k = cos_k.astype(np.float32)
    tk32 = t_k.astype(np.float32)
    inten = refl * (0.2 + 0.8 * cos_k) * (255.0 / (1.0 + (tk32 * np.float32(1 / 80.0)) ** 2))
    retro = np.flatnonzero(_RETRO.take(mat_k))
    if retro.size:
        frac = tk32[retro] * np.float32(1.0 / model.max_range)
        inten[retro] = 255.0 * refl[retro] * (0.85 + 0.15 * cos_k[retro]) * (
            1.0 - 0.25 * frac * frac)
    faces = np.flatnonzero(front[keep])
    if faces.size:
        inten[faces] *= table.face_gain.take(code_k[faces])
    # 5 % multiplicative and 1.0 additive noise, drawn as one Gaussian.
    inten += np.sqrt((0.05 * inten) ** 2 + 1.0) * rng.standard_normal(n, dtype=np.float32)
    np.clip(inten, 0.0, 255.0, out=inten)

    points = make_points(x=rays.lx.take(keep) * r, y=rays.ly.take(keep) * r,
                         z=rays.lz.take(keep) * r, intensity=inten, ring=rays.ring.take(keep))
    ids_table = table.ids
    object_ids = np.where(code_k >= 0, ids_table[np.maximum(code_k, 0)] if ids_table.size
                          else -1, -1).astype(np.int32)
    sign_hits: dict[int, np.ndarray] = {}
    face_pts = faces
    if face_pts.size:
        codes = code_k[face_pts]
        order = np.argsort(codes, kind='stable')
        codes, face_pts = codes[order], face_pts[order]
        splits = np.flatnonzero(np.diff(codes)) + 1
        for grp_codes, grp in zip(np.split(codes, splits), np.split(face_pts, splits)):
            sign_hits[int(table.objs[grp_codes[0]].object_id)] = np.sort(grp)
    return Scan(points, object_ids, sign_hits)
