"""One frame's boxes -> the ``Sign`` list the ``classifier`` node publishes (no rclpy).

The rules a consumer of ``/workzone/signs`` relies on, shared by the node and by
``workzone-ros evaluate workzone --signs pipeline`` so both give the same signs:

* a box smaller than ``min_size`` px on either side, or with less than ``min_visible`` of it
  inside the image, is published as class ``unknown`` with the reason -- never a guess;
* every other box of the frame is classified in one batch
  (:meth:`~workzone_ros.core.classifier.SignClassifier.classify_boxes`); ``background``
  answers are rejected (returned separately, not published);
* a box that only the recall-first colour proposals found (``proposal`` set on the detection
  or track) is weighed by its lower prior: ``proposal_prior`` is added to the log-odds of
  ``background`` before the most probable class is taken (:func:`weigh_prior`);
* a work-zone speed limit gets its value from :func:`workzone_ros.core.digits.
  read_speed_limit` when it can be read;
* every sign gets a distance: its LiDAR ROI's range, else its apparent size
  (:mod:`workzone_ros.core.sign_distance`);
* general signs found on the whole frame (:mod:`workzone_ros.core.general`: stop, yield,
  do-not-enter, warning, speed limit, guide signs and mile markers) are added by
  :func:`general_signs` with category ``general``, unless a work-zone chain's sign already
  covers the same place.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Sequence

from workzone_ros.core import signs as catalogue
from workzone_ros.core.classifier import Prediction
from workzone_ros.core.sign_distance import estimate_distance
from workzone_ros.interfaces import Box, Roi, Sign

__all__ = ['RecognitionConfig', 'SignRecognizer', 'unclassifiable', 'weigh_prior',
           'general_signs', 'GENERAL_OVERLAP', 'PROPOSAL_PRIOR']

#: :attr:`RecognitionConfig.proposal_prior`'s default: ln(odds that a rule-checked box is a
#: labelled sign / odds that a proposal is), 2.88 over the six labelled real clips
#: (``evaluate real_signs``, rules and proposals; docs/real_cameras.md).
PROPOSAL_PRIOR = 2.9

#: A general sign whose box overlaps a published sign's by this IoU or more is not added.
GENERAL_OVERLAP = 0.3


@dataclass(frozen=True)
class RecognitionConfig:
    """The node's rules (its parameters of the same names)."""

    margin: float = 0.1          # crop margin per side, fraction of the box
    min_size: int = 12           # px; smaller boxes are unknown
    min_visible: float = 0.5     # share of the box inside the image
    read_speed: bool = True      # read the work-zone speed limit's value
    #: ln(odds that a rule-checked box is a sign / odds that a proposal is); measured on
    #: labelled clips by ``evaluate real_signs`` (``measured_proposal_prior``)
    proposal_prior: float = PROPOSAL_PRIOR


def unclassifiable(box: Box, width: int, height: int, min_size: int,
                   min_visible: float) -> str:
    """Why ``box`` cannot be classified in a ``width`` x ``height`` image ('' when it can)."""
    if min(box.w, box.h) < min_size:
        return f'box {box.w:.0f}x{box.h:.0f} px is below min_size {min_size}'
    iw = max(0.0, min(box.x2, width) - max(box.x, 0.0))
    ih = max(0.0, min(box.y2, height) - max(box.y, 0.0))
    visible = iw * ih / box.area if box.area > 0 else 0.0
    if visible < min_visible:
        return f'only {visible:.0%} of the box is inside the image'
    return ''


def weigh_prior(pred: Prediction, prior: float) -> Prediction:
    """``pred`` with ``background``'s probability multiplied by ``exp(prior)`` and the
    probabilities renormalised: Bayes' rule for a box whose source holds fewer signs than
    the classifier's training assumed.  Unchanged when ``prior`` is 0 or the model has no
    ``background`` class."""
    probs = pred.probabilities
    if not prior or 'background' not in probs:
        return pred
    scaled = {k: v * math.exp(prior) if k == 'background' else v for k, v in probs.items()}
    total = sum(scaled.values()) or 1.0
    scaled = {k: v / total for k, v in scaled.items()}
    key = max(scaled, key=scaled.get)
    return Prediction(class_key=key, score=scaled[key], probabilities=scaled)


def _unit(x: float) -> float:
    return float(min(1.0, max(0.0, x))) if math.isfinite(x) else 0.0


def _unknown(item: Any, reason: str) -> Sign:
    return Sign(box=item.box, class_key='unknown', code='-', category='unknown', score=0.0,
                track_id=getattr(item, 'track_id', None), reason=reason)


class SignRecognizer:
    """Classifies the tracks (or detections) of a frame into published signs.

    Args:
        model: a loaded :class:`~workzone_ros.core.classifier.SignClassifier`.
        config: the rules.
    """

    def __init__(self, model: Any, config: RecognitionConfig = RecognitionConfig()) -> None:
        self.model = model
        self.config = config

    def recognize(self, frame, items: Sequence[Any], focal_px: Optional[float],
                  rois: Sequence[Roi] = ()) -> tuple[list[Sign], list[Box]]:
        """``(signs, rejected boxes)`` of one BGR frame; ``items`` have ``.box``
        (and ``.track_id`` for tracks)."""
        cfg = self.config
        h_img, w_img = frame.shape[:2]
        ok, signs = [], []
        for item in items:
            reason = unclassifiable(item.box, w_img, h_img, cfg.min_size, cfg.min_visible)
            if reason:
                signs.append(_unknown(item, reason))
            else:
                ok.append(item)
        boxes = [(it.box.x, it.box.y, it.box.w, it.box.h) for it in ok]
        preds = self.model.classify_boxes(frame, boxes, margin=cfg.margin) if boxes else []
        rejected = []
        for item, pred in zip(ok, preds):
            if pred is not None and getattr(item, 'proposal', False):
                pred = weigh_prior(pred, cfg.proposal_prior)
            if pred is None:
                signs.append(_unknown(item, 'nothing of the box is inside the image'))
            elif pred.class_key == 'background' or pred.class_key not in catalogue.BY_KEY:
                rejected.append(item.box)
            else:
                signs.append(self._sign(frame, item, pred, focal_px, rois))
        return signs, rejected

    def _sign(self, frame, item, pred, focal_px: Optional[float], rois) -> Sign:
        c = catalogue.get(pred.class_key)
        speed, speed_conf = None, None
        if c.key == 'work_zone_speed_limit' and self.config.read_speed:
            speed, speed_conf = self._read_speed(frame, item.box)
        dist, source = estimate_distance(item.box, c.key, focal_px, rois)
        return Sign(box=item.box, class_key=c.key, code=c.code, category=c.category,
                    score=_unit(pred.score), track_id=getattr(item, 'track_id', None),
                    speed_limit_mph=speed, speed_limit_confidence=speed_conf,
                    probabilities={k: round(float(v), 4)
                                   for k, v in pred.probabilities.items()},
                    distance_m=None if dist is None else round(dist, 2),
                    distance_source=source)

    def _read_speed(self, frame, box: Box) -> tuple[Optional[int], Optional[float]]:
        from workzone_ros.core.digits import read_speed_limit
        from workzone_ros.core.features import crop_sign
        crop, _ = crop_sign(frame, (box.x, box.y, box.w, box.h), self.config.margin)
        if crop is None:
            return None, None
        reading = read_speed_limit(crop)
        if reading.value is None:
            return None, None
        return int(reading.value), _unit(reading.confidence)



def general_signs(found: Sequence[Any], focal_px: Optional[float], rois: Sequence[Roi] = (),
                  published: Sequence[Sign] = ()) -> list[Sign]:
    """``Sign`` payload items (category ``general``) of the general signs ``found`` in a frame.

    ``found`` are :class:`workzone_ros.core.general.GeneralSign` (``box`` as x, y, w, h;
    ``class_key``, ``score``, ``mile``, ``mile_confidence``).  One overlapping a sign of
    ``published`` by :data:`GENERAL_OVERLAP` IoU or more is left out: the work-zone chain
    already said what is there.
    """
    out: list[Sign] = []
    for g in found:
        c = catalogue.BY_KEY.get(g.class_key)
        if c is None:
            continue
        box = Box(x=float(g.box[0]), y=float(g.box[1]), w=float(g.box[2]), h=float(g.box[3]))
        if any(box.iou(p.box) >= GENERAL_OVERLAP for p in published):
            continue
        dist, source = estimate_distance(box, c.key, focal_px, rois)
        mile = getattr(g, 'mile', None)
        conf = getattr(g, 'mile_confidence', None)
        out.append(Sign(box=box, class_key=c.key, code=c.code, category='general',
                        score=_unit(g.score),
                        distance_m=None if dist is None else round(dist, 2),
                        distance_source=source,
                        mile=None if mile is None else int(mile),
                        mile_confidence=None if mile is None or conf is None else _unit(conf)))
    return out
