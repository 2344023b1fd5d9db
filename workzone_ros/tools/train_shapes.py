"""``workzone-ros train shapes``: the sign-shape cascades of Balali and Golparvar-Fard (Balali and
Golparvar-Fard) from rendered crops.

Data: the crops ``workzone-ros synth crops`` exports (``workzone_ros.sim.writer.export_crops``:
every catalogue sign with detector-like box jitter of 10-20 %, plus background crops of
drums, cones, vehicles and roadside patches), for every library scenario of each ``--seeds``
seed plus ``--random R`` random scenarios per seed (weathers cycling), cached under
``--cache`` as ``workzone-ros train classifier`` caches them.  Each crop gives training
windows (:func:`training_windows`):

* a sign crop (shape from the catalogue, ``square`` -> ``rectangle``): the jittered crop as
  the detector would give it, and a window centred on the true face with a margin of 5-40 %
  of its side, each also mirrored (every shape is left-right symmetric);
* a background crop: the crop, its mirror and ``--sub-windows`` of the windows the scan
  slides over it at scales 0.75 and 1.25 (``ShapeCascade.scan``), so the stages see the
  negatives they will be shown.

The renders show stop, yield and do-not-enter signs (side roads) at 8-11 px only, so
``--composites N`` adds N crops per shape of the simulator's sign art pasted on rendered
background crops (:func:`composite_crops`).  Background crops that overlap a sign face and
sign faces under ``--min-side`` pixels are left out (:func:`load_renders`).

No real image is used: the real crops of ``test/data/real_crops`` only measure the result
(``workzone-ros evaluate shapes``).  Renders of seeds 5-7 are the held-out test set, so
keep them out of ``--seeds``.

Example (the shipped model, docs/shapes.md)::

    workzone-ros train shapes --seeds 0 1 2 3 4 --random 8
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.general import shapes as sh

__all__ = ['RenderedCrop', 'load_renders', 'training_windows', 'main']

DEFAULT_CACHE = Path('/tmp/workzone_ros_crops')
FRAME = (640, 480)          # the simulator camera (workzone_ros.sim.world.DEFAULT_CAMERA)


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


@dataclass
class RenderedCrop:
    """A rendered crop: the candidate as a detector gives it, and where the face is in it."""

    image: np.ndarray               # BGR, the part of the jittered box inside the frame
    class_key: str
    shape: str                      # sh.SHAPES or 'none'
    face: Optional[tuple]           # (x, y, w, h) of the true face in ``image`` (signs only)
    scenario: str
    seed: int
    side: float = float('inf')      # shorter side of the face in the frame, px (signs only)


def load_renders(specs: Sequence, cache: Path = DEFAULT_CACHE, per_class: int = 20,
                 size: int = 64, min_side: float = 0.0,
                 progress: Optional[Callable[[str], None]] = _say) -> list[RenderedCrop]:
    """Rendered crops of every ``(spec, seed)`` (rendered into ``cache`` when missing).

    A crop box that left the frame is cut to its visible part (as a detector's box is
    clipped); one with less than half inside is dropped.  Sign crops whose face is under
    ``min_side`` pixels (shorter side, in the frame) are dropped.  A background crop that
    overlaps a sign face exported from the same frame is dropped: ``export_crops`` checks
    its random patches against the signs but not the boxes of drums, cones and vehicles,
    and about one in six of those show a whole sign next to the object.
    """
    from workzone_ros.tools.train_classifier import _render_one
    out: list[RenderedCrop] = []
    t0 = time.monotonic()
    for n, (spec, seed) in enumerate(specs, 1):
        folder = _render_one(spec, seed, per_class, size, Path(cache))
        with open(folder / 'index.csv', newline='') as fh:
            rows = list(csv.DictReader(fh))
        faces: dict[str, list] = {}
        for r in rows:
            if r['class_key'] != 'background':
                faces.setdefault(r['frame'], []).append(
                    [float(r[k]) for k in ('box_x', 'box_y', 'box_w', 'box_h')])
        for r in rows:
            if r['class_key'] == 'background' and _touches(r, faces.get(r['frame'], ())):
                continue
            if r['class_key'] != 'background' and \
                    min(float(r['box_w']), float(r['box_h'])) < min_side:
                continue
            x, y, w, h = (float(r[k]) for k in ('crop_x', 'crop_y', 'crop_w', 'crop_h'))
            x0, y0 = max(x, 0.0), max(y, 0.0)
            x1, y1 = min(x + w, FRAME[0]), min(y + h, FRAME[1])
            if x1 <= x0 or y1 <= y0 or (x1 - x0) * (y1 - y0) < 0.5 * w * h:
                continue
            img = cv2.imread(str(folder / r['path']), cv2.IMREAD_COLOR)
            if img is None:
                continue
            fx, fy = img.shape[1] / w, img.shape[0] / h
            c0, r0 = int(round((x0 - x) * fx)), int(round((y0 - y) * fy))
            c1, r1 = int(round((x1 - x) * fx)), int(round((y1 - y) * fy))
            if c1 - c0 < 6 or r1 - r0 < 6:
                continue
            img = img[r0:r1, c0:c1]
            key = r['class_key']
            face, side = None, float('inf')
            if key != 'background':
                bx, by, bw, bh = (float(r[k]) for k in ('box_x', 'box_y', 'box_w', 'box_h'))
                face = ((bx - x) * fx - c0, (by - y) * fy - r0, bw * fx, bh * fy)
                side = min(bw, bh)
            out.append(RenderedCrop(img, key, sh.shape_of(key), face, spec.name, seed, side))
        if progress:
            progress(f'renders {n}/{len(specs)}: {spec.name} (seed {seed}) {len(rows)} crops, '
                     f'{time.monotonic() - t0:.0f} s')
    return out


def _touches(row: dict, faces) -> bool:
    x, y, w, h = (float(row[k]) for k in ('crop_x', 'crop_y', 'crop_w', 'crop_h'))
    return any(bx < x + w and x < bx + bw and by < y + h and y < by + bh
               for bx, by, bw, bh in faces)


def _cut(img: np.ndarray, cx: float, cy: float, side: float) -> np.ndarray:
    """A square of ``side`` centred at (cx, cy); parts outside repeat the edge."""
    n = max(4, int(round(side)))
    x0, y0 = int(round(cx - side / 2)), int(round(cy - side / 2))
    H, W = img.shape[:2]
    pad = max(0, -x0, -y0, x0 + n - W, y0 + n - H)
    if pad:
        img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    return img[y0 + pad:y0 + pad + n, x0 + pad:x0 + pad + n]


def composite_crops(n_per_shape: int, backgrounds: Sequence[RenderedCrop],
                    rng: np.random.Generator) -> list[RenderedCrop]:
    """Sign art of the simulator (``workzone_ros.sim.signart``) pasted on rendered background.

    The renders show side-road signs (stop, yield, do not enter) at 8-11 px only, so every
    shape gets ``n_per_shape`` such crops, classes drawn evenly within the shape: the face's
    longer side 9-56 px, squeezed to 75-100 % of its width (seen from the lane), on a post,
    the box around it 100-140 % of the face and off-centre by up to 10 %, darker or brighter
    (x0.55-1.2), blurred and with sensor noise.
    """
    from workzone_ros.core import signs
    from workzone_ros.sim import signart
    by_shape: dict[str, list[str]] = {}
    for c in signs.CATALOGUE:
        if c.category != 'background':
            by_shape.setdefault(sh.CATALOGUE_SHAPE[c.shape], []).append(c.key)
    out = []
    for shape in sh.SHAPES:
        for _ in range(n_per_shape):
            key = str(rng.choice(by_shape[shape]))
            bg = backgrounds[int(rng.integers(len(backgrounds)))].image
            variant = str(rng.choice(signart.OTHER_VARIANTS)) if key == 'other_workzone' \
                else None
            art = signart.sign_face(key, 256, variant=variant,
                                    orange=signart.sheeting_orange(int(rng.integers(1 << 16))))
            long_side = float(np.exp(rng.uniform(np.log(9), np.log(56))))
            ah, aw = art.shape[:2]
            k = long_side / max(ah, aw)
            fw = max(4, int(round(aw * k * rng.uniform(0.75, 1.0))))
            fh = max(4, int(round(ah * k)))
            face = cv2.resize(art, (fw, fh), interpolation=cv2.INTER_AREA)
            side = int(round(max(fw, fh) * rng.uniform(1.0, 1.4)))
            canvas = cv2.resize(bg, (side, side), interpolation=cv2.INTER_AREA)
            canvas = canvas[:, ::-1] if rng.random() < 0.5 else canvas
            canvas = canvas.astype(np.float32)
            fx = int(round((side - fw) / 2 + rng.uniform(-0.1, 0.1) * side))
            fy = int(round((side - fh) / 2 + rng.uniform(-0.1, 0.1) * side))
            post = max(1, fw // 12)
            grey = rng.uniform(70, 150)
            canvas[max(fy + fh // 2, 0):, max(fx + fw // 2 - post // 2, 0):
                   max(fx + fw // 2 - post // 2 + post, 0)] = grey
            x0, y0 = max(fx, 0), max(fy, 0)
            x1, y1 = min(fx + fw, side), min(fy + fh, side)
            if x1 > x0 and y1 > y0:
                part = face[y0 - fy:y1 - fy, x0 - fx:x1 - fx]
                canvas[y0:y1, x0:x1] = signart.over(part, canvas[y0:y1, x0:x1])
            canvas = canvas * rng.uniform(0.55, 1.2)
            sigma = rng.uniform(0.0, 0.8)
            if sigma > 0.3:
                canvas = cv2.GaussianBlur(canvas, (0, 0), sigma)
            canvas += rng.normal(0.0, rng.uniform(1.0, 6.0), canvas.shape)
            img = np.clip(np.rint(canvas), 0, 255).astype(np.uint8)
            out.append(RenderedCrop(img, key, shape, (fx, fy, fw, fh), 'composite', -1,
                                    float(min(fw, fh))))
    return out


def training_windows(crops: Sequence[RenderedCrop], rng: np.random.Generator,
                     sub_windows: int = 16) -> tuple[list[np.ndarray], list[str]]:
    """Training windows and their shapes (see the module docstring)."""
    wins, labels = [], []

    def add(img, label):
        wins.extend([img, img[:, ::-1]])
        labels.extend([label, label])
    for c in crops:
        h, w = c.image.shape[:2]
        add(_cut(c.image, w / 2, h / 2, max(w, h)), c.shape)
        if c.face is not None:
            fx, fy, fw, fh = c.face
            side = max(fw, fh) * rng.uniform(1.05, 1.4)
            dx, dy = rng.uniform(-0.05, 0.05, 2) * side
            add(_cut(c.image, fx + fw / 2 + dx, fy + fh / 2 + dy, side), c.shape)
        else:
            scan = sh.window_boxes((0, 0, w, h))
            for i in rng.choice(len(scan), min(sub_windows, len(scan)), replace=False):
                _, x0, y0, side = scan[i]
                wins.append(_cut(c.image, x0 + side / 2, y0 + side / 2, side))
                labels.append(sh.NONE)
    return wins, labels


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        print(f'{self.prog}: {message}', file=sys.stderr)
        raise SystemExit(2)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog='workzone-ros train shapes', description=__doc__,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2, 3, 4], metavar='SEED',
                   help='render seeds (default 0-4; 5-7 are the held-out test renders)')
    p.add_argument('--random', type=int, default=8, metavar='R',
                   help='random scenarios per seed (default 8)')
    p.add_argument('--per-class', type=int, default=20,
                   help='crops per class and scenario (default 20)')
    p.add_argument('--cache', default=str(DEFAULT_CACHE), help='render cache folder')
    p.add_argument('--min-side', type=float, default=10.0,
                   help='rendered sign faces under this many pixels are left out (default 10)')
    p.add_argument('--composites', type=int, default=400, metavar='N',
                   help='sign-art composites per shape on rendered background (default 400)')
    p.add_argument('--sub-windows', type=int, default=16,
                   help='scan windows per background crop (default 16)')
    p.add_argument('--window', type=int, default=20, help='window side, px (default 20)')
    p.add_argument('--candidates', type=int, default=6000,
                   help='random Haar features the selector ranks (default 6000)')
    p.add_argument('--features', type=int, default=600, help='features kept (default 600)')
    p.add_argument('--stages', type=int, default=5, help='stages per cascade (seed: 5)')
    p.add_argument('--false-alarm-rate', type=float, default=0.2,
                   help='most negatives a stage passes (seed: 0.2)')
    p.add_argument('--true-positive-rate', type=float, default=0.995,
                   help='least positives a stage keeps (seed: 0.995)')
    p.add_argument('--max-stumps', type=int, default=200,
                   help='stumps per stage at most (default 200)')
    p.add_argument('--min-windows', type=int, default=sh.DEFAULT_MIN_WINDOWS,
                   help='windows that must accept a shape at run time, stored with the model '
                        f'(default {sh.DEFAULT_MIN_WINDOWS})')
    p.add_argument('--seed', type=int, default=0, help='sampling / boosting seed')
    p.add_argument('-o', '--output',
                   default=str(Path(__file__).resolve().parents[2] / 'config'
                               / sh.DEFAULT_MODEL),
                   help='model file (default config/models/shape_cascade.npz)')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point; returns the exit status (2 with one line on stderr for bad input)."""
    args = _parser().parse_args(argv)
    from workzone_ros.tools.train_classifier import synth_specs
    if set(args.seeds) & {5, 6, 7}:
        _say('note: seeds 5-7 are the held-out renders of `workzone-ros evaluate shapes`')
    t0 = time.monotonic()
    specs = synth_specs(args.seeds, args.random)
    crops = load_renders(specs, Path(args.cache), args.per_class, min_side=args.min_side)
    rng = np.random.default_rng(args.seed)
    n_rendered = len(crops)
    if args.composites:
        crops += composite_crops(args.composites, [c for c in crops if c.shape == sh.NONE],
                                 rng)
    wins, labels = training_windows(crops, rng, args.sub_windows)
    counts = {s: labels.count(s) for s in sh.SHAPES + (sh.NONE,)}
    _say(f'{len(crops)} crops -> {len(wins)} windows: '
         + ', '.join(f'{k} {v}' for k, v in counts.items()))
    source = {'renders': {'seeds': args.seeds, 'random_per_seed': args.random,
                          'library': True, 'per_class_per_scenario': args.per_class,
                          'crop_size': 64, 'scenarios': len(specs), 'crops': n_rendered,
                          'min_face_side_px': args.min_side,
                          'crops_by_class': {k: sum(c.class_key == k for c in crops[:n_rendered])
                                             for k in sorted({c.class_key for c in crops})}},
              'composites_per_shape': args.composites,
              'windows': counts, 'sub_windows_per_background': args.sub_windows,
              'real_images': 'none (test/data/real_crops only measures)',
              'square_maps_to': 'rectangle'}
    try:
        model = sh.train_cascade(
            wins, labels, window=args.window, n_candidates=args.candidates,
            n_features=args.features, stages=args.stages,
            false_alarm_rate=args.false_alarm_rate, true_positive_rate=args.true_positive_rate,
            max_stumps=args.max_stumps, seed=args.seed,
            metadata={'training_sources': source, 'min_windows': args.min_windows,
                      'command': 'workzone-ros train shapes ' + ' '.join(argv or sys.argv[1:])},
            progress=_say)
    except ValueError as exc:
        print(f'workzone-ros train shapes: {exc}', file=sys.stderr)
        return 2
    model.metadata['training_seconds'] = round(time.monotonic() - t0, 1)
    model.save(args.output)
    print(f'model written to {args.output} ({Path(args.output).stat().st_size / 1024:.0f} KiB, '
          f'{model.metadata["n_features_used"]} features, trained in '
          f'{time.monotonic() - t0:.0f} s)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
