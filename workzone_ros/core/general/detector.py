"""The general (non-work-zone) sign recogniser: red and yellow signs after seed 004, white
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

No ROS import (DESIGN.md, principle 1).
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from workzone_ros.core.general import colour, panels, templates
from workzone_ros.core.general.config import GeneralConfig, GeneralSign, GeneralSignError

__all__ = ['GeneralSignDetector', 'check_image']

Box = tuple[int, int, int, int]


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


def _overlap(a: Box, b: Box) -> float:
    """Intersection over the smaller box's area."""
    ix = max(0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    return ix * iy / float(max(1, min(a[2] * a[3], b[2] * b[3])))


class GeneralSignDetector:
    """Recognise stop, yield, do not enter, yellow warning, speed limit, guide signs and mile
    markers in BGR frames.

    Args:
        config: thresholds (:class:`GeneralConfig`).

    Raises:
        GeneralSignError: ``config`` is not a GeneralConfig.
    """

    def __init__(self, config: GeneralConfig = GeneralConfig()) -> None:
        if not isinstance(config, GeneralConfig):
            raise GeneralSignError(f'config must be a GeneralConfig, got '
                                   f'{type(config).__name__}')
        self.config = config
        templates.template_bank(config.template_px, tuple(config.scales))   # draw them now

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
