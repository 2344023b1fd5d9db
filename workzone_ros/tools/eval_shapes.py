"""``workzone-ros evaluate shapes``: the sign-shape cascades (Balali and Golparvar-Fard,
Tables 3 and 4) on held-out renders, and the drum / cone veto on the real labelled crops.

Candidates are crops as a detector gives them (the renders of ``workzone-ros synth crops``:
the sign's box jittered by 10-20 %); the candidate box is the whole crop and the cascade
slides its windows at each scale (``ShapeCascade.scan_scales``).

* Table 3 (Balali and Golparvar-Fard): per shape and window scale, the false-negative rate
  (crops of the shape its cascade does not accept at that scale) and the false-positive rate
  (crops of other shapes or background it accepts).
* Table 4 (Balali and Golparvar-Fard): the answer at all scales together
  (``ShapeCascade.scan``, with the model's ``min_windows`` accepting windows), one shape
  against the rest: precision, recall and accuracy ``(TP + TN) / all``.
* Sets: held-out renders (``--seeds``, default 5 6 7: never trained on) with faces of at
  least ``--min-side`` px, the same at every size, and sign-art composites on held-out
  render backgrounds (``train_shapes.composite_crops`` with another seed).
* Veto: the real crops of ``test/data/real_crops`` (never trained on): real signs whose
  answer is ``none`` (wrongly vetoed) and non-signs (drums, cones, barricades, vests,
  trucks, ...) whose answer is ``none`` (vetoed); also the work-zone rule "keep only
  diamonds and rectangles".

Usage::

    workzone-ros evaluate shapes [--model NPZ] [--seeds 5 6 7] [--random 8] [--sheet PNG]
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.general import shapes as sh
from workzone_ros.tools.clips import GROW

__all__ = ['scores_of', 'table3', 'table4', 'veto', 'main']

REPO = Path(__file__).resolve().parents[2]
REAL = REPO / 'test' / 'data' / 'real_crops'
REAL_FRAME = (722, 406)       # the real clips' frame size (test/data/real_crops/README.md)


def scores_of(model: sh.ShapeCascade, crops: Sequence[np.ndarray],
              boxes: Optional[Sequence] = None, scales: Sequence[float] = sh.DEFAULT_SCALES,
              min_windows: int = 1) -> np.ndarray:
    """(N, scales, shapes) best window scores; a crop's box is the whole crop by default."""
    out = np.empty((len(crops), len(scales), len(sh.SHAPES)), np.float32)
    for i, img in enumerate(crops):
        box = boxes[i] if boxes is not None else (0, 0, img.shape[1], img.shape[0])
        out[i] = model.scan_scales(img, box, scales, min_windows=min_windows)
    return out


def answers(scores: np.ndarray) -> np.ndarray:
    """The answer over every scale: the best accepted shape or ``none``."""
    flat = scores.reshape(len(scores), -1, len(sh.SHAPES)).max(axis=1)
    best = flat.argmax(axis=1)
    return np.where(flat.max(axis=1) > 0, np.array(sh.SHAPES)[best], sh.NONE)


def table3(scores: np.ndarray, truth: np.ndarray, scales: Sequence[float]) -> dict:
    """Per shape and scale: false-negative and false-positive rates of the shape's cascade."""
    out = {}
    for s, shape in enumerate(sh.SHAPES):
        pos, neg = truth == shape, truth != shape
        out[shape] = {'n_pos': int(pos.sum()), 'n_neg': int(neg.sum()),
                      'fn': [float(np.mean(scores[pos, k, s] <= 0)) if pos.any() else None
                             for k in range(len(scales))],
                      'fp': [float(np.mean(scores[neg, k, s] > 0)) if neg.any() else None
                             for k in range(len(scales))]}
    return out


def table4(answer: np.ndarray, truth: np.ndarray) -> dict:
    """Per shape, one against the rest: TP, FP, FN, TN, precision, recall, accuracy."""
    out = {}
    for shape in sh.SHAPES:
        tp = int(np.sum((answer == shape) & (truth == shape)))
        fp = int(np.sum((answer == shape) & (truth != shape)))
        fn = int(np.sum((answer != shape) & (truth == shape)))
        tn = len(truth) - tp - fp - fn
        out[shape] = {'tp': tp, 'fp': fp, 'fn': fn, 'tn': tn,
                      'precision': tp / (tp + fp) if tp + fp else None,
                      'recall': tp / (tp + fn) if tp + fn else None,
                      'accuracy': (tp + tn) / len(truth) if len(truth) else None}
    out['all'] = {'n': int(len(truth)), 'accuracy_5way': float(np.mean(answer == truth)),
                  'mean_precision': _mean(out[s]['precision'] for s in sh.SHAPES),
                  'mean_recall': _mean(out[s]['recall'] for s in sh.SHAPES),
                  'mean_accuracy': _mean(out[s]['accuracy'] for s in sh.SHAPES)}
    return out


def _mean(vals) -> Optional[float]:
    v = [x for x in vals if x is not None]
    return float(np.mean(v)) if v else None


def _real_crops(root: Path):
    """Real crops with their box inside the crop, class key and labelled shape."""
    with open(root / 'index.csv', newline='') as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for r in rows:
        img = cv2.imread(str(root / r['path']), cv2.IMREAD_COLOR)
        if img is None:
            continue
        x, y, w, h = (float(r[k]) for k in ('x', 'y', 'w', 'h'))
        x0, y0 = max(0.0, x - GROW * w), max(0.0, y - GROW * h)
        x1 = min(REAL_FRAME[0], x + w + GROW * w)
        y1 = min(REAL_FRAME[1], y + h + GROW * h)
        fx, fy = img.shape[1] / (x1 - x0), img.shape[0] / (y1 - y0)
        box = ((x - x0) * fx, (y - y0) * fy, w * fx, h * fy)
        shape = r.get('shape') or sh.NONE
        out.append((img, box, r['class_key'], sh.CATALOGUE_SHAPE.get(shape, shape), r['clip']))
    return out


def veto(answer: np.ndarray, keys: Sequence[str], truth: np.ndarray) -> dict:
    """Signs wrongly vetoed and non-signs vetoed, by two rules."""
    keys = np.asarray(keys)
    sign = truth != sh.NONE
    out = {'per_class': {}}
    for k in sorted(set(keys)):
        m = keys == k
        out['per_class'][k] = {a: int(np.sum(answer[m] == a)) for a in sh.SHAPES + (sh.NONE,)}
    keep_wz = np.isin(answer, ('diamond', 'rectangle'))
    wz_sign = np.isin(truth, ('diamond', 'rectangle'))
    out['rule_none'] = {
        'signs': int(sign.sum()), 'signs_vetoed': int(np.sum(sign & (answer == sh.NONE))),
        'signs_wrong_shape': int(np.sum(sign & (answer != sh.NONE) & (answer != truth))),
        'non_signs': int((~sign).sum()),
        'non_signs_vetoed': int(np.sum(~sign & (answer == sh.NONE)))}
    out['rule_diamond_rectangle'] = {
        'signs': int(wz_sign.sum()), 'signs_vetoed': int(np.sum(wz_sign & ~keep_wz)),
        'non_signs': int((~sign).sum()), 'non_signs_vetoed': int(np.sum(~sign & ~keep_wz))}
    return out


def _sheet(path: str, groups: list[tuple[str, list[tuple[np.ndarray, str]]]]) -> None:
    """A contact sheet: one row per group, each tile labelled with the answer."""
    tile, per_row = 64, 16
    rows = []
    for title, items in groups:
        head = np.full((16, tile * per_row, 3), 255, np.uint8)
        cv2.putText(head, title, (2, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        rows.append(head)
        tiles = []
        for img, label in items[:per_row]:
            t = cv2.resize(img, (tile, tile), interpolation=cv2.INTER_NEAREST)
            t = cv2.copyMakeBorder(t[:-12], 0, 12, 0, 0, cv2.BORDER_CONSTANT, value=(0, 0, 0))
            cv2.putText(t, label[:10], (1, tile - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.33,
                        (255, 255, 255), 1)
            tiles.append(t)
        tiles += [np.zeros((tile, tile, 3), np.uint8)] * (per_row - len(tiles))
        rows.append(np.hstack(tiles))
    cv2.imwrite(path, np.vstack(rows))


def _pct(v) -> str:
    return '   -   ' if v is None else f'{100 * v:6.2f}%'


def _print_tables(name: str, t3: dict, t4: dict, scales: Sequence[float]) -> None:
    print(f'\n== {name}: {t4["all"]["n"]} candidates ==')
    print("Table 3 (Balali and Golparvar-Fard): false negatives / false positives of each "
          "shape's cascade per window scale")
    sc = ' '.join(f'{s:>7.2f}' for s in scales)
    print(f'{"shape":<10} {"n+":>5} {"n-":>6} | FN {sc} | FP {sc}')
    for shape in sh.SHAPES:
        r = t3[shape]
        print(f'{shape:<10} {r["n_pos"]:>5} {r["n_neg"]:>6} | '
              f'   {" ".join(_pct(v) for v in r["fn"])} | '
              f'   {" ".join(_pct(v) for v in r["fp"])}')
    print('Table 4 (Balali and Golparvar-Fard): answer at all scales, one shape against the rest')
    print(f'{"shape":<10} {"TP":>5} {"FP":>5} {"FN":>5} {"TN":>6} {"precision":>9} '
          f'{"recall":>8} {"accuracy":>8}')
    for shape in sh.SHAPES:
        r = t4[shape]
        print(f'{shape:<10} {r["tp"]:>5} {r["fp"]:>5} {r["fn"]:>5} {r["tn"]:>6} '
              f'{_pct(r["precision"]):>9} {_pct(r["recall"]):>8} {_pct(r["accuracy"]):>8}')
    a = t4['all']
    print(f'mean precision {_pct(a["mean_precision"])}, recall {_pct(a["mean_recall"])}, '
          f'accuracy {_pct(a["mean_accuracy"])}; 5-way accuracy (4 shapes + none) '
          f'{_pct(a["accuracy_5way"])}   (Balali and Golparvar-Fard: 76.65 %, 99.33 %, 79.30 %)')


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        print(f'{self.prog}: {message}', file=sys.stderr)
        raise SystemExit(2)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog='workzone-ros evaluate shapes', description=__doc__,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--model', help='shape cascade (default config/models/shape_cascade.npz)')
    p.add_argument('--seeds', type=int, nargs='+', default=[5, 6, 7],
                   help='held-out render seeds (default 5 6 7)')
    p.add_argument('--random', type=int, default=8, help='random scenarios per seed (8)')
    p.add_argument('--cache', default='/tmp/workzone_ros_crops', help='render cache folder')
    p.add_argument('--min-side', type=float, default=12.0,
                   help='faces under this many px are reported apart (default 12)')
    p.add_argument('--composites', type=int, default=150,
                   help='held-out sign-art composites per shape (default 150; 0: none)')
    p.add_argument('--real', default=str(REAL), help='real labelled crops (index.csv)')
    p.add_argument('--scales', type=float, nargs='+', default=list(sh.DEFAULT_SCALES))
    p.add_argument('--min-windows', type=int,
                   help="windows that must accept a shape (default: the model's)")
    p.add_argument('--sheet', help='write a contact sheet of labelled crops (PNG)')
    p.add_argument('--json', help='write every number as JSON')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    from workzone_ros.tools.train_classifier import synth_specs
    from workzone_ros.tools.train_shapes import composite_crops, load_renders
    try:
        model = sh.ShapeCascade.load(args.model)
    except (FileNotFoundError, sh.ShapeModelError) as exc:
        print(f'workzone-ros evaluate shapes: {exc}', file=sys.stderr)
        return 2
    trained = model.metadata.get('training_sources', {}).get('renders', {}).get('seeds', [])
    overlap = sorted(set(trained) & set(args.seeds))
    if overlap:
        print(f'warning: seeds {overlap} also trained the model', file=sys.stderr)
    min_windows = model.min_windows if args.min_windows is None else args.min_windows
    n_win = len(sh.window_boxes((0, 0, 1, 1), args.scales))
    print(f'Table 4 answers need {min_windows} accepting window(s) of {n_win}')
    t0 = time.monotonic()
    crops = load_renders(synth_specs(args.seeds, args.random), Path(args.cache), progress=None)
    side = np.array([c.side for c in crops])
    sets = {'renders, faces >= %g px' % args.min_side: [c for c, s in zip(crops, side)
                                                         if s >= args.min_side],
            'renders, every size': crops}
    if args.composites:
        rng = np.random.default_rng(1001)
        sets['sign-art composites on held-out backgrounds'] = composite_crops(
            args.composites, [c for c in crops if c.shape == sh.NONE], rng)
    report = {'model': model.metadata.get('training_sources'), 'sets': {}}
    sheet_groups = []
    for name, items in sets.items():
        images = [c.image for c in items]
        scores = scores_of(model, images, scales=args.scales)     # Table 3: each window
        truth = np.array([c.shape for c in items])
        ans = answers(scores_of(model, images, scales=args.scales, min_windows=min_windows)
                      if min_windows > 1 else scores)
        t3, t4 = table3(scores, truth, args.scales), table4(ans, truth)
        report['sets'][name] = {'table3': t3, 'table4': t4}
        _print_tables(name, t3, t4, args.scales)
        if name.startswith('renders, faces'):
            for shape in sh.SHAPES + (sh.NONE,):
                wrong = [(c.image, a) for c, a, t in zip(items, ans, truth)
                         if t == shape and a != shape]
                right = [(c.image, a) for c, a, t in zip(items, ans, truth)
                         if t == shape and a == shape]
                sheet_groups.append((f'renders, true {shape}: right', right[::7]))
                sheet_groups.append((f'renders, true {shape}: wrong (answer shown)', wrong))
    real = _real_crops(Path(args.real))
    rs = scores_of(model, [r[0] for r in real], [r[1] for r in real], args.scales,
                   min_windows)
    ra = answers(rs)
    rtruth = np.array([r[3] for r in real])
    v = veto(ra, [r[2] for r in real], rtruth)
    v['per_clip_non_signs'] = {c: {'n': int(np.sum((rtruth == sh.NONE) & (clips == c))),
                                   'vetoed': int(np.sum((rtruth == sh.NONE) & (clips == c)
                                                        & (ra == sh.NONE)))}
                               for clips in [np.array([r[4] for r in real])]
                               for c in sorted(set(clips))}
    report['veto'] = v
    print(f'\n== veto on the real crops ({args.real}; never trained on) ==')
    print('answers per class: ' + '; '.join(
        f'{k}: ' + ', '.join(f'{a} {n}' for a, n in d.items() if n)
        for k, d in v['per_class'].items()))
    a, b = v['rule_none'], v['rule_diamond_rectangle']
    print(f'veto when the answer is none: real signs wrongly vetoed {a["signs_vetoed"]}/'
          f'{a["signs"]} ({_pct(a["signs_vetoed"] / max(a["signs"], 1))}), wrong shape '
          f'{a["signs_wrong_shape"]}; non-signs vetoed {a["non_signs_vetoed"]}/'
          f'{a["non_signs"]} ({_pct(a["non_signs_vetoed"] / max(a["non_signs"], 1))})')
    print(f'veto unless diamond or rectangle: diamond/rectangle signs wrongly vetoed '
          f'{b["signs_vetoed"]}/{b["signs"]} ({_pct(b["signs_vetoed"] / max(b["signs"], 1))}); '
          f'non-signs vetoed {b["non_signs_vetoed"]}/{b["non_signs"]} '
          f'({_pct(b["non_signs_vetoed"] / max(b["non_signs"], 1))})')
    print('non-signs vetoed per clip: ' + ', '.join(
        f'{c} {d["vetoed"]}/{d["n"]}' for c, d in v['per_clip_non_signs'].items()))
    if args.sheet:
        for key in sorted(set(r[2] for r in real)):
            items = [(r[0], x) for r, x in zip(real, ra) if r[2] == key]
            sheet_groups.append((f'real {key} (answer shown)', items[::max(1, len(items) // 16)]))
        _sheet(args.sheet, sheet_groups)
        print(f'contact sheet: {args.sheet}')
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    print(f'evaluated in {time.monotonic() - t0:.0f} s', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
