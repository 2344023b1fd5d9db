"""Camera ROIs sized by the LiDAR cluster they come from.

:func:`workzone_ros.core.projection.crop_boxes` sizes a crop from the candidate's radius with
a minimum radius of 0.6 m and a margin of 1.5: a 0.6 m sign gets a crop four times its
width.  ``lidar_cluster`` now measures each cluster (``half_w``: half its width across the
line of sight, ``half_h``: half its height, each plus one beam spacing at its range -- where
the face may extend between and beyond the rings that hit it; ``dz``: how far above the
candidate the box centre lies when the face is cut by the top of the sensor's field of
view) and publishes 0 when it cannot (a cluster on a single ring).  :func:`size_rois`
gives measured candidates a crop of their size plus a margin in metres (calibration and
synchronisation error) and in pixels; the others keep the radius-based crop and its
minimum, the only place a minimum is needed.

No rclpy here.
"""
from __future__ import annotations

from typing import Sequence

import msgspec
import numpy as np

__all__ = ['extent_boxes', 'size_rois']


def extent_boxes(uv: np.ndarray, depth: np.ndarray, half_w: np.ndarray, half_h: np.ndarray,
                 fx: float, fy: float, width: int, height: int, pad_m: float = 0.15,
                 pad_px: float = 6.0, min_px: float = 16.0) -> np.ndarray:
    """Boxes ``x, y, w, h`` of the measured half sizes around projected centres.

    ``half = (half_m + pad_m) * f / depth + pad_px`` (at least ``min_px / 2``), clipped to
    the image.

    Args:
        uv: (N, 2) projected centres, pixels.
        depth: (N,) camera z, metres.
        half_w, half_h: (N,) measured half width / height, metres.
        fx, fy: focal lengths, pixels.
        width, height: image size.
        pad_m, pad_px, min_px: margins.
    """
    uv = np.asarray(uv, float).reshape(-1, 2)
    d = np.maximum(np.asarray(depth, float).reshape(-1), 1e-3)
    hx = np.maximum((np.asarray(half_w, float) + pad_m) * fx / d + pad_px, min_px / 2)
    hy = np.maximum((np.asarray(half_h, float) + pad_m) * fy / d + pad_px, min_px / 2)
    x0, x1 = np.clip(uv[:, 0] - hx, 0, width), np.clip(uv[:, 0] + hx, 0, width)
    y0, y1 = np.clip(uv[:, 1] - hy, 0, height), np.clip(uv[:, 1] + hy, 0, height)
    return np.column_stack([x0, y0, x1 - x0, y1 - y0])


def size_rois(rois: Sequence, cands: np.ndarray, camera, pad_m: float = 0.15,
              pad_px: float = 6.0, min_px: float = 16.0) -> list:
    """The ROIs of :func:`~workzone_ros.core.projection.candidates_to_rois`, each measured
    candidate's box replaced by its own size.

    Args:
        rois: ``interfaces.Roi`` list (``candidate_id``, ``center``, ``position``).
        cands: the candidate rows they came from (``id``, and ``half_w`` / ``half_h`` / ``dz``
            when the publisher measured them; without those fields the ROIs are returned
            unchanged).  ``dz`` moves the box up the image (a camera without roll).
        camera: :class:`~workzone_ros.core.projection.CameraModel` (focal lengths, size).
        pad_m, pad_px, min_px: margins (see :func:`extent_boxes`).

    Returns:
        A new list; ROIs of unmeasured candidates (``half_w`` or ``half_h`` 0) are kept.
    """
    names = cands.dtype.names or ()
    if not rois or 'half_w' not in names or 'half_h' not in names:
        return list(rois)
    from workzone_ros.interfaces import Box
    by_id = {int(i): k for k, i in enumerate(cands['id'])} if 'id' in names else {}
    out = []
    for r in rois:
        k = by_id.get(int(r.candidate_id), int(r.candidate_id))
        hw, hh = float(cands['half_w'][k]), float(cands['half_h'][k])
        dz = float(cands['dz'][k]) if 'dz' in names else 0.0
        if hw <= 0 or hh <= 0:
            out.append(r)
            continue
        depth = max(float(r.position[2]), 1e-3)
        uv = np.array([[r.center[0], r.center[1] - dz * camera.fy / depth]])   # up: -v
        b = extent_boxes(uv, np.array([depth]), np.array([hw]), np.array([hh]), camera.fx,
                         camera.fy, camera.width, camera.height, pad_m, pad_px, min_px)[0]
        if b[2] <= 0 or b[3] <= 0:
            out.append(r)
            continue
        out.append(msgspec.structs.replace(r, box=Box(x=float(b[0]), y=float(b[1]), w=float(b[2]),
                                      h=float(b[3]))))
    return out
