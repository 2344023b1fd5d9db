"""Painting scene objects onto the synthetic camera's canvas, far to near.

Box faces and quads are filled with ``cv2.fillConvexPoly`` after clipping against the near
plane, cylinders and cones as projected convex silhouettes with their bands, sign faces
warped from the procedural art (sim/signart.py) by the plane homography on their bounding
ROI only and alpha-blended, each sign in its own orange
(:func:`~workzone_ros.sim.signart.sheeting_orange` of its id and the scene seed).  A label
canvas records which sign (or distractor) owns each pixel; nearer objects overwrite it, so
occlusion is exact, and :meth:`ObjectPainter.sign_edges` labels sign edges as the lens
samples them.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.sim import signart
from workzone_ros.sim.lens import NEAR_M, Lens, clip_near
from workzone_ros.sim.weather import FLUORESCENT_SAT, Weather
from workzone_ros.sim.world import MATERIALS, Box, Cone, Cylinder, Quad, SignPanel

__all__ = ['ART_SIZES', 'ObjectPainter', 'straight_colour']

ART_SIZES = (32, 48, 64, 96, 128, 192, 256, 384)


def straight_colour(bgra: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(colour (H, W, 3) float32, alpha (H, W) in [0, 1]) of premultiplied BGRA art.

    Sign art is drawn anti-aliased over black (:func:`~workzone_ros.sim.signart.sign_face`):
    a pixel the face covers in part holds the face's colour times its coverage, and it is
    warped so (interpolating premultiplied colour is what keeps black out of the edge).  Its
    own colour is that over its alpha; compositing the premultiplied colour by alpha again
    ringed every sign with a dark fringe half a pixel wide.
    """
    alpha = bgra[..., 3].astype(np.float32) * (1.0 / 255.0)
    rgb = bgra[..., :3].astype(np.float32) / np.maximum(alpha, 1.0 / 255.0)[..., None]
    return np.minimum(rgb, 255.0), alpha


class ObjectPainter:
    """Paints world objects onto a canvas and its label canvas.

    Args:
        lens: the canvas (projection, size).
        weather: the scene's weather (haze, sign brightness).
        scene_seed: the scene's seed (each sign's orange).
    """

    def __init__(self, lens: Lens, weather: Weather, scene_seed: int):
        self.lens = lens
        self.weather = weather
        self.scene_seed = scene_seed

    def draw_object(self, canvas, label, o, cam_pos, R_cw, dist: float, lab: int) -> None:
        """Paint a quad, box, cylinder or cone (its label ``lab``, 0 for none) in place."""
        if isinstance(o, Quad):
            self._draw_quad(canvas, label, o, cam_pos, R_cw, dist, lab)
        elif isinstance(o, Box):
            self._draw_box(canvas, label, o, cam_pos, R_cw, dist, lab)
        elif isinstance(o, (Cylinder, Cone)):
            self._draw_cyl(canvas, label, o, cam_pos, R_cw, dist, lab)

    def _fill(self, canvas, label, pc, colour, lab: int) -> bool:
        q = clip_near(pc)
        if len(q) < 3:
            return False
        uv = np.round(self.lens.proj(q) * 16).astype(np.int32)
        cv2.fillConvexPoly(canvas, uv, colour, cv2.LINE_AA, 4)
        cv2.fillConvexPoly(label, uv, lab, cv2.LINE_8, 4)
        return True

    def _draw_quad(self, canvas, label, q: Quad, cam_pos, R_cw, dist, lab: int) -> None:
        c = np.asarray(q.corners, float)
        pc = (c - cam_pos) @ R_cw.T
        # Facing test without np.cross: in camera coordinates the projected winding tells.
        a, b = pc[1] - pc[0], pc[2] - pc[0]
        nz = (a[1] * b[2] - a[2] * b[1]) * pc[0, 0] + (a[2] * b[0] - a[0] * b[2]) * pc[0, 1] + \
            (a[0] * b[1] - a[1] * b[0]) * pc[0, 2]
        shade = 0.95 if nz <= 0 else 0.8
        col = self.weather.haze(np.array(MATERIALS[q.material].bgr, float) * shade, dist)
        self._fill(canvas, label, pc, col, lab)
        if q.kind == 'guardrail' and dist < 80.0:
            # Darker lower edge and a mid-height groove of the W-beam.
            c = np.asarray(q.corners, float)
            for a, b, f in ((0.0, 0.25, 0.7), (0.45, 0.55, 0.8)):
                strip = np.array([c[0] + (c[3] - c[0]) * (1 - a), c[1] + (c[2] - c[1]) * (1 - a),
                                  c[1] + (c[2] - c[1]) * (1 - b), c[0] + (c[3] - c[0]) * (1 - b)])
                col2 = self.weather.haze(np.array(MATERIALS[q.material].bgr, float) * shade * f,
                                         dist)
                self._fill(canvas, label, (strip - cam_pos) @ R_cw.T, col2, lab)

    def _silhouette(self, canvas, label, pts_w, cam_pos, R_cw, colour, lab: int) -> None:
        pc = (pts_w - cam_pos) @ R_cw.T
        if (pc[:, 2] < NEAR_M).any():
            return
        uv = self.lens.proj(pc)
        hull = cv2.convexHull(np.round(uv * 16).astype(np.int32))
        cv2.fillConvexPoly(canvas, hull, colour, cv2.LINE_AA, 4)
        cv2.fillConvexPoly(label, hull, lab, cv2.LINE_8, 4)

    _RING = np.stack([np.cos(np.linspace(0, 2 * np.pi, 12, endpoint=False)),
                      np.sin(np.linspace(0, 2 * np.pi, 12, endpoint=False))], -1)

    def _ring(self, base, r, z) -> np.ndarray:
        return np.column_stack([base[0] + r * self._RING[:, 0], base[1] + r * self._RING[:, 1],
                                np.full(len(self._RING), base[2] + z)])

    def _draw_cyl(self, canvas, label, o, cam_pos, R_cw, dist, lab: int) -> None:
        base = np.asarray(o.base, float)
        cone = isinstance(o, Cone)

        def rad(z):
            return o.radius * (1 - z / o.height) * 0.85 + o.radius * 0.15 if cone else o.radius

        def section(z0, z1, mat, f=1.0):
            if cone and z1 >= o.height - 1e-6:
                pts = np.vstack([self._ring(base, rad(z0), z0), base + [0, 0, o.height]])
            else:
                pts = np.vstack([self._ring(base, rad(z0), z0), self._ring(base, rad(z1), z1)])
            col = self.weather.haze(np.array(MATERIALS[mat].bgr, float) * f, dist)
            self._silhouette(canvas, label, pts, cam_pos, R_cw, col, lab)

        section(0.0, o.height, o.material)
        if cone:
            section(0.0, 0.04, 'vehicle_paint', 0.3)      # black rubber base
        for z0, z1, mat in o.bands:
            section(z0, z1, mat)

    def _draw_box(self, canvas, label, b: Box, cam_pos, R_cw, dist, lab: int) -> None:
        c = np.asarray(b.center, float)
        f = np.array([math.cos(b.yaw), math.sin(b.yaw), 0.0])
        lft = np.array([-f[1], f[0], 0.0])
        up = np.array([0.0, 0.0, 1.0])
        L, Wd, H = b.length / 2, b.width / 2, b.height
        body = np.array(MATERIALS[b.material].bgr, float)
        rear = np.array(MATERIALS[b.rear_material or b.material].bgr, float)

        def P(a, bb, z):
            return c + a * L * f + bb * Wd * lft + z * up

        faces = [  # (normal, corners, colour, shade)
            (-f, [P(-1, 1, H), P(-1, -1, H), P(-1, -1, 0.25), P(-1, 1, 0.25)], rear, 0.92),
            (f, [P(1, -1, H), P(1, 1, H), P(1, 1, 0.25), P(1, -1, 0.25)], body, 0.92),
            (lft, [P(1, 1, H), P(-1, 1, H), P(-1, 1, 0.25), P(1, 1, 0.25)], body, 0.78),
            (-lft, [P(-1, -1, H), P(1, -1, H), P(1, -1, 0.25), P(-1, -1, 0.25)], body, 0.78),
            (up, [P(-1, 1, H), P(1, 1, H), P(1, -1, H), P(-1, -1, H)], body, 1.08),
        ]
        # Wheels / dark underbody band.
        under = np.array(MATERIALS['glass'].bgr, float) * 0.5
        for n, pts, col, sh in faces:
            pts = np.array(pts)
            if np.dot(n, cam_pos - pts.mean(0)) <= 0:
                continue
            pc = (pts - cam_pos) @ R_cw.T
            self._fill(canvas, label, pc, self.weather.haze(col * sh, dist), lab)
            if n[2] == 0:
                low = np.array([pts[3], pts[2], pts[2] - 0.25 * up, pts[3] - 0.25 * up])
                self._fill(canvas, label, (low - cam_pos) @ R_cw.T,
                           self.weather.haze(under, dist), lab)
        if np.dot(-f, cam_pos - (c - L * f)) > 0:
            r0 = c - L * f - 0.01 * f
            truck = 'truck' in b.kind
            details = []
            if not truck:
                details.append((0.75, 0.2, 0.68 * H, 0.92 * H, 'glass'))   # rear window
            if b.plate:
                details.append((0.0, 0.27, 0.45, 0.75, 'plate'))
            details += [(-0.8, 0.1, 0.55, 0.75, 'tail_reflector'),
                        (0.8, 0.1, 0.55, 0.75, 'tail_reflector')]
            for xc, half, z0, z1, mat in details:
                if mat == 'glass':
                    a0, a1 = -xc * Wd, xc * Wd
                else:
                    a0, a1 = (xc - half) * Wd if mat == 'tail_reflector' else -half, \
                        (xc + half) * Wd if mat == 'tail_reflector' else half
                pts = np.array([r0 + a0 * lft + z1 * up, r0 + a1 * lft + z1 * up,
                                r0 + a1 * lft + z0 * up, r0 + a0 * lft + z0 * up])
                self._fill(canvas, label, (pts - cam_pos) @ R_cw.T,
                           self.weather.haze(np.array(MATERIALS[mat].bgr, float), dist), lab)

    def draw_sign(self, canvas, label, sp: SignPanel, cam_pos, R_cw, dist,
                  lab: int) -> 'tuple | None':
        """Paint one sign face; returns ``(lab, x0, y0, alpha, label ROI after painting)``
        for :meth:`sign_edges`, or None when nothing of its face was painted."""
        corners = sp.corners()
        pc = (corners - cam_pos) @ R_cw.T
        c = catalogue.get(sp.class_key)
        front = np.dot(sp.normal, cam_pos - np.asarray(sp.center, float)) > 0
        if not front:
            # Back of the sign: grey, in the face's outline.
            ol = signart.outline(c.shape, 1.0, 1.0)
            pw = corners[0] + ol[:, :1] * (corners[1] - corners[0]) + \
                ol[:, 1:] * (corners[3] - corners[0])
            col = self.weather.haze(np.array(MATERIALS['sign_back'].bgr, float), dist)
            self._fill(canvas, label, (pw - cam_pos) @ R_cw.T, col, 0)
            return None
        q = clip_near(pc)
        if len(q) < 3:
            return None
        uv = self.lens.proj(q)
        Wc, Hc = self.lens.canvas_size
        x0 = max(int(math.floor(uv[:, 0].min())) - 1, 0)
        y0 = max(int(math.floor(uv[:, 1].min())) - 1, 0)
        x1 = min(int(math.ceil(uv[:, 0].max())) + 2, Wc)
        y1 = min(int(math.ceil(uv[:, 1].max())) + 2, Hc)
        if x1 <= x0 or y1 <= y0:
            return None
        # Art resolution ~1.5x the projected size (limits aliasing of the warp).
        extent = max(uv[:, 0].max() - uv[:, 0].min(), uv[:, 1].max() - uv[:, 1].min())
        size = next((a for a in ART_SIZES if a >= 1.5 * extent), ART_SIZES[-1])
        variant = signart.OTHER_VARIANTS[sp.object_id % len(signart.OTHER_VARIANTS)] \
            if sp.class_key == 'other_workzone' else None
        orange = signart.sheeting_orange(sp.object_id, self.scene_seed) \
            if signart.uses_orange(sp.class_key) else None
        art = signart.sign_face(sp.class_key, size, sp.speed_value, variant, orange)
        ah, aw = art.shape[:2]
        ex = R_cw @ (corners[1] - corners[0]) / aw
        ey = R_cw @ (corners[3] - corners[0]) / ah
        o = R_cw @ (corners[0] - cam_pos) + 0.5 * (ex + ey)
        Hm = self.lens.Kc @ np.column_stack([ex, ey, o])
        T = np.array([[1.0, 0, -x0], [0, 1.0, -y0], [0, 0, 1.0]])
        warped = cv2.warpPerspective(art, T @ Hm, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        rgb, alpha = straight_colour(warped)
        if len(q) != 4 or not (pc[:, 2] >= NEAR_M).all():
            m = np.zeros(alpha.shape, np.uint8)
            cv2.fillConvexPoly(m, np.round((uv - [x0, y0]) * 16).astype(np.int32), 1,
                               cv2.LINE_8, 4)
            alpha *= m
        if sp.fade > 0:
            grey = rgb.mean(-1, keepdims=True)
            pale = grey * 0.45 + 130.0
            fd = float(np.clip(sp.fade, 0.0, 1.0)) * 0.75
            rgb = rgb * (1 - fd) + pale * fd
        w = self.weather
        if orange is not None and w.saturation < FLUORESCENT_SAT:
            # Fluorescent orange sheeting keeps its colour under a grey sky (fluorescence
            # turns the diffuse daylight's blue into orange): pre-saturate so that after the
            # frame's grading it keeps at least FLUORESCENT_SAT of its saturation.
            k = FLUORESCENT_SAT / w.saturation
            lum = rgb @ np.array([0.114, 0.587, 0.299], np.float32)
            rgb = lum[..., None] + (rgb - lum[..., None]) * k
        # Retroreflective sheeting: less haze than the scene, its own brightness.
        f = 1.0 - math.exp(-dist / (1.6 * w.haze_m))
        hor = np.array(w.sky_horizon, np.float32) * w.light
        rgb = rgb * (w.sign_light * (1 - f)) + hor * f
        roi = canvas[y0:y1, x0:x1]
        a3 = alpha[..., None]
        roi[:] = np.clip(roi * (1 - a3) + rgb * a3, 0, 255).astype(np.uint8)
        lroi = label[y0:y1, x0:x1]
        lroi[alpha > 0.5] = lab
        return lab, x0, y0, alpha, lroi.copy()

    def sign_edges(self, lab_img: np.ndarray, label: np.ndarray, faces: list) -> None:
        """Label each sign's edge pixels as the image samples them, in place.

        The label canvas holds, per canvas pixel, whether the sign covers more than half of
        it; the lens then takes each image pixel's label from the *nearest* canvas pixel, a
        second rounding: on about a quarter of a straight edge's rows the label is a pixel
        off where the image's edge (bilinearly resampled) is right to 0.1 px.  Here a sign's
        pixel is one whose centre, mapped into the canvas, has the sign's coverage (its
        alpha, bilinearly sampled as the image is) above one half, so the label marks the
        pixels the image shows more than half covered by the face.  Canvas pixels that a
        nearer object painted over after the sign (their label changed since) count as not
        covered, and an image pixel whose nearest canvas pixel was painted over keeps that
        object's label.

        Args:
            lab_img: the distorted label image (nearest canvas pixel), changed in place.
            label: the canvas label after every object is painted.
            faces: :meth:`draw_sign`'s records, in painting order.
        """
        H, W = lab_img.shape
        for lab, x0, y0, alpha, after in faces:
            h, w = alpha.shape
            now = label[y0:y0 + h, x0:x0 + w]
            kept = now == after                  # not painted over by a nearer object
            ys, xs = np.nonzero(lab_img == lab)
            if ys.size == 0:
                continue
            r0, r1 = max(int(ys.min()) - 2, 0), min(int(ys.max()) + 3, H)
            c0, c1 = max(int(xs.min()) - 2, 0), min(int(xs.max()) + 3, W)
            mx = self.lens.fmap[0, r0:r1, c0:c1] - np.float32(x0)
            my = self.lens.fmap[1, r0:r1, c0:c1] - np.float32(y0)
            cover = cv2.remap(np.where(kept, alpha, 0.0).astype(np.float32), mx, my,
                              cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            ix, iy = np.round(mx).astype(np.int64), np.round(my).astype(np.int64)
            inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
            nn_kept = np.zeros(ix.shape, bool)
            nn_kept[inside] = kept[iy[inside], ix[inside]]
            roi = lab_img[r0:r1, c0:c1]
            on = roi == lab
            gain = (cover > 0.5) & ~on & nn_kept
            roi[gain] = lab
            for r, c in zip(*np.nonzero(on & (cover <= 0.5))):
                # what the pixel shows instead: the nearest of its four canvas neighbours
                # that is not this sign's
                fx, fy = float(mx[r, c]) + x0, float(my[r, c]) + y0
                best = None
                for cy in (math.floor(fy), math.floor(fy) + 1):
                    for cx in (math.floor(fx), math.floor(fx) + 1):
                        if 0 <= cy < label.shape[0] and 0 <= cx < label.shape[1] and \
                                label[cy, cx] != lab:
                            d = (cx - fx) ** 2 + (cy - fy) ** 2
                            if best is None or d < best[0]:
                                best = (d, label[cy, cx])
                if best is not None:
                    roi[r, c] = best[1]

