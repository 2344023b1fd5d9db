"""How far a classified sign is: the LiDAR range of its ROI, else its apparent size.

The fusion decides when the vehicle *reaches* a sign (a work zone begins at the begin sign,
not where that sign is first seen), so every published sign carries a distance estimate:

* ``lidar``: the range of the LiDAR ROI (``Roi.range_m``) of the same image that covers the
  sign's box best (the sign's centre inside the ROI box, nearest ROI centre first);
* ``size``: the pinhole relation ``distance = f_y * H / h``, with ``h`` the box height in
  pixels, ``f_y`` the camera's focal length (CameraInfo ``K[1,1]``, or one derived from a
  stated field of view) and ``H`` the height of the class's standard face (a diamond's box is
  its side times sqrt(2));
* ``none``: neither applies (an unknown class, an empty box).

No rclpy import.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

from workzone_ros.core import signs as catalogue
from workzone_ros.interfaces import Box, Roi

__all__ = ['face_box_height_m', 'focal_from_fov', 'distance_from_size', 'distance_from_rois',
           'estimate_distance']


def face_box_height_m(class_key: str) -> Optional[float]:
    """Height in metres of the image box of a standard face of ``class_key`` (None: unknown).

    Diamonds are squares turned by 45 degrees: their box is the side times sqrt(2).
    """
    c = catalogue.BY_KEY.get(class_key)
    if c is None or c.height_m <= 0:
        return None
    return c.height_m * math.sqrt(2.0) if c.shape == 'diamond' else c.height_m


def focal_from_fov(width_px: int, hfov_deg: float) -> float:
    """Focal length in pixels of a camera ``width_px`` wide with horizontal field ``hfov_deg``.

    Raises:
        ValueError: a field of view outside (0, 180) degrees or a non-positive width.
    """
    if not 0.0 < hfov_deg < 180.0 or width_px <= 0:
        raise ValueError(f'cannot derive a focal length from width {width_px} px and field '
                         f'of view {hfov_deg} deg')
    return width_px / 2.0 / math.tan(math.radians(hfov_deg) / 2.0)


def distance_from_size(box: Box, class_key: str, focal_px: float) -> Optional[float]:
    """Pinhole distance (m) of a sign of ``class_key`` whose box is ``box``; None if unknown."""
    height = face_box_height_m(class_key)
    if height is None or box.h <= 0 or focal_px <= 0:
        return None
    return focal_px * height / box.h


def distance_from_rois(box: Box, rois: Sequence[Roi]) -> Optional[float]:
    """Range (m) of the ROI that contains the box's centre (nearest ROI centre first)."""
    cx, cy = box.x + box.w / 2.0, box.y + box.h / 2.0
    best, best_d2 = None, math.inf
    for roi in rois:
        b = roi.box
        if not (b.x <= cx <= b.x2 and b.y <= cy <= b.y2):
            continue
        d2 = (roi.center[0] - cx) ** 2 + (roi.center[1] - cy) ** 2
        if d2 < best_d2:
            best, best_d2 = roi, d2
    return None if best is None else float(best.range_m)


def estimate_distance(box: Box, class_key: str, focal_px: Optional[float],
                      rois: Sequence[Roi] = ()) -> tuple[Optional[float], str]:
    """``(distance_m, source)``: LiDAR range first, else apparent size, else ``(None, 'none')``."""
    d = distance_from_rois(box, rois)
    if d is not None:
        return d, 'lidar'
    if focal_px is not None:
        d = distance_from_size(box, class_key, focal_px)
        if d is not None:
            return d, 'size'
    return None, 'none'
