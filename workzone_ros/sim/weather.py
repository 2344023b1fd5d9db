"""Weather presets of the synthetic camera and the per-frame camera effects.

A :class:`Weather` sets the sky, haze, light and colour grading of a scene;
:class:`CameraEffects` applies what a real camera adds to every frame: exposure episodes,
white-balance drift, the weather's colour grading, motion blur, rain streaks and drops,
sun glare, sensor noise and JPEG blocking, all seeded from (seed, frame_index).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ['CAMERA_JPEG', 'WEATHER_PRESETS', 'WEATHERS', 'FLUORESCENT_SAT', 'Weather',
           'CameraEffects', 'jpeg_degrade']

WEATHER_PRESETS = ('winter_overcast', 'spring_sunny', 'spring_rain', 'dusk')

#: Fluorescent orange sheeting keeps at least this share of its saturation in any weather.
FLUORESCENT_SAT = 0.9


@dataclass(frozen=True)
class Weather:
    """Look of one weather preset (colours BGR, 8-bit units)."""

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

    @property
    def horizon(self) -> np.ndarray:
        """Lit horizon colour (float64 BGR), what distant things fade into."""
        return np.array(self.sky_horizon, float) * self.light

    def haze(self, bgr, dist: float, light: float | None = None) -> tuple:
        """Colour ``bgr`` lit by the weather and hazed at ``dist`` metres, as a BGR tuple."""
        f = 1.0 - math.exp(-max(dist, 0.0) / self.haze_m)
        li = self.light if light is None else light
        c = np.asarray(bgr, float) * (li * (1 - f)) + self.horizon * f
        return (float(c[0]), float(c[1]), float(c[2]))


WEATHERS: dict[str, Weather] = {
    'winter_overcast': Weather((200, 192, 182), (222, 216, 210), 380.0, 0.95, 0.85, 0.72,
                               0.65, (1.06, 1.0, 0.94), 2.5, 0.8, 0.0, 1.25, snow=True),
    'spring_sunny': Weather((215, 150, 90), (235, 215, 195), 900.0, 1.05, 1.0, 1.18, 1.1,
                            (0.97, 1.0, 1.03), 2.0, 0.45, 0.0, 1.0, sun=True),
    'spring_rain': Weather((150, 145, 140), (175, 172, 168), 220.0, 0.72, 0.75, 0.85, 0.6,
                           (1.03, 1.0, 0.97), 3.5, 0.85, 0.35, 0.75, rain=True),
    'dusk': Weather((110, 70, 60), (120, 150, 215), 500.0, 0.45, 0.75, 0.95, 0.85,
                    (0.85, 0.98, 1.15), 7.0, 0.8, 0.1, 0.9),
}


class CameraEffects:
    """What the camera adds to a rendered frame, deterministic in (seeds, frame index).

    Args:
        weather: the scene's weather (grading, noise level, rain, sun).
        width: image width in pixels.
        height: image height in pixels.
        base_seed: the renderer's (appearance seed, scene seed).
    """

    def __init__(self, weather: Weather, width: int, height: int, base_seed: tuple[int, int]):
        self.weather = weather
        self._size = (width, height)
        self._base_seed = base_seed
        W, H = width, height
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
            W, H = self._size
            rng = np.random.default_rng(list(self._base_seed) + [29, level])
            bank = rng.standard_normal((H + 32, W + 32, 3), dtype=np.float32)
            self._noise[level] = (bank * self._noise_sigmas[level]).astype(np.int16)
        return self._noise[level]

    def _block_value(self, frame: int, block: int, salt: int, fn) -> float:
        """Smooth per-clip random signal: values drawn per block, cosine-interpolated."""
        b, r = divmod(frame, block)
        u = (1 - math.cos(math.pi * r / block)) / 2
        va = fn(np.random.default_rng(list(self._base_seed) + [salt, b]))
        vb = fn(np.random.default_rng(list(self._base_seed) + [salt, b + 1]))
        return va * (1 - u) + vb * u

    def exposure(self, frame: int) -> float:
        """Exposure gain of a frame: mostly near 1, with under- and over-exposed episodes."""
        def draw(r: np.random.Generator) -> float:
            p = r.random()
            if p < 0.15:
                return math.log(r.uniform(0.5, 0.72))       # under-exposure episode
            if p < 0.30:
                return math.log(r.uniform(1.35, 1.75))      # over-exposure episode
            return math.log(r.uniform(0.9, 1.1))
        return math.exp(self._block_value(frame, 75, 31, draw))

    def white_balance(self, frame: int) -> np.ndarray:
        """BGR gains of a frame's white balance, drifting slowly."""
        return np.array([self._block_value(frame, 240, 41 + c, lambda r: r.uniform(0.9, 1.1))
                         for c in range(3)])

    def grade(self, img: np.ndarray, frame: int, rng: np.random.Generator) -> np.ndarray:
        """Exposure, white balance, the weather's saturation, cast and contrast curve."""
        w = self.weather
        gain = self.exposure(frame) * rng.uniform(0.97, 1.03)
        wb = self.white_balance(frame) * np.array(w.cast)
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

    def apply(self, img: np.ndarray, frame: int, rng: np.random.Generator,
              sun_uv) -> np.ndarray:
        """All effects on one distorted frame.

        Args:
            img: the distorted BGR frame (sun glare may draw into it in place).
            frame: frame index (exposure and white-balance episodes).
            rng: the frame's generator (blur, rain, glare, noise offsets, JPEG).
            sun_uv: the sun's pixel position, or None when it is out of view.

        Returns:
            The frame as the camera delivers it.
        """
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
        img = self.grade(img, frame, rng)
        # Sensor noise (more when under-exposed), from precomputed banks at random offsets.
        sigma = w.noise * (1.0 + 0.8 * max(0.0, 1.0 - self.exposure(frame)))
        bank = self._noise_bank(int(np.argmin(np.abs(self._noise_sigmas - sigma))))
        ox, oy = int(rng.integers(0, 32)), int(rng.integers(0, 32))
        img = cv2.add(img, bank[oy:oy + H, ox:ox + W], dtype=cv2.CV_8U)
        return jpeg_degrade(img, rng, 0.3, 25, 70)


#: ``(share, q_lo, q_hi)`` of :func:`jpeg_degrade` for training augmentation that makes a
#: frame look like another camera's: 70 % of the copies at quality 30-95.  Real frames reach
#: the models compressed: dashcams record H.264 at a few Mbit/s (its blocking and 4:2:0
#: chroma smearing look like JPEG at quality 30-60) and vehicle bags carry ``CompressedImage``
#: JPEG, typically quality 75-95; 30 % stay uncompressed (raw topics, high-bitrate cameras).
CAMERA_JPEG = (0.7, 30, 96)


def jpeg_degrade(img: np.ndarray, rng: np.random.Generator, share: float, q_lo: int,
                 q_hi: int) -> np.ndarray:
    """``img`` (uint8 BGR) through a JPEG round trip at a quality drawn from ``q_lo`` to
    ``q_hi - 1``, with probability ``share`` (one ``rng.random()`` draw, then the quality);
    unchanged otherwise or when encoding fails."""
    if rng.random() < share:
        q = int(rng.integers(q_lo, q_hi))
        ok, buf = cv2.imencode('.jpg', img, [cv2.IMWRITE_JPEG_QUALITY, q])
        if ok:
            img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return img
