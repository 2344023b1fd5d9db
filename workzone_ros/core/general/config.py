"""Result and configuration types of the general (non-work-zone) sign recogniser.

:class:`GeneralSign` is what :class:`~workzone_ros.core.general.detector.GeneralSignDetector`
returns for one sign; :class:`GeneralConfig` holds every threshold, each with what it does to
the output.  No ROS import (DESIGN.md, principle 1).
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Optional

__all__ = ['GeneralSign', 'GeneralConfig', 'GeneralSignError', 'GENERAL_CLASSES',
           'RED_TEMPLATES']

#: Class keys the recogniser reports (catalogue keys, core/signs.py).
GENERAL_CLASSES: tuple[str, ...] = ('stop', 'yield', 'do_not_enter', 'warning_diamond',
                                    'speed_limit', 'guide', 'mile_marker')
#: The red signs recognised by template matching (Cahail et al., section 3.4.3).
RED_TEMPLATES: tuple[str, ...] = ('stop', 'yield', 'do_not_enter')


class GeneralSignError(ValueError):
    """Bad input or configuration of the general sign recogniser."""


@dataclass(frozen=True)
class GeneralSign:
    """One recognised general sign.

    Attributes:
        box: (x, y, w, h) in image pixels.
        class_key: ``stop``, ``yield``, ``do_not_enter``, ``warning_diamond``,
            ``speed_limit``, ``guide`` or ``mile_marker``.
        score: 0..1, how sure the recogniser is: with ``verify='cnn'`` the CNN's
            probability of the general classes of the sign's colour; with
            ``verify='templates'`` the best normalised correlation for red signs, a
            shape/legend score for the others.
        colour: ``red``, ``yellow``, ``white`` or ``green``.
        shape: ``octagon``, ``triangle``, ``square``, ``diamond`` or ``rectangle``.
        template: the red template that matched best ('' for other signs, and with
            ``verify='cnn'`` for red signs the CNN was sure of: templates are then only
            matched where the CNN hesitates).
        template_score: Cahail et al.'s score of that template: the share of positions
            whose normalised correlation is above ``GeneralConfig.corr_threshold``, the
            maximum over scales.
        template_ncc: the best normalised correlation of that template over positions
            and scales.
        mile: the number on a mile marker, None when it is not legible.
        mile_confidence: the reader's confidence in ``mile`` (None when nothing was read).
    """

    box: tuple[int, int, int, int]
    class_key: str
    score: float
    colour: str
    shape: str
    template: str = ''
    template_score: float = 0.0
    mile: Optional[int] = None
    mile_confidence: Optional[float] = None
    template_ncc: float = 0.0


def _pair(v) -> bool:
    return isinstance(v, tuple) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v)


@dataclass(frozen=True)
class GeneralConfig:
    """Every threshold of the recogniser.  Hues are OpenCV units (0..180), saturation and
    value 0..255; sizes are full-image pixels unless the name says otherwise."""

    # ---- working image
    #: frames wider than this are shrunk (area) to it for the colour masks; crops for the
    #: templates and the mile reader come from the full frame.  Time scales with its square.
    work_width: int = 640
    #: grey-world white balance gains are clipped to [1 / g, g]: removes the colour cast of
    #: dusk light and camera white balance (without it dusk red signs read orange).
    max_gain: float = 1.4
    # ---- colour blob filter (Cahail et al., 3.4.2): pixel ranges
    #: red is hue <= red_hue_lo or hue >= red_hue_hi (the two ranges of the red sheeting).
    red_hue_lo: int = 6
    red_hue_hi: int = 160
    #: yellow pixel hue range (fluorescent yellow-green reaches 40).
    yellow_hue: tuple[int, int] = (18, 42)
    #: minimum saturation and value of a red or yellow pixel (rain and overcast light
    #: desaturate the sheeting to ~45).
    min_saturation: int = 45
    min_value: int = 50
    #: every colour is also searched with this minimum saturation (a second, strict pass):
    #: in sun a sign merges with dry grass or foliage of its hue in the loose mask, never
    #: in the strict one.
    strict_saturation: int = 140
    #: side (work px) of the square erosion / dilation kernels, and dilation iterations.
    erode_px: int = 3
    dilate_iter: int = 1
    # ---- blob filters (3.4.2)
    #: the shorter side of a blob's box, full-image px (the evaluation's visibility floor).
    min_side_px: int = 14
    #: a blob's box must be at most this much wider than tall (or taller than wide).
    max_aspect: float = 1.45
    #: bounding box area < blob area * fill_constant (the paper's constant): 2.5 admits
    #: diamonds and triangles (area half the box).
    fill_constant: float = 2.5
    # ---- colour verification (keeps work-zone orange out)
    #: median hue of a blob's saturated pixels (hue wrapped to -90..90): red up to this,
    #: yellow from ``yellow_median_min``; orange sheeting lies between and is dropped.
    red_median_max: float = 4.5
    yellow_median_min: float = 18.5
    # ---- red templates (3.4.3)
    #: the blob's longer side is scaled to this many px before matching.
    template_px: int = 40
    #: crop margin around the blob's box, share of its size per side.
    crop_margin: float = 0.15
    #: template sizes, shares of ``template_px`` (several sizes, Fig. 3.7).
    scales: tuple[float, ...] = (0.85, 0.93, 1.0, 1.08)
    #: which template wins: 'ncc', the best normalised correlation, or 'score', the highest
    #: share of positions above ``corr_threshold`` (Cahail et al.'s rule; on our renders
    #: it takes STOP for DO NOT ENTER, whose smooth face correlates broadly: see the docs).
    select_by: str = 'ncc'
    #: a position "matches well" when its normalised correlation exceeds this.
    corr_threshold: float = 0.5
    #: a red blob is a sign only if the best template's share of good positions and best
    #: correlation reach these; otherwise it is dropped (red cars, brick, taillights).
    min_template_score: float = 0.05
    min_template_ncc: float = 0.68
    #: a red sign overrides an overlapping yellow one (the paper's rule) only when its box
    #: is at least this share of the yellow box's area (a red symbol on a warning sign is
    #: part of the warning sign).
    override_area: float = 0.4
    # ---- yellow warning diamonds
    #: the blob covers at most this share of each corner triangle of its box (a diamond
    #: leaves them empty; vehicles and foliage do not).
    max_corner_fill: float = 0.25
    #: and covers at least this share of the diamond inscribed in its box (less a rim).
    min_diamond_fill: float = 0.85
    #: share of dark (legend / border) pixels inside the face, a range.
    legend_dark: tuple[float, float] = (0.03, 0.6)
    # ---- white and green panels
    #: white: saturation at most this, value at least white_value times the frame's 99th
    #: percentile of value (and at least 70).
    white_max_saturation: int = 70
    white_value: float = 0.62
    #: green sheeting hue range, minimum saturation and value.
    green_hue: tuple[int, int] = (50, 96)
    #: the strict green pass starts at this hue (foliage sits at 50-60).
    green_strict_hue: int = 58
    green_min_saturation: int = 60
    green_min_value: int = 35
    #: a panel fills at least this share of its box.
    panel_fill: float = 0.8
    #: panel aspect (w / h) ranges: speed limit (R2-1, 0.75), guide (wide), mile marker (0.4).
    speed_limit_aspect: tuple[float, float] = (0.55, 0.95)
    guide_aspect: tuple[float, float] = (1.3, 4.5)
    mile_aspect: tuple[float, float] = (0.22, 0.62)
    #: share of legend pixels (dark on white, white on green) inside a panel, a range.
    panel_legend: tuple[float, float] = (0.05, 0.5)
    #: a white panel's black border: the share of a line just outside each side that is
    #: dark, on at least ``border_sides`` of the four sides.
    border_dark: float = 0.5
    border_sides: int = 4
    #: panels larger than this share of the working image are sky, trailers, walls.
    max_panel_share: float = 0.15
    # ---- mile marker number
    #: a digit at least this many full-image px high is legible; smaller: mile None.
    min_digit_px: int = 8
    #: the read is kept only when every digit's confidence reaches this.
    min_mile_confidence: float = 0.8
    # ---- verification (docs/general_signs.md, "Learned verification")
    #: 'cnn': generous colour candidates (candidates.py) verified by the CNN sign
    #: classifier, which decides sign or background; 'templates': the paper's pipeline
    #: (blob shape tests, red templates), kept as the baseline.
    verify: str = 'cnn'
    #: saturation floors of the candidate colour masks (one mask per level and colour).
    candidate_saturations: tuple[int, ...] = (45, 90, 140)
    #: a candidate's shorter side, full-image px (a 20 px sign at IoU 0.5 needs >= 14).
    candidate_min_px: int = 12
    #: a candidate's longer side at most this share of the working image height.
    candidate_max_share: float = 0.4
    #: colours whose masks are also cut along grey-level edges (Canny, ``edge_thresholds``)
    #: before their blobs are taken: a sign's border separates it from foliage or grass
    #: of its colour.
    edge_cut: tuple[str, ...] = ()
    edge_thresholds: tuple[int, int] = (60, 150)
    #: white candidates also come from pixels brighter by ``local_white_delta`` than the
    #: mean of the ``local_white_block`` (working px) square around them, with saturation
    #: at most ``local_white_saturation``: a panel against grey rain, a warm-lit panel.
    local_white_block: int = 41
    local_white_delta: int = 30
    local_white_saturation: int = 90
    #: red candidates are also proposed grown by this share of their size (DO NOT ENTER's
    #: disc on its white plate, a STOP with its white rim).
    candidate_grow: float = 0.3
    #: candidates overlapping a better one by more than this IoU are dropped.
    candidate_nms: float = 0.7
    #: at most this many candidates per frame go to the CNN (one batch), best cheap score.
    max_candidates: int = 12
    #: a candidate is a sign when the CNN's probability of the general classes its colour
    #: can be reaches this (the rest is background or a work-zone sign).
    cnn_threshold: float = 0.8
    #: a red candidate below ``cnn_threshold`` is still a sign when the paper's template
    #: test accepts it (``min_template_score``, ``min_template_ncc``) and the CNN's
    #: background probability is at most this (the CNN saw few YIELD / DO NOT ENTER).
    cnn_red_background: float = 0.6
    #: a red candidate whose CNN probabilities of STOP / YIELD / DO NOT ENTER have no class
    #: above this share of their sum takes the red template's class instead.
    cnn_red_margin: float = 0.7
    #: a candidate whose value channel's standard deviation (working image) is below
    #: this is not verified (a uniform patch: no legend, no border).
    min_contrast: float = 10.0
    #: a red or yellow candidate is not a sign when more than this share of the band
    #: below it (0.35 of its height) is its colour at 0.7 of its median saturation: a
    #: face ends at its edge, a drum, a truck or a van's lettering go on.
    max_colour_below: float = 0.35
    #: accepted boxes overlapping a better one by more than this IoU are the same sign.
    detection_nms: float = 0.3

    def __post_init__(self) -> None:
        if self.verify not in ('cnn', 'templates'):
            raise GeneralSignError(f"GeneralConfig.verify must be 'cnn' or 'templates', got "
                                   f'{self.verify!r}')
        if self.select_by not in ('ncc', 'score'):
            raise GeneralSignError(f"GeneralConfig.select_by must be 'ncc' or 'score', got "
                                   f'{self.select_by!r}')
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ('select_by', 'verify'):
                continue
            if f.name == 'edge_cut':
                if not isinstance(v, tuple) or any(
                        c not in ('red', 'yellow', 'white', 'green') for c in v):
                    raise GeneralSignError(f'GeneralConfig.edge_cut must be a tuple of '
                                           f'colours (red, yellow, white, green), got {v!r}')
                continue
            if isinstance(v, bool):
                raise GeneralSignError(f'GeneralConfig.{f.name} must be a number, got {v!r}')
            if isinstance(v, tuple):
                many = f.name in ('scales', 'candidate_saturations')
                ok = _pair(v) if not many else (
                    len(v) > 0 and all(isinstance(x, (int, float)) and x > 0 for x in v))
                if not ok or (not many and v[0] > v[1]):
                    raise GeneralSignError(f'GeneralConfig.{f.name} must be a (low, high) pair '
                                           f'of numbers (scales: positive numbers), got {v!r}')
            elif not isinstance(v, (int, float)) or v < 0:
                raise GeneralSignError(f'GeneralConfig.{f.name} must be a non-negative '
                                       f'number, got {v!r}')
        checks = [
            (self.work_width >= 64, 'work_width must be >= 64'),
            (self.max_gain >= 1.0, 'max_gain must be >= 1'),
            (self.red_hue_lo < self.red_hue_hi <= 180, 'need red_hue_lo < red_hue_hi <= 180'),
            (self.erode_px >= 1 and self.template_px >= 12, 'erode_px >= 1, template_px >= 12'),
            (self.max_aspect >= 1.0, 'max_aspect must be >= 1'),
            (self.max_candidates >= 1, 'max_candidates must be >= 1'),
            (self.local_white_block >= 3, 'local_white_block must be >= 3'),
            (self.border_sides <= 4, 'border_sides must be 0..4'),
            (self.fill_constant >= 1.0, 'fill_constant must be >= 1'),
            (self.red_median_max < self.yellow_median_min,
             'red_median_max must be below yellow_median_min'),
            (all(0 <= getattr(self, n) <= 1 for n in (
                'corr_threshold', 'min_template_score', 'min_template_ncc', 'override_area',
                'max_corner_fill', 'min_diamond_fill', 'white_value', 'panel_fill', 'border_dark',
                'max_panel_share', 'min_mile_confidence', 'crop_margin', 'candidate_max_share',
                'candidate_nms', 'cnn_threshold', 'cnn_red_margin', 'cnn_red_background',
                'max_colour_below',
                'detection_nms')),
             'shares, correlations and confidences must be in [0, 1]'),
        ]
        for ok, msg in checks:
            if not ok:
                raise GeneralSignError(f'GeneralConfig: {msg}')
