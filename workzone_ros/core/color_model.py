"""Per-pixel sign colour models: boosted hue/saturation stumps baked into a lookup table.

Seo et al., section III.A (and Lee et al., III.A): the likelihood that a pixel belongs to an
orange work-zone sign is learned with AdaBoost over decision stumps on the pixel's hue and
saturation,

    f(x) = sum_i alpha_i h_i(x),   h_i(x) in {-1, +1}                  (Seo et al., eq. 2)
    g(f) = e^f / (e^f + e^-f)                                          (Seo et al., eq. 2; [8])

and the posterior multiplies it by a prior over image locations learned from the ground-truth
boxes (the heat map of Seo et al., Fig. 1):  P(sign | x) = eta P(x | sign) P(sign)  (eq. 1).

scikit-learn's discrete SAMME AdaBoost fits those stumps (:func:`fit_boosted`; each stump
votes +-1).

Because the model only sees (hue, saturation) and OpenCV's 8-bit HSV has 180 x 256 distinct
values, the whole boosted model is evaluated once per bin and stored as a table: a frame
then costs one lookup per pixel instead of H stump evaluations (``workzone-ros bench color``
measures the ratio).

The red and yellow models of the general signs (stop, yield, do-not-enter; yellow warning
diamonds) are the Cahail et al. (section 3.4.2) HSV ranges baked into the same kind of table.

A model file is a compressed ``.npz`` read with ``allow_pickle=False`` (loading it never
executes code).  It carries a schema name and version, the tables, the class list, the prior
and its ROI, and the training metadata as JSON.  A missing, truncated or other-version file
raises one :class:`ModelError` whose message says what is wrong.
"""
from __future__ import annotations

import json
import math
import os
import zipfile
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.kernels import low_chroma_rounds

__all__ = [
    'ModelError', 'SCHEMA', 'VERSION', 'H_BINS', 'S_BINS', 'HSV_RANGES', 'ColorModel',
    'SpatialPrior', 'logistic_link', 'stump_margin', 'boosted_probability', 'fit_boosted',
    'boosted_lut', 'hsv_range_lut', 'histogram_from_pixels', 'fit_prior', 'save_model',
    'load_model', 'default_model', 'gray_world_gains', 'low_chroma_gains', 'WHITE_BALANCE',
    'apply_gains', 'SatNorm', 'saturation_gain', 'saturation_table',
]

SCHEMA = 'workzone_ros/ColorModel'
VERSION = 1
H_BINS = 180       # OpenCV 8-bit hue 0..179
S_BINS = 256       # saturation 0..255

#: Cahail et al. section 3.4.2 colour-blob ranges (OpenCV HSV, inclusive): a colour is a list of
#: (h_lo, h_hi, s_lo, v_lo) intervals.  The seed names the colours, not the numbers; these are
#: the usual MUTCD sheeting hues and were set on our development renders, not the evaluation
#: scenarios.  ``orange`` is used only by the Cahail et al. baseline.
HSV_RANGES: dict[str, list[tuple[int, int, int, int]]] = {
    'red': [(0, 6, 110, 60), (168, 179, 110, 60)],
    'orange': [(7, 19, 130, 90)],
    'yellow': [(20, 34, 110, 90)],
}


class ModelError(Exception):
    """A colour model file that is missing, truncated, malformed or of another version."""


# --- the boosted model -------------------------------------------------------------------

def logistic_link(f: np.ndarray) -> np.ndarray:
    """g(f) = e^f / (e^f + e^-f) = 1 / (1 + e^(-2f)) (Seo et al., eq. 2), overflow-safe."""
    f = np.asarray(f, dtype=np.float64)
    return 0.5 * (1.0 + np.tanh(f))


def stump_margin(clf: Any, X: np.ndarray) -> np.ndarray:
    """f(x) = sum_i alpha_i h_i(x) evaluated stump by stump (the reference implementation).

    ``alpha_i`` is half of scikit-learn's SAMME estimator weight: for two classes SAMME's
    weight is log((1 - err) / err), twice the discrete-AdaBoost coefficient that the
    logistic link of Friedman et al. [8] (Seo et al.) assumes.

    Args:
        clf: a fitted binary ``AdaBoostClassifier`` over (hue, saturation).
        X: (N, 2) features.

    Returns:
        (N,) float64 margins.
    """
    X = np.asarray(X, dtype=np.float64)
    f = np.zeros(len(X))
    positive = clf.classes_[1]
    for est, w in zip(clf.estimators_, clf.estimator_weights_):
        if w == 0:
            continue
        h = np.where(est.predict(X) == positive, 1.0, -1.0)
        f += 0.5 * w * h
    return f


def boosted_probability(clf: Any, X: np.ndarray) -> np.ndarray:
    """P(x | sign) = g(f(x)) through scikit-learn's vectorised ``decision_function``.

    scikit-learn's binary decision function is ``2 sum_i w_i h_i / sum_i w_i``; multiplied
    by ``sum_i w_i / 4`` it is the margin of :func:`stump_margin`.  (scikit-learn's own
    ``predict_proba`` is the same link on the margin divided by ``sum_i w_i / 2``: the same
    ranking, squeezed into [0.27, 0.73].)
    """
    d = clf.decision_function(np.asarray(X, dtype=np.float64))
    return logistic_link(d * 0.25 * float(np.sum(clf.estimator_weights_)))


def _grid() -> np.ndarray:
    h, s = np.meshgrid(np.arange(H_BINS), np.arange(S_BINS), indexing='ij')
    return np.column_stack([h.ravel(), s.ravel()]).astype(np.float64)


def boosted_lut(clf: Any) -> np.ndarray:
    """The boosted model evaluated on every (hue, saturation) bin: (180, 256) float32."""
    return boosted_probability(clf, _grid()).reshape(H_BINS, S_BINS).astype(np.float32)


def histogram_from_pixels(hsv: np.ndarray, mask: np.ndarray,
                          v_min: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Count positive and negative pixels per (hue, saturation) bin.

    Args:
        hsv: (H, W, 3) uint8 OpenCV HSV image.
        mask: (H, W) bool/uint8, nonzero on sign pixels.
        v_min: pixels darker than this are left out (the detector gates them out too).

    Returns:
        (pos, neg): two (180, 256) float64 count tables.
    """
    keep = hsv[..., 2] >= v_min
    idx = hsv[..., 0].astype(np.int64) * S_BINS + hsv[..., 1]
    m = mask.astype(bool)
    pos = np.bincount(idx[keep & m], minlength=H_BINS * S_BINS)
    neg = np.bincount(idx[keep & ~m], minlength=H_BINS * S_BINS)
    n = H_BINS * S_BINS
    return (pos[:n].reshape(H_BINS, S_BINS).astype(np.float64),
            neg[:n].reshape(H_BINS, S_BINS).astype(np.float64))


def fit_boosted(pos: np.ndarray, neg: np.ndarray, n_estimators: int = 40,
                pos_weight: float = 1.0, random_state: int = 0) -> Any:
    """Fit AdaBoost over decision stumps (H = ``n_estimators``) on (hue, saturation).

    Training on the per-bin counts with sample weights is exactly training on every pixel
    (identical features have identical stump outputs), and it costs 46 080 rows at most.

    Args:
        pos, neg: (180, 256) pixel counts from :func:`histogram_from_pixels`.
        n_estimators: number of weak learners H.
        pos_weight: total weight of the positive class relative to the negative class
            (1.0 balances the classes, whatever their pixel counts).
        random_state: for reproducibility.

    Returns:
        The fitted ``sklearn.ensemble.AdaBoostClassifier``.

    Raises:
        ModelError: no positive or no negative pixels.
    """
    from sklearn.ensemble import AdaBoostClassifier
    from sklearn.tree import DecisionTreeClassifier

    if pos.sum() <= 0 or neg.sum() <= 0:
        raise ModelError('training needs both sign and background pixels')
    grid = _grid()
    p, n = pos.ravel(), neg.ravel()
    ip, ineg = np.nonzero(p)[0], np.nonzero(n)[0]
    X = np.concatenate([grid[ip], grid[ineg]])
    y = np.concatenate([np.ones(len(ip), int), np.zeros(len(ineg), int)])
    w = np.concatenate([p[ip] / p.sum() * pos_weight, n[ineg] / n.sum()])
    clf = AdaBoostClassifier(estimator=DecisionTreeClassifier(max_depth=1),
                             n_estimators=n_estimators, random_state=random_state)
    clf.fit(X, y, sample_weight=w / w.sum())
    return clf



def hsv_range_lut(ranges: Sequence[tuple[int, int, int, int]],
                  inside: float = 0.95) -> tuple[np.ndarray, int]:
    """A hue x saturation table from Cahail et al. HSV ranges.

    Returns:
        (lut, v_min): ``inside`` on the bins of any range, 0 elsewhere, and the smallest
        value bound of the ranges (the detector's value gate).
    """
    lut = np.zeros((H_BINS, S_BINS), np.float32)
    for h_lo, h_hi, s_lo, _ in ranges:
        lut[h_lo:h_hi + 1, s_lo:] = inside
    return lut, int(min(r[3] for r in ranges))


# --- colour constancy (outside the table) -------------------------------------------------

def gray_world_gains(bgr: np.ndarray, lo: float = 0.6, hi: float = 1.6) -> tuple:
    """Per-channel gains that make the frame's mean grey (grey-world white balance).

    Dusk light tints a whole frame orange (sky, lane paint); after the gains the tint is gone
    and only truly orange surfaces stay orange.  Clipped to [lo, hi] so a frame filled by one
    orange truck is not turned blue.  Returns (b, g, r) gains.
    """
    m = cv2.mean(bgr)[:3]
    grey = (m[0] + m[1] + m[2]) / 3.0
    return tuple(float(np.clip(grey / max(c, 1.0), lo, hi)) for c in m)


def _quantile(values: np.ndarray, q: float) -> np.floating:
    """``np.quantile(values, q)`` of a 1-d float array without NaNs, the same value
    (numpy's default ``linear`` method: the order statistics either side of ``(n - 1) q``
    by a partial sort, interpolated as numpy does, in the array's float type), without
    np.quantile's generic machinery (most of its ~40 us on the few thousand values here)."""
    n = values.size
    vi = (n - 1) * q
    i = math.floor(vi)
    j = min(i + 1, n - 1)
    part = np.partition(values, (i, j))
    a, b = part[i], part[j]
    t = vi - i
    diff = b - a
    # numpy's lerp: from the nearer end, so that t = 1 gives b exactly
    return a + diff * t if t < 0.5 else b - diff * (1 - t)


def low_chroma_gains(bgr: np.ndarray, lo: float = 0.6, hi: float = 1.6, share: float = 0.2,
                     iters: int = 2, top: float = 0.5) -> tuple:
    """Per-channel gains that make the frame's least chromatic pixels grey.

    Grey world (:func:`gray_world_gains`) assumes the frame averages to grey; a clear day's
    blue sky and green verges do not, and its gains then tint the neutral asphalt orange
    (13.9 % of the background of sunny renders passed the orange table that way).  Here only
    the ``share`` of well-exposed pixels with the lowest chroma (max - min) / max in the
    image below ``top`` (a road camera's ground: asphalt, lane paint, concrete; the sky is
    left out, since a warm cast turns a blue sky grey), on a quarter-size copy, is averaged:
    the ground as the light or the camera's white balance tints it.  A sign face is among the
    most chromatic pixels of any frame and never takes part.  The selection is redone once
    after the first gains (``iters``).  Clipped to [lo, hi].  Returns (b, g, r) gains.
    """
    bgr = bgr[int(bgr.shape[0] * top):]
    h, w = bgr.shape[:2]
    small = bgr if min(h, w) < 64 else cv2.resize(bgr, (w // 4, h // 4),
                                                   interpolation=cv2.INTER_AREA)
    # (the selection and the means: compiled, in numpy's float32 arithmetic)
    g = low_chroma_rounds(np.ascontiguousarray(small), lo, hi, share, iters)
    return (1.0, 1.0, 1.0) if g.size == 0 else tuple(float(v) for v in g)


#: White-balance estimators by model metadata name (``white_balance``).
WHITE_BALANCE = {'grey_world': gray_world_gains, 'low_chroma': low_chroma_gains}


def table_lookup(table: np.ndarray, hue: np.ndarray, sat: np.ndarray) -> np.ndarray:
    """``table[hue, sat]`` of a colour table over (hue, saturation), a new array; compiled
    (:func:`~workzone_ros.core.kernels.hue_sat_take`, a third of numpy's time) for 2-d
    uint8 channels and a float32 or uint8 table."""
    if (hue.ndim != 2 or hue.shape != sat.shape or table.ndim != 2
            or hue.dtype != np.uint8 or sat.dtype != np.uint8
            or table.dtype not in (np.float32, np.uint8)):
        return table[hue, sat]
    from workzone_ros.core.kernels import hue_sat_take  # numba, loaded on first use
    return hue_sat_take(table, hue, sat)


def apply_gains(bgr: np.ndarray, gains: tuple) -> np.ndarray:
    """``bgr`` times per-channel ``gains``, saturated to uint8."""
    return cv2.transform(bgr, np.diag(np.asarray(gains, np.float64)))


@dataclass(frozen=True)
class SatNorm:
    """Frame-level saturation normalisation (colour constancy for haze and dull light).

    Haze, overcast light, rain and a camera's own colour processing scale the saturation of
    a whole frame: a sign that is S ~ 220 on a clear day with a vivid phone camera can be
    S ~ 60 in fog.  A table over absolute saturation then has to accept S ~ 60 as "sign",
    and on a clear frame warm grey asphalt, brick and beige walls (S 40..140) pass too.  So
    the saturation is rescaled per frame before the table: the ``quantile`` of the frame's
    saturation (pixels above the value gate) is brought up to ``ref`` with a gain in
    [1, ``max_gain``].  A frame that is already colourful (a clear day) is left alone; a
    washed-out one is stretched.  Training does the same, so the table sees normalised
    saturation only.

    Attributes:
        quantile: frame saturation statistic (0.9: the 90th percentile).
        ref: target value of that statistic.
        max_gain: largest gain (a frame that is all grey is not blown up).
    """

    quantile: float = 0.9
    ref: float = 120.0
    max_gain: float = 4.0

    def to_dict(self) -> dict:
        """JSON form for the model metadata."""
        return {'quantile': self.quantile, 'ref': self.ref, 'max_gain': self.max_gain}

    @classmethod
    def from_mapping(cls, d: Optional[Mapping[str, Any]]) -> Optional['SatNorm']:
        """From model metadata (None when absent: no normalisation)."""
        if not d:
            return None
        try:
            return cls(float(d['quantile']), float(d['ref']), float(d['max_gain']))
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f'malformed sat_norm metadata {d!r}: {exc}') from None


def saturation_gain(hsv: np.ndarray, norm: SatNorm, v_min: int = 0) -> float:
    """The :class:`SatNorm` gain of one HSV frame (pixels with V >= ``v_min`` count)."""
    mask = None
    if v_min > 0:
        mask = cv2.threshold(hsv[..., 2], v_min - 1, 255, cv2.THRESH_BINARY)[1]
    hist = cv2.calcHist([hsv], [1], mask, [256], [0, 256]).ravel()
    total = float(hist.sum())
    if total <= 0:
        return 1.0
    q = int(np.searchsorted(np.cumsum(hist), norm.quantile * total))
    return float(np.clip(norm.ref / max(q, 1), 1.0, norm.max_gain))


def saturation_table(gain: float) -> np.ndarray:
    """uint8 (256,) table S -> min(255, round(gain S)) (for ``cv2.LUT``)."""
    return np.minimum(255, np.round(np.arange(256) * float(gain))).astype(np.uint8)


# --- the spatial prior -------------------------------------------------------------------

@dataclass(frozen=True)
class SpatialPrior:
    """P(sign) over image locations (Seo et al., Fig. 1) and the ROI it implies.

    Attributes:
        heat: (gh, gw) float32 in [0, 1]: smoothed box density normalised to its maximum.
        image_size: (width, height) the heat map covers.
        roi: (x, y, w, h) pixels: where the heat is at least ``roi_level``.
        floor: prior value where no training sign ever was (signs do appear there).
    """

    heat: np.ndarray
    image_size: tuple[int, int]
    roi: tuple[int, int, int, int]
    floor: float = 0.2

    def prior_image(self, width: int, height: int) -> np.ndarray:
        """The prior resampled to ``width`` x ``height``: floor + (1 - floor) * heat."""
        heat = cv2.resize(self.heat, (width, height), interpolation=cv2.INTER_LINEAR)
        return (self.floor + (1.0 - self.floor) * np.clip(heat, 0.0, 1.0)).astype(np.float32)

    def roi_for(self, width: int, height: int) -> tuple[int, int, int, int]:
        """The ROI scaled to an image of ``width`` x ``height``."""
        sx, sy = width / self.image_size[0], height / self.image_size[1]
        x, y, w, h = self.roi
        return (int(x * sx), int(y * sy), int(np.ceil(w * sx)), int(np.ceil(h * sy)))

    @classmethod
    def uniform(cls, width: int = 640, height: int = 480) -> 'SpatialPrior':
        """A flat prior over the whole image (no location knowledge)."""
        return cls(np.ones((8, 8), np.float32), (width, height), (0, 0, width, height), 1.0)

    @classmethod
    def flat(cls, value: float, width: int, height: int) -> 'SpatialPrior':
        """The same prior ``value`` at every location, the ROI the whole image."""
        return cls(np.zeros((8, 8), np.float32), (width, height), (0, 0, width, height),
                   float(np.clip(value, 1e-3, 1.0)))

    def expected(self) -> float:
        """The prior's mean over its ROI (the region where the training signs appeared).

        What the model believes, on average, about a place where signs were seen at all,
        without knowing which place it is: the location-free prior for frames of a camera
        the heat map was not learnt on (:meth:`ColorModel.same_camera`), where the heat
        map's rows and columns mean other directions.  A uniform prior gives 1.
        """
        width, height = self.image_size
        x, y, w, h = self.roi
        p = self.prior_image(width, height)[max(0, y):max(0, y + h), max(0, x):max(0, x + w)]
        return float(p.mean()) if p.size else 1.0


def fit_prior(boxes: Sequence[tuple[float, float, float, float]], image_size: tuple[int, int],
              cell: int = 8, sigma_cells: float = 2.5, roi_level: float = 0.02,
              roi_margin: int = 16, floor: float = 0.2,
              saturate: float = 1.0,
              camera_jitter: Optional[tuple[float, float, float]] = None) -> SpatialPrior:
    """Project every ground-truth box onto one image and smooth it (Seo et al., Fig. 1).

    Args:
        boxes: (x, y, w, h) ground-truth boxes in pixels.
        image_size: (width, height).
        cell: heat-map cell size in pixels.
        sigma_cells: Gaussian smoothing in cells.
        roi_level: the ROI is the bounding rectangle of cells with heat >= this level.
        roi_margin: pixels added around the ROI.
        floor: prior outside the training signs' locations.
        saturate: the heat is the smoothed box density divided by this fraction of its
            maximum and clipped to 1: with 1 only the single densest cell has P(sign) = 1;
            with e.g. 0.1 every location with a tenth of the peak density is a full-prior
            location (P(sign) multiplies the likelihood, so a peaked prior would demand
            likelihoods near 1 everywhere but at the peak).
        camera_jitter: (pitch, yaw, zoom): the heat map is averaged over other cameras'
            views of the same boxes: the image shifted up / down by up to ``pitch`` and
            sideways by up to ``yaw`` (fractions of the image height / width: another
            mounting pitch and yaw) and scaled about the image centre by 1/(1 + zoom) ..
            (1 + zoom) (another focal length), so the prior does not assume the training
            camera's exact horizon.  None: the training camera only.

    Returns:
        The :class:`SpatialPrior`; uniform if ``boxes`` is empty.
    """
    width, height = image_size
    if len(boxes) == 0:
        return SpatialPrior.uniform(width, height)
    gw, gh = -(-width // cell), -(-height // cell)
    acc = np.zeros((gh, gw), np.float64)
    for x, y, w, h in boxes:
        x0, y0 = int(max(0, x // cell)), int(max(0, y // cell))
        x1 = int(min(gw, np.ceil((x + w) / cell)))
        y1 = int(min(gh, np.ceil((y + h) / cell)))
        if x1 > x0 and y1 > y0:
            acc[y0:y1, x0:x1] += 1.0
    if camera_jitter is not None:
        acc = _jitter_views(acc, *camera_jitter)
    acc = cv2.GaussianBlur(acc, (0, 0), sigma_cells)
    heat = (np.clip(acc / (saturate * acc.max()), 0.0, 1.0).astype(np.float32)
            if acc.max() > 0 else np.ones_like(acc, np.float32))
    ys, xs = np.nonzero(heat >= roi_level)
    x0 = max(0, int(xs.min()) * cell - roi_margin)
    y0 = max(0, int(ys.min()) * cell - roi_margin)
    x1 = min(width, (int(xs.max()) + 1) * cell + roi_margin)
    y1 = min(height, (int(ys.max()) + 1) * cell + roi_margin)
    return SpatialPrior(heat, (width, height), (x0, y0, x1 - x0, y1 - y0), floor)


def _jitter_views(acc: np.ndarray, pitch: float, yaw: float, zoom: float,
                  steps: int = 3) -> np.ndarray:
    """Mean of ``acc`` seen by cameras with other pitch, yaw and focal length (cells)."""
    gh, gw = acc.shape
    cx, cy = (gw - 1) / 2.0, (gh - 1) / 2.0
    out = np.zeros_like(acc, np.float64)
    n = 0
    for s in np.geomspace(1.0 / (1.0 + zoom), 1.0 + zoom, steps) if zoom > 0 else [1.0]:
        for dy in np.linspace(-pitch, pitch, 2 * steps + 1) * gh if pitch > 0 else [0.0]:
            for dx in np.linspace(-yaw, yaw, steps) * gw if yaw > 0 else [0.0]:
                m = np.array([[s, 0.0, (1 - s) * cx + dx], [0.0, s, (1 - s) * cy + dy]])
                out += cv2.warpAffine(acc, m, (gw, gh), flags=cv2.INTER_LINEAR,
                                      borderMode=cv2.BORDER_CONSTANT)
                n += 1
    return out / max(n, 1)


# --- the model and its file --------------------------------------------------------------

@dataclass(frozen=True)
class ColorModel:
    """Per-colour likelihood tables, the value gate, and the spatial prior.

    Attributes:
        classes: colour names, one per table (``orange`` first when learned).
        luts: (C, 180, 256) float32 P(x | colour) per (hue, saturation) bin.
        v_min: per-colour minimum HSV value (darker pixels have no reliable hue).
        prior: the spatial prior of the orange work-zone signs.
        metadata: training metadata (JSON-serialisable).
        extras: further numeric arrays saved with the model (``rgb_lp_thresholds``: the
            Balali and Golparvar-Fard thresholds chosen by the trainer).
    """

    classes: tuple[str, ...]
    luts: np.ndarray
    v_min: tuple[int, ...]
    prior: SpatialPrior
    metadata: Mapping[str, Any] = field(default_factory=dict)
    extras: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.luts.shape != (len(self.classes), H_BINS, S_BINS):
            raise ModelError(f'tables of shape {self.luts.shape} do not match '
                             f'{len(self.classes)} classes x {H_BINS} x {S_BINS}')
        if len(self.v_min) != len(self.classes):
            raise ModelError('one value gate per class is required')

    def index(self, color: str) -> int:
        """Position of ``color`` in :attr:`classes`.

        Raises:
            ModelError: the model has no such colour.
        """
        try:
            return self.classes.index(color)
        except ValueError:
            raise ModelError(f'colour {color!r} not in model classes {self.classes}') from None

    def lut(self, color: str) -> np.ndarray:
        """The (180, 256) float32 table of ``color``."""
        return self.luts[self.index(color)]

    @property
    def gray_world(self) -> bool:
        """True when the tables were trained on grey-world balanced frames."""
        return bool(self.metadata.get('gray_world', False))

    @property
    def white_balance(self) -> Optional[str]:
        """The white-balance estimator the tables were trained with (None: none).

        Models before ``white_balance`` existed mean grey world by ``gray_world`` true.
        """
        if not self.gray_world:
            return None
        name = self.metadata.get('white_balance') or 'grey_world'
        if name not in WHITE_BALANCE:
            raise ModelError(f'unknown white_balance {name!r} in model metadata '
                             f'(known: {", ".join(WHITE_BALANCE)})')
        return name

    def balance_gains(self, bgr: np.ndarray) -> Optional[tuple]:
        """The frame's white-balance gains as the model was trained (None: no balancing)."""
        name = self.white_balance
        return None if name is None else WHITE_BALANCE[name](bgr)

    @property
    def sat_norm(self) -> Optional[SatNorm]:
        """The frame saturation normalisation the tables were trained with (or None)."""
        return SatNorm.from_mapping(self.metadata.get('sat_norm'))

    def normalised_hsv(self, bgr: np.ndarray, color: str = 'orange') -> np.ndarray:
        """The frame as the tables see it: grey-world balanced and saturation-normalised
        when the model was trained that way (the gain is computed on this frame)."""
        gains = self.balance_gains(bgr)
        if gains is not None:
            bgr = apply_gains(bgr, gains)
        return self.normalise_saturation(cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV), color)

    def normalise_saturation(self, hsv: np.ndarray, color: str = 'orange') -> np.ndarray:
        """The saturation normalisation of :meth:`normalised_hsv` on an already balanced
        HSV frame, in place (returns ``hsv``)."""
        norm = self.sat_norm
        if norm is not None and color == 'orange':     # the learned table only
            g = saturation_gain(hsv, norm, self.v_min[self.index(color)])
            hsv[..., 1] = cv2.LUT(hsv[..., 1], saturation_table(g))
        return hsv

    def likelihood(self, bgr: np.ndarray, color: str = 'orange') -> np.ndarray:
        """P(x | colour) for every pixel of a BGR image (value gate applied), float32.

        The frame is grey-world balanced and saturation-normalised first when the model was
        trained that way.
        """
        return self.lookup(self.normalised_hsv(bgr, color), color)

    def lookup(self, hsv: np.ndarray, color: str = 'orange') -> np.ndarray:
        """P(x | colour) of every pixel of an already normalised HSV image (value gate
        applied), float32."""
        i = self.index(color)
        p = table_lookup(self.luts[i], hsv[..., 0], hsv[..., 1])
        p[hsv[..., 2] < self.v_min[i]] = 0.0
        return p

    @property
    def camera(self) -> dict[str, float]:
        """The training camera the prior and mounting geometry were learnt on.

        Metadata ``camera`` (``width``, ``height`` and, when known, ``fx``, ``fy``, ``cx``,
        ``cy`` in pixels) written by ``train color``; older files: the prior's image size.

        Raises:
            ModelError: a malformed ``camera`` entry.
        """
        d = self.metadata.get('camera') if self.metadata else None
        if not d:
            width, height = self.prior.image_size
            return {'width': float(width), 'height': float(height)}
        try:
            out = {k: float(d[k]) for k in ('width', 'height')}
            out.update({k: float(d[k]) for k in ('fx', 'fy', 'cx', 'cy') if k in d})
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f'malformed camera metadata {d!r}: {exc}') from None
        if out['width'] <= 0 or out['height'] <= 0:
            raise ModelError(f'malformed camera metadata {d!r}: non-positive size')
        return out

    def same_camera(self, width: int, height: int,
                    intrinsics: Optional[Sequence[float]] = None,
                    tolerance: float = 0.02) -> bool:
        """Whether frames of ``width`` x ``height`` come from the model's training camera.

        With the frames' ``intrinsics`` (fx, fy, cx, cy in pixels) and a model that records
        its own, the normalised intrinsics (fx / width, fy / height, cx / width, cy / height)
        must agree within the relative ``tolerance`` (a resized stream of the same camera
        matches);
        otherwise the frame size must be the training size exactly: an unknown camera of
        another size is never assumed to look like ours.
        """
        cam = self.camera
        known = all(k in cam for k in ('fx', 'fy', 'cx', 'cy'))
        if intrinsics is not None and known:
            fx, fy, cx, cy = (float(v) for v in intrinsics)
            mine = (cam['fx'] / cam['width'], cam['fy'] / cam['height'],
                    cam['cx'] / cam['width'], cam['cy'] / cam['height'])
            theirs = (fx / width, fy / height, cx / width, cy / height)
            return all(abs(a - b) <= tolerance * abs(a) for a, b in zip(mine, theirs))
        return (int(round(cam['width'])), int(round(cam['height']))) == (int(width), int(height))

    def with_prior(self, prior: SpatialPrior) -> 'ColorModel':
        """A copy with another prior (e.g. uniform)."""
        return ColorModel(self.classes, self.luts, self.v_min, prior, dict(self.metadata),
                          dict(self.extras))


def default_model(orange_lut: Optional[np.ndarray] = None, orange_v_min: int = 60,
                  prior: Optional[SpatialPrior] = None,
                  metadata: Optional[Mapping[str, Any]] = None) -> ColorModel:
    """A model with the given (learned) orange table and the Cahail et al. red/yellow ranges.

    Without ``orange_lut`` the orange table is the Cahail et al. orange range too (a fallback
    that needs no training).
    """
    red, v_red = hsv_range_lut(HSV_RANGES['red'])
    yellow, v_yellow = hsv_range_lut(HSV_RANGES['yellow'])
    if orange_lut is None:
        orange_lut, orange_v_min = hsv_range_lut(HSV_RANGES['orange'])
    luts = np.stack([orange_lut, red, yellow]).astype(np.float32)
    return ColorModel(('orange', 'red', 'yellow'), luts, (int(orange_v_min), v_red, v_yellow),
                      prior or SpatialPrior.uniform(), dict(metadata or {}))


def save_model(model: ColorModel, path: str | os.PathLike) -> None:
    """Write ``model`` as a compressed, versioned ``.npz`` (no pickled objects)."""
    path = os.fspath(path)
    os.makedirs(os.path.dirname(path) or '.', exist_ok=True)
    tmp = path + '.tmp.npz'
    np.savez_compressed(
        tmp, schema=np.array(SCHEMA), version=np.array(VERSION, np.int64),
        classes=np.array(model.classes), luts=model.luts.astype(np.float32),
        v_min=np.array(model.v_min, np.int64), prior_heat=model.prior.heat.astype(np.float32),
        prior_image_size=np.array(model.prior.image_size, np.int64),
        prior_roi=np.array(model.prior.roi, np.int64),
        prior_floor=np.array(model.prior.floor, np.float64),
        metadata=np.array(json.dumps(dict(model.metadata), sort_keys=True)),
        **{f'extra_{k}': np.asarray(v, np.float64) for k, v in model.extras.items()})
    os.replace(tmp, path)


_KEYS = ('schema', 'version', 'classes', 'luts', 'v_min', 'prior_heat', 'prior_image_size',
         'prior_roi', 'prior_floor', 'metadata')


def load_model(path: str | os.PathLike) -> ColorModel:
    """Read a model file written by :func:`save_model`.

    Raises:
        ModelError: the file is missing, not a readable ``.npz`` (e.g. truncated), lacks a
            field, or has another schema or version.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ModelError(f'colour model file {path!r} does not exist; train one with '
                         "'workzone-ros train color' or set the model_path parameter")
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in ('schema', 'version') if k not in z.files]
            if missing:
                raise ModelError(f'{path!r} is not a workzone_ros colour model (no '
                                 f'{", ".join(missing)})')
            schema, version = str(z['schema']), int(z['version'])
            if schema != SCHEMA:
                raise ModelError(f'{path!r} has schema {schema!r}, expected {SCHEMA!r}')
            if version != VERSION:
                raise ModelError(f'{path!r} is colour model version {version}; this build reads '
                                 f'version {VERSION} (retrain with workzone-ros train color)')
            missing = [k for k in _KEYS if k not in z.files]
            if missing:
                raise ModelError(f'{path!r} lacks {", ".join(missing)}')
            data = {k: z[k] for k in _KEYS}
            extras = {k[len('extra_'):]: z[k] for k in z.files if k.startswith('extra_')}
    except ModelError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise ModelError(f'cannot read colour model {path!r} (truncated or corrupt?): '
                         f'{exc}') from None
    try:
        prior = SpatialPrior(data['prior_heat'].astype(np.float32),
                             tuple(int(v) for v in data['prior_image_size']),
                             tuple(int(v) for v in data['prior_roi']),
                             float(data['prior_floor']))
        return ColorModel(tuple(str(c) for c in data['classes']),
                          data['luts'].astype(np.float32),
                          tuple(int(v) for v in data['v_min']), prior,
                          json.loads(str(data['metadata'])), extras)
    except (ValueError, TypeError) as exc:
        raise ModelError(f'colour model {path!r} is malformed: {exc}') from None
