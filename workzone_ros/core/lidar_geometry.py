"""Where the LiDAR is: its mounting on the vehicle and the road under it, per scan.

The sign-candidate thresholds are heights above the road and positions ahead / left of the
vehicle, so they hold for any sensor on any vehicle.  Two pieces give them:

* :class:`Mount` -- the sensor's pose in ``base_link`` (``lidar_in_base``: x y z roll pitch
  yaw, metres and radians; ``base_link`` on the road surface, x forward, y left, z up, as
  REP-103 and the simulator have it).  Its rotation gives the axes (a sensor with x right /
  y forward is ``yaw = -pi/2``: never an assumed convention); its z is the mounting height.
  Points go to the *level frame*: base axes, origin on the road right under the sensor
  (``level = R p + (0, 0, z)``), so ranges stay sensor-centred.
* :class:`GroundPlane` -- where the ground is visible, a robust per-scan plane fit
  (:func:`fit_ground`: RANSAC over a subsample of low points ahead, within 40 m and 10 m
  to either side, refined by least squares on its inliers) gives the road under the car
  even when the mounting height is a few decimetres off, the car pitches under braking or
  the road slopes.  Heights are ``level z - (a x + b y + c)``.  A fit is used only when
  it is plausible (enough inliers, a slope below ``max_slope``, within ``max_offset`` of
  the mounting); otherwise the last plausible plane (the caller's ``prior``) or the
  mounting alone.
* :func:`beam_spacing` -- the sensor's vertical resolution (the median elevation step
  between its rings, from the ``ring`` field), so the clustering can join the rings of one
  sign face on a 16- or 32-beam sensor, whose rings are further apart than the points of a
  ring.

No rclpy here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

__all__ = ['LidarGeometryError', 'Mount', 'GroundPlane', 'fit_ground', 'rotation_rpy',
           'describe_axes', 'beam_spacing']


class LidarGeometryError(ValueError):
    """A mounting that cannot be used (wrong length, not finite, not above the road)."""


def rotation_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` (the ROS / ``euler_matrix`` convention)."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


_AXES = {(1, 0, 0): 'forward', (-1, 0, 0): 'backward', (0, 1, 0): 'left',
         (0, -1, 0): 'right', (0, 0, 1): 'up', (0, 0, -1): 'down'}


def describe_axes(rot: np.ndarray) -> str:
    """'x forward, y left, z up' for a rotation close to axis-aligned, else the angles."""
    words = []
    for axis, name in enumerate('xyz'):
        col = np.round(rot[:, axis], 3)
        key = tuple(int(round(v)) for v in col)
        if np.abs(col - np.array(key)).max() > 0.05 or key not in _AXES:
            words.append(f'{name} ({col[0]:+.2f}, {col[1]:+.2f}, {col[2]:+.2f})')
        else:
            words.append(f'{name} {_AXES[key]}')
    return ', '.join(words)


@dataclass(frozen=True)
class Mount:
    """The sensor's pose on the vehicle (lidar frame -> level frame).

    Attributes:
        rot: 3x3 rotation, base_link <- lidar.
        height: sensor height above the road, metres.
        xy: sensor position in base_link (x, y), metres (for odometry, not for thresholds).
    """

    rot: np.ndarray
    height: float
    xy: tuple = (0.0, 0.0)

    @classmethod
    def from_list(cls, values: Sequence[float], name: str = 'lidar_in_base') -> 'Mount':
        """Build from ``x y z roll pitch yaw`` (metres, radians).

        Raises:
            LidarGeometryError: not 6 finite values, or z (the height above the road) <= 0.
        """
        v = [float(x) for x in values]
        if len(v) != 6:
            raise LidarGeometryError(f'{name} needs 6 values (x y z roll pitch yaw, metres and '
                                     f'radians), got {len(v)}')
        if not all(math.isfinite(x) for x in v):
            raise LidarGeometryError(f'{name} has a value that is not finite: {v}')
        if v[2] <= 0.0:
            raise LidarGeometryError(f'{name} z = {v[2]} m: it is the height of the sensor above '
                                     f'the road (base_link on the road), so it must be > 0')
        if any(abs(a) > 2 * math.pi + 1e-9 for a in v[3:]):
            raise LidarGeometryError(f'{name} roll/pitch/yaw {v[3:]} look like degrees; they are '
                                     f'radians')
        return cls(rotation_rpy(*v[3:]), v[2], (v[0], v[1]))

    def to_level(self, xyz: np.ndarray) -> np.ndarray:
        """(N, 3) lidar-frame points -> level frame (base axes, origin on the road below)."""
        out = np.asarray(xyz, np.float64) @ self.rot.T
        out[:, 2] += self.height
        return out

    def to_lidar(self, level: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`to_level`."""
        p = np.array(level, np.float64).reshape(-1, 3)
        p[:, 2] -= self.height
        return p @ self.rot

    def describe(self) -> str:
        """One line for the log: height and axes."""
        return (f'sensor {self.height:.2f} m above the road, axes in base_link: '
                f'{describe_axes(self.rot)}')


@dataclass(frozen=True)
class GroundPlane:
    """The road in the level frame: ``z = a x + b y + c``.

    Attributes:
        a, b, c: plane coefficients (c: road height under the sensor, 0 when the mounting
            height is exact).
        inliers: points that supported the fit (0 for the mounting alone).
        source: 'fit', 'prior' (the last plausible fit) or 'mount'.
    """

    a: float = 0.0
    b: float = 0.0
    c: float = 0.0
    inliers: int = 0
    source: str = 'mount'

    def height(self, level: np.ndarray) -> np.ndarray:
        """Height above the road of (N, 3) level-frame points."""
        p = np.asarray(level)
        return p[:, 2] - (self.a * p[:, 0] + self.b * p[:, 1] + self.c)

    def road_z(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Road height (level frame) at horizontal positions."""
        return self.a * np.asarray(x) + self.b * np.asarray(y) + self.c

    def describe(self) -> str:
        """One line: where the road is and where that came from."""
        slope = math.degrees(math.atan(math.hypot(self.a, self.b)))
        return (f'road {self.c:+.2f} m from the mounting, slope {slope:.1f} deg '
                f'({self.source}{", %d inliers" % self.inliers if self.inliers else ""})')


def fit_ground(level: np.ndarray, prior: Optional[GroundPlane] = None, *,
               search: float = 0.8, max_range: float = 40.0, min_range: float = 3.0,
               x_min: float = 0.0, half_width: float = 10.0, tol: float = 0.08,
               max_slope: float = 0.1, max_offset: float = 0.6,
               iterations: int = 50, min_inliers: int = 150, sample: int = 2500,
               seed: int = 0) -> GroundPlane:
    """Fit the road plane to one scan (RANSAC, then least squares on the inliers).

    Args:
        level: (N, 3) points in the level frame (any subsample of the scan; NaN allowed).
        prior: returned when this scan's fit is not plausible (else the mounting alone).
        search: only points within this height of the mounting's road are candidates, m.
        max_range, min_range: horizontal range of the candidates, m (the car's own body and
            far, sparse rings are left out).
        x_min, half_width: candidates ahead of ``x_min`` and within ``half_width`` of the
            sensor's line, m: the road where the signs are measured, not the sidewalks,
            curbs and embankments beside it (on the real scenes a fit over the whole circle
            tilts sideways by up to 2.7 deg).
        tol: inlier distance, m.
        max_slope: a plane steeper than this (rise per metre) is not the road.
        max_offset: a road further than this from the mounting's is not believed, m.
        iterations: RANSAC hypotheses (fixed seed: the same scan gives the same plane).
        min_inliers: fewer supporting points: the ground is not visible enough.
        sample: at most this many candidates are used.
        seed: random seed.

    Returns:
        The plane, with ``source`` 'fit', 'prior' or 'mount'.
    """
    fallback = prior if prior is not None else GroundPlane()
    if prior is not None and prior.source == 'fit':
        fallback = GroundPlane(prior.a, prior.b, prior.c, prior.inliers, 'prior')
    p = np.asarray(level, np.float64)
    if p.shape[0] < 3:
        return fallback
    r2 = p[:, 0] ** 2 + p[:, 1] ** 2
    cand = p[(np.abs(p[:, 2]) <= search) & (r2 >= min_range ** 2) & (r2 <= max_range ** 2)
             & (p[:, 0] >= x_min) & (np.abs(p[:, 1]) <= half_width)]      # NaN fails all
    if cand.shape[0] < min_inliers:
        return fallback
    if cand.shape[0] > sample:
        cand = cand[:: cand.shape[0] // sample + 1]
    rng = np.random.default_rng(seed)
    tri = rng.integers(0, cand.shape[0], size=(iterations, 3))
    p0, p1, p2 = cand[tri[:, 0]], cand[tri[:, 1]], cand[tri[:, 2]]
    nrm = np.cross(p1 - p0, p2 - p0)
    nz = nrm[:, 2]
    ok = np.abs(nz) > 1e-9
    a = np.where(ok, -nrm[:, 0] / np.where(ok, nz, 1.0), 0.0)
    b = np.where(ok, -nrm[:, 1] / np.where(ok, nz, 1.0), 0.0)
    c = p0[:, 2] - a * p0[:, 0] - b * p0[:, 1]
    ok &= np.hypot(a, b) <= max_slope
    if not ok.any():
        return fallback
    a, b, c = a[ok], b[ok], c[ok]
    # Hypotheses are scored on a few hundred candidates; the best is refined on all of them
    # (inliers, least squares, inliers again, least squares).
    probe = cand[:: max(1, cand.shape[0] // 400)]
    res = np.abs(probe[None, :, 2] - (a[:, None] * probe[None, :, 0] + b[:, None]
                                      * probe[None, :, 1] + c[:, None]))
    best = int(np.argmax((res <= tol).sum(axis=1)))
    fa, fb, fc = float(a[best]), float(b[best]), float(c[best])
    for _ in range(2):
        inl = cand[np.abs(cand[:, 2] - (fa * cand[:, 0] + fb * cand[:, 1] + fc)) <= tol]
        if inl.shape[0] < min_inliers:
            return fallback
        design = np.column_stack([inl[:, 0], inl[:, 1], np.ones(inl.shape[0])])
        coef, *_ = np.linalg.lstsq(design, inl[:, 2], rcond=None)
        fa, fb, fc = (float(v) for v in coef)
    if math.hypot(fa, fb) > max_slope or abs(fc) > max_offset:
        return fallback
    return GroundPlane(fa, fb, fc, int(inl.shape[0]), 'fit')


def beam_spacing(xyz: np.ndarray, rings: Optional[np.ndarray]) -> float:
    """The sensor's vertical beam spacing in radians, from a subsample of one scan.

    Each ring's mean elevation (in the sensor's own frame) is taken, and the median step
    between consecutive rings sorted by elevation is the spacing (robust to the non-uniform
    blocks of an HDL-64E and to rings that see only sky).  Without a ``ring`` field the
    rings cannot be told apart reliably (lasers with vertical offsets smear a ring's
    elevation over range), so the spacing is unknown.

    Args:
        xyz: (N, 3) lidar-frame points.
        rings: (N,) their ring numbers, or None.

    Returns:
        The spacing (rad), or NaN when unknown (no ring field, fewer than 3 rings).
    """
    if rings is None or len(rings) == 0:
        return float('nan')
    p = np.asarray(xyz, np.float64)
    ok = np.isfinite(p).all(axis=1)
    if not ok.any():
        return float('nan')
    el = np.arctan2(p[ok, 2], np.hypot(p[ok, 0], p[ok, 1]))
    ring = np.asarray(rings)[ok].astype(np.int64)
    ring -= ring.min()
    hits = np.bincount(ring)
    levels = np.sort(np.bincount(ring, el)[hits > 0] / hits[hits > 0])
    if levels.size < 3:
        return float('nan')
    return float(np.median(np.diff(levels)))
