"""``workzone-ros train color``: learn the orange sign colour model (Seo et al., section III.A).

Reads one or more folders with ``images/*.png`` and ``masks/*.png`` of the same names
(``workzone-ros synth pixels -o DIR`` writes them; a user's own images and masks work the
same way: mask 0 = background, 128 = ignored (neither: e.g. cones, which are orange but no
sign; ``workzone-ros real-pixels`` writes such masks from labelled video frames), any other
value = work-zone sign face), then

1. splits each face mask into its orange pixels (positives) and its black legend / border
   and white panels (ignored: neither sign colour nor background, ``--orange-only``);
2. adds ``--augment`` colour-jittered copies of every image (white balance, exposure, tone
   curve, saturation, hue, in the ranges of real cameras, then most of them through a JPEG
   round trip: the blocking and chroma smearing of dashcam video and compressed image
   topics) so the model transfers to other cameras and light; in a share of them
   (``--bg-hue``) the background's hue is rotated by a random angle (the sign's is not):
   real roadsides hold warm grey asphalt, brick, beige walls and dirt that our renders'
   palette lacks, so the table must not call a colour orange just because no rendered
   background had it;
3. grey-world balances every frame (``--gray-world``) and normalises its saturation
   (``--sat-norm``: the frame's 90th saturation percentile is brought up to ``--sat-ref``,
   gain 1..``--sat-max-gain``; haze and dull light no longer make washed-out signs look
   like warm grey asphalt); the detector does the same at run time, outside the table;
4. counts sign / background pixels per (hue, saturation) bin (pixels darker than ``--v-min``
   are left out: the detector gates them out too) and fits AdaBoost over decision stumps
   (``--estimators`` = H weak learners) on those counts;
5. bakes g(f) into the 180 x 256 table (Seo et al. eq. 2);
6. builds the spatial prior from the boxes of the masks' connected components (Fig. 1),
   averaged over other cameras' views (``--camera-pitch/-yaw/-zoom``: another mounting
   pitch, yaw and focal length, so the prior does not assume our camera's exact horizon),
   and the mounting geometry (model extra ``geometry``: how low a sign's bottom edge gets
   at all, e.g. on a portable stand, and how low it usually gets, ``--geometry-quantile``,
   relative to the image middle: unlike the prior this test is tied to the training
   camera's height and horizon; for another camera retrain it or set the detector's
   ``use_geometry`` false).  Both are stored with the training camera (metadata ``camera``:
   the frame size and, with ``--camera FX FY CX CY``, the intrinsics): the detector applies
   them only to frames of that camera and uses a location-free prior on any other;
7. optionally (``--rgb-lp``) chooses the RGB thresholds of Balali and Golparvar-Fard by their
   Boolean LP;
8. writes the versioned model file and prints training / validation pixel metrics.

Images whose name hashes into the validation share (``--val-frac``) are kept out of training
and only scored.  Never point this at evaluation data (the real clips are evaluation only).

Example::

    workzone-ros synth pixels -o /tmp/pix --seed 11 --frames 240
    workzone-ros train color /tmp/pix -o config/models/color_orange.npz --rgb-lp \
        --pos-weight 0.6 --v-min 75 --val-frac 0
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import cv2
import numpy as np

from workzone_ros.core import color_model as cm
from workzone_ros.core import detect as dt
from workzone_ros.sim.weather import CAMERA_JPEG, jpeg_degrade

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


def mask_boxes(pairs) -> tuple[list, Optional[tuple[int, int]]]:
    """Boxes (x, y, w, h) of the masks' connected components (>= 20 px) and the image size."""
    boxes, size = [], None
    for _, mp in pairs:
        mask = cv2.imread(str(mp), cv2.IMREAD_GRAYSCALE)
        if mask is None:
            raise ValueError(f'unreadable mask {mp}')
        size = (mask.shape[1], mask.shape[0])
        n, _, stats, _ = cv2.connectedComponentsWithStats((mask > 0).astype(np.uint8))
        boxes += [tuple(int(v) for v in stats[i, :4]) for i in range(1, n) if stats[i, 4] >= 20]
    return boxes, size


def _is_val(path: Path, frac: float) -> bool:
    return (zlib.crc32(path.stem.encode()) % 1000) / 1000.0 < frac


#: Mask value of pixels that are neither sign face nor background (left out of the counts).
IGNORE = 128


def _read(img_path: Path, mask_path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(image, face, ignored): mask 0 is background, 128 ignored, any other value face."""
    img = cv2.imread(str(img_path), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE)
    if img is None or mask is None or img.shape[:2] != mask.shape[:2]:
        raise ValueError(f'unreadable or mismatched pair {img_path} / {mask_path}')
    ignored = mask == IGNORE
    return img, (mask > 0) & ~ignored, ignored


def orange_mask(hsv: np.ndarray, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split sign-face masks into orange pixels and ignored (legend, border, white) ones.

    A face pixel is orange when it is chromatic relative to its own face: saturation at least
    half the median saturation of the face's saturated pixels and value at least 40 % of
    their median value.  Returns (orange, use): ``use`` is False on the ignored face pixels.
    """
    orange = np.zeros_like(face)
    if face.any():
        s, v = hsv[..., 1], hsv[..., 2]
        chrom = face & (s >= 60)
        if chrom.any():
            s_ref, v_ref = float(np.median(s[chrom])), float(np.median(v[chrom]))
            orange = face & (s >= 0.5 * s_ref) & (v >= 0.4 * v_ref)
    return orange, ~(face & ~orange)


#: Colour jitter ranges of :func:`augment` (plausible camera / light variation), and its
#: JPEG round trip ``'jpeg': (share, q_lo, q_hi)`` (:data:`workzone_ros.sim.weather.CAMERA_JPEG`,
#: as the CNN's crop augmentation: real frames reach the table compressed).
AUGMENT = {'white_balance': (0.8, 1.25), 'exposure': (0.55, 1.6), 'gamma': (0.7, 1.4),
           'saturation': (0.55, 1.8), 'hue': 4, 'jpeg': CAMERA_JPEG}


def augment(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Colour jitter as another camera would see the scene: white balance (per-channel
    gain), exposure (with clipping), tone curve (gamma), saturation (vivid phone processing
    to washed-out) and a small hue shift, then, last, a JPEG round trip at a random quality
    (compression artefacts: blocks, ringing, chroma smeared across edges) in a share of the
    copies; ranges in :data:`AUGMENT`.  With a JPEG share of 0 no JPEG draw is made (the
    random stream, and so the copies, are those of the colour jitter alone)."""
    a = AUGMENT
    f = img.astype(np.float32) / 255.0
    f *= rng.uniform(*a['white_balance'], 3).astype(np.float32)
    f *= float(rng.uniform(*a['exposure']))
    f = np.power(np.clip(f, 0.0, 1.0), float(rng.uniform(*a['gamma'])))
    hsv = cv2.cvtColor((f * 255.0 + 0.5).astype(np.uint8), cv2.COLOR_BGR2HSV)
    h = (hsv[..., 0].astype(np.int16) + int(rng.integers(-a['hue'], a['hue'] + 1))) % 180
    hsv[..., 0] = h.astype(np.uint8)
    s = hsv[..., 1].astype(np.float32) * float(rng.uniform(*a['saturation']))
    hsv[..., 1] = np.clip(s, 0, 255).astype(np.uint8)
    out = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)
    share, q_lo, q_hi = a['jpeg']
    return jpeg_degrade(out, rng, share, q_lo, q_hi) if share > 0 else out


def rotate_background_hue(img: np.ndarray, face: np.ndarray, rng: np.random.Generator,
                           warm: float = 0.5) -> np.ndarray:
    """The frame with the hue of every non-sign pixel rotated by one random angle.

    With probability ``warm`` the angle brings the background's median hue (of its
    chromatic pixels) into the earth tones (OpenCV hue 0..30: soil, brick, dry grass, wood,
    sunlit asphalt), which dominate real roadsides and which our renders' palette lacks;
    otherwise the angle is uniform.
    """
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    chrom = ~face & (hsv[..., 1] >= 25)
    if rng.random() < warm and chrom.any():
        angle = int(rng.integers(0, 31)) - int(np.median(hsv[..., 0][chrom]))
    else:
        angle = int(rng.integers(1, 180))
    h = (hsv[..., 0].astype(np.int16) + angle) % 180
    hsv[..., 0] = np.where(face, hsv[..., 0], h.astype(np.uint8))
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)


def table_hsv(img: np.ndarray, gray_world: bool, sat_norm: Optional[cm.SatNorm],
              v_min: int, white_balance: str = 'grey_world') -> np.ndarray:
    """The frame's HSV as the orange table sees it (white balance, saturation norm)."""
    if gray_world:
        img = cm.apply_gains(img, cm.WHITE_BALANCE[white_balance](img))
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    if sat_norm is not None:
        g = cm.saturation_gain(hsv, sat_norm, v_min)
        hsv[..., 1] = cv2.LUT(hsv[..., 1], cm.saturation_table(g))
    return hsv


def pixel_metrics(lut: np.ndarray, v_min: int, pairs, threshold: float = 0.5,
                  gray_world: bool = False, sat_norm: Optional[cm.SatNorm] = None,
                  white_balance: str = 'grey_world') -> dict:
    """Pixel accuracy of P(x | sign) >= threshold (and the value gate) against the masks.

    Positives are the orange pixels of the sign faces (:func:`orange_mask`); the black legend
    / border and white panels of the faces are left out (the colour model is not meant to
    call them orange, and they are not background either).  ``accuracy`` is over every other
    pixel of the frames; since signs are a small share of a frame, ``balanced_accuracy`` (the
    mean of sign recall and background specificity) is reported too.
    """
    tp = fp = fn = tn = 0
    for ip, mp in pairs:
        img, face, ignored = _read(ip, mp)
        hsv = table_hsv(img, gray_world, sat_norm, v_min, white_balance)
        mask, use = orange_mask(hsv, face)
        use &= ~ignored
        pred = (lut[hsv[..., 0], hsv[..., 1]] >= threshold) & (hsv[..., 2] >= v_min)
        tp += int(np.count_nonzero(pred & mask))
        fn += int(np.count_nonzero(~pred & mask))
        fp += int(np.count_nonzero(pred & ~mask & use))
        tn += int(np.count_nonzero(~pred & ~mask & use))
    n = max(tp + fp + fn + tn, 1)
    recall, spec = tp / max(tp + fn, 1), tn / max(fp + tn, 1)
    return {'pixels': n, 'accuracy': (tp + tn) / n, 'balanced_accuracy': 0.5 * (recall + spec),
            'sign_recall': recall, 'sign_precision': tp / max(tp + fp, 1),
            'background_false_positive_rate': fp / max(fp + tn, 1)}


def _add_input_arguments(p: argparse.ArgumentParser) -> None:
    """Data, output, boosting size and the camera the training frames come from."""
    p.add_argument('data', nargs='+', help='folder(s) with images/ and masks/')
    p.add_argument('-o', '--output', default=str(DEFAULT_OUT), help='model file (.npz)')
    p.add_argument('--estimators', type=int, default=60, help='weak learners H (default 60)')
    p.add_argument('--geometry-from', nargs='+', default=None, metavar='DIR',
                   help='mounting geometry from the masks of these folders instead of the '
                        'training folders: renders from our fixed camera (synth pixels '
                        '--fixed-camera), whose horizon is the --horizon-row, while the table '
                        'and the prior learn from jittered cameras')
    p.add_argument('--camera', type=float, nargs=4, metavar=('FX', 'FY', 'CX', 'CY'),
                   help='intrinsics (pixels) of the camera the training frames come from, '
                        'stored in the model (metadata camera): the detector applies the '
                        'prior and the fixed mounting row only to frames of this camera '
                        '(without it: frames of the training size)')
    p.add_argument('--horizon-row', type=float, default=0.5,
                   help='true horizon row of the geometry renders, fraction of the height '
                        '(our level camera: 0.5)')


def _add_counting_arguments(p: argparse.ArgumentParser) -> None:
    """Which pixels are counted, augmentation and the mounting-geometry limits."""
    p.add_argument('--v-min', type=int, default=35, help='value gate (default 35)')
    p.add_argument('--ignore-s', type=int, default=0,
                   help='leave sign-face pixels with S below this out of training (default 0)')
    p.add_argument('--erode', type=int, default=1,
                   help='ignore this many pixels at the face outline (blended edge; default 1)')
    p.add_argument('--pos-weight', type=float, default=1.0,
                   help='positive class weight relative to background (default 1: balanced)')
    p.add_argument('--val-frac', type=float, default=0.2, help='validation share (default 0.2)')
    p.add_argument('--orange-only', action=argparse.BooleanOptionalAction, default=True,
                   help='positives are the orange pixels of the face masks only; the black '
                        'legend / border and white panels are ignored (default on)')
    p.add_argument('--augment', type=int, default=2,
                   help='colour-jittered copies of each training image (hue, saturation, '
                        'white balance, exposure, then a JPEG round trip in most; '
                        'default 2)')
    p.add_argument('--bg-hue', type=float, default=0.5,
                   help='share of the augmented copies whose background hue is rotated '
                        '(default 0.5; half of those into the earth tones)')
    p.add_argument('--seed', type=int, default=0, help='augmentation seed')
    p.add_argument('--geometry-margin', type=float, default=0.15,
                   help='margin on the lowest sign bottom seen in training (sign heights)')
    p.add_argument('--geometry-quantile', type=float, default=0.9,
                   help='soft mounting limit: this quantile of the sign bottoms (+ margin); '
                        'blobs lower than it must look like a clear sign face')


def _add_colour_arguments(p: argparse.ArgumentParser) -> None:
    """White balance and saturation normalisation before the table."""
    p.add_argument('--gray-world', action=argparse.BooleanOptionalAction, default=True,
                   help='grey-world balance every frame before the table (the detector then '
                        'does the same; default on)')
    p.add_argument('--white-balance', choices=tuple(cm.WHITE_BALANCE), default='low_chroma',
                   help='white-balance estimator when balancing (--gray-world): low_chroma '
                        '(the least chromatic fifth of the frame is made grey; default) or '
                        'grey_world (the frame mean; a clear sky and green verges then tint '
                        'asphalt orange)')
    p.add_argument('--sat-norm', action=argparse.BooleanOptionalAction, default=True,
                   help='normalise each frame saturation before the table (the detector '
                        'then does the same; default on)')
    p.add_argument('--sat-ref', type=float, default=120.0,
                   help='saturation norm: target of the 90th percentile (default 120)')
    p.add_argument('--sat-max-gain', type=float, default=4.0,
                   help='saturation norm: largest gain (default 4)')


def _add_prior_arguments(p: argparse.ArgumentParser) -> None:
    """The location prior and its camera jitter."""
    p.add_argument('--prior-saturate', type=float, default=0.1,
                   help='prior heat = box density / (this x its maximum), clipped to 1')
    p.add_argument('--prior-roi-level', type=float, default=0.02,
                   help='the ROI covers heat >= this level')
    p.add_argument('--camera-pitch', type=float, default=0.1,
                   help='prior: horizon uncertainty, fraction of the image height '
                        '(default 0.1, about 5 degrees)')
    p.add_argument('--camera-yaw', type=float, default=0.05,
                   help='prior: sideways uncertainty, fraction of the image width')
    p.add_argument('--camera-zoom', type=float, default=0.25,
                   help='prior: focal length uncertainty (scale 1/(1+z) .. 1+z)')


def _add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Metrics, the bin-count cache and the RGB-threshold LP."""
    p.add_argument('--metrics', action=argparse.BooleanOptionalAction, default=True,
                   help='score the table on the training images (default on)')
    p.add_argument('--counts', metavar='NPZ',
                   help='bin-count cache: written after counting, read instead of counting '
                        'when it exists (same data and counting options only; not with '
                        '--rgb-lp)')
    p.add_argument('--rgb-lp', action='store_true',
                   help='also choose the Balali and Golparvar-Fard RGB thresholds (Boolean LP)')
    p.add_argument('--lp-w', type=float, default=1.0,
                   help='FN weight w of the RGB-threshold LP, relative to the class sizes '
                        '(default 1)')
    p.add_argument('--lp-max', type=int, default=6,
                   help='most RGB thresholds the LP may choose (default 6)')


def _parser() -> argparse.ArgumentParser:
    """The ``workzone-ros train color`` argument parser."""
    p = argparse.ArgumentParser(prog='workzone-ros train color', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_input_arguments(p)
    _add_counting_arguments(p)
    _add_colour_arguments(p)
    _add_prior_arguments(p)
    _add_run_arguments(p)
    return p


@dataclass
class _Counts:
    """Bin counts of the training pixels, and the sign boxes of the training masks."""

    pos: np.ndarray
    neg: np.ndarray
    rgb_pos: np.ndarray
    rgb_neg: np.ndarray
    boxes: list = field(default_factory=list)
    size: Optional[tuple[int, int]] = None


def _training_pixels(args: argparse.Namespace, hsv: np.ndarray, face: np.ndarray,
                     ignored: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The positive mask and the pixels used for training (``(mask, use)``)."""
    if args.orange_only:
        mask, use = orange_mask(hsv, face)
    else:
        mask, use = face, np.ones_like(face)
    use &= ~ignored
    if args.ignore_s > 0:
        use &= ~mask | (hsv[..., 1] >= args.ignore_s)
    if args.erode > 0:
        k = np.ones((2 * args.erode + 1, 2 * args.erode + 1), np.uint8)
        m8 = face.astype(np.uint8)
        use &= ~((cv2.dilate(m8, k) > 0) & (cv2.erode(m8, k) == 0))
    return mask, use


def _count_pair(args: argparse.Namespace, ip: Path, mp: Path, rng: np.random.Generator,
                sat_norm: Optional[cm.SatNorm], counts: _Counts) -> None:
    """Add one image/mask pair (and its augmented copies) to ``counts``."""
    img0, face, ignored = _read(ip, mp)
    counts.size = (img0.shape[1], img0.shape[0])
    n, _, stats, _ = cv2.connectedComponentsWithStats(face.astype(np.uint8))
    counts.boxes += [tuple(int(v) for v in stats[i, :4]) for i in range(1, n)
                     if stats[i, 4] >= 20]
    for a in range(1 + args.augment):
        img = img0 if a == 0 else augment(img0, rng)
        if a > 0 and rng.random() < args.bg_hue:
            img = rotate_background_hue(img, face, rng)
        hsv = table_hsv(img, args.gray_world, sat_norm, args.v_min, args.white_balance)
        if args.gray_world and args.rgb_lp and a == 0:
            img = cm.apply_gains(img, cm.WHITE_BALANCE[args.white_balance](img))
        mask, use = _training_pixels(args, hsv, face, ignored)
        # positives: orange face pixels; negatives: background; the rest is ignored
        pp_, _ = cm.histogram_from_pixels(hsv, mask & use, args.v_min)
        nn_, _ = cm.histogram_from_pixels(hsv, ~face & use, args.v_min)
        counts.pos += pp_
        counts.neg += nn_
        if args.rgb_lp and a == 0:
            a_, _ = dt.rgb_histograms(img, mask & use)
            b_, _ = dt.rgb_histograms(img, ~face & use)
            counts.rgb_pos += a_
            counts.rgb_neg += b_


def _count_pixels(args: argparse.Namespace, train: list[tuple[Path, Path]],
                  sat_norm: Optional[cm.SatNorm]) -> _Counts:
    """Count the training pixels, or read the counts from the ``--counts`` cache."""
    pos = np.zeros((cm.H_BINS, cm.S_BINS))
    rgb_pos = np.zeros((256 // 8) ** 3)
    counts = _Counts(pos, np.zeros_like(pos), rgb_pos, np.zeros_like(rgb_pos))
    rng = np.random.default_rng(args.seed)
    cached = bool(args.counts and Path(args.counts).exists() and not args.rgb_lp)
    if cached:
        with np.load(args.counts, allow_pickle=False) as z:
            cache = {k: z[k] for k in z.files}
        counts.pos, counts.neg = cache['pos'], cache['neg']
        counts.boxes = [tuple(int(v) for v in b) for b in cache['boxes']]
        counts.size = tuple(int(v) for v in cache['size'])
    else:
        for ip, mp in train:
            _count_pair(args, ip, mp, rng, sat_norm, counts)
    if args.counts and not cached and counts.size is not None:
        # the bin counts depend on the data and the counting options only (not on the
        # boosting options): keep them to refit with another --pos-weight / H
        np.savez_compressed(args.counts, pos=counts.pos, neg=counts.neg,
                            boxes=np.array(counts.boxes, np.int64).reshape(-1, 4),
                            size=np.array(counts.size, np.int64))
    return counts


def _metadata(args: argparse.Namespace, n_train: int, n_val: int, counts: _Counts,
              n_est: int, sat_norm: Optional[cm.SatNorm], jitter: tuple) -> dict:
    """The model metadata of the training run (without geometry, LP and metrics)."""
    meta = {
        'trained_on': [str(Path(d).resolve()) for d in args.data],
        'train_images': n_train, 'val_images': n_val,
        'sign_boxes': len(counts.boxes), 'estimators': n_est, 'boost': 'discrete',
        'requested_estimators': args.estimators, 'v_min': args.v_min,
        'ignore_s': args.ignore_s, 'erode': args.erode, 'pos_weight': args.pos_weight,
        'orange_only': bool(args.orange_only), 'gray_world': bool(args.gray_world),
        'white_balance': args.white_balance,
        'sat_norm': sat_norm.to_dict() if sat_norm is not None else None,
        'augment': args.augment, 'augment_ranges': AUGMENT, 'bg_hue': args.bg_hue,
        'camera_jitter': list(jitter), 'seed': args.seed,
        'positive_pixels': int(counts.pos.sum()), 'negative_pixels': int(counts.neg.sum()),
        'created': time.strftime('%Y-%m-%dT%H:%M:%S'),
    }
    if counts.size is not None:
        # the camera the prior and the mounting geometry belong to
        meta['camera'] = {'width': int(counts.size[0]), 'height': int(counts.size[1])}
        if args.camera:
            meta['camera'].update(zip(('fx', 'fy', 'cx', 'cy'), map(float, args.camera)))
    return meta


def _geometry_and_lp(args: argparse.Namespace, counts: _Counts, meta: dict) -> dict:
    """The model extras (mounting geometry, RGB-LP thresholds); records them in ``meta``."""
    extras: dict = {}
    # mounting geometry: sign bottoms relative to the horizon row, in sign heights
    g_boxes, g_size = counts.boxes, counts.size
    if args.geometry_from:
        g_boxes, g_size = mask_boxes(load_pairs(args.geometry_from))
    row = args.horizon_row
    rel = [(y + h - row * g_size[1]) / h for x, y, w, h in g_boxes if h >= 8] if g_size \
        else []
    if rel:
        # [reference row, hard limit (the lowest sign seen, e.g. on a portable stand),
        #  soft limit (the usual mounting: below it only clear sign faces pass)]
        extras['geometry'] = np.array([
            row, float(np.max(rel)) + args.geometry_margin,
            float(np.quantile(rel, args.geometry_quantile)) + args.geometry_margin])
        meta['geometry'] = extras['geometry'].tolist()
        meta['geometry_from'] = ([str(Path(d).resolve()) for d in args.geometry_from]
                                 if args.geometry_from else 'training folders')
    if args.rgb_lp:
        lp = dt.fit_rgb_lp(counts.rgb_pos, np.maximum(counts.rgb_neg, 0), w=args.lp_w,
                           max_thresholds=args.lp_max)
        extras['rgb_lp_thresholds'] = lp.thresholds
        meta['rgb_lp'] = lp.metadata
    return extras


def _table_metrics(args: argparse.Namespace, lut: np.ndarray, train: list, val: list,
                   sat_norm: Optional[cm.SatNorm]) -> dict:
    """Pixel metrics of the table on the training (``--metrics``) and validation images."""
    metrics = {}
    if args.metrics:
        metrics['train'] = pixel_metrics(lut, args.v_min, train, gray_world=args.gray_world,
                                         sat_norm=sat_norm, white_balance=args.white_balance)
    if val:
        metrics['validation'] = pixel_metrics(lut, args.v_min, val,
                                              gray_world=args.gray_world, sat_norm=sat_norm,
                                              white_balance=args.white_balance)
    return metrics


def _load_training_pairs(data: list[str]) -> Optional[list[tuple[Path, Path]]]:
    """The image/mask pairs of ``data``; None (after one line on stderr) when there are none."""
    try:
        pairs = load_pairs(data)
    except FileNotFoundError as exc:
        print(f'workzone-ros train color: {exc}', file=sys.stderr)
        return None
    if not pairs:
        print('workzone-ros train color: no image/mask pairs found', file=sys.stderr)
        return None
    return pairs


def main(argv: Optional[list[str]] = None) -> int:
    """Train and write the colour model; returns the exit status."""
    args = _parser().parse_args(argv)
    pairs = _load_training_pairs(args.data)
    if pairs is None:
        return 2
    train = [pp for pp in pairs if not _is_val(pp[0], args.val_frac)]
    val = [pp for pp in pairs if _is_val(pp[0], args.val_frac)]
    t0 = time.perf_counter()
    sat_norm = cm.SatNorm(ref=args.sat_ref, max_gain=args.sat_max_gain) if args.sat_norm \
        else None
    counts = _count_pixels(args, train, sat_norm)
    t_count = time.perf_counter() - t0
    clf = cm.fit_boosted(counts.pos, counts.neg, args.estimators, args.pos_weight)
    lut = cm.boosted_lut(clf)
    n_est = int(len(clf.estimators_))
    t_fit = time.perf_counter() - t0 - t_count
    jitter = (args.camera_pitch, args.camera_yaw, args.camera_zoom)
    prior = cm.fit_prior(counts.boxes, counts.size or (640, 480),
                         saturate=args.prior_saturate, roi_level=args.prior_roi_level,
                         camera_jitter=jitter if any(jitter) else None)
    meta = _metadata(args, len(train), len(val), counts, n_est, sat_norm, jitter)
    extras = _geometry_and_lp(args, counts, meta)
    model = cm.default_model(lut, args.v_min, prior, meta)
    model = cm.ColorModel(model.classes, model.luts, model.v_min, model.prior, meta, extras)
    meta['metrics'] = _table_metrics(args, lut, train, val, sat_norm)
    cm.save_model(model, args.output)
    print(json.dumps({'output': args.output, 'bytes': Path(args.output).stat().st_size,
                      'seconds': {'count': round(t_count, 2), 'fit': round(t_fit, 2)},
                      'prior_roi': list(prior.roi), **meta}, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
