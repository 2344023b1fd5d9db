"""``workzone-ros train cnn``: a small CNN sign classifier, exported to ONNX for ``cv2.dnn``.

Needs PyTorch and onnx (``pip install -e .[cnn]``); the model it writes does not
(``workzone_ros.core.cnn_classifier`` runs it with OpenCV).  One thread
(``torch.set_num_threads(1)``), a time budget (``--max-minutes``, default 14).

Sources are those of ``workzone-ros train classifier`` (the same render cache and the same
folder loader): ``--synth N`` renders, ``--data DIR`` folders, ``--exclude-clip`` /
``--real-clips`` to choose which real clips of ``DIR/index.csv`` train the model.

Every training crop is re-cut and degraded on the fly like a phone camera's frame, so the
network does not learn the renderer:

* size: a render of a small sign (stored enlarged to 64 px, with blocky pixels) is first
  brought back to the size it had in the frame, then the cut is shrunk by up to 2x (seen
  from farther away), never enlarged (8 % of them go to 70-130 px: the run-time path of big
  crops); the network's input resize enlarges it smoothly, as at run time.  Rendered signs
  below ``--min-sign-side`` (12 px, the node's ``min_size``) are left out, and no sign is
  shrunk below it: at 8-11 px a sign is an orange blob, and a network that learns to call
  blobs signs calls real cones and loaders signs;
* framing: the object's box (from the crop index) grown by the node's margin and squared,
  as ``classify_boxes`` cuts it, then shifted by up to 12 % and scaled by 0.86-1.42 (a
  detector's localisation error; the stored real crops' 25 % margin is inside that range),
  a rotation of up to 12 deg and a horizontal squeeze (a sign seen at an angle); parts
  outside the stored crop are clipped (as at the image border) or padded;
* surroundings: half of the rendered sign draws (``--composite``) are replaced by a sign
  on one of the training background crops, real ones preferred: the simulator's sign art
  (any class, orange sheeting varied, light gradient, grain, often a post) or the render
  itself cut out along its class's outline.  Without it the network learns that busy real
  surroundings (houses, brick, traffic) mean ``background``: with them blurred, a real
  UTILITY WORK AHEAD diamond it called background at 0.9 became a sign;
* real signs' surroundings: half of the real sign draws (``--real-composite``) are the
  sign's labelled box put on another real background crop (``cnn_augment.transplant``), so
  that the few real signs are not learned together with their own street.  Leave one clip
  out over three seeds it named more of the held-out clip's sign (docs/classifier.md);
* colour: white balance, exposure, gamma, contrast, saturation, hue (+-6 deg), haze,
  sensor noise; JPEG quality 30-95 at the crop's size; Gaussian blur;
* partial occlusion from a border (a pole, a car, foliage: a flat or textured band);
* left-right flips of background crops and of the pictogram mirror pairs (W1-4, W4-2:
  the label swaps), never of a legend.

Then a 4-block CNN (3x3 conv + BN + ReLU, 2x2 max-pool; widths w, 2w, 4w, 8w; global
average; dropout; linear) on ``--input-size`` (32) px colour crops, AdamW, a cosine schedule,
label smoothing.  Sampling: classes balanced by the square root of their counts, real
crops ``--real-share`` of the draws of each class that has them (the same share in every
class, so that looking real does not mean ``background``), ``background``
``--background-share`` of all draws.  ``--background-bias`` is stored in the model and
added to its ``background`` output at run time (a prior for a detector whose boxes are
mostly not signs; 0 by default).

Measurement (every number from crops the model did not train on):

* ``--holdout-split K``: train on the training part of split K of ``evaluate classifier``'s
  Table III splits of the rendered crops (``StratifiedGroupKFold(3)`` by physical object,
  ``--split-seed``) and report on its test part: macro P / R, mirror pairs, background
  false-sign rate, and what each background bias would give (``background_bias``);
* real clips left out with ``--exclude-clip`` are reported per clip (accuracy, per class,
  background false-sign rate), the leave-one-clip-out protocol of ``test/data/real_crops``,
  on the stored crops and re-cut as ``classify_boxes`` cuts (``runtime_framing``).

Example (docs/classifier.md)::

    workzone-ros train cnn --synth 20 --synth-seeds 0 1 2 3 4 5 --synth-random 4 \\
        --data test/data/real_crops -o config/models/sign_classifier_cnn.npz
"""
from __future__ import annotations

import argparse
import collections
import csv
import datetime as _dt
import io
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from workzone_ros.core import cnn_classifier as cnn
from workzone_ros.tools import train_classifier as tc
from workzone_ros.tools.clips import GROW, MAX_SIDE
from workzone_ros.tools.cnn_augment import RUN_MARGIN, augment, composite, cutout, transplant
from workzone_ros.tools.outputs import json_default

__all__ = ['Sample', 'TrainConfig', 'load_samples', 'augment', 'composite', 'cutout',
           'build_net', 'train', 'export', 'bias_table', 'runtime_crop', 'main']

DEFAULT_OUTPUT = Path(__file__).resolve().parents[2] / 'config' / cnn.DEFAULT_MODEL
#: Mirror pictograms: a flipped crop of one is a crop of the other.
FLIP_SWAP = {'lane_shift_left': 'lane_shift_right', 'lane_shift_right': 'lane_shift_left',
             'left_lane_ends': 'right_lane_ends', 'right_lane_ends': 'left_lane_ends'}
OPSET = 17
#: Classes told from another only by their top: hidden, a crop of one is the other's.
TOP_DEFINED = frozenset({'work_zone_speed_limit'})


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


# --- data: crops with the object's box inside each ----------------------------------------

@dataclass
class Sample:
    """Training crops, their labels, and where the object is in each crop.

    ``boxes`` are ``(x, y, w, h)`` in the crop's pixels (``None``: the whole crop);
    ``scales`` are the frame pixels one crop pixel covers (a render of a 13 px sign is
    stored at 64 px: 0.2); ``data`` keeps the
    :class:`~workzone_ros.tools.train_classifier.CropSet` (labels, groups, clips, sources)
    in the same order.
    """

    data: tc.CropSet
    boxes: list = field(default_factory=list)
    scales: list = field(default_factory=list)

    def subset(self, idx: Sequence[int]) -> 'Sample':
        idx = list(idx)
        return Sample(self.data.subset(idx), [self.boxes[i] for i in idx],
                      [self.scales[i] for i in idx])

    def extend(self, other: 'Sample') -> 'Sample':
        self.data.extend(other.data)
        self.boxes.extend(other.boxes)
        self.scales.extend(other.scales)
        return self


def render_boxes(specs: Sequence, per_class: int, size: int, cache: Path
                 ) -> tuple[list, list]:
    """The object's box inside every crop :func:`train_classifier.render_crops` returns,
    in the same order (from the render index: the box, and the jittered crop box that was
    cut, then cut to its visible part), and the crops' scales (frame px per crop px)."""
    from workzone_ros.sim.world import DEFAULT_CAMERA
    W, H = DEFAULT_CAMERA.width, DEFAULT_CAMERA.height
    out, scales = [], []
    for spec, seed in specs:
        folder = tc._render_one(spec, seed, per_class, size, Path(cache))
        with open(folder / 'index.csv', newline='') as fh:
            for r in csv.DictReader(fh):
                x, y, w, h = (float(r[k]) for k in ('crop_x', 'crop_y', 'crop_w', 'crop_h'))
                x0, y0, x1, y1 = max(x, 0.0), max(y, 0.0), min(x + w, W), min(y + h, H)
                if x1 <= x0 or y1 <= y0 or (x1 - x0) * (y1 - y0) < 0.5 * w * h:
                    continue                          # _visible_part drops it
                sx, sy = size / w, size / h
                c0, r0 = int(round((x0 - x) * sx)), int(round((y0 - y) * sy))
                if (x0, y0, x1, y1) != (x, y, x + w, y + h):
                    c1, r1 = int(round((x1 - x) * sx)), int(round((y1 - y) * sy))
                    if c1 - c0 < 4 or r1 - r0 < 4:
                        continue
                bx, by, bw, bh = (float(r[k]) for k in ('box_x', 'box_y', 'box_w', 'box_h'))
                out.append(((bx - x) * sx - c0, (by - y) * sy - r0, bw * sx, bh * sy))
                scales.append(w / size)
    return out, scales


def folder_boxes(root: Path, exclude: Sequence[str], only: Optional[Sequence[str]],
                 shapes: Sequence[tuple]) -> tuple[list, list]:
    """The object's box inside every crop :func:`train_classifier.load_folder` returns.

    From ``root/index.csv`` columns ``x, y, w, h`` (the box in the frame) for crops cut as
    ``workzone-ros make-crops`` does (the box grown by 25 %, clipped, shrunk);
    ``None`` for crops without an index row.  Also the crops' scales (frame px per crop
    px: 1 unless the crop was shrunk to 64 px).
    """
    rows = {}
    index = root / 'index.csv'
    if index.is_file():
        with open(index, newline='') as fh:
            reader = csv.DictReader(fh)
            if {'path', 'x', 'y', 'w', 'h'} <= set(reader.fieldnames or ()):
                rows = {Path(r['path']).as_posix(): r for r in reader}
    clips = tc._clip_index(root)
    out = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        for img in sorted(folder.iterdir()):
            if img.suffix.lower() not in tc.IMAGE_EXT:
                continue
            rel = img.relative_to(root).as_posix()
            clip = clips.get(rel, ('', 0.0))[0]
            if clip in exclude or (only is not None and clip not in only):
                continue
            r = rows.get(rel)
            if r is None:
                out.append(None)
                continue
            x, y, w, h = (float(r[k]) for k in ('x', 'y', 'w', 'h'))
            x0, y0 = round(max(0.0, x - GROW * w)), round(max(0.0, y - GROW * h))
            out.append([x - x0, y - y0, w, h])             # native pixels; scaled below
    if len(out) != len(shapes):
        raise tc.DataError(f'{root}: {len(out)} index boxes for {len(shapes)} crops')
    scales = [1.0] * len(out)
    for k, (b, shape) in enumerate(zip(out, shapes)):
        if b is None:
            continue
        x, y, w, h = b
        s = 1.0                                # stored at native size unless shrunk to 64
        if max(shape[:2]) >= MAX_SIDE:
            # the native crop reaches GROW past the box on the right / bottom unless
            # the frame edge cut it (smaller), so the larger of the two ratios is the shrink
            s = min(1.0, max(shape[1] / (x + w * (1 + GROW)),
                             shape[0] / (y + h * (1 + GROW))))
        out[k] = (x * s, y * s, w * s, h * s)
        scales[k] = 1.0 / s
    return out, scales


def load_samples(args: argparse.Namespace, progress=_say) -> tuple[Sample, Sample]:
    """``(renders, real)``: every crop the source options select, with boxes."""
    real = Sample(tc.CropSet())
    for d in args.data:
        root = Path(d)
        part = tc.load_folder(root, exclude_clips=args.exclude_clip, only_clips=args.real_clips)
        real.extend(Sample(part, *folder_boxes(root, args.exclude_clip, args.real_clips,
                                               [c.shape for c in part.crops])))
    renders = Sample(tc.CropSet())
    if args.synth > 0:
        specs = tc.synth_specs(args.synth_seeds, args.synth_random, not args.no_library)
        data = tc.render_crops(specs, args.synth, args.size, Path(args.cache), progress)
        boxes, scales = render_boxes(specs, args.synth, args.size, Path(args.cache))
        if len(boxes) != len(data):
            raise tc.DataError(f'render index gives {len(boxes)} boxes for {len(data)} crops')
        renders = Sample(data, boxes, scales)
    if not len(renders.data) + len(real.data):
        raise tc.DataError('no training crops: give --synth N and/or --data DIR')
    return renders, real


# --- network -------------------------------------------------------------------------------

def build_net(n_classes: int, width: int = 8, dropout: float = 0.2):
    """The CNN: 4 blocks of 3x3 conv + BN + ReLU (widths w, 2w, 4w, 8w), 2x2 max-pools
    between them, global average, dropout, linear."""
    import torch.nn as nn

    def block(i: int, o: int) -> list:
        return [nn.Conv2d(i, o, 3, padding=1, bias=False), nn.BatchNorm2d(o), nn.ReLU()]

    w = width
    return nn.Sequential(*block(3, w), nn.MaxPool2d(2), *block(w, 2 * w), nn.MaxPool2d(2),
                         *block(2 * w, 4 * w), nn.MaxPool2d(2), *block(4 * w, 8 * w),
                         nn.AdaptiveAvgPool2d(1), nn.Flatten(), nn.Dropout(dropout),
                         nn.Linear(8 * w, n_classes))


def macs(width: int, size: int, n_classes: int) -> int:
    """Multiply-accumulates of one crop through :func:`build_net`."""
    chans = [3, width, 2 * width, 4 * width, 8 * width]
    total, s = 0, size
    for k in range(4):
        total += s * s * chans[k + 1] * chans[k] * 9
        if k < 3:
            s //= 2
    return total + 8 * width * n_classes


@dataclass
class TrainConfig:
    input_size: int = 32
    width: int = 8
    epochs: int = 40
    samples_per_epoch: int = 6000
    batch: int = 128
    lr: float = 3e-3
    weight_decay: float = 5e-4
    label_smoothing: float = 0.05
    dropout: float = 0.2
    real_share: float = 0.4
    composite: float = 0.5
    real_composite: float = 0.5
    min_sign_side: float = 12.0
    background_share: float = 0.3
    class_power: float = 0.5
    max_minutes: float = 14.0
    seed: int = 0


def _weights(labels: np.ndarray, real: np.ndarray, cfg: TrainConfig) -> np.ndarray:
    """Sampling weights: classes balanced towards uniform by ``class_power``; within a class
    that has real and rendered crops, the real ones get ``real_share`` of its draws (the
    same share in every class, so that looking real does not predict ``background``);
    ``background`` gets ``background_share`` of all draws (0: as ``class_power`` says)."""
    keys, inv, counts = np.unique(labels, return_inverse=True, return_counts=True)
    w = counts[inv].astype(float) ** (1.0 - cfg.class_power)      # mass of each class
    out = np.zeros(len(labels))
    for k in range(len(keys)):
        sel = inv == k
        r, s = sel & real, sel & ~real
        share = cfg.real_share if r.any() and s.any() else float(r.any())
        if r.any():
            out[r] = w[r] * share / r.sum()
        if s.any():
            out[s] = w[s] * (1.0 - share) / s.sum()
    out /= out.sum()
    bg = labels == 'background'
    if cfg.background_share > 0 and bg.any() and (~bg).any():
        out[bg] *= cfg.background_share / out[bg].sum()
        out[~bg] *= (1.0 - cfg.background_share) / out[~bg].sum()
    return out


def train(sample: Sample, labels: Sequence[str], classes: Sequence[str], cfg: TrainConfig,
          progress=_say):
    """Train the network on ``sample`` (labels mapped to ``classes``); returns it (eval)."""
    import torch
    torch.set_num_threads(1)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    idx_of = {c: i for i, c in enumerate(classes)}
    real = np.array([c != '' for c in sample.data.clip])
    p = _weights(np.asarray(labels), real, cfg)
    net = build_net(len(classes), cfg.width, cfg.dropout)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    loss_fn = torch.nn.CrossEntropyLoss(label_smoothing=cfg.label_smoothing)
    steps_per_epoch = max(1, cfg.samples_per_epoch // cfg.batch)
    epochs, step, t0 = cfg.epochs, 0, time.monotonic()
    crops, boxes, scales = sample.data.crops, sample.boxes, sample.scales
    bg = np.flatnonzero(np.asarray(labels) == 'background')
    real_bg = np.flatnonzero((np.asarray(labels) == 'background') & real)
    flip_ok = {k for k in FLIP_SWAP if k in idx_of and FLIP_SWAP[k] in idx_of} | {'background'}

    def lr_at(s: int, total: int) -> float:
        warm = steps_per_epoch
        if s < warm:
            return cfg.lr * (s + 1) / warm
        return 0.5 * cfg.lr * (1 + math.cos(math.pi * min(1.0, (s - warm) / max(1, total - warm))))

    epoch = 0
    while epoch < epochs:
        net.train()
        tot_loss = correct = seen = 0
        draw = rng.choice(len(crops), size=steps_per_epoch * cfg.batch, p=p)
        for b in range(steps_per_epoch):
            ids = draw[b * cfg.batch:(b + 1) * cfg.batch]
            imgs, ys = [], []
            for i in ids:
                tex = crops[int(bg[rng.integers(len(bg))])] if len(bg) else None
                lab = labels[i]
                top = lab in TOP_DEFINED
                if lab != 'background' and not real[i] and len(bg) \
                        and rng.random() < cfg.composite:
                    pool = real_bg if len(real_bg) and rng.random() < 0.6 else bg
                    backdrop = crops[int(pool[rng.integers(len(pool))])]
                    if rng.random() < 0.5 or boxes[i] is None:
                        canvas, box = composite(lab, backdrop, rng)
                    else:
                        canvas, box = cutout(lab, crops[i], boxes[i], scales[i], backdrop,
                                             rng)
                    img = augment(canvas, box, rng, 1.0, tex, cfg.min_sign_side, top)
                elif (lab != 'background' and real[i] and boxes[i] is not None
                      and len(real_bg) and cfg.real_composite > 0
                      and rng.random() < cfg.real_composite):
                    backdrop = crops[int(real_bg[rng.integers(len(real_bg))])]
                    canvas, box = transplant(crops[i], boxes[i], backdrop, rng)
                    img = augment(canvas, box, rng, scales[i], tex, cfg.min_sign_side, top)
                else:
                    img = augment(crops[i], boxes[i], rng, scales[i], tex,
                                  0.0 if lab == 'background' else cfg.min_sign_side, top)
                if lab in flip_ok and rng.random() < 0.5:
                    img = img[:, ::-1]
                    lab = FLIP_SWAP.get(lab, lab)
                imgs.append(img)
                ys.append(idx_of[lab])
            x = torch.from_numpy(cnn.preprocess(imgs, cfg.input_size))
            y = torch.tensor(ys)
            for g in opt.param_groups:
                g['lr'] = lr_at(step, epochs * steps_per_epoch)
            out = net(x)
            loss = loss_fn(out, y)
            opt.zero_grad()
            loss.backward()
            opt.step()
            step += 1
            tot_loss += loss.item() * len(ys)
            correct += int((out.argmax(1) == y).sum())
            seen += len(ys)
        epoch += 1
        spent = time.monotonic() - t0
        if epoch == 1:                       # fit the schedule into the time budget
            fit = int(cfg.max_minutes * 60 / max(spent, 1e-3))
            if fit < epochs:
                epochs = max(2, fit)
                progress(f'time budget {cfg.max_minutes:g} min: {epochs} epochs '
                         f'({spent:.0f} s each)')
        progress(f'epoch {epoch}/{epochs}: loss {tot_loss / seen:.3f}, train accuracy '
                 f'(augmented) {correct / seen:.3f}, {spent / 60:.1f} min')
    net.eval()
    return net, {'epochs': epochs, 'minutes': round((time.monotonic() - t0) / 60, 2)}


def export(net, input_size: int) -> bytes:
    """The network as ONNX bytes (batch dimension dynamic), BatchNorm folded."""
    import torch
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        torch.onnx.export(net, torch.zeros(1, 3, input_size, input_size), buf,
                          input_names=['crops'], output_names=['logits'],
                          dynamic_axes={'crops': {0: 'n'}, 'logits': {0: 'n'}},
                          opset_version=OPSET, do_constant_folding=True, dynamo=False)
    return buf.getvalue()


def _check_export(net, model: cnn.CnnSignClassifier, crops: Sequence[np.ndarray]) -> float:
    """Largest |logit difference| between torch and cv2.dnn on some crops."""
    import torch
    x = cnn.preprocess(crops, model.input_size)
    with torch.no_grad():
        ref = net(torch.from_numpy(x)).numpy()
    return float(np.abs(model._forward(x) - ref).max())


# --- measurement ---------------------------------------------------------------------------

def report(model, data: tc.CropSet) -> dict:
    """``evaluate classifier``'s figures of ``model`` on ``data``."""
    from workzone_ros.tools import eval_classifier as ec
    res, _ = ec.evaluate_model(model, data)
    res.pop('_confusion', None)
    res['counts'] = data.counts()
    return res


BIASES = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0)


def bias_table(model, data: tc.CropSet, biases: Sequence[float] = BIASES) -> dict:
    """What a ``background_bias`` would do on ``data``: per bias, background crops given a
    sign class, sign crops given their class, and the macro P / R, all crops and the
    node's sizes (sign boxes >= 12 px); pooled over splits, it chooses the shipped bias."""
    from workzone_ros.tools import eval_classifier as ec
    z = np.vstack([model.logits(data.crops[i:i + 256]) for i in range(0, len(data), 256)])
    labels = np.array(tc.map_labels(data.labels, model.classes))
    big = (labels == 'background') | ~(np.asarray(data.side, float) < 12)
    saved, out = model.background_bias, {}
    try:
        for b in biases:
            model.background_bias = b
            pred = np.asarray(model.classes)[model.proba_of_logits(z).argmax(1)]
            bg = labels == 'background'
            sc, sc12 = (ec.scores(labels[k], pred[k], model.classes) for k in (
                slice(None), big))
            out[f'{b:g}'] = {
                'background_crops': int(bg.sum()),
                'background_given_sign': int(np.sum(pred[bg] != 'background')),
                'sign_crops': int((~bg).sum()),
                'sign_given_its_class': int(np.sum(pred[~bg] == labels[~bg])),
                'precision': round(sc['precision'], 4), 'recall': round(sc['recall'], 4),
                'precision_12px': round(sc12['precision'], 4),
                'recall_12px': round(sc12['recall'], 4)}
    finally:
        model.background_bias = saved
    return out


def runtime_crop(crop: np.ndarray, box) -> np.ndarray:
    """A stored crop re-cut as ``classify_boxes`` cuts the frame (square, the node's
    margin), clipped to the stored crop; the whole crop when its box is unknown."""
    from workzone_ros.core.features import crop_sign
    if box is None:
        return crop
    out, _ = crop_sign(crop, box, RUN_MARGIN, square=True)
    return crop if out is None else out


def _line(name: str, r: dict) -> str:
    bg = r['background']
    return (f'{name}: {sum(r["counts"].values())} crops, P {r["precision"]:.3f} '
            f'R {r["recall"]:.3f} accuracy {r["accuracy"]:.3f}, background false-sign '
            f'{bg["false_sign_rate"]} ({bg["background_crops"]})')


# --- command line --------------------------------------------------------------------------

def _parser() -> argparse.ArgumentParser:
    p = tc._Parser(prog='workzone-ros train cnn', description=__doc__,
                   formatter_class=argparse.RawDescriptionHelpFormatter)
    tc.add_source_arguments(p, synth_default=20)
    p.add_argument('--real-clips', nargs='+', default=None, metavar='NAME',
                   help="train only on these clips of the --data folders (index.csv column "
                        "'clip'; default all but --exclude-clip)")
    d = TrainConfig()
    p.add_argument('--input-size', type=int, default=d.input_size,
                   help=f'network input side, px (default {d.input_size})')
    p.add_argument('--width', type=int, default=d.width,
                   help=f'channels of the first block (then x2, x4, x8; default {d.width})')
    p.add_argument('--epochs', type=int, default=d.epochs, help=f'default {d.epochs}')
    p.add_argument('--samples-per-epoch', type=int, default=d.samples_per_epoch,
                   help=f'augmented crops drawn per epoch (default {d.samples_per_epoch})')
    p.add_argument('--batch', type=int, default=d.batch, help=f'default {d.batch}')
    p.add_argument('--lr', type=float, default=d.lr, help=f'peak AdamW rate ({d.lr:g})')
    p.add_argument('--real-share', type=float, default=d.real_share,
                   help='share of the draws of a class that are real crops, when it has '
                        f'real and rendered ones (default {d.real_share:g})')
    p.add_argument('--composite', type=float, default=d.composite,
                   help='share of the rendered sign draws replaced by the sign art pasted on a '
                        f'training background crop (default {d.composite:g})')
    p.add_argument('--real-composite', type=float, default=d.real_composite,
                   help='share of the real sign draws whose box is put on another real '
                        f'background crop (default {d.real_composite:g})')
    p.add_argument('--background-share', type=float, default=d.background_share,
                   help='share of the draws that are background crops (0: balanced like '
                        f'the other classes; default {d.background_share:g})')
    p.add_argument('--background-bias', type=float, default=0.0,
                   help='added to the background output at run time (stored in the model; '
                        'default 0)')
    p.add_argument('--min-sign-side', type=float, default=d.min_sign_side,
                   help='leave out rendered sign crops whose box is smaller (px) and never '
                        'shrink a sign below it in augmentation (the node publishes smaller '
                        f'boxes as unknown; default {d.min_sign_side:g})')
    p.add_argument('--max-minutes', type=float, default=d.max_minutes,
                   help='time budget: fewer epochs when one epoch says it would not fit '
                        f'(default {d.max_minutes:g})')
    p.add_argument('--seed', type=int, default=0, help='training seed')
    p.add_argument('--holdout-split', type=int, default=None, metavar='K',
                   help="train on split K's training part of the rendered crops (evaluate "
                        "classifier's Table III splits) and report on its test part")
    p.add_argument('--splits', type=int, default=5, help='splits of --holdout-split (5)')
    p.add_argument('--split-seed', type=int, default=0, help='seed of the splits (0)')
    p.add_argument('--json', metavar='OUT', help='write the figures to this JSON file')
    p.add_argument('-o', '--output', default=str(DEFAULT_OUTPUT),
                   help='model file (default config/models/sign_classifier_cnn.npz)')
    return p


def _have_torch(prog: str) -> bool:
    """True when PyTorch and onnx import; else one line on stderr."""
    try:
        import onnx  # noqa: F401
        import torch  # noqa: F401
    except ImportError as exc:
        print(f'{prog}: needs PyTorch and onnx ({exc.name} is missing): pip install -e '
              '.[cnn]', file=sys.stderr)
        return False
    return True


def _split_holdout(args: argparse.Namespace, renders: Sample, classes: list[str]
                   ) -> tuple[Sample, Optional[tc.CropSet]]:
    """``--holdout-split``: the training part of the renders and the held-out test part."""
    if args.holdout_split is None:
        return renders, None
    from workzone_ros.tools import eval_classifier as ec
    if not len(renders.data):
        raise tc.DataError('--holdout-split splits the rendered crops: give --synth')
    if not 0 <= args.holdout_split < args.splits:
        raise tc.DataError(f'--holdout-split must be in 0..{args.splits - 1}')
    lab = tc.map_labels(renders.data.labels, classes)
    tr, te = ec.grouped_splits(lab, renders.data.groups, args.splits,
                               args.split_seed)[args.holdout_split]
    test = renders.data.subset(te)
    return renders.subset(tr), test


def _drop_small_renders(args: argparse.Namespace, renders: Sample, classes: list[str]
                        ) -> tuple[Sample, int]:
    """The renders without signs below ``--min-sign-side``, and how many were dropped."""
    # rendered signs too small for the node to classify (its min_size) are left out:
    # at 8-11 px a sign is an orange blob, and a blob is what a network must not learn
    # to call a sign
    # (unless that leaves a class without crops: then it keeps its small ones)
    mapped = tc.map_labels(renders.data.labels, classes)
    small = [i for i, (lab, side) in enumerate(zip(mapped, renders.data.side))
             if lab != 'background' and side < args.min_sign_side]
    left = collections.Counter(mapped)
    left.subtract(mapped[i] for i in small)
    small = [i for i in small if left[mapped[i]] > 0]
    return renders.subset(sorted(set(range(len(renders.data))) - set(small))), len(small)


@dataclass
class _TrainingData:
    """The crops of a run: training set, its labels and classes, and the held-out renders."""

    renders: Sample
    real: Sample
    train_set: Sample
    labels: list[str]
    classes: list[str]
    test: Optional[tc.CropSet]
    dropped: int


def _training_data(args: argparse.Namespace) -> _TrainingData:
    """Load, split and filter the crops; raises :class:`tc.DataError` on bad input."""
    renders, real = load_samples(args)
    everything = Sample(tc.CropSet()).extend(renders).extend(real)
    classes = tc.class_list(args.classes, everything.data.labels)
    renders, test = _split_holdout(args, renders, classes)
    renders, dropped = _drop_small_renders(args, renders, classes)
    train_set = Sample(tc.CropSet()).extend(renders).extend(real)
    labels = tc.map_labels(train_set.data.labels, classes)
    missing = [c for c in classes if c not in set(labels)]
    if missing:
        raise tc.DataError(f'no crops of class(es) {", ".join(missing)}; add renders '
                           '(--synth) or folders for them, or use --classes workzone')
    return _TrainingData(renders, real, train_set, labels, classes, test, dropped)


def _train_config(args: argparse.Namespace) -> TrainConfig:
    """The :class:`TrainConfig` of the command-line options."""
    return TrainConfig(input_size=args.input_size, width=args.width, epochs=args.epochs,
                       samples_per_epoch=args.samples_per_epoch, batch=args.batch, lr=args.lr,
                       real_share=args.real_share, composite=args.composite,
                       real_composite=args.real_composite,
                       min_sign_side=args.min_sign_side,
                       background_share=args.background_share,
                       max_minutes=args.max_minutes, seed=args.seed)


def _model_metadata(args: argparse.Namespace, cfg: TrainConfig, net, run: dict,
                    data: _TrainingData) -> dict:
    """The metadata stored with the trained model."""
    import torch
    classes, labels = data.classes, data.labels
    src = tc.describe_sources(args, data.train_set.data)
    src['only_clips'] = args.real_clips
    src['render_signs_below_min_side_left_out'] = data.dropped
    if args.holdout_split is not None:
        src['holdout'] = {'split': args.holdout_split, 'of': args.splits,
                          'seed': args.split_seed,
                          'trained_render_crops': len(data.renders.data),
                          'held_out_render_crops': len(data.test)}
    md = {'input_size': cfg.input_size, 'normalise': 'per_crop', 'channels': 'bgr',
          'margin': RUN_MARGIN, 'square_crops': True, 'temperature': 1.0,
          'method': 'cnn', 'features': 'cnn',
          'architecture': {'blocks': [cfg.width * m for m in (1, 2, 4, 8)], 'conv': '3x3',
                           'norm': 'batch (folded)', 'pool': 'max 2x2 between blocks',
                           'head': 'global average, dropout, linear',
                           'parameters': int(sum(q.numel() for q in net.parameters())),
                           'macs_per_crop': macs(cfg.width, cfg.input_size, len(classes))},
          'training': {**{k: getattr(cfg, k) for k in (
              'epochs', 'samples_per_epoch', 'batch', 'lr', 'weight_decay', 'label_smoothing',
              'dropout', 'real_share', 'composite', 'real_composite', 'min_sign_side',
              'background_share', 'class_power', 'seed')}, **run,
              'optimiser': 'AdamW, cosine schedule, 1 warm-up epoch',
              'augmentation': 'renders at their size in the frame, shrunk up to 2x, '
                              'signs >= min_sign_side; run-time framing +-12 % shift, '
                              'x0.86-1.42 scale, +-12 deg, x0.75-1.08 squeeze; signs on '
                              'training background crops (art or render cut-outs); JPEG '
                              '30-95; blur; white balance, exposure, gamma, contrast, '
                              'saturation, hue, haze, noise; border occlusion; flips of '
                              'background and W1-4 / W4-2 (label swapped)',
              'torch': torch.__version__, 'onnx_opset': OPSET},
          'training_sources': src, 'class_set': args.classes,
          'train_counts': {c: labels.count(c) for c in classes},
          'date': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds')}
    if args.background_bias:
        md['background_bias'] = args.background_bias
    return md


def _held_out_clips(args: argparse.Namespace, model, classes: list[str]) -> dict:
    """Figures of the model on the ``--exclude-clip`` clips of the ``--data`` folders."""
    clips = {}
    for d in args.data:
        for clip in args.exclude_clip:
            try:
                part = tc.load_folder(d, only_clips=[clip])
            except tc.DataError:
                continue
            res = report(model, part)
            boxes, _ = folder_boxes(Path(d), (), [clip], [c.shape for c in part.crops])
            recut = tc.CropSet(*[list(getattr(part, f)) for f in tc._FIELDS])
            recut.crops = [runtime_crop(c, b) for c, b in zip(part.crops, boxes)]
            res['runtime_framing'] = report(model, recut)
            res['wrong'] = [f'{t} -> {p}' for t, p in zip(
                tc.map_labels(part.labels, classes),
                [q.class_key for q in model.classify(part.crops)]) if t != p][:20]
            clips[clip] = res
            _say(_line(f'held-out clip {clip}', res))
            _say(_line(f'held-out clip {clip}, run-time framing', res['runtime_framing']))
    return clips


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point; returns the exit status (2 with one line on stderr for bad input)."""
    args = _parser().parse_args(argv)
    prog = 'workzone-ros train cnn'
    if not _have_torch(prog):
        return 2
    try:
        data = _training_data(args)
    except tc.DataError as exc:
        print(f'{prog}: {exc}', file=sys.stderr)
        return 2
    cfg = _train_config(args)
    classes, train_set = data.classes, data.train_set
    _say(f'training a CNN (width {cfg.width}, {cfg.input_size} px, '
         f'{macs(cfg.width, cfg.input_size, len(classes)) / 1e6:.2f} M MAC per crop) on '
         f'{len(train_set.data)} crops ({len(data.real.data)} real), {len(classes)} classes: '
         + ', '.join(f'{k} {v}' for k, v in sorted(train_set.data.counts().items())))
    net, run = train(train_set, data.labels, classes, cfg)
    md = _model_metadata(args, cfg, net, run, data)
    model = cnn.CnnSignClassifier(export(net, cfg.input_size), classes, md)
    probe = train_set.data.crops[:64]
    model.metadata['onnx_check_max_abs_logit_diff'] = round(_check_export(net, model, probe), 6)
    cnn.save_model(model, args.output)
    out = {'model': args.output, 'metadata': model.metadata}
    if data.test is not None:
        out['holdout'] = report(model, data.test)
        out['holdout']['background_bias'] = bias_table(model, data.test)
        _say(_line(f'held-out renders (split {args.holdout_split})', out['holdout']))
    if args.data and args.exclude_clip:
        out['held_out_clips'] = _held_out_clips(args, model, classes)
    text = json.dumps(out, indent=2, default=json_default)
    if args.json:
        Path(args.json).write_text(text)
        _say(f'figures written to {args.json}')
    print(f'model written to {args.output} ({Path(args.output).stat().st_size / 1024:.0f} KiB)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
