"""Background of the synthetic camera: sky, ground plane, tree lines and overpasses.

The sky and ground are drawn at half resolution from the Frenet coordinates of every
ground pixel: a sky gradient, asphalt lanes with dashed and solid lane lines (anti-aliased
by the pixel footprint), shoulders, grass or snow with world-anchored textures, overpass
shadows, a wet sheen, then haze.  Tree lines are bumpy canopy walls painted over it far to
near; overpasses are returned as quads for the object painter.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from workzone_ros.sim.lens import Lens
from workzone_ros.sim.weather import Weather
from workzone_ros.sim.world import (
    LEFT_SHOULDER,
    MATERIALS,
    RIGHT_SHOULDER,
    ROAD_HALF_WIDTH,
    Quad,
    Scene,
)

__all__ = ['FAR_M', 'Ground', 'hash01']

FAR_M = 1500.0               # ground beyond this is horizon haze
_TREE_RIGHT = -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 22.0)    # tree-line lateral offsets (m)
_TREE_LEFT = ROAD_HALF_WIDTH + LEFT_SHOULDER + 18.0


def hash01(i: np.ndarray, salt: int) -> np.ndarray:
    """Deterministic pseudo-random values in [0, 1) for integer arrays."""
    x = (np.asarray(i, np.int64) * 2654435761 + salt * 97531) & 0xFFFFFFFF
    x = (x ^ (x >> 15)) * 2246822519 & 0xFFFFFFFF
    x = x ^ (x >> 13)
    return (x & 0xFFFF) / 65536.0


def _periodic_noise(rng: np.random.Generator, n: int, sigma: float) -> np.ndarray:
    """Tileable smooth noise (n x n, unit variance) for world-anchored textures."""
    a = rng.standard_normal((n, n)).astype(np.float32)
    big = cv2.GaussianBlur(np.tile(a, (3, 3)), (0, 0), sigma)[n:2 * n, n:2 * n]
    return big / (big.std() + 1e-6)


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


class Ground:
    """Sky, ground and roadside structures of one scene, for one lens.

    Args:
        scene: the world (road, ground cover, overpasses, scene seed).
        weather: the scene's weather.
        lens: the canvas the background is drawn for.
        base_seed: the renderer's (appearance seed, scene seed); seeds the textures.
    """

    def __init__(self, scene: Scene, weather: Weather, lens: Lens, base_seed: tuple[int, int]):
        self.scene = scene
        self.weather = weather
        self.lens = lens
        self._hor = weather.horizon
        Wc, Hc = lens.canvas_size
        self.half = (Wc // 2, Hc // 2)
        w2, h2 = self.half
        # Pixel (i, j) of the half-res image covers full pixels 2i, 2i+1: centre 2i + 0.5.
        u = np.arange(w2) * 2 + 0.5
        v = np.arange(h2) * 2 + 0.5
        uu, vv = np.meshgrid(u, v)
        Ki = np.linalg.inv(lens.Kc)
        rays = np.stack([uu, vv, np.ones_like(uu)], -1).reshape(-1, 3) @ Ki.T
        self._rays = (rays / np.linalg.norm(rays, axis=1, keepdims=True)).astype(np.float32)
        # Quarter-res grid aligned with cv2.resize x2 of the half-res one: centre 4j + 1.5.
        uq, vq = np.meshgrid(np.arange(w2 // 2) * 4 + 1.5, np.arange(h2 // 2) * 4 + 1.5)
        rq = np.stack([uq, vq, np.ones_like(uq)], -1).reshape(-1, 3) @ Ki.T
        self._rays_q = (rq / np.linalg.norm(rq, axis=1, keepdims=True)).astype(np.float32)
        self._fpix = float(lens.Kc[0, 0]) / 2.0       # focal length of the half-res grid
        self._straight = bool(np.all(np.abs(np.diff(scene.road.heading)) < 1e-12))
        rng = np.random.default_rng(list(base_seed) + [11])
        # 256 texels over 64 m (fine grain) and 32 m x 16 m cells of large patches.
        self._tex = _periodic_noise(rng, 256, 0.8)
        self._patch = _periodic_noise(rng, 64, 2.0)

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

    def background(self, cam_pos: np.ndarray, R_cw: np.ndarray, s_cam: float,
                   rng: np.random.Generator) -> np.ndarray:
        """Sky and ground seen from a camera pose.

        Args:
            cam_pos: camera position in the world.
            R_cw: world -> camera rotation.
            s_cam: the camera's arc length along the road.
            rng: the frame's generator.

        Returns:
            (h, w, 3) float32 BGR at half the canvas resolution.
        """
        w = self.weather
        w2, h2 = self.half
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

    def tree_walls(self, canvas, label, cam_pos, R_cw, s_cam) -> None:
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
            x, y, _ = road.pose_at(s, dl + 3.0 * side * hash01(k // 8, 17 + side))
            # Canopy: rounded crowns (|sin|) of random heights.
            h = 9.0 + 5.0 * hash01(k // 4, 3 + side) + 2.5 * np.abs(np.sin(s * 0.9 + side))
            pts = np.concatenate([np.stack([x, y, np.zeros_like(x)], -1),
                                  np.stack([x, y, h], -1)])
            pc = (pts - cam_pos) @ R_cw.T
            n = len(s)
            ok = (pc[:n, 2] > 1.0) & (pc[n:, 2] > 1.0)
            if ok.sum() < 2:
                continue
            pc[:, 2] = np.maximum(pc[:, 2], 1.0)
            uv = np.clip(np.round(self.lens.proj(pc) * 16), -2 ** 22, 2 ** 22).astype(np.int32)
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
                shade = 0.8 + 0.35 * float(hash01(np.array([k[j[0]] // 6]), 9 + side)[0])
                col = self.weather.haze(tc * shade, float(dist[j].mean()))
                cv2.fillPoly(canvas, [poly], col, cv2.LINE_AA, 4)
                cv2.fillPoly(label, [poly], 0, cv2.LINE_8, 4)

    def overpass_quads(self, s_cam: float) -> list[Quad]:
        """Deck and pier faces of the overpasses ahead of ``s_cam``, for the object painter."""
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
