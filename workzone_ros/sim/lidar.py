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

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..core.pointcloud import make_points
from .lidar_materials import _REFL32, _RETRO, sign_shape_contains
from .lidar_model import (
    DEFAULT_PRESET,
    LIDAR_PRESETS,
    LidarError,
    LidarModel,
    Scan,
    lidar_preset,
)
from .lidar_rays import (
    _hit_box,
    _hit_cone,
    _hit_cylinder,
    _hit_quad,
    _hit_sign,
    _ray_table,
    _rot_batch,
)
from .lidar_scene import _BOX, _CONE, _CYL, _SIGN, _ground_materials, _table_for, _windows
from .world import Pose, Scene

__all__ = ['LidarError', 'LidarModel', 'LIDAR_PRESETS', 'DEFAULT_PRESET', 'Scan', 'cast_scan',
           'lidar_preset', 'sign_shape_contains']


# --------------------------------------------------------------------------------------------
# The caster

_KNOTS = 9


@dataclass
class _Spin:
    """The sensor's motion over one revolution: knots and per-column poses, world frame."""

    tk: np.ndarray          # (_KNOTS,) knot times
    pos_k: np.ndarray       # (_KNOTS, 3) knot positions
    ang_k: np.ndarray       # (_KNOTS, 3) knot yaw (unwrapped), pitch, roll
    R_k: np.ndarray         # (_KNOTS, 3, 3) knot rotations
    tc: np.ndarray          # (nc,) column firing times
    pos_c: np.ndarray       # (nc, 3) column positions
    D: np.ndarray           # (N, 3) world ray directions


@dataclass
class _Hits:
    """Nearest hit per ray so far: distance, object (index into table.objs, -1 ground),
    material, cosine of incidence and whether it is a sign's front face."""

    t_best: np.ndarray
    code: np.ndarray
    mat: np.ndarray
    cosi: np.ndarray
    front: np.ndarray


def _spin_poses(t0: float, spin: float, lidar_pose_at: Callable[[float], Pose],
                rays) -> _Spin:
    """Sensor pose per column, interpolated from knots, and the rays' world directions."""
    nc, nb = rays.n_cols, rays.n_beams
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
    return _Spin(tk, pos_k, ang_k, R_k, tc, pos_c, D)


def _ground_hits(sp: _Spin, nb: int) -> _Hits:
    """Hits on the ground plane z = 0 (rays pointing down)."""
    D = sp.D
    N = D.shape[0]
    oz = np.repeat(sp.pos_c[:, 2], nb)
    dz = D[:, 2]
    t_best = np.full(N, np.inf)
    down = dz < -1e-9
    t_best[down] = -oz[down] / dz[down]
    code = np.full(N, -1, dtype=np.int32)                      # index into table.objs
    mat = np.zeros(N, dtype=np.int16)
    cosi = np.abs(dz)
    front = np.zeros(N, dtype=bool)
    return _Hits(t_best, code, mat, cosi, front)


def _candidate_objects(table, model: LidarModel, sp: _Spin, t0: float,
                       spin: float) -> np.ndarray:
    """Indices into table.objs of the objects within reach of this revolution."""
    n_obj = len(table.objs)
    if n_obj:
        pos_k = sp.pos_k
        travel = float(np.linalg.norm(pos_k[-1] - pos_k[0]))
        ctr = table.centre + table.vel * t0
        reach = (model.max_range + table.radius + travel
                 + np.linalg.norm(table.vel, axis=1) * spin + 1.0)
        return np.flatnonzero(np.linalg.norm(ctr - pos_k[0], axis=1) < reach)
    return np.zeros(0, dtype=int)


def _hit_object(table, oi, O_b: np.ndarray, D_b: np.ndarray, T_b: np.ndarray):
    """Intersect rays with object ``oi`` of the table: (t, material, cos, front) per ray."""
    kind, ex = table.kinds[oi], table.extra[oi]
    if kind == _SIGN:
        return _hit_sign(ex, O_b, D_b, T_b)
    if kind == _CYL:
        return _hit_cylinder(ex, O_b, D_b, T_b)
    if kind == _CONE:
        return _hit_cone(ex, O_b, D_b, T_b)
    if kind == _BOX:
        return _hit_box(ex, O_b, D_b, T_b, table.vel[oi])
    return _hit_quad(ex, O_b, D_b, T_b)


def _cast_objects(table, model: LidarModel, rays, sp: _Spin, cand: np.ndarray,
                  hits: _Hits) -> None:
    """Objects: cull by azimuth / elevation window, then intersect, nearest first."""
    nc, nb = rays.n_cols, rays.n_beams
    t_best = hits.t_best
    tilt = float(np.max(np.abs(sp.ang_k[:, 1]) + np.abs(sp.ang_k[:, 2])))
    col_lo, col_hi, full, b_lo, b_hi, dmin = _windows(
        table, cand, sp.tk, sp.pos_k, sp.R_k, tilt, rays)
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
        O_b, D_b = np.take(sp.pos_c, col_of, axis=0), np.take(sp.D, idx, axis=0)
        T_b = sp.tc.take(col_of)
        t, m, ci, fr = _hit_object(table, oi, O_b, D_b, T_b)
        better = t < t_best[idx]
        if not better.any():
            continue
        k = idx[better]
        t_best[k] = t[better]
        hits.code[k] = oi
        hits.mat[k] = m[better]
        hits.cosi[k] = ci[better]
        hits.front[k] = fr[better]


def _ground_material(scene: Scene, table, sp: _Spin, nb: int, keep: np.ndarray,
                     t_k: np.ndarray, code_k: np.ndarray, mat_k: np.ndarray) -> None:
    """Set the road / shoulder material of the kept ground returns in ``mat_k``."""
    ground = code_k < 0
    if ground.any():
        pos_c, pos_k = sp.pos_c, sp.pos_k
        gi = keep[ground]
        col_g = gi // nb
        D_g, t_g = np.take(sp.D, gi, axis=0), t_k[ground]
        gx = pos_c[:, 0].take(col_g) + t_g * D_g[:, 0]
        gy = pos_c[:, 1].take(col_g) + t_g * D_g[:, 1]
        road = scene.road
        s0 = float(road.s[np.argmin((road.x - pos_k[0, 0]) ** 2 + (road.y - pos_k[0, 1]) ** 2)])
        mat_k[ground] = _ground_materials(scene, table, gx, gy, s0)


def _returns(model: LidarModel, table, rng, t_k: np.ndarray, code_k: np.ndarray,
             mat_k: np.ndarray, cos_k: np.ndarray, front_k: np.ndarray):
    """Noisy ranges (float32), intensities (0-255, float32) and the sign-face returns."""
    n = t_k.size
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
    faces = np.flatnonzero(front_k)
    if faces.size:
        inten[faces] *= table.face_gain.take(code_k[faces])
    # 5 % multiplicative and 1.0 additive noise, drawn as one Gaussian.
    inten += np.sqrt((0.05 * inten) ** 2 + 1.0) * rng.standard_normal(n, dtype=np.float32)
    np.clip(inten, 0.0, 255.0, out=inten)
    return r, inten, faces


def _sign_hits(table, code_k: np.ndarray, faces: np.ndarray) -> dict[int, np.ndarray]:
    """Sign object id -> sorted indices of its face returns."""
    sign_hits: dict[int, np.ndarray] = {}
    face_pts = faces
    if face_pts.size:
        codes = code_k[face_pts]
        order = np.argsort(codes, kind='stable')
        codes, face_pts = codes[order], face_pts[order]
        splits = np.flatnonzero(np.diff(codes)) + 1
        for grp_codes, grp in zip(np.split(codes, splits), np.split(face_pts, splits)):
            sign_hits[int(table.objs[grp_codes[0]].object_id)] = np.sort(grp)
    return sign_hits


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
    nb = rays.n_beams
    spin = 1.0 / model.rate_hz
    sp = _spin_poses(t0, spin, lidar_pose_at, rays)
    hits = _ground_hits(sp, nb)
    cand = _candidate_objects(table, model, sp, t0, spin)
    if cand.size:
        _cast_objects(table, model, rays, sp, cand, hits)

    # Returns in range, then random dropouts.
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, int(scan_index) & 0xFFFFFFFF])
    t_best = hits.t_best
    valid = (t_best >= model.min_range) & (t_best <= model.max_range)
    keep = np.flatnonzero(valid)
    keep = keep[rng.random(keep.size) >= model.dropout]
    t_k, code_k = t_best[keep], hits.code[keep]
    mat_k, cos_k = hits.mat[keep], np.minimum(hits.cosi[keep], 1.0)
    _ground_material(scene, table, sp, nb, keep, t_k, code_k, mat_k)
    r, inten, faces = _returns(model, table, rng, t_k, code_k, mat_k, cos_k, hits.front[keep])

    points = make_points(x=rays.lx.take(keep) * r, y=rays.ly.take(keep) * r,
                         z=rays.lz.take(keep) * r, intensity=inten, ring=rays.ring.take(keep))
    ids_table = table.ids
    object_ids = np.where(code_k >= 0, ids_table[np.maximum(code_k, 0)] if ids_table.size
                          else -1, -1).astype(np.int32)
    return Scan(points, object_ids, _sign_hits(table, code_k, faces))
