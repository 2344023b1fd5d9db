"""Synthetic camera: renders the world of sim/world.py into distorted 640x480 BGR frames.

Pipeline per frame (all deterministic in (scene, seed, t, pose, frame_index)):

1. An undistorted canvas a little larger than the image (so the lens can pull pixels in)
   gets the background at half resolution: sky gradient, ground plane (asphalt lanes,
   dashed and solid lane lines, shoulders, grass or snow, overpass shadows, wet sheen) from
   the Frenet coordinates of every ground pixel, then haze.
2. Tree walls, overpass faces and every scene object are painted far to near (painter's
   algorithm): box faces and quads with ``cv2.fillConvexPoly`` after clipping against the
   near plane, cylinders and cones as projected convex silhouettes with their bands, sign
   faces warped from the procedural art (sim/signart.py) by the plane homography on their
   bounding ROI only and alpha-blended, each sign in its own orange
   (:func:`~workzone_ros.sim.signart.sheeting_orange` of its id and the scene seed).  A
   label canvas records which sign (or distractor) owns each pixel; nearer objects overwrite
   it, so occlusion is exact.
3. The lens: a precomputed ``cv2.remap`` applies the plumb_bob distortion of the
   :class:`~workzone_ros.sim.world.CameraModel` to the image and (nearest) to the labels, so
   ground-truth boxes are measured in the distorted image.
4. Appearance: exposure episodes, white-balance drift, per-weather colour grading, motion
   blur, rain streaks, sun glare, sensor noise and JPEG blocking, all seeded from
   (seed, frame_index).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.sim import signart
from workzone_ros.sim.world import (
    BASE_TO_CAMERA_ROT,
    CAMERA_IN_BASE,
    DEFAULT_CAMERA,
    LEFT_SHOULDER,
    MATERIALS,
    RIGHT_SHOULDER,
    ROAD_HALF_WIDTH,
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
    'is_distractor',
]

WEATHER_PRESETS = ('winter_overcast', 'spring_sunny', 'spring_rain', 'dusk')
NEAR_M = 0.3                 # near clipping plane (camera z, metres)
FAR_M = 1500.0               # ground beyond this is horizon haze
_ART_SIZES = (32, 48, 64, 96, 128, 192, 256, 384)
_TREE_RIGHT = -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 22.0)    # tree-line lateral offsets (m)
_TREE_LEFT = ROAD_HALF_WIDTH + LEFT_SHOULDER + 18.0


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


@dataclass(frozen=True)
class _Weather:
    sky_top: tuple[float, float, float]
    sky_horizon: tuple[float, float, float]
    haze_m: float                  # visibility scale of the exponential haze
    light: float                   # scene brightness factor
    sign_light: float              # sign sheeting brightness (retroreflection)
    contrast: float
    saturation: float
    cast: tuple[float, float, float]   # BGR gains
    noise: float                   # sensor noise sigma (8-bit units)
    shadow: float                  # overpass shadow darkness factor
    wet: float                     # road sky reflection
    asphalt_gain: float
    snow: bool = False
    rain: bool = False
    sun: bool = False


_WEATHER: dict[str, _Weather] = {
    'winter_overcast': _Weather((200, 192, 182), (222, 216, 210), 380.0, 0.95, 0.85, 0.72,
                                0.65, (1.06, 1.0, 0.94), 2.5, 0.8, 0.0, 1.25, snow=True),
    'spring_sunny': _Weather((215, 150, 90), (235, 215, 195), 900.0, 1.05, 1.0, 1.18, 1.1,
                             (0.97, 1.0, 1.03), 2.0, 0.45, 0.0, 1.0, sun=True),
    'spring_rain': _Weather((150, 145, 140), (175, 172, 168), 220.0, 0.72, 0.75, 0.85, 0.6,
                            (1.03, 1.0, 0.97), 3.5, 0.85, 0.35, 0.75, rain=True),
    'dusk': _Weather((110, 70, 60), (120, 150, 215), 500.0, 0.45, 0.75, 0.95, 0.85,
                     (0.85, 0.98, 1.15), 7.0, 0.8, 0.1, 0.9),
}


#: Fluorescent orange sheeting keeps at least this share of its saturation in any weather.
_FLUORESCENT_SAT = 0.9


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


def _hash01(i: np.ndarray, salt: int) -> np.ndarray:
    """Deterministic pseudo-random values in [0, 1) for integer arrays."""
    x = (np.asarray(i, np.int64) * 2654435761 + salt * 97531) & 0xFFFFFFFF
    x = (x ^ (x >> 15)) * 2246822519 & 0xFFFFFFFF
    x = x ^ (x >> 13)
    return (x & 0xFFFF) / 65536.0


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


def _clip_near(pc: np.ndarray) -> np.ndarray:
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


def _periodic_noise(rng: np.random.Generator, n: int, sigma: float) -> np.ndarray:
    """Tileable smooth noise (n x n, unit variance) for world-anchored textures."""
    a = rng.standard_normal((n, n)).astype(np.float32)
    big = cv2.GaussianBlur(np.tile(a, (3, 3)), (0, 0), sigma)[n:2 * n, n:2 * n]
    return big / (big.std() + 1e-6)


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


def _sample(tex: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear, wrapping lookup of a float texture at (u, v) texel coordinates (1-D arrays)."""
    n = u.size
    cols = 512
    rows = -(-n // cols)
    pad = rows * cols - n
    mu = np.pad(u.astype(np.float32), (0, pad)).reshape(rows, cols)
    mv = np.pad(v.astype(np.float32), (0, pad)).reshape(rows, cols)
    out = cv2.remap(tex, mu, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    return out.ravel()[:n]


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
        if scene.weather not in _WEATHER:
            raise RenderError(f'unknown weather {scene.weather!r}; known: {WEATHER_PRESETS}')
        self.scene = scene
        self.camera = camera
        self.seed = int(seed)
        self.weather = _WEATHER[scene.weather]
        self._base_seed = (abs(self.seed), abs(int(scene.seed)))
        self._init_lens()
        self._init_background()
        self._init_effects()
        self._init_objects()

    # ------------------------------------------------------------------ static set-up
    def _init_lens(self) -> None:
        cam = self.camera
        self.margin, self._map1, self._map2, self._nn_map, self._fmap = _lens_maps(cam)
        mx, my = self.margin
        self.canvas_size = (cam.width + 2 * mx, cam.height + 2 * my)
        self.Kc = cam.K.copy()
        self.Kc[0, 2] += mx
        self.Kc[1, 2] += my
        self._f2 = np.array([self.Kc[0, 0], self.Kc[1, 1]])
        self._c2 = np.array([self.Kc[0, 2], self.Kc[1, 2]])
        self._hor = np.array(self.weather.sky_horizon, float) * self.weather.light

    def _init_objects(self) -> None:
        """Bounding spheres of everything that does not move, for per-frame view culling."""
        sc = self.scene
        self._static = list(sc.signs) + [o for o in sc.objects
                                         if not (isinstance(o, Box) and o.speed)]
        self._static_ref, self._static_rad = _bounds(self._static)
        cam = self.camera
        self._tan = (1.25 * max(cam.cx, cam.width - cam.cx) / cam.fx,
                     1.25 * max(cam.cy, cam.height - cam.cy) / cam.fy)

    def _init_background(self) -> None:
        Wc, Hc = self.canvas_size
        self._half = (Wc // 2, Hc // 2)
        w2, h2 = self._half
        # Pixel (i, j) of the half-res image covers full pixels 2i, 2i+1: centre 2i + 0.5.
        u = np.arange(w2) * 2 + 0.5
        v = np.arange(h2) * 2 + 0.5
        uu, vv = np.meshgrid(u, v)
        Ki = np.linalg.inv(self.Kc)
        rays = np.stack([uu, vv, np.ones_like(uu)], -1).reshape(-1, 3) @ Ki.T
        self._rays = (rays / np.linalg.norm(rays, axis=1, keepdims=True)).astype(np.float32)
        # Quarter-res grid aligned with cv2.resize x2 of the half-res one: centre 4j + 1.5.
        uq, vq = np.meshgrid(np.arange(w2 // 2) * 4 + 1.5, np.arange(h2 // 2) * 4 + 1.5)
        rq = np.stack([uq, vq, np.ones_like(uq)], -1).reshape(-1, 3) @ Ki.T
        self._rays_q = (rq / np.linalg.norm(rq, axis=1, keepdims=True)).astype(np.float32)
        self._fpix = float(self.Kc[0, 0]) / 2.0       # focal length of the half-res grid
        self._straight = bool(np.all(np.abs(np.diff(self.scene.road.heading)) < 1e-12))
        rng = np.random.default_rng(list(self._base_seed) + [11])
        # 256 texels over 64 m (fine grain) and 32 m x 16 m cells of large patches.
        self._tex = _periodic_noise(rng, 256, 0.8)
        self._patch = _periodic_noise(rng, 64, 2.0)

    def _init_effects(self) -> None:
        W, H = self.camera.width, self.camera.height
        rng = np.random.default_rng(list(self._base_seed) + [23])
        pad = 32
        self._noise: dict[int, np.ndarray] = {}          # filled lazily per sigma level
        self._noise_sigmas = np.array([2.0, 4.0, 7.0, 11.0])
        self._noise_bank(int(np.argmin(np.abs(self._noise_sigmas - self.weather.noise))))
        self._rain = None
        if self.weather.rain:
            layer = np.zeros((H + 2 * pad, W + 2 * pad), np.float32)
            n = 700
            xs = rng.uniform(0, W + 2 * pad, n)
            ys = rng.uniform(0, H + 2 * pad, n)
            ln = rng.uniform(8, 22, n)
            br = rng.uniform(12, 40, n)
            for x, y, L, b in zip(xs, ys, ln, br):
                cv2.line(layer, (int(x), int(y)), (int(x + 0.18 * L), int(y + L)), float(b), 1,
                         cv2.LINE_AA)
            self._rain = cv2.GaussianBlur(layer, (3, 3), 0).astype(np.uint8)
            drops = np.zeros((H, W), np.float32)
            for _ in range(9):
                cv2.circle(drops, (int(rng.uniform(0, W)), int(rng.uniform(0, H))),
                           int(rng.uniform(6, 18)), 1.0, -1, cv2.LINE_AA)
            self._drops = cv2.GaussianBlur(drops, (0, 0), 4.0)[..., None]
        g = np.linspace(-1, 1, 257, dtype=np.float32)
        gx, gy = np.meshgrid(g, g)
        self._glare = np.exp(-(gx ** 2 + gy ** 2) * 5.0)[..., None].astype(np.float32)

    def _noise_bank(self, level: int) -> np.ndarray:
        """Precomputed int16 Gaussian noise of one sigma level (its own seed: order-free)."""
        if level not in self._noise:
            W, H = self.camera.width, self.camera.height
            rng = np.random.default_rng(list(self._base_seed) + [29, level])
            bank = rng.standard_normal((H + 32, W + 32, 3), dtype=np.float32)
            self._noise[level] = (bank * self._noise_sigmas[level]).astype(np.int16)
        return self._noise[level]

    # ------------------------------------------------------------------ helpers
    def _camera_pose(self, base_pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """World position of the camera and the world -> camera rotation."""
        pos = base_pose.to_world(CAMERA_IN_BASE)
        R_wb = base_pose.R
        R_cw = BASE_TO_CAMERA_ROT @ R_wb.T
        return pos, R_cw

    def _proj(self, pc: np.ndarray) -> np.ndarray:
        """Project (N, 3) camera points (z > 0) onto the undistorted canvas."""
        return pc[:, :2] / pc[:, 2:3] * self._f2 + self._c2

    def _haze(self, bgr, dist: float, light: float | None = None) -> tuple:
        w = self.weather
        f = 1.0 - math.exp(-max(dist, 0.0) / w.haze_m)
        li = w.light if light is None else light
        c = np.asarray(bgr, float) * (li * (1 - f)) + self._hor * f
        return (float(c[0]), float(c[1]), float(c[2]))

    # ------------------------------------------------------------------ background
    def _frenet(self, px: np.ndarray, py: np.ndarray, s0: float) -> tuple:
        road = self.scene.road
        x0, y0, h0 = road.pose_at(s0)
        s = s0 + (px - x0) * math.cos(h0) + (py - y0) * math.sin(h0)
        if not self._straight:
            xs, ys, hs = road.pose_at(s)
            s = s + (px - xs) * np.cos(hs) + (py - ys) * np.sin(hs)
        xs, ys, hs = road.pose_at(s)
        d = -(px - xs) * np.sin(hs) + (py - ys) * np.cos(hs)
        return s.astype(np.float32), d.astype(np.float32)

    def _background(self, cam_pos: np.ndarray, R_cw: np.ndarray, s_cam: float,
                    rng: np.random.Generator) -> np.ndarray:
        w = self.weather
        w2, h2 = self._half
        dirs = self._rays @ R_cw.astype(np.float32)          # camera -> world directions
        dz = dirs[:, 2]
        img = np.empty((dirs.shape[0], 3), np.float32)
        # Sky: vertical gradient, a little brighter towards the sun for sunny weather.
        sky = ~(dz < -1e-3)
        e = np.clip(dz[sky] / 0.45, 0.0, 1.0)[:, None] ** 0.7
        top = np.array(w.sky_top, np.float32) * w.light
        hor = np.array(w.sky_horizon, np.float32) * w.light
        img[sky] = hor + (top - hor) * e
        # Ground.
        g = ~sky
        t = np.minimum(-cam_pos[2] / dz[g], FAR_M)
        # Frenet coordinates are smooth over the image: computed on a quarter-res grid and
        # upsampled (exact range t stays per pixel for the line footprint and haze).
        dq = self._rays_q @ R_cw.astype(np.float32)
        tq = np.where(dq[:, 2] < -1e-6, np.minimum(-cam_pos[2] / np.minimum(dq[:, 2], -1e-6),
                                                   FAR_M), FAR_M)
        sq, dd = self._frenet(cam_pos[0] + tq * dq[:, 0], cam_pos[1] + tq * dq[:, 1], s_cam)
        wq, hq = w2 // 2, h2 // 2
        s = cv2.resize((sq - s_cam).reshape(hq, wq), (w2, h2),
                       interpolation=cv2.INTER_LINEAR).ravel()[g] + np.float32(s_cam)
        d = cv2.resize(dd.reshape(hq, wq), (w2, h2), interpolation=cv2.INTER_LINEAR).ravel()[g]
        img[g] = self._ground_colour(s, d, t, rng)
        return img.reshape(h2, w2, 3)

    def _ground_colour(self, s: np.ndarray, d: np.ndarray, rng_m: np.ndarray,
                       rng: np.random.Generator) -> np.ndarray:
        w = self.weather
        M = MATERIALS
        cover = 'snow' if (self.scene.ground_cover == 'snow' or w.snow) else \
            ('dry_grass' if self.scene.ground_cover == 'dry_grass' else 'grass')
        asph = np.array(M['asphalt'].bgr, np.float32) * w.asphalt_gain
        shld = np.array(M['shoulder'].bgr, np.float32) * w.asphalt_gain
        pal = np.stack([asph, shld, np.array(M[cover].bgr, np.float32),
                        np.array(M['tree'].bgr, np.float32) * 0.6]) * w.light
        idx = np.full(s.shape, 2, np.uint8)
        idx[(d > -(ROAD_HALF_WIDTH + RIGHT_SHOULDER)) & (d < ROAD_HALF_WIDTH + LEFT_SHOULDER)] = 1
        idx[np.abs(d) <= ROAD_HALF_WIDTH] = 0
        idx[(d < _TREE_RIGHT) | (d > _TREE_LEFT)] = 3
        # World-anchored textures, bilinear (fine grain and large patches).
        tex = _sample(self._tex, np.mod(d * 4.0, 256.0), np.mod(s * 4.0, 256.0))
        patch = _sample(self._patch, np.mod(d * 0.5, 64.0), np.mod(s * 0.25, 64.0))
        amp = np.array([0.035, 0.05, 0.03 if cover == 'snow' else 0.09, 0.12], np.float32)[idx]
        # Far away the texture averages out within a pixel.
        fade = np.exp(-rng_m * (1.0 / 60.0))
        col = pal[idx] * (1.0 + amp * (tex * fade + 0.8 * patch))[:, None]
        if cover == 'snow':
            # Snow drifting onto the shoulders (patchy); the lanes stay clear.
            onto = (idx == 1) & (patch > 0.0)
            snow = np.array(M['snow'].bgr, np.float32) * w.light
            col[onto] = col[onto] * 0.35 + snow * 0.65
        # Lane lines, anti-aliased by the pixel footprint (lateral metres per pixel).
        inv_foot = 1.0 / np.maximum(rng_m / self._fpix, 0.02)
        dashed = (np.mod(s, 12.0) < 3.0).astype(np.float32)
        ad = np.abs(d)
        edge = np.clip((0.08 - np.abs(ad - (ROAD_HALF_WIDTH - 0.15))) * inv_foot + 0.5, 0, 1)
        lane = np.clip((0.065 - np.abs(ad - 1.85)) * inv_foot + 0.5, 0, 1) * dashed
        cov = np.maximum(edge, lane)
        on = cov > 0
        paint = np.where((d[on] > 3.0)[:, None],
                         np.array(M['lane_paint_yellow'].bgr, np.float32),
                         np.array(M['lane_paint'].bgr, np.float32)) * (w.light * 0.95)
        c = cov[on][:, None]
        col[on] = col[on] * (1.0 - c) + paint * c
        for so in self.scene.overpasses:
            col[np.abs(s - so) < 7.0] *= w.shadow
        hor = self._hor.astype(np.float32)
        if w.wet > 0:
            road = idx <= 1
            refl = (w.wet * (1.0 - np.exp(-rng_m[road] / 35.0)))[:, None]
            col[road] = col[road] * (1 - refl) + hor * refl
        f = (1.0 - np.exp(-rng_m / w.haze_m))[:, None]
        return col + (hor - col) * f

    # ------------------------------------------------------------------ scene objects
    def _tree_walls(self, canvas, label, cam_pos, R_cw, s_cam) -> None:
        """Tree lines on both sides: a bumpy canopy wall from the ground, far chunks first."""
        road = self.scene.road
        near = np.arange(math.floor(s_cam / 3.0) * 3.0, s_cam + 120.0, 3.0)
        far = np.arange(math.ceil((s_cam + 120.0) / 12.0) * 12.0, s_cam + 800.0, 12.0)
        s = np.concatenate([near, far])
        s = s[(s >= 0) & (s <= road.length)]
        if len(s) < 2:
            return
        k = np.round(s / 3.0).astype(np.int64)
        tc = np.array(MATERIALS['tree'].bgr, float)
        for side, dl in ((-1, _TREE_RIGHT), (1, _TREE_LEFT)):
            x, y, _ = road.pose_at(s, dl + 3.0 * side * _hash01(k // 8, 17 + side))
            # Canopy: rounded crowns (|sin|) of random heights.
            h = 9.0 + 5.0 * _hash01(k // 4, 3 + side) + 2.5 * np.abs(np.sin(s * 0.9 + side))
            pts = np.concatenate([np.stack([x, y, np.zeros_like(x)], -1),
                                  np.stack([x, y, h], -1)])
            pc = (pts - cam_pos) @ R_cw.T
            n = len(s)
            ok = (pc[:n, 2] > 1.0) & (pc[n:, 2] > 1.0)
            if ok.sum() < 2:
                continue
            pc[:, 2] = np.maximum(pc[:, 2], 1.0)
            uv = np.clip(np.round(self._proj(pc) * 16), -2 ** 22, 2 ** 22).astype(np.int32)
            bot, top = uv[:n], uv[n:]
            idx = np.nonzero(ok)[0]
            dist = np.hypot(x - cam_pos[0], y - cam_pos[1])
            chunks = np.array_split(idx, max(1, len(idx) // 6))
            for ch in chunks[::-1]:
                if len(ch) == 0:
                    continue
                j = np.arange(ch[0], min(ch[-1] + 2, idx[-1] + 1))
                j = j[ok[j]]
                if len(j) < 2:
                    continue
                poly = np.concatenate([bot[j], top[j][::-1]])
                shade = 0.8 + 0.35 * float(_hash01(np.array([k[j[0]] // 6]), 9 + side)[0])
                col = self._haze(tc * shade, float(dist[j].mean()))
                cv2.fillPoly(canvas, [poly], col, cv2.LINE_AA, 4)
                cv2.fillPoly(label, [poly], 0, cv2.LINE_8, 4)

    def _overpass_quads(self, s_cam: float) -> list[Quad]:
        road = self.scene.road
        quads: list[Quad] = []
        for j, so in enumerate(self.scene.overpasses):
            if not (-20.0 < so - s_cam < 600.0):
                continue
            for k, (s1, d0, d1, z0, z1) in enumerate((
                    (so - 6.0, -60.0, 60.0, 5.4, 7.2),
                    (so - 5.5, -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 1.5),
                     -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 0.5), 0.0, 5.4),
                    (so - 5.5, ROAD_HALF_WIDTH + LEFT_SHOULDER + 0.5,
                     ROAD_HALF_WIDTH + LEFT_SHOULDER + 1.5, 0.0, 5.4))):
                x, y, _ = road.pose_at(np.array([s1, s1]), np.array([d1, d0]))
                corners = np.array([[x[0], y[0], z1], [x[1], y[1], z1], [x[1], y[1], z0],
                                    [x[0], y[0], z0]])
                quads.append(Quad(-1000 - 3 * j - k, 'overpass', corners, 'concrete'))
        return quads

    def _fill(self, canvas, label, pc, colour, lab: int) -> bool:
        q = _clip_near(pc)
        if len(q) < 3:
            return False
        uv = np.round(self._proj(q) * 16).astype(np.int32)
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
        col = self._haze(np.array(MATERIALS[q.material].bgr, float) * shade, dist)
        self._fill(canvas, label, pc, col, lab)
        if q.kind == 'guardrail' and dist < 80.0:
            # Darker lower edge and a mid-height groove of the W-beam.
            c = np.asarray(q.corners, float)
            for a, b, f in ((0.0, 0.25, 0.7), (0.45, 0.55, 0.8)):
                strip = np.array([c[0] + (c[3] - c[0]) * (1 - a), c[1] + (c[2] - c[1]) * (1 - a),
                                  c[1] + (c[2] - c[1]) * (1 - b), c[0] + (c[3] - c[0]) * (1 - b)])
                col2 = self._haze(np.array(MATERIALS[q.material].bgr, float) * shade * f, dist)
                self._fill(canvas, label, (strip - cam_pos) @ R_cw.T, col2, lab)

    def _silhouette(self, canvas, label, pts_w, cam_pos, R_cw, colour, lab: int) -> None:
        pc = (pts_w - cam_pos) @ R_cw.T
        if (pc[:, 2] < NEAR_M).any():
            return
        uv = self._proj(pc)
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
            col = self._haze(np.array(MATERIALS[mat].bgr, float) * f, dist)
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
            self._fill(canvas, label, pc, self._haze(col * sh, dist), lab)
            if n[2] == 0:
                low = np.array([pts[3], pts[2], pts[2] - 0.25 * up, pts[3] - 0.25 * up])
                self._fill(canvas, label, (low - cam_pos) @ R_cw.T, self._haze(under, dist),
                           lab)
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
                           self._haze(np.array(MATERIALS[mat].bgr, float), dist), lab)

    def _draw_sign(self, canvas, label, sp: SignPanel, cam_pos, R_cw, dist,
                   lab: int) -> 'tuple | None':
        """Paint one sign face; returns ``(lab, x0, y0, alpha, label ROI after painting)``
        for :meth:`_sign_edges`, or None when nothing of its face was painted."""
        corners = sp.corners()
        pc = (corners - cam_pos) @ R_cw.T
        c = catalogue.get(sp.class_key)
        front = np.dot(sp.normal, cam_pos - np.asarray(sp.center, float)) > 0
        if not front:
            # Back of the sign: grey, in the face's outline.
            ol = signart.outline(c.shape, 1.0, 1.0)
            pw = corners[0] + ol[:, :1] * (corners[1] - corners[0]) + \
                ol[:, 1:] * (corners[3] - corners[0])
            col = self._haze(np.array(MATERIALS['sign_back'].bgr, float), dist)
            self._fill(canvas, label, (pw - cam_pos) @ R_cw.T, col, 0)
            return None
        q = _clip_near(pc)
        if len(q) < 3:
            return None
        uv = self._proj(q)
        Wc, Hc = self.canvas_size
        x0 = max(int(math.floor(uv[:, 0].min())) - 1, 0)
        y0 = max(int(math.floor(uv[:, 1].min())) - 1, 0)
        x1 = min(int(math.ceil(uv[:, 0].max())) + 2, Wc)
        y1 = min(int(math.ceil(uv[:, 1].max())) + 2, Hc)
        if x1 <= x0 or y1 <= y0:
            return None
        # Art resolution ~1.5x the projected size (limits aliasing of the warp).
        extent = max(uv[:, 0].max() - uv[:, 0].min(), uv[:, 1].max() - uv[:, 1].min())
        size = next((a for a in _ART_SIZES if a >= 1.5 * extent), _ART_SIZES[-1])
        variant = signart.OTHER_VARIANTS[sp.object_id % len(signart.OTHER_VARIANTS)] \
            if sp.class_key == 'other_workzone' else None
        orange = signart.sheeting_orange(sp.object_id, self.scene.seed) \
            if signart.uses_orange(sp.class_key) else None
        art = signart.sign_face(sp.class_key, size, sp.speed_value, variant, orange)
        ah, aw = art.shape[:2]
        ex = R_cw @ (corners[1] - corners[0]) / aw
        ey = R_cw @ (corners[3] - corners[0]) / ah
        o = R_cw @ (corners[0] - cam_pos) + 0.5 * (ex + ey)
        Hm = self.Kc @ np.column_stack([ex, ey, o])
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
        if orange is not None and w.saturation < _FLUORESCENT_SAT:
            # Fluorescent orange sheeting keeps its colour under a grey sky (fluorescence
            # turns the diffuse daylight's blue into orange): pre-saturate so that after the
            # frame's grading it keeps at least _FLUORESCENT_SAT of its saturation.
            k = _FLUORESCENT_SAT / w.saturation
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

    def _sign_edges(self, lab_img: np.ndarray, label: np.ndarray, faces: list) -> None:
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
            faces: :meth:`_draw_sign`'s records, in painting order.
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
            mx = self._fmap[0, r0:r1, c0:c1] - np.float32(x0)
            my = self._fmap[1, r0:r1, c0:c1] - np.float32(y0)
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

    # ------------------------------------------------------------------ effects
    def _block_value(self, frame: int, block: int, salt: int, fn) -> float:
        """Smooth per-clip random signal: values drawn per block, cosine-interpolated."""
        b, r = divmod(frame, block)
        u = (1 - math.cos(math.pi * r / block)) / 2
        va = fn(np.random.default_rng(list(self._base_seed) + [salt, b]))
        vb = fn(np.random.default_rng(list(self._base_seed) + [salt, b + 1]))
        return va * (1 - u) + vb * u

    def _exposure(self, frame: int) -> float:
        def draw(r: np.random.Generator) -> float:
            p = r.random()
            if p < 0.15:
                return math.log(r.uniform(0.5, 0.72))       # under-exposure episode
            if p < 0.30:
                return math.log(r.uniform(1.35, 1.75))      # over-exposure episode
            return math.log(r.uniform(0.9, 1.1))
        return math.exp(self._block_value(frame, 75, 31, draw))

    def _white_balance(self, frame: int) -> np.ndarray:
        return np.array([self._block_value(frame, 240, 41 + c, lambda r: r.uniform(0.9, 1.1))
                         for c in range(3)])

    def _grade(self, img: np.ndarray, frame: int, rng: np.random.Generator) -> np.ndarray:
        w = self.weather
        gain = self._exposure(frame) * rng.uniform(0.97, 1.03)
        wb = self._white_balance(frame) * np.array(w.cast)
        sat = w.saturation
        lum = np.array([0.114, 0.587, 0.299])
        M = (np.eye(3) * sat + (1 - sat) * np.tile(lum, (3, 1)))
        M = (M * (wb * gain)[:, None]).astype(np.float32)
        out = cv2.transform(img, M)
        x = np.arange(256, dtype=np.float32) / 255.0
        y = 0.5 + (x - 0.5) * w.contrast
        if w.contrast > 1.0:                                 # S-curve for harsh sun
            y = np.clip(y, 0, 1)
            y = y * y * (3 - 2 * y) * 0.35 + y * 0.65
        lut = np.clip(y * 255.0, 0, 255).astype(np.uint8)
        return cv2.LUT(out, lut)

    def _effects(self, img: np.ndarray, frame: int, rng: np.random.Generator,
                 sun_uv) -> np.ndarray:
        w = self.weather
        H, W = img.shape[:2]
        # Motion blur: small global kernel on some frames (vibration, speed).
        if rng.random() < 0.25:
            # odd sizes only: an even kernel's centre is half a pixel off filter2D's anchor
            # and moved the image (not its labels) by half a pixel
            k = int(rng.integers(3, 6)) | 1
            ang = rng.uniform(-0.3, 0.3) + (math.pi / 2 if rng.random() < 0.5 else 0.0)
            ker = np.zeros((k, k), np.float32)
            c = (k - 1) / 2
            cv2.line(ker, (int(round(c - c * math.cos(ang))), int(round(c - c * math.sin(ang)))),
                     (int(round(c + c * math.cos(ang))), int(round(c + c * math.sin(ang)))),
                     1.0, 1)
            # point-symmetric about the anchor (a rasterised line need not be): blur, no shift
            ker = ker + ker[::-1, ::-1]
            img = cv2.filter2D(img, -1, ker / ker.sum())
        if self._rain is not None:
            ox, oy = int(rng.integers(0, 64)), int(rng.integers(0, 64))
            streak = self._rain[oy:oy + H, ox:ox + W]
            img = cv2.add(img, cv2.merge([streak, streak, streak]))
            if rng.random() < 0.5:
                blur = cv2.blur(img, (9, 9))
                img = (img * (1 - self._drops) + blur * self._drops).astype(np.uint8)
        if w.sun and sun_uv is not None:
            u, v = sun_uv
            r = int(rng.uniform(110, 170))
            x0, y0 = int(u) - r, int(v) - r
            xa, ya, xb, yb = max(x0, 0), max(y0, 0), min(x0 + 2 * r, W), min(y0 + 2 * r, H)
            if xa < xb and ya < yb:
                g = cv2.resize(self._glare, (2 * r, 2 * r))[..., None] * rng.uniform(90, 160)
                roi = img[ya:yb, xa:xb].astype(np.float32)
                roi += g[ya - y0:yb - y0, xa - x0:xb - x0] * np.array([0.85, 0.95, 1.0],
                                                                       np.float32)
                img[ya:yb, xa:xb] = np.clip(roi, 0, 255).astype(np.uint8)
        img = self._grade(img, frame, rng)
        # Sensor noise (more when under-exposed), from precomputed banks at random offsets.
        sigma = w.noise * (1.0 + 0.8 * max(0.0, 1.0 - self._exposure(frame)))
        bank = self._noise_bank(int(np.argmin(np.abs(self._noise_sigmas - sigma))))
        ox, oy = int(rng.integers(0, 32)), int(rng.integers(0, 32))
        img = cv2.add(img, bank[oy:oy + H, ox:ox + W], dtype=cv2.CV_8U)
        if rng.random() < 0.3:
            q = int(rng.integers(25, 70))
            ok, buf = cv2.imencode('.jpg', img, [cv2.IMWRITE_JPEG_QUALITY, q])
            if ok:
                img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return img

    # ------------------------------------------------------------------ main entry
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
        Wc, Hc = self.canvas_size
        bg = self._background(cam_pos, R_cw, s_cam, rng)
        canvas = cv2.resize(np.clip(bg, 0, 255).astype(np.uint8), (Wc, Hc),
                            interpolation=cv2.INTER_LINEAR)
        label = np.zeros((Hc, Wc), np.uint16)
        self._tree_walls(canvas, label, cam_pos, R_cw, s_cam)

        # Painter's list: (sort key, distance, kind, object, label index) of what is in view.
        items = []
        entries: list[tuple[str, object, float]] = []
        moving = [o for o in self.scene.objects_at(t) if isinstance(o, Box) and o.speed]
        cands = [(self._static, self._static_ref, self._static_rad)]
        dyn = moving + self._overpass_quads(s_cam)
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
        faces = []
        for _, dist, what, o, lab in items:
            if what == 'sign':
                face = self._draw_sign(canvas, label, o, cam_pos, R_cw, dist, lab)
                if face is not None:
                    faces.append(face)
            elif isinstance(o, Quad):
                self._draw_quad(canvas, label, o, cam_pos, R_cw, dist, lab)
            elif isinstance(o, Box):
                self._draw_box(canvas, label, o, cam_pos, R_cw, dist, lab)
            elif isinstance(o, (Cylinder, Cone)):
                self._draw_cyl(canvas, label, o, cam_pos, R_cw, dist, lab)

        # Lens distortion.
        img = cv2.remap(canvas, self._map1, self._map2, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE)
        lab_img = cv2.remap(label, self._nn_map, None, cv2.INTER_NEAREST,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        self._sign_edges(lab_img, label, faces)
        sign_hits, obj_hits, lut = self._ground_truth(entries, lab_img, cam_pos, R_cw)
        out_label = lut[lab_img]

        sun_uv = self._sun_uv(cam_pos, R_cw) if self.weather.sun else None
        img = self._effects(img, int(frame_index), rng, sun_uv)
        return RenderResult(image=img, signs=sign_hits, distractors=obj_hits, label=out_label)

    def _sun_uv(self, cam_pos, R_cw):
        az = _hash01(np.array([self.scene.seed]), 5)[0] * 1.2 - 0.6
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
