"""The general (non-work-zone) sign recogniser: red and yellow signs after Cahail et al., white
and green panels by colour and shape.

Pipeline per frame (docs/general_signs.md):

1. working image: shrunk to ``work_width``, grey-world white balanced, HSV
   (:mod:`.colour`);
2. red and yellow colour blob filters, erosion then dilation, blob filters on aspect and
   fill (Cahail et al., section 3.4.2), each blob's colour verified by its median hue
   (orange work-zone sheeting lies between red and yellow and is dropped);
3. red blobs: the crop with the non-sign painted white is matched against the STOP, YIELD
   and DO NOT ENTER templates at several sizes (3.4.3, :mod:`.templates`); a blob no
   template fits is dropped;
4. yellow blobs of diamond shape with a dark legend are generic warning signs; a red sign
   that overlaps one and is not much smaller than it replaces it (the paper's rule), a small
   red one inside it is its symbol and is dropped;
5. white speed limit panels and green guide signs / mile markers (:mod:`.panels`), the
   mile number read where legible.

That is ``verify='templates'``, the baseline.  With ``verify='cnn'`` (the default) steps 2-5
only propose boxes, generously (:mod:`.candidates`: several saturation floors, pieces
joined, red boxes grown, at most ``max_candidates`` per frame), and the CNN sign classifier
(:mod:`workzone_ros.core.cnn_classifier`, one batch per frame) decides sign or background:
a candidate is a sign when the probability of the general classes its colour can be
reaches ``cnn_threshold``; its class is the CNN's, except that a red candidate on which
the CNN hesitates between STOP, YIELD and DO NOT ENTER takes the red template's class.

No ROS import (DESIGN.md, principle 1).
"""
from __future__ import annotations

import os
from typing import Any, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.general import candidates, colour, panels, templates
from workzone_ros.core.general.config import (
    RED_TEMPLATES,
    GeneralConfig,
    GeneralSign,
    GeneralSignError,
)

__all__ = ['GeneralSignDetector', 'check_image', 'DEFAULT_CLASSIFIER', 'COLOUR_CLASSES']

Box = tuple[int, int, int, int]
#: The CNN model loaded when none is given (relative to ``config/``).
DEFAULT_CLASSIFIER = 'models/sign_classifier_cnn.npz'
#: The general classes a candidate of each colour may be (the CNN's other classes --
#: work-zone signs, background -- count against it).  Fluorescent yellow-green warning
#: sheeting can come out of the green mask.
COLOUR_CLASSES = {'red': RED_TEMPLATES, 'yellow': ('warning_diamond',),
                  'white': ('speed_limit',),
                  'green': ('guide', 'mile_marker', 'warning_diamond')}
_SHAPES = {'stop': 'octagon', 'yield': 'triangle', 'do_not_enter': 'square',
           'warning_diamond': 'diamond', 'speed_limit': 'rectangle', 'guide': 'rectangle',
           'mile_marker': 'rectangle'}


def check_image(bgr) -> np.ndarray:
    """``bgr`` if it is a non-empty uint8 (H, W, 3) array.

    Raises:
        GeneralSignError: (a ValueError) anything else, with what was given.
    """
    if not isinstance(bgr, np.ndarray):
        raise GeneralSignError(f'image must be a numpy array, got {type(bgr).__name__}')
    if bgr.dtype != np.uint8 or bgr.ndim != 3 or bgr.shape[2] != 3 or bgr.size == 0:
        raise GeneralSignError(f'image must be a non-empty uint8 BGR array (H, W, 3), got '
                               f'{bgr.dtype} {bgr.shape}')
    return bgr


def _check_rois(rois, shape) -> list[Box]:
    out = []
    for r in rois:
        if len(r) != 4 or any(not np.isfinite(v) for v in r) or r[2] <= 0 or r[3] <= 0:
            raise GeneralSignError(f'roi must be (x, y, w, h) with w, h > 0, got {tuple(r)}')
        out.append(tuple(float(v) for v in r))
    return out


def _dedupe(signs: list[GeneralSign]) -> list[GeneralSign]:
    """One sign per place: of detections with IoU > 0.5 the highest score stays."""
    out: list[GeneralSign] = []
    for g in sorted(signs, key=lambda g: -g.score):
        if not any(colour.iou(g.box, o.box) > 0.5 for o in out):
            out.append(g)
    return out


def _prefer_whole(signs: list[GeneralSign]) -> list[GeneralSign]:
    """Drop a yellow, white or green sign that lies (80 % of its area) inside a larger one
    of the same class the CNN is at least as sure of: the larger is the whole face, the
    smaller a piece of it (half a diamond cut by its arrow).  A larger box the CNN is less
    sure of is the face with some background (a diamond with the flags above it): the
    smaller stays and the detection NMS keeps the likelier.  Red signs are left to the
    probabilities (a grown red box holds the white rim)."""
    out = []
    for a in signs:
        area = a.box[2] * a.box[3]
        if a.colour != 'red' and any(
                b is not a and b.class_key == a.class_key and b.box[2] * b.box[3] > area
                and _overlap(a.box, b.box) >= 0.8 and b.score >= a.score
                for b in signs):
            continue
        out.append(a)
    return out


def _plaque_above(hsv: np.ndarray, box: Box, cfg: GeneralConfig) -> bool:
    """:func:`panels._plaque_above` on either half of the box's width: a WORK ZONE plaque
    spans the panel, the edge of an orange-brown wall behind it does not; and the band's
    saturated pixels must be orange, not red (median hue above ``red_median_max``, the
    red / orange split of the colour checks): a red brick wall behind a panel is no
    plaque."""
    x, y, w, h = box
    band = hsv[max(0, y - int(0.4 * h)):y, x:x + w]
    sat = band[..., 1] >= cfg.min_saturation
    if sat.any():
        hue = band[..., 0][sat].astype(np.int16)
        if float(np.median(np.where(hue >= 90, hue - 180, hue))) <= cfg.red_median_max:
            return False
    half = max(1, w // 2)
    return all(panels._plaque_above(hsv, (x0, y, half, h), cfg) for x0 in (x, x + w - half))


def _colour_of(key: str) -> str:
    return {'warning_diamond': 'yellow', 'speed_limit': 'white', 'guide': 'green',
            'mile_marker': 'green'}.get(key, 'red')


def _overlap(a: Box, b: Box) -> float:
    """Intersection over the smaller box's area."""
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    return ix * iy / float(max(1, min(a[2] * a[3], b[2] * b[3])))


class GeneralSignDetector:
    """Recognise stop, yield, do not enter, yellow warning, speed limit, guide signs and mile
    markers in BGR frames.

    Args:
        config: thresholds (:class:`GeneralConfig`); ``config.verify`` chooses the CNN
            verification (default) or the paper's template pipeline.
        classifier: for ``verify='cnn'``: a loaded sign classifier (anything with
            ``classes`` and ``classify_boxes(frame, boxes)`` returning predictions with
            ``probabilities``, e.g. the classifier node's model, so it is not loaded
            twice), or a model path; None loads ``config/models/sign_classifier_cnn.npz``
            on the first frame.  The model's classes must include the general ones.

    Raises:
        GeneralSignError: ``config`` is not a GeneralConfig, or ``classifier`` lacks
            ``classify_boxes`` or a general class.
    """

    def __init__(self, config: GeneralConfig = GeneralConfig(), classifier: Any = None
                 ) -> None:
        if not isinstance(config, GeneralConfig):
            raise GeneralSignError(f'config must be a GeneralConfig, got '
                                   f'{type(config).__name__}')
        self.config = config
        templates.template_bank(config.template_px, tuple(config.scales))   # draw them now
        self._classifier = None
        self._classifier_path: Optional[str] = None
        if isinstance(classifier, (str, os.PathLike)):
            self._classifier_path = os.fspath(classifier)
        elif classifier is not None:
            self._classifier = self._checked(classifier)

    @classmethod
    def sharing(cls, model: Any, config: GeneralConfig = GeneralConfig()
                ) -> 'GeneralSignDetector':
        """A detector that verifies with ``model`` when it is the CNN (its thresholds were
        set for the CNN), else with the default CNN file, loaded at the first frame."""
        from workzone_ros.core.cnn_classifier import CnnSignClassifier
        return cls(config, classifier=model if isinstance(model, CnnSignClassifier) else None)

    @staticmethod
    def _checked(model: Any) -> Any:
        if not callable(getattr(model, 'classify_boxes', None)):
            raise GeneralSignError(f'classifier must have classify_boxes(frame, boxes), got '
                                   f'{type(model).__name__}')
        missing = [k for v in COLOUR_CLASSES.values() for k in v
                   if k not in tuple(getattr(model, 'classes', ()))]
        if missing:
            raise GeneralSignError(f'classifier lacks the general classes {sorted(set(missing))}'
                                   ' (train it with the general signs: class_set all)')
        return model

    @property
    def classifier(self) -> Any:
        """The CNN (or other) sign classifier of ``verify='cnn'``, loaded on first use."""
        if self._classifier is None:
            from workzone_ros.core.classifier import load_model
            from workzone_ros.resources import config_path
            path = self._classifier_path or str(config_path(DEFAULT_CLASSIFIER))
            self._classifier = self._checked(load_model(path))
        return self._classifier

    # ---------------------------------------------------------------- public
    def detect(self, bgr: np.ndarray, rois: Optional[Sequence[Box]] = None
               ) -> list[GeneralSign]:
        """The general signs in one frame.

        Args:
            bgr: uint8 (H, W, 3) BGR image, any size.
            rois: optional (x, y, w, h) image regions (e.g. LiDAR candidates); when given,
                only blobs whose centre lies in one of them are considered.

        Returns:
            Signs, left to right.

        Raises:
            GeneralSignError: (a ValueError) a bad image or roi.
        """
        img = check_image(bgr)
        roi_list = None if rois is None else _check_rois(rois, img.shape)
        cfg = self.config
        work = colour.working_image(img, cfg)
        if cfg.verify == 'cnn':
            return self._detect_cnn(img, work, roi_list)
        s = work.scale
        red = _dedupe([g for b in self._blobs(colour.red_mask, work, roi_list, 'red')
                       if (g := self._red_sign(img, work, b)) is not None])
        yellow = _dedupe([g for b in self._blobs(colour.yellow_mask, work, roi_list, 'yellow')
                          if (g := self._yellow_sign(work, b)) is not None])
        out = self._override(red, yellow)
        # green first: a mile marker's white digits are not white panels
        for p in panels.green_panels(work, cfg) + panels.white_panels(work, cfg):
            box = self._full(p.box, s)
            if not self._in_rois(box, roi_list) or any(_overlap(box, g.box) > 0.5 for g in out):
                continue
            mile, conf = (panels.read_mile(img, box, cfg) if p.class_key == 'mile_marker'
                          else (None, None))
            out.append(GeneralSign(box, p.class_key, p.score,
                                   'white' if p.class_key == 'speed_limit' else 'green',
                                   'rectangle', mile=mile, mile_confidence=conf))
        return sorted(out, key=lambda g: (g.box[0], g.box[1]))

    # ---------------------------------------------------------------- CNN verification
    def _detect_cnn(self, img: np.ndarray, work: colour.Working, rois: Optional[list]
                    ) -> list[GeneralSign]:
        """Candidates (:mod:`.candidates`), one CNN batch, accepted by the probability of
        the general classes of their colour (or, red ones, by the paper's template test
        when the CNN's background probability is low); overlapping acceptances: the
        likelier; a small red sign on a warning sign is its symbol (the paper's rule)."""
        cfg = self.config
        cands, boxes = self._candidates(work, rois)
        if not cands:
            return []
        preds = self.classifier.classify_boxes(img, boxes)
        found = []
        for c, box, p in zip(cands, boxes, preds):
            if p is None:
                continue
            allowed = COLOUR_CLASSES[c.colour]
            prob = {k: float(p.probabilities.get(k, 0.0)) for k in allowed}
            total = sum(prob.values())
            background = float(p.probabilities.get('background', 0.0))
            if total < cfg.cnn_threshold and (
                    c.colour != 'red' or background > cfg.cnn_red_background):
                continue
            key = max(allowed, key=prob.__getitem__)
            tscore = tncc = 0.0
            tkey = ''
            if c.colour == 'red' and (total < cfg.cnn_threshold
                                      or prob[key] < cfg.cnn_red_margin * total):
                # the CNN is unsure (sign, or which red sign): the paper's templates
                m = self._red_template(img, work, c.box)
                tkey, tscore, tncc = m.key, round(m.score, 3), round(m.ncc, 3)
                template_ok = tncc >= cfg.min_template_ncc and tscore >= cfg.min_template_score
                if total < cfg.cnn_threshold:
                    if not template_ok:
                        continue               # neither the CNN nor the template
                    key, total = tkey, max(total, 1.0 - background)
                elif template_ok:
                    key = tkey                 # the CNN hesitates, the template does not
            found.append(GeneralSign(box, key, round(min(1.0, total), 3), _colour_of(key),
                                     _SHAPES[key], tkey, tscore, template_ncc=tncc))
        found = candidates.nms(_prefer_whole(found), cfg.detection_nms)
        found = self._override([g for g in found if g.colour == 'red'],
                               [g for g in found if g.colour != 'red'])
        out = []
        for g in found:
            if g.class_key == 'mile_marker':
                mile, conf = panels.read_mile(img, g.box, cfg)
                g = GeneralSign(g.box, g.class_key, g.score, g.colour, g.shape,
                                mile=mile, mile_confidence=conf)
            out.append(g)
        return sorted(out, key=lambda g: (g.box[0], g.box[1]))

    def candidate_boxes(self, bgr: np.ndarray) -> list[tuple[Box, str]]:
        """The boxes (full-image px) and colours the CNN mode hands its classifier in one
        frame: what a hard-negative miner collects where no sign is in view.

        Raises:
            GeneralSignError: (a ValueError) a bad image.
        """
        img = check_image(bgr)
        cands, boxes = self._candidates(colour.working_image(img, self.config), None)
        return [(b, c.colour) for c, b in zip(cands, boxes)]

    def _candidates(self, work: colour.Working, rois: Optional[list]
                    ) -> tuple[list[candidates.Candidate], list[Box]]:
        """The CNN mode's candidates that pass the colour checks, and their full boxes."""
        cands = candidates.propose(work, self.config, rois,
                                   keep=lambda c: self._colour_ok(work, c))
        return cands, [self._full(c.box, work.scale) for c in cands]

    def _colour_ok(self, work: colour.Working, c: candidates.Candidate) -> bool:
        """The colour checks of the template pipeline, on the candidate's box: red and
        yellow by the median hue of its saturated pixels (work-zone orange lies between),
        a white panel without an orange WORK ZONE plaque on top (a work-zone limit); and
        some contrast in the box (a face has a legend or a border: the CNN standardises
        every crop, so a uniform reddish asphalt patch's noise can look like a STOP)."""
        cfg = self.config
        x, y, w, h = c.box
        if float(work.hsv[y:y + h, x:x + w, 2].std()) < cfg.min_contrast:
            return False                       # a uniform patch: no legend, no border
        if c.colour == 'white':
            return not _plaque_above(work.hsv, c.box, cfg)
        if c.colour not in ('red', 'yellow'):
            return True
        hsv = work.hsv[y:y + h, x:x + w]
        make = colour.red_mask if c.colour == 'red' else colour.yellow_mask
        sel = make(hsv, cfg, cfg.min_saturation) > 0
        if not sel.any():
            return False
        hue = hsv[..., 0][sel].astype(np.int16)
        med = float(np.median(np.where(hue >= 90, hue - 180, hue)))
        if c.colour == 'red' and not -cfg.red_median_max - 1.0 <= med <= cfg.red_median_max:
            return False
        if c.colour == 'yellow' and med < cfg.yellow_median_min:
            return False
        # a face ends at its bottom edge (a post, background below); the same sheeting
        # going on below is a drum, a truck, lettering on a van
        band = work.hsv[y + h:y + h + max(2, int(round(0.35 * h))), x:x + w]
        if band.size:
            floor = int(max(cfg.min_saturation, 0.7 * float(np.median(hsv[..., 1][sel]))))
            below = np.count_nonzero(make(band, cfg, floor)) / float(band.shape[0] * band.shape[1])
            if below > cfg.max_colour_below:
                return False
        return True

    def _red_template(self, img: np.ndarray, work: colour.Working, box: Box
                      ) -> templates.Match:
        """The red templates matched on a candidate box (working px): its red pixels,
        outlines filled, are the region kept."""
        cfg = self.config
        x, y, w, h = box
        red = colour.red_mask(work.hsv[y:y + h, x:x + w], cfg, cfg.min_saturation)
        contours, _ = cv2.findContours(red, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        region = np.zeros((h, w), np.uint8)
        cv2.drawContours(region, contours, -1, 1, -1)
        if not region.any():
            region[:] = 1
        crop = templates.prepare_crop(img, tuple(v * work.scale for v in box), region,
                                      work.gains, cfg)
        return templates.match_templates(crop, cfg)

    # ---------------------------------------------------------------- stages
    @staticmethod
    def _full(box: Box, s: float) -> Box:
        x, y, w, h = box
        return (int(round(x * s)), int(round(y * s)), int(round(w * s)), int(round(h * s)))

    @staticmethod
    def _in_rois(box: Box, rois: Optional[list]) -> bool:
        if rois is None:
            return True
        cx, cy = box[0] + box[2] / 2, box[1] + box[3] / 2
        return any(r[0] <= cx <= r[0] + r[2] and r[1] <= cy <= r[1] + r[3] for r in rois)

    def _blobs(self, make_mask, work: colour.Working, rois, which: str
               ) -> list[colour.Blob]:
        """Blobs of the colour mask ``make_mask`` (loose and strict saturation) that pass
        the paper's filters (aspect near 1, box area below blob area times a constant) and
        whose median hue is ``which``.  Stacked pieces (a STOP cut in two by its legend at a
        distance) are joined first."""
        cfg = self.config
        out: list[colour.Blob] = []
        found = []
        for sat in (cfg.min_saturation, cfg.strict_saturation):
            mask = colour.clean(make_mask(work.hsv, cfg, sat), cfg)
            pieces = colour.blobs(mask, 2.0)
            found += [b for b in colour.merge_stacked(pieces)
                      if not any(colour.iou(b.box, o.box) > 0.8 for o in found)]
        for b in found:
            _, _, w, h = b.box
            if min(w, h) < cfg.min_side_px / work.scale:
                continue
            if max(w / h, h / w) > cfg.max_aspect or w * h >= b.area * cfg.fill_constant:
                continue
            if not self._in_rois(self._full(b.box, work.scale), rois):
                continue
            hue = colour.median_hue(work.hsv, b, cfg.min_saturation, cfg.min_value)
            if which == 'red' and not -30.0 <= hue <= cfg.red_median_max:
                continue
            if which == 'yellow' and not cfg.yellow_median_min <= hue <= cfg.yellow_hue[1]:
                continue
            out.append(b)
        return out

    def _red_sign(self, img: np.ndarray, work: colour.Working, b: colour.Blob
                  ) -> Optional[GeneralSign]:
        cfg = self.config
        s = work.scale
        box = tuple(v * s for v in b.box)
        crop = templates.prepare_crop(img, box, b.mask, work.gains, cfg)
        m = templates.match_templates(crop, cfg)
        if m.score < cfg.min_template_score or m.ncc < cfg.min_template_ncc:
            return None
        return GeneralSign(self._full(b.box, s), m.key, round(float(np.clip(m.ncc, 0, 1)), 3),
                           'red', templates.SHAPES[m.key], m.key, round(m.score, 3),
                           template_ncc=round(m.ncc, 3))

    def _yellow_sign(self, work: colour.Working, b: colour.Blob) -> Optional[GeneralSign]:
        """A yellow blob is a warning sign when it is a diamond: its box's corners empty,
        the diamond inscribed in the box (less a rim) yellow, dark legend or a saturated
        symbol, the dark legend's share of it in range."""
        cfg = self.config
        x, y, w, h = b.box
        yy, xx = np.mgrid[0:h, 0:w]
        u = np.abs((xx + 0.5) / w - 0.5) + np.abs((yy + 0.5) / h - 0.5)
        corners, core = u > 0.5, u <= 0.42
        corner_fill = np.count_nonzero(b.mask[corners]) / max(1, np.count_nonzero(corners))
        if corner_fill > cfg.max_corner_fill:
            return None
        patch = work.hsv[y:y + h, x:x + w]
        yellow = b.mask > 0
        bright = core & yellow & (patch[..., 1] >= cfg.min_saturation)
        if not bright.any():
            return None
        dark = patch[..., 2] < 0.5 * float(np.median(patch[..., 2][bright]))
        n_core = max(1, np.count_nonzero(core))
        symbol = patch[..., 1] >= cfg.strict_saturation       # a coloured symbol (W3-1)
        diamond_fill = np.count_nonzero(core & (yellow | dark | symbol)) / n_core
        share = np.count_nonzero(core & dark) / n_core
        if diamond_fill < cfg.min_diamond_fill or \
                not cfg.legend_dark[0] <= share <= cfg.legend_dark[1]:
            return None
        score = round(float((1.0 - corner_fill) * diamond_fill), 3)
        return GeneralSign(self._full(b.box, work.scale), 'warning_diamond', score,
                           'yellow', 'diamond')

    def _override(self, red: list[GeneralSign], yellow: list[GeneralSign]
                  ) -> list[GeneralSign]:
        """The paper's rule: a warning sign unless a red template fits well enough; a red
        sign much smaller than the yellow one it lies on is that sign's symbol."""
        cfg = self.config
        keep_red, keep_yellow = [], list(yellow)
        for r in red:
            hits = [y for y in keep_yellow if _overlap(r.box, y.box) > 0.5]
            area = r.box[2] * r.box[3]
            if any(area < cfg.override_area * y.box[2] * y.box[3] for y in hits):
                continue                       # a symbol on a warning sign
            keep_yellow = [y for y in keep_yellow if y not in hits]
            keep_red.append(r)
        return keep_red + keep_yellow
