"""The synthetic camera's lens: an undistorted canvas, its projection and the plumb_bob remap.

The renderer paints on a pinhole canvas a little larger than the image (so the lens can
pull pixels in), then :meth:`Lens.distort` applies the plumb_bob distortion of the
:class:`~workzone_ros.sim.world.CameraModel` with a precomputed ``cv2.remap``: bilinear for
the image, nearest for the label canvas, so ground-truth boxes are measured in the
distorted image.
"""
from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np

from workzone_ros.sim.world import CameraModel

__all__ = ['NEAR_M', 'Lens', 'clip_near']

NEAR_M = 0.3                 # near clipping plane (camera z, metres)


def clip_near(pc: np.ndarray) -> np.ndarray:
    """Clip a convex polygon (N, 3) in camera coordinates against z >= NEAR_M."""
    inside = pc[:, 2] >= NEAR_M
    if inside.all():
        return pc
    if not inside.any():
        return pc[:0]
    out = []
    n = len(pc)
    for i in range(n):
        a, b = pc[i], pc[(i + 1) % n]
        ia, ib = a[2] >= NEAR_M, b[2] >= NEAR_M
        if ia:
            out.append(a)
        if ia != ib:
            u = (NEAR_M - a[2]) / (b[2] - a[2])
            out.append(a + u * (b - a))
    return np.array(out)


def _undistort_normalized(xd: np.ndarray, yd: np.ndarray, D: np.ndarray,
                          iterations: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Invert the plumb_bob model by fixed-point iteration (exact to ~1e-12 for mild lenses)."""
    k1, k2, p1, p2, k3 = (list(D) + [0.0] * 5)[:5]
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        x = (xd - dx) / radial
        y = (yd - dy) / radial
    return x, y


@lru_cache(maxsize=8)
def _lens_maps(cam: CameraModel):
    """Margins of the undistorted canvas and the remap tables distorted <- canvas (static)."""
    W, H = cam.width, cam.height
    uu, vv = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    xn, yn = _undistort_normalized((uu - cam.cx) / cam.fx, (vv - cam.cy) / cam.fy, cam.D)
    ux = xn * cam.fx + cam.cx
    uy = yn * cam.fy + cam.cy
    mx = int(math.ceil(max(-ux.min(), ux.max() - (W - 1), 0))) + 3
    my = int(math.ceil(max(-uy.min(), uy.max() - (H - 1), 0))) + 3
    mx += mx % 2
    my += my % 2
    fx_, fy_ = (ux + mx).astype(np.float32), (uy + my).astype(np.float32)
    map1, map2 = cv2.convertMaps(fx_, fy_, cv2.CV_16SC2)
    # Labels: nearest canvas pixel (rounded, not floored as the fixed-point map would be).
    nn = np.stack([np.round(fx_), np.round(fy_)], -1).astype(np.int16)
    fxy = np.stack([fx_, fy_])          # sign edges: their coverage, sampled as the image is
    for a in (map1, map2, nn, fxy):
        a.flags.writeable = False
    return (mx, my), map1, map2, nn, fxy


class Lens:
    """The undistorted canvas of a camera and the remap from it to the distorted image.

    Attributes:
        camera: the output camera (intrinsics and plumb_bob distortion).
        margin: (mx, my) canvas pixels added on each side of the image.
        canvas_size: (width, height) of the canvas.
        Kc: 3x3 pinhole matrix of the canvas.
        fmap: (2, H, W) float32 canvas coordinates of each image pixel's centre.
    """

    def __init__(self, camera: CameraModel):
        self.camera = camera
        self.margin, self._map1, self._map2, self._nn_map, self.fmap = _lens_maps(camera)
        mx, my = self.margin
        self.canvas_size = (camera.width + 2 * mx, camera.height + 2 * my)
        self.Kc = camera.K.copy()
        self.Kc[0, 2] += mx
        self.Kc[1, 2] += my
        self._f2 = np.array([self.Kc[0, 0], self.Kc[1, 1]])
        self._c2 = np.array([self.Kc[0, 2], self.Kc[1, 2]])

    def proj(self, pc: np.ndarray) -> np.ndarray:
        """Project (N, 3) camera points (z > 0) onto the undistorted canvas."""
        return pc[:, :2] / pc[:, 2:3] * self._f2 + self._c2

    def distort(self, canvas: np.ndarray, label: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distorted image, distorted label image) of a painted canvas and its labels."""
        img = cv2.remap(canvas, self._map1, self._map2, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE)
        lab_img = cv2.remap(label, self._nn_map, None, cv2.INTER_NEAREST,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return img, lab_img
