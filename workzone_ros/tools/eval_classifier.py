"""``workzone-ros evaluate classifier``: Seo et al. Table III on held-out renders, and more.

What it measures (every number from crops it did not train on):

* **Table III** -- SVM, LDA and kNN (k = 10) on log-polar + PCA(10) and on 100 x 100 raw
  intensity + PCA(10), plus our feature variants (``--variants``), macro precision and
  recall (mean / std) over ``--splits`` random splits of the rendered crops (every weather).
  Splits are grouped by physical object: every view of one sign instance (the same library
  sign under another render seed too) and every background frame falls on one side, so a
  test crop is never a near-copy of a training crop; a third of each class is held out.
* For the chosen configuration (``--features``, default the trainer's): the confusion
  matrix pooled over the splits (PNG), the left/right mirror pairs' separation
  (1 - share of the pair's crops given its mirror class), the background false-sign rate
  (background crops given any sign class) and recall by box size.
* ``--model M``: that model on all selected crops (pass sources it was not trained on,
  e.g. ``--no-library --synth-seeds 4 5``: random scenarios of new seeds).
* ``--real DIR``: leave-one-clip-out on hand-labelled real crops (``DIR/index.csv`` column
  ``clip``): train on the renders plus the real crops of the other clips, report on the
  held-out clip, per clip.

Usage (docs/classifier.md)::

    workzone-ros evaluate classifier --json /tmp/cls.json --report /tmp/cls_report
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core import classifier as clf_mod
from workzone_ros.core import features as ft
from workzone_ros.core import signs
from workzone_ros.tools import train_classifier as tc
from workzone_ros.tools.outputs import print_json

__all__ = ['main', 'grouped_splits', 'scores', 'mirror_separation', 'background_fp',
           'score_thresholds', 'draw_confusion', 'contact_sheet']

MIRROR_PAIRS = (('lane_shift_left', 'lane_shift_right'),
                ('left_lane_ends', 'right_lane_ends'),
                ('left_lane_closed_ahead', 'right_lane_closed_ahead'))
SEED_ROWS = ('logpolar', 'raw')
#: Our rows: the extras on the seed's log-polar, the centred log-polar alone and with them.
VARIANTS = ('logpolar+color+mirror', 'logpolar-centred', 'logpolar-centred+color',
            'logpolar-centred+color+mirror')
SIZE_BANDS = ((0, 12), (12, 20), (20, 40), (40, 1e9))
REAL_DEFAULT = Path(__file__).resolve().parents[2] / 'test' / 'data' / 'real_crops'


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


# --- splits and metrics --------------------------------------------------------------------

def grouped_splits(labels: Sequence[str], groups: Sequence[str], n_splits: int = 5,
                   seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n_splits`` random (train, test) index pairs, a third of each class in test, by group.

    Each split is the first fold of a shuffled ``StratifiedGroupKFold(3)``: no group is on
    both sides and classes keep their proportions as far as the groups allow.
    """
    from sklearn.model_selection import StratifiedGroupKFold
    y = np.asarray(labels)
    g = np.asarray(groups)
    out = []
    for r in range(n_splits):
        cv = StratifiedGroupKFold(3, shuffle=True, random_state=seed + r)
        out.append(next(iter(cv.split(np.zeros(len(y)), y, g))))
    return out


def scores(y_true: Sequence[str], y_pred: Sequence[str], classes: Sequence[str]) -> dict:
    """Macro precision / recall / accuracy and the confusion matrix (rows: truth)."""
    from sklearn.metrics import confusion_matrix, precision_recall_fscore_support
    present = [c for c in classes if c in set(y_true)]
    p, r, _, _ = precision_recall_fscore_support(y_true, y_pred, labels=present,
                                                 average='macro', zero_division=0)
    return {'precision': float(p), 'recall': float(r),
            'accuracy': float(np.mean(np.asarray(y_true) == np.asarray(y_pred))),
            'confusion': confusion_matrix(y_true, y_pred, labels=list(classes))}


def mirror_separation(conf: np.ndarray, classes: Sequence[str]) -> dict:
    """Per mirror pair: 1 - (crops of one side given the other) / (crops of the pair)."""
    idx = {c: i for i, c in enumerate(classes)}
    out = {}
    for a, b in MIRROR_PAIRS:
        if a not in idx or b not in idx:
            continue
        i, j = idx[a], idx[b]
        n = int(conf[i].sum() + conf[j].sum())
        swapped = int(conf[i, j] + conf[j, i])
        out[f'{a}/{b}'] = {'crops': n, 'swapped': swapped,
                           'separation': round(1 - swapped / n, 4) if n else None}
    return out


def background_fp(y_true: Sequence[str], y_pred: Sequence[str]) -> dict:
    """Share of background crops given a sign class (any, and a work-zone one)."""
    t, p = np.asarray(y_true), np.asarray(y_pred)
    bg = t == 'background'
    n = int(bg.sum())
    wz = np.isin(p[bg], signs.WORKZONE_KEYS)
    return {'background_crops': n,
            'false_sign_rate': round(float(np.mean(p[bg] != 'background')), 4) if n else None,
            'false_workzone_rate': round(float(np.mean(wz)), 4) if n else None}


def _ms(values: Sequence[float]) -> list[float]:
    return [round(float(np.mean(values)), 3), round(float(np.std(values)), 3)]


# --- pictures ------------------------------------------------------------------------------

def draw_confusion(conf: np.ndarray, classes: Sequence[str], path: str | Path,
                   title: str = '') -> None:
    """A row-normalised confusion matrix as a PNG (rows: truth, columns: prediction)."""
    k, cell, left, top = len(classes), 30, 190, 190
    img = np.full((top + k * cell + 10, left + k * cell + 10, 3), 255, np.uint8)
    rows = conf / np.maximum(conf.sum(1, keepdims=True), 1)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for i in range(k):
        for j in range(k):
            v = rows[i, j]
            colour = (255, int(255 * (1 - v)), int(255 * (1 - v))) if i == j else \
                (int(255 * (1 - v)), int(255 * (1 - v)), 255)
            x, y = left + j * cell, top + i * cell
            cv2.rectangle(img, (x, y), (x + cell - 1, y + cell - 1), colour, -1)
            if conf[i, j]:
                ink = (255, 255, 255) if v > 0.5 else (0, 0, 0)
                cv2.putText(img, str(int(conf[i, j])), (x + 2, y + 19), font, 0.33, ink, 1,
                            cv2.LINE_AA)
        cv2.putText(img, classes[i][:24], (4, top + i * cell + 19), font, 0.4, (0, 0, 0), 1,
                    cv2.LINE_AA)
    labels = np.full((k * cell, top - 4, 3), 255, np.uint8)
    for j in range(k):
        cv2.putText(labels, classes[j][:24], (4, j * cell + 19), font, 0.4,
                    (0, 0, 0), 1, cv2.LINE_AA)
    rot = cv2.rotate(labels, cv2.ROTATE_90_COUNTERCLOCKWISE)   # (top - 4, k * cell)
    img[:rot.shape[0], left:left + rot.shape[1]] = rot
    cv2.putText(img, title[:40], (4, 20), font, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.imwrite(str(path), img)


def contact_sheet(crops: Sequence[np.ndarray], captions: Sequence[str], path: str | Path,
                  cols: int = 8, side: int = 96) -> None:
    """Crops in a grid with a caption under each (e.g. ``truth -> prediction``)."""
    n = max(1, len(crops))
    rows = (n + cols - 1) // cols
    sheet = np.full((rows * (side + 28), cols * side, 3), 255, np.uint8)
    for k, (crop, text) in enumerate(zip(crops, captions)):
        y, x = (k // cols) * (side + 28), (k % cols) * side
        sheet[y:y + side, x:x + side] = cv2.resize(crop, (side, side),
                                                   interpolation=cv2.INTER_NEAREST)
        for m, part in enumerate(text.split('\n')[:2]):
            cv2.putText(sheet, part[:16], (x + 2, y + side + 11 + 12 * m),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.32, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.imwrite(str(path), sheet)


# --- experiments ---------------------------------------------------------------------------

class _Bank:
    """Features of every crop by kind, computed once and sliced per split."""

    def __init__(self, crops: Sequence[np.ndarray]):
        self.crops = crops
        self._cache: dict[str, tuple] = {}

    def _get(self, kind: str) -> tuple:
        if kind not in self._cache:
            self._cache[kind] = ft.features(kind, self.crops)
        return self._cache[kind]

    def base(self, kind: str) -> np.ndarray:
        return self._get(kind)[0]

    def extra(self, kind: str) -> Optional[np.ndarray]:
        return self._get(kind)[1]


def _fit_predict(bank: _Bank, kind: str, method: str, labels: np.ndarray,
                 classes: Sequence[str], tr: np.ndarray, te: np.ndarray, seed: int
                 ) -> tuple[np.ndarray, np.ndarray, clf_mod.SignClassifier]:
    base, extra = bank.base(kind), bank.extra(kind)
    model = clf_mod.fit_arrays(base[tr], None if extra is None else extra[tr], labels[tr],
                               classes, features=kind, method=method, seed=seed)
    z = model.reduce(base[te], None if extra is None else extra[te])
    proba = model.predict_proba_reduced(z)
    return np.asarray(model.classes)[proba.argmax(1)], proba, model


def score_thresholds(labels: np.ndarray, proba: np.ndarray, classes: Sequence[str],
                     thresholds: Sequence[float] = (0.0, 0.5, 0.6, 0.7, 0.8, 0.9)) -> dict:
    """What a consumer's minimum score does: a prediction below it counts as background.

    Per threshold: background crops still given a sign class, and sign crops given their
    own class at or above it (the rest is rejected or wrong).
    """
    names = np.asarray(classes)
    best, score = names[proba.argmax(1)], proba.max(1)
    bg, out = labels == 'background', {}
    for t in thresholds:
        pred = np.where(score >= t, best, 'background')
        out[f'{t:.1f}'] = {
            'background_false_sign_rate': round(float(np.mean(pred[bg] != 'background')), 4),
            'sign_recall': round(float(np.mean(pred[~bg] == labels[~bg])), 4)}
    return out


def table_iii(bank: _Bank, labels: np.ndarray, groups: Sequence[str], classes: Sequence[str],
              rows: Sequence[str], methods: Sequence[str], n_splits: int, seed: int,
              main_kind: str) -> tuple[dict, dict]:
    """Table III cells per (features, method) and the pooled test predictions of main_kind."""
    splits = grouped_splits(labels, groups, n_splits, seed)
    cells: dict = {}
    pooled = {'idx': [], 'pred': [], 'proba': []}
    for s, (tr, te) in enumerate(splits):
        for kind in rows:
            for method in methods:
                t0 = time.monotonic()
                pred, proba, model = _fit_predict(bank, kind, method, labels, classes, tr,
                                                  te, seed + s)
                sc = scores(labels[te], pred, classes)
                cell = cells.setdefault(kind, {}).setdefault(method, {
                    'precision': [], 'recall': [], 'accuracy': [], 'pca_variance_held': []})
                for key in ('precision', 'recall', 'accuracy'):
                    cell[key].append(sc[key])
                cell['pca_variance_held'].append(model.metadata['pca_variance_held'])
                if kind == main_kind and method == 'svm':
                    pooled['idx'].append(te)
                    pooled['pred'].append(pred)
                    pooled['proba'].append(proba)
                _say(f'split {s + 1}/{n_splits} {kind:<22} {method}: P {sc["precision"]:.3f} '
                     f'R {sc["recall"]:.3f} ({len(tr)} train / {len(te)} test, '
                     f'{time.monotonic() - t0:.1f} s)')
    table = {kind: {m: {k: _ms(v) for k, v in c.items()} for m, c in ms.items()}
             for kind, ms in cells.items()}
    return table, pooled


def _size_recall(labels: np.ndarray, pred: np.ndarray, side: np.ndarray) -> dict:
    out = {}
    for lo, hi in SIZE_BANDS:
        sel = (side >= lo) & (side < hi) & (labels != 'background')
        name = f'{lo}-{hi:g}px' if hi < 1e8 else f'>={lo}px'
        out[name] = {'sign_crops': int(sel.sum()),
                     'accuracy': round(float(np.mean(labels[sel] == pred[sel])), 4)
                     if sel.any() else None}
    return out


def _at_min_side(labels: np.ndarray, pred: np.ndarray, side: np.ndarray,
                 classes: Sequence[str], min_side: float) -> dict:
    """Macro figures over the crops the node classifies: sign boxes of at least
    ``min_side`` px (its ``min_size``; unknown sizes kept) and every background crop."""
    keep = (labels == 'background') | ~(side < min_side)
    sc = scores(labels[keep], pred[keep], classes)
    return {'min_side_px': min_side, 'crops': int(keep.sum()),
            **{k: round(sc[k], 4) for k in ('precision', 'recall', 'accuracy')}}


def _summary(labels: np.ndarray, pred: np.ndarray, classes: Sequence[str]) -> dict:
    sc = scores(labels, pred, classes)
    conf = sc.pop('confusion')
    per_class = {}
    for i, c in enumerate(classes):
        n_true, n_pred = int(conf[i].sum()), int(conf[:, i].sum())
        if n_true or n_pred:
            per_class[c] = {'crops': n_true,
                            'recall': round(conf[i, i] / n_true, 4) if n_true else None,
                            'precision': round(conf[i, i] / n_pred, 4) if n_pred else None}
    return {**{k: round(v, 4) for k, v in sc.items()}, 'per_class': per_class,
            'mirror_pairs': mirror_separation(conf, classes),
            'background': background_fp(labels, pred), '_confusion': conf}


def _report_pictures(report: Path, name: str, data: tc.CropSet, idx: np.ndarray,
                     labels: np.ndarray, pred: np.ndarray, conf: np.ndarray,
                     classes: Sequence[str], title: str) -> None:
    report.mkdir(parents=True, exist_ok=True)
    draw_confusion(conf, classes, report / f'{name}_confusion.png', title)
    wrong = np.flatnonzero(labels != pred)[:96]
    contact_sheet([data.crops[idx[k]] for k in wrong],
                  [f'{labels[k]}\n>{pred[k]}' for k in wrong], report / f'{name}_errors.png')


def evaluate_model(model: clf_mod.SignClassifier, data: tc.CropSet, min_side: float = 12.0
                   ) -> tuple[dict, np.ndarray]:
    """A trained model on every crop of ``data`` (labels mapped to the model's classes)."""
    labels = np.array(tc.map_labels(data.labels, model.classes))
    proba = np.vstack([model.predict_proba(data.crops[i:i + 256])
                       for i in range(0, len(data), 256)])
    pred = np.asarray(model.classes)[proba.argmax(1)]
    out = _summary(labels, pred, model.classes)
    side = np.asarray(data.side, float)
    out['by_box_side'] = _size_recall(labels, pred, side)
    out['node_sizes'] = _at_min_side(labels, pred, side, model.classes, min_side)
    out['min_score'] = score_thresholds(labels, proba, model.classes)
    return out, pred


def leave_one_clip_out(renders: tc.CropSet, real_dir: Path, classes: Sequence[str],
                       kind: str, seed: int) -> dict:
    """Per real clip: train on renders + the other clips' real crops, report on this clip."""
    real = tc.load_folder(real_dir)
    clips = sorted({c for c in real.clip if c})
    out = {}
    for clip in clips:
        train = tc.CropSet().extend(renders).extend(
            real.subset(i for i, c in enumerate(real.clip) if c != clip))
        test = real.subset(i for i, c in enumerate(real.clip) if c == clip)
        model = clf_mod.fit(train.crops, tc.map_labels(train.labels, classes), classes,
                            features=kind, method='svm', seed=seed)
        res, pred = evaluate_model(model, test)
        res.pop('_confusion')
        res['labels'] = test.counts()
        res['wrong'] = [f'{t} -> {p}' for t, p in
                        zip(tc.map_labels(test.labels, classes), pred) if t != p][:20]
        out[clip] = res
        _say(f'clip {clip}: {len(test)} crops, accuracy {res["accuracy"]:.3f}, '
             f'background false-sign {res["background"]["false_sign_rate"]}')
    return out


# --- command line --------------------------------------------------------------------------

def _parser() -> argparse.ArgumentParser:
    p = tc._Parser(prog='workzone-ros evaluate classifier', description=__doc__,
                   formatter_class=argparse.RawDescriptionHelpFormatter)
    tc.add_source_arguments(p, synth_default=20)
    p.add_argument('--model', help='evaluate this trained model on the selected crops '
                                   '(instead of Table III)')
    p.add_argument('--features', choices=ft.FEATURE_KINDS, default=tc.DEFAULT_FEATURES,
                   help='the configuration whose confusion / mirror / background figures are '
                        f'reported (default {tc.DEFAULT_FEATURES})')
    p.add_argument('--variants', nargs='*', choices=ft.FEATURE_KINDS, default=list(VARIANTS),
                   help='feature kinds compared with the seed rows (default: '
                        f'{" ".join(VARIANTS)})')
    p.add_argument('--methods', nargs='+', choices=clf_mod.METHODS, default=list(
        clf_mod.METHODS), help='classifiers of the table (default svm lda knn)')
    p.add_argument('--splits', type=int, default=5,
                   help='random splits (default 5; 0: no Table III)')
    p.add_argument('--min-side', type=float, default=12.0,
                   help="also report crops of boxes at least this large (the classifier "
                        "node's min_size, default 12 px)")
    p.add_argument('--seed', type=int, default=0, help='split seed')
    p.add_argument('--real', nargs='?', const=str(REAL_DEFAULT), default=None, metavar='DIR',
                   help='leave-one-clip-out on real crops (default folder '
                        'test/data/real_crops)')
    p.add_argument('--json', metavar='OUT', help='write the figures to this JSON file')
    p.add_argument('--report', metavar='DIR',
                   help='write confusion matrices and contact sheets of errors here')
    return p


def _run_table(args, data: tc.CropSet, classes) -> dict:
    labels = np.array(tc.map_labels(data.labels, classes))
    rows = list(dict.fromkeys([*SEED_ROWS, *args.variants, args.features]))
    bank = _Bank(data.crops)
    table, pooled = table_iii(bank, labels, data.groups, classes, rows, args.methods,
                              args.splits, args.seed, args.features)
    out = {'table_iii': table, 'splits': args.splits, 'test_share': '1/3 by group',
           'crops': len(data), 'counts': dict(zip(*np.unique(labels, return_counts=True)))}
    out['counts'] = {str(k): int(v) for k, v in out['counts'].items()}
    if pooled['idx']:
        idx, pred = np.concatenate(pooled['idx']), np.concatenate(pooled['pred'])
        summ = _summary(labels[idx], pred, classes)
        conf = summ.pop('_confusion')
        side = np.asarray(data.side, float)[idx]
        summ['by_box_side'] = _size_recall(labels[idx], pred, side)
        summ['node_sizes'] = _at_min_side(labels[idx], pred, side, classes, args.min_side)
        summ['min_score'] = score_thresholds(labels[idx], np.vstack(pooled['proba']), classes)
        summ['by_weather'] = {
            w: round(float(np.mean(labels[idx][sel] == pred[sel])), 4)
            for w in sorted(set(data.weather))
            if (sel := np.asarray(data.weather)[idx] == w).any()}
        out['pooled_' + args.features] = summ
        if args.report:
            _report_pictures(Path(args.report), 'table3_' + args.features.replace('+', '_'),
                             data, idx, labels[idx], pred, conf, classes,
                             f'SVM {args.features}, pooled test')
    return out


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        data = tc.gather(args)
        if args.model:
            model = clf_mod.load_model(args.model)
        classes = model.classes if args.model else tc.class_list(args.classes, data.labels)
    except (tc.DataError, clf_mod.ModelError) as exc:
        print(f'workzone-ros evaluate classifier: {exc}', file=sys.stderr)
        return 2
    _say(f'{len(data)} crops: ' + ', '.join(f'{k} {v}' for k, v in
                                             sorted(data.counts().items())))
    if args.model:
        res, pred = evaluate_model(model, data, args.min_side)
        conf = res.pop('_confusion')
        out = {'model': args.model, 'model_metadata': model.metadata, 'result': res}
        if args.report:
            labels = np.array(tc.map_labels(data.labels, model.classes))
            _report_pictures(Path(args.report), 'model', data, np.arange(len(data)), labels,
                             pred, conf, model.classes, Path(args.model).name)
    else:
        out = _run_table(args, data, classes)
    if args.real:
        renders = data.subset(i for i, s in enumerate(data.source) if s.startswith('synth:'))
        out['leave_one_clip_out'] = leave_one_clip_out(
            renders, Path(args.real), classes, args.features, args.seed)
    out['sources'] = tc.describe_sources(args, data)
    print_json(out, args.json)
    if args.json:
        _say(f'figures written to {args.json}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
