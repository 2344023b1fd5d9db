"""``workzone-ros evaluate general``: Cahail et al.'s results table for the general sign
recogniser (core/general) on held-out renders, and false signs on the real clips.

Renders.  Every scenario seed is a :func:`random_scenario` (random weather, road, work zone,
distractors) plus ten explicitly placed general signs (stop, yield, do not enter, yellow
warning, speed limit, guide, mile marker; right or left side, post or stand, numbered mile
markers) 80-760 m along the route.  Frames are rendered in-process with the full camera
model every ``--every`` frames (15 fps) and come with exact ground truth
(:class:`~workzone_ros.sim.camera.SignHit`, the category from the catalogue, as in
``/groundtruth/signs``):

* a general sign is *visible* when its box is at least ``--min-px`` (20) on the shorter side
  and at least ``--min-visible`` (0.8) of its face is in view; the others are don't-care;
* a detection *detects* a visible sign when their boxes have IoU >= 0.5 (one to one, best
  IoU first), and *recognises* it when its class is the sign's; a wrong class is a false
  recognition;
* a *false detection* overlaps no general sign (visible or not) with IoU >= 0.3; those on a
  work-zone sign (IoU >= 0.3) are counted apart too (orange must not come out).

Cahail et al. report total signs, signs detected, false detections, signs recognised and
false recognitions (counts, and percents of the signs; false detections as a percent of
their images); we report the same per frame, in all and per class, and the mile numbers
read (correct / wrong / unread) on visible mile markers.

``--mile-hd WxH`` (e.g. ``1280x720``; default off): every rendered frame with a mile marker
in view (ground truth) is rendered again at that instant with a WxH camera of the same
horizontal field of view (:func:`hd_camera`), the detector runs on it and the mile markers
are scored with a separate table (the same rules, ``--min-px`` in the HD frame's pixels):
report key ``renders.mile_hd`` (frames, visible mile markers, detected, recognised, mile
numbers read correct / wrong / unread, by distance).  A D10-1 is 0.25 m wide, so at
1280x720 it mostly leaves the frame before it is 20 px wide: ``at_mile_min_px`` repeats the
table with ``--mile-min-px`` (12, the detector's smallest candidate) as the visible rule.  The
reader never guesses: a marker whose digits are too small is unread.  ``--mile-work-width
N`` runs the detector on the HD frames with ``work_width`` N (default: the same detector,
whose colour masks work at 640 px).

Real clips (``--real``, default ../shared/realdata/us_workzone_video): general signs per
frame on every clip, by class; whether the STOP sign in houston (frames 150-200) and the
yellow warning diamond in minneapolis (290-371) are recognised (share of those frames with a
detection of that class in the right half of the image).

Timing: milliseconds per frame (time.perf_counter) of :meth:`GeneralSignDetector.detect` on
the rendered frames at their size and scaled to 1280x720, p50 / p99.

``--verify cnn`` (default) evaluates the colour candidates verified by the CNN sign
classifier (``--model``, default ``config/models/sign_classifier_cnn.npz``);
``--verify templates`` the paper's pipeline (the baseline).

Usage::

    workzone-ros evaluate general --seeds 300-319 --every 4 --real --json out.json \\
        --sheet docs/images/general_signs_sheet.jpg
    workzone-ros evaluate general --verify templates --seeds 300-319 --every 4 --real
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path
from typing import Any, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core import signs as catalogue
from workzone_ros.core.general import GENERAL_CLASSES, GeneralConfig, GeneralSignDetector
from workzone_ros.tools.outputs import print_json, seed_list

__all__ = ['main', 'make_specs', 'Table', 'iou', 'REAL_TARGETS', 'frame_size', 'hd_camera']

REALDATA = Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata'
#: Real clip -> (class, first frame, last frame) of the general sign in it (README, by eye).
REAL_TARGETS = {'houston.mp4': ('stop', 150, 200),
                'minneapolis.mp4': ('warning_diamond', 290, 371)}
REAL_CLIPS = ('charlotte.mp4', 'denver.mp4', 'houston.mp4', 'minneapolis.mp4', 'chicago.mp4',
              'san_francisco.mp4')
#: Explicit general signs per scenario, in this order (cycled).
_PLACED = ('stop', 'yield', 'do_not_enter', 'warning_diamond', 'speed_limit', 'guide',
           'mile_marker', 'stop', 'warning_diamond', 'speed_limit')
_COLOURS = {'red': (40, 40, 230), 'yellow': (0, 220, 255), 'white': (255, 255, 255),
            'green': (60, 200, 60)}


def make_specs(seeds: Sequence[int]) -> list:
    """(spec, seed) pairs: a random scenario per seed with ten general signs placed on it."""
    from workzone_ros.sim import scenario as sc
    specs = []
    for seed in seeds:
        rng = np.random.default_rng([seed, 0x6e5])
        spec = sc.random_scenario(seed)
        extra = []
        for i, key in enumerate(_PLACED):
            s = 80.0 + 75.0 * i + float(rng.uniform(-10, 10))
            side = 'left' if rng.random() < 0.3 else 'right'
            mount = 'stand' if key in ('warning_diamond', 'stop') and rng.random() < 0.3 \
                else 'post'
            value = int(rng.integers(1, 400)) if key == 'mile_marker' else (
                int(rng.choice([55, 60, 65, 70])) if key == 'speed_limit' else None)
            extra.append(sc.SignSpec(key, round(s, 1), side=side, speed_value=value,
                                     mount=mount))
        specs.append((replace(spec, name=f'{spec.name}_general',
                              signs=spec.signs + tuple(extra)), seed))
    return specs


def iou(a, b) -> float:
    """IoU of two (x, y, w, h) boxes."""
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def _match(dets: Sequence, gts: Sequence, tau: float) -> list[tuple[int, int]]:
    """Greedy one-to-one (det, gt) pairs with IoU >= tau, best first."""
    pairs = sorted(((iou(d.box, g.box), i, j) for i, d in enumerate(dets)
                    for j, g in enumerate(gts)), reverse=True)
    used_d, used_g, out = set(), set(), []
    for v, i, j in pairs:
        if v < tau or i in used_d or j in used_g:
            continue
        used_d.add(i)
        used_g.add(j)
        out.append((i, j))
    return out


class Table:
    """Cahail et al.'s table, in all and per class."""

    def __init__(self) -> None:
        self.n: dict = defaultdict(lambda: defaultdict(int))
        self.frames = 0
        self.frames_with_false = 0
        self.mile = defaultdict(int)
        self.confusion: dict = defaultdict(lambda: defaultdict(int))

    def add(self, dets: Sequence, hits: Sequence, truth: dict, min_px: float,
            min_visible: float) -> list:
        """One frame: detections, every SignHit, sign id -> mile number.  Returns the
        (gt, det or None) pairs of the visible general signs (for the sheet)."""
        self.frames += 1
        general = [h for h in hits if catalogue.get(h.class_key).category == 'general']
        visible = [h for h in general if min(h.box[2:]) >= min_px
                   and h.visible_fraction >= min_visible]
        pairs = dict((j, i) for i, j in _match(dets, visible, 0.5))
        for j, g in enumerate(visible):
            row = self.n[g.class_key]
            row['total'] += 1
            if j not in pairs:
                continue
            d = dets[pairs[j]]
            row['detected'] += 1
            self.confusion[g.class_key][d.class_key] += 1
            row['recognised' if d.class_key == g.class_key else 'false_recognition'] += 1
            if g.class_key == 'mile_marker' and d.class_key == 'mile_marker':
                want = truth.get(g.sign_id)
                self.mile['read_correct' if d.mile == want else
                          'unread' if d.mile is None else 'read_wrong'] += 1
        matched = set(pairs.values())
        false = 0
        for i, d in enumerate(dets):
            if i in matched or any(iou(d.box, h.box) >= 0.3 for h in general):
                continue
            false += 1
            self.n[d.class_key]['false_detection'] += 1
            if any(iou(d.box, h.box) >= 0.3 for h in hits
                   if catalogue.get(h.class_key).category == 'workzone'):
                self.n[d.class_key]['false_on_workzone_sign'] += 1
        self.frames_with_false += bool(false)
        return [(g, dets[pairs[j]] if j in pairs else None) for j, g in enumerate(visible)]

    def summary(self) -> dict:
        """The table: all classes and per class."""
        def row(c: dict) -> dict:
            t = c.get('total', 0)
            out = {k: c.get(k, 0) for k in ('total', 'detected', 'recognised',
                                            'false_recognition', 'false_detection',
                                            'false_on_workzone_sign')}
            for k in ('detected', 'recognised', 'false_recognition'):
                out[f'{k}_pct'] = round(100.0 * out[k] / t, 2) if t else None
            return out
        total: dict = defaultdict(int)
        for c in self.n.values():
            for k, v in c.items():
                total[k] += v
        out = {'frames': self.frames, 'all': row(total),
               'frames_with_false_detection_pct': round(
                   100.0 * self.frames_with_false / max(1, self.frames), 2),
               'false_detections_per_frame': round(total['false_detection']
                                                   / max(1, self.frames), 4),
               'per_class': {k: row(self.n[k]) for k in GENERAL_CLASSES if k in self.n},
               'confusion': {k: dict(v) for k, v in self.confusion.items()},
               'mile_numbers': dict(self.mile)}
        return out


def draw(img: np.ndarray, dets: Sequence, gts: Sequence = (), label: str = '') -> np.ndarray:
    """Overlay: ground truth thin green, detections in their colour with class and score."""
    out = img.copy()
    for g in gts:
        x, y, w, h = g
        cv2.rectangle(out, (x, y), (x + w, y + h), (0, 255, 0), 1)
    for d in dets:
        x, y, w, h = d.box
        col = _COLOURS.get(d.colour, (255, 0, 255))
        cv2.rectangle(out, (x, y), (x + w, y + h), col, 2)
        text = f'{d.class_key} {d.score:.2f}' + (f' mile {d.mile}' if d.mile is not None else '')
        cv2.putText(out, text, (x, max(10, y - 3)), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3)
        cv2.putText(out, text, (x, max(10, y - 3)), cv2.FONT_HERSHEY_SIMPLEX, 0.4, col, 1)
    if label:
        cv2.putText(out, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 3)
        cv2.putText(out, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1)
    return out


def sheet(tiles: list[np.ndarray], path: str, cols: int = 3, width: int = 340) -> None:
    """Write ``tiles`` as a contact sheet (JPEG quality 75 for .jpg)."""
    if not tiles:
        return
    tiles = [cv2.resize(t, (width, int(width * t.shape[0] / t.shape[1]))) for t in tiles]
    h = max(t.shape[0] for t in tiles)
    tiles = [cv2.copyMakeBorder(t, 0, h - t.shape[0], 0, 0, cv2.BORDER_CONSTANT) for t in tiles]
    while len(tiles) % cols:
        tiles.append(np.zeros_like(tiles[0]))
    img = np.vstack([np.hstack(tiles[i:i + cols]) for i in range(0, len(tiles), cols)])
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(path, img, [cv2.IMWRITE_JPEG_QUALITY, 75])


def _pct(v: Sequence[float]) -> dict:
    a = np.asarray(v, float) * 1e3
    return {'p50': round(float(np.percentile(a, 50)), 3), 'p99': round(float(np.percentile(
        a, 99)), 3), 'frames': int(a.size)} if a.size else {}


def frame_size(text: str) -> tuple[int, int]:
    """``'1280x720'`` -> (1280, 720); argparse type of ``--mile-hd``."""
    parts = text.lower().strip().split('x')
    try:
        w, h = (int(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected WxH, e.g. 1280x720, got {text!r}') from None
    if not (160 <= w <= 7680 and 120 <= h <= 4320):
        raise argparse.ArgumentTypeError(f'frame size {w}x{h} out of range '
                                         '(160-7680 x 120-4320)')
    return w, h


def hd_camera(width: int, height: int):
    """The simulator's camera at ``width`` x ``height``: the same horizontal field of view
    (60 deg), square pixels, principal point at the same relative place and the same
    distortion (normalised coordinates); a wider aspect narrows the vertical view."""
    from workzone_ros.sim.world import DEFAULT_CAMERA as cam
    f = width / cam.width
    return replace(cam, width=int(width), height=int(height), fx=cam.fx * f, fy=cam.fy * f,
                   cx=cam.cx * f, cy=cam.cy * height / cam.height)


#: Distance bins (m) of the mile-marker table at HD.
_MILE_BINS = (0.0, 25.0, 50.0, 75.0, 100.0, 150.0, float('inf'))


class MileHD:
    """Mile markers re-rendered at HD: a separate :class:`Table` and reads by distance, under
    the ``--min-px`` rule and under ``--mile-min-px`` (a D10-1 is 0.25 m wide: at 1280x720
    it mostly leaves the frame before it is 20 px wide)."""

    def __init__(self, size: tuple[int, int], min_px: float, mile_min_px: float) -> None:
        self.size = size
        self.rules = {px: (Table(), defaultdict(lambda: defaultdict(int)))
                      for px in dict.fromkeys((float(min_px), float(mile_min_px)))}
        self.min_px = float(min_px)
        self.times: list = []
        self.wrong: list = []                   # wrong reads at --min-px

    def add(self, dets: Sequence, hits: Sequence, truth: dict, min_visible: float) -> None:
        """One HD frame (detections, every SignHit, sign id -> mile number)."""
        for px, (table, bins) in self.rules.items():
            for g, d in table.add(dets, hits, truth, px, min_visible):
                if g.class_key != 'mile_marker':
                    continue
                lo = max(b for b in _MILE_BINS if b <= g.distance_m)
                row = bins[f'{lo:g}-{_MILE_BINS[_MILE_BINS.index(lo) + 1]:g}']
                row['visible'] += 1
                if d is None or d.class_key != 'mile_marker':
                    continue
                row['recognised'] += 1
                want = truth.get(g.sign_id)
                row['read_correct' if d.mile == want else
                    'unread' if d.mile is None else 'read_wrong'] += 1
                if d.mile is not None and d.mile != want and px == self.min_px:
                    self.wrong.append({'truth': want, 'read': d.mile,
                                       'confidence': d.mile_confidence,
                                       'distance_m': round(g.distance_m, 1),
                                       'box': list(g.box)})

    @staticmethod
    def _rule(px: float, table: Table, bins: dict) -> dict:
        s = table.summary()
        row = s['per_class'].get('mile_marker', {})
        return {'min_px': px, 'visible_mile_markers': row.get('total', 0),
                'detected': row.get('detected', 0), 'recognised': row.get('recognised', 0),
                'false_recognition': row.get('false_recognition', 0),
                'confused_with': s['confusion'].get('mile_marker', {}),
                'mile_numbers': {k: s['mile_numbers'].get(k, 0)
                                 for k in ('read_correct', 'read_wrong', 'unread')},
                'by_distance_m': {k: dict(bins[k]) for k in sorted(
                    bins, key=lambda b: float(b.split('-')[0]))},
                'all_general_signs': s['all']}

    def summary(self) -> dict:
        """frames, visible / detected / recognised mile markers and the numbers read (at
        ``--min-px``; ``at_mile_min_px``: the same at ``--mile-min-px``)."""
        out: dict[str, Any] = {'frame_size': list(self.size)}
        for px, (table, bins) in self.rules.items():
            out['frames'] = table.frames
            if px == self.min_px:
                out.update(self._rule(px, table, bins))
            else:
                out['at_mile_min_px'] = self._rule(px, table, bins)
        out['wrong_reads'] = self.wrong
        out['ms_per_frame'] = _pct(self.times)
        return out


def _mile_in_view(hits: Sequence) -> bool:
    return any(h.class_key == 'mile_marker' and h.visible_fraction > 0 for h in hits)


def evaluate_renders(specs, det: GeneralSignDetector, args, tiles: list) -> dict:
    """Cahail et al.'s table over rendered frames of ``specs``; timing at native size and 720p."""
    from workzone_ros.sim.camera import CameraRenderer
    from workzone_ros.sim.scenario import FPS, build_scene
    from workzone_ros.sim.world import DEFAULT_CAMERA
    table, by_weather = Table(), defaultdict(Table)
    mile_size = getattr(args, 'mile_hd', None)
    mile_hd = MileHD(mile_size, args.min_px, getattr(args, 'mile_min_px', None)
                     or args.min_px) if mile_size else None
    work = getattr(args, 'mile_work_width', None)
    hd_det = GeneralSignDetector(replace(det.config, work_width=int(work)), classifier=(
        det.classifier if det.config.verify == 'cnn' else None)) if mile_size and work else det
    times, times_hd, cpu, cpu_hd = [], [], [], []
    for spec, seed in specs:
        scene, ego, _ = build_scene(spec, seed)
        truth = {s.object_id: (s.speed_value if s.speed_value is not None else 123)
                 for s in scene.signs if s.class_key == 'mile_marker'}
        renderer = CameraRenderer(scene, DEFAULT_CAMERA, seed=seed)
        hd_renderer = CameraRenderer(scene, hd_camera(*mile_size), seed=seed) \
            if mile_hd else None
        for k in range(0, int(spec.duration * FPS), args.every):
            res = renderer.render(k / FPS, ego.base_pose(k / FPS), k)
            t0, c0 = time.perf_counter(), time.process_time()
            dets = det.detect(res.image)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            if len(times_hd) < args.hd_frames and k % (2 * args.every) == 0:
                hd = cv2.resize(res.image, (1280, 720), interpolation=cv2.INTER_LINEAR)
                t0, c0 = time.perf_counter(), time.process_time()
                det.detect(hd)
                times_hd.append(time.perf_counter() - t0)
                cpu_hd.append(time.process_time() - c0)
            if mile_hd is not None and hd_renderer is not None and _mile_in_view(res.signs):
                hd_res = hd_renderer.render(k / FPS, ego.base_pose(k / FPS), k)
                t0 = time.perf_counter()
                hd_dets = hd_det.detect(hd_res.image)
                mile_hd.times.append(time.perf_counter() - t0)
                mile_hd.add(hd_dets, hd_res.signs, truth, args.min_visible)
            pairs = table.add(dets, res.signs, truth, args.min_px, args.min_visible)
            by_weather[spec.weather].add(dets, res.signs, truth, args.min_px,
                                         args.min_visible)
            missed = any(d is None or d.class_key != g.class_key for g, d in pairs)
            if tiles is not None and pairs and len(tiles) < args.sheet_n and (
                    missed or k % (8 * args.every) == 0):
                tiles.append(draw(res.image, dets, [g.box for g, _ in pairs],
                                  f'{spec.name} {spec.weather} #{k}'))
        print(f'{spec.name}: {table.frames} frames so far', file=sys.stderr, flush=True)
    out = table.summary()
    out['by_weather'] = {w: {'frames': t.frames, 'all': t.summary()['all'],
                             'false_detections_per_frame': t.summary()[
                                 'false_detections_per_frame']}
                         for w, t in sorted(by_weather.items())}
    # wall time (perf_counter) and the process's CPU time: on a shared machine the first
    # includes waiting for a core
    out['ms_per_frame'] = {'native': _pct(times), 'hd_1280x720': _pct(times_hd),
                           'native_cpu': _pct(cpu), 'hd_1280x720_cpu': _pct(cpu_hd)}
    out['frame_size'] = [DEFAULT_CAMERA.width, DEFAULT_CAMERA.height]
    if mile_hd is not None:
        out['mile_hd'] = mile_hd.summary()
        out['mile_hd']['work_width'] = hd_det.config.work_width
    return out


def evaluate_real(folder: Path, det: GeneralSignDetector, args, tiles: list) -> dict:
    """Per clip: general signs per frame by class; the houston STOP and the minneapolis
    warning diamond recognised (share of their frames)."""
    out: dict[str, Any] = {}
    for clip in REAL_CLIPS:
        path = folder / clip
        if not path.exists():
            out[clip] = {'skipped': f'{path} not found'}
            continue
        target = REAL_TARGETS.get(clip)
        cap = cv2.VideoCapture(str(path))
        counts: dict = defaultdict(int)
        frames, hit, in_range, k = 0, 0, 0, -1
        while True:
            ok, img = cap.read()
            if not ok:
                break
            k += 1
            frames += 1
            dets = det.detect(img)
            in_target = target is not None and target[1] <= k <= target[2]
            for d in dets:
                on_target = in_target and d.class_key == target[0] and \
                    d.box[0] + d.box[2] / 2 > img.shape[1] / 2
                counts['target' if on_target else d.class_key] += 1
            if in_target:
                in_range += 1
                hit += any(d.class_key == target[0] and d.box[0] + d.box[2] / 2
                           > img.shape[1] / 2 for d in dets)
            if tiles is not None and (k % 60 == 30 or (in_target and k % 20 == 0)):
                tiles.append(draw(img, dets, (), f'{clip} #{k}'))
        cap.release()
        others = {c: v for c, v in counts.items() if c != 'target'}
        r: dict[str, Any] = {'frames': frames,
                             'other_general_signs_per_frame': round(sum(others.values())
                                                                    / max(1, frames), 4),
                             'other_by_class': others}
        if target is not None:
            r['target'] = {'class': target[0], 'frames': list(target[1:]),
                           'recognised_share': round(hit / max(1, in_range), 3)}
        out[clip] = r
    return out


def main(argv: Optional[list[str]] = None) -> int:
    """Run the evaluation; prints JSON, returns the exit status."""
    p = argparse.ArgumentParser(prog='workzone-ros evaluate general', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--seeds', default='300-319',
                   help="scenario seeds, e.g. '300-319' (development seeds: 0-7)")
    p.add_argument('--every', type=int, default=4, help='render every n-th frame (15 fps)')
    p.add_argument('--min-px', type=float, default=20.0, help='visible: shorter side, px')
    p.add_argument('--min-visible', type=float, default=0.8, help='visible: face share')
    p.add_argument('--select-by', choices=('ncc', 'score'), default='ncc',
                   help="red template rule: best correlation, or Cahail et al.'s score")
    p.add_argument('--verify', choices=('cnn', 'templates'), default='cnn',
                   help="'cnn': colour candidates verified by the CNN sign classifier "
                        "(default); 'templates': the paper's blob tests and red templates")
    p.add_argument('--model', help='sign classifier for --verify cnn (default '
                                   'config/models/sign_classifier_cnn.npz)')
    p.add_argument('--hd-frames', type=int, default=150, help='frames timed at 1280x720')
    p.add_argument('--mile-hd', type=frame_size, metavar='WxH',
                   help='re-render frames with a mile marker in view at WxH (e.g. 1280x720, '
                        'same horizontal field of view) and score the mile markers apart '
                        '(report key renders.mile_hd); default off')
    p.add_argument('--mile-min-px', type=float, default=12.0,
                   help='with --mile-hd: also score the HD mile markers with this visible '
                        'shorter side, px (report key renders.mile_hd.at_mile_min_px)')
    p.add_argument('--mile-work-width', type=int,
                   help="with --mile-hd: the detector's work_width on the HD frames "
                        '(default: the same detector, work_width 640)')
    p.add_argument('--no-renders', action='store_true', help='skip the rendered frames')
    p.add_argument('--real', nargs='?', const=str(REALDATA / 'us_workzone_video'),
                   help='real clips folder (default ../shared/realdata/us_workzone_video)')
    p.add_argument('--json', help='write the report here')
    p.add_argument('--sheet', help='contact sheet of renders and real frames (.jpg / .png)')
    p.add_argument('--sheet-n', type=int, default=9, help='render tiles on the sheet')
    args = p.parse_args(argv)
    cv2.setNumThreads(1)
    det = GeneralSignDetector(GeneralConfig(select_by=args.select_by, verify=args.verify),
                              classifier=args.model)
    report: dict[str, Any] = {'seeds': args.seeds, 'every': args.every,
                              'visible_rule': f'shorter side >= {args.min_px} px and '
                                              f'visible fraction >= {args.min_visible}',
                              'select_by': args.select_by, 'verify': args.verify}
    if args.verify == 'cnn':
        report['model'] = args.model or 'config/models/sign_classifier_cnn.npz'
        det.classifier                          # load it before the timed frames
    tiles: Optional[list] = [] if args.sheet else None
    if not args.no_renders:
        report['renders'] = evaluate_renders(make_specs(seed_list(args.seeds)), det, args,
                                             tiles)
    if args.real:
        real_tiles: Optional[list] = [] if args.sheet else None
        report['real'] = evaluate_real(Path(args.real), det, args, real_tiles)
        if tiles is not None and real_tiles:
            pick = [t for t in real_tiles]
            tiles += pick[:: max(1, len(pick) // 9)][:9]
    if args.sheet and tiles:
        sheet(tiles, args.sheet)
    print_json(report, args.json, default=float)
    return 0


if __name__ == '__main__':
    sys.exit(main())
