"""Contact sheet of the synthetic camera: one frame per weather preset and a 64-px crop of every
catalogue class (through the camera and the raw art), for people to look at.

Builds its own small scenes from the world primitives (no dependency on sim/scenario.py).
Usage: ``python -m workzone_ros.sim.sheet /tmp/contact_sheet.png [--seed N]``.
"""
from __future__ import annotations

import argparse
import math

import cv2
import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.sim import signart
from workzone_ros.sim.camera import WEATHER_PRESETS, CameraRenderer
from workzone_ros.sim.world import (
    LANE_CENTERS,
    RIGHT_SHOULDER,
    ROAD_HALF_WIDTH,
    SIGN_BOTTOM_HEIGHT,
    SIGN_LATERAL,
    Box,
    Cone,
    Cylinder,
    Pose,
    Quad,
    Road,
    Scene,
    SignPanel,
)

__all__ = ['make_sign', 'ego_pose', 'demo_scene', 'catalogue_scene', 'make_contact_sheet',
           'main']


def make_sign(object_id: int, key: str, road: Road, s: float, d: float = SIGN_LATERAL,
              tilt: float = 0.0, fade: float = 0.0, speed_value: int | None = None,
              objects: list | None = None) -> SignPanel:
    """A sign facing the ego traffic at (s, d), bottom 2.1 m above the road, with its post.

    Args:
        object_id: id of the face (the post gets ``object_id + 10000``).
        key: catalogue key.
        road: the road.
        s: arc length of the post.
        d: lateral offset of the post (default: right shoulder).
        tilt: in-plane rotation (rad).
        fade: art wash-out in [0, 1].
        speed_value: number on speed-limit faces / mile markers.
        objects: if given, the post Cylinder is appended to it.

    Returns:
        The sign panel.
    """
    c = catalogue.get(key)
    if c.shape == 'diamond':
        w = h = c.width_m * math.sqrt(2.0)
    else:
        w, h = c.width_m, c.height_m
    x, y, hd = road.pose_at(s, d)
    centre = np.array([float(x), float(y), SIGN_BOTTOM_HEIGHT + h / 2])
    if objects is not None:
        objects.append(Cylinder(object_id + 10000, 'post', np.array([float(x) + 0.06 *
                                math.cos(hd), float(y) + 0.06 * math.sin(hd), 0.0]), 0.05,
                                SIGN_BOTTOM_HEIGHT + h * 0.8, 'post'))
    return SignPanel(object_id, key, centre, float(hd) + math.pi, w, h, tilt, fade, speed_value)


def ego_pose(road: Road, s: float, lane: str = 'middle') -> Pose:
    """The base_link pose of the ego car at arc length ``s`` in ``lane``."""
    x, y, h = road.pose_at(s, LANE_CENTERS[lane])
    return Pose(np.array([float(x), float(y), 0.0]), float(h))


def _drum(oid: int, road: Road, s: float, d: float) -> Cylinder:
    x, y, _ = road.pose_at(s, d)
    return Cylinder(oid, 'drum', np.array([float(x), float(y), 0.0]), 0.29, 0.95, 'drum_orange',
                    [(0.15, 0.25, 'drum_band'), (0.45, 0.55, 'drum_band')])


def _guardrails(road: Road, s0: float, s1: float, d: float, oid: int) -> list[Quad]:
    out = []
    for k, s in enumerate(np.arange(s0, s1, 8.0)):
        x, y, _ = road.pose_at(np.array([s, s + 8.0]), d)
        out.append(Quad(oid + k, 'guardrail', np.array(
            [[x[0], y[0], 0.78], [x[1], y[1], 0.78], [x[1], y[1], 0.45], [x[0], y[0], 0.45]]),
            'guardrail'))
    return out


def demo_scene(weather: str, seed: int = 0) -> tuple[Scene, float]:
    """A short work-zone approach with distractors; returns the scene and the ego's s."""
    road = Road([(300.0, 0.0), (900.0, 1.0 / 1500.0)])
    objects: list = []
    signs_ = [
        make_sign(1, 'road_work_ahead', road, 150.0, objects=objects),
        make_sign(2, 'work_zone_speed_limit', road, 230.0, objects=objects, tilt=0.03),
        make_sign(3, 'lane_shift_left', road, 300.0, objects=objects, fade=0.3),
        make_sign(4, 'speed_limit', road, 120.0, d=ROAD_HALF_WIDTH + 3.0, objects=objects),
    ]
    for i in range(14):
        objects.append(_drum(200 + i, road, 175.0 + 9.0 * i,
                             -ROAD_HALF_WIDTH + 0.4 + min(i, 6) * 0.5))
    x, y, h = road.pose_at(160.0, LANE_CENTERS['right'])
    objects.append(Box(300, 'truck', np.array([float(x), float(y), 0.0]), 7.0, 2.5, 3.2,
                       float(h), 'vehicle_paint', 0.0, True, 'vehicle_orange'))
    x, y, h = road.pose_at(128.0, LANE_CENTERS['left'])
    objects.append(Box(301, 'car', np.array([float(x), float(y), 0.0]), 4.5, 1.8, 1.5,
                       float(h), 'vehicle_yellow', 0.0))
    for i in range(4):
        x, y, _ = road.pose_at(140.0 + 6 * i, -ROAD_HALF_WIDTH - 1.0)
        objects.append(Cone(400 + i, 'cone', np.array([float(x), float(y), 0.0]), 0.18, 0.7,
                            bands=[(0.35, 0.45, 'drum_band')]))
    objects += _guardrails(road, 60.0, 400.0, -(ROAD_HALF_WIDTH + RIGHT_SHOULDER + 0.5), 500)
    cover = 'snow' if weather == 'winter_overcast' else 'grass'
    scene = Scene(f'demo_{weather}', seed, road, signs_, objects, weather, cover, [250.0])
    return scene, 100.0


def catalogue_scene(weather: str = 'spring_sunny', seed: int = 0,
                    spacing: float = 80.0) -> tuple[Scene, list[tuple[str, float]]]:
    """Every drawable class on the right shoulder every ``spacing`` metres.

    Returns:
        The scene and ``[(class_key, s_of_sign), ...]``.
    """
    keys = [c.key for c in catalogue.CATALOGUE if c.key != 'background']
    road = Road([(spacing * (len(keys) + 2), 0.0)])
    objects: list = []
    signs_, where = [], []
    for i, key in enumerate(keys):
        s = spacing * (i + 1)
        signs_.append(make_sign(i + 1, key, road, s, objects=objects))
        where.append((key, s))
    return Scene('catalogue', seed, road, signs_, objects, weather, 'grass'), where


def _label(img: np.ndarray, text: str, scale: float = 0.45) -> np.ndarray:
    bar = np.full((18, img.shape[1], 3), 30, np.uint8)
    cv2.putText(bar, text, (3, 13), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1,
                cv2.LINE_AA)
    return np.vstack([bar, img])


def _crop(img: np.ndarray, box, size: int = 64, pad: float = 0.15) -> np.ndarray:
    x, y, w, h = box
    m = max(w, h) * (1 + 2 * pad)
    cx, cy = x + w / 2, y + h / 2
    k = size / m
    M = np.array([[k, 0, size / 2 - cx * k], [0, k, size / 2 - cy * k]])
    return cv2.warpAffine(img, M, (size, size), flags=cv2.INTER_AREA,
                          borderMode=cv2.BORDER_REPLICATE)


def make_contact_sheet(out_png: str, seed: int = 0, crop_distance: float = 25.0) -> np.ndarray:
    """Render the contact sheet and write it to ``out_png``.

    Args:
        out_png: output PNG path.
        seed: appearance seed.
        crop_distance: ego-to-sign distance (m) of the through-camera class crops.

    Returns:
        The sheet image (BGR).
    """
    frames = []
    for i, weather in enumerate(WEATHER_PRESETS):
        scene, s = demo_scene(weather, seed)
        r = CameraRenderer(scene, seed=seed).render(0.0, ego_pose(scene.road, s), 7 + i)
        img = r.image.copy()
        for h in r.signs:
            x, y, w, hh = h.box
            cv2.rectangle(img, (x, y), (x + w - 1, y + hh - 1), (0, 255, 0), 1)
        for h in r.distractors:
            x, y, w, hh = h.box
            cv2.rectangle(img, (x, y), (x + w - 1, y + hh - 1), (255, 0, 255), 1)
        frames.append(_label(img, f'{weather}  (green: GT sign boxes, magenta: distractors)'))
    grid = np.vstack([np.hstack(frames[:2]), np.hstack(frames[2:])])

    scene, where = catalogue_scene('spring_sunny', seed)
    rend = CameraRenderer(scene, seed=seed)
    tiles = []
    for k, (key, s) in enumerate(where):
        res = rend.render(0.0, ego_pose(scene.road, s - crop_distance), 1000 + k)
        hit = next((h for h in res.signs if h.class_key == key), None)
        cam = _crop(res.image, hit.box) if hit else np.zeros((64, 64, 3), np.uint8)
        art = signart.sign_face(key, 64)
        raw = np.full((64, 64, 3), 128, np.uint8)
        hh, ww = art.shape[:2]
        oy, ox = (64 - hh) // 2, (64 - ww) // 2
        raw[oy:oy + hh, ox:ox + ww] = signart.over(art, 128).astype(np.uint8)
        pair = np.hstack([cam, np.full((64, 2, 3), 255, np.uint8), raw])
        pair = cv2.resize(pair, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
        tile = _label(pair, key[:22], 0.4)
        tiles.append(np.pad(tile, ((2, 2), (2, 2), (0, 0))))
    per_row = grid.shape[1] // tiles[0].shape[1]
    rows = []
    for i in range(0, len(tiles), per_row):
        row = np.hstack(tiles[i:i + per_row])
        rows.append(np.pad(row, ((0, 0), (0, grid.shape[1] - row.shape[1]), (0, 0))))
    title = _label(np.zeros((0, grid.shape[1], 3), np.uint8),
                   f'class crops at 64 px (left: through the camera at {crop_distance:.0f} m, '
                   'right: raw art), shown 2x', 0.5)
    sheet = np.vstack([grid, title] + rows)
    cv2.imwrite(out_png, sheet)
    return sheet


def main(argv: list[str] | None = None) -> None:
    """Command line: ``python -m workzone_ros.sim.sheet OUT_PNG [--seed N]``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('out_png', nargs='?', default='/tmp/contact_sheet.png')
    ap.add_argument('--seed', type=int, default=0)
    args = ap.parse_args(argv)
    make_contact_sheet(args.out_png, args.seed)
    print(args.out_png)


if __name__ == '__main__':
    main()
