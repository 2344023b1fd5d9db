"""Colour detector parameters: :class:`DetectorConfig`.

Each field is a :func:`~workzone_ros.core.knobs.knob`: its one-line doc says what it is and
its unit, its metadata its range (checked on construction by
:func:`~workzone_ros.core.knobs.check_knobs`; for the color_detector node's parameters
``min`` / ``max`` are the node parameter's range, ``check`` the range this class itself
enforces where it differs).  Why each default is what it is, and what it was measured to
do, is in ``docs/detector_history.md``.
"""
from __future__ import annotations

from dataclasses import dataclass

from workzone_ros.core.detect.edges import _PROFILE_SIG
from workzone_ros.core.knobs import check_knobs, knob

__all__ = ['METHODS', 'COLORS', 'DetectorConfig']

METHODS = ('learned', 'rgb_lp', 'hsv')
COLORS = ('orange', 'red', 'yellow')


@dataclass(frozen=True)
class DetectorConfig:
    """Detector parameters (the color_detector node's parameters of the same names).

    Raises:
        ValueError: a value out of its range (checked on construction), naming the field.
    """

    method: str = knob('learned', 'learned (the colour model of Seo et al.), rgb_lp '
                       '(Balali and Golparvar-Fard) or hsv (Cahail et al.)',
                       choices=METHODS)
    colors: tuple[str, ...] = knob(('orange', 'red', 'yellow'), 'colours to detect: orange (work '
                                   'zone), red, yellow (general signs)')
    threshold: float = knob(0.5, 'posterior threshold tau on P(x | sign) P(sign)',
                            0.01, 0.99, check=(0.0, 1.0), open_lo=True, open_hi=True,
                            note='a posterior probability')
    scale: int = knob(2, 'the mask is computed on the frame downscaled by this integer factor',
                      1, 4, check=(1, None), note='an integer downscale factor')
    use_prior: bool = knob(True, 'multiply by the spatial prior and evaluate only its ROI (seed '
                           '000 Fig. 1)')
    open_px: int = knob(2, 'opening (erosion then dilation) kernel, mask pixels (0: off)',
                        0, 15, check=False)
    close_px: int = knob(3, 'closing kernel, mask pixels (0: off)', 0, 15, check=False)
    min_radius_px: float = knob(4.0, 'smallest sign radius (half the smaller box side), '
                                'full-resolution px',
                                min=0.0, check=False)
    thin_min_radius_px: float = knob(2.0, 'smallest half-height (px) of a thin orange plaque '
                                     'kept when a white part is found below it (0: off)',
                                     min=0.0, note='px; 0: off')
    max_radius_px: float = knob(240.0, 'largest sign radius (half the larger box side), px',
                                min=1.0, check=False)
    min_area_px: float = knob(40.0, 'smallest blob area, full-resolution px', min=0.0, check=False)
    min_hull_fill: float = knob(0.35, 'smallest convex-hull area / box area of an orange blob')
    max_aspect: float = knob(4.0, 'largest w/h or h/w of an orange blob')
    diamond_hull_fill: float = knob(0.72, 'an orange blob with a hull fill below this is a '
                                    'diamond (warning sign)')
    refine: bool = knob(True, 'refine boxes at full resolution')
    border_scale: tuple[float, float] = knob((1.0, 1.0), 'extra (w, h) factors applied to every '
                                             'orange box (1: none)')
    smooth_px: int = knob(3, 'box filter on the likelihood before thresholding, mask pixels',
                          0, 9, check=False)
    v_hysteresis: float = knob(0.65, "pixels of the colour between this share of the model's "
                               'brightness gate (v_min) and the gate join the bright blobs they '
                               'connect, within their box (an under-exposed plaque split by its '
                               'legend); 0 = off',
                               0.0, 1.0, note='a share of the model v_min; 0: off')
    grow_level: float = knob(0.85, 'an orange blob that passes no test is measured again grown '
                             'into its neighbours above this share of the posterior threshold, '
                             'and kept as a diamond whose edges measure (a real face paler in '
                             'part); 0 = off',
                             0.0, 1.0, note='a share of the posterior threshold; 0: off')
    grow_reach: float = knob(0.4, "how far the growth reaches beyond the blob's box, a share of "
                             'its larger side',
                             min=0.0, note='a share of the blob')
    grow_min_px: float = knob(20.0, 'smallest shorter side of the grown blob, px',
                              min=0.0, note='px')
    use_geometry: bool = knob(True, 'reject orange blobs mounted lower than the training signs '
                              "(the colour model's extra geometry)")
    low_min_solidity: float = knob(0.85, "below the usual mounting height: a clear diamond's "
                                   'smallest solidity')
    low_max_aspect: float = knob(1.4, "below the usual mounting height: a clear diamond's "
                                 'largest w/h or h/w')
    low_min_inliers: float = knob(0.7, "below the usual mounting height: or a clear diamond's "
                                  'share of rows and columns on the fitted tents')
    close_frac: float = knob(0.12, "closing kernel at full resolution, a share of the blob's size")
    weak_threshold: float = knob(0.3, 'hysteresis: pixels of at least this likelihood next to a '
                                 'blob join it')
    clip_grow: float = knob(0.5, 'pixels with clipped red join the face up to ``1 + clip_grow`` '
                            "x the core's size (0: off)",
                            min=0.0, note="a share of the core's size; 0: off")
    border_frac: float = knob(0.04, "the sign's border and margin outside its orange hull, a "
                              'share of its size per side',
                              0.0, 0.3, check=False)
    diamond_trim: float = knob(0.0, "rows beyond a fitted diamond's corners by more than ``0.5 + "
                               'diamond_trim x b`` px are dropped (negative: off)')
    diamond_scale: float = knob(1.07, "a warning box from the mask's diamond: its half-diagonals "
                                'times this (0: the hull box)')
    diamond_clamp: float = knob(0.12, 'a warning box reaches at most this x the half-diagonal '
                                "beyond the face's pixels")
    refined_clamp: float = knob(0.4, 'a warning box refined on the brightness reaches at most '
                                "this x the half-diagonal beyond the face's pixels",
                                0.0, 2.0, note='half-diagonals')
    cut_min_width: float = knob(0.5, "an occluder's straight cut across the face's lower part: "
                                "its row at least this share of the diamond's width (0: off)",
                                0.0, 1.0, note='0: off')
    diamond_square_px: float = knob(2.5, 'a refined outline whose width and height differ by at '
                                    'most this (px) is taken as square',
                                    min=0.0, note='box px')
    diamond_square_max: float = knob(32.0, 'a refined outline is taken as square '
                                     '(diamond_square_px) only when smaller than this (box px; '
                                     '0: off)',
                                     min=0.0, note='box px; 0: off')
    diamond_grown_starts: tuple = knob((1.2, 1.4), "extra refinement starts: the hull's box "
                                       'grown by each of these factors')
    diamond_refine: bool = knob(True, "warning boxes from the face's edges measured on the "
                                'brightness at sub-pixel precision (off: from the orange mask)')
    diamond_face_ratio: float = knob(1.1266, "the catalogue's sign / face half-diagonal ratio")
    diamond_edge_bias: float = knob(0.1, 'measured half-diagonals less this, px',
                                    -1.0, 2.0, note='px')
    diamond_box_bias: float = knob(0.15, "the box's half-diagonals less this much more on sharp "
                                   'faces, px',
                                   -1.0, 2.0, note='px')
    diamond_blur_bias: float = knob(0.4, "edge bias when the edges' fitted blur is "
                                    '``diamond_blur_sigma`` or more, px',
                                    -1.0, 2.0, note='px')
    diamond_blur_sigma: float = knob(1.0, 'fitted edge blur from which ``diamond_blur_bias`` '
                                     'applies, px',
                                     min=0.0, open_lo=True, note='px')
    diamond_bright_bias: tuple = knob((0.3, 0.47, 0.95), '``(px, line0, line1)``: an edge before '
                                      'a brighter background moves out px, tapered by the border '
                                      "line's width (px)")
    diamond_tall_max: float = knob(1.08, 'a measured face is at most this x as tall as wide',
                                   1.0, 2.0, note='a ratio of the half-diagonals')
    diamond_wide_max: float = knob(1.06, 'a measured face is at most this x as wide as tall',
                                   1.0, 2.0, note='a ratio of the half-diagonals')
    diamond_luma: bool = knob(True, 'measure the edges on the luma, not the HSV value')
    diamond_clamp_px: float = knob(1.0, 'extra px the clamp allows a refined outline (blur eats '
                                   'about a pixel)')
    diamond_border_rel: float = knob(0.0676, "the diamond's border line width, in face "
                                     'half-diagonals')
    diamond_margin_rel: float = knob(0.022, "the diamond's outer margin width, in face "
                                     'half-diagonals')
    diamond_max_change: float = knob(0.4, "the measured face may differ from the mask's diamond "
                                     'by this share',
                                     0.0, 1.0, open_lo=True, note='a share of the half-diagonal')
    diamond_stroke_steps: int = knob(2, 'an edge stretch blurred this many blur-grid steps more '
                                     'than the others is a legend stroke (0: off)',
                                     0, _PROFILE_SIG.size - 1, integer=True, note='steps of the '
                                     'edge blur grid; 0 = off')
    diamond_hold: float = knob(0.97, 'the catalogue outline must hold this share of the orange '
                               'in two quadrants',
                               0.0, 1.0, open_lo=True, note='a share of the orange pixels')
    hold_sat: float = knob(0.85, 'orange left outside the outline is a blended background unless '
                           "this share of the face's saturation (0: off)",
                           0.0, 1.5, note='a share of the face saturation; 0: off')
    shift_min_px: float = knob(40.0, "refine the mask's starts moved by 2.25 px when nothing "
                               'measures a blob this large (shorter side px; 0: off)',
                               min=0.0, note='px; 0: off')
    search_min_contrast: float = knob(0.5, "a grown-start face's edges show at least this "
                                      'contrast, a share of the face',
                                      0.0, 1.0, open_lo=True, open_hi=True, note='a share of the '
                                      'face')
    blur_fit: bool = knob(True, 'when nothing refines (a faded or blurred sign, no border line '
                          'seen), the warning box from a blurred diamond fitted to the chroma R '
                          '- B')
    blur_fit_ratio: float = knob(1.06, 'the sign / fitted chroma diamond half-diagonal ratio',
                                 0.5, 2.0, note='sign / fitted half-diagonal')
    blur_fit_bias: float = knob(0.25, 'the fitted half-diagonals less this, px',
                                -3.0, 3.0, note='px')
    blur_fit_max_sigma: float = knob(4.0, 'largest blur of the chroma fit, px',
                                     0.3, 10.0, open_lo=True, note='px')
    max_blur_fits: int = knob(2, 'chroma fits per frame at most (the largest blobs first): a '
                              'busy frame of many orange surfaces costs a bounded time',
                              0, 50, integer=True, note='per frame')
    max_grown: int = knob(4, 'blobs grown into their neighbours per frame at most (the largest '
                          'first): a busy frame costs a bounded time',
                          0, 100, integer=True, note='per frame')
    max_shifted: int = knob(1, "blobs whose mask's starts are moved (shift_min_px) per frame "
                            'at most (the largest first): 8 refinements per start, a busy frame '
                            'costs a bounded time',
                            0, 50, integer=True, note='per frame')
    rim_chroma: float = knob(0.35, 'reject an outline whose rim is this far from the '
                             "background's chroma to the face's (0: off)",
                             0.0, 1.0, note='0 = off')
    rect_refine: bool = knob(True, "regulatory boxes from the orange part's edges measured on "
                             'the brightness (off: the orange hull grown by the border)')
    rect_needs_edges: bool = knob(True, 'a rectangular orange blob with neither border edges, '
                                  'nor a white part, nor a diamond found in it is dropped (dirt, '
                                  'a cone, a vest, a brick wall; LiDAR-supported blobs are kept)')
    rect_edge_bias: float = knob(0.25, 'measured rectangle edges move in by this, px')
    rect_dim_bias: tuple = knob((0.3, 80.0, 170.0), "``(px, v0, v1)``: a dim plaque's edges move "
                                'in px less at brightness v0 and below, none from v1')
    blur_px_growth: bool = knob(True, 'a box left at its hull grows by its blur rings in px on '
                                'every side')
    rect_max_change: float = knob(0.3, "the measured face's width may differ from the hull's by "
                                  'this share')
    rect_inward: tuple = knob((1.5, 3.0), "when the fit fails, a lost side's stretches are "
                              'moved in by each of these (px; empty: off)')
    rect_clip_bias: float = knob(0.3, 'sides and top move in by this x the share of clipped '
                                 'pixels, px (0: off)',
                                 min=0.0, note='px; 0: off')
    rect_border_rel: float = knob(0.03, "a rectangle's border line width, a share of its shorter "
                                  'side')
    rect_margin_rel: float = knob(0.015, "a rectangle's outer margin width, a share of its "
                                  'shorter side')
    pixel_boxes: bool = knob(True, 'refined boxes in whole pixels: the pixels the measured '
                             'outline covers more than half, as box labels are drawn (off: '
                             'sub-pixel)')
    ext_ratio_tol: float = knob(0.12, "a two-colour sign's height / width within this share of a "
                                'catalogue one',
                                min=0.0, note='0: the first dark row ends the sign')
    ext_overlong: float = knob(0.24, 'a white part taller than the catalogue by this share ends '
                               'at a bridged row (0: off)',
                               min=0.0, note='a share of the height / width; 0: off')
    ext_overlong_border: float = knob(0.75, 'a white part taller than the catalogue '
                                      '(ext_overlong) also ends after a dark band at least this '
                                      'share of the width (0: off)',
                                      0.0, 1.0, note='a share of the width; 0: off')
    ext_band_long: float = knob(0.5, 'a dark band this many orange heights long also ends the '
                                'white part at its first row',
                                min=0.0, open_lo=True, note='orange heights')
    border_dark: float = knob(0.0, 'dark share of the ring outside the hull meaning "border line '
                              'outside" (0: compare with the ring inside)')
    blur_like: float = knob(0.08, 'blur rings outside the hull of at least this mean likelihood '
                            'are added')
    blur_max_frac: float = knob(0.15, 'at most this share of the size (+ 2) of blur rings')
    min_solidity: float = knob(0.45, 'smallest orange pixels / hull area of an orange blob')
    min_dark_inside: float = knob(0.02, 'smallest share of dark (legend, border) pixels inside '
                                  'the hull')
    outline_evidence: bool = knob(True, 'a warning blob without a legend the dark test sees '
                                  '(faded, rain-washed), or an unclear face below the usual '
                                  'mounting (behind a guardrail), is kept when its diamond edges '
                                  'are measured')
    band_test: bool = knob(True, 'reject blobs that white bands separate from more orange '
                           '(cones, drums; not in LiDAR ROIs)')
    band_min_px: float = knob(6.0, 'smallest blob height for the band test, px')
    band_white_luma: float = knob(1.25, "white band: luma at least this x the blob's median luma")
    band_min_rows: float = knob(0.12, "a band has at least this share of the blob's height (at "
                                'least 2) white rows')
    cone_taper: float = knob(0.88, 'a capped blob widening downward to this row taper is a cone')
    max_surround_like: float = knob(0.5, "reject a blob whose surround's mean likelihood is "
                                    'above this (1: off; not in LiDAR ROIs)')
    surround_in: float = knob(0.1, "the surround ring's inner edge, a share of the blob's size "
                              'beyond its hull')
    min_surround_face: float = knob(0.05, 'max_surround_like rejects a blob only when also more '
                                    "than this share of the surround is at the blob's threshold")
    surround_out: float = knob(0.2, "the surround ring's outer edge, a share of the blob's size "
                               'beyond its hull')
    dark_rel: float = knob(0.6, "dark: value below this share of the blob's median orange value")
    structure_min_px: float = knob(18.0, 'blobs smaller than this (shorter side, px) skip the '
                                   'legend test')
    nms_iou: float = knob(0.3, 'non-maximum suppression: boxes overlapping a kept box by more '
                          'than this IoU are suppressed',
                          0.0, 1.0, check=False)
    nms_contain: float = knob(0.7, 'boxes lying more than this share inside a kept box are '
                              'suppressed')
    extension: bool = knob(True, 'the regulatory two-colour box extension (Seo et al.)')
    ext_min_aspect: float = knob(1.5, 'an orange rectangle at least this wide (w/h) is examined '
                                 'for a white part',
                                 0.5, 10.0, check=False)
    ext_max_ratio: float = knob(3.5, 'the extension adds at most this many orange heights')
    white_s_max: int = knob(45, 'white: saturation at most this (0-255)')
    white_v_rel: float = knob(0.8, "white: value at least this share of the orange blob's median "
                              'value')
    white_own_rel: float = knob(0.7, "white: value at least this share of the white part's own "
                                'level (0: off)',
                                0.0, 1.0, open_hi=True, note='a share of the level of the white '
                                'part itself; 0: off')
    ext_min_dark: float = knob(0.03, 'smallest dark (legend, border) share of the white part')
    ext_max_wratio: float = knob(1.8, 'the extension may also reach this many orange widths')
    ext_gap_w: float = knob(0.6, 'black legend rows may interrupt the white part for this share '
                            'of the width')
    ext_gap_s: int = knob(60, 'legend rows: median saturation at most this (0-255)')
    ext_frame: bool = knob(True, 'end a white part that runs to the reach at its black bottom '
                           'border')
    ext_border_share: float = knob(0.9, 'a border row is dark across at least this share of the '
                                   'width')
    ext_border_rel: float = knob(0.7, 'border row: darker than this share of the white '
                                 "sheeting's level")
    roi_prior: float = knob(1.0, 'the spatial prior inside LiDAR ROIs', 0.01, 1.0, check=False)
    roi_threshold: float = knob(0.3, 'the posterior threshold inside LiDAR ROIs',
                                0.01, 0.99, check=False)
    roi_margin: float = knob(0.25, 'ROI growth, a share of its size', 0.0, 2.0, check=False)
    roi_relax: float = knob(0.75, 'inside an ROI the shape minima are multiplied (the aspect '
                            'maximum divided) by this (no legend and no mounting-height test '
                            'there)',
                            0.1, 1.0, check=False)
    roi_contain: float = knob(0.8, 'a relaxed blob must lie at least this share inside its ROI')
    lidar_confidence: float = knob(0.5, 'noisy-OR weight of LiDAR support', 0.0, 1.0, check=False)
    lidar_only: bool = knob(True, 'report an ROI without a colour blob but with a sign-coloured '
                            'region of plausible size as a lidar-only detection')
    lidar_only_threshold: float = knob(0.25, "likelihood of the lidar-only region's pixels",
                                       0.01, 0.99, check=False)
    lidar_only_min_share: float = knob(0.12, "the lidar-only region's larger side at least this "
                                       "share of the ROI's")
    lidar_only_max_share: float = knob(0.9, "the lidar-only region's larger side at most this "
                                       "share of the ROI's")
    lidar_only_confidence: float = knob(0.3, 'confidence of lidar-only detections',
                                        0.0, 1.0, check=False)
    camera_match: bool = knob(True, "apply the model's fixed-camera prior and mounting row only "
                              "to frames of the model's camera (size and normalised intrinsics); "
                              'other cameras get a location-free prior (foreign_prior)')
    foreign_prior: float = knob(0.0, 'location-free prior on another camera (0: the model '
                                "prior's ROI mean relative to its table's peak)",
                                0.0, 1.0, note="0: the model prior's mean")
    camera_tolerance: float = knob(0.02, 'relative tolerance of the normalised intrinsics '
                                   'comparison')
    general_max_aspect: float = knob(1.6, 'red / yellow blobs: largest w/h or h/w (Cahail et al.)')
    general_min_fill: float = knob(0.35, 'red / yellow blobs: smallest blob area / box area '
                                   '(Cahail et al.)')
    mser_delta: int = knob(2, 'MSER delta of the ``rgb_lp`` method')

    def __post_init__(self) -> None:
        check_knobs(self)          # every scalar range and choice in the fields' metadata
        bad = [c for c in self.colors if c not in COLORS]
        if bad:
            raise ValueError(f'unknown colours {bad}; use orange, red, yellow')
        if any(not 1.0 <= g <= 3.0 for g in self.diamond_grown_starts):
            raise ValueError('diamond_grown_starts must be factors in [1, 3]')
        for name, unit in (('rect_dim_bias', 'plaque brightness, 8-bit'),
                           ('diamond_bright_bias', 'border line px')):
            t = tuple(getattr(self, name))
            if len(t) != 3 or not (0.0 <= t[0] <= 2.0 and 0.0 <= t[1] < t[2]):
                raise ValueError(f'{name} must be (px, x0, x1) with px in [0, 2] and '
                                 f'0 <= x0 < x1 ({unit}), got {t!r}')
        if any(not v > 0 for v in self.rect_inward):
            raise ValueError(f'rect_inward must be px > 0 (empty: off), got {self.rect_inward}')
