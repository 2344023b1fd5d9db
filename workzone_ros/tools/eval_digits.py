"""Measure the speed limit reader (core/digits.py) on simulator frames.

Every scenario seed draws a workzone speed limit (a multiple of 5 in 5..85) for the
scenario's own R2-1 + WORK ZONE sign and two more explicitly placed ones (other values,
post or stand mounts); the ego drives past them and frames are rendered with the full camera
model (weather, exposure, motion blur, noise, JPEG) when each sign is 11-95 m ahead.  Each
sign's ground-truth box is grown by 10 % a side and, on half of the crops, jittered like a
detector's localisation (centre shifted and size scaled by 10-20 %); the crop is cut by the
image border, never padded.  The truth is the sign's ``speed_value`` in the scene.

Reported per bin of the sign's height in the frame (ground-truth box, px): correct, wrong,
unread; for all crops, and separately for the crops that hold the whole number (the sign at
least 95 % visible, not cut by the image border or hidden, and the number's rows and
columns with a little white around them inside the crop); and the reader's time per crop.

Usage::

    python -m workzone_ros.tools.eval_digits --seeds 1000-1039 [--scenario random|NAME,...]
        [--per-sign 12] [--jitter 0.5] [--json out.json] [--sheet /tmp/digits_sheet.png]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass, replace
from typing import Iterator, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core import digits
from workzone_ros.tools.outputs import seed_list, tile_grid

__all__ = ['main', 'Sample', 'make_specs', 'samples', 'export_samples', 'summarise',
           'contact_sheet', 'BINS']

#: Sign-height bins (px) of the report: [lo, hi).
BINS: tuple[tuple[int, int], ...] = ((0, 16), (16, 24), (24, 32), (32, 48), (48, 64),
                                     (64, 96), (96, 10_000))
KEY = 'work_zone_speed_limit'
# The number on the face: rows 0.67-0.90 and columns 0.13-0.86 of the sign (measured on the
# sign art, every value), with a margin of 0.05 of the sign's width (a digit touching the
# crop's edge cannot be told from a cut one).
_NUMBER_ROWS, _NUMBER_COLS = (0.67, 0.91), (0.08, 0.91)


@dataclass
class Sample:
    """One crop and what the reader made of it."""

    scenario: str
    weather: str
    frame: int
    sign_id: int
    truth: int
    box_h: int
    visible: float
    jittered: bool
    whole_number: bool
    value: Optional[int]
    confidence: float
    reason: str
    ms: float
    box: tuple = ()
    crop_box: tuple = ()

    @property
    def outcome(self) -> str:
        """'correct', 'wrong' or 'unread'."""
        if self.value is None:
            return 'unread'
        return 'correct' if self.value == self.truth else 'wrong'


def make_specs(seeds: Sequence[int], scenario: str = 'random') -> list:
    """Scenario specs, one per seed (and per name of a comma-separated ``scenario``), with
    drawn speed limits on three speed limit signs.

    'random' uses :func:`random_scenario` (random weather, road, distractors); a library
    name keeps its layout and cycles the weather with the seed.
    """
    names = [n.strip() for n in scenario.split(',') if n.strip()]
    if len(names) > 1:
        return [spec for name in names for spec in make_specs(seeds, name)]
    from workzone_ros.sim import scenario as sc
    specs = []
    for seed in seeds:
        rng = np.random.default_rng([seed, 0xd161])
        values = [int(v) for v in rng.choice(digits.VALID_SPEEDS, 3, replace=False)]
        if scenario == 'random':
            spec = sc.random_scenario(seed)
        else:
            spec = sc.load_scenario(scenario, seed)
            spec = replace(spec, weather=sc.WEATHERS[seed % len(sc.WEATHERS)])
        wz = spec.workzone or sc.WorkzoneSpec(taper_s=600.0)
        first = max(60.0, wz.taper_s - wz.advance) + 70.0
        extra = tuple(sc.SignSpec(KEY, first + 95.0 * i, speed_value=v,
                                  mount='stand' if rng.random() < 0.4 else 'post')
                      for i, v in enumerate(values[1:]))
        spec = replace(spec, name=f'{spec.name}_{seed}', workzone=replace(
            wz, speed_limit=values[0]), signs=spec.signs + extra)
        specs.append((spec, seed))
    return specs


def _crop_box(box, rng: np.random.Generator, jitter: bool) -> tuple[float, float, float, float]:
    """The box grown by 10 % a side; if ``jitter``, shifted and scaled by 10-20 %."""
    x, y, w, h = (float(v) for v in box)
    cx, cy, w, h = x + w / 2, y + h / 2, w * 1.2, h * 1.2
    if jitter:
        def amt() -> float:
            return float(rng.uniform(0.10, 0.20)) * (1 if rng.random() < 0.5 else -1)
        cx, cy = cx + amt() * w, cy + amt() * h
        s = 1.0 + amt()
        w, h = w * s, h * s
    return cx - w / 2, cy - h / 2, w, h


def _cut(img: np.ndarray, box) -> Optional[np.ndarray]:
    """``img`` inside ``box`` (x, y, w, h), cut by the image border; None if empty."""
    H, W = img.shape[:2]
    x, y, w, h = box
    x0, y0 = max(0, int(round(x))), max(0, int(round(y)))
    x1, y1 = min(W, int(round(x + w))), min(H, int(round(y + h)))
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    return img[y0:y1, x0:x1]


def _holds_number(sign_box, crop_box, shape) -> bool:
    """True when the number's rows and columns of the sign (and a little white around it)
    lie inside the (cut) crop."""
    x, y, w, h = sign_box
    cx, cy, cw, ch = crop_box
    H, W = shape[:2]
    left, top = max(cx, 0.0), max(cy, 0.0)
    right, bottom = min(cx + cw, W), min(cy + ch, H)
    return (left <= x + _NUMBER_COLS[0] * w and right >= x + _NUMBER_COLS[1] * w and
            top <= y + _NUMBER_ROWS[0] * h and bottom >= y + _NUMBER_ROWS[1] * h)


def _sign_times(scene, ego, duration: float, per_sign: int) -> list[tuple[float, int]]:
    """(time, sign id) when each speed limit sign is 95..11 m ahead, ``per_sign`` each
    (distances spaced evenly in 1 / distance, so sign heights spread evenly)."""
    road = scene.road
    out = []
    for sp in scene.signs:
        if sp.class_key != KEY:
            continue
        s_sign = float(road.to_frenet(np.array([sp.center[0]]), np.array([sp.center[1]]))[0][0])
        for inv in np.linspace(1 / 95.0, 1 / 11.0, per_sign):
            t = float(ego.t_at(s_sign - 1.0 / inv))
            if 0.0 <= t <= duration:
                out.append((t, sp.object_id))
    return out


def samples(specs, per_sign: int = 12, jitter: float = 0.5,
            keep_crops: bool = False) -> Iterator[tuple[Sample, Optional[np.ndarray]]]:
    """Render, crop and read every speed limit sign of ``specs`` ((spec, seed) pairs)."""
    from workzone_ros.sim.camera import CameraRenderer
    from workzone_ros.sim.scenario import FPS, build_scene
    from workzone_ros.sim.world import DEFAULT_CAMERA
    for spec, seed in specs:
        scene, ego, _ = build_scene(spec, seed)
        truth = {s.object_id: s.speed_value for s in scene.signs if s.class_key == KEY}
        renderer = CameraRenderer(scene, DEFAULT_CAMERA, seed=seed)
        rng = np.random.default_rng([seed, 0xc0b])
        for t, sid in _sign_times(scene, ego, spec.duration, per_sign):
            k = int(round(t * FPS))
            res = renderer.render(k / FPS, ego.base_pose(k / FPS), k)
            hit = next((h for h in res.signs if h.sign_id == sid), None)
            if hit is None or hit.visible_fraction < 0.5:
                continue
            jit = bool(rng.random() < jitter)
            box = _crop_box(hit.box, rng, jit)
            crop = _cut(res.image, box)
            if crop is None:
                continue
            t0 = time.perf_counter()
            r = digits.read_speed_limit(crop)
            ms = (time.perf_counter() - t0) * 1e3
            s = Sample(spec.name, spec.weather, k, sid, int(truth[sid]), int(hit.box[3]),
                       round(float(hit.visible_fraction), 3), jit,
                       hit.visible_fraction >= 0.95 and
                       _holds_number(hit.box, box, res.image.shape), r.value, r.confidence,
                       r.reason, round(ms, 3), tuple(int(v) for v in hit.box),
                       tuple(round(float(v), 1) for v in box))
            yield s, (crop.copy() if keep_crops else None)


def export_samples(specs, out_dir: str, per_class: int = 400, size: int = 64
                   ) -> Iterator[tuple[Sample, Optional[np.ndarray]]]:
    """Read the ``work_zone_speed_limit`` crops that ``workzone-ros synth crops``
    (:func:`workzone_ros.sim.writer.export_crops`) writes for ``specs``: square boxes jittered
    by 10-20 % around the sign, resized to ``size`` px (the classifier's input).  The truth
    comes from the scene (``index.csv`` names the scenario and the sign's object id).  Every
    spec is rendered with the first spec's seed (``export_crops`` takes one)."""
    import csv
    from pathlib import Path

    from workzone_ros.sim import writer
    from workzone_ros.sim.scenario import build_scene
    seed = specs[0][1] if specs else 0           # export_crops renders every spec with one
    truth, weather = {}, {}
    for spec, _ in specs:
        scene, _, _ = build_scene(spec, seed)
        weather[spec.name] = spec.weather
        for sp in scene.signs:
            if sp.class_key == KEY:
                truth[(spec.name, sp.object_id)] = int(sp.speed_value)
    writer.export_crops(out_dir, [spec for spec, _ in specs], seed, per_class, size,
                        progress=None)
    with open(Path(out_dir) / 'index.csv') as fh:
        rows = [r for r in csv.DictReader(fh) if r['class_key'] == KEY]
    for r in rows:
        crop = cv2.imread(str(Path(out_dir) / r['path']))
        t0 = time.perf_counter()
        res = digits.read_speed_limit(crop)
        ms = (time.perf_counter() - t0) * 1e3
        box = tuple(float(r[k]) for k in ('box_x', 'box_y', 'box_w', 'box_h'))
        cbox = tuple(float(r[k]) for k in ('crop_x', 'crop_y', 'crop_w', 'crop_h'))
        s = Sample(r['scenario'], weather.get(r['scenario'], ''), int(r['frame']),
                   int(r['object_id']), truth[(r['scenario'], int(r['object_id']))],
                   int(round(box[3])), 1.0, True, _holds_number(box, cbox, (480, 640)),
                   res.value, res.confidence, res.reason, round(ms, 3), box, cbox)
        yield s, crop


def _bin_name(lo: int, hi: int) -> str:
    return f'{lo}-{hi}' if hi < 10_000 else f'>={lo}'


def summarise(rows: Sequence[Sample], min_h: int = 24) -> dict:
    """Counts per size bin and in total (>= ``min_h`` px), for all crops and for the crops
    that hold the whole number."""
    out: dict = {}
    for subset, keep in (('all', lambda s: True), ('whole_number', lambda s: s.whole_number)):
        table = {}
        for lo, hi in BINS + ((min_h, 10_000),):
            sel = [s for s in rows if keep(s) and lo <= s.box_h < hi]
            name = _bin_name(lo, hi) if (lo, hi) != (min_h, 10_000) else f'total>={min_h}'
            counts = {k: sum(s.outcome == k for s in sel) for k in ('correct', 'wrong',
                                                                     'unread')}
            table[name] = {'n': len(sel), **counts}
        out[subset] = table
    ms = np.array([s.ms for s in rows]) if rows else np.zeros(1)
    out['ms_per_read'] = {'mean': round(float(ms.mean()), 3),
                          'median': round(float(np.median(ms)), 3),
                          'p95': round(float(np.percentile(ms, 95)), 3)}
    reasons: dict[str, int] = {}
    for s in rows:
        if s.value is None and s.box_h >= min_h:
            reasons[s.reason] = reasons.get(s.reason, 0) + 1
    out['unread_reasons_ge_min_h'] = dict(sorted(reasons.items(), key=lambda kv: -kv[1]))
    return out


def _format(summary: dict) -> str:
    lines = []
    for subset in ('all', 'whole_number'):
        lines.append(f'{subset}:')
        lines.append(f'  {"height px":>11} {"n":>5} {"correct":>13} {"wrong":>11} '
                     f'{"unread":>13}')
        for name, c in summary[subset].items():
            n = max(c['n'], 1)
            lines.append(f'  {name:>11} {c["n"]:5d} {c["correct"]:5d} '
                         f'({100 * c["correct"] / n:5.1f} %) {c["wrong"]:3d} '
                         f'({100 * c["wrong"] / n:4.1f} %) {c["unread"]:5d} '
                         f'({100 * c["unread"] / n:5.1f} %)')
    m = summary['ms_per_read']
    lines.append(f'ms per read: mean {m["mean"]}, median {m["median"]}, p95 {m["p95"]}')
    lines.append(f'unread reasons (>= min height): {summary["unread_reasons_ge_min_h"]}')
    return '\n'.join(lines)


def contact_sheet(items: Sequence[tuple[Sample, np.ndarray]], path: str, cols: int = 16,
                  tile: int = 80) -> None:
    """A PNG of crops (scaled to ``tile`` px high) with truth / read: green correct, red
    wrong, grey unread."""
    colours = {'correct': (0, 170, 0), 'wrong': (0, 0, 230), 'unread': (150, 150, 150)}
    tiles = []
    for s, crop in items:
        f = tile / crop.shape[0]
        img = cv2.resize(crop, (min(tile, max(1, int(crop.shape[1] * f))), tile),
                         interpolation=cv2.INTER_NEAREST)
        t = np.full((tile + 30, tile, 3), 255, np.uint8)
        t[:tile, :img.shape[1]] = img
        read = '-' if s.value is None else str(s.value)
        cv2.putText(t, f'{s.truth}:{read} {s.box_h}', (2, tile + 12), cv2.FONT_HERSHEY_PLAIN,
                    0.9, colours[s.outcome], 1, cv2.LINE_AA)
        cv2.putText(t, s.reason[:12] if s.value is None else f'{s.confidence:.2f}',
                    (2, tile + 26), cv2.FONT_HERSHEY_PLAIN, 0.8, colours[s.outcome], 1,
                    cv2.LINE_AA)
        tiles.append(t)
    if tiles:
        cv2.imwrite(path, tile_grid(tiles, cols, fill=255))


def _sheet_items(items, n: int = 256):
    """Wrong reads first, then a spread of the rest (every k-th)."""
    wrong = [it for it in items if it[0].outcome == 'wrong']
    rest = [it for it in items if it[0].outcome != 'wrong']
    k = max(1, len(rest) // max(1, n - len(wrong)))
    return (wrong + rest[::k])[:n]


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point; prints the table, returns 0."""
    p = argparse.ArgumentParser(prog='eval_digits', description=__doc__.split('\n')[0])
    p.add_argument('--seeds', default='1000-1019', help="'A-B' or 'a,b,c'")
    p.add_argument('--scenario', default='random',
                   help="'random' or library scenario names, comma-separated")
    p.add_argument('--per-sign', type=int, default=12, help='crops per sign')
    p.add_argument('--jitter', type=float, default=0.5, help='share of jittered crops')
    p.add_argument('--min-height', type=int, default=24, help='sign height for the total')
    p.add_argument('--export', metavar='DIR',
                   help='instead: write `synth crops` (square, resized to 64 px) to DIR for '
                   'these scenarios and read those')
    p.add_argument('--json', help='write the summary and every sample here')
    p.add_argument('--sheet', help='contact sheet PNG of the reads')
    args = p.parse_args(argv)
    cv2.setNumThreads(1)
    specs = make_specs(seed_list(args.seeds), args.scenario)
    digits.warm_up()                         # train outside the timing
    if args.export:
        items = list(export_samples(specs, args.export))
    else:
        items = list(samples(specs, args.per_sign, args.jitter, keep_crops=bool(args.sheet)))
    rows = [s for s, _ in items]
    summary = summarise(rows, args.min_height)
    print(f'{len(rows)} crops from {len(specs)} scenarios ({args.scenario}, seeds '
          f'{args.seeds})')
    print(_format(summary))
    if args.json:
        with open(args.json, 'w') as fh:
            json.dump({'args': vars(args), 'summary': summary,
                       'samples': [asdict(s) for s in rows]}, fh, indent=1)
    if args.sheet:
        contact_sheet(_sheet_items(items), args.sheet)
        print(f'sheet {args.sheet}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
