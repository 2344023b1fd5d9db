"""Beam and ray geometry of the LiDAR caster: the per-model ray table (beam elevations x
column azimuths, cached), the batched sensor rotations, and the ray-primitive intersections
(sign faces, cylinders, cones, boxes with plates and tail reflectors, quads).
"""
# Ray origins / directions as O, D (the usual ray-casting names).
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .lidar_materials import _MAT, sign_shape_contains
from .lidar_model import LidarModel

# --------------------------------------------------------------------------------------------
# Ray table (per model)

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
