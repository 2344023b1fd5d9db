"""Sign shape by boosted cascades of Haar-like features (Balali and Golparvar-Fard,
"Shape-based Candidate Classification").

Balali and Golparvar-Fard, "Video-based Detection and Classification of US Traffic Signs and
Mile Markers using Color Candidate Extraction and Feature-Based Recognition", refine colour
candidates with a Viola-Jones cascade of boosted Haar-like classifiers per sign shape
(diamond, rectangle, octagon, triangle), slid over each candidate at window scales 0.75, 1.0
and 1.25 with a 6.67 % shift (their Table 1: false-alarm rate 0.2 per stage, 5 stages,
true-positive rate 0.995 per stage).  This module is that cascade:

* a window is resized to ``window`` x ``window`` pixels and turned into two channels, grey
  and HSV saturation (a coloured face on grey road or foliage stands out in saturation even
  where it does not in grey), each normalised to zero mean and unit variance (Viola and
  Jones normalise the window variance);
* the Haar-like features are scikit-image's five types (``haar_like_feature_coord``) on
  either channel; a few hundred are selected once, at training time, by a cheap selector
  (one-vs-rest extra-trees importances over a random subset of all features) and their
  coordinates are stored.  A Haar feature is linear in the pixels, so the selected
  features are evaluated as one matrix product; the matrix is rebuilt at load time from
  the coordinates with ``skimage.feature.haar_like_feature`` on unit images, so values are
  scikit-image's exactly;
* one cascade per shape, as the seed: each stage is discrete AdaBoost of decision stumps
  (on quantile-binned features, so a round costs two histograms per feature) grown until,
  with its threshold lowered until the stage keeps ``true_positive_rate`` of its
  positives, it passes at most ``false_alarm_rate`` of its negatives; the negatives of
  the next stage are those that pass the stages so far;
* a candidate's answer is the shape whose cascade accepts a window with the largest
  final-stage margin, provided at least ``min_windows`` of the candidate's windows accept
  it (Viola-Jones detectors group overlapping detections the same way), or ``none``.

Square catalogue faces (``do_not_enter``) count as rectangles: the seed has four shapes and a
square is a rectangle of aspect 1 (:data:`CATALOGUE_SHAPE`).

A model is a compressed ``.npz`` of arrays plus JSON metadata (schema, version, training
data, SHA-256 over all of it), read with ``allow_pickle=False``.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable, Mapping, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.model_files import check_header, one_line, read_npz, write_npz

__all__ = [
    'SCHEMA', 'VERSION', 'DEFAULT_MODEL', 'SHAPES', 'NONE', 'CATALOGUE_SHAPE', 'DEFAULT_SCALES',
    'DEFAULT_SHIFT', 'ShapeModelError', 'HaarFeatures', 'ShapeCascade', 'shape_of',
    'train_cascade',
]

SCHEMA = 'workzone_ros/ShapeCascade'
VERSION = 1
#: Relative to ``config/`` (``workzone_ros.resources.config_path``).
DEFAULT_MODEL = 'models/shape_cascade.npz'
SHAPES: tuple[str, ...] = ('diamond', 'rectangle', 'octagon', 'triangle')
NONE = 'none'
#: Catalogue shape (``workzone_ros.core.signs``) -> cascade shape.
CATALOGUE_SHAPE: dict[str, str] = {'diamond': 'diamond', 'rectangle': 'rectangle',
                                   'square': 'rectangle', 'octagon': 'octagon',
                                   'triangle': 'triangle', 'none': NONE}
#: Window scales (Balali and Golparvar-Fard, "Sliding Window Comparison").
DEFAULT_SCALES: tuple[float, ...] = (0.75, 1.0, 1.25)
DEFAULT_SHIFT = 1.0 / 15.0                                # 6.67 % of the window per step
DEFAULT_MIN_WINDOWS = 3       # windows that must accept a shape (OpenCV's minNeighbors default)
FEATURE_TYPES: tuple[str, ...] = ('type-2-x', 'type-2-y', 'type-3-x', 'type-3-y', 'type-4')
CHANNELS: tuple[str, ...] = ('gray', 'saturation')
_MIN_STD = 0.04           # floor of a channel's standard deviation (flat windows stay flat)


class ShapeModelError(ValueError):
    """A shape-cascade file that is unreadable, truncated, tampered or of another version."""


def shape_of(class_key: str) -> str:
    """Cascade shape of a catalogue class (``none`` for ``background``)."""
    from workzone_ros.core import signs
    return CATALOGUE_SHAPE[signs.get(class_key).shape]


# --- windows -------------------------------------------------------------------------------

def _channels(bgr: np.ndarray) -> np.ndarray:
    """(H, W, 2) float32 grey and saturation in [0, 1]."""
    if bgr.ndim == 2:
        bgr = cv2.cvtColor(bgr, cv2.COLOR_GRAY2BGR)
    bgr = np.ascontiguousarray(bgr[..., :3], dtype=np.uint8)
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    sat = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)[..., 1]
    return np.dstack([gray, sat]).astype(np.float32) / 255.0


def _normalise(win: np.ndarray) -> np.ndarray:
    """(N, C, W, W) windows to zero mean and unit variance per window and channel."""
    mean = win.mean(axis=(2, 3), keepdims=True)
    std = np.maximum(win.std(axis=(2, 3), keepdims=True), _MIN_STD)
    return ((win - mean) / std).astype(np.float32)


def _resize(patch: np.ndarray, size: int) -> np.ndarray:
    interp = cv2.INTER_AREA if min(patch.shape[:2]) >= size else cv2.INTER_LINEAR
    return cv2.resize(patch, (size, size), interpolation=interp)


def prepare(crops: Sequence[np.ndarray], window: int) -> np.ndarray:
    """Whole crops (BGR) as normalised (N, C, window, window) windows."""
    out = np.empty((len(crops), len(CHANNELS), window, window), np.float32)
    for i, crop in enumerate(crops):
        out[i] = _resize(_channels(crop), window).transpose(2, 0, 1)
    return _normalise(out)


def window_boxes(box: Sequence[float], scales: Sequence[float] = DEFAULT_SCALES,
                 shift: float = DEFAULT_SHIFT) -> list[tuple[int, float, float, float]]:
    """Square sliding windows of a candidate box: ``(scale index, x0, y0, side)``.

    The window side is ``scale`` times the box's longer side (aspect 1:1, as the seed).  A
    window smaller than the box slides inside it, a larger one slides over the positions
    where it still contains the box, in steps of ``shift`` times the window side; at scale
    1 the window is the box.
    """
    x, y, w, h = (float(v) for v in box)
    side0 = max(w, h)
    cx, cy = x + w / 2, y + h / 2
    out = []
    for k, s in enumerate(scales):
        side = s * side0
        span = abs(1.0 - s) * side0
        n = int(np.floor(span / max(shift * side, 1e-9) + 1e-6)) + 1
        offs = np.linspace(-span / 2, span / 2, n) if n > 1 else np.zeros(1)
        for oy in offs:
            for ox in offs:
                out.append((k, cx + ox - side / 2, cy + oy - side / 2, side))
    return out


def extract_windows(bgr: np.ndarray, wins: Sequence[tuple[int, float, float, float]],
                    window: int) -> np.ndarray:
    """Normalised (N, C, window, window) windows; parts outside the image repeat its edge."""
    x0 = int(np.floor(min(w[1] for w in wins)))
    y0 = int(np.floor(min(w[2] for w in wins)))
    x1 = int(np.ceil(max(w[1] + w[3] for w in wins)))
    y1 = int(np.ceil(max(w[2] + w[3] for w in wins)))
    H, W = bgr.shape[:2]
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if cx1 <= cx0 or cy1 <= cy0:
        raise ValueError(f'box outside the image ({W}x{H})')
    roi = _channels(bgr[cy0:cy1, cx0:cx1])
    roi = cv2.copyMakeBorder(roi, cy0 - y0, y1 - cy1, cx0 - x0, x1 - cx1, cv2.BORDER_REPLICATE)
    out = np.empty((len(wins), len(CHANNELS), window, window), np.float32)
    for i, (_, wx, wy, side) in enumerate(wins):
        c0, r0 = int(round(wx - x0)), int(round(wy - y0))
        n = max(2, int(round(side)))
        out[i] = _resize(roi[r0:r0 + n, c0:c0 + n], window).transpose(2, 0, 1)
    return _normalise(out)


# --- features ------------------------------------------------------------------------------

def all_features(window: int) -> tuple[np.ndarray, np.ndarray]:
    """Every Haar-like feature of a window: types (F,) int8 and rectangles (F, 4, 4) int16
    rows ``r0, c0, r1, c1`` (inclusive corners, scikit-image's order; -1 pads)."""
    types, rects = [], []
    for t, name in enumerate(FEATURE_TYPES):
        from skimage.feature import haar_like_feature_coord
        coords, _ = haar_like_feature_coord(window, window, name)
        r = np.full((len(coords), 4, 4), -1, np.int16)
        for i, feat in enumerate(coords):
            for j, ((a, b), (c, d)) in enumerate(feat):
                r[i, j] = (a, b, c, d)
        types.append(np.full(len(coords), t, np.int8))
        rects.append(r)
    return np.concatenate(types), np.concatenate(rects)


class HaarFeatures:
    """A fixed list of Haar-like features on the window channels, evaluated as a matrix product.

    Args:
        window: window side in pixels.
        types: (F,) index into :data:`FEATURE_TYPES`.
        rects: (F, 4, 4) rectangles as :func:`all_features` gives them.
        channels: (F,) index into :data:`CHANNELS`.
    """

    def __init__(self, window: int, types: np.ndarray, rects: np.ndarray,
                 channels: np.ndarray):
        from skimage.feature import haar_like_feature
        from skimage.transform import integral_image
        self.window = int(window)
        self.types = np.asarray(types, np.int8)
        self.rects = np.asarray(rects, np.int16)
        self.channels = np.asarray(channels, np.int8)
        n = len(self.types)
        if not (self.rects.shape == (n, 4, 4) and self.channels.shape == (n,)):
            raise ValueError('feature arrays of different lengths')
        if n and (self.types.min() < 0 or self.types.max() >= len(FEATURE_TYPES)
                  or self.channels.min() < 0 or self.channels.max() >= len(CHANNELS)
                  or self.rects.max() >= self.window):
            raise ValueError('feature type, channel or rectangle out of range')
        coord = np.empty(n, dtype=object)
        for i in range(n):
            coord[i] = [[(int(a), int(b)), (int(c), int(d))]
                        for a, b, c, d in self.rects[i] if a >= 0]
        names = np.array(FEATURE_TYPES, dtype=object)[self.types]
        # A Haar feature is linear in the pixels: its weights are its values on unit images.
        ww = self.window * self.window
        weights = np.zeros((ww, n), np.float32)
        for p in range(ww):
            unit = np.zeros(ww)
            unit[p] = 1.0
            if n:
                weights[p] = haar_like_feature(
                    integral_image(unit.reshape(self.window, self.window)), 0, 0,
                    self.window, self.window, feature_type=names, feature_coord=coord)
        self.matrix = np.zeros((len(CHANNELS) * ww, n), np.float32)
        for c in range(len(CHANNELS)):
            cols = self.channels == c
            self.matrix[c * ww:(c + 1) * ww, cols] = weights[:, cols]

    def __len__(self) -> int:
        return len(self.types)

    def values(self, windows: np.ndarray) -> np.ndarray:
        """(N, F) feature values of normalised (N, C, W, W) windows."""
        return windows.reshape(len(windows), -1) @ self.matrix

    def subset(self, idx: np.ndarray) -> 'HaarFeatures':
        """The features at ``idx``."""
        return HaarFeatures(self.window, self.types[idx], self.rects[idx], self.channels[idx])


# --- the cascade ---------------------------------------------------------------------------

@dataclass(frozen=True)
class _Stages:
    """Every stump of every stage of every shape's cascade, flat."""

    shape: np.ndarray        # (K,) int8 index into SHAPES
    stage: np.ndarray        # (K,) int8
    feature: np.ndarray      # (K,) int32 column of HaarFeatures
    threshold: np.ndarray    # (K,) float64: x <= threshold -> left
    left: np.ndarray         # (K,) float64 vote (alpha * +-1)
    right: np.ndarray        # (K,) float64
    stage_shape: np.ndarray  # (G,) int8
    stage_index: np.ndarray  # (G,) int8
    stage_threshold: np.ndarray  # (G,) float64: pass when the sum of votes >= it
    stage_norm: np.ndarray   # (G,) float32: sum of |alpha| (margins are divided by it)


class ShapeCascade:
    """One boosted Haar cascade per shape; answers a candidate's shape or ``none``."""

    def __init__(self, features: HaarFeatures, stages: _Stages, metadata: Mapping):
        self.features = features
        self.stages = stages
        self.metadata = dict(metadata)
        self.window = features.window
        self.shapes = SHAPES
        #: Windows that must accept a shape (:meth:`scan_scales`); stored with the model.
        self.min_windows = int(self.metadata.get('min_windows', DEFAULT_MIN_WINDOWS))

    # -- evaluation
    def window_scores(self, windows: np.ndarray) -> np.ndarray:
        """Per window and shape a score: > 0 (the final stage's normalised margin) when the
        cascade accepts the window, else ``stages passed / stages - 1`` (in [-1, 0))."""
        st = self.stages
        x = self.features.values(windows)
        votes = np.where(x[:, st.feature] <= st.threshold, st.left, st.right)
        out = np.full((len(windows), len(SHAPES)), -1.0, np.float32)
        for s in range(len(SHAPES)):
            g = np.flatnonzero(st.stage_shape == s)
            if not len(g):
                continue
            g = g[np.argsort(st.stage_index[g])]
            alive = np.ones(len(windows), bool)
            passed = np.zeros(len(windows), np.int32)
            margin = np.zeros(len(windows), np.float32)
            for gi in g:
                cols = (st.shape == s) & (st.stage == st.stage_index[gi])
                total = votes[:, cols].sum(axis=1)
                margin = (total - st.stage_threshold[gi]) / st.stage_norm[gi]
                alive &= margin >= 0
                passed += alive
            out[:, s] = np.where(alive, np.maximum(margin, 1e-6), passed / len(g) - 1.0)
        return out

    def scan_scales(self, bgr: np.ndarray, box: Sequence[float],
                    scales: Sequence[float] = DEFAULT_SCALES, shift: float = DEFAULT_SHIFT,
                    min_windows: int = 1) -> np.ndarray:
        """(len(scales), len(SHAPES)) best window score per scale and shape.

        A shape accepted by fewer than ``min_windows`` of the candidate's windows (all
        scales together) counts as rejected (score 0): true faces are accepted by many
        overlapping windows, stray accepts by few (OpenCV's ``minNeighbors``).
        """
        wins = window_boxes(box, scales, shift)
        scores = self.window_scores(extract_windows(bgr, wins, self.window))
        weak = (scores > 0).sum(axis=0) < min_windows
        scores[:, weak] = np.minimum(scores[:, weak], 0.0)
        k = np.array([w[0] for w in wins])
        return np.stack([scores[k == i].max(axis=0) for i in range(len(scales))])

    def scan(self, bgr: np.ndarray, box: Sequence[float],
             scales: Sequence[float] = DEFAULT_SCALES,
             min_windows: Optional[int] = None) -> tuple[str, float, float]:
        """Shape of the candidate ``box`` (x, y, w, h) in ``bgr``: ``(shape, score, scale)``.

        The shape whose cascade accepts a window with the largest margin, at the scale of
        that window, provided at least ``min_windows`` windows accept it (default: the
        model's ``min_windows``); ``('none', score, scale)`` with the deepest rejection when
        no cascade does.
        """
        if min_windows is None:
            min_windows = self.min_windows
        per = self.scan_scales(bgr, box, scales, min_windows=min_windows)
        i, s = np.unravel_index(int(np.argmax(per)), per.shape)
        score = float(per[i, s])
        return (SHAPES[s] if score > 0 else NONE), score, float(scales[i])

    def classify(self, crop_bgr: np.ndarray) -> tuple[str, float]:
        """Shape of a candidate crop (the crop is the candidate box): ``(shape, score)``."""
        h, w = crop_bgr.shape[:2]
        shape, score, _ = self.scan(crop_bgr, (0, 0, w, h))
        return shape, score

    # -- files
    def _arrays(self) -> dict[str, np.ndarray]:
        f, st = self.features, self.stages
        out = {'f_types': f.types, 'f_rects': f.rects, 'f_channels': f.channels,
               'window': np.array(self.window, np.int64)}
        out.update({f's_{k}': getattr(st, k) for k in st.__dataclass_fields__})
        return out

    def save(self, path: str | os.PathLike) -> None:
        """Write the cascade as a compressed ``.npz`` (arrays + JSON metadata, no pickles)."""
        md = {**self.metadata, 'schema': SCHEMA, 'version': VERSION, 'shapes': list(SHAPES),
              'channels': list(CHANNELS), 'feature_types': list(FEATURE_TYPES)}
        write_npz(path, self._arrays(), md)

    @classmethod
    def load(cls, path: str | os.PathLike | None = None) -> 'ShapeCascade':
        """Read a cascade written by :meth:`save` (default: the shipped model).

        Raises:
            FileNotFoundError: no file at ``path``.
            ShapeModelError: truncated or corrupt, not a shape cascade, another version, or
                arrays / metadata changed after training.
        """
        if path is None:
            from workzone_ros.resources import config_path
            path = config_path(DEFAULT_MODEL)
        path = os.fspath(path)
        if not os.path.isfile(path):
            raise FileNotFoundError(f'shape cascade {path!r} does not exist; train one with '
                                    "'workzone-ros train shapes'")
        arrays, md = read_npz(path, 'shape cascade', ShapeModelError)
        check_header(path, arrays, md, what='shape cascade', schema=SCHEMA, version=VERSION,
                     retrain='workzone-ros train shapes', error=ShapeModelError)
        try:
            feats = HaarFeatures(int(arrays['window']), arrays['f_types'], arrays['f_rects'],
                                 arrays['f_channels'])
            stages = _Stages(**{k: arrays[f's_{k}'] for k in _Stages.__dataclass_fields__})
        except (KeyError, ValueError, TypeError, IndexError) as exc:
            raise ShapeModelError(f'shape cascade {path!r} is malformed: '
                                  f'{one_line(exc)}') from None
        return cls(feats, stages, md)


# --- training ------------------------------------------------------------------------------

def _select_features(windows: np.ndarray, labels: np.ndarray, n_candidates: int,
                     n_features: int, rng: np.random.Generator,
                     progress: Callable[[str], None]) -> HaarFeatures:
    """Random ``n_candidates`` of all features on all channels, then the ``n_features`` the
    one-vs-rest extra-trees of every shape rank highest (an equal share per shape)."""
    from sklearn.ensemble import ExtraTreesClassifier
    types, rects = all_features(windows.shape[-1])
    pick = rng.choice(len(types) * len(CHANNELS), n_candidates, replace=False)
    cand = HaarFeatures(windows.shape[-1], types[pick % len(types)],
                        rects[pick % len(types)], pick // len(types))
    sample = rng.choice(len(windows), min(len(windows), 4000), replace=False)
    x = cand.values(windows[sample])
    y = labels[sample]
    ranks = []
    for shape in SHAPES:
        et = ExtraTreesClassifier(n_estimators=60, max_depth=10, min_samples_leaf=3,
                                  class_weight='balanced', n_jobs=1,
                                  random_state=int(rng.integers(2 ** 31)))
        et.fit(x, y == shape)
        ranks.append(np.argsort(-et.feature_importances_))
    chosen: list[int] = []
    depth = 0
    while len(chosen) < min(n_features, len(cand)):
        for r in ranks:
            if r[depth] not in chosen and len(chosen) < n_features:
                chosen.append(int(r[depth]))
        depth += 1
    progress(f'features: {len(chosen)} of {n_candidates} candidates selected')
    return cand.subset(np.array(sorted(chosen)))


def _boost_stumps(x: np.ndarray, y: np.ndarray, rounds: int, n_bins: int = 64):
    """Discrete AdaBoost of decision stumps (Viola and Jones), classes weighted equally.

    Each feature is cut into ``n_bins`` quantile bins once, so a round is two weighted
    histograms per feature instead of a sort.  Returns ``(feature, threshold, left, right,
    alpha)`` per stump: the stump votes ``left`` when the feature is <= threshold.
    """
    n, n_feat = x.shape
    edges = np.quantile(x, np.linspace(0, 1, n_bins + 1)[1:-1], axis=0).T    # (F, B-1)
    bins = np.empty((n_feat, n), np.int16)
    for f in range(n_feat):
        bins[f] = np.searchsorted(edges[f], x[:, f], side='left')
    w = np.where(y, 0.5 / max(y.sum(), 1), 0.5 / max((~y).sum(), 1))
    ys = np.where(y, 1.0, -1.0)
    stumps = []
    for _ in range(rounds):
        hp = np.empty((n_feat, n_bins))
        hn = np.empty((n_feat, n_bins))
        wp, wn = w * y, w * ~y
        for f in range(n_feat):
            hp[f] = np.bincount(bins[f], wp, n_bins)
            hn[f] = np.bincount(bins[f], wn, n_bins)
        cp, cn = np.cumsum(hp, axis=1)[:, :-1], np.cumsum(hn, axis=1)[:, :-1]
        tp, tn = wp.sum(), wn.sum()
        err_hi = cp + (tn - cn)          # positive when x > threshold
        err_lo = (tp - cp) + cn          # positive when x <= threshold
        err = np.minimum(err_hi, err_lo) / (tp + tn)
        f, b = np.unravel_index(int(np.argmin(err)), err.shape)
        e = float(np.clip(err[f, b], 1e-10, None))
        if e >= 0.5:
            break
        alpha = 0.5 * np.log((1.0 - e) / e)
        low_is_pos = err_lo[f, b] < err_hi[f, b]
        h = np.where(bins[f] <= b, 1.0, -1.0) * (1.0 if low_is_pos else -1.0)
        stumps.append((int(f), float(edges[f, b]), alpha * (1.0 if low_is_pos else -1.0),
                       alpha * (-1.0 if low_is_pos else 1.0), float(alpha)))
        w = w * np.exp(-alpha * ys * h)
        w /= w.sum()
    return stumps


def _fit_stage(x: np.ndarray, pos: np.ndarray, neg: np.ndarray, far: float, tpr: float,
               max_stumps: int):
    """One stage: boosted stumps on ``x[pos]`` vs ``x[neg]``, cut to the fewest stumps whose
    threshold, lowered until the stage keeps ``tpr`` of the positives, passes at most
    ``far`` of the negatives (Viola and Jones; Balali and Golparvar-Fard Table 1)."""
    idx = np.concatenate([pos, neg])
    xs = x[idx]
    stumps = _boost_stumps(xs, np.r_[np.ones(len(pos), bool), np.zeros(len(neg), bool)],
                           max_stumps)
    if not stumps:
        raise ValueError('a stage found no informative feature')
    f = np.array([s[0] for s in stumps])
    votes = np.where(xs[:, f] <= np.array([s[1] for s in stumps]),
                     np.array([s[2] for s in stumps]), np.array([s[3] for s in stumps]))
    cum = np.cumsum(votes, axis=1)
    k = int(np.floor((1.0 - tpr) * len(pos)))
    best = None
    for n in range(1, len(stumps) + 1):
        thr = float(np.sort(cum[:len(pos), n - 1])[k]) - 1e-6
        fa = float(np.mean(cum[len(pos):, n - 1] >= thr))
        best = (n, thr, fa)
        if fa <= far:
            break
    n, thr, fa = best
    return stumps[:n], thr, fa


def train_cascade(crops: Sequence[np.ndarray], labels: Sequence[str], *, window: int = 20,
                  n_candidates: int = 6000, n_features: int = 600, stages: int = 5,
                  false_alarm_rate: float = 0.2, true_positive_rate: float = 0.995,
                  max_stumps: int = 200, max_negatives: int = 12000, seed: int = 0,
                  metadata: Optional[Mapping] = None,
                  progress: Optional[Callable[[str], None]] = None) -> ShapeCascade:
    """Train one cascade per shape from square crops (each crop is one training window).

    Args:
        crops: BGR crops; a crop of a shape shows the whole face with little margin.
        labels: per crop a shape of :data:`SHAPES` or ``none`` (background).
        window: window side in pixels.
        n_candidates: random Haar features (over both channels) the selector ranks.
        n_features: features kept (their coordinates are stored).
        stages: stages per cascade (Balali and Golparvar-Fard: 5).
        false_alarm_rate: most negatives a stage may pass (Balali and Golparvar-Fard: 0.2).
        true_positive_rate: least positives a stage keeps (Balali and Golparvar-Fard: 0.995).
        max_stumps: most stumps per stage.
        max_negatives: negatives per stage at most (a random subset of those still passing).
        seed: random seed.
        metadata: stored with the model (training data, ...).
        progress: callback for one line per stage.

    Returns:
        The trained :class:`ShapeCascade`; its metadata records each stage's stumps, rates
        and counts.

    Raises:
        ValueError: unknown labels or a shape without crops.
    """
    say = progress or (lambda line: None)
    labels = np.asarray(labels, dtype=str)
    unknown = sorted(set(labels) - set(SHAPES) - {NONE})
    if unknown or len(labels) != len(crops):
        raise ValueError(f'labels must be one per crop, from {SHAPES + (NONE,)}; '
                         f'got {unknown or len(labels)}')
    missing = [s for s in SHAPES if not np.any(labels == s)]
    if missing:
        raise ValueError(f'no crops of shape(s) {", ".join(missing)}')
    rng = np.random.default_rng(seed)
    windows = prepare(crops, window)
    feats = _select_features(windows, labels, n_candidates, n_features, rng, say)
    x = feats.values(windows)
    cols = {k: [] for k in ('shape', 'stage', 'feature', 'threshold', 'left', 'right')}
    gcols = {k: [] for k in ('stage_shape', 'stage_index', 'stage_threshold', 'stage_norm')}
    report = []
    for si, shape in enumerate(SHAPES):
        pos = np.flatnonzero(labels == shape)
        neg_alive = np.flatnonzero(labels != shape)
        for k in range(stages):
            if len(neg_alive) < 2:
                say(f'{shape}: stage {k + 1} skipped, no negatives left')
                break
            neg = neg_alive if len(neg_alive) <= max_negatives else \
                np.sort(rng.choice(neg_alive, max_negatives, replace=False))
            stumps, thr, fa = _fit_stage(x, pos, neg, false_alarm_rate, true_positive_rate,
                                         max_stumps)
            f = np.array([s[0] for s in stumps])
            t = np.array([s[1] for s in stumps])
            lv, rv = np.array([s[2] for s in stumps]), np.array([s[3] for s in stumps])

            def passes(ix, f=f, t=t, lv=lv, rv=rv, thr=thr):
                return np.where(x[ix][:, f] <= t, lv, rv).sum(axis=1) >= thr
            tp = float(np.mean(passes(pos)))
            n_neg = len(neg_alive)
            pos = pos[passes(pos)]
            neg_alive = neg_alive[passes(neg_alive)]
            for key, val in zip(cols, (si, k, f, t, lv, rv)):
                cols[key].append(np.broadcast_to(val, f.shape))
            for key, val in zip(gcols, (si, k, thr, float(sum(s[4] for s in stumps)))):
                gcols[key].append(val)
            report.append({'shape': shape, 'stage': k + 1, 'stumps': len(stumps),
                           'tpr': round(tp, 4), 'far': round(fa, 4), 'negatives': n_neg,
                           'positives_left': int(len(pos))})
            say(f'{shape}: stage {k + 1}/{stages}: {len(stumps)} stumps, TPR {tp:.3f}, '
                f'false alarms {fa:.3f} of {len(neg)} negatives; {len(pos)} positives and '
                f'{len(neg_alive)} of {int(np.sum(labels != shape))} negatives pass')
    dtypes = {'shape': np.int8, 'stage': np.int8, 'feature': np.int32,
              'threshold': np.float64, 'left': np.float64, 'right': np.float64,
              'stage_shape': np.int8, 'stage_index': np.int8, 'stage_threshold': np.float64,
              'stage_norm': np.float32}
    arrays = {k: np.concatenate(v).astype(dtypes[k]) for k, v in cols.items()}
    arrays.update({k: np.array(v, dtypes[k]) for k, v in gcols.items()})
    # keep only the features the stumps use, renumbered
    used, inv = np.unique(arrays['feature'], return_inverse=True)
    arrays['feature'] = inv.astype(np.int32)
    md = {**(metadata or {}), 'window': window, 'stages': stages,
          'false_alarm_rate': false_alarm_rate, 'true_positive_rate': true_positive_rate,
          'max_stumps': max_stumps, 'n_candidates': n_candidates,
          'n_features_selected': len(feats), 'n_features_used': int(len(used)), 'seed': seed,
          'counts': {s: int(np.sum(labels == s)) for s in SHAPES + (NONE,)},
          'stage_report': report}
    return ShapeCascade(feats.subset(used), _Stages(**arrays), md)
