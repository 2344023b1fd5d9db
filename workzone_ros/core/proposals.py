"""Sign candidates for recall: every orange blob that could be a sign, ranked and bounded.

The colour detector (:mod:`workzone_ros.core.detect`) is built for precision: its shape
and refinement rules make rendered signs exact, and on an unfamiliar camera they throw real
signs away (a shaded face just under the table's threshold, a sign merged with the orange
drums below it, a sign cut by the frame edge).  This module turns the stage around: colour
only *proposes*, with a low threshold, and the classifier's reject class decides what is a
sign by how it looks.

One frame costs a fixed amount of work:

1. the frame is shrunk by ``scale`` (area interpolation) and the colour model's
   ``P(orange sign | pixel)`` is looked up (with the model's own white balance and saturation
   normalisation);
2. four masks are cut from it: ``P >= threshold`` (recall) closed with a 3x3 kernel; the
   same closed with a ``join`` kernel, so that a face broken into pieces by a large legend
   (arrows, two lines of text) is one candidate again; ``P >= strong`` (the sign's saturated
   face alone); and the recall mask with the image's edges removed (Canny of the brightness
   and of the saturation), so that a sign's border separates it from a same-coloured
   barrier or drum behind it, or from autumn foliage as bright as the sign but duller.  Each
   is split into connected components;
3. a component is a candidate when its box is at least ``min_size`` px, not more elongated
   than ``max_aspect``, fills at least ``min_fill`` of its box and covers at most
   ``max_area`` of the frame; components touching the frame edge are kept (a sign cut by
   the edge is still a candidate);
4. candidates are scored, de-duplicated by non-maximum suppression and cut to the
   ``max_candidates`` best, so the classifier's cost per frame is bounded whatever the scene.

The score is a logistic regression over cheap measurements of the candidate
(:data:`FEATURES`: likelihood, fill, size, aspect, colour, texture, edges, the dark legend
share, position), learned from the same images and masks as the colour table
(:func:`fit_ranker`, ``workzone-ros train proposals``) and stored in the colour model file
(extra ``proposal_ranker``).  A model without one scores by mean likelihood times fill.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Optional

import cv2
import numpy as np

from workzone_ros.core.kernels import components_with_stats
from workzone_ros.core.proposal_kernels import component_sums

__all__ = ['ProposalConfig', 'Proposal', 'SignProposer', 'FEATURES', 'Ranker', 'fit_ranker',
           'candidate_labels', 'proposals_as_detections', 'MODES', 'stage_plan',
           'detect_frame']

#: The values of the colour detector's ``proposals`` and ``rules`` parameters.
MODES = ('auto', 'on', 'off')


def stage_plan(proposals: str, rules: str, own_camera: bool) -> tuple[bool, bool]:
    """Whether a frame goes through the rule-based detector and the proposals: ``(rules,
    proposals)``.

    ``proposals`` ``auto`` runs them on frames of any camera other than the colour model's
    own (``own_camera`` false), where the rules, built and measured on that camera, miss real
    signs; ``rules`` ``auto`` runs the rules only where the proposals do not run or on the
    model's own camera.  ``on`` and ``off`` are always and never.
    """
    for name, mode in (('proposals', proposals), ('rules', rules)):
        if mode not in MODES:
            raise ValueError(f'{name} must be one of {", ".join(MODES)}, got {mode!r}')
    props = proposals == 'on' or (proposals == 'auto' and not own_camera)
    use_rules = rules == 'on' or (rules == 'auto' and (own_camera or not props))
    return use_rules, props


@dataclass(frozen=True)
class ProposalConfig:
    """Parameters of :class:`SignProposer` (module docstring)."""

    #: P(orange sign | pixel) of a candidate pixel (low: recall).
    threshold: float = 0.5
    #: The second, tighter level: the saturated face alone.
    strong: float = 0.9
    #: The frame is shrunk by this factor before the colour lookup.
    scale: int = 2
    #: Shortest longer side of a candidate box, full-resolution pixels.
    min_size: int = 14
    #: Longest box side over shortest side.
    max_aspect: float = 3.0
    #: Least share of its box a component must fill.
    min_fill: float = 0.25
    #: Largest share of the frame one candidate may cover.
    max_area: float = 0.12
    #: IoU above which the weaker of two candidates is dropped.
    nms_iou: float = 0.5
    #: At most this many candidates per frame, the best scores first.
    max_candidates: int = 12
    #: Cut the recall mask along Canny edges as a further level.
    edge_split: bool = True
    #: The edges that cut it include the saturation's, not only the brightness's: a sign's
    #: saturated face against dull orange foliage or brick of the same brightness.
    saturation_edges: bool = True
    #: Closing kernel (shrunk-frame pixels) of the level that joins a face broken by its
    #: legend; 3 or less turns that level off.
    join: int = 7

    def __post_init__(self) -> None:
        checks = {
            'threshold': 0.0 < self.threshold <= 1.0,
            'strong': self.threshold <= self.strong <= 1.0,
            'scale': 1 <= self.scale <= 8,
            'min_size': self.min_size >= 2,
            'max_aspect': self.max_aspect >= 1.0,
            'min_fill': 0.0 <= self.min_fill <= 1.0,
            'max_area': 0.0 < self.max_area <= 1.0,
            'nms_iou': 0.0 < self.nms_iou <= 1.0,
            'max_candidates': self.max_candidates >= 1,
            'join': 0 <= self.join <= 31,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            k = bad[0]
            raise ValueError(f'proposal parameter {k}={getattr(self, k)!r} is out of range')

    @classmethod
    def from_mapping(cls, values: dict[str, Any]) -> 'ProposalConfig':
        """A config from a mapping of field values; unknown keys are a one-line error."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f'unknown proposal parameter(s): {", ".join(unknown)}')
        return cls(**values)


@dataclass(frozen=True)
class Proposal:
    """One candidate: its box (x, y, w, h, full-resolution pixels) and score in [0, 1]."""

    box: tuple[float, float, float, float]
    score: float


_K3 = np.ones((3, 3), np.uint8)
#: Canny's hysteresis thresholds on the saturation (0-255) where it cuts the edge level: a
#: sign's face is tens of levels more saturated than the foliage or brick around it.
_SATURATION_CANNY = (40, 100)

#: The candidate measurements the ranker weighs (all on the shrunk frame).
FEATURES = ('mean_p', 'fill', 'log_size', 'log_aspect', 'edge_touch', 'centre_row',
            'saturation', 'value', 'value_spread', 'edge_density', 'dark_share')


@dataclass(frozen=True)
class Ranker:
    """A logistic regression over standardised :data:`FEATURES`."""

    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: float

    @classmethod
    def from_array(cls, a: np.ndarray) -> 'Ranker':
        """Unpack the model file's ``proposal_ranker`` extra (3 F + 1 numbers)."""
        a = np.asarray(a, np.float64).ravel()
        f = len(FEATURES)
        if a.size != 3 * f + 1 or not np.all(np.isfinite(a)):
            raise ValueError(f'proposal_ranker has {a.size} values, expected {3 * f + 1}')
        return cls(a[:f], a[f:2 * f], a[2 * f:3 * f], float(a[-1]))

    def to_array(self) -> np.ndarray:
        """The model file's ``proposal_ranker`` extra."""
        return np.concatenate([self.mean, self.scale, self.coef, [self.intercept]])

    def score(self, x: np.ndarray) -> np.ndarray:
        """P(sign) of each row of features."""
        z = ((x - self.mean) / self.scale) @ self.coef + self.intercept
        return 1.0 / (1.0 + np.exp(-np.clip(z, -30, 30)))


class SignProposer:
    """Orange sign candidates of a frame (module docstring)."""

    def __init__(self, model, config: ProposalConfig = ProposalConfig(),
                 color: str = 'orange') -> None:
        self.model = model
        self.config = config
        self.color = color
        model.index(color)            # a model without the colour is a one-line error now
        extra = getattr(model, 'extras', {}).get('proposal_ranker')
        self.ranker = Ranker.from_array(extra) if extra is not None else None

    def _small(self, bgr: np.ndarray) -> np.ndarray:
        s = self.config.scale
        return bgr if s == 1 else cv2.resize(
            bgr, (max(bgr.shape[1] // s, 1), max(bgr.shape[0] // s, 1)),
            interpolation=cv2.INTER_AREA)

    def masks(self, prob: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
        """The candidate masks of one frame (module docstring, step 2); ``edges``: where the
        edge level cuts."""
        c = self.config
        low = cv2.morphologyEx((prob >= c.threshold).astype(np.uint8), cv2.MORPH_CLOSE, _K3)
        out = [low]
        if c.join > 3:                # a face broken by its legend's strokes, made whole
            k = np.ones((c.join, c.join), np.uint8)
            out.append(cv2.morphologyEx(low, cv2.MORPH_CLOSE, k))
        if c.strong > c.threshold:
            out.append(cv2.morphologyEx((prob >= c.strong).astype(np.uint8),
                                        cv2.MORPH_CLOSE, _K3))
        if c.edge_split:
            out.append(low & (edges == 0).astype(np.uint8))
        return out

    def view_of(self, detector) -> Optional[tuple[np.ndarray, np.ndarray]]:
        """The rule-based detector's last frame view (``ColorDetector.frame_view``: the
        shrunk frame and its white-balanced HSV) when it is what :meth:`candidates` would
        compute (the same scale and white balance), else None."""
        view = getattr(detector, 'frame_view', None)
        if view is None or detector.config.scale != self.config.scale \
                or detector.model.white_balance != self.model.white_balance:
            return None
        return view

    def candidates(self, bgr: np.ndarray, view: Optional[tuple] = None
                   ) -> tuple[list, np.ndarray]:
        """Every candidate box (full resolution) and its :data:`FEATURES` row, unranked.

        ``view``: the frame already shrunk and white-balanced (:meth:`view_of`), reused when
        its size is this frame's shrunk size."""
        if bgr is None or bgr.ndim != 3 or bgr.shape[0] < 2 or bgr.shape[1] < 2:
            raise ValueError('proposals need a BGR image of at least 2x2 pixels')
        s = self.config.scale
        size = (max(bgr.shape[0] // s, 1), max(bgr.shape[1] // s, 1))
        if view is not None and view[0].shape[:2] == size:
            small = view[0]
            hsv = self.model.normalise_saturation(view[1].copy(), self.color)
        else:
            small = self._small(bgr)
            hsv = self.model.normalised_hsv(small, self.color)
        prob = self.model.lookup(hsv, self.color)                # the model's likelihood
        edges = cv2.Canny(cv2.cvtColor(small, cv2.COLOR_BGR2GRAY), 60, 150)
        maps = _Maps(prob, hsv, edges)
        cut = edges
        if self.config.edge_split and self.config.saturation_edges:
            cut = edges | cv2.Canny(np.ascontiguousarray(hsv[..., 1]), *_SATURATION_CANNY)
        boxes, rows = [], []
        for mask in self.masks(prob, cut):
            b, f = self._components(mask, maps)
            boxes += b
            rows.append(f)
        feats = np.concatenate(rows) if rows else np.zeros((0, len(FEATURES)))
        return boxes, feats

    def propose(self, bgr: np.ndarray, view: Optional[tuple] = None) -> list[Proposal]:
        """The ranked, bounded candidates of one BGR frame (``view``: :meth:`candidates`)."""
        boxes, feats = self.candidates(bgr, view)
        if not boxes:
            return []
        if self.ranker is not None:
            scores = self.ranker.score(feats)
        else:
            scores = feats[:, FEATURES.index('mean_p')] * feats[:, FEATURES.index('fill')]
        return self._best(boxes, [float(v) for v in scores])

    def _components(self, mask: np.ndarray, maps: '_Maps') -> tuple[list, np.ndarray]:
        c, s = self.config, self.config.scale
        n, labels, stats = components_with_stats(mask, 4)
        st = stats[1:]
        x, y, w, h, area = (st[:, k] for k in range(5))
        longer, shorter = np.maximum(w, h), np.maximum(np.minimum(w, h), 1)
        fill = area / np.maximum(w * h, 1)
        frame = mask.shape[0] * mask.shape[1]
        keep = ((longer * s >= c.min_size) & (longer / shorter <= c.max_aspect)
                & (fill >= c.min_fill) & (w * h <= c.max_area * frame))
        idx = np.flatnonzero(keep)
        if idx.size == 0:
            return [], np.zeros((0, len(FEATURES)))
        feats = maps.features(labels, mask, n, st, idx)
        boxes = [(float(x[i] * s), float(y[i] * s), float(w[i] * s), float(h[i] * s))
                 for i in idx]
        return boxes, feats

    def _best(self, boxes: list, scores: list) -> list[Proposal]:
        c = self.config
        keep = cv2.dnn.NMSBoxes([list(b) for b in boxes], scores, 0.0, c.nms_iou)
        keep = sorted(np.asarray(keep, int).ravel(), key=lambda i: -scores[i])
        return [Proposal(boxes[i], float(scores[i])) for i in keep[:c.max_candidates]]


class _Maps:
    """Per-frame maps and integral images the candidate features are read from."""

    def __init__(self, prob: np.ndarray, hsv: np.ndarray, edges: np.ndarray) -> None:
        self.prob = prob
        self.sat = hsv[..., 1]
        self.val = hsv[..., 2]
        self.shape = prob.shape
        self.edge_ii = cv2.integral((edges > 0).astype(np.uint8))
        self.dark_ii = cv2.integral((hsv[..., 2] < 80).astype(np.uint8))

    def _box_share(self, ii: np.ndarray, x, y, w, h) -> np.ndarray:
        tot = ii[y + h, x + w] - ii[y, x + w] - ii[y + h, x] + ii[y, x]
        return tot / np.maximum(w * h, 1)

    def features(self, labels: np.ndarray, mask: np.ndarray, n: int, st: np.ndarray,
                 idx: np.ndarray) -> np.ndarray:
        """The :data:`FEATURES` rows of components ``idx`` (0-based, background excluded)."""
        keep = np.zeros(n, np.bool_)
        keep[idx + 1] = True                       # only the candidates' pixels are summed
        sums = component_sums(labels, mask, keep, self.prob, self.sat, self.val)[idx + 1]
        area = np.maximum(st[idx, 4], 1).astype(np.float64)
        m_p, m_s, m_v, m_v2 = (sums[:, k] / area for k in range(4))
        spread = np.sqrt(np.maximum(m_v2 - m_v * m_v, 0.0)) / np.maximum(m_v, 1.0)
        x, y, w, h = (st[idx, k] for k in range(4))
        hh, ww = self.shape
        touch = ((x == 0) | (y == 0) | (x + w >= ww) | (y + h >= hh)).astype(np.float64)
        longer = np.maximum(w, h).astype(np.float64)
        aspect = longer / np.maximum(np.minimum(w, h), 1)
        return np.column_stack([
            m_p, st[idx, 4] / np.maximum(w * h, 1), np.log2(longer), np.log(aspect),
            touch, (y + h / 2) / hh, m_s / 255.0, m_v / 255.0, spread,
            self._box_share(self.edge_ii, x, y, w, h), self._box_share(self.dark_ii, x, y, w, h),
        ])


def proposals_as_detections(proposals: list[Proposal], detections: list,
                            overlap: float = 0.3) -> list:
    """The proposals no rule-checked detection already covers, as ``Detection`` payloads.

    A proposal whose IoU with one of ``detections`` reaches ``overlap`` is the same sign and
    is left out; the rest are flagged ``proposal`` and carry their rank score.
    """
    from workzone_ros.interfaces import Box, Detection
    have = [(d.box.x, d.box.y, d.box.w, d.box.h) for d in detections]
    out = []
    for p in proposals:
        if any(_iou(p.box, h) >= overlap for h in have):
            continue
        out.append(Detection(box=Box(*p.box), confidence=min(max(p.score, 0.0), 1.0),
                             proposal=True))
    return out


def detect_frame(detector, proposer: Optional['SignProposer'], bgr: np.ndarray,
                 proposals: str = 'auto', rules: str = 'on', rois=(), lean: bool = False,
                 lean_beside: bool = True) -> tuple[list, bool, bool]:
    """One frame through the colour stage as the ``color_detector`` node runs it: the
    rule-based ``detector`` (a ``ColorDetector``) and the ``proposer`` where
    :func:`stage_plan` says (no ``proposer``: no proposals), the rules measured lean
    beside the proposals when ``lean_beside`` (or always when ``lean``), and the proposals
    reusing the detector's shrunk frame.  Returns the detections and whether the rules and
    the proposals ran."""
    own = detector.same_camera(bgr.shape[1], bgr.shape[0])
    use_rules, props = stage_plan(proposals if proposer is not None else 'off', rules, own)
    dets = detector.detect(bgr, rois, lean or (props and lean_beside)) if use_rules else []
    if props:
        view = proposer.view_of(detector) if use_rules else None
        dets = dets + proposals_as_detections(proposer.propose(bgr, view), dets)
    return dets, use_rules, props


def candidate_labels(boxes: list, truth: list, iou: float = 0.3) -> np.ndarray:
    """1 for each candidate box whose IoU with a true sign box is at least ``iou``."""
    out = np.zeros(len(boxes), np.int64)
    for i, b in enumerate(boxes):
        out[i] = any(_iou(b, t) >= iou for t in truth)
    return out


def _iou(a, b) -> float:
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[0] + a[2], b[0] + b[2]), min(a[1] + a[3], b[1] + b[3])
    inter = max(0.0, x1 - x0) * max(0.0, y1 - y0)
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def fit_ranker(features: np.ndarray, labels: np.ndarray, c: float = 1.0) -> Ranker:
    """A class-balanced logistic regression over candidate features (training only)."""
    from sklearn.linear_model import LogisticRegression
    if len(set(labels.tolist())) < 2:
        raise ValueError('the ranker needs both sign and non-sign candidates to learn from')
    mean = features.mean(axis=0)
    scale = np.maximum(features.std(axis=0), 1e-6)
    lr = LogisticRegression(C=c, class_weight='balanced', max_iter=2000)
    lr.fit((features - mean) / scale, labels)
    return Ranker(mean, scale, lr.coef_.ravel().astype(np.float64), float(lr.intercept_[0]))
