"""Colour detector parameters: :class:`DetectorConfig`.

One line per field says what it is and its unit.  Why each default is what it is, and what
it was measured to do, is in ``docs/detector_history.md``.
"""
from __future__ import annotations

from dataclasses import dataclass

from workzone_ros.core.detect.edges import _PROFILE_SIG

__all__ = ['METHODS', 'DetectorConfig']

METHODS = ('learned', 'rgb_lp', 'hsv')


@dataclass(frozen=True)
class DetectorConfig:
    """Detector parameters (the color_detector node's parameters of the same names).

    Raises:
        ValueError: a value out of its range (checked on construction).
    """

    #: ``learned`` (the colour model of Seo et al.), ``rgb_lp`` (Balali and Golparvar-Fard) or
    #: ``hsv`` (Cahail et al.)
    method: str = 'learned'
    #: colours to detect: ``orange`` (work zone), ``red``, ``yellow`` (general signs)
    colors: tuple[str, ...] = ('orange', 'red', 'yellow')
    #: posterior threshold tau on P(x | sign) P(sign)
    threshold: float = 0.5
    #: the mask is computed on the frame downscaled by this integer factor
    scale: int = 2
    #: multiply by the spatial prior and evaluate only its ROI
    use_prior: bool = True
    #: opening (erosion then dilation) kernel, mask pixels (0: off)
    open_px: int = 2
    #: closing kernel, mask pixels (0: off)
    close_px: int = 3
    #: smallest sign radius (half the smaller box side), full-resolution px
    min_radius_px: float = 4.0
    #: smallest half-height (px) of a thin orange plaque kept when a white part is found below it
    #: (0: off)
    thin_min_radius_px: float = 2.0
    #: largest sign radius (half the larger box side), px
    max_radius_px: float = 240.0
    #: smallest blob area, full-resolution px
    min_area_px: float = 40.0
    #: smallest convex-hull area / box area of an orange blob
    min_hull_fill: float = 0.35
    #: largest w/h or h/w of an orange blob
    max_aspect: float = 4.0
    #: an orange blob with a hull fill below this is a diamond (warning sign)
    diamond_hull_fill: float = 0.72
    #: refine boxes at full resolution
    refine: bool = True
    #: extra (w, h) factors applied to every orange box (1: none)
    border_scale: tuple[float, float] = (1.0, 1.0)
    #: box filter on the likelihood before thresholding, mask pixels
    smooth_px: int = 3
    #: second brightness gate, a share of the model's ``v_min``: dim pixels rejoin the bright blobs
    #: they connect (0: off)
    v_hysteresis: float = 0.65
    #: a failed orange blob is grown into pixels at this share of the threshold and kept only as a
    #: refined diamond (0: off)
    grow_level: float = 0.85
    #: how far the growth reaches beyond the blob's box, a share of its larger side
    grow_reach: float = 0.4
    #: smallest shorter side of the grown blob, px
    grow_min_px: float = 20.0
    #: reject orange blobs mounted lower than the training signs (model extra ``geometry``)
    use_geometry: bool = True
    #: below the usual mounting height: a clear diamond's smallest solidity
    low_min_solidity: float = 0.85
    #: below the usual mounting height: a clear diamond's largest w/h or h/w
    low_max_aspect: float = 1.4
    #: below the usual mounting height: or the share of rows and columns on the fitted tents
    low_min_inliers: float = 0.7
    #: closing kernel at full resolution, a share of the blob's size
    close_frac: float = 0.12
    #: hysteresis: pixels of at least this likelihood next to a blob join it
    weak_threshold: float = 0.3
    #: pixels with clipped red join the face up to ``1 + clip_grow`` x the core's size (0: off)
    clip_grow: float = 0.5
    #: the sign's border and margin outside its orange hull, a share of its size per side
    border_frac: float = 0.04
    #: rows beyond a fitted diamond's corners by more than ``0.5 + diamond_trim x b`` px are
    #: dropped (negative: off)
    diamond_trim: float = 0.0
    #: also drop the rows above a neck between a stand's flags and the diamond's top corner
    neck_trim: bool = True
    #: a warning box from the mask's diamond: its half-diagonals times this (0: the hull box)
    diamond_scale: float = 1.07
    #: a warning box reaches at most this x the half-diagonal beyond the face's pixels
    diamond_clamp: float = 0.12
    #: the same for an outline refined on the brightness
    refined_clamp: float = 0.4
    #: an occluder's straight cut across the face's lower part: its row at least this share of the
    #: diamond's width (0: off)
    cut_min_width: float = 0.5
    #: the box ends at an occluder that reaches past the sign's bottom corner
    tip_check: bool = True
    #: an occluder of two tones reaches past the bottom when nothing below it has the sign's colour
    tip_colour: bool = True
    #: those checks need the occluder to hide at least this share of the half-height
    tip_min_cut: float = 0.1
    #: the occluder may begin this many rows after the cut (a blended row), 0..3
    cut_blend_rows: int = 1
    #: a refined outline whose width and height differ by at most this (px) is taken as square
    diamond_square_px: float = 2.5
    #: ... when smaller than this (box px; 0: off)
    diamond_square_max: float = 32.0
    #: extra refinement starts: the hull's box grown by each of these factors
    diamond_grown_starts: tuple = (1.2, 1.4)
    #: scale the mask's diamond only when the ring outside it is darker than the ring inside
    diamond_ring_test: bool = True
    #: warning boxes from the face's edges measured on the brightness at sub-pixel precision
    diamond_refine: bool = True
    #: the catalogue's sign / face half-diagonal ratio
    diamond_face_ratio: float = 1.1266
    #: measured half-diagonals less this, px
    diamond_edge_bias: float = 0.1
    #: the box's half-diagonals less this much more on sharp faces, px
    diamond_box_bias: float = 0.15
    #: edge bias when the edges' fitted blur is ``diamond_blur_sigma`` or more, px
    diamond_blur_bias: float = 0.4
    #: fitted edge blur from which ``diamond_blur_bias`` applies, px
    diamond_blur_sigma: float = 1.0
    #: ``(px, line0, line1)``: an edge before a brighter background moves out px, tapered by the
    #: border line's width (px)
    diamond_bright_bias: tuple = (0.3, 0.47, 0.95)
    #: a measured face is at most this x as tall as wide
    diamond_tall_max: float = 1.08
    #: a measured face is at most this x as wide as tall
    diamond_wide_max: float = 1.06
    #: measure the edges on the luma, not the HSV value
    diamond_luma: bool = True
    #: extra px the clamp allows a refined outline (blur eats about a pixel)
    diamond_clamp_px: float = 1.0
    #: the diamond's border line width, in face half-diagonals
    diamond_border_rel: float = 0.0676
    #: the diamond's outer margin width, in face half-diagonals
    diamond_margin_rel: float = 0.022
    #: the measured face may differ from the mask's diamond by this share
    diamond_max_change: float = 0.4
    #: an edge stretch blurred this many blur-grid steps more than the others is a legend stroke
    #: (0: off)
    diamond_stroke_steps: int = 2
    #: the catalogue outline must hold this share of the orange in two quadrants
    diamond_hold: float = 0.97
    #: orange left outside the outline is a blended background unless this share of the face's
    #: saturation (0: off)
    hold_sat: float = 0.85
    #: search the face diamond in the brightness when no mask start refines
    diamond_search: bool = True
    #: refine the mask's starts moved by 2.25 px when nothing measures a blob this large (shorter
    #: side px; 0: off)
    shift_min_px: float = 40.0
    #: smallest blob (shorter side, px) the search looks at
    search_min_px: float = 12.0
    #: a searched sign is at least this share of the blob's shorter side
    search_min_share: float = 0.6
    #: a searched (or grown-start) face's edges show at least this contrast, a share of the face
    search_min_contrast: float = 0.5
    #: fit a blurred diamond to the chroma R - B when nothing refines
    blur_fit: bool = True
    #: the sign / fitted chroma diamond half-diagonal ratio
    blur_fit_ratio: float = 1.06
    #: the fitted half-diagonals less this, px
    blur_fit_bias: float = 0.25
    #: largest blur of the chroma fit, px
    blur_fit_max_sigma: float = 4.0
    #: reject an outline whose rim is this far from the background's chroma to the face's (0: off)
    rim_chroma: float = 0.35
    #: regulatory boxes from the orange part's edges measured on the brightness
    rect_refine: bool = True
    #: drop a rectangular blob with no border edges, no white part and no diamond found (not in
    #: LiDAR ROIs)
    rect_needs_edges: bool = True
    #: measured rectangle edges move in by this, px
    rect_edge_bias: float = 0.25
    #: ``(px, v0, v1)``: a dim plaque's edges move in px less at brightness v0 and below, none from
    #: v1
    rect_dim_bias: tuple = (0.3, 80.0, 170.0)
    #: a box left at its hull grows by its blur rings in px on every side
    blur_px_growth: bool = True
    #: the measured face's width may differ from the hull's by this share
    rect_max_change: float = 0.3
    #: fit again on a two-colour sign's white part's columns when the orange part's fit fails or
    #: disagrees
    rect_white_span: bool = True
    #: when both starts fail, a lost side's stretches are moved in by each of these (px; empty:
    #: off)
    rect_inward: tuple = (1.5, 3.0)
    #: sides and top move in by this x the share of clipped pixels, px (0: off)
    rect_clip_bias: float = 0.3
    #: widen a two-colour sign's box to its face turned on a leaning post
    rect_lean: bool = True
    #: smallest mean slope (dx / dy) taken as a lean
    rect_lean_min: float = 0.025
    #: largest difference of the two sides' slopes
    rect_lean_agree: float = 0.05
    #: widen a two-colour sign to its white part's ends beyond the measured sides
    white_ends: bool = True
    #: a rectangle's border line width, a share of its shorter side
    rect_border_rel: float = 0.03
    #: a rectangle's outer margin width, a share of its shorter side
    rect_margin_rel: float = 0.015
    #: refined boxes in whole pixels, as box labels are drawn
    pixel_boxes: bool = True
    #: a blob that passes no test is judged again at higher likelihood levels
    peel: bool = True
    #: peel levels at least this above the blob's median likelihood
    peel_gap: float = 0.08
    #: peel likelihood levels after Otsu's
    peel_levels: tuple = (0.8, 0.9)
    #: a peeled warning box may reach this x the half-diagonal beyond the core
    peel_clamp: float = 0.3
    #: at most this many blobs peeled per frame
    peel_max: int = 2
    #: measure two blobs that are pieces of one diamond as one
    merge_fragments: bool = True
    #: of the this-many largest blobs
    merge_max: int = 6
    #: then three blobs the same way
    merge_triples: bool = True
    #: a two-colour sign's height / width within this share of a catalogue one
    ext_ratio_tol: float = 0.12
    #: a white part taller than the catalogue by this share ends at a bridged row (0: off)
    ext_overlong: float = 0.24
    #: ... or after a dark band at least this share of the width (0: off)
    ext_overlong_border: float = 0.75
    #: choose the white part's end again with the measured top and width
    ext_rechoose: bool = True
    #: a dark band this many orange heights long also ends the white part at its first row
    ext_band_long: float = 0.5
    #: dark share of the ring outside the hull meaning "border line outside" (0: compare with the
    #: ring inside)
    border_dark: float = 0.0
    #: blur rings outside the hull of at least this mean likelihood are added
    blur_like: float = 0.08
    #: at most this share of the size (+ 2) of blur rings
    blur_max_frac: float = 0.15
    #: smallest orange pixels / hull area of an orange blob
    min_solidity: float = 0.45
    #: smallest share of dark (legend, border) pixels inside the hull
    min_dark_inside: float = 0.02
    #: a warning blob without a legend (or unclear and low) is kept when its diamond edges measure
    outline_evidence: bool = True
    #: a plaque without a legend is kept when the extension finds its white part
    white_part_evidence: bool = True
    #: ... and that white part is at least this x as bright as the orange
    white_part_level: float = 1.1
    #: reject blobs that white bands separate from more orange (cones, drums; not in LiDAR ROIs)
    band_test: bool = True
    #: smallest blob height for the band test, px
    band_min_px: float = 6.0
    #: white band: luma at least this x the blob's median luma
    band_white_luma: float = 1.25
    #: a band has at least this share of the blob's height (at least 2) white rows
    band_min_rows: float = 0.12
    #: a capped blob widening downward to this row taper is a cone
    cone_taper: float = 0.88
    #: reject a blob whose surround's mean likelihood is above this (1: off; not in LiDAR ROIs)
    max_surround_like: float = 0.5
    #: the surround ring's inner edge, a share of the blob's size beyond its hull
    surround_in: float = 0.1
    #: ... and more than this share of the surround at the blob's threshold
    min_surround_face: float = 0.05
    #: the surround ring's outer edge, a share of the blob's size beyond its hull
    surround_out: float = 0.2
    #: dark: value below this share of the blob's median orange value
    dark_rel: float = 0.6
    #: blobs smaller than this (shorter side, px) skip the legend test
    structure_min_px: float = 18.0
    #: boxes overlapping a kept box by more than this IoU are suppressed
    nms_iou: float = 0.3
    #: so are boxes lying more than this share inside a kept one
    nms_contain: float = 0.7
    #: the regulatory two-colour extension (Seo et al.)
    extension: bool = True
    #: an orange rectangle at least this wide (w/h) is examined for a white part
    ext_min_aspect: float = 1.5
    #: the extension adds at most this many orange heights
    ext_max_ratio: float = 3.5
    #: white: saturation at most this (0-255)
    white_s_max: int = 45
    #: white: value at least this share of the orange blob's median value
    white_v_rel: float = 0.8
    #: white: value at least this share of the white part's own level (0: off)
    white_own_rel: float = 0.7
    #: smallest dark (legend, border) share of the white part
    ext_min_dark: float = 0.03
    #: the extension may also reach this many orange widths
    ext_max_wratio: float = 1.8
    #: black legend rows may interrupt the white part for this share of the width
    ext_gap_w: float = 0.6
    #: legend rows: median saturation at most this (0-255)
    ext_gap_s: int = 60
    #: judge coloured-looking gap rows again on the white part's own columns
    ext_gap_cols: bool = True
    #: end a white part that runs to the reach at its black bottom border
    ext_frame: bool = True
    #: a border row is dark across at least this share of the width
    ext_border_share: float = 0.9
    #: border row: darker than this share of the white sheeting's level
    ext_border_rel: float = 0.7
    #: the spatial prior inside LiDAR ROIs
    roi_prior: float = 1.0
    #: the posterior threshold inside LiDAR ROIs
    roi_threshold: float = 0.3
    #: ROI growth, a share of its size
    roi_margin: float = 0.25
    #: inside an ROI the shape minima are multiplied (the aspect maximum divided) by this
    roi_relax: float = 0.75
    #: a relaxed blob must lie at least this share inside its ROI
    roi_contain: float = 0.8
    #: noisy-OR weight of LiDAR support
    lidar_confidence: float = 0.5
    #: report an ROI without a colour blob but with a sign-coloured region as a lidar-only
    #: detection
    lidar_only: bool = True
    #: likelihood of the lidar-only region's pixels
    lidar_only_threshold: float = 0.25
    #: the region's larger side at least this share of the ROI's
    lidar_only_min_share: float = 0.12
    #: ... and at most this share
    lidar_only_max_share: float = 0.9
    #: confidence of lidar-only detections
    lidar_only_confidence: float = 0.3
    #: apply the model's fixed-camera prior and mounting row only to its own camera's frames
    camera_match: bool = True
    #: location-free prior on another camera (0: the model prior's mean relative to the table's
    #: peak)
    foreign_prior: float = 0.0
    #: relative tolerance of the normalised intrinsics comparison
    camera_tolerance: float = 0.02
    #: red / yellow blobs: largest w/h or h/w (Cahail et al.)
    general_max_aspect: float = 1.6
    #: red / yellow blobs: smallest blob area / box area (Cahail et al.)
    general_min_fill: float = 0.35
    #: MSER delta of the ``rgb_lp`` method
    mser_delta: int = 2

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f'method {self.method!r} is not one of {METHODS}')
        bad = [c for c in self.colors if c not in ('orange', 'red', 'yellow')]
        if bad:
            raise ValueError(f'unknown colours {bad}; use orange, red, yellow')
        if not 0.0 < self.threshold < 1.0:
            raise ValueError('threshold must be in (0, 1)')
        if int(self.scale) < 1:
            raise ValueError('scale must be >= 1')
        if not 0.0 <= self.foreign_prior <= 1.0:
            raise ValueError("foreign_prior must be in [0, 1] (0: the model prior's mean)")
        if not 0.0 < self.diamond_max_change <= 1.0:
            raise ValueError('diamond_max_change must be in (0, 1] (a share of the half-diagonal)')
        if self.diamond_stroke_steps not in range(0, _PROFILE_SIG.size):
            raise ValueError('diamond_stroke_steps must be an integer in '
                             f'0..{_PROFILE_SIG.size - 1} (steps of the edge blur grid; 0 = off)')
        if any(not 1.0 <= g <= 3.0 for g in self.diamond_grown_starts):
            raise ValueError('diamond_grown_starts must be factors in [1, 3]')
        if not (-1.0 <= self.diamond_edge_bias <= 2.0 and -1.0 <= self.diamond_blur_bias <= 2.0
                and self.diamond_blur_sigma > 0):
            raise ValueError('diamond_edge_bias / diamond_blur_bias must be in [-1, 2] px and '
                             'diamond_blur_sigma > 0')
        if not (1.0 <= self.diamond_tall_max <= 2.0 and 1.0 <= self.diamond_wide_max <= 2.0):
            raise ValueError('diamond_tall_max and diamond_wide_max must be in [1, 2] (ratios '
                             'of the half-diagonals)')
        if not 0.0 <= self.cut_min_width <= 1.0:
            raise ValueError('cut_min_width must be in [0, 1] (0: off)')
        if not -1.0 <= self.diamond_box_bias <= 2.0:
            raise ValueError(f'diamond_box_bias must be in [-1, 2] px, got '
                             f'{self.diamond_box_bias}')
        for name, unit in (('rect_dim_bias', 'plaque brightness, 8-bit'),
                           ('diamond_bright_bias', 'border line px')):
            t = tuple(getattr(self, name))
            if len(t) != 3 or not (0.0 <= t[0] <= 2.0 and 0.0 <= t[1] < t[2]):
                raise ValueError(f'{name} must be (px, x0, x1) with px in [0, 2] and '
                                 f'0 <= x0 < x1 ({unit}), got {t!r}')
        if self.diamond_square_px < 0 or self.diamond_square_max < 0:
            raise ValueError('diamond_square_px and diamond_square_max must be >= 0 (box px; '
                             '0: off)')
        if self.white_part_level < 0.0:
            raise ValueError(f'white_part_level must be >= 0 (white / orange brightness), got '
                             f'{self.white_part_level}')
        if not 0.0 <= self.white_own_rel < 1.0:
            raise ValueError(f'white_own_rel must be in [0, 1) (a share of the level of the '
                             f'white part itself; 0: off), got {self.white_own_rel}')
        if self.cut_blend_rows not in range(0, 4):
            raise ValueError(f'cut_blend_rows must be an integer in 0..3, got '
                             f'{self.cut_blend_rows!r}')
        if not 0.0 <= self.tip_min_cut < 1.0:
            raise ValueError(f'tip_min_cut must be in [0, 1) (a share of the half-height), '
                             f'got {self.tip_min_cut}')
        if not 0.0 <= self.refined_clamp <= 2.0:
            raise ValueError('refined_clamp must be in [0, 2] (half-diagonals)')
        if not 0.0 <= self.hold_sat <= 1.5:
            raise ValueError('hold_sat must be in [0, 1.5] (a share of the face saturation)')
        if not 0.5 <= self.blur_fit_ratio <= 2.0 or not 0.3 < self.blur_fit_max_sigma <= 10:
            raise ValueError('blur_fit_ratio must be in [0.5, 2] and blur_fit_max_sigma in '
                             '(0.3, 10] px')
        if not -3.0 <= self.blur_fit_bias <= 3.0:
            raise ValueError('blur_fit_bias must be in [-3, 3] px')
        if not 0.0 <= self.rim_chroma <= 1.0:
            raise ValueError('rim_chroma must be in [0, 1] (0 = off)')
        if not 0.0 < self.search_min_contrast < 1.0:
            raise ValueError('search_min_contrast must be in (0, 1) (a share of the face)')
        if self.search_min_px < 0 or not 0.0 <= self.search_min_share <= 1.5:
            raise ValueError('search_min_px must be >= 0 and search_min_share in [0, 1.5]')
        if self.shift_min_px < 0.0:
            raise ValueError(f'shift_min_px must be >= 0 (px; 0: off), got {self.shift_min_px}')
        if not 0.0 < self.diamond_hold <= 1.0:
            raise ValueError('diamond_hold must be in (0, 1] (a share of the orange pixels)')
        if not all(0.0 < float(v) < 1.0 for v in self.peel_levels):
            raise ValueError('peel_levels must be likelihoods in (0, 1)')
        if not 0.0 <= self.v_hysteresis <= 1.0:
            raise ValueError('v_hysteresis must be in [0, 1] (a share of the model v_min; '
                             '0: off)')
        if not (0.0 <= self.grow_level <= 1.0 and self.grow_reach >= 0.0
                and self.grow_min_px >= 0.0):
            raise ValueError('grow_level must be in [0, 1] (a share of the posterior '
                             'threshold; 0: off), grow_reach >= 0 (a share of the blob) '
                             'and grow_min_px >= 0')
        if int(self.peel_max) < 0 or self.peel_gap < 0 or self.peel_clamp < 0:
            raise ValueError('peel_max, peel_gap and peel_clamp must be >= 0')
        if int(self.merge_max) < 0:
            raise ValueError(f'merge_max must be >= 0 (got {self.merge_max})')
        if self.thin_min_radius_px < 0:
            raise ValueError('thin_min_radius_px must be >= 0 (0: off)')
        if not self.ext_band_long > 0:
            raise ValueError('ext_band_long must be > 0 (orange heights)')
        if self.clip_grow < 0:
            raise ValueError(f"clip_grow must be >= 0 (a share of the core's size; 0: off), "
                             f'got {self.clip_grow}')
        if not 0.0 <= self.ext_overlong_border <= 1.0:
            raise ValueError(f'ext_overlong_border must be in [0, 1] (a share of the width; '
                             f'0: off), got {self.ext_overlong_border}')
        if self.rect_clip_bias < 0:
            raise ValueError(f'rect_clip_bias must be >= 0 (px; 0: off), got '
                             f'{self.rect_clip_bias}')
        if any(not v > 0 for v in self.rect_inward):
            raise ValueError(f'rect_inward must be px > 0 (empty: off), got {self.rect_inward}')
        if self.ext_overlong < 0:
            raise ValueError(f'ext_overlong must be >= 0 (a share of the height / width; 0: '
                             f'off), got {self.ext_overlong}')
        if self.ext_ratio_tol < 0:
            raise ValueError('ext_ratio_tol must be >= 0 (0: the first dark row ends the sign)')
        if not (0.0 <= self.rect_lean_min <= 0.5 and 0.0 <= self.rect_lean_agree <= 0.5):
            raise ValueError('rect_lean_min and rect_lean_agree must be in [0, 0.5] (slopes, '
                             'dx / dy)')
