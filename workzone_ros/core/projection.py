"""Project LiDAR candidates into the camera image and size their crops (Cahail et al. section 2).

Cahail et al. s2.4.2: ``s [u v 1]^T = A [R|t] [X Y Z 1]^T`` with the plumb_bob distortion
``x'' = x'(1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x'y' + p2 (r^2 + 2 x'^2)`` (and the y
counterpart), computed by OpenCV's ``projectPoints`` (the seed's ``cvProjectPoints2``).
Beyond the seed (its future work s6.x):

* points behind the camera are never projected (``projectPoints`` would mirror them), and
  points whose undistorted direction is far outside the field of view are reported as
  outside instead of being folded back into the image by the distortion polynomial;
* several candidates per frame;
* each crop is sized from the candidate's radius and range (``half = margin * max(radius,
  min_radius) * f / depth + pad``) instead of a fixed +-250 px;
* ego-motion compensation between the time the candidate was scanned and the image time,
  from odometry poses: ``X_lidar(t_img) = T_lidar(t_img)^-1 T_lidar(t_scan) X_lidar(t_scan)``
  -- at 27 m/s a 50 ms offset is 1.35 m of travel.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

__all__ = ['ProjectionError', 'CameraModel', 'Projected', 'project_points', 'crop_boxes',
           'compensate', 'point_times', 'invert', 'extrinsics_from_list', 'euler_matrix',
           'RoiParams', 'candidates_to_rois', 'forward_time_offset']


class ProjectionError(ValueError):
    """Missing or unusable calibration."""


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Intrinsics and distortion as in CameraInfo (raw, distorted image).

    Attributes:
        width, height: image size, pixels.
        K: 3x3 intrinsic matrix.
        D: distortion coefficients (plumb_bob k1 k2 p1 p2 [k3], rational_polynomial 8+,
            equidistant k1..k4); may be empty.
        model: ``plumb_bob``, ``rational_polynomial`` or ``equidistant``.
    """

    width: int
    height: int
    K: np.ndarray
    D: np.ndarray
    model: str = 'plumb_bob'

    @classmethod
    def from_info(cls, info) -> 'CameraModel':
        """From a ``conversions.CameraInfoData`` (or anything with the same attributes)."""
        return cls(int(info.width), int(info.height), np.asarray(info.K, float).reshape(3, 3),
                   np.asarray(info.D, float).reshape(-1), info.distortion_model or 'plumb_bob')

    @property
    def fx(self) -> float:
        """Focal length x, pixels."""
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        """Focal length y, pixels."""
        return float(self.K[1, 1])


@dataclass
class Projected:
    """Projection of N points.

    Attributes:
        uv: (N, 2) pixels (NaN where not projectable: behind the camera or far outside).
        depth: (N,) z in the camera frame, metres.
        xyz_cam: (N, 3) points in the camera frame.
        in_front: (N,) depth above the minimum.
        in_image: (N,) projected inside the image.
    """

    uv: np.ndarray
    depth: np.ndarray
    xyz_cam: np.ndarray
    in_front: np.ndarray
    in_image: np.ndarray


def invert(t: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    out = np.eye(4)
    r = t[:3, :3]
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ t[:3, 3]
    return out


def euler_matrix(xyz: tuple, rpy: tuple) -> np.ndarray:
    """4x4 from a translation and roll/pitch/yaw (R = Rz(yaw) Ry(pitch) Rx(roll))."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    t = np.eye(4)
    t[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    t[:3, 3] = xyz
    return t


def extrinsics_from_list(values, name: str = 'lidar_to_camera') -> np.ndarray:
    """A row-major 4x4 (16 values) or top 3x4 (12 values) -> validated 4x4 rigid transform.

    Raises:
        ProjectionError: wrong count, non-finite values, or a rotation that is not one.
    """
    v = np.asarray(list(values), dtype=float).reshape(-1)
    if v.size == 12:
        v = np.concatenate([v, [0.0, 0.0, 0.0, 1.0]])
    if v.size != 16:
        raise ProjectionError(f'{name} needs 16 (4x4) or 12 (3x4) values, got {v.size}')
    t = v.reshape(4, 4)
    if not np.isfinite(t).all():
        raise ProjectionError(f'{name} has non-finite values')
    r = t[:3, :3]
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-3) or abs(np.linalg.det(r) - 1) > 1e-3:
        raise ProjectionError(f'{name} rotation part is not a rotation (R R^T != I or '
                              f'det != 1); is the matrix row-major?')
    if not np.allclose(t[3], [0, 0, 0, 1]):
        raise ProjectionError(f'{name} last row must be 0 0 0 1')
    return t


def project_points(xyz_lidar: np.ndarray, lidar_to_camera: np.ndarray, camera: CameraModel,
                   min_depth: float = 0.5, fov_margin: float = 0.25) -> Projected:
    """Project LiDAR points with K, distortion and extrinsics (Cahail et al. s2.4.2).

    Args:
        xyz_lidar: (N, 3) points in the lidar frame.
        lidar_to_camera: 4x4 with ``X_cam = T @ X_lidar``.
        camera: intrinsics and distortion.
        min_depth: points with camera z below this are "behind" (not projected).
        fov_margin: undistorted normalised coordinates beyond the image's own extent by more
            than this fraction are not projected (distortion polynomials fold them back).

    Returns:
        :class:`Projected`.
    """
    xyz = np.asarray(xyz_lidar, float).reshape(-1, 3)
    pc = xyz @ lidar_to_camera[:3, :3].T + lidar_to_camera[:3, 3]
    depth = pc[:, 2]
    in_front = depth > min_depth
    uv = np.full((xyz.shape[0], 2), np.nan)
    if in_front.any():
        k = camera.K
        xn = pc[in_front, 0] / depth[in_front]
        yn = pc[in_front, 1] / depth[in_front]
        # Normalised extent of the image (pinhole), with a margin.
        x_lo, x_hi = -k[0, 2] / k[0, 0], (camera.width - k[0, 2]) / k[0, 0]
        y_lo, y_hi = -k[1, 2] / k[1, 1], (camera.height - k[1, 2]) / k[1, 1]
        mx, my = fov_margin * (x_hi - x_lo), fov_margin * (y_hi - y_lo)
        ok = (xn >= x_lo - mx) & (xn <= x_hi + mx) & (yn >= y_lo - my) & (yn <= y_hi + my)
        idx = np.flatnonzero(in_front)[ok]
        if idx.size:
            obj = pc[idx].reshape(-1, 1, 3)
            zero = np.zeros(3)
            if camera.model == 'equidistant':
                d = np.zeros(4) if camera.D.size == 0 else camera.D[:4]
                out, _ = cv2.fisheye.projectPoints(obj, zero, zero, k, d)
            else:
                out, _ = cv2.projectPoints(obj, zero, zero, k,
                                           camera.D if camera.D.size else None)
            uv[idx] = out.reshape(-1, 2)
    fin = np.isfinite(uv).all(axis=1)
    in_image = np.zeros(xyz.shape[0], bool)
    in_image[fin] = ((uv[fin, 0] >= 0) & (uv[fin, 0] <= camera.width - 1)
                     & (uv[fin, 1] >= 0) & (uv[fin, 1] <= camera.height - 1))
    return Projected(uv, depth, pc, in_front, in_image)


def crop_boxes(uv: np.ndarray, depth: np.ndarray, radius: np.ndarray, camera: CameraModel,
               margin: float = 1.5, min_radius: float = 0.6, pad_px: float = 6.0,
               min_px: float = 16.0, max_px: Optional[float] = None,
               pad_m: float = 0.3) -> np.ndarray:
    """Crop boxes sized from the candidate radius and range (replaces Cahail et al.'s +-250 px).

    ``half = (margin * max(radius, min_radius) + pad_m) * f / depth + pad_px`` (at least
    ``min_px / 2``); ``min_radius`` keeps a sparse cluster (one ring on a far sign, the lower
    edge of a sign) from a crop smaller than the sign, ``pad_m`` absorbs calibration and
    residual sync error.  Boxes are clipped to the image.

    Args:
        uv: (N, 2) centres, pixels.
        depth: (N,) camera z, metres.
        radius: (N,) candidate radii, metres.
        camera: intrinsics (focal lengths) and image size.
        margin, min_radius, pad_px, min_px, pad_m: sizing; ``max_px`` caps the side.

    Returns:
        (N, 4) float boxes ``x, y, w, h`` (w or h 0 when the box misses the image).
    """
    uv = np.asarray(uv, float).reshape(-1, 2)
    depth = np.maximum(np.asarray(depth, float).reshape(-1), 1e-3)
    r = np.maximum(np.asarray(radius, float).reshape(-1), min_radius)
    hx = np.maximum((margin * r + pad_m) * camera.fx / depth + pad_px, min_px / 2)
    hy = np.maximum((margin * r + pad_m) * camera.fy / depth + pad_px, min_px / 2)
    if max_px is not None:
        hx, hy = np.minimum(hx, max_px / 2), np.minimum(hy, max_px / 2)
    x0 = np.clip(uv[:, 0] - hx, 0, camera.width)
    x1 = np.clip(uv[:, 0] + hx, 0, camera.width)
    y0 = np.clip(uv[:, 1] - hy, 0, camera.height)
    y1 = np.clip(uv[:, 1] + hy, 0, camera.height)
    out = np.column_stack([x0, y0, x1 - x0, y1 - y0])
    out[~np.isfinite(out).all(axis=1)] = 0.0
    return out


def compensate(xyz_lidar: np.ndarray, lidar_pose_scan: np.ndarray,
               lidar_pose_image: np.ndarray) -> np.ndarray:
    """Move static points from the lidar frame at scan time to the lidar frame at image time.

    Args:
        xyz_lidar: (N, 3) points measured at the scan time.
        lidar_pose_scan: 4x4 odom <- lidar at the scan time (one, or (N, 4, 4) per point).
        lidar_pose_image: 4x4 odom <- lidar at the image time.

    Returns:
        (N, 3) the same static points seen from the lidar at the image time.
    """
    xyz = np.asarray(xyz_lidar, float).reshape(-1, 3)
    inv_img = invert(lidar_pose_image)
    ps = np.asarray(lidar_pose_scan, float)
    if ps.ndim == 2:
        delta = inv_img @ ps
        return xyz @ delta[:3, :3].T + delta[:3, 3]
    world = np.einsum('nij,nj->ni', ps[:, :3, :3], xyz) + ps[:, :3, 3]
    return world @ inv_img[:3, :3].T + inv_img[:3, 3]


def point_times(xyz_lidar: np.ndarray, stamp_ns: int, rate_hz: float,
                start_azimuth: float = np.pi, clockwise: bool = True) -> np.ndarray:
    """Firing time of each point of a spinning LiDAR whose stamp is the start of the spin.

    A Velodyne-style head turning clockwise seen from above from ``start_azimuth`` (pi: the
    scan starts behind the car) fires azimuth ``a`` at
    ``stamp + ((start - a) mod 2 pi) / (2 pi rate)``: the forward points of a 10 Hz scan are
    50 ms younger than its stamp.

    Returns:
        (N,) int64 nanoseconds.
    """
    xyz = np.asarray(xyz_lidar, float).reshape(-1, 3)
    az = np.arctan2(xyz[:, 1], xyz[:, 0])
    turn = (start_azimuth - az) if clockwise else (az - start_azimuth)
    frac = np.mod(turn, 2 * np.pi) / (2 * np.pi)
    return int(stamp_ns) + np.round(frac / rate_hz * 1e9).astype(np.int64)


@dataclass(frozen=True)
class RoiParams:
    """Crop sizing and timing of :func:`candidates_to_rois`.

    Attributes:
        margin, min_radius, pad_px, min_px, max_px, pad_m: see :func:`crop_boxes`.
        min_depth: camera depth below which a candidate is behind the camera.
        spin_timing: the scan stamp is the start of a spin (see :func:`point_times`), so
            each candidate gets its own firing time; else every candidate has the stamp.
        lidar_rate_hz, start_azimuth, clockwise: spin model for ``spin_timing``.
    """

    margin: float = 1.5
    min_radius: float = 0.6
    pad_px: float = 6.0
    min_px: float = 16.0
    max_px: float = 0.0
    pad_m: float = 0.3
    min_depth: float = 0.5
    spin_timing: bool = True
    lidar_rate_hz: float = 10.0
    start_azimuth: float = float(np.pi)
    clockwise: bool = True


def forward_time_offset(params: 'RoiParams') -> int:
    """Nanoseconds from a scan stamp to when the spin looks forward (+x, the camera axis).

    Half a spin for the default spin model (:func:`point_times`); 0 without ``spin_timing``.
    The projector's ``nearest`` synchroniser matches images against this time.
    """
    if not params.spin_timing:
        return 0
    return int(point_times(np.array([[1.0, 0.0, 0.0]]), 0, params.lidar_rate_hz,
                           params.start_azimuth, params.clockwise)[0])


def candidates_to_rois(cands: np.ndarray, lidar_stamp_ns: int, image_stamp_ns: int,
                       camera: CameraModel, lidar_to_camera: np.ndarray,
                       lidar_pose_at=None, params: RoiParams = RoiParams()):
    """Candidates (``CANDIDATE_DTYPE`` rows) -> ``interfaces.Roi`` list for one image.

    Args:
        cands: structured rows with x, y, z, radius (intensity, count, id optional).
        lidar_stamp_ns: stamp of the candidates' scan.
        image_stamp_ns: stamp of the image.
        camera: intrinsics.
        lidar_to_camera: 4x4 extrinsics.
        lidar_pose_at: ``f(t_ns) -> 4x4 odom <- lidar or None``; None disables compensation.
        params: sizing and timing.

    Returns:
        ``(rois, compensated)``: the ROIs of candidates in front of the camera whose box
        overlaps the image, and whether every one was ego-motion compensated.
    """
    from workzone_ros.interfaces import Box, Roi
    names = cands.dtype.names or ()
    n = cands.shape[0]
    if n == 0:
        return [], lidar_pose_at is not None
    xyz = np.column_stack([cands['x'], cands['y'], cands['z']]).astype(float)
    compensated = False
    if lidar_pose_at is not None:
        t_img = lidar_pose_at(int(image_stamp_ns))
        if params.spin_timing:
            times = point_times(xyz, lidar_stamp_ns, params.lidar_rate_hz,
                                params.start_azimuth, params.clockwise)
        else:
            times = np.full(n, int(lidar_stamp_ns), np.int64)
        poses = [lidar_pose_at(int(t)) for t in times]
        if t_img is not None and all(p is not None for p in poses):
            xyz = compensate(xyz, np.stack(poses), t_img)
            compensated = True
    proj = project_points(xyz, lidar_to_camera, camera, params.min_depth)
    radius = np.asarray(cands['radius'], float)
    boxes = crop_boxes(proj.uv, proj.depth, radius, camera, params.margin, params.min_radius,
                       params.pad_px, params.min_px, params.max_px or None, params.pad_m)
    rois = []
    for i in np.flatnonzero(proj.in_front & np.isfinite(proj.uv).all(axis=1)):
        x, y, w, h = (float(v) for v in boxes[i])
        if w <= 0 or h <= 0:
            continue
        rois.append(Roi(
            candidate_id=int(cands['id'][i]) if 'id' in names else int(i),
            box=Box(x=x, y=y, w=w, h=h),
            center=(float(proj.uv[i, 0]), float(proj.uv[i, 1])),
            range_m=float(np.linalg.norm(proj.xyz_cam[i])),
            radius_m=float(max(radius[i], 0.0)),
            position=tuple(float(v) for v in proj.xyz_cam[i]),
            intensity=float(cands['intensity'][i]) if 'intensity' in names else 0.0,
            points=int(cands['count'][i]) if 'count' in names else 0))
    return rois, compensated
