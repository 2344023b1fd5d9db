"""Synthetic camera: renders the world of sim/world.py into distorted 640x480 BGR frames.

Pipeline per frame (all deterministic in (scene, seed, t, pose, frame_index)):

1. An undistorted canvas a little larger than the image (so the lens can pull pixels in,
   sim/lens.py) gets the sky and ground at half resolution, then the tree lines
   (sim/ground.py).
2. Overpass faces and every scene object in view are painted far to near (painter's
   algorithm, sim/painter.py), sign faces warped from the procedural art.  A label canvas
   records which sign (or distractor) owns each pixel; nearer objects overwrite it, so
   occlusion is exact.
3. The lens: a precomputed ``cv2.remap`` applies the plumb_bob distortion of the
   :class:`~workzone_ros.sim.world.CameraModel` to the image and (nearest) to the labels, so
   ground-truth boxes are measured in the distorted image.
4. Appearance: exposure episodes, white-balance drift, per-weather colour grading, motion
   blur, rain streaks, sun glare, sensor noise and JPEG blocking, all seeded from
   (seed, frame_index) (sim/weather.py).

This module holds the renderer and its ground truth; it re-exports :data:`WEATHER_PRESETS`
and :func:`straight_colour` from the modules that define them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.sim import signart
from workzone_ros.sim.ground import Ground, hash01
from workzone_ros.sim.lens import NEAR_M, Lens
from workzone_ros.sim.painter import ObjectPainter, straight_colour
from workzone_ros.sim.weather import WEATHER_PRESETS, WEATHERS, CameraEffects
from workzone_ros.sim.world import (
    BASE_TO_CAMERA_ROT,
    CAMERA_IN_BASE,
    DEFAULT_CAMERA,
    Box,
    CameraModel,
    Cone,
    Cylinder,
    Pose,
    Quad,
    Scene,
    SignPanel,
)

__all__ = [
    'WEATHER_PRESETS', 'SignHit', 'ObjectHit', 'RenderResult', 'CameraRenderer', 'RenderError',
    'is_distractor', 'straight_colour',
]


class RenderError(ValueError):
    """Bad renderer input (unknown weather preset, ...)."""


@dataclass
class SignHit:
    """A sign face visible in a frame.

    Attributes:
        sign_id: ``SignPanel.object_id``.
        class_key: catalogue key.
        box: (x, y, w, h) of the visible part of the face in the distorted image (pixels).
        distance_m: camera centre to face centre.
        visible_fraction: visible face pixels / face area (occlusion and image border).
    """

    sign_id: int
    class_key: str
    box: tuple[int, int, int, int]
    distance_m: float
    visible_fraction: float


@dataclass
class ObjectHit:
    """A visible hard negative (drum, cone, orange or yellow vehicle)."""

    object_id: int
    kind: str
    box: tuple[int, int, int, int]
    distance_m: float


@dataclass
class RenderResult:
    """One rendered camera frame and its exact ground truth."""

    image: np.ndarray
    signs: list[SignHit] = field(default_factory=list)
    distractors: list[ObjectHit] = field(default_factory=list)
    label: np.ndarray | None = None


def is_distractor(obj) -> bool:
    """True for hard negatives reported in :attr:`RenderResult.distractors`."""
    if isinstance(obj, Cone):
        return True
    if isinstance(obj, Cylinder):
        return 'drum' in obj.kind or obj.material == 'drum_orange'
    if isinstance(obj, Box):
        return obj.material in ('vehicle_orange', 'vehicle_yellow') or \
            obj.rear_material in ('vehicle_orange', 'vehicle_yellow')
    return False


def _bounds(objs: list) -> tuple[np.ndarray, np.ndarray]:
    """Bounding-sphere centres (N, 3) and radii (N,) of world objects."""
    ref = np.zeros((len(objs), 3))
    rad = np.zeros(len(objs))
    for i, o in enumerate(objs):
        if isinstance(o, SignPanel):
            ref[i] = o.center
            rad[i] = 0.5 * math.hypot(o.width, o.height)
        elif isinstance(o, Quad):
            c = np.asarray(o.corners, float)
            ref[i] = c.mean(0)
            rad[i] = np.linalg.norm(c - ref[i], axis=1).max()
        elif isinstance(o, Box):
            ref[i] = np.asarray(o.center, float) + [0, 0, o.height / 2]
            rad[i] = 0.5 * math.sqrt(o.length ** 2 + o.width ** 2 + o.height ** 2)
        else:
            ref[i] = np.asarray(o.base, float) + [0, 0, o.height / 2]
            rad[i] = math.hypot(o.radius, o.height / 2)
    return ref, rad


class CameraRenderer:
    """Renders camera frames of a :class:`~workzone_ros.sim.world.Scene`.

    Args:
        scene: the world to render (read only).
        camera: intrinsics and plumb_bob distortion of the output image.
        seed: appearance seed (noise, exposure episodes, ...); geometry comes from ``scene``.

    Raises:
        RenderError: the scene's weather is not one of :data:`WEATHER_PRESETS`.
    """

    def __init__(self, scene: Scene, camera: CameraModel = DEFAULT_CAMERA, seed: int = 0):
        if scene.weather not in WEATHERS:
            raise RenderError(f'unknown weather {scene.weather!r}; known: {WEATHER_PRESETS}')
        self.scene = scene
        self.camera = camera
        self.seed = int(seed)
        self.weather = WEATHERS[scene.weather]
        self._base_seed = (abs(self.seed), abs(int(scene.seed)))
        self.lens = Lens(camera)
        self.ground = Ground(scene, self.weather, self.lens, self._base_seed)
        self.effects = CameraEffects(self.weather, camera.width, camera.height,
                                     self._base_seed)
        self.painter = ObjectPainter(self.lens, self.weather, scene.seed)
        # Bounding spheres of everything that does not move, for per-frame view culling.
        self._static = list(scene.signs) + [o for o in scene.objects
                                            if not (isinstance(o, Box) and o.speed)]
        self._static_ref, self._static_rad = _bounds(self._static)
        self._tan = (1.25 * max(camera.cx, camera.width - camera.cx) / camera.fx,
                     1.25 * max(camera.cy, camera.height - camera.cy) / camera.fy)

    def _camera_pose(self, base_pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """World position of the camera and the world -> camera rotation."""
        pos = base_pose.to_world(CAMERA_IN_BASE)
        R_wb = base_pose.R
        R_cw = BASE_TO_CAMERA_ROT @ R_wb.T
        return pos, R_cw

    def _in_view(self, t: float, cam_pos, R_cw, s_cam: float) -> tuple[list, list]:
        """Painter's list, far first, and the ground-truth entries of what is in view.

        Returns:
            ``(items, entries)``: items are (sort key, distance, kind, object, label index);
            entries are (kind, object, distance), label index i - 1.
        """
        items = []
        entries: list[tuple[str, object, float]] = []
        moving = [o for o in self.scene.objects_at(t) if isinstance(o, Box) and o.speed]
        cands = [(self._static, self._static_ref, self._static_rad)]
        dyn = moving + self.ground.overpass_quads(s_cam)
        if dyn:
            ref, rad = _bounds(dyn)
            cands.append((dyn, ref, rad))
        for objs, ref, rad in cands:
            if not objs:
                continue
            pc = (ref - cam_pos) @ R_cw.T
            dist_all = np.linalg.norm(ref - cam_pos, axis=1)
            z = pc[:, 2]
            keep = (z > NEAR_M - rad) & (dist_all < 900.0 + rad) & \
                (np.abs(pc[:, 0]) < z * self._tan[0] + rad) & \
                (np.abs(pc[:, 1]) < z * self._tan[1] + rad)
            for i in np.nonzero(keep)[0]:
                o = objs[i]
                dist = float(dist_all[i])
                lab = 0
                if isinstance(o, SignPanel):
                    entries.append(('sign', o, dist))
                    items.append((dist, dist, 'sign', o, len(entries)))
                    continue
                if is_distractor(o):
                    entries.append(('obj', o, dist))
                    lab = len(entries)
                # posts and portable stands (mast, legs, flags) stand behind their face
                post = (isinstance(o, Cylinder) and 'post' in (o.kind + o.material)) or \
                    str(getattr(o, 'kind', '')).startswith('stand')
                items.append((dist + (0.5 if post else 0.0), dist, 'obj', o, lab))
        items.sort(key=lambda it: -it[0])
        return items, entries

    def render(self, t: float, base_pose: Pose, frame_index: int) -> RenderResult:
        """Render one frame.

        Args:
            t: scene time in seconds (moves vehicles).
            base_pose: the ego base_link pose in the world.
            frame_index: frame counter; seeds the per-frame appearance with ``seed``.

        Returns:
            The distorted BGR image, visible signs and distractors with boxes of their visible
            parts, and the per-pixel sign label (sign object_id or -1).
        """
        rng = np.random.default_rng(list(self._base_seed) + [abs(int(frame_index)), 1])
        cam_pos, R_cw = self._camera_pose(base_pose)
        s_cam, _ = self.scene.road.to_frenet(np.array([cam_pos[0]]), np.array([cam_pos[1]]))
        s_cam = float(s_cam[0])
        Wc, Hc = self.lens.canvas_size
        bg = self.ground.background(cam_pos, R_cw, s_cam, rng)
        canvas = cv2.resize(np.clip(bg, 0, 255).astype(np.uint8), (Wc, Hc),
                            interpolation=cv2.INTER_LINEAR)
        label = np.zeros((Hc, Wc), np.uint16)
        self.ground.tree_walls(canvas, label, cam_pos, R_cw, s_cam)

        items, entries = self._in_view(t, cam_pos, R_cw, s_cam)
        faces = []
        for _, dist, what, o, lab in items:
            if what == 'sign':
                face = self.painter.draw_sign(canvas, label, o, cam_pos, R_cw, dist, lab)
                if face is not None:
                    faces.append(face)
            else:
                self.painter.draw_object(canvas, label, o, cam_pos, R_cw, dist, lab)

        img, lab_img = self.lens.distort(canvas, label)
        self.painter.sign_edges(lab_img, label, faces)
        sign_hits, obj_hits, lut = self._ground_truth(entries, lab_img, cam_pos, R_cw)
        out_label = lut[lab_img]

        sun_uv = self._sun_uv(cam_pos, R_cw) if self.weather.sun else None
        img = self.effects.apply(img, int(frame_index), rng, sun_uv)
        return RenderResult(image=img, signs=sign_hits, distractors=obj_hits, label=out_label)

    def _sun_uv(self, cam_pos, R_cw):
        az = hash01(np.array([self.scene.seed]), 5)[0] * 1.2 - 0.6
        el = 0.35
        h0 = float(self.scene.road.heading[0])
        d = np.array([math.cos(h0 + az) * math.cos(el), math.sin(h0 + az) * math.cos(el),
                      math.sin(el)])
        pc = R_cw @ d
        if pc[2] <= 0.05:
            return None
        pts, _ = cv2.projectPoints(pc.reshape(1, 1, 3), np.zeros(3), np.zeros(3),
                                   self.camera.K, self.camera.D)
        return tuple(pts.reshape(2))

    def _ground_truth(self, entries, lab_img, cam_pos, R_cw):
        """Boxes and visible fractions from the distorted label image (one pass)."""
        n = len(entries) + 1
        lut = np.full(n, -1, np.int32)
        ys, xs = np.nonzero(lab_img)
        vals = lab_img[ys, xs]
        present = np.bincount(vals, minlength=n)
        big = np.iinfo(np.int64).max
        x0 = np.full(n, big)
        y0 = np.full(n, big)
        x1 = np.full(n, -1)
        y1 = np.full(n, -1)
        np.minimum.at(x0, vals, xs)
        np.minimum.at(y0, vals, ys)
        np.maximum.at(x1, vals, xs)
        np.maximum.at(y1, vals, ys)
        sign_hits: list[SignHit] = []
        obj_hits: list[ObjectHit] = []
        for i, (what, o, dist) in enumerate(entries, start=1):
            if present[i] == 0:
                continue
            box = (int(x0[i]), int(y0[i]), int(x1[i] - x0[i] + 1), int(y1[i] - y0[i] + 1))
            if what == 'sign':
                lut[i] = o.object_id
                area = self._face_area(o, cam_pos, R_cw)
                vis = float(min(1.0, present[i] / area)) if area > 0 else 0.0
                sign_hits.append(SignHit(o.object_id, o.class_key, box, dist, vis))
            else:
                obj_hits.append(ObjectHit(o.object_id, o.kind, box, dist))
        return sign_hits, obj_hits, lut

    def _face_area(self, sp: SignPanel, cam_pos, R_cw) -> float:
        """Area in pixels of the whole face in the distorted image (unclipped by borders)."""
        c = catalogue.get(sp.class_key)
        ol = signart.outline(c.shape, 1.0, 1.0)
        # Densify the outline so the distortion bends its edges.
        n = len(ol)
        u = np.linspace(0, 1, 6, endpoint=False)[:, None]
        dense = np.vstack([ol[i] + u * (ol[(i + 1) % n] - ol[i]) for i in range(n)])
        corners = sp.corners()
        pw = corners[0] + dense[:, :1] * (corners[1] - corners[0]) + \
            dense[:, 1:] * (corners[3] - corners[0])
        pc = (pw - cam_pos) @ R_cw.T
        if (pc[:, 2] < NEAR_M).any():
            return float(np.inf)
        pts, _ = cv2.projectPoints(pc.reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                                   self.camera.K, self.camera.D)
        return float(cv2.contourArea(pts.reshape(-1, 2).astype(np.float32)))
