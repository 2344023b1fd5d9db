"""``workzone-ros train color``: learn the orange sign colour model (seed 000, section III.A).

Reads one or more folders with ``images/*.png`` and ``masks/*.png`` of the same names
(``workzone-ros synth pixels -o DIR`` writes them; a user's own images and masks work the
same way: nonzero mask = work-zone sign face), then

1. counts sign / background pixels per (hue, saturation) bin (pixels darker than ``--v-min``
   are left out: the detector gates them out too; with ``--ignore-s`` the achromatic parts of
   the sign faces, i.e. black legend and white panels, are neither positive nor negative);
2. fits AdaBoost over decision stumps (``--estimators`` = H weak learners) on those counts;
3. bakes g(f) into the 180 x 256 table (seed 000 eq. 2);
4. builds the spatial prior from the boxes of the mask's connected components (Fig. 1);
5. optionally (``--rgb-lp``) chooses the seed 002 RGB thresholds by the Boolean LP;
6. writes the versioned model file and prints training / validation pixel metrics.

Images whose name hashes into the validation share (``--val-frac``) are kept out of training
and only scored.  Never point this at evaluation data (the real clips are evaluation only).

Example::

    workzone-ros synth pixels -o /tmp/pix --seed 1 --frames 240
    workzone-ros train color /tmp/pix -o config/models/color_orange.npz --rgb-lp
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import zlib
from pathlib import Path
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core import color_model as cm
from workzone_ros.core import detection as dt

__all__ = ['main', 'load_pairs', 'pixel_metrics']

DEFAULT_OUT = Path(__file__).resolve().parents[2] / 'config' / 'models' / 'color_orange.npz'


def load_pairs(dirs: list[str]) -> list[tuple[Path, Path]]:
    """(image, mask) paths of every image that has a mask, over all ``dirs``."""
    pairs = []
    for d in dirs:
        root = Path(d)
        if not (root / 'images').is_dir() or not (root / 'masks').is_dir():
            raise FileNotFoundError(f'{root} has no images/ and masks/ folders')
        for img in sorted((root / 'images').iterdir()):
            if img.suffix.lower() not in ('.png', '.jpg', '.jpeg', '.bmp'):
                continue
            mask = next((root / 'masks' / (img.stem + ext) for ext in ('.png', '.bmp')
                         if (root / 'masks' / (img.stem + ext)).exists()), None)
            if mask is not None:
                pairs.append((img, mask))
    return pairs


def _is_val(path: Path, frac: float) -> bool:
    return (zlib.crc32(path.stem.encode()) % 1000) / 1000.0 < frac


def _read(img_path: Path, mask_path: Path) -> tuple[np.ndarray, np.ndarray]:
    img = cv2.imread(str(img_path), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE)
    if img is None or mask is None or img.shape[:2] != mask.shape[:2]:
        raise ValueError(f'unreadable or mismatched pair {img_path} / {mask_path}')
    return img, mask > 0


def pixel_metrics(lut: np.ndarray, v_min: int, pairs, ignore_s: int = 0,
                  threshold: float = 0.5) -> dict:
    """Pixel accuracy of P(x | sign) >= threshold against the masks.

    Returns accuracy over all pixels (mask = sign), and sign-pixel recall / precision, both on
    all face pixels and on the chromatic (S >= ignore_s) face pixels.
    """
    tp = fp = fn = tn = 0
    tp_c = fn_c = 0
    for ip, mp in pairs:
        img, mask = _read(ip, mp)
        hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
        pred = (lut[hsv[..., 0], hsv[..., 1]] >= threshold) & (hsv[..., 2] >= v_min)
        tp += int(np.count_nonzero(pred & mask))
        fp += int(np.count_nonzero(pred & ~mask))
        fn += int(np.count_nonzero(~pred & mask))
        tn += int(np.count_nonzero(~pred & ~mask))
        chrom = mask & (hsv[..., 1] >= max(ignore_s, 1))
        tp_c += int(np.count_nonzero(pred & chrom))
        fn_c += int(np.count_nonzero(~pred & chrom))
    n = max(tp + fp + fn + tn, 1)
    return {'pixels': n, 'accuracy': (tp + tn) / n,
            'sign_recall': tp / max(tp + fn, 1), 'sign_precision': tp / max(tp + fp, 1),
            'chromatic_sign_recall': tp_c / max(tp_c + fn_c, 1),
            'background_false_positive_rate': fp / max(fp + tn, 1)}


def main(argv: Optional[list[str]] = None) -> int:
    """Train and write the colour model; returns the exit status."""
    p = argparse.ArgumentParser(prog='workzone-ros train color', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('data', nargs='+', help='folder(s) with images/ and masks/')
    p.add_argument('-o', '--output', default=str(DEFAULT_OUT), help='model file (.npz)')
    p.add_argument('--estimators', type=int, default=40, help='weak learners H (default 40)')
    p.add_argument('--v-min', type=int, default=35, help='value gate (default 35)')
    p.add_argument('--ignore-s', type=int, default=0,
                   help='leave sign-face pixels with S below this out of training (default 0)')
    p.add_argument('--erode', type=int, default=1,
                   help='ignore this many pixels at the face outline (blended edge; default 1)')
    p.add_argument('--pos-weight', type=float, default=1.0,
                   help='positive class weight relative to background (default 1: balanced)')
    p.add_argument('--val-frac', type=float, default=0.2, help='validation share (default 0.2)')
    p.add_argument('--rgb-lp', action='store_true',
                   help='also choose the seed 002 RGB thresholds (Boolean LP)')
    p.add_argument('--lp-w', type=float, default=1.0,
                   help='seed 002 FN weight w, relative to the class sizes (default 1)')
    p.add_argument('--lp-max', type=int, default=6, help='seed 002 max thresholds (default 6)')
    args = p.parse_args(argv)

    try:
        pairs = load_pairs(args.data)
    except FileNotFoundError as exc:
        print(f'workzone-ros train color: {exc}', file=sys.stderr)
        return 2
    if not pairs:
        print('workzone-ros train color: no image/mask pairs found', file=sys.stderr)
        return 2
    train = [pp for pp in pairs if not _is_val(pp[0], args.val_frac)]
    val = [pp for pp in pairs if _is_val(pp[0], args.val_frac)]
    t0 = time.perf_counter()
    pos = np.zeros((cm.H_BINS, cm.S_BINS))
    neg = np.zeros_like(pos)
    rgb_pos = np.zeros((256 // 8) ** 3)
    rgb_neg = np.zeros_like(rgb_pos)
    boxes, size = [], None
    for ip, mp in train:
        img, mask = _read(ip, mp)
        size = (img.shape[1], img.shape[0])
        hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
        use = np.ones(mask.shape, bool)
        if args.ignore_s > 0:
            use = ~mask | (hsv[..., 1] >= args.ignore_s)
        if args.erode > 0:
            k = np.ones((2 * args.erode + 1, 2 * args.erode + 1), np.uint8)
            m8 = mask.astype(np.uint8)
            edge = (cv2.dilate(m8, k) > 0) & (cv2.erode(m8, k) == 0)
            use &= ~edge
            neg -= cm.histogram_from_pixels(hsv, edge & ~mask, args.v_min)[0]
        pp_, nn_ = cm.histogram_from_pixels(hsv, mask & use, args.v_min)
        excl, _ = cm.histogram_from_pixels(hsv, mask & ~use, args.v_min)
        pos += pp_
        neg += nn_ - excl          # ignored face pixels are not background either
        if args.rgb_lp:
            chrom = mask & (hsv[..., 1] >= max(args.ignore_s, 1))
            a, b = dt.rgb_histograms(img, chrom)
            rgb_pos += a
            rgb_neg += b - dt.rgb_histograms(img, mask & ~chrom)[0]
        n, _, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8))
        boxes += [tuple(int(v) for v in stats[i, :4]) for i in range(1, n)
                  if stats[i, 4] >= 20]
    t_count = time.perf_counter() - t0
    clf = cm.fit_boosted(pos, neg, args.estimators, args.pos_weight)
    lut = cm.boosted_lut(clf)
    t_fit = time.perf_counter() - t0 - t_count
    prior = cm.fit_prior(boxes, size or (640, 480))
    # face box / orange box: the black border and the thin outer margin the blob misses
    ratios = []
    for ip, mp in train:
        img, mask = _read(ip, mp)
        hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
        orange = (lut[hsv[..., 0], hsv[..., 1]] >= 0.5) & (hsv[..., 2] >= args.v_min)
        n, lab, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8))
        for i in range(1, n):
            x, y, w, h, _ = stats[i]
            if min(w, h) < 24:
                continue
            ys, xs = np.nonzero(orange[y:y + h, x:x + w] & (lab[y:y + h, x:x + w] == i))
            if len(xs) < 50:
                continue
            rw, rh = w / (xs.max() - xs.min() + 1), h / (ys.max() - ys.min() + 1)
            if rh < 1.3:            # two-colour faces are the extension's business
                ratios.append((rw, rh))
    box_scale = tuple(float(v) for v in np.median(ratios, axis=0)) if ratios else (1.0, 1.0)
    meta = {
        'trained_on': [str(Path(d).resolve()) for d in args.data],
        'train_images': len(train), 'val_images': len(val),
        'sign_boxes': len(boxes), 'estimators': int(len(clf.estimators_)),
        'requested_estimators': args.estimators, 'v_min': args.v_min,
        'ignore_s': args.ignore_s, 'erode': args.erode, 'pos_weight': args.pos_weight,
        'positive_pixels': int(pos.sum()), 'negative_pixels': int(neg.sum()),
        'created': time.strftime('%Y-%m-%dT%H:%M:%S'),
    }
    extras = {'box_scale': np.array(box_scale)}
    meta['box_scale'] = list(box_scale)
    meta['box_scale_faces'] = len(ratios)
    if args.rgb_lp:
        lp = dt.fit_rgb_lp(rgb_pos, np.maximum(rgb_neg, 0), w=args.lp_w,
                           max_thresholds=args.lp_max)
        extras['rgb_lp_thresholds'] = lp.thresholds
        meta['rgb_lp'] = lp.metadata
    model = cm.default_model(lut, args.v_min, prior, meta)
    model = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior, meta, extras)
    metrics = {'train': pixel_metrics(lut, args.v_min, train, args.ignore_s)}
    if val:
        metrics['validation'] = pixel_metrics(lut, args.v_min, val, args.ignore_s)
    meta['metrics'] = metrics
    cm.save_model(model, args.output)
    print(json.dumps({'output': args.output, 'bytes': Path(args.output).stat().st_size,
                      'seconds': {'count': round(t_count, 2), 'fit': round(t_fit, 2)},
                      'prior_roi': list(prior.roi), **meta}, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
