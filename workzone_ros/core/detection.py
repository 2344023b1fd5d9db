"""Colour sign detection: posterior mask -> blobs -> filtered, scored, extended boxes.

Main path (``method='learned'``, seed 000 section III.A, seed 001 section III.A):

1. P(x | sign) from the colour model's hue x saturation table, one lookup per pixel, on an
   image downscaled by ``scale`` (a 640x480 frame is looked up at 320x240); pixels darker than
   the model's value gate have no reliable hue and are left out.
2. Posterior threshold P(x | sign) P(sign) >= tau (eq. 1), done as a comparison with the
   precomputed per-pixel threshold tau / P(sign).  Only the prior's ROI is evaluated (Fig. 1).
   The heat map and its ROI are rows and columns of the training camera: frames of another
   camera (another size, or other normalised intrinsics given with ``set_camera``) get a
   location-free prior instead, the heat map's mean over its ROI relative to the table's
   peak, over the whole frame, and no fixed-row mounting test (``camera_match``; on the real
   722x406 dashcam clips the stretched 640x480 map put a sidewalk sign at the prior's floor,
   where no likelihood can pass).  That prior demands the likelihood of saturated sign
   sheeting (the default table's upper step, 0.97-0.99) and so also separates a sign from
   warm mid-saturation brick, lawns and asphalt (0.65-0.78) behind it.
   This colour-only pass is the same with or without LiDAR.  A second pass then looks only
   at the LiDAR ROIs (``/workzone/rois``) that no colour detection explains (its centre
   inside): there the prior is raised to ``roi_prior`` and the lower ``roi_threshold`` is
   used, so a sign the colour model half-sees is still found (seed 004's two-layer idea,
   done as fusion), while blobs outside those ROIs never merge differently.  A blob inside
   an ROI also needs less shape evidence (``roi_relax``: looser hull-fill / solidity /
   aspect, no legend and no mounting-height test) as long as it lies mostly inside the ROI
   (``roi_contain``); outside ROIs nothing changes.
3. Erosion then dilation (opening, seed 004 3.4.2) and a closing, connected components
   (``cv2.connectedComponentsWithStats``), radius filters (seed 000 footnote 2: centroid to
   side distance, here half the smaller box side).
   Before the table the frame is grey-world balanced when the model was trained so
   (colour constancy outside the table: a dusk cast no longer turns sky and lane paint
   orange) and its saturation is normalised (``SatNorm``: a hazy, washed-out frame is
   stretched so its 90th saturation percentile reaches the model's reference; a colourful
   frame is left alone, so warm grey asphalt and walls stay below the sign's saturation),
   and the likelihood is box-filtered at the mask's resolution before the
   threshold (isolated orange-hued pixels are averaged away).
4. Each blob is measured at full resolution inside a small window (so the half-resolution
   mask costs no box accuracy): hysteresis (pixels >= ``weak_threshold`` next to the blob
   join it) and a closing sized to the blob bridge the border line and legend strokes; the
   face must look like a sign: solidity, convex-hull fill (~0.5 diamond, ~1 rectangle),
   aspect, a dark legend / border inside the hull, and a bottom edge no lower than the
   training signs' mounting geometry allows (model extra ``geometry``; drums, cones and
   vehicles stand on the road; lifted inside LiDAR ROIs).  A warning blob that fails the
   legend test (a faded or rain-washed legend) or, mounted low, is no clear diamond (a
   guardrail across it) is kept only when its diamond outline is then measured in the
   brightness (``outline_evidence``).  The box is the orange hull's,
   grown per blob from its own edge profile (``_border_growth``): by ``border_frac`` when the
   black border line lies outside the hull (margin and line lost), plus the width of the
   soft colour edge around it (blurred, small or rain-washed signs); a bright sign whose
   margin is already inside the hull does not grow.  A model whose table scores the
   blended edge smoothly (Gentle AdaBoost) says so in its metadata (``measure``: relative):
   the box is taken from the blob's core (pixels at least ``edge_rel`` of the way from its
   own background likelihood level to its face level) and grown by the blur rings judged on
   the same relative scale (:func:`relative_measure`); which blobs are signs is still
   judged on the absolute face.  Warning diamonds and the orange part of regulatory
   rectangles then get their edges at sub-pixel precision from the brightness
   (:func:`refine_diamond`, :func:`refine_rectangle`; ``diamond_refine``, ``rect_refine``):
   the colour table cannot place them, because a blend of the orange face and its black
   border line keeps the face's hue and saturation; the mask-based box stays the fallback
   when an edge shows no face-to-border step.  A diamond is fitted to its eight edge points
   (:func:`fit_rhombus`, outliers dropped) measured on the luma (``diamond_luma``: linear in
   a blend of two colours, as the edge model), cut back to a plausible shape (a square sign
   facing the road: ``diamond_tall_max``, ``diamond_wide_max``), and refined boxes are given
   in whole pixels,
   the pixels the measured outline covers more than half, as box labels are drawn
   (``pixel_boxes``).  A blob that passes no test is judged again at higher likelihood
   levels (``peel``): a sign merged with a surface of nearly its colour, an orange dusk
   sky or a brick wall, is where the likelihood is clearly higher; two blobs that are the
   pieces of one diamond cut by its symbol are measured as one (``merge_fragments``).  When
   no start from the mask refines (a sign merged with an orange dusk sky: the mask's diamond
   is the union's, and an about square union's hull is a rectangle's), the face diamond is
   searched in the brightness itself (``diamond_search``, :func:`diamond_starts`).  The
   confidence
   is the mode of the blob's pixels' probabilities (eq. 2: mode of g(f(x_j))).  The seed
   takes the mode over all pixels of the box; we take it over the blob's pixels, because
   on a diamond half of the box is background and the mode would be the background's.
5. The regulatory two-colour extension (seed 000): a wide orange rectangle with white rows
   under it (orange top, white bottom: R22-1, R2-1 + G20-5aP) is extended down over the
   white part; the aspect ratio selects the candidates, the white rows decide how far.
6. Non-maximum suppression; unlike the seed (which keeps the largest box) every sign in the
   frame is kept.  Each detection lists its sources: ``color``, ``lidar`` or both.  A blob
   no LiDAR candidate supports keeps its own confidence (the LiDAR misses signs too); a
   supported one is raised by noisy-OR with ``lidar_confidence``; a LiDAR ROI with no
   colour blob is examined at full resolution and reported as a ``lidar``-only detection
   (``lidar_only``) when it holds a sign-coloured region of plausible size and shape.

Alternatives, selectable with ``method``:

- ``rgb_lp`` (seed 002, "Color-based Candidate Detection"): the OR of linear RGB thresholds
  alpha R + beta G + lambda B >= t (eq. 1), the subset chosen by a Boolean linear program
  minimising FP + w FN (eq. 2, ``scipy.optimize.milp``), pixels grouped by MSER.
- ``hsv`` (seed 004, section 3.4.2): fixed HSV ranges, erosion then dilation, aspect-ratio
  and fill-ratio filters.
"""
from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Optional, Sequence

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.special import ndtr

from workzone_ros.core.color_model import (
    HSV_RANGES,
    ColorModel,
    ModelError,
    SpatialPrior,
    _quantile,
    apply_gains,
    saturation_gain,
    saturation_table,
)
from workzone_ros.core.kernels import (
    NO_PIXEL,
    diamond_tent,
    edge_choice,
    flat_take,
    hue_sat_take,
    label_at_first_pixel,
    profile_medians,
    rhombus_fit,
    tip_pixel,
)
from workzone_ros.core.signs import CATALOGUE
from workzone_ros.interfaces import Box, Detection, Roi

# height / width of the catalogue's orange-top, white-bottom signs (R22-1, R2-1 + G20-5aP)
_TWO_COLOUR_RATIOS = tuple(sorted({c.height_m / c.width_m for c in CATALOGUE
                                   if c.regulatory_two_color}))


def _ratio_error(heights: np.ndarray, width: float) -> np.ndarray:
    """Per height: the relative difference of ``height / width`` to the nearest two-colour
    sign's height / width in the catalogue."""
    return np.min(np.abs(np.asarray(heights, float)[:, None] / width
                         / np.array(_TWO_COLOUR_RATIOS)[None, :] - 1.0), axis=1)


__all__ = [
    'METHODS', 'DetectorConfig', 'Candidate', 'ColorDetector', 'RgbLpModel',
    'candidate_rgb_thresholds', 'fit_rgb_lp', 'rgb_histograms', 'nms', 'box_metrics',
    'dominant_color', 'estimate_horizon', 'relative_measure', 'open_background_rows',
]

METHODS = ('learned', 'rgb_lp', 'hsv')
_P_SCALE = 254.0          # probabilities as uint8 0..254; a threshold of 255 never passes


@dataclass(frozen=True)
class DetectorConfig:
    """Detector parameters (the node's parameters of the same names).

    Attributes:
        method: ``learned`` (seed 000), ``rgb_lp`` (seed 002) or ``hsv`` (seed 004).
        colors: colours to detect: ``orange`` (work zone), ``red``, ``yellow`` (general).
        threshold: posterior threshold tau.
        scale: the mask is computed on the image downscaled by this integer factor.
        use_prior: multiply by the spatial prior and evaluate only its ROI.
        open_px, close_px: opening (erosion then dilation) and closing kernel sizes at the
            mask's resolution (0 disables).
        min_radius_px, max_radius_px: radius filter in full-resolution pixels.
        thin_min_radius_px: an orange blob under ``min_radius_px`` in half-height but not
            in half-width, at least ``ext_min_aspect`` wide and ``thin_min_radius_px`` in
            half-height, is kept when the two-colour extension finds its white part below
            it: the orange part of a small two-colour sign (16-20 px wide: 5-7 px of
            orange) is thinner than the radius filter.  0: off.  Tuning: regulatory found
            0.641 -> 0.770, Table I regulatory recall 0.955 -> 0.947 (small signs' boxes
            are less exact), false detections per frame 0.0849 -> 0.0852.
        min_area_px: smallest blob area at full resolution.
        min_hull_fill: smallest convex-hull area / box area (rejects thin, ragged blobs).
        max_aspect: largest w/h or h/w of an orange blob.
        diamond_hull_fill: below this hull fill an orange blob is a diamond (warning sign).
        refine: refine boxes at full resolution.
        border_scale: extra (w, h) factors applied to every orange box (1 = none; the border
            is handled by ``border_frac``).
        use_geometry: reject orange blobs whose bottom edge lies lower than the training
            signs' (model extra ``geometry``: reference row as a fraction of the image
            height, largest (bottom - row) / height seen in training plus a margin; trained
            on renders with portable-stand signs it allows low signs).  A third entry is the
            soft limit (the usual mounting): a blob lower than it passes only as a clear
            diamond face (solidity >= ``low_min_solidity``, hull fill below
            ``diamond_hull_fill``, aspect within ``low_max_aspect``).  Applies to
            colour-only blobs; lifted inside LiDAR ROIs.
        smooth_px: box filter on the likelihood at the mask's resolution before thresholding.
        v_hysteresis: a second brightness gate at this share of the model's ``v_min``: the
            pixels of the colour between the two join blobs they connect, within those
            blobs' box (:func:`_hysteresis`); they never make a blob nor grow a single one
            (0: off).  An under-exposed small plaque (sunny exposure dips to 0.5-0.7) lost
            half its pixels to the gate where its legend darkens them, and its fragments
            vanished in the mask's opening (stop 23: 116xx regulatory signs found 0.625 ->
            0.789 of their frames, warning 0.870 -> 0.897; false detections per frame
            0.236 -> 0.213).
        grow_level, grow_reach, grow_min_px: an orange blob that passes no test is measured
            once more grown into the pixels connected to it whose (smoothed) likelihood is
            at least ``grow_level`` x the posterior threshold, no further than
            ``grow_reach`` x its larger side beyond its box (:meth:`ColorDetector._grown`);
            the grown blob is kept only as a warning diamond whose edges the brightness
            confirms (a refined one, not the chroma fit's). On another camera's frames the
            threshold is 0.97 (``foreign_prior``): part of a real diamond's face (paler
            under the sky, or darker) lies at 0.85-0.95, the rest is a pentagon or a cut
            square that no test takes (stop 24: charlotte's sign found on 0.588 -> 0.711 of
            its frames, its false detections unchanged; denver's 9 new ones are a flagger's
            SLOW paddle, an orange diamond; the seven synthetic sets' Table I unchanged).
            ``grow_min_px``: the grown blob's shorter side (full resolution) at least this
            (distant orange truck rears in haze, 13-20 px, came out as diamonds). The
            growth must make the box 1.4 x larger (a rim is no missing part of the face;
            measuring rims cost 0.8 ms on a bench frame). ``grow_level`` 0: off.
        close_frac: closing kernel at full resolution as a fraction of the blob's size
            (bridges the black border line and legend strokes that split a face).
        weak_threshold: hysteresis: pixels of at least this likelihood next to a blob join it
            at full resolution (the blended outer margin, shaded parts).
        clip_grow: and so do such pixels connected to the blob's core through pixels whose
            red the camera clipped (:func:`_clipped_growth`; the part at most ``1 +
            clip_grow`` times the core's width and height): a sunlit plaque whose face reads
            yellowish (its red clipped at 255, the true hue lower) was rated 0.4 by the
            table next to a 0.98 core along its legend and boxed to the core, 4-6 px short
            of a side (seed 13003).  Stop 29, on 120 bags 120xx-131xx: 24 regulatory records
            changed (5 signs newly found), P / R summed over them +1.0 / +0.9; 21 warning
            records (3 newly found), -0.4 / +0.8.  Real clips: charlotte (sunlit signs)
            0.753 -> 0.814 of the sign's frames, denver 0.917 -> 0.907, false detections
            per frame unchanged within 0.02.  0.5 and 1 changed the same records on the
            bags; 0.5, 1 and 2 gave the same on the real clips.  0: off.
        border_frac: the part of a sign outside its orange hull as a fraction of the sign's
            size (MUTCD borders are a fixed fraction of the size; our art: 3.5 % orange
            margin + 3 % black line, the margin blending into the background).  When the
            ring just outside the orange hull is dark enough (``border_dark``), the hull's
            box grows by this fraction of its size on every side.
        diamond_trim: a blob that is not wide (w/h below ``ext_min_aspect``) and whose rows
            mostly follow a fitted diamond (:func:`fit_diamond`) loses the rows more than
            ``0.5 + diamond_trim x b`` px beyond the diamond's top or bottom corner (b: its
            half-height) before its kind and box are measured: a portable stand's orange
            flags above the top corner (negative: off).  ``neck_trim``: then also the rows
            above a neck where the rows narrow from the flags to the diamond's top corner
            and widen again (:meth:`ColorDetector._neck_trim`: a face cut by its symbol,
            whose diamond fit does not find the corners; stop 20: tuning sunny warning
            found 0.942 -> 0.974, 106xx 0.927 -> 0.984).
        diamond_scale, diamond_clamp: a warning (diamond) blob's box is the box of the diamond
            fitted to its face (:func:`fit_diamond_2d`, corners extrapolated from the
            straight edges), its half-diagonals times ``diamond_scale`` (the black border
            and outer margin outside the orange, less the blend the face mask already
            takes in), but no side further out than ``diamond_clamp`` x the half-diagonal
            beyond the face's own pixels (a corner hidden behind a barrier is not
            invented); 0: the hull box grown by ``border_frac`` as for other blobs.  The
            scale applies only when the black border lies outside the fitted face:
            ``diamond_ring_test`` compares the dark share of the rings just outside and
            just inside the fitted diamond's edge (``2 border_frac a`` px wide; off: the
            hull's ``border_mode`` test decides); ``border_frac`` 0 means no border.
        diamond_refine: the warning box from the face's edges measured on the brightness
            at sub-pixel precision (:func:`refine_diamond`; the orange mask's edge is wherever the
            value gate cuts the face-to-border blend) less ``diamond_edge_bias`` px
            (``diamond_blur_bias`` when the edges' fitted blur is ``diamond_blur_sigma`` px or
            more), times ``diamond_face_ratio`` (the catalogue's sign / face half-diagonal is 1 /
            0.8876 = 1.1266 and the art is drawn so; MUTCD signs ~1.09).  The bias is a measurement
            correction plus an operating point.  On 516 refined tuning signs rendered with the art
            centred in its rectangle, boxes of 1.1266 a (no bias) are right on average on every
            side (mean side error -0.03 to +0.04 px, small and large signs alike) while the edges'
            fitted blur is under 0.9 px; blurred by 0.9 px or more (defocus, motion) the face
            measures 0.2-0.45 px further out.  Boxes right on average have precision = recall
            (0.972 / 0.974 on those signs): the issue's targets ask 0.02 more of precision (0.97 /
            0.95), and every box comes out 0.1 px smaller for it (tuning warning P / R 0.966 /
            0.970 -> 0.974 / 0.963; 0.2 and 0.5, the values before the art was centred, where they
            also made up for the labels' cut right and bottom tips: 0.978 / 0.953).  Hence 0.1 and
            0.4.  ``diamond_box_bias``: the box's half-diagonals less this much more (px),
            for the box only, after the checks that judge the measured face (stop 26): the
            labels are now the pixels the face covers more than half as the image shows
            them (``CameraRenderer._sign_edges``; before, the nearest canvas pixel's, a pixel
            off on about a quarter of an edge's rows), and with them boxes 0.1 px in had
            recall to spare and precision at the target's edge (120xx-122xx, 30 bags, warning
            P / R 0.973 / 0.968, sunny 0.969 / 0.973); 0.1 more gave 0.979 / 0.963 and every
            weather at least 0.974 / 0.959, 0.15 more 0.981 / 0.959 (winter recall 0.955),
            and with ``diamond_square_px`` 0.15 more keeps every weather at least 0.977 /
            0.960 on 120xx-123xx (fresh 124xx + 125xx: 0.979 / 0.958).  (Taken off the
            face itself, 0.25 px in all, a drawn sign whose line lies 4 px in failed
            :meth:`ColorDetector._holds` and was lost.)  No side
            more than ``refined_clamp`` x the half-diagonal + ``diamond_clamp_px``
            beyond the face's own pixels (blur eats about a pixel of a small face's mask; the
            labels are the whole sign's, and a refined outline extrapolates a tip a guardrail
            hides: 0.25 on tuning renders, recall +0.005, precision -0.002; 0.12 before;
            0.4 since stop 21: a dim winter face's mask can cover only its middle 60 %, and
            0.25 cut its refined outline's tips; warning recall +0.001 to +0.004 on tuning
            and five held-out sets, precision 0 to -0.002);
            ``cut_min_width``: a face whose rows end in a straight cut at least this share
            of the fitted diamond's width there, well above its bottom corner (a guardrail
            across a sign on a stand), has its edges measured above the cut and its
            outline's bottom unclamped (the tip below the rail is in the labels; tuning
            warning signs 60-100 % visible, sunny: recall 0.942 -> 0.961, precision 0.976
            -> 0.974; 0: off); ``tip_check``: unless the occluder reaches past the sign's
            bottom corner (a vehicle's side, :meth:`ColorDetector._tip_hidden`): then the box
            ends at it (105xx sunny warning precision 0.964 -> 0.972, recall unchanged);
            ``tip_colour``: an occluder of two tones (a vehicle's pale side over its dark
            sill) counts as reaching past the bottom too when nothing inside the outline
            below its first rows has the sign's colour (stop 20: 108xx paper_c_10808
            frames 27-29; 105xx sunny warning precision 0.972 -> 0.974, tuning unchanged);
            ``tip_min_cut``: those checks are made when the occluder hides at least this
            share of the half-height (0.25 until stop 28: a snowy guardrail hiding a
            diamond's lowest 18 % was passed over and its box ran 2-7 px below the label,
            seed 12901 frames 179-203; 0.1 on the 90 bags 120xx-128xx: warning P / R
            0.9803 / 0.9696 -> 0.9806 / 0.9692);
            ``diamond_square_px``, ``diamond_square_max``: a refined outline smaller than
            ``diamond_square_max`` (box px) whose width and height differ by at most
            ``diamond_square_px`` is taken as square, both half-diagonals their mean (stop
            26).  A far sign is seen about face on (its width foreshortened by under 1-2 %
            at 30 m and more), while each half-diagonal is measured with its own noise
            (on 40 held-out bags a small sign's box width and height errors correlate by
            0.1-0.4, each about 1 px sd): on 120xx-122xx, boxes 0.25 px in, warning P / R
            0.9806 / 0.9592 -> 0.9828 / 0.9621, every weather both up; on signs of 32 px and
            more, seen at wider angles, it cost 0.002 of both, hence the size limit
            (0 = off);
            ``diamond_bright_bias = (px, line0, line1)``: an edge stretch whose fitted
            background is brighter than the face (a grey sky, snow, a pale wall behind a
            dull sign) is taken ``px`` further out (along its normal: a square diamond's
            half-diagonals grow by sqrt(2) x as much) on a face whose border line is
            ``line0`` px wide or thinner (a sign of about 16 px), less on larger ones, not
            from ``line1`` (about 32 px): :func:`_taper` (stop 28).  Measured on the
            80 bags 120xx-127xx (warning signs under 22 px, refined, whole-pixel boxes): the
            sides were -0.06 to +0.05 px inside the labels where the background beside them
            was darker than the face and 0.20-0.44 px inside where it was brighter, in every
            weather (sunny too); signs of 35 px and more showed no such difference.  The
            catalogue art drawn over grey and blurred shows it only for signs of 14-16 px
            (0.2-0.35 px); what adds the rest in the renders is not known.  With 0.3: warning
            P / R 0.9816 / 0.9659 -> 0.9798 / 0.9693 (winter 0.9834 / 0.9628 -> 0.9786 /
            0.9726, rain 0.9837 / 0.9604 -> 0.9806 / 0.9665), signs found 0.864 -> 0.867;
            0.5 gave 0.9779 / 0.9707 (rain P 0.9757).  (0, ...): off;
            ``cut_blend_rows``: the occluder may begin this many rows after the cut when
            the cut's row is a blend of face and occluder (blur, chroma bleed): the box
            ends at the first row that is across (stop 26; 0: at the cut, as before);
            ``diamond_stroke_steps``: an edge stretch fitted with a blur this many steps
            of the edge model's grid wider than the sign's other stretches is a legend
            stroke running into the edge and is left out (:func:`refine_diamond`'s
            ``stroke_steps``; stop 21: lane-ends diamonds came out 0.6 px short, 0.4 with
            it; tuning warning P / R 0.978 / 0.961 -> 0.978 / 0.962, 106xx 0.980 / 0.954
            -> 0.980 / 0.957; 0 = off);
            ``diamond_luma``: the edges measured on the luma, not the HSV value (the max of
            B, G, R is not linear in a blend of the orange margin and a background brighter
            in another channel, a blue sky: with blur the face came out up to 0.8 px larger
            against a bright background than against a dark one);
            ``diamond_border_rel`` / ``diamond_margin_rel``: the border line's width and the
            outer margin normal to the edge, in face half-diagonals.  The measured face may
            differ from the mask's diamond by up to ``diamond_max_change`` (the mask's
            corners are extrapolated from its rows and often 15-40 % off on small signs
            with a big symbol), but the catalogue's outline must then hold the orange
            pixels (:func:`diamond_holds`, ``diamond_hold`` of them in at least two of
            the four quadrants): a sign whose orange reaches beyond it all round has its
            line further in than the catalogue's and is not measured so, unless the orange
            left out is not the face's own (``hold_sat``: fewer than half of those pixels,
            and of the ring just beyond the outline on every side, as saturated as
            ``hold_sat`` x the face's median and not dark; a dusk or rain background
            blended with the sign's edge; 0 = off; :meth:`ColorDetector._holds`).  When an
            edge shows no face-to-border step, or the check fails, the mask fit
            (``diamond_scale``) is used.  Starts: the mask's diamond, the hull box's, the
            rows' own, then the hull's box grown by each of ``diamond_grown_starts`` (a
            faded or rain-washed face whose mask, or a peeled core,
            :meth:`ColorDetector._peel`, covers less than the face; on a whole blob such a
            fit needs ``search_min_contrast``).
        rect_refine: a regulatory (rectangular) blob's box from its orange part's left,
            right and top edges measured on the brightness (:func:`refine_rectangle`), moved
            out by the border line and margin (``rect_border_rel`` + ``rect_margin_rel`` of
            the sign's shorter side, the width of a two-colour sign); its bottom (the
            extension's) is kept.  When an edge shows no face-to-border step the hull box
            grown by ``border_frac`` is used.  ``rect_edge_bias``: each measured edge moves
            in by this (px): with none the boxes of clear (sunny) tuning signs come out
            0.2-0.3 px too large on every side (winter signs' 0.5-1 px too small: most
            of them were turned, see ``rect_lean``).  0.2 with ``rect_lean`` (stop 20; 0.15
            at stop 19): tuning regulatory P / R 0.976 / 0.963 at 0.15, 0.979 / 0.959 at
            0.2, 0.982 / 0.955 at 0.25; 105xx / 106xx 0.966 / 0.969, 0.970 / 0.974 at 0.15,
            0.968 / 0.965, 0.973 / 0.971 at 0.2 (precision is the target these miss).
            Since stop 28 0.25, with ``rect_dim_bias = (px, v0, v1)``: the sides and top of
            a plaque whose median brightness (V) is ``v0`` or less move in ``px`` less, none
            less from ``v1`` (linear between).  On the 80 bags 120xx-127xx the measured
            sides lay further in the dimmer the plaque, in every weather: 0.38 px inside
            the labels at V under 90, 0.22 at 90-120, 0.09 at 120-150, -0.05 at 150-180,
            -0.12 to -0.17 above (sunny alone: 0.41 under 90, -0.17 above 210), so rain,
            dusk and winter signs (dim plaques) were boxed 0.2-0.35 px inside on each
            side and sunny ones not.  Halving a sunny frame's brightness moved its signs'
            sides 0.26-0.27 px in (the fit itself is unchanged by a scale: the colour hull
            it starts from shrinks); desaturating it (0.6) moved them 0.14-0.31 px.  The
            trend is 0.43 px over V 80-170; 0.3 of it is taken (the rest left to the
            operating point).  Regulatory P / R 0.9776 / 0.9648 -> 0.9756 / 0.9694 (rain
            recall 0.949 -> 0.957, dusk 0.955 -> 0.962; 0.4 with 0.3: 0.9768 / 0.9683,
            dusk precision 0.974 either way).  (0, ...): off.
            ``rect_white_span``: the fit is made again on a two-colour sign's white part's
            columns (the longest run of columns white in 0.3 of the upper half's white
            rows, at least 0.6 of the blob's width) when it fails or measures a face wider
            than them by 2 px and 10 % while the blob is that much wider too (the blob took
            in a surface of its colour beside the plaque, a dusk sky: the plaque's edges lay
            past the search, or the blob's were measured), or measures a face that much
            narrower (a side taken at the plaque's legend strokes; kept only when the new
            face's width is nearer the white part's).  Stop 23: such signs kept the blob's
            grown box, up to 9 px too wide, or were cut 6-8 px at one side.
            ``rect_max_change``: the measured face's width may differ from the hull's by
            this share (0.2 before: small dusk signs whose hull took in 1.5-3 px of a sky
            of their colour were left at the hull's grown box, precision ~0.8; 105xx /
            106xx regulatory precision 0.963 / 0.968 -> 0.965 / 0.974).  A side
            whose profiles would leave the image (a sign at its edge) keeps the hull's and
            the box is clipped to the image; a side of the orange part without a step is
            measured on the white part below it (:func:`refine_rectangle`).
            ``rect_inward``: when the fit fails on both starts (the hull, the white part's
            columns) of a two-colour sign, a side with no step is looked for again with its
            stretches moved in by each of these (px; :func:`refine_rectangle`'s
            ``inward``), first from the hull, then from the white part's columns (with
            ``rect_white_span``): a pale
            wall right beside the sign (rain) passes for orange next to the plaque and for
            white next to the white part, so both starts' sides lay on the wall and the
            sign's edge inside the search's inner end; the box was the hull's grown, up to
            8 px too wide.  Kept only when the sign's height / width is a catalogue
            two-colour sign's within ``ext_ratio_tol`` and its white part (by its own
            level, :func:`white_beyond`) does not run on past either side (a narrow hull,
            short of a clipped plaque's yellowish side, moved in onto the legend).  Stop
            29: on 120 bags 120xx-131xx 14 regulatory records changed, all 14 more
            precise, regulatory P / R 0.9743 / 0.9700 -> 0.9751 / 0.9703; without the two
            checks 22 changed, 5 boxed 6-9 px narrow.  (): off.
            ``rect_clip_bias``: the sides and top move in by this (px) times the share of
            the plaque's pixels whose brightness the camera clipped (250 or more), the
            bottom by it times that share of the white part's lower rows (20-80 % of the
            width): a clipped face's true level is above 255, so the half level of its
            blurred edge lies further in than the clipped profile shows.  Stop 29, on 120
            bags 120xx-131xx (records of the build before it): the bottom lay -0.08 px
            (outward positive) from the label where the white part was not clipped, +0.13
            at a clipped share of 0.2-0.5 and +0.28 at 0.5-0.8; the top +0.30 and the sides
            +0.12 to +0.15 where half the plaque or more was clipped.  All sunny: sunny
            regulatory P / R 0.9738 / 0.9785 -> 0.9769 / 0.9746 (0.5: 0.9787 / 0.9710);
            every other weather within 0.0005.  It trades recall for precision (P + R
            -0.0008): the targets ask 0.97 / 0.95, and this brings sunny's two margins
            nearer each other.  0: off.
        rect_needs_edges: a regulatory blob that is not a two-colour sign (no white part
            found below it), whose rectangle shows no face-to-border step
            (:func:`refine_rectangle` fails) and in which the diamond search finds no face,
            is dropped (LiDAR-supported blobs excepted): a patch of something orange
            (dirt, a cone, a worker's vest, a brick wall, a turn lamp).  Stop 22: on the
            real clips such blobs were 632 of the 902 false detections (charlotte 399 of
            517, denver 233 of 385); on the 18 tuning bags 289 of 585 false candidates and
            4 of 1110 matched signs of 16 px or more (30 smaller or part-hidden ones).
            Tuning false detections per frame 0.351 -> 0.204 (105xx / 106xx 0.487 ->
            0.304), Table I the same or better (a dropped blob had sometimes swallowed a
            sign the peel now finds: warning found +0.03 on 113xx and 115xx); real clips
            1.25 / 1.79 -> 0.29 / 0.71, but charlotte's sign, which its blob merges with the
            ground or a trailer's mesh for a third of its frames, is detected in 0.588 of
            its frames instead of 0.835 (denver 0.944 -> 0.917).  False: the hull box grown
            by ``border_frac``, as before.
        white_ends: a measured two-colour sign whose white part runs on past its sides
            and ends (its border) within half the box's width is widened to it, when the
            orange part's colour runs on above the new columns too (:func:`white_part_ends`,
            :meth:`ColorDetector._white_ends`): a dim winter plaque cut by its legend into
            pieces, only one of which became a blob, was boxed to that piece (105xx / 106xx
            winter regulatory recall 0.937 / 0.953 -> 0.948 / 0.958, tuning unchanged;
            without the colour check two signs were widened over a pale background).
        rect_lean, rect_lean_min, rect_lean_agree: a measured two-colour sign's left and
            right edges are measured again over the upper and lower quarters of its face
            (:func:`rectangle_lean`); when both lean alike (slopes of one sign, within
            ``rect_lean_agree`` of each other, their mean at least ``rect_lean_min``
            (dx / dy)) the box becomes the bounding box of the face so turned
            (:meth:`ColorDetector._lean`): a sign on a leaning post (the simulator turns
            a quarter of its signs by up to 3 degrees in their plane).  The face measured
            in the middle left such boxes 1-2 px short: on the 18 tuning bags, regulatory
            signs turned 1.5-3 degrees had recall 0.90 (upright 0.97; 51 of the 72
            winter regulatory matches are of turned signs: winter recall 0.918).
        peel, peel_gap, peel_levels, peel_clamp: a blob that passes no test is judged again
            at higher likelihood levels (:meth:`ColorDetector._peel`): a sign merged with a
            surface of nearly its colour (an orange dusk sky, a brick wall) is where the
            likelihood is clearly higher.  Levels at least ``peel_gap`` above the blob's
            median: Otsu's over its pixels, then ``peel_levels``; the first that gives
            candidates wins; no hysteresis back into the surface; a warning box may reach
            ``peel_clamp`` x the half-diagonal beyond the core (``diamond_clamp``
            otherwise).  At most ``peel_max`` blobs per frame, the largest first.
        blur_px_growth: a box left at its hull grows by the blur rings
            (:meth:`ColorDetector._border_growth`: 1-px rings outside the hull that still
            look like the sign's colour) in pixels on every side; off: by the rings as a
            share of the hull's shorter side times each side's length (the behaviour before
            stop 19), which grew a wide plaque's width by its aspect times the blur, and the
            two-colour extension then judged a strip twice the sign's width (tuning
            regulatory found 0.770 -> 0.791, dusk 0.833 -> 0.872, P / R 0.978 / 0.950 ->
            0.979 / 0.952).
        merge_fragments, merge_max: two blobs (of the ``merge_max`` largest) that lie
            next to each other inside an about square joint box are measured as one when a
            symbol cuts a diamond's face from edge to edge
            (:meth:`ColorDetector._merge_fragments`); the pieces give way when that makes a
            refined warning diamond.  ``merge_triples``: then three blobs the same way, small
            refined diamonds among them when the joint diamond holds them all (a bold legend
            in rain light cuts a face into three; 106xx rain warning P / R 0.965 / 0.886 ->
            0.978 / 0.926, the tuning bags unchanged).
        diamond_search, search_min_px, search_min_share, search_min_contrast: when no
            start from the mask
            refines, a blob at least ``search_min_px`` on its shorter side (a warning, or
            a blob the hull took for a rectangle when neither the two-colour extension nor
            the rectangle refinement measured it) is searched for a face
            diamond with a dark line round it in the brightness (:func:`diamond_starts`:
            box sums over a copy turned by 45 deg, where the diamond is a square); the best
            starts are refined, and a result is kept when the orange its outline leaves out
            is not the face's own (:meth:`ColorDetector._holds`, ``hold_sat``), its face
            lies inside the blob's box and it is at least ``search_min_share`` of the blob's
            shorter side (a sign merged with an orange dusk sky or a rusty wall: the blob is
            the union);
            its edges must show a clear line (``search_min_contrast`` of the face, 0.5: the
            sign's outer edge against dark asphalt, 0.37 in a test, is no face's edge).
        shift_min_px: when nothing above (nor the chroma fit, ``blur_fit``) measures a
            warning blob at least this large (its shorter side, full resolution), its
            mask's starts are refined again moved by 2.25 px in the eight directions
            (:func:`refine_shifted`; the smallest fit the face holds is kept): the edges'
            search reaches only a few pixels, and a large real diamond whose mask took in a
            surface of its colour beside it (a lawn, a house front) starts 3-5 px off.  A
            blob the frame's edge cuts keeps a fit only if the sign's diamond reaches past
            that edge (a smaller whole diamond inside the frame fitted a cut sign's part).
            Stop 25: see the README.  0: off.
        blur_fit, blur_fit_ratio, blur_fit_bias, blur_fit_max_sigma: when neither a start
            nor the search refines (a faded, rain-washed or blurred sign: no border line
            shows in the brightness, the mask stops short of the tips), the sign's diamond
            is fitted to the chroma R - B (:func:`fit_blurred_diamond`: a blurred diamond
            over a background plane, its blur up to ``blur_fit_max_sigma`` px); the sign is
            that diamond x ``blur_fit_ratio`` less ``blur_fit_bias`` px (the line and margin
            blend into the fitted edge), kept when its centre lies inside the blob's box and
            it is no smaller than that box (a pixel a side).
        diamond_tall_max, diamond_wide_max: the plausible shape of a measured face: a
            square sign facing the road is as tall as wide in the image, taller when turned
            away (1 / cos of the yaw: 1.08 at 22 deg), and wider only by a little roll, pitch
            or lens distortion (the tuning labels' width / height: 99 % up to 1.06).  A
            refined face taller than ``diamond_tall_max`` x its width (a frame blurred by
            the car's vertical motion stretches a small sign's edges apart; on the tuning
            renders 54 of 518 refined signs came out 3 px or more taller than wide, 22 of
            the labels are) or wider than ``diamond_wide_max`` x its height is cut back to
            it about its centre; so is the chroma fit's diamond.  Tuning warning precision /
            recall 0.9727 / 0.9615 -> 0.9783 / 0.9587 (refined faces alone: 0.9770 /
            0.9593), a better trade than a larger edge bias (0.3 px: 0.9776 / 0.9532);
            1.08 / 1.03 on refined faces gave 0.9783 / 0.9583, 1.12 / 1.06 0.9758 / 0.9598.
        rim_chroma: a refined outline that holds all of its blob's orange is rejected when
            the chroma R - B of the ring 0.5-1.5 px beyond the sign's outline is on average
            more than this share of the way from the background's (3-6 px beyond) to the
            face's: the outline lies inside a faded sign whose mask stops short (a legend's
            edge taken for the line); a correct outline reaches ~0.3 only under 2 px of
            blur.  0 = off.
        pixel_boxes: refined boxes (diamond and rectangle) in whole pixels: the pixels the
            measured outline covers more than half (:func:`pixel_box`,
            :func:`diamond_pixel_box`), as box labels are drawn; on average no further off
            than the sub-pixel box, and equal to the label when the measurement is right to
            a fraction of a pixel.
        border_dark: share of dark pixels in the ring outside the hull that means "border
            line outside" (0: compare with the band just inside the hull instead).
        border_mode: ``profile`` (per blob, see ``_border_growth``) or ``always`` (grow by
            ``border_frac`` whatever the blob looks like; the previous behaviour).
        blur_like, blur_max_frac: the soft edge: 1-px rings outside the hull whose mean
            likelihood is at least ``blur_like`` are added (at most ``blur_max_frac`` of
            the size + 2).
        min_solidity: smallest orange pixels / convex-hull area of an orange blob.
        min_dark_inside: smallest share of dark (legend, border) pixels inside the hull of an
            orange blob of at least ``structure_min_px`` (sign faces carry a legend; sky
            patches, drums, vehicle panels mostly do not).
        outline_evidence: a warning blob that fails the legend test, or (below the usual
            mounting height) the clear-diamond test, is still kept when its diamond outline
            is measured in the brightness (:func:`refine_diamond`, the search).  A faded,
            rain-washed or blurred legend loses its dark pixels first (on the tuning renders
            85 of 727 eligible warning signs, clear diamonds among them, had a dark share
            below 0.02: 25 at dusk, 27 in rain, 33 in winter), and a portable stand's face
            behind a guardrail is no clear diamond to the mask; a patch of dusk sky, a
            vehicle's panel, a drum or a cone has no diamond's edges.  Without a measured
            outline (no refinement, or only the chroma fit) such a blob is rejected as
            before, and a sign merged with a surface is still peeled out of it.
        white_part_evidence: a two-colour plaque that fails the legend test (its legend grey,
            not dark, in dim winter light) is still kept when the extension finds its white
            part below (black legend, a bottom edge: :meth:`ColorDetector._extend`); without
            one it is dropped as before.  Not below the usual mounting height (a drum's
            orange and white bands).  ``white_part_level``: and the white part at least this
            many times as bright as the orange (retro-reflective white sheeting is brighter
            than the fluorescent orange in every light; on the real clips a patch of orange
            dirt over a car's grey hood passed for a plaque with its white part).
        dark_rel: dark = value below this fraction of the blob's median orange value.
        band_test: reject an orange blob of at least ``band_min_px`` (height) that a white
            band separates from more orange above or below it, or that holds one
            (:func:`banded_rows`: the retro-reflective bands of traffic cones and drums,
            MUTCD 6F.63 / 6F.64; a sign face has none).  Not inside LiDAR ROIs.  White:
            saturation at most ``white_s_max`` and luma at least ``band_white_luma`` x the
            blob's median luma (white sheeting is brighter than orange under the same light;
            orange (255, 120, 20) has luma 149, white sheeting about 240).  A blob at least as
            tall as wide whose :func:`row_taper` is at most ``cone_taper`` (widening
            downward like a cone) and that a white band caps (:func:`white_cap`) is rejected
            too.  A band (and a cap) has at least ``band_min_rows`` x the blob's height
            (at least 2) white rows.
        max_surround_like, min_surround_face, surround_in, surround_out: reject an orange
            blob whose surroundings (the ring ``surround_in`` .. ``surround_out`` x its size
            outside its hull, beyond the border and blur) have a mean colour likelihood
            above ``max_surround_like`` and more than ``min_surround_face`` of their pixels
            at the blob's own threshold: the surface around it is more sign-coloured than
            not and carries the face's colour, the blob is a patch of it (dirt piles, brick,
            vehicle panels), not an object on its own.  A sign in front of a warm wall
            (likely, but below the face's level) is kept.  Limit: a fragment of a sign
            split by an occluder has the rest of the face in its ring.  1: off.  Not inside
            LiDAR ROIs.
        structure_min_px: blobs smaller than this (shorter side) skip the legend test.
        nms_iou: boxes overlapping a larger kept box by more than this IoU are suppressed;
            a box lying mostly (``nms_contain``) inside a larger one too.
        extension: regulatory two-colour extension on/off.
        ext_min_aspect: an orange rectangle at least this wide (w/h) is examined for a
            white bottom.
        ext_max_ratio: the extension adds at most this many times the orange height.
        white_s_max, white_v_rel: a pixel is white if S <= white_s_max and V >= white_v_rel x
            the orange blob's median V.
        white_own_rel: and, once the white part's own level is known (the median V of the
            white pixels in its first rows, under the orange part), V >= white_own_rel x that
            level: under a grey sky a dull orange's V is little above a grey background's
            (road, verge, snow), which then passed for the white part and ran the
            extension on past the sign; retroreflective white sheeting is far brighter.
            0 turns it off.
        ext_min_dark: smallest share of dark (legend, border) pixels in the white part; the
            white part must also end (a bottom edge) within its reach.
        ext_max_wratio: the extension may also reach this many times the orange width
            (a thin orange plaque over a tall white sign: R2-1 + G20-5aP is 1.75 w high).
        ext_frame: when the white runs to the end of the reach (snow, a pale sky or wall
            behind the sign continue it), end it at its black bottom border
            (``_bottom_border``): a row at least ``ext_border_share`` dark; of several, the
            one that gives the sign the height / width of a catalogue two-colour sign
            (within ``ext_ratio_tol``; a bold legend row of a small sign looks like a
            border too), else the first.  A dark band's last row is a candidate and, when
            the band is at least ``ext_band_long`` orange heights long (a background darker
            than the sheeting that the border line merges with: a grey wall behind a dim
            winter sign), its first row too.  ``ext_rechoose``: the choice is made again
            with the sign's measured top and width once the orange part's edges are
            measured (the blob of a dim winter sign is narrower than the sign, and by its
            width a "BEGINS" row made the better shape; stop 21).
        ext_overlong: when the white ends before the reach but is taller than any
            catalogue two-colour sign by more than this share of its height / width (a pale
            wall right behind the sign, in rain as bright as white by the orange's level,
            continued the white part past its black bottom border, which the legend-gap
            rule bridged), it ends after the bridged row (under 45 % white) that gives the
            height nearest a catalogue sign's, when that is within this share too (stop
            28; 0: off).  0.24, twice ``ext_ratio_tol``: the box is still grown by the blur
            here, and turned signs (narrower) are taller than the catalogue by up to 0.12:
            with 0.12, 14 records changed on 120xx-128xx, turned signs cut at a legend row
            among them (net worse).  On those
            90 bags 7 records changed (6 better), regulatory 0.9761 / 0.9696 -> 0.9763 /
            0.9699, rain 0.9759 / 0.9572 -> 0.9776 / 0.9577 (found 0.832 -> 0.852); on 130xx,
            where two such speed limits were boxed 32 px too tall, rain precision 0.931 ->
            0.945.
            ``ext_overlong_border``: and when no bridged row gives such a height, the row
            after a dark band (at least this share of the strip's middle columns below
            ``ext_border_rel`` x its 90th percentile of brightness, as
            :meth:`_bottom_border` looks for the border) that does, within
            ``ext_overlong``: a dim plaque's white threshold is low enough that the black
            bottom border, a blurred pixel wide, passed for white and no row was bridged.
            0.75 (the border test's own 0.9 missed a border row at 0.89).  Stop 29: on 120
            bags 4 regulatory records changed, 3 more precise (a 75 px box on a 43 px sign
            among them), one 4 px short.  0: off.
        ext_gap_w, ext_gap_s: rows of a large black legend inside the white part (median
            saturation at most ``ext_gap_s``: achromatic like the sheeting) may separate
            white rows by up to ``ext_gap_w`` x the width.
        ext_gap_cols: rows that look coloured across the strip are judged again on the white
            part's own columns (those white in its white rows before the gap), bright against
            the sheeting's level rather than the orange's: a dusk blob may be wider than the
            sign (the background beside it is of its colour) and the dim numerals' noisy
            pixels passed for bright; after such a gap a single white row (the strip under
            the numerals, too short for the running window) continues the white part
            (stop 23: curve_dusk speed limits ended at their numerals, 7-9 px short).
        roi_prior, roi_threshold, roi_margin: LiDAR ROIs: prior and posterior threshold
            inside them, and the fraction of their size added around them.
        roi_relax: inside an ROI the hull-fill and solidity minima are multiplied (and the
            aspect maximum divided) by this; the legend and mounting-height tests are off.
        roi_contain: a relaxed blob (and a lidar-only one) must lie at least this share
            inside its ROI, else it is judged like any other blob.
        lidar_confidence: noisy-OR weight of LiDAR support.
        lidar_only: report an ROI that no colour blob explains as a ``lidar``-only
            detection when it holds a sign-coloured region (below).
        lidar_only_threshold: likelihood of that region's pixels.
        lidar_only_min_share, lidar_only_max_share: the region's larger side as a share of
            the ROI's (the projector sizes ROIs from the candidate's radius and range).
        lidar_only_confidence: their confidence.
        geometry_reference: the row the mounting-height test measures from: ``fixed`` (the
            model's reference row, a fraction of the image height: our camera's horizon) or
            ``horizon`` (the horizon estimated from the frames' lane lines,
            :func:`estimate_horizon`, median of the last ``horizon_window`` reliable
            estimates, one every ``horizon_every`` frames, forgotten after
            ``horizon_memory`` frames; the test is off while there is no reliable
            estimate).  The model's limits are relative to the true horizon of its
            geometry renders, so ``horizon`` carries them to another camera.
        camera_match: the spatial prior's heat map and ROI and the ``fixed`` mounting-height
            row are our training camera's image rows and columns: apply them only to frames
            from that camera (:meth:`ColorModel.same_camera`: the model's frame size, or its
            normalised intrinsics when the node passes the frames' ones with
            :meth:`ColorDetector.set_camera`).  Frames of another camera get the same prior
            at every location, ``foreign_prior``, over the whole frame, and no fixed-row
            mounting test (the ``horizon`` reference still applies: it is measured on the
            frames).  False: the model's prior and row on any camera (the previous
            behaviour).
        foreign_prior: that location-free prior; 0: the model prior's mean over its ROI
            (:meth:`SpatialPrior.expected`) relative to the orange table's peak
            (:meth:`ColorDetector.foreign_prior`; default model 0.513 / 0.991: the
            posterior threshold becomes 0.97, the likelihood of the sign's own saturated
            sheeting, 0.98-0.99, not of warm mid-saturation walls, lawns and asphalt,
            0.65-0.78).
        camera_tolerance: relative tolerance of the normalised intrinsics comparison.
        general_max_aspect, general_min_fill: seed 004 filters for red / yellow blobs.
        mser_delta: MSER delta of the ``rgb_lp`` method.
    """

    method: str = 'learned'
    colors: tuple[str, ...] = ('orange', 'red', 'yellow')
    threshold: float = 0.5
    scale: int = 2
    use_prior: bool = True
    open_px: int = 2
    close_px: int = 3
    min_radius_px: float = 4.0
    thin_min_radius_px: float = 2.0
    max_radius_px: float = 240.0
    min_area_px: float = 40.0
    min_hull_fill: float = 0.35
    max_aspect: float = 4.0
    diamond_hull_fill: float = 0.72
    refine: bool = True
    border_scale: tuple[float, float] = (1.0, 1.0)
    smooth_px: int = 3
    v_hysteresis: float = 0.65
    grow_level: float = 0.85
    grow_reach: float = 0.4
    grow_min_px: float = 20.0
    use_geometry: bool = True
    low_min_solidity: float = 0.85
    low_max_aspect: float = 1.4
    low_min_inliers: float = 0.7
    close_frac: float = 0.12
    weak_threshold: float = 0.3
    clip_grow: float = 0.5
    border_frac: float = 0.04
    diamond_trim: float = 0.0
    neck_trim: bool = True
    diamond_scale: float = 1.07
    diamond_clamp: float = 0.12
    refined_clamp: float = 0.4
    cut_min_width: float = 0.5
    tip_check: bool = True
    tip_colour: bool = True
    tip_min_cut: float = 0.1
    cut_blend_rows: int = 1
    diamond_square_px: float = 2.5
    diamond_square_max: float = 32.0
    diamond_grown_starts: tuple = (1.2, 1.4)
    diamond_ring_test: bool = True
    diamond_refine: bool = True
    diamond_face_ratio: float = 1.1266
    diamond_edge_bias: float = 0.1
    diamond_box_bias: float = 0.15
    diamond_blur_bias: float = 0.4
    diamond_blur_sigma: float = 1.0
    diamond_bright_bias: tuple = (0.3, 0.47, 0.95)
    diamond_tall_max: float = 1.08
    diamond_wide_max: float = 1.06
    diamond_luma: bool = True
    diamond_clamp_px: float = 1.0
    diamond_border_rel: float = 0.0676
    diamond_margin_rel: float = 0.022
    diamond_max_change: float = 0.4
    diamond_stroke_steps: int = 2
    diamond_hold: float = 0.97
    hold_sat: float = 0.85
    diamond_search: bool = True
    shift_min_px: float = 40.0
    search_min_px: float = 12.0
    search_min_share: float = 0.6
    search_min_contrast: float = 0.5
    blur_fit: bool = True
    blur_fit_ratio: float = 1.06
    blur_fit_bias: float = 0.25
    blur_fit_max_sigma: float = 4.0
    rim_chroma: float = 0.35
    rect_refine: bool = True
    rect_needs_edges: bool = True
    rect_edge_bias: float = 0.25
    rect_dim_bias: tuple = (0.3, 80.0, 170.0)
    blur_px_growth: bool = True
    rect_max_change: float = 0.3
    rect_white_span: bool = True
    rect_inward: tuple = (1.5, 3.0)
    rect_clip_bias: float = 0.3
    rect_lean: bool = True
    rect_lean_min: float = 0.025
    rect_lean_agree: float = 0.05
    white_ends: bool = True
    rect_border_rel: float = 0.03
    rect_margin_rel: float = 0.015
    pixel_boxes: bool = True
    peel: bool = True
    peel_gap: float = 0.08
    peel_levels: tuple = (0.8, 0.9)
    peel_clamp: float = 0.3
    peel_max: int = 2
    merge_fragments: bool = True
    merge_max: int = 6
    merge_triples: bool = True
    ext_ratio_tol: float = 0.12
    ext_overlong: float = 0.24
    ext_overlong_border: float = 0.75
    ext_rechoose: bool = True
    ext_band_long: float = 0.5
    border_dark: float = 0.0
    border_mode: str = 'profile'
    blur_like: float = 0.08
    blur_max_frac: float = 0.15
    min_solidity: float = 0.45
    min_dark_inside: float = 0.02
    outline_evidence: bool = True
    white_part_evidence: bool = True
    white_part_level: float = 1.1
    band_test: bool = True
    band_min_px: float = 6.0
    band_white_luma: float = 1.25
    band_min_rows: float = 0.12
    cone_taper: float = 0.88
    max_surround_like: float = 0.5
    surround_in: float = 0.1
    min_surround_face: float = 0.05
    surround_out: float = 0.2
    dark_rel: float = 0.6
    structure_min_px: float = 18.0
    nms_iou: float = 0.3
    nms_contain: float = 0.7
    extension: bool = True
    ext_min_aspect: float = 1.5
    ext_max_ratio: float = 3.5
    white_s_max: int = 45
    white_v_rel: float = 0.8
    white_own_rel: float = 0.7
    ext_min_dark: float = 0.03
    ext_max_wratio: float = 1.8
    ext_gap_w: float = 0.6
    ext_gap_s: int = 60
    ext_gap_cols: bool = True
    ext_frame: bool = True
    ext_border_share: float = 0.9
    ext_border_rel: float = 0.7
    roi_prior: float = 1.0
    roi_threshold: float = 0.3
    roi_margin: float = 0.25
    roi_relax: float = 0.75
    roi_contain: float = 0.8
    lidar_confidence: float = 0.5
    lidar_only: bool = True
    lidar_only_threshold: float = 0.25
    lidar_only_min_share: float = 0.12
    lidar_only_max_share: float = 0.9
    lidar_only_confidence: float = 0.3
    geometry_reference: str = 'fixed'
    horizon_every: int = 3
    horizon_window: int = 15
    horizon_memory: int = 90
    camera_match: bool = True
    foreign_prior: float = 0.0
    camera_tolerance: float = 0.02
    general_max_aspect: float = 1.6
    general_min_fill: float = 0.35
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
        if self.geometry_reference not in ('fixed', 'horizon'):
            raise ValueError("geometry_reference must be 'fixed' or 'horizon'")
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


@dataclass
class Candidate:
    """A blob on its way to a :class:`Detection` (full-resolution pixels)."""

    x: float
    y: float
    w: float
    h: float
    color: str
    confidence: float
    kind: str = 'unknown'
    area: float = 0.0
    hull_fill: float = 1.0
    extended: bool = False
    refined: bool = False
    chroma_fit: bool = False
    white_span: Optional[tuple[float, float]] = None
    white_level: float = 0.0        # the white part's brightness / the orange's (extended)
    sources: list[str] = field(default_factory=lambda: ['color'])
    roi_id: Optional[int] = None

    @property
    def box(self) -> Box:
        """The candidate's :class:`Box`."""
        return Box(float(self.x), float(self.y), float(self.w), float(self.h))

    def detection(self) -> Detection:
        """The candidate as an interfaces :class:`Detection`."""
        return Detection(box=self.box, confidence=float(min(max(self.confidence, 0.0), 1.0)),
                         color=self.color, kind=self.kind, sources=list(self.sources),
                         roi_id=self.roi_id)


# --- small helpers -----------------------------------------------------------------------

def _iou(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(IoU, intersection / smaller area) of two (x, y, w, h) boxes."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0, 0.0
    inter = iw * ih
    aa, ab = a[2] * a[3], b[2] * b[3]
    return inter / (aa + ab - inter), inter / max(min(aa, ab), 1e-9)


def _contained(a: Sequence[float], b: Sequence[float]) -> float:
    """Share of box ``a``'s area inside box ``b`` (both x, y, w, h)."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    return 0.0 if iw <= 0 or ih <= 0 else iw * ih / max(a[2] * a[3], 1e-9)


def nms(cands: list[Candidate], iou: float, contain: float,
        by: str = 'confidence') -> list[Candidate]:
    """Greedy non-maximum suppression; every non-overlapping box stays.

    ``by='confidence'``: most confident first (ties: larger first), so a large, weakly
    orange region (sunlit asphalt, a vehicle) does not swallow a sign inside it.
    ``by='area'``: larger first (the seed 002 MSER path, whose nested regions of one sign
    share a confidence scale with their fill).
    """
    if by == 'area':
        order = sorted(cands, key=lambda c: (c.w * c.h, c.confidence), reverse=True)
    else:
        order = sorted(cands, key=lambda c: (round(c.confidence, 2), c.w * c.h),
                       reverse=True)
    kept: list[Candidate] = []
    for c in order:
        b = (c.x, c.y, c.w, c.h)
        if all((lambda r: r[0] <= iou and r[1] <= contain)(_iou(b, (k.x, k.y, k.w, k.h)))
               for k in kept):
            kept.append(c)
    return kept


def box_metrics(det: Box, gt: Box) -> tuple[float, float, float]:
    """(IoU, area precision, area recall) of a detection against a ground-truth box.

    Seed 000, section III.A: precision = |o n g| / |o|, recall = |o n g| / |g|.
    """
    iw = min(det.x2, gt.x2) - max(det.x, gt.x)
    ih = min(det.y2, gt.y2) - max(det.y, gt.y)
    if iw <= 0 or ih <= 0:
        return 0.0, 0.0, 0.0
    inter = iw * ih
    return (inter / (det.area + gt.area - inter), inter / max(det.area, 1e-9),
            inter / max(gt.area, 1e-9))


def dominant_color(hsv: np.ndarray) -> str:
    """The main colour of an HSV patch: orange / red / yellow / green / white."""
    if hsv.size == 0:
        return 'white'
    h, s, v = (hsv[..., i].ravel().astype(np.int32) for i in range(3))
    chroma = (s >= 90) & (v >= 60)
    if chroma.mean() < 0.15:
        return 'white'
    hh = h[chroma]
    votes = {'red': np.count_nonzero((hh <= 6) | (hh >= 168)),
             'orange': np.count_nonzero((hh >= 7) & (hh <= 19)),
             'yellow': np.count_nonzero((hh >= 20) & (hh <= 34)),
             'green': np.count_nonzero((hh >= 35) & (hh <= 95))}
    return max(votes, key=votes.get)


@functools.lru_cache(maxsize=16)
def _bin_edges(dtype: np.dtype, lo: float, hi: float, bins: int) -> np.ndarray:
    """``np.histogram``'s bin edges for ``bins`` bins over ``(lo, hi)`` of ``dtype`` data."""
    edges = np.histogram_bin_edges(np.empty(0, dtype), bins=bins, range=(lo, hi))
    edges.flags.writeable = False
    return edges


def _mode(values: np.ndarray, lo: float = 0.0, hi: float = 1.0, bins: int = 20) -> float:
    """Mode of ``values`` as the centre of the fullest of ``bins`` histogram bins.

    The histogram is ``np.histogram(values, bins, (lo, hi))``'s: bin ``i`` counts the values
    in ``[edges[i], edges[i + 1])``, the last bin also those equal to ``hi``, values outside
    the range none; counted here by a binary search in its edges (np.histogram's own
    set-up costs ~0.1 ms per call).
    """
    if values.size == 0:
        return 0.0
    edges = _bin_edges(values.dtype, lo, hi, bins)
    # slot k: values in [edges[k - 1], edges[k]); slot bins + 1: at or beyond the last edge
    slots = np.bincount(np.searchsorted(edges, values, side='right'), minlength=bins + 2)
    hist = slots[1:bins + 1]
    hist[-1] += np.count_nonzero(values == edges[-1])
    i = int(np.argmax(hist))
    return float(0.5 * (edges[i] + edges[i + 1]))


def _median(values: np.ndarray, axis: Optional[int] = None) -> Any:
    """``np.median(values, axis)`` of NaN-free data, the same values, by a partial sort.

    The middle order statistic, or the mean of the middle two: in the data's own float type
    (float64 for integers), as np.median takes it; without np.median's generic machinery
    (about 10 us per call, more than the partial sort of the small arrays here).
    """
    if axis is None:
        values, axis = values.ravel(), 0
    n = values.shape[axis]
    if n == 0:
        return np.median(values, axis=axis)
    k = n // 2
    # a short axis is sorted outright (quicker than the partial sort at these lengths)
    part = np.sort(values, axis=axis) if n <= 64 else np.partition(values, (k - 1, k),
                                                                    axis=axis)
    # (the middle entries by a basic index: np.take's values, without its call overhead)
    lead = (slice(None),) * (axis % values.ndim)
    hi = part[lead + (k,)]
    lo = part[lead + (k - 1,)] if n % 2 == 0 else None
    if values.dtype.kind != 'f':
        hi = hi.astype(np.float64)
        lo = None if lo is None else lo.astype(np.float64)
    return hi if lo is None else (lo + hi) / 2


def _row_extents(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row centre, left edge, right edge) of every non-empty row of a binary mask.

    Edges in continuous coordinates (pixel ``i`` spans ``[i, i + 1)``).
    """
    m = mask > 0
    rows = np.nonzero(m.any(axis=1))[0]
    if rows.size == 0:
        return rows.astype(float), rows.astype(float), rows.astype(float)
    sub = m[rows]
    left = np.argmax(sub, axis=1).astype(float)
    right = (m.shape[1] - np.argmax(sub[:, ::-1], axis=1)).astype(float)
    return rows + 0.5, left, right


@functools.lru_cache(maxsize=8)
def _slope_grid(lo: float, hi: float) -> np.ndarray:
    """:func:`fit_diamond`'s six tent slopes from ``lo`` to ``hi`` (read-only)."""
    ss = np.linspace(lo, hi, 6)
    ss.flags.writeable = False
    return ss


def fit_diamond(mask: np.ndarray, min_rows: int = 5, slopes: tuple[float, float] = (0.7, 1.4)
                ) -> Optional[tuple[float, float, float, float, float]]:
    """Fit a diamond (axis-aligned diagonals) to a blob: ``(cx, cy, a, b, inliers)``.

    A diamond ``|x - cx| / a + |y - cy| / b <= 1`` has half-width ``a - s |y - cy|`` at
    row ``y`` (``s = a / b``): a tent over the rows, centred on ``cx`` on every row.  A
    warning sign is a square diamond facing the road, so ``s`` lies near 1 (``slopes``:
    the range allowed, for yaw and lens distortion).  The tent is found by consensus: for
    every apex row ``cy`` on a grid (half a pixel, coarser for large blobs) and slope in
    ``slopes`` the peak ``a`` is the median over (at most ~24 of) the rows, and the
    (cy, s) with the most rows within ``max(1, a/10)`` px of the tent wins; least squares
    over those rows, the apex row on a quarter-pixel grid, refines it.  An appendage of the same
    colour (a portable stand's flags above the top corner, a post) does not follow the
    tent and is left out; corners thinned by blur are extrapolated from the straight
    edges.  ``inliers``: the share of the blob's rows on the tent.  Continuous
    coordinates (pixel ``i`` spans ``[i, i + 1)``).  None: fewer than ``min_rows`` rows
    or no tent.  Computed by the compiled :func:`~workzone_ros.core.kernels.diamond_tent`
    (numpy's arithmetic, the same values); ``mask``: any 2-d array, non-zero on the blob.
    """
    m = mask if mask.dtype == np.uint8 else (mask > 0).view(np.uint8)
    out = diamond_tent(np.ascontiguousarray(m), min_rows, _slope_grid(*slopes),
                       float(slopes[0]), float(slopes[1]))
    return None if math.isnan(out[0]) else tuple(out.tolist())


def fit_diamond_2d(mask: np.ndarray, min_rows: int = 5, rows: Optional[tuple] = None
                   ) -> Optional[tuple[float, float, float, float, float]]:
    """:func:`fit_diamond` over the rows and over the columns, combined.

    Each fit measures two things well: the peak of its tent (the half-width ``a`` from
    the rows, the half-height ``b`` from the columns: many rows or columns near the
    middle agree on it) and the centre across the tent (``cx`` from the rows' midpoints,
    ``cy`` from the columns'); the apex position along the tent and the slope, from the
    few short rows near the corners, are the noisy parts and are not used.  Returns
    ``(cx, cy, a, b, inliers)`` (the smaller inlier share) or None.  ``rows``: the row
    fit of this mask when already known.
    """
    fr = rows if rows is not None else fit_diamond(mask, min_rows)
    fc = fit_diamond(np.ascontiguousarray(mask.T), min_rows)
    if fr is None or fc is None:
        return None
    return fr[0], fc[0], fr[2], fc[2], min(fr[4], fc[4])


def row_taper(mask: np.ndarray) -> float:
    """A blob's mean width over its upper rows (15-40 % of its height from the top) over its
    mean width over its lower rows (60-85 %): about 1 for a diamond or a rectangle (symmetric
    about the middle row), about 0.7-0.8 for the orange part of a traffic cone below its
    band (a truncated cone, its top about a fifth of its base: MUTCD 6F.63).  1.0 for a blob
    of fewer than 5 rows."""
    yc, left, right = _row_extents(mask)
    if yc.size < 5:
        return 1.0
    y0 = yc[0] - 0.5
    t = (yc - y0) / (yc[-1] + 0.5 - y0)
    w = right - left
    up, lo = (t >= 0.15) & (t <= 0.4), (t >= 0.6) & (t <= 0.85)
    if not (up.any() and lo.any()):
        return 1.0
    return float(w[up].mean() / max(w[lo].mean(), 1e-6))


def open_background_rows(left: np.ndarray, right: np.ndarray, min_cols: int
                         ) -> Optional[np.ndarray]:
    """Rows whose white runs on past a blob on both flanks (``left``, ``right``: the white
    masks beside it): the background (an overcast sky, snow, a wall), not a band of the
    object's own.  A flank cut by the image border (narrower than ``min_cols``) does not
    count, the other one decides (a sign leaving the frame with its stand's flags over the
    sky); None when neither flank is in the frame."""
    sides = [np.count_nonzero(m, axis=1) / m.shape[1] >= 0.5 for m in (left, right)
             if m.shape[1] >= min_cols]
    return np.logical_and.reduce(sides) if sides else None


def white_cap(white: np.ndarray, top: int, min_run: int, gap: int, min_white: float = 0.5
              ) -> bool:
    """True when at least ``min_run`` rows at least ``min_white`` white lie right above row
    ``top`` of a strip (within ``gap`` rows of it): a cone's white band over its orange
    body."""
    w = float(max(white.shape[1], 1))
    is_w = white.sum(axis=1) / w >= min_white
    n = 0
    for i in range(top - 1, max(-1, top - 1 - gap - min_run - 1), -1):
        if is_w[i]:
            n += 1
            if n >= min_run:
                return True
        elif n:
            break
    return False


def banded_rows(orange: np.ndarray, white: np.ndarray, dark: np.ndarray, top: int, bottom: int,
                min_run: int, gap: int, max_band: int, min_beyond: int = 3,
                min_white: float = 0.5,
                min_orange: float = 0.2, line: float = 0.9) -> bool:
    """True when a white band separates the blob from more orange above or below it.

    ``orange``, ``white``, ``dark``: boolean masks of a strip of columns over a blob (its
    orange, white and dark pixels; the strip's rows reach beyond the blob above and
    below); the blob spans rows ``top`` .. ``bottom - 1``.  Traffic cones and drums (MUTCD
    6F.63, 6F.64) carry horizontal white retro-reflective bands across their whole width
    between orange parts.  From the blob's top edge upward (and from its bottom edge
    downward): at most ``gap`` rows of blend, then a band of at most ``max_band`` rows
    holding at least ``min_run`` rows that are at least ``min_white`` white, then at least
    ``min_beyond`` consecutive rows that are at least ``min_orange`` orange (fewer are part of
    the band: a legend's edges blended with a reddish light); or, inside the blob, such a
    band between orange rows.  A row at least ``line`` dark ends the search (a two-colour
    sign's white part ends at its black border line).
    """
    n = orange.shape[0]
    if n == 0 or orange.shape[1] == 0:
        return False
    w = float(orange.shape[1])
    is_w = white.sum(axis=1) / w >= min_white
    is_o = (orange.sum(axis=1) / w >= min_orange) & ~is_w
    is_d = dark.sum(axis=1) / w >= line
    # the row tests as lists of bools: the loops below read them one row at a time
    is_w, is_o, is_d = is_w.tolist(), is_o.tolist(), is_d.tolist()
    for start, step in ((top - 1, -1), (bottom, 1)):
        i, n_white, first = start, 0, None
        while 0 <= i < n and not is_d[i]:
            if is_w[i]:
                n_white += 1
                first = i if first is None else first
            elif is_o[i]:
                k = i
                while 0 <= k < n and is_o[k]:
                    k += step
                if first is not None and n_white >= min_run and abs(k - i) >= min_beyond:
                    return True
                if first is None and abs(i - start) >= gap:
                    break                       # more orange, no band: not this blob's edge
                if first is not None:
                    i = k                       # a few orange rows (legend blend): go on
                    continue
            if first is None and abs(i - start) >= gap + 1:
                break                           # no band right at the edge
            if first is not None and abs(i - first) >= max_band:
                break
            i += step
    # a band inside the blob (the closing bridged a drum's stripes into one blob)
    i = top
    while i < min(bottom, n):
        if is_o[i] or not (is_w[i] or not is_d[i]) or i == top:
            i += 1
            continue
        j = i
        while j < min(bottom, n) and not is_o[j] and not is_d[j]:
            j += 1
        if j < min(bottom, n) and is_o[j] and is_o[i - 1] and sum(is_w[i:j]) >= min_run:
            return True
        i = j + 1
    return False

def diamond_rings(shape: tuple, fit: tuple, width: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Boolean (inner, outer) rings of ``width`` px either side of a fitted diamond's edge.

    The signed normal distance of a pixel centre from the edge of ``fit``'s diamond
    ``(cx, cy, a, b)`` is ``(|x - cx| / a + |y - cy| / b - 1) a b / sqrt(a^2 + b^2)``.
    """
    cx, cy, a, b = (float(v) for v in fit[:4])
    ys, xs = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float32)
    n = (np.abs(xs + 0.5 - cx) / a + np.abs(ys + 0.5 - cy) / b - 1.0) * (
        a * b / math.hypot(a, b))
    return (n < 0) & (n >= -width), (n >= 0) & (n < width)


def _padded(window: tuple, bw: int, bh: int) -> tuple[int, int, int, int]:
    """A blob's window ``(x0, y0, x1, y1)`` grown by a quarter of the blob's size ``(bw,
    bh)`` + 3 px (a mask fit that is too large puts an edge's outer samples beyond it)."""
    pad = 3 + int(0.25 * max(bw, bh))
    x0, y0, x1, y1 = window
    return x0 - pad, y0 - pad, x1 + pad, y1 + pad


def pixel_box(x: float, y: float, w: float, h: float) -> tuple[float, float, float, float]:
    """The whole-pixel box of the pixels whose centres lie inside an upright rectangle
    ``(x, y, w, h)`` (pixel ``i`` spans ``[i, i + 1)``, its centre at ``i + 0.5``): each edge
    rounded to the nearest pixel boundary.  Box labels drawn from a sign's pixels are whole
    pixels; rounding a sub-pixel measurement the same way matches them exactly when it is
    right to a fraction of a pixel, and is on average never further off than the sub-pixel
    box itself (the label's rounding is independent of the measurement's error)."""
    x0, y0 = math.ceil(x - 0.5), math.ceil(y - 0.5)
    x1, y1 = math.floor(x + w - 0.5) + 1, math.floor(y + h - 0.5) + 1
    return float(x0), float(y0), float(max(x1 - x0, 1)), float(max(y1 - y0, 1))


#: sub-pixel sample offsets for the coverage of a pixel (8 x 8 samples)
_SUBPIXEL = (np.arange(8) + 0.5) / 8


def _tip_pixel(c: float, r: float, c2: float, r2: float) -> Optional[int]:
    """The first pixel index, from the low side along one axis, of a pixel more than half
    covered by the diamond ``|x - c| / r + |y - c2| / r2 <= 1`` (``x`` along the axis,
    ``y`` across it), from the pixels about its tip (three across; along, a few and more for
    a narrow tip), or None when none of them is."""
    i = tip_pixel(c, r, c2, r2, _SUBPIXEL)
    return None if i == NO_PIXEL else i


def diamond_pixel_box(cx: float, cy: float, a: float, b: float) -> tuple[int, int, int, int]:
    """``(left, top, right, bottom)`` whole-pixel edges of the pixels more than half covered
    by the diamond ``|x - cx| / a + |y - cy| / b <= 1``, as a sign's pixel labels are drawn
    (its anti-aliased art's alpha above one half).  Along the edges that is the pixels whose
    centres lie inside (as :func:`pixel_box`); at a corner it takes more: a square diamond's
    tip covers half of a pixel on its middle row only when it reaches a quarter pixel past
    the pixel's centre (the wedge covers less than the pixel's half beyond its centre line),
    further on the rows above or below, so the box is on average about half a pixel per
    side inside the sub-pixel diamond's.  A diamond too small for any pixel to be half
    covered at a corner is boxed by the pixel centres it holds."""
    dy = abs(math.floor(cy) + 0.5 - cy)      # the pixel-centre row nearest the middle
    dx = abs(math.floor(cx) + 0.5 - cx)
    ha = a * max(0.0, 1.0 - dy / b)           # the diamond's half-width on that row
    hb = b * max(0.0, 1.0 - dx / a)
    left, right = math.ceil(cx - ha - 0.5), math.floor(cx + ha - 0.5) + 1
    top, bottom = math.ceil(cy - hb - 0.5), math.floor(cy + hb - 0.5) + 1
    if a > 0.5 and b > 0.5:
        tips = (_tip_pixel(cx, a, cy, b), _tip_pixel(cy, b, cx, a),
                _tip_pixel(-cx, a, cy, b), _tip_pixel(-cy, b, cx, a))
        left = left if tips[0] is None else tips[0]
        top = top if tips[1] is None else tips[1]
        right = right if tips[2] is None else -tips[2]
        bottom = bottom if tips[3] is None else -tips[3]
    return left, top, max(right, left + 1), max(bottom, top + 1)


def _lookup(table: np.ndarray, hue: np.ndarray, sat: np.ndarray) -> np.ndarray:
    """``table[hue, sat]`` of a colour table over (hue, saturation) and 2-d uint8 channels
    (compiled: :func:`~workzone_ros.core.kernels.hue_sat_take`)."""
    if (hue.ndim != 2 or hue.shape != sat.shape or table.ndim != 2
            or hue.dtype != np.uint8 or sat.dtype != np.uint8
            or table.dtype not in (np.float32, np.uint8)):
        return table[hue, sat]
    return hue_sat_take(table, hue, sat)


def _clipped_growth(bgr: np.ndarray, weak: np.ndarray, strong: np.ndarray, bound: float,
                    near: Optional[np.ndarray] = None) -> np.ndarray:
    """The pixels that join a blob's face (uint8 mask) because the camera clipped their red:
    pixels of ``weak`` likelihood whose red channel in ``bgr`` (as the camera gave it) is 250
    or more and above the green, connected to the ``strong`` core through such pixels.  A
    clipped red hides how red the pixel was: its true hue is lower (more orange) and its
    saturation higher than the image shows, so a sunlit plaque's face reads yellowish and
    the table rates it weak.  A connected part more than ``1 + bound`` times the core's
    width or height (plus 2 px) is left out (a surface of that colour, not the face).
    ``near``: pixels the face has already (nothing to do when they hold every clipped one)."""
    clip = (weak > 0) & (bgr[..., 2] >= 250) & (bgr[..., 1] < bgr[..., 2])
    out = np.zeros(weak.shape, np.uint8)
    if not (clip.any() if near is None else (clip & (near == 0)).any()):
        return out
    n, lab, st, _ = _components((clip | (strong > 0)).astype(np.uint8))
    keep = np.zeros(n, bool)
    keep[np.unique(lab[strong > 0])] = True
    keep[0] = False
    _, _, cw, ch = cv2.boundingRect(strong)
    keep &= (st[:, 2] <= (1 + bound) * cw + 2) & (st[:, 3] <= (1 + bound) * ch + 2)
    out[keep[lab]] = 1
    return out


def _dark_share(value: np.ndarray, rel: float) -> np.ndarray:
    """Per row of the brightness ``value`` of a strip under a two-colour sign's orange part:
    the share of its middle columns (its outer tenth on each side left out: the strip may
    reach past the sign) darker than ``rel`` x the strip's 90th percentile (the white
    sheeting's level)."""
    w = value.shape[1]
    m = max(1, w // 10)
    ref = float(np.percentile(value, 90))
    return (value[:, m:w - m] < rel * ref).mean(axis=1)


def _bands(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first and last row of each run of consecutive rows in the sorted ``rows``."""
    brk = np.diff(rows) > 1
    return rows[np.insert(brk, 0, True)], rows[np.append(brk, True)]


def _components(mask: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """``cv2.connectedComponentsWithStats(mask, connectivity=8)``, by the BBDT labelling when
    OpenCV runs on one thread.

    Single-threaded, BBDT and OpenCV's default (Spaghetti) both label 2x2 blocks in raster
    order and number the components by their first block: the same labels and statistics
    (checked on every mask of the tuning bags), and BBDT's statistics pass costs a third
    of the default's (0.05 vs 0.16 ms on a 192x132 mask, OpenCV 5.0).  Their parallel
    versions (more threads) number some components differently, so there the default is
    kept.
    """
    if cv2.getNumThreads() != 1:
        return cv2.connectedComponentsWithStats(mask, connectivity=8)
    return cv2.connectedComponentsWithStatsWithAlgorithm(mask, 8, cv2.CV_32S, cv2.CCL_BBDT)


def _paste(dst: np.ndarray, src: np.ndarray, oy: int, ox: int) -> None:
    """``dst[oy:oy + h, ox:ox + w] = src``, clipped to ``dst`` (a blob of a half-resolution
    mask scaled back up can reach a row or column past an odd-sized frame's edge)."""
    h = min(src.shape[0], dst.shape[0] - oy)
    w = min(src.shape[1], dst.shape[1] - ox)
    if h > 0 and w > 0:
        dst[oy:oy + h, ox:ox + w] = src[:h, :w]

_PROFILE_U0 = np.arange(-3.0, 3.0 + 1e-6, 0.1, dtype=np.float32)
_PROFILE_SIG = np.array([0.45, 0.65, 0.9, 1.2, 1.6], np.float32)


@functools.lru_cache(maxsize=256)
def _profile_bases(u_out: float, u_in: float, border: float, margin: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Blurred step-profile bases of a sign edge and their normal-equation inverses.

    Samples ``u`` every quarter pixel from ``-u_out`` (outside) to ``u_in`` (inside).  For
    every edge offset ``u0`` in :data:`_PROFILE_U0` and blur width in :data:`_PROFILE_SIG`:
    a face at ``u > u0`` (level ``hi``), the black border line ``border`` px wide outside it
    (``lo``), a thin outer margin of the face's colour ``margin`` px wide (``hi``), then the
    background (``bg``), each step blurred by a Gaussian (optics, motion and the pixel's own
    width).  Returns ``(u, bases, inv(bases^T bases) (k, 3, 3), valid (k,))``; the profile
    is a linear combination of the hi, lo and bg bases (returned transposed, (k * 3,
    len(u)), for one matrix product per profile).
    """
    u = np.arange(-u_out, u_in + 1e-6, 0.25, dtype=np.float64)
    d = u[None, None, :] - _PROFILE_U0.astype(np.float64)[:, None, None]
    sg = _PROFILE_SIG.astype(np.float64)[None, :, None]
    f_in = ndtr(d / sg)
    f_bl = ndtr((d + border) / sg)
    f_mg = ndtr((d + border + margin) / sg)
    bases = np.stack(np.broadcast_arrays(f_in + (f_mg - f_bl), f_bl - f_in, 1.0 - f_mg),
                     axis=-1).reshape(-1, u.size, 3)
    ata = np.einsum('kui,kuj->kij', bases, bases) + 1e-6 * np.eye(3)
    # offsets that leave at least a pixel of face inside and of background outside
    ok = (_PROFILE_U0 <= u_in - 1.0) & (_PROFILE_U0 >= border + margin + 1.0 - u_out)
    return u, np.ascontiguousarray(bases.transpose(0, 2, 1).reshape(-1, u.size)), \
        np.linalg.inv(ata), np.repeat(ok, _PROFILE_SIG.size)


def _edge_profile(extent: float, border: float, margin: float) -> tuple:
    """:func:`_profile_bases` for a face ``extent`` px from its middle to its edge (inside
    samples reach a fifth of it, 1.5-3.5 px, plus a pixel) with the line and margin outside
    (plus 2.5 px of background); widths rounded so that faces of about the same size share
    the cached bases."""
    u_in = round(2 * min(max(1.5, 0.2 * extent), 3.5)) / 2 + 1.0
    u_out = round(4 * (border + margin)) / 4 + 2.5
    return _profile_bases(u_out, u_in, round(4 * border) / 4, round(4 * margin) / 4)


@functools.lru_cache(maxsize=256)
def _unit_steps(n: int) -> np.ndarray:
    """``np.linspace(0, 1, n)``, read-only (the sample positions along an edge stretch)."""
    ts = np.linspace(0.0, 1.0, n)
    ts.flags.writeable = False
    return ts


def _taper(spec: Sequence[float], x: float) -> float:
    """``spec = (px, x0, x1)``: ``px`` at ``x <= x0``, none from ``x1``, linear between (0
    when ``px`` is 0).  The shift of ``DetectorConfig.diamond_bright_bias`` by the border
    line's width (px), and of ``rect_dim_bias`` by the plaque's brightness.

    ``diamond_bright_bias``: an edge stretch whose fitted background is brighter than the
    face is taken this much further out.  A line and margin under a pixel wide, blurred,
    leave only a shallow dip between a background brighter than the face and the face,
    and the edge model places the edge further in than it is there: the catalogue art
    drawn over grey (luma 60 -> 240, the face's about 100), blurred 0.6 px, measures a
    14 px diamond's half-diagonal 0.34 px less and a 16 px one's 0.22 px less (18 px and
    more: no difference); on the simulator's frames small signs come out 0.2-0.4 px short
    against bright backgrounds up to about 30 px."""
    px, x0, x1 = (float(v) for v in spec)
    if px == 0.0:
        return 0.0
    return px * min(1.0, max(0.0, (x1 - x) / max(x1 - x0, 1e-9)))


def _edge_offsets(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, prof: tuple,
                  min_contrast: float, missing: bool = False,
                  blur: Optional[np.ndarray] = None,
                  levels: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
    """Offsets (px, along each inward normal) of the face edge on several edge stretches.

    ``segs`` (n, 2, 2): each stretch's end points; ``nvecs`` (n, 2): its inward unit
    normal.  Per stretch: the median of its brightness profiles along the normal (bilinear,
    every quarter pixel), the best fit of the edge model over the offset x blur grid of
    :func:`_profile_bases`, a parabola through the neighbouring offsets.  None when a
    stretch lies outside ``img`` or shows no face-to-border step (contrast below
    ``min_contrast`` of the face at every offset); with ``missing`` such a stretch's offset
    is NaN instead (None when no stretch shows one).  ``blur`` (n,), when given, receives
    each stretch's fitted blur width (px, NaN without a step); ``levels`` (n, 2), when
    given, its fitted face and background levels (NaN without a step).
    """
    u, bases_t, ata_inv, valid = prof
    length = float(np.hypot(*(segs[0, 1] - segs[0, 0])))
    ts = _unit_steps(max(3, int(length) + 1))
    # the sample points ``s0 + t (s1 - s0) + u n`` (n, t, u): the part along the stretch
    # (n, t) and the part along the normal (n, u) each once, then summed per point in that
    # order (the same sums as over the broadcast (n, t, u, 2) points, at a fraction of the
    # multiplications)
    along = segs[:, None, 0, :] + ts[None, :, None] * (segs[:, 1] - segs[:, 0])[:, None, :]
    across = u[None, :, None] * nvecs[:, None, :]
    mx = (along[:, :, None, 0] + across[:, None, :, 0] - 0.5).astype(np.float32)
    my = (along[:, :, None, 1] + across[:, None, :, 1] - 0.5).astype(np.float32)
    h, w = img.shape[:2]
    if mx.min() < 0 or my.min() < 0 or mx.max() > w - 1 or my.max() > h - 1:
        return None
    n, nt, nu = mx.shape
    samples = cv2.remap(img, mx.reshape(n * nt, nu), my.reshape(n * nt, nu), cv2.INTER_LINEAR)
    prof_v = profile_medians(samples, n, nt)                                    # (n, u)
    atb = (bases_t @ prof_v.T).reshape(-1, 3, n)                                # (k, 3, n)
    coef = ata_inv @ atb
    # per stretch: the best model among those showing a step (the border line is dark: a
    # plain step is the face's edge against a background as dark as the line, never the
    # margin's outer edge with a line as bright as the face), its offset moved by the
    # parabola through its neighbours' residuals (compiled: :func:`kernels.edge_choice`)
    off = np.empty(n)
    best = np.empty(n, np.int64)
    seen = edge_choice(prof_v, atb, coef, valid, float(min_contrast), _PROFILE_U0,
                       _PROFILE_SIG.size, off, best)
    if not (seen > 0 if missing else seen == n):
        return None
    if blur is not None or levels is not None:
        shown = best >= 0
        k = np.where(shown, best, 0)
        if blur is not None:
            blur[:] = np.where(shown, _PROFILE_SIG[k % _PROFILE_SIG.size], np.nan)
        if levels is not None:
            cols = np.arange(n)
            levels[:] = np.where(shown[:, None], np.stack([coef[k, 0, cols], coef[k, 2, cols]],
                                                         axis=1), np.nan)
    return off


# the (x, y) signs of the diamond's edges in refine_diamond's order: upper left, upper
# right, lower right, lower left
_RHOMBUS_SIGNS = np.array([(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)])
_STRETCH_SIGNS = np.repeat(_RHOMBUS_SIGNS, 2, axis=0)      # two stretches per edge
# the two stretches of each edge, as fractions of its length from its first corner
_STRETCH_FROM = np.array([0.15, 0.55])
_STRETCH_TO = np.array([0.45, 0.85])
# the same per edge (4, 2), and every stretch shown (read-only: each round uses them as
# they are unless an occluder hides some, when :func:`_stretches_above` makes new ones)
_EDGE_FROM = np.tile(_STRETCH_FROM, (4, 1))
_EDGE_TO = np.tile(_STRETCH_TO, (4, 1))
_ALL_SHOWN = np.ones(8, bool)
_EDGE_FROM.flags.writeable = _EDGE_TO.flags.writeable = _ALL_SHOWN.flags.writeable = False


def fit_rhombus(points: np.ndarray, signs: np.ndarray, outlier_px: float = 1.0,
                max_drop: int = 2) -> Optional[tuple[float, float, float, float]]:
    """Least-squares upright diamond ``|x - cx| / a + |y - cy| / b = 1`` through edge points.

    ``points`` (n, 2): points measured on the diamond's edges; ``signs`` (n, 2): the edge
    each lies on, as the signs of ``x - cx`` and ``y - cy`` on it.  The edge equation is
    linear in ``(1/a, 1/b, cx/a, cy/b)``; points further than ``outlier_px`` (or 7 % of the
    smaller half-diagonal) from the outline fitted without them are dropped one at a time,
    worst first (a legend stroke near an edge, a pole across it), at most ``max_drop``,
    while every edge keeps a point.  Returns ``(cx, cy, a, b)`` or None (degenerate, or still
    inconsistent).  Computed by the compiled :func:`~workzone_ros.core.kernels.rhombus_fit`."""
    out = rhombus_fit(np.ascontiguousarray(points, np.float64),
                      np.ascontiguousarray(signs, np.float64), float(outlier_px), int(max_drop))
    return None if math.isnan(out[0]) else tuple(out.tolist())


# the smallest face-to-line contrast (a share of the face's brightness) an edge must show
EDGE_MIN_CONTRAST = 0.25
#: how far (px, along x and y) :func:`refine_shifted` moves a start: half the edge search's
#: width on a large face (offsets -1.5 to 3 px)
START_SHIFT_PX = 2.25


def refine_shifted(starts: Sequence[Sequence[float]],
                   refine: Callable[[tuple], Optional[tuple]],
                   accept: Optional[Callable[[tuple], tuple]] = None,
                   step: float = START_SHIFT_PX) -> Optional[tuple]:
    """``refine`` (e.g. :func:`refine_diamond` on a brightness window) from each of
    ``starts`` ``(cx, cy, a, b)`` moved by ``step`` px in the eight directions: the edges'
    search reaches only a few pixels, so a large face's start a few pixels off (a mask that
    took in a surface of the sign's colour beside it) fails however clear the face.  Of the
    fits ``accept`` keeps (it returns ``(fit or None, verdict)``), the smallest: a start too
    large also fits the sign's outer edge (its margin against the background) or its
    line's, both outside the face's edge (a fit inside it is rarer).  Returns ``(fit,
    verdict)`` (verdict None without ``accept``) or None when no moved start fits."""
    best, best_area = None, math.inf
    for st in starts:
        for ddx, ddy in itertools.product((-1, 0, 1), repeat=2):
            if ddx == 0 and ddy == 0:
                continue                        # (the caller tried it as it is)
            fit = refine((st[0] + ddx * step, st[1] + ddy * step, st[2], st[3]))
            if fit is None or fit[2] * fit[3] >= best_area:
                continue
            got = (fit, None) if accept is None else accept(fit)
            if got[0] is not None:
                best, best_area = (got[0], got[1]), got[0][2] * got[0][3]
    return best


def frame_edges(x: float, y: float, w: float, h: float, width: int, height: int,
                tol: float = 0.0) -> tuple[bool, bool, bool, bool]:
    """Which edges of a ``width`` x ``height`` frame the box ``(x, y, w, h)`` reaches
    (within ``tol`` px): ``(left, top, right, bottom)``."""
    return (x <= tol, y <= tol, x + w >= width - tol, y + h >= height - tol)


def start_shrink(border_rel: float, margin_rel: float) -> float:
    """The factor :func:`refine_diamond` applies to its start's half-diagonals: half-way
    from an outline with the line and margin to the face without them."""
    return 1.0 - 0.5 * (border_rel + margin_rel) * math.sqrt(2)


def refine_diamond(value: np.ndarray, fit: Sequence[float], border_rel: float = 0.0676,
                   margin_rel: float = 0.022, max_change: float = 0.15,
                   min_contrast: float = EDGE_MIN_CONTRAST, iterations: int = 2,
                   aspect: tuple[float, float] = (0.75, 1.2), outlier_px: float = 1.0,
                   max_lost: int = 2, info: Optional[dict] = None,
                   hidden_below: Optional[float] = None, stroke_steps: int = 0,
                   bright_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
                   ) -> Optional[tuple[float, float, float, float]]:
    """Sub-pixel edges of a warning diamond's orange face from the brightness image.

    ``fit = (cx, cy, a, b)``: a first estimate of the face's diamond (continuous
    coordinates, pixel ``i`` spans ``[i, i + 1)``), e.g. :func:`fit_diamond_2d` on the face
    mask.  The colour table cannot place the face's edge: a blend of the orange face and the
    black border line keeps the face's hue and saturation and only gets darker, so the mask
    ends wherever the value gate happens to cut the blend.  The brightness does place it:
    each of the four edges is measured on two stretches (15-45 % and 55-85 % of its length,
    away from the corners), each by the median of its brightness profiles along the edge's
    normal (legend strokes and noise drop out) fitted with the edge model of
    :func:`_profile_bases` (face, border line ``border_rel`` x a wide, outer margin
    ``margin_rel`` x a, background, each with its own level: a headlight's hot spot or a
    bright sky behind one edge does not bias it).  The eight edge points give the diamond by
    least squares (:func:`fit_rhombus`: a point more than ``outlier_px`` off the diamond
    fitted to the others, a legend stroke or a big symbol next to the edge taken for it, is
    dropped; so is a stretch without a face-to-border step, a symbol reaching the edge: at
    most ``max_lost`` points in all); ``iterations`` rounds.
    The defaults are the catalogue's diamond art: the border line's inner edge at 0.888 of
    the half-diagonal, the line 0.06 of the half-diagonal wide (normal to the edge), the
    orange margin outside it.

    ``stroke_steps``: a stretch whose fitted blur is at least this many steps of the edge
    model's blur grid (0.45, 0.65, 0.9, 1.2, 1.6 px) wider than the median of the sign's
    stretches is a legend stroke running into the face's edge there (a lane-shift arrow's
    head, a lane-ends line: the dark stroke beside the border line reads as a wide, soft
    step 0.5-1.5 px inside the edge, often still within ``outlier_px`` of the others);
    it counts as one of the lost points, the widest first, while at most ``max_lost`` are
    lost and each edge keeps a stretch; when the points left then do not agree on a
    diamond, the round is fitted with them kept, and when the refinement fails after
    leaving any out, it is done again without the test (as with 0 = off).

    ``bright_bias``: an edge stretch whose fitted background is brighter than the face is
    taken further out on a small face (:func:`_taper`).

    ``info``, when given, receives ``blur``: the median of the edge stretches' fitted blur
    widths (px) in the last round.

    ``hidden_below``: an occluder (a guardrail, a car's roof) hides the face from this row
    down.  The lower edges are then measured only above it: each lower edge's stretch
    nearest its side corner runs from 10 % of the edge to where its profiles would reach
    the occluder (a pixel above its edge), and a stretch left shorter than 10 % of the
    edge, or any stretch reaching the occluder, is not measured (not one of the points
    the fit may drop: it was never seen).

    Returns ``(cx, cy, a, b)`` or None when a stretch shows no face-to-border step
    (contrast below ``min_contrast`` of the face's brightness: washed out, heavily blurred)
    or lies outside ``value``, the edge points do not agree on a diamond, a half-diagonal
    moves by more than ``max_change`` from the estimate's, or the result is no diamond facing
    the road (``a / b`` outside ``aspect``: turned away by up to ~40 deg, rolled or
    distorted a little).
    """
    used = [False]
    out = _refine_diamond_rounds(value, fit, border_rel, margin_rel, max_change, min_contrast,
                                 iterations, aspect, outlier_px, max_lost, info, hidden_below,
                                 stroke_steps, used, bright_bias)
    if out is None and used[0]:
        out = _refine_diamond_rounds(value, fit, border_rel, margin_rel, max_change,
                                     min_contrast, iterations, aspect, outlier_px, max_lost,
                                     info, hidden_below, 0, used, bright_bias)
    return out


def _refine_diamond_rounds(value: np.ndarray, fit: Sequence[float], border_rel: float,
                           margin_rel: float, max_change: float, min_contrast: float,
                           iterations: int, aspect: tuple[float, float], outlier_px: float,
                           max_lost: int, info: Optional[dict], hidden_below: Optional[float],
                           stroke_steps: int, used: list,
                           bright_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
                           ) -> Optional[tuple[float, float, float, float]]:
    """:func:`refine_diamond`'s rounds; ``used[0]`` is set when a round's fit left out a
    stroke's stretches."""
    cx, cy, a, b = (float(v) for v in fit[:4])
    a_in, b_in = a, b
    if a < 3 or b < 3:
        return None
    # start half-way between the estimate and the face's edge without margin and line
    # (a mask that took in the orange margin): the face's edge is within the search
    # either way
    shrink = start_shrink(border_rel, margin_rel)
    a, b = a * shrink, b * shrink
    img = np.ascontiguousarray(value, dtype=np.float32)
    for _ in range(iterations):
        m = min(a, b)
        border, margin = border_rel * m, margin_rel * m
        prof = _edge_profile(m, border, margin)
        # the four edges (left corner to top, top to right, right to bottom, bottom to
        # left), all at once: direction, inward normal, and the two stretches of each
        p0 = np.array([(cx - a, cy), (cx, cy - b), (cx + a, cy), (cx, cy + b)])
        p1 = p0[[1, 2, 3, 0]]
        e = p1 - p0
        dvec = e / np.hypot(e[:, 0], e[:, 1])[:, None]
        nvec = np.stack([-dvec[:, 1], dvec[:, 0]], axis=1)
        inward = (nvec * (np.array([cx, cy]) - 0.5 * (p0 + p1))).sum(axis=1)
        nvec[inward < 0] *= -1.0
        f_from, f_to, shown = _EDGE_FROM, _EDGE_TO, _ALL_SHOWN
        if hidden_below is not None:
            f_from, f_to, shown = _stretches_above(p0, e, nvec, f_from, f_to, prof[0],
                                                   hidden_below - 1.0)
            if not shown.any():
                return None
        segs = np.stack([p0[:, None] + f_from[..., None] * e[:, None],
                         p0[:, None] + f_to[..., None] * e[:, None]],
                        axis=2).reshape(8, 2, 2)
        mids = 0.5 * (segs[:, 0] + segs[:, 1])
        nv = np.repeat(nvec, 2, axis=0)
        blur = np.full(8, np.nan)
        off = np.full(8, np.nan)
        b_ = np.empty(int(shown.sum()))
        bright = _taper(bright_bias, border)
        lv = np.empty((b_.size, 2)) if bright > 0 else None
        o_ = _edge_offsets(img, segs[shown], nv[shown], prof, min_contrast, missing=True,
                           blur=b_, levels=lv)
        if o_ is None:
            return None
        if lv is not None:
            # (NaN levels compare False: a stretch without a step stays NaN)
            o_ = o_ - bright * (lv[:, 1] > lv[:, 0])
        off[shown], blur[shown] = o_, b_
        # a stretch without a face-to-border step (a symbol or legend reaching the edge)
        # counts as one of the points the fit may drop
        seen = np.isfinite(off)
        lost = int(np.count_nonzero(shown & ~seen))
        if lost > max_lost:
            return None
        fit_ = None
        if stroke_steps > 0:
            # without the stretches a stroke runs into, unless the rest then disagree
            drop = _stroke_stretches(blur, seen, max_lost - lost, stroke_steps)
            if drop.any():
                s_seen = seen & ~drop
                fit_ = fit_rhombus(mids[s_seen] + off[s_seen, None] * nv[s_seen],
                                   _STRETCH_SIGNS[s_seen], outlier_px,
                                   max_lost - lost - int(np.count_nonzero(drop)))
                used[0] = used[0] or fit_ is not None
        if fit_ is None:
            q = mids[seen] + off[seen, None] * nv[seen]
            fit_ = fit_rhombus(q, _STRETCH_SIGNS[seen], outlier_px, max_lost - lost)
        if fit_ is None:
            return None
        cx, cy, a, b = fit_
        if not (abs(a / a_in - 1) <= max_change and abs(b / b_in - 1) <= max_change
                and aspect[0] <= a / b <= aspect[1]):
            return None
    if info is not None:
        # the last round's stretches (np.nanmedian's value: the median of the measured
        # ones; at least one is, or the round returned)
        info['blur'] = float(_median(blur[~np.isnan(blur)]))
    return cx, cy, a, b


def _stroke_stretches(blur: np.ndarray, seen: np.ndarray, spare: int, steps: int
                      ) -> np.ndarray:
    """:func:`refine_diamond`'s ``stroke_steps`` test on one round's eight stretches: the
    mask of those to leave out, the widest-blurred first, at most ``spare`` of them, each
    edge keeping one (``seen``: the stretches measured; ``blur``: their fitted blur)."""
    drop = np.zeros(seen.shape, bool)
    if spare <= 0 or np.count_nonzero(seen) <= 4:
        return drop
    level = np.searchsorted(_PROFILE_SIG, np.where(seen, blur, 0.0) - 1e-6)
    cut = _median(level[seen]) + steps             # (np.median's value, float64)
    for j in np.argsort(-np.where(seen, level, -1), kind='stable'):
        if spare <= 0 or level[j] < cut:
            break
        if seen[j ^ 1] and not drop[j ^ 1]:    # the edge's other stretch is measured
            drop[j] = True
            spare -= 1
    return drop


_SQRT_HALF = math.sqrt(0.5)


def _stretches_above(p0: np.ndarray, e: np.ndarray, nvec: np.ndarray, f_from: np.ndarray,
                     f_to: np.ndarray, u: np.ndarray, limit: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`refine_diamond`'s stretches (fractions ``f_from``, ``f_to`` (4, 2) along its
    edges ``p0 + f e``, profiles sampled at ``u`` along the inward normals ``nvec``) kept
    above row ``limit``: a lower edge's stretch nearest its side corner ends where its
    profiles reach the row (at least 10 % of the edge long, from 10 %), any other stretch
    reaching it is dropped.  Returns the new fractions and which of the 8 stretches show."""
    f_from, f_to = f_from.copy(), f_to.copy()
    # the lowest row a profile at fraction f of edge i samples: the edge point's row plus
    # the normal's reach down (outwards or inwards, whichever goes lower); the outermost
    # 2 px of background may fall on the occluder (another background level at the
    # profile's end: it moves no edge)
    reach = np.maximum((u[0] + 2.0) * nvec[:, 1], u[-1] * nvec[:, 1])    # (4,)
    low = lambda f: p0[:, None, 1] + f * e[:, None, 1] + reach[:, None]   # noqa: E731
    for i in (2, 3):          # right corner to bottom, bottom to left corner
        if e[i, 1] == 0:
            continue
        # the fraction where the profiles reach the limit, and the near-corner stretch
        f_lim = (limit - reach[i] - p0[i, 1]) / e[i, 1]
        if i == 2:              # going down from the right corner: stretch 0 nearest it
            f_from[i, 0], f_to[i, 0] = 0.1, min(_STRETCH_TO[0], f_lim)
        else:                   # going up to the left corner: stretch 1 nearest it
            f_from[i, 1], f_to[i, 1] = max(_STRETCH_FROM[1], f_lim), 0.9
    shown = (np.maximum(low(f_from), low(f_to)) <= limit + 1e-6) & (f_to - f_from >= 0.1)
    return f_from, f_to, shown.reshape(8)


def diamond_starts(value: np.ndarray, box: Sequence[float], min_a: float, max_a: float,
                   count: int = 3, inner_frac: float = 0.2, line_rel: float = 0.07,
                   step: float = 1.08, min_contrast: float = 0.05
                   ) -> list[tuple[float, float, float, float, float]]:
    """Where in ``value`` a face diamond with a dark line around it could be: a coarse search.

    A start for :func:`refine_diamond` when the mask gives none (a sign merged with a surface
    of about its colour, an orange dusk sky behind it: the mask's diamond is the union's).
    In coordinates turned by 45 deg an upright diamond with equal half-diagonals is a square,
    so box sums over a turned copy of ``value`` (one integral image) score every centre in
    ``box = (x, y, w, h)`` and every half-diagonal from ``min_a`` to ``max_a`` (steps of
    ``step``) at once: per side, the face's band ``inner_frac`` of the half-side wide just
    inside against the line's band (``line_rel`` of the half-diagonal, a pixel at least)
    just outside, on the middle 70 % of the side; the score is the smallest of the four
    relative contrasts ``(inside - outside) / inside`` (every edge must show the face-to-line
    step; a merged surface shows none on its side).  Returns up to ``count`` diamonds
    ``(cx, cy, a, a, score)`` (continuous coordinates), best first, at least
    ``min_contrast``, none within about a third of its size of a better one."""
    img = np.ascontiguousarray(value, dtype=np.float32)
    H, W = img.shape[:2]
    c = _SQRT_HALF
    side = int(math.ceil((W + H) * c)) + 3
    voff = H * c + 1.0
    # turned[v, u] = value at x = (u + v - voff) c, y = (u - v + voff) c (pixel centres);
    # outside the window -1 (counted out of every band)
    mat = np.array([[c, c, -c * voff], [c, -c, c * voff]], np.float32)
    turned = cv2.warpAffine(img, mat, (side, side), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
    inside = turned >= 0
    sums = cv2.integral(np.where(inside, turned, 0.0).astype(np.float64))
    counts = cv2.integral(inside.astype(np.uint8))
    # candidate centres: corners of the turned grid (a square's sides on pixel boundaries)
    # whose continuous (x, y) lies in the box
    x, y, w, h = (float(v) for v in box[:4])
    corners = np.array([(x, y), (x + w, y), (x, y + h), (x + w, y + h)]) - 0.5
    us_, vs_ = (corners[:, 0] + corners[:, 1]) * c, (corners[:, 0] - corners[:, 1]) * c + voff
    uu, vv = np.meshgrid(np.arange(max(0, int(us_.min())), min(side, int(us_.max()) + 2) + 1),
                         np.arange(max(0, int(vs_.min())), min(side, int(vs_.max()) + 2) + 1))
    px = (uu + vv - 1.0 - voff) * c + 0.5
    py = (uu - vv + voff) * c + 0.5
    sel = (px >= x) & (px <= x + w) & (py >= y) & (py <= y + h)
    uc, vc = uu[sel], vv[sel]

    def mean(u0, u1, v0, v1):
        s_ = sums[v1, u1] - sums[v0, u1] - sums[v1, u0] + sums[v0, u0]
        n_ = counts[v1, u1] - counts[v0, u1] - counts[v1, u0] + counts[v0, u0]
        return s_ / np.maximum(n_, 1), n_ > 0

    lo, hi = max(2.0, min_a * c), max_a * c
    found = []
    sizes = sorted({int(round(lo * step ** k)) for k in range(
        int(math.log(max(hi / lo, 1.0)) / math.log(step)) + 1)})
    for s in sizes:
        d = max(1, int(round(inner_frac * s)))
        lw = max(1, int(round(line_rel * s / c)))
        t = max(1, int(round(0.7 * s)))
        ok = (uc >= s + lw) & (vc >= s + lw) & (uc + s + lw <= side) & (vc + s + lw <= side)
        u, v = uc[ok], vc[ok]
        if u.size == 0:
            continue
        score = None
        # left, right (u = uc -/+ s), top, bottom (v = vc -/+ s): face band, line band
        for fb, lb in (((u - s, u - s + d, v - t, v + t), (u - s - lw, u - s, v - t, v + t)),
                       ((u + s - d, u + s, v - t, v + t), (u + s, u + s + lw, v - t, v + t)),
                       ((u - t, u + t, v - s, v - s + d), (u - t, u + t, v - s - lw, v - s)),
                       ((u - t, u + t, v + s - d, v + s), (u - t, u + t, v + s, v + s + lw))):
            mf, nf = mean(*fb)
            ml, nl = mean(*lb)
            sc = np.where(nf & nl, (mf - ml) / np.maximum(mf, 1.0), -1.0)
            score = sc if score is None else np.minimum(score, sc)
        good = score >= min_contrast
        if good.any():
            found.append((score[good], u[good], v[good], np.full(int(good.sum()), s)))
    if not found:
        return []
    score, u, v, s = (np.concatenate(a) for a in zip(*found))
    picked: list[int] = []
    for i in np.argsort(-score, kind='stable')[:400]:
        if any(abs(u[i] - u[j]) + abs(v[i] - v[j]) <= 0.35 * max(s[i], s[j])
               and abs(s[i] / s[j] - 1.0) < 0.25 for j in picked):
            continue
        picked.append(int(i))
        if len(picked) >= count:
            break
    out = []
    for i in picked:
        cx = (u[i] + v[i] - 1.0 - voff) * c + 0.5
        cy = (u[i] - v[i] + voff) * c + 0.5
        out.append((float(cx), float(cy), s[i] / c, s[i] / c, float(score[i])))
    return out


def diamond_holds(pixels: np.ndarray, face: Sequence[float], ratio: float, share: float,
                  slack_px: float = 1.0) -> bool:
    """Whether the sign outline ``ratio`` x the face diamond ``(cx, cy, a, b)`` (continuous
    coordinates) holds the nonzero ``pixels`` (their centres; the outline grown by
    ``slack_px``): False when in three or four of the diamond's quadrants less than
    ``share`` of the quadrant's pixels lie inside (a sign whose orange reaches out all
    round: not the catalogue's layout).  Orange beyond one or two sides (flags above a
    portable stand, a merge with an orange sky or a drum) does not count."""
    ys, xs = np.nonzero(pixels)
    if xs.size == 0:
        return True
    cx, cy, a, b = (float(v) for v in face[:4])
    dx, dy = xs + 0.5 - cx, ys + 0.5 - cy
    out = np.abs(dx) / (ratio * a + slack_px) + np.abs(dy) / (ratio * b + slack_px) > 1.0
    quad = (dx > 0).astype(np.int64) + 2 * (dy > 0)
    n = np.bincount(quad, minlength=4)
    n_out = np.bincount(quad, weights=out, minlength=4)
    return int(np.count_nonzero(n_out > (1.0 - share) * np.maximum(n, 1))) < 3


def _blurred_diamond(p: np.ndarray, xs: np.ndarray, ys: np.ndarray, jac: bool = False
                     ) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """The blurred diamond model of :func:`fit_blurred_diamond` at ``(xs, ys)`` and, with
    ``jac``, its Jacobian (n, 9) in ``p = (cx, cy, a, b, sigma, face, bg, gx, gy)``."""
    cx, cy, a, b, sg, face, bg, gx, gy = (float(v) for v in p)
    r2 = a * a + b * b
    n = a * b / math.sqrt(r2)
    dx, dy = xs - cx, ys - cy
    u, v = dx / a, dy / b
    # signed distances inside the four edges; the blurred indicator of the diamond is the
    # product of the edges' blurred half-planes (exact at a right-angled corner)
    signs = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))
    z = np.stack([(1.0 - sx * u - sy * v) * (n / sg) for sx, sy in signs])     # (4, n)
    cdf = ndtr(z)
    prod = cdf.prod(axis=0)
    contrast = face - bg
    model = bg + gx * dx + gy * dy + contrast * prod
    if not jac:
        return model, None
    pdf = np.exp(-0.5 * z * z) * (1.0 / math.sqrt(2.0 * math.pi))
    # d prod / d z_i: the edge's density times the other three edges' blurred half-planes
    others = np.stack([np.prod(np.delete(cdf, i, axis=0), axis=0) for i in range(4)])
    dp_dz = pdf * others                                                      # (4, n)
    dn_da, dn_db = b ** 3 / r2 ** 1.5, a ** 3 / r2 ** 1.5
    out = np.empty((xs.size, 9))
    g = np.zeros((5, xs.size))
    for i, (sx, sy) in enumerate(signs):
        lin = 1.0 - sx * u - sy * v
        g[0] += dp_dz[i] * (sx * n / (a * sg))
        g[1] += dp_dz[i] * (sy * n / (b * sg))
        g[2] += dp_dz[i] * ((sx * u / a) * n + lin * dn_da) / sg
        g[3] += dp_dz[i] * ((sy * v / b) * n + lin * dn_db) / sg
        g[4] += dp_dz[i] * (-z[i] / sg)
    out[:, :5] = contrast * g.T
    out[:, 0] -= gx
    out[:, 1] -= gy
    out[:, 5] = prod
    out[:, 6] = 1.0 - prod
    out[:, 7] = dx
    out[:, 8] = dy
    return model, out


def fit_blurred_diamond(chroma: np.ndarray, start: Sequence[float], max_sigma: float = 4.0,
                        robust: float = 0.15, inner_skip: float = 0.5, max_nfev: int = 60,
                        max_half: float = 10.0
                        ) -> Optional[tuple[float, float, float, float, float, float, float]]:
    """The sign's orange diamond fitted to a blurred chroma image, where its edges are not.

    A faded, rain-washed or motion-blurred sign may show no border line in the brightness
    (:func:`refine_diamond` finds no face-to-line step) and its colour mask stops well short
    of the tips.  Its colour does still place the sign: ``chroma`` (R - B, a linear
    function of a blend of the sign's and the background's colours) is modelled as a
    background plane plus the sign's uniform level times the diamond ``|x - cx| / a +
    |y - cy| / b <= 1`` blurred by a Gaussian of width ``sigma`` (the product of its four
    edges' blurred half-planes); all nine parameters by robust least squares (soft L1 at
    ``robust`` x the start's contrast: legend strokes and a post are outliers) from
    ``start = (cx, cy, a, b)`` (continuous coordinates, pixel ``i`` spans ``[i, i + 1)``),
    over the window less the start's middle (``inner_skip`` of its half-diagonals: the
    legend's place).  A sign larger than ``max_half`` px half-diagonal is fitted on the
    window binned by a whole factor (block means: still linear in the blend) to about that
    size: the cost is about the same for every size (a few ms).  The border line and the
    thin margin outside it blend with the edge: the fitted diamond lies between the sign's
    outline and the face's.  Not claimed: a legend blurred into a small face lowers the
    face's level and puts the edge further out (about 0.5 px at 9 px half-diagonal and
    1.5 px blur, 1 px at 2.5 px blur, on a test sign with a stroke down its middle).

    Returns ``(cx, cy, a, b, sigma, face, bg)`` or None: the fit did not converge, a
    half-diagonal reached half or twice the start's, the blur reached ``max_sigma``, or
    the sign is not more coloured than its background.
    """
    cx, cy, a, b = (float(v) for v in start[:4])
    h, w = chroma.shape[:2]
    if a < 2 or b < 2 or h < 4 or w < 4:
        return None
    f = max(1, math.ceil(min(a, b) / max_half))
    if f > 1:
        h, w = h // f, w // f
        chroma = chroma[:h * f, :w * f].reshape(h, f, w, f).mean(axis=(1, 3))
        cx, cy, a, b, max_sigma = cx / f, cy / f, a / f, b / f, max_sigma / f
    ys, xs = np.mgrid[0:h, 0:w]
    xs = xs.ravel() + 0.5
    ys = ys.ravel() + 0.5
    vals = chroma.astype(np.float64).ravel()
    rel = np.abs(xs - cx) / a + np.abs(ys - cy) / b
    inner, outer = vals[rel < 0.7], vals[rel > 1.3]
    if inner.size < 4 or outer.size < 4:
        return None
    face0, bg0 = float(np.percentile(inner, 75)), float(np.median(outer))
    if face0 <= bg0:
        return None
    # the middle holds the legend, and only the face's level: fitted without it
    keep = rel >= inner_skip
    xs, ys, vals = xs[keep], ys[keep], vals[keep]
    p0 = np.array([cx, cy, a, b, 1.0, face0, bg0, 0.0, 0.0])
    lo = [cx - 0.5 * a, cy - 0.5 * b, 0.5 * a, 0.5 * b, 0.3, -np.inf, -np.inf, -np.inf, -np.inf]
    hi = [cx + 0.5 * a, cy + 0.5 * b, 2.0 * a, 2.0 * b, max_sigma, np.inf, np.inf, np.inf,
          np.inf]

    last: list = [None, None]

    def resid(p):
        # the model and its Jacobian in one pass; least_squares asks for the Jacobian at
        # the point it has just evaluated
        model, last[1] = _blurred_diamond(p, xs, ys, jac=True)
        last[0] = p.copy()
        return model - vals

    def jac(p):
        if last[0] is None or not np.array_equal(p, last[0]):
            resid(p)
        return last[1]

    try:
        res = least_squares(resid, p0, jac=jac, bounds=(lo, hi), loss='soft_l1',
                            f_scale=robust * (face0 - bg0), x_scale='jac', max_nfev=max_nfev,
                            xtol=1e-4, ftol=1e-4)
    except (ValueError, np.linalg.LinAlgError):
        return None
    fcx, fcy, fa, fb, fs, face, bg = (float(v) for v in res.x[:7])
    if res.status <= 0 or face <= bg:
        return None
    if not (0.505 * a < fa < 1.99 * a and 0.505 * b < fb < 1.99 * b and fs < 0.99 * max_sigma):
        return None
    return fcx * f, fcy * f, fa * f, fb * f, fs * f, face, bg


#: refine_rectangle's top-edge stretches (fractions of the face's width): clear of a centred
#: legend (the catalogue's WORK ZONE / END lines start at 0.17 of the face's width) and of
#: the side lines' blur.  Over the middle (0.2-0.45, 0.55-0.8), tuning regulatory P / R
#: 0.975 / 0.957, dusk 0.964 / 0.947; here 0.979 / 0.955, dusk 0.971 / 0.951.
RECT_TOP_STRETCHES = ((0.06, 0.2), (0.8, 0.94))


def _shifted_offsets(img: np.ndarray, segs: np.ndarray, nvecs: np.ndarray, prof: tuple,
                     min_contrast: float, shifts: Sequence[float] = (1.5, 3.0)
                     ) -> Optional[np.ndarray]:
    """:func:`_edge_offsets` of edge stretches moved out (against their inward normals) by
    each of ``shifts`` px in turn (negative: moved in), as offsets from where they were: the
    first shift at which every stretch shows a step short of the search's outer end (the
    edge is not further out still).  None when none does or a stretch leaves ``img``."""
    outer = float(_PROFILE_U0[prof[3][::_PROFILE_SIG.size]].min())
    for sh in shifts:
        off = _edge_offsets(img, segs - sh * nvecs[:, None], nvecs, prof, min_contrast)
        if off is None:
            continue
        if (off > outer + 0.1).all():
            return off - sh
    return None


def _white_sides(img: np.ndarray, x: float, w: float, y0: float, y1: float, prof: tuple,
                 min_contrast: float) -> Optional[np.ndarray]:
    """The left and right edge offsets (from ``x`` and ``x + w``, inwards) of a two-colour
    sign's white part (rows ``y0`` to ``y1``) on two stretches each (20-45 % and 55-80 % of
    its height): ``(2, 2)``, NaN where a stretch shows no step; None when the part is too
    short or a stretch leaves ``img``."""
    if y1 - y0 < 4:
        return None
    segs, nvecs = _side_stretches(x, w, y0, y1 - y0)
    off = _edge_offsets(img, segs, nvecs, prof, min_contrast, missing=True)
    return None if off is None else off.reshape(2, 2)


def _hysteresis(mask: np.ndarray, prob_lo: np.ndarray, thr: np.ndarray, smooth_px: int
                ) -> np.ndarray:
    """``mask`` filled in from the mask of ``prob_lo`` (the likelihood with a lower
    brightness gate, smoothed and thresholded like it): each blob of the latter that holds
    two or more blobs of ``mask`` is added within their box.  A small dim plaque whose
    legend darkens half its pixels below the gate is left in fragments, which its dim
    pixels join again; dim pixels never make a blob, nor grow a single one (real cones and
    brick came out as more false detections), nor grow past the bright pixels' box (a dusk
    sign's dim white part, a sky of its colour)."""
    # only around the bright pixels (the box of them all, and the blur's reach)
    bx, by, bw, bh = cv2.boundingRect(mask)
    pad = max(1, smooth_px)
    H, W = mask.shape
    wx0, wy0 = max(0, bx - 2 * pad), max(0, by - 2 * pad)
    wx1, wy1 = min(W, bx + bw + 2 * pad), min(H, by + bh + 2 * pad)
    win = (slice(wy0, wy1), slice(wx0, wx1))
    part = prob_lo[win]
    if smooth_px > 1:
        part = cv2.blur(part, (smooth_px, smooth_px))
    lo = cv2.compare(part, thr[win], cv2.CMP_GE)
    hi = mask[win]
    # the lower gate passes a superset and the blur keeps the order: lo holds hi
    if cv2.countNonZero(lo) == cv2.countNonZero(hi):
        return mask
    n_hi, lab_hi, stats, _ = cv2.connectedComponentsWithStats(hi, connectivity=8)
    _, lab_lo = cv2.connectedComponents(lo, connectivity=8)
    boxes: dict = {}                 # dim blob -> its bright pixels' box (x0, y0, x1, y1)
    count: dict = {}
    # the dim blob of each bright blob: the one at its first pixel (compiled: one pass)
    keys = label_at_first_pixel(lab_hi, n_hi, lab_lo).tolist()
    for key, (x, y, w, h, _) in zip(keys[1:], stats.tolist()[1:]):
        b = boxes.get(key)
        count[key] = count.get(key, 0) + 1
        boxes[key] = (x, y, x + w, y + h) if b is None else (
            min(b[0], x), min(b[1], y), max(b[2], x + w), max(b[3], y + h))
    out = mask.copy()
    sub_out = out[win]
    for key, (x0, y0, x1, y1) in boxes.items():
        if key == 0 or count[key] < 2:
            continue
        sl = (slice(y0, y1), slice(x0, x1))
        sub_out[sl][lab_lo[sl] == key] = 255
    return out


def _white_span(rows: np.ndarray, x0: int) -> Optional[tuple[float, float]]:
    """The columns (image coordinates: ``x0`` is the mask's first column) of a two-colour
    sign's white part: the longest run of columns white in at least 0.3 of its white rows
    ``rows`` (a boolean mask: a column through a bold legend's strokes is white above and
    below them, one beside the sign hardly ever); None without any."""
    if not len(rows):
        return None
    cols = np.flatnonzero(np.diff(np.r_[0, (rows.mean(axis=0) >= 0.3).astype(np.int8), 0]))
    if not cols.size:
        return None
    starts, ends = cols[0::2], cols[1::2]
    k = int(np.argmax(ends - starts))
    return float(x0 + starts[k]), float(x0 + ends[k])


def _side_stretches(x: float, w: float, y: float, h: float,
                    at: tuple = ((0.2, 0.45), (0.55, 0.8))) -> tuple[np.ndarray, np.ndarray]:
    """A rectangle's side stretches (the left edge ``x`` and right edge ``x + w`` of rows
    ``y`` to ``y + h``, at the fractions ``at`` of the height: 20-45 % and 55-80 %) and
    their inward normals, in the order left, right, left, right: ``((4, 2, 2), (4, 2))``."""
    segs = np.array([((xe, y + f0 * h), (xe, y + f1 * h))
                     for f0, f1 in at for xe in (x, x + w)], float)
    return segs, np.array([(1.0, 0.0), (-1.0, 0.0)] * 2)


#: rectangle_lean's side stretches (fractions of the face's height): its upper and lower
#: ends, a quarter of the height each
LEAN_STRETCHES = ((0.08, 0.33), (0.67, 0.92))


def rectangle_lean(value: np.ndarray, face: Sequence[float], size: float,
                   border_rel: float = 0.03, margin_rel: float = 0.015,
                   min_contrast: float = 0.25) -> Optional[tuple[float, float]]:
    """How far a rectangular sign leans: the slopes (dx / dy) of its left and right edges.

    ``face = (left, top, right, bottom)``: its face's edges (the border line's inner edge,
    continuous coordinates in ``value``), e.g. from :func:`refine_rectangle` and the white
    part's bottom; ``size``: its shorter side (px), for the border line and margin as
    there.  Each side is measured on the brightness (:func:`_edge_offsets`) on two
    stretches, over the upper and lower quarters of the face (:data:`LEAN_STRETCHES`:
    for a two-colour sign one on each part); the slope is the measured edge's shift
    between them over their distance.  A sign turned about the axis towards the camera
    (a post leaning 1-3 degrees) has both sides lean alike, and its box, the bounding
    box of the turned face, is wider and taller than the face measured in the middle.
    Returns ``(left slope, right slope)`` or None when the face is too small (under 12
    px high) or a stretch leaves ``value`` or shows no face-to-border step.
    """
    left, top, right, bottom = (float(v) for v in face)
    h, w = bottom - top, right - left
    if h < 12 or w < 6:
        return None
    border, margin = border_rel * size, margin_rel * size
    prof = _edge_profile(min(0.5 * w, h), border, margin)
    inset = 0.5 * (border + margin)            # as refine_rectangle: the edge mid-search
    x0, x1 = left - inset, right + inset
    segs, nvecs = _side_stretches(x0, x1 - x0, top, h, LEAN_STRETCHES)
    off = _edge_offsets(np.ascontiguousarray(value, dtype=np.float32), segs, nvecs, prof,
                        min_contrast)
    if off is None:
        return None
    dy = h * (np.mean(LEAN_STRETCHES[1]) - np.mean(LEAN_STRETCHES[0]))
    return float(off[2] - off[0]) / dy, float(off[1] - off[3]) / dy


def refine_rectangle(value: np.ndarray, box: Sequence[float], size: float,
                     border_rel: float = 0.03, margin_rel: float = 0.015,
                     max_change: float = 0.2, min_contrast: float = 0.25,
                     bottom: Optional[float] = None, free_top: bool = False,
                     top_at: tuple = RECT_TOP_STRETCHES, inward: Sequence[float] = ()
                     ) -> Optional[tuple[Optional[float], Optional[float], Optional[float],
                                         Optional[float]]]:
    """Sub-pixel left, right and top edges of a rectangular sign's orange face.

    ``box = (x, y, w, h)``: a first estimate of the orange part (continuous coordinates), e.g.
    its hull's box; ``size``: the sign's shorter side (its width for a two-colour sign, px).
    As :func:`refine_diamond`, on the brightness: the left and right edges on two stretches
    each (20-45 % and 55-80 % of the height), the top edge on two near the corners (``top_at``,
    fractions of the width: a rectangle's legend is centred and its first line starts just
    under the top border, so stretches over the middle measured the legend's dark strokes as
    part of the edge profile), each fitted with the face / border line / margin / background
    model; the line's width and the margin outside it are ``border_rel`` and ``margin_rel`` x
    ``size`` (defaults: the catalogue's rectangles, a line 3 % of the shorter side at 1.5-4.5 %
    from the edge).  The bottom of the orange part (a divider line over the white part, or the
    sign's own bottom) is not measured; ``bottom``: the row where the caller found the sign's
    face to end (the white part's last white row of a two-colour sign), whose edge is measured
    the same way.

    ``free_top``: the sign is known to be a rectangle (a two-colour sign's white part was
    found below it): its top is measured on those of its stretches that show a step, and
    is None when neither does (a small sign's legend runs into its top line).

    A stretch whose profiles would leave ``value`` (a sign at the image's edge) is not
    measured: a side (or the top) with such a stretch is returned as None.  A side of the
    orange part without a step is measured on the white part below it when ``bottom`` is
    given (:func:`_white_sides`), else with its stretches moved out by 1.5 or 3 px
    (:func:`_shifted_offsets`: a hull short of a pale face), then in by each of ``inward``
    (px: a hull that took in a pale wall beside the face); without ``bottom`` such a side
    fails the fit (the blob may be a diamond merged with a sky of its colour).

    Returns the face's ``(left, right, top, bottom)`` (``bottom`` None when not asked for or
    not measurable) or None when a side (on neither part) or top stretch in ``value`` shows
    no face-to-border step (but ``free_top``), neither side is measured, or the width moves
    by more than ``max_change``.
    """
    x, y, w, h = (float(v) for v in box[:4])
    if w < 6 or h < 4:
        return None
    img = np.ascontiguousarray(value, dtype=np.float32)
    border, margin = border_rel * size, margin_rel * size
    prof = _edge_profile(min(0.5 * w, h), border, margin)
    # start half-way between the hull's edge and the face's edge without margin and line:
    # the face's edge is then within the search either way
    inset = 0.5 * (border + margin)
    x, y, w = x + inset, y + inset, w - 2 * inset
    # per stretch pair: left, right (20-45 % and 55-80 % of the height), top (``top_at``)
    sides, side_n = _side_stretches(x, w, y, h)
    tops = np.array([((x + g0 * w, y), (x + g1 * w, y)) for g0, g1 in top_at], float)
    segs = np.concatenate([sides[:2], tops[:1], sides[2:], tops[1:]])
    nvecs = np.concatenate([side_n[:2], [(0.0, 1.0)], side_n[2:], [(0.0, 1.0)]])
    # a stretch whose profiles leave the image (a sign at its edge) is not measured
    u = prof[0]
    ends = np.concatenate([segs + u[0] * nvecs[:, None], segs + u[-1] * nvecs[:, None]], 1)
    inside = ((ends >= 0.5).all(axis=(1, 2)) & (ends[..., 0] <= img.shape[1] - 0.5).all(1)
              & (ends[..., 1] <= img.shape[0] - 0.5).all(1))
    if not inside.any():
        return None
    off = np.full(len(segs), np.nan)
    o_ = _edge_offsets(img, segs[inside], nvecs[inside], prof, min_contrast, missing=True)
    if o_ is None:
        return None
    off[inside] = o_
    side = off.reshape(2, 3)                  # the two stretches' left, right, top offsets
    shown = inside.reshape(2, 3)
    if not (free_top or (np.isfinite(side[:, 2]) | ~shown[:, 2]).all()):
        return None
    lost = shown[:, :2] & ~np.isfinite(side[:, :2])
    if lost.any():
        # a side of the orange part shows no step (a small plaque's legend runs up to
        # it, a dim one's line merges with a dark background): that side of the white
        # part below it, when there is one
        if bottom is None:
            return None         # (not known to be a rectangle: a diamond merged with a sky)
        white = _white_sides(img, x, w, y + h, float(bottom) - inset, prof, min_contrast)
        for k in (0, 1):
            if not lost[:, k].any():
                continue
            if white is not None and np.isfinite(white[:, k]).all():
                side[:, k] = white[:, k]
                continue
            # or the edge lies beyond the search (a hull short of a pale face's side):
            # the side's stretches moved out by a search's width or two
            got = _shifted_offsets(img, segs[[k, 3 + k]], nvecs[[k, 3 + k]], prof,
                                   min_contrast, (1.5, 3.0) + tuple(-v for v in inward))
            if got is None:
                return None
            side[:, k] = got
    # a side off the image is the box's own (the caller clips it to the image)
    left = x + float(side[:, 0].mean()) if shown[:, 0].all() else None
    right = x + w - float(side[:, 1].mean()) if shown[:, 1].all() else None
    tops = side[np.isfinite(side[:, 2]), 2]
    top = y + float(tops.mean()) if tops.size else None
    if left is None and right is None:
        return None
    if left is not None and right is not None and not abs(
            (right - left) / (w + 2 * inset) - 1) <= max_change:
        return None
    low = None
    if bottom is not None:
        yb = float(bottom) - inset
        ob = _edge_offsets(img, np.array([((x + 0.2 * w, yb), (x + 0.45 * w, yb)),
                                          ((x + 0.55 * w, yb), (x + 0.8 * w, yb))]),
                           np.array([(0.0, -1.0), (0.0, -1.0)]), prof, min_contrast)
        if ob is not None:
            low = yb - 0.5 * (ob[0] + ob[1])
    return left, right, top, low


def _white_columns(bgr: np.ndarray, left: float, right: float, r0: int, r1: int, c0: int,
                   c1: int) -> Optional[np.ndarray]:
    """Per column ``c0``..``c1`` (inclusive): the share of rows ``r0``..``r1`` (exclusive)
    that are white by a two-colour sign's white part's own level (brightness at least 0.85
    x its 75th percentile between the face's sides ``left`` and ``right``; saturation at
    most 90 of 255).  None when no column lies between the sides."""
    hsv = cv2.cvtColor(bgr[r0:r1, c0:c1 + 1], cv2.COLOR_BGR2HSV)
    v, sat = hsv[..., 2].astype(np.float32), hsv[..., 1]
    inner = v[:, int(math.ceil(left)) + 1 - c0:int(right) - 1 - c0]
    if inner.size == 0:
        return None
    level = float(np.percentile(inner, 75))
    return ((v >= 0.85 * level) & (sat <= 90)).mean(axis=0)


def white_beyond(bgr: np.ndarray, face: Sequence[float], rows: Sequence[float],
                 gap: float) -> bool:
    """Whether a two-colour sign's white part (``rows = (top, bottom)``, its middle 10-90 %
    looked at) is white (:func:`_white_columns`, at least half the rows) on every column of
    ``gap`` px just outside either side of ``face = (left, right)``: a side measured inside
    the sign.  False at the image's edge."""
    left, right = float(face[0]), float(face[1])
    h, w = bgr.shape[:2]
    top, bottom = float(rows[0]), float(rows[1])
    r0, r1 = int(math.ceil(top + 0.1 * (bottom - top))), int(bottom - 0.1 * (bottom - top))
    g = max(1, int(round(gap)))
    c0, c1 = int(math.floor(left)) - g, int(math.ceil(right)) + g - 1
    if r1 - r0 < 3 or right - left < 4 or c0 < 0 or c1 >= w or r0 < 0 or r1 > h:
        return False
    share = _white_columns(bgr, left, right, r0, r1, c0, c1)
    if share is None:
        return False
    white = share >= 0.5
    return bool(white[:g].all() or white[-g:].all())


def white_part_ends(bgr: np.ndarray, face: Sequence[float], rows: Sequence[float],
                    max_out: float, min_gap: float = 2.0
                    ) -> tuple[Optional[float], Optional[float]]:
    """Where a two-colour sign's white part ends left and right, when it runs on past the
    face's sides as measured on its orange part.

    A small plaque in dim (winter) light is cut by its legend into pieces, and the sign was
    boxed to the piece that became a blob.  ``face = (left, right)``: the face's edges
    (continuous image coordinates); ``rows = (top, bottom)``: the white part's rows.  Per
    column, the share of the white part's middle rows (10-90 %) that are white (brightness
    at least 0.85 x the white part's own, its 75th percentile between the sides;
    saturation at most 90 of 255); from a pixel inside each side outwards the part runs on
    from the first column where that share is at least a half (the side may lie on a
    legend stroke) and ends at the first column where it is not (the border line, the
    background).  Returns the face's new left and right edges (the end columns' inner
    boundaries) where the part runs on at least ``min_gap`` px past the side and ends
    within ``max_out`` px of it; else None for that side (also at the image's edge)."""
    left, right = float(face[0]), float(face[1])
    h, w = bgr.shape[:2]
    top, bottom = float(rows[0]), float(rows[1])
    r0, r1 = int(math.ceil(top + 0.1 * (bottom - top))), int(bottom - 0.1 * (bottom - top))
    c0, c1 = int(math.floor(left - max_out)), int(math.ceil(right + max_out))
    if r1 - r0 < 3 or right - left < 4 or c0 < 0 or c1 >= w or r0 < 0 or r1 > h:
        return None, None
    share = _white_columns(bgr, left, right, r0, r1, c0, c1)
    if share is None:
        return None, None

    def end(start: int, step: int) -> Optional[int]:
        c, seen = start, False
        while 0 <= c - c0 < share.size:
            white = share[c - c0] >= 0.5
            if seen and not white:
                return c
            # (the side may lie on a legend stroke: the run starts at its first white column)
            seen = seen or white
            c += step
        return None

    out: list = [None, None]
    stop = end(int(math.ceil(left)), -1)              # the first column left of the run
    if stop is not None and left - (stop + 1) >= min_gap:
        out[0] = float(stop + 1)
    stop = end(int(right) - 1, 1)
    if stop is not None and stop - right >= min_gap:
        out[1] = float(stop)
    return out[0], out[1]


# --- seed 002: linear RGB thresholds chosen by a Boolean LP ------------------------------

_RGB_Q = 8            # RGB quantisation step for the LP's pixel bins


def rgb_histograms(bgr: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positive / negative pixel counts per quantised RGB bin (32^3 bins)."""
    q = (bgr // _RGB_Q).astype(np.int64)
    n = 256 // _RGB_Q
    idx = (q[..., 2] * n + q[..., 1]) * n + q[..., 0]       # R, G, B order
    m = mask.astype(bool)
    return (np.bincount(idx[m], minlength=n ** 3).astype(np.float64),
            np.bincount(idx[~m], minlength=n ** 3).astype(np.float64))


def _bin_centres() -> np.ndarray:
    n = 256 // _RGB_Q
    r, g, b = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing='ij')
    return (np.column_stack([r.ravel(), g.ravel(), b.ravel()]) * _RGB_Q + _RGB_Q / 2.0)


def candidate_rgb_thresholds(pos_rgb: np.ndarray, levels: Sequence[float] = (
        0.02, 0.1, 0.25, 0.5)) -> np.ndarray:
    """Candidate thresholds (alpha, beta, lambda, t) of seed 002 eq. 1.

    Directions: every (alpha, beta, lambda) in {-1, -0.5, 0, 0.5, 1}^3 up to scale; levels t:
    quantiles of the positive pixels' projections (a threshold keeps at least that share
    of them).
    """
    dirs = set()
    for a, b, c in itertools.product((-1.0, -0.5, 0.0, 0.5, 1.0), repeat=3):
        v = np.array([a, b, c])
        if not v.any():
            continue
        dirs.add(tuple(np.round(v / np.abs(v).max(), 3)))
    out = []
    for d in sorted(dirs):
        proj = pos_rgb @ np.array(d)
        for q in levels:
            out.append((*d, float(np.quantile(proj, q))))
    return np.array(out, np.float64)


@dataclass(frozen=True)
class RgbLpModel:
    """The selected thresholds rho* of seed 002 (rows alpha, beta, lambda, t on R, G, B)."""

    thresholds: np.ndarray
    metadata: dict = field(default_factory=dict)

    def mask(self, bgr: np.ndarray) -> np.ndarray:
        """uint8 count of thresholds each pixel passes (0 = none)."""
        count = np.zeros(bgr.shape[:2], np.uint8)
        f = bgr.astype(np.float32)
        for a, b, c, t in self.thresholds:
            # cv2.transform: BGR -> alpha R + beta G + lambda B
            proj = cv2.transform(f, np.array([[c, b, a]], np.float32))
            count += (proj >= t).astype(np.uint8)
        return count

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Arrays for an ``.npz`` next to the colour model."""
        return {'rgb_lp_thresholds': self.thresholds.astype(np.float64)}


def fit_rgb_lp(pos: np.ndarray, neg: np.ndarray, w: float = 1.0, max_thresholds: int = 6,
               max_candidates: int = 80, time_limit: float = 60.0,
               max_bins: int = 3000) -> RgbLpModel:
    """Choose rho* = argmin FP(rho) + w FN(rho) over subsets of thresholds (seed 002, eq. 2).

    Boolean linear program over quantised RGB bins with pixel counts as weights: x_k selects
    threshold k, y_i = 1 when positive bin i passes a selected threshold (y_i <= sum_k A_ik
    x_k), z_j = 1 when negative bin j does (deg_j z_j >= sum_k A_jk x_k); minimise
    sum_j n_j z_j + w sum_i p_i (1 - y_i), with at most ``max_thresholds`` thresholds.
    Solved with ``scipy.optimize.milp`` (HiGHS).

    Args:
        pos, neg: counts from :func:`rgb_histograms`.
        w: the weight of a false negative relative to a false positive, in units of the
            class-size ratio (1 = balanced).
        max_thresholds: cardinality bound (each threshold costs time per frame).
        max_candidates: candidates kept after a single-threshold pre-screen.
        max_bins: only the heaviest positive / negative colour bins enter the program (the
            rest hold a small share of the pixels; the reported rates count every bin).
        time_limit: solver time limit in seconds.

    Returns:
        The :class:`RgbLpModel`.
    """
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import csr_matrix, hstack, identity, vstack

    centres = _bin_centres()
    ip, ineg = np.nonzero(pos)[0], np.nonzero(neg)[0]
    ip = ip[np.argsort(pos[ip])[::-1][:max_bins]]
    ineg_all = ineg
    if len(ip) == 0 or len(ineg) == 0:
        raise ModelError('the RGB threshold LP needs both sign and background pixels')
    # w is relative to the class sizes: FP + w (N_neg / N_pos) FN, so w = 1 weighs the
    # classes equally (raw pixel counts make "no threshold at all" optimal: signs are <0.1 %)
    w = w * float(neg.sum()) / float(pos.sum())
    pw, nw = pos[ip], neg[ineg]
    rep = np.repeat(centres[ip], np.minimum(pw, 50).astype(int), axis=0)
    cands = candidate_rgb_thresholds(rep)
    # Pre-screen: the single-threshold objective; keep the best candidates.
    a_pos = (centres[ip] @ cands[:, :3].T) >= cands[:, 3]
    a_neg = (centres[ineg] @ cands[:, :3].T) >= cands[:, 3]
    single = nw @ a_neg + w * (pw @ ~a_pos)
    keep = np.argsort(single)[:max_candidates]
    cands, a_pos, a_neg = cands[keep], a_pos[:, keep], a_neg[:, keep]
    # Only negative bins that some candidate passes matter; the heaviest of them.
    live = np.nonzero(a_neg.any(axis=1))[0]
    live = live[np.argsort(nw[live])[::-1][:max_bins]]
    a_neg, nw = a_neg[live], nw[live]
    k, npos, nneg = len(cands), len(ip), len(nw)
    # variables: x (k), y (npos), z (nneg)
    c = np.concatenate([np.zeros(k), -w * pw, nw]) / (pw.sum() * w + nw.sum())
    ap, an = csr_matrix(a_pos.astype(np.float64)), csr_matrix(a_neg.astype(np.float64))
    deg = np.asarray(an.sum(axis=1)).ravel()
    from scipy.sparse import diags
    rows = [
        hstack([-ap, identity(npos), csr_matrix((npos, nneg))]),          # y - A x <= 0
        hstack([an, csr_matrix((nneg, npos)), -diags(deg)]),              # A x - deg z <= 0
        hstack([csr_matrix(np.ones((1, k))), csr_matrix((1, npos + nneg))]),  # sum x <= m
    ]
    A = vstack(rows).tocsr()
    ub = np.concatenate([np.zeros(npos + nneg), [max_thresholds]])
    res = milp(c, constraints=LinearConstraint(A, -np.inf, ub),
               integrality=np.ones(k + npos + nneg), bounds=Bounds(0, 1),
               options={'time_limit': time_limit, 'disp': False})
    if res.x is None:
        raise ModelError(f'RGB threshold LP failed: {res.message}')
    sel = np.nonzero(res.x[:k] > 0.5)[0]
    chosen = cands[sel]
    allc = centres[ineg_all]
    pass_all = np.zeros(len(ineg_all), bool)
    for a, b, c_, t in chosen:
        pass_all |= allc @ np.array([a, b, c_]) >= t
    pos_all = np.nonzero(pos)[0]
    pass_pos = np.zeros(len(pos_all), bool)
    for a, b, c_, t in chosen:
        pass_pos |= centres[pos_all] @ np.array([a, b, c_]) >= t
    meta = {'w_effective': w, 'candidates': int(k), 'selected': int(len(sel)),
            'fn_rate': float(pos[pos_all][~pass_pos].sum() / pos.sum()),
            'fp_rate': float(neg[ineg_all][pass_all].sum() / neg.sum()),
            'status': str(res.message), 'mip_gap': float(getattr(res, 'mip_gap', 0.0) or 0.0)}
    return RgbLpModel(chosen, meta)


# --- the horizon --------------------------------------------------------------------------

def estimate_horizon(bgr: np.ndarray, width: int = 320, top: float = 0.3, bottom: float = 0.95,
                     min_angle: float = 15.0, max_angle: float = 75.0, min_len: float = 0.07,
                     min_pairs: int = 3, max_spread: float = 0.04) -> Optional[float]:
    """The horizon row of one frame from the vanishing point of the road's lane lines.

    Line segments (Canny + probabilistic Hough, on the frame scaled to ``width``) between
    rows ``top`` and ``bottom`` (fractions of the height) that slope by ``min_angle`` ..
    ``max_angle`` degrees are split into left-leaning (rising to the right) and
    right-leaning ones; every left / right pair is intersected, and the length-weighted
    median row of the intersections is the horizon (a level road's lane lines meet there).

    Returns:
        The horizon row in pixels of ``bgr``, or None when the estimate is unreliable: fewer
        than ``min_pairs`` pairs, or the weighted median absolute deviation of the
        intersection rows above ``max_spread`` x the height, or a vanishing point below the
        top of the segments that define it.
    """
    H, W = bgr.shape[:2]
    if H < 16 or W < 16:
        return None
    f = min(1.0, width / float(W))
    small = cv2.resize(bgr, (max(16, int(W * f)), max(16, int(H * f))),
                       interpolation=cv2.INTER_AREA) if f < 1.0 else bgr
    h, w = small.shape[:2]
    y0, y1 = int(top * h), int(bottom * h)
    gray = cv2.cvtColor(small[y0:y1], cv2.COLOR_BGR2GRAY)
    edges = cv2.Canny(gray, 60, 160)
    segs = cv2.HoughLinesP(edges, 1, np.pi / 180, 18, minLineLength=max(6, int(min_len * w)),
                           maxLineGap=4)
    if segs is None or len(segs) < 2:
        return None
    seg = np.asarray(segs).reshape(-1, 4).astype(np.float64)
    seg[:, [1, 3]] += y0
    dx, dy = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    ang = np.degrees(np.arctan2(np.abs(dy), np.abs(dx)))
    keep = (ang >= min_angle) & (ang <= max_angle)
    seg, dx, dy = seg[keep], dx[keep], dy[keep]
    if len(seg) < 2:
        return None
    slope = dy / np.where(dx == 0, 1e-9, dx)
    length = np.hypot(dx, dy)
    left, right = slope < 0, slope > 0           # y down: a left lane line rises to the right
    if not left.any() or not right.any():
        return None
    # lines y = y_a + m (x - x_a); intersect every left with every right
    la, ra = seg[left], seg[right]
    ml, mr = slope[left][:, None], slope[right][None, :]
    xl, yl = la[:, 0][:, None], la[:, 1][:, None]
    xr, yr = ra[:, 0][None, :], ra[:, 1][None, :]
    x = (yr - yl + ml * xl - mr * xr) / (ml - mr)
    y = yl + ml * (x - xl)
    wgt = length[left][:, None] * length[right][None, :]
    # the vanishing point lies above both segments and not far outside the frame
    top_l = np.minimum(la[:, 1], la[:, 3])[:, None]
    top_r = np.minimum(ra[:, 1], ra[:, 3])[None, :]
    ok = ((y <= np.minimum(top_l, top_r) + 2) & (y >= 0.05 * h) & (x >= -0.25 * w)
          & (x <= 1.25 * w))
    if np.count_nonzero(ok) < min_pairs:
        return None
    ys, ws = y[ok], wgt[ok]
    order = np.argsort(ys)
    ys, ws = ys[order], ws[order]
    cw = np.cumsum(ws)
    med = float(ys[np.searchsorted(cw, 0.5 * cw[-1])])
    dev = np.abs(ys - med)
    o2 = np.argsort(dev)
    mad = float(dev[o2][np.searchsorted(np.cumsum(ws[o2]), 0.5 * cw[-1])])
    if mad > max_spread * h:
        return None
    return med / f


# --- the detector ------------------------------------------------------------------------

def relative_measure(metadata: Any) -> Optional[tuple[float, float]]:
    """The box-measurement levels a model file asks for (metadata ``measure``).

    ``{"mode": "relative", "edge_rel": a, "blur_rel": b}``: every orange blob's box is the
    bounding box of its core, the face pixels with likelihood at least ``base + a (face -
    base)``, grown by 1-px rings whose mean likelihood is at least ``base + b (face -
    base)``, where face and base are that blob's own face and background likelihood levels
    (see ``ColorDetector._relative_levels``); the shape, legend and mounting-height tests
    still use the absolute face.  For tables that score a sign's blended edge smoothly
    (Gentle AdaBoost).  Absent (old models) or ``"mode": "absolute"``: the configured
    ``weak_threshold`` and ``blur_like`` (tuned for step-shaped tables) give the box.

    Raises:
        ModelError: a malformed ``measure`` entry.
    """
    d = metadata.get('measure') if metadata else None
    if not d:
        return None
    try:
        mode = d.get('mode', 'absolute')
        if mode == 'absolute':
            return None
        if mode != 'relative':
            raise ValueError(f'unknown mode {mode!r}')
        a, b = float(d['edge_rel']), float(d['blur_rel'])
        if not (0.0 <= a <= 1.0 and 0.0 <= b <= 1.0):
            raise ValueError('edge_rel and blur_rel must lie in [0, 1]')
        return a, b
    except (AttributeError, KeyError, TypeError, ValueError) as exc:
        raise ModelError(f'malformed measure metadata {d!r}: {exc}') from None


class ColorDetector:
    """Colour sign detector over a :class:`ColorModel` (and optional seed 002 thresholds).

    Args:
        model: the colour model (tables and prior).
        config: detector parameters.
        rgb_lp: thresholds for ``method='rgb_lp'``.

    Raises:
        ModelError: the model lacks a configured colour, or ``rgb_lp`` is missing.
    """

    def __init__(self, model: ColorModel, config: DetectorConfig = DetectorConfig(),
                 rgb_lp: Optional[RgbLpModel] = None) -> None:
        self.model = model
        self.config = config
        self.rgb_lp = rgb_lp
        #: places (16 px cells) of the last frame's blobs rejected as drums or cones
        self.channelizers: set = set()
        if config.method == 'rgb_lp' and rgb_lp is None:
            raise ModelError("method 'rgb_lp' needs the seed 002 thresholds (train them with "
                             'workzone-ros train color --rgb-lp)')
        colors = config.colors if config.method != 'rgb_lp' else ('orange',)
        self.colors = tuple(colors)
        self._idx = {c: model.index(c) for c in self.colors} if config.method == 'learned' \
            else {}
        self._lut_u8 = {c: np.ascontiguousarray(
            np.round(model.luts[i] * _P_SCALE).astype(np.uint8).reshape(-1))
            for c, i in self._idx.items()}
        self._vmin = {c: model.v_min[i] for c, i in self._idx.items()}
        self._cache: dict[tuple, Any] = {}
        self.debug: Optional[list] = None      # a list: rejected / measured blobs land here
        self._gains: Optional[tuple] = None
        self._sat_norm = model.sat_norm if config.method == 'learned' else None
        self._sat_tab: Optional[np.ndarray] = None
        g = model.extras.get('geometry')
        self._geometry = ((float(g[0]), float(g[1]), float(g[2] if len(g) >= 3 else g[1]))
                          if g is not None and len(g) >= 2 else None)
        self._frame_no = 0
        self._horizons: list[tuple[int, float]] = []      # (frame number, row)
        self._ref_row: Optional[float] = None             # this frame's reference row
        self._peels_left = 0                               # peels this frame may still do
        # half-diagonals (a, b) of this frame's faces measured on sharp edges: their box
        # takes ``diamond_box_bias`` (a face keeps them when moved to its blob's window)
        self._sharp_faces: set[tuple[float, float]] = set()
        self._relative = relative_measure(model.metadata)
        self._intrinsics: Optional[tuple[float, float, float, float]] = None

    def set_camera(self, intrinsics: Optional[Sequence[float]]) -> None:
        """The frames' intrinsics (fx, fy, cx, cy in pixels, e.g. from CameraInfo; None:
        unknown), compared with the model's training camera (``camera_match``)."""
        new = None if intrinsics is None else tuple(float(v) for v in intrinsics)
        if new is not None and len(new) != 4:
            raise ValueError('intrinsics are (fx, fy, cx, cy)')
        if new != self._intrinsics:
            self._intrinsics = new
            self._cache.clear()

    def foreign_prior(self) -> float:
        """The location-free prior used on another camera's frames (``foreign_prior``).

        0 in the config: the model prior's mean over its ROI divided by the orange table's
        peak.  The seed's posterior multiplies two factors each scaled to a peak of 1 (the
        heat map by construction; the table is scaled here), so the posterior threshold
        on another camera is the one the model applies at an average place of its own
        ROI, relative to its most sign-like colour.
        """
        if self.config.foreign_prior > 0.0:
            return float(self.config.foreign_prior)
        peak = 1.0
        if 'orange' in self._idx:
            peak = max(float(self.model.luts[self._idx['orange']].max()), 1e-3)
        return float(min(1.0, self.model.prior.expected() / peak))

    def same_camera(self, width: int, height: int) -> bool:
        """Whether the model's fixed-camera prior and mounting row apply to these frames."""
        if not self.config.camera_match:
            return True
        return self.model.same_camera(width, height, self._intrinsics,
                                      self.config.camera_tolerance)

    def reset(self) -> None:
        """Forget the horizon history (a new camera or clip)."""
        self._frame_no = 0
        self._horizons = []

    def horizon(self) -> Optional[float]:
        """The smoothed horizon row of the last frame (None: no reliable estimate)."""
        cfg = self.config
        recent = [r for k, r in self._horizons if self._frame_no - k <= cfg.horizon_memory]
        return float(np.median(recent)) if recent else None

    def _update_horizon(self, bgr: np.ndarray) -> None:
        cfg = self.config
        self._frame_no += 1
        if (self._frame_no - 1) % max(1, cfg.horizon_every) == 0:
            row = estimate_horizon(bgr)
            if row is not None:
                self._horizons.append((self._frame_no, row))
                self._horizons = self._horizons[-max(1, cfg.horizon_window):]

    def with_config(self, **changes) -> 'ColorDetector':
        """A detector sharing the model with some parameters changed."""
        det = ColorDetector(self.model, replace(self.config, **changes), self.rgb_lp)
        det.set_camera(self._intrinsics)
        return det

    # -- geometry caches --
    def _frame_setup(self, width: int, height: int) -> tuple:
        key = (width, height)
        if key not in self._cache:
            cfg = self.config
            s = int(cfg.scale)
            sw, sh = -(-width // s), -(-height // s)
            own = self.same_camera(width, height)
            if not cfg.use_prior:
                prior = SpatialPrior.uniform(width, height)
            elif own:
                prior = self.model.prior
            else:
                # another camera: the heat map's rows and columns are other directions
                # there, so only its location-free content is kept (seed 000's prior is a
                # property of the training camera, not of the signs)
                prior = SpatialPrior.flat(self.foreign_prior(), width, height)
            p = prior.prior_image(sw, sh)
            thr = np.clip(np.ceil(cfg.threshold / p * _P_SCALE), 0, 255).astype(np.uint8)
            p_full = prior.prior_image(width, height)
            rx, ry, rw, rh = prior.roi_for(width, height) if cfg.use_prior else (
                0, 0, width, height)
            roi = (max(0, rx // s), max(0, ry // s), min(sw, -(-(rx + rw) // s)),
                   min(sh, -(-(ry + rh) // s)))
            self._cache[key] = (s, sw, sh, thr, p_full, roi, own)
        return self._cache[key]

    # -- the public API --
    def detect(self, bgr: np.ndarray, rois: Sequence[Roi] = ()) -> list[Detection]:
        """Detect colour signs in one BGR frame.

        Args:
            bgr: (H, W, 3) uint8 image.
            rois: LiDAR ROIs of this frame (empty when there is no LiDAR).

        Returns:
            Every detected sign, largest first.
        """
        return [c.detection() for c in self.candidates(bgr, rois)]

    def candidates(self, bgr: np.ndarray, rois: Sequence[Roi] = ()) -> list[Candidate]:
        """As :meth:`detect`, returning :class:`Candidate` objects (with shape features)."""
        if bgr.ndim != 3 or bgr.shape[2] != 3 or bgr.dtype != np.uint8:
            raise ValueError(f'expected an (H, W, 3) uint8 BGR image, got {bgr.shape} '
                             f'{bgr.dtype}')
        height, width = bgr.shape[:2]
        s, sw, sh, thr_base, p_full, roi, own = self._frame_setup(width, height)
        cfg = self.config
        self.channelizers = set()   # blobs rejected as banded drums / cones this frame
        self._ref_row = None
        self._peels_left = cfg.peel_max
        self._sharp_faces = set()
        if self._geometry is not None and cfg.use_geometry:
            if cfg.geometry_reference == 'horizon':
                self._update_horizon(bgr)
                self._ref_row = self.horizon()
            elif own:
                # the training camera's horizon row; on another camera the row is unknown
                self._ref_row = self._geometry[0] * height
        # LiDAR ROIs in mask coordinates, expanded by roi_margin.
        lboxes = []
        for r in rois:
            mx, my = r.box.w * cfg.roi_margin, r.box.h * cfg.roi_margin
            x0 = int(max(0, (r.box.x - mx) // s))
            y0 = int(max(0, (r.box.y - my) // s))
            x1 = int(min(sw, math.ceil((r.box.x2 + mx) / s)))
            y1 = int(min(sh, math.ceil((r.box.y2 + my) / s)))
            if x1 > x0 and y1 > y0:
                lboxes.append((x0, y0, x1, y1))
        small = cv2.resize(bgr, (sw, sh), interpolation=cv2.INTER_AREA) if s > 1 else bgr
        self._gains = None
        if cfg.method == 'learned' and small.size:
            # colour constancy outside the table (as the model was trained; None: none)
            self._gains = self.model.balance_gains(small)
        self._sat_tab = None
        if self._sat_norm is not None and 'orange' in self._idx and small.size:
            # frame saturation normalisation (the model was trained this way), measured on
            # a quarter of the mask's pixels
            sub = small[::2, ::2]
            if self._gains is not None:
                sub = apply_gains(sub, self._gains)
            g = saturation_gain(cv2.cvtColor(sub, cv2.COLOR_BGR2HSV), self._sat_norm,
                                self._vmin['orange'])
            if g > 1.0:
                self._sat_tab = saturation_table(g)
        # 1. the colour-only pass over the prior's ROI, exactly as without LiDAR
        cands = self._pass(small, bgr, roi, thr_base, s, thr_base, [])
        cands = nms(cands, cfg.nms_iou, cfg.nms_contain,
                    'area' if cfg.method == 'rgb_lp' else 'confidence')
        # 2. a separate pass, with the ROI threshold, over the LiDAR ROIs that no colour
        # detection explains (its centre in the ROI); it never changes a colour detection
        todo = [b for b in lboxes if not any(
            b[0] <= (c.x + c.w / 2) / s < b[2] and b[1] <= (c.y + c.h / 2) / s < b[3]
            for c in cands)]
        if todo:
            thr = thr_base
            if cfg.method == 'learned':
                thr = thr_base.copy()
                t_roi = np.uint8(min(255, math.ceil(cfg.roi_threshold / cfg.roi_prior
                                                    * _P_SCALE)))
                for x0, y0, x1, y1 in todo:
                    np.minimum(thr[y0:y1, x0:x1], t_roi, out=thr[y0:y1, x0:x1])
            region = (min(b[0] for b in todo), min(b[1] for b in todo),
                      max(b[2] for b in todo), max(b[3] for b in todo))
            extra = self._pass(small, bgr, region, thr, s, thr_base, todo, limit=todo)
            extra = nms(extra, cfg.nms_iou, cfg.nms_contain,
                        'area' if cfg.method == 'rgb_lp' else 'confidence')
            for c in extra:
                if self._in_roi((c.x, c.y, c.w, c.h), s, todo) is not None and all(
                        _iou((c.x, c.y, c.w, c.h), (k.x, k.y, k.w, k.h))[1] <= cfg.nms_contain
                        for k in cands):
                    cands.append(c)
        out = self._fuse(cands, rois, bgr, thr_base)
        for c in out:
            # a sign's box ends at the frame's edge (a two-colour extension or a border
            # growth of a sign the edge cuts reached past it)
            x1, y1 = min(c.x + c.w, float(width)), min(c.y + c.h, float(height))
            c.x, c.y = max(c.x, 0.0), max(c.y, 0.0)
            c.w, c.h = max(x1 - c.x, 1.0), max(y1 - c.y, 1.0)
        return out

    def _pass(self, small: np.ndarray, bgr: np.ndarray, region: tuple, thr_full: np.ndarray,
              s: int, thr_base: np.ndarray, lboxes: list,
              limit: Optional[list] = None) -> list[Candidate]:
        """One detection pass over ``region`` (mask coordinates) with thresholds ``thr_full``.

        ``limit``: only pixels inside these mask-coordinate boxes may form blobs.
        """
        cfg = self.config
        cx0, cy0, cx1, cy1 = region
        crop = small[cy0:cy1, cx0:cx1]
        if crop.size == 0:
            return []
        if self._gains is not None:
            crop = apply_gains(crop, self._gains)
        keep = None
        if limit:
            keep = np.zeros(crop.shape[:2], np.uint8)
            for x0, y0, x1, y1 in limit:
                keep[max(0, y0 - cy0):max(0, y1 - cy0), max(0, x0 - cx0):max(0, x1 - cx0)] = 255
        thr = thr_full[cy0:cy1, cx0:cx1]
        hsv = cv2.cvtColor(crop, cv2.COLOR_BGR2HSV)
        cands: list[Candidate] = []
        if cfg.method == 'learned':
            h, sat, v = cv2.split(hsv)
            idx = cv2.merge([sat, h]).view(np.uint16)[..., 0]      # h * 256 + s
            for color in self.colors:
                if color == 'orange' and self._sat_tab is not None:
                    idx_c = cv2.merge([cv2.LUT(sat, self._sat_tab), h]).view(np.uint16)[..., 0]
                else:
                    idx_c = idx
                prob = full = flat_take(self._lut_u8[color], idx_c)
                if self._vmin[color] > 0:
                    # brightness gate outside the table: too dark for a reliable hue
                    prob = full & cv2.threshold(v, self._vmin[color] - 1, 255,
                                                cv2.THRESH_BINARY)[1]
                raw = prob
                if cfg.smooth_px > 1:
                    # denoise at the mask's resolution before thresholding: isolated
                    # orange-hued pixels (dusk sky, sensor noise) are averaged away
                    prob = cv2.blur(prob, (cfg.smooth_px, cfg.smooth_px))
                mask = cv2.compare(prob, thr, cv2.CMP_GE)
                if self._vmin[color] > 0 and cfg.v_hysteresis > 0 and cv2.countNonZero(mask):
                    # (the lower gate only when there is a blob to rejoin)
                    prob_lo = full & cv2.threshold(
                        v, int(cfg.v_hysteresis * self._vmin[color]) - 1, 255,
                        cv2.THRESH_BINARY)[1]
                    mask = _hysteresis(mask, prob_lo, thr, cfg.smooth_px)
                if keep is not None:
                    mask &= keep
                grow = (prob, thr, keep) if color == 'orange' and cfg.grow_level > 0 \
                    else None
                cands += self._blobs(mask, bgr, color, (cx0, cy0), s, thr_base, lboxes,
                                     raw, grow=grow)
        elif cfg.method == 'hsv':
            for color in self.colors:
                mask = np.zeros(hsv.shape[:2], np.uint8)
                for h_lo, h_hi, s_lo, v_lo in HSV_RANGES[color]:
                    mask |= cv2.inRange(hsv, (h_lo, s_lo, v_lo), (h_hi, 255, 255))
                if keep is not None:
                    mask &= keep
                cands += self._blobs(mask, bgr, color, (cx0, cy0), s, thr_base, lboxes)
        else:
            count = self.rgb_lp.mask(crop)
            if keep is not None:
                count = np.where(keep > 0, count, 0).astype(count.dtype)
            cands += self._mser_blobs(count, bgr, (cx0, cy0), s)
        return cands

    # -- seed 000 / 004 blob path --
    def _blobs(self, mask: np.ndarray, bgr: np.ndarray, color: str, off: tuple[int, int],
               s: int, thr_base: np.ndarray, lboxes: list,
               prob: Optional[np.ndarray] = None, peel_t: Optional[float] = None,
               grow: Optional[tuple] = None) -> list[Candidate]:
        """Candidates from the blobs of a mask-resolution ``mask``.  ``prob``: the raw
        likelihood behind it (blobs that pass no test are peeled, :meth:`_peel`);
        ``peel_t``: the blobs are cores peeled at this likelihood level; ``grow``: the
        smoothed likelihood, the thresholds and the pass's limit mask (or None) that a blob
        passing no test is grown with (:meth:`_grown`)."""
        cfg = self.config
        if not cv2.countNonZero(mask):
            return []               # nothing to open, close or label (most red / yellow masks)
        if cfg.method == 'hsv':
            # seed 004: erosion removes speckle, dilation reconnects the remaining blobs
            k = np.ones((3, 3), np.uint8)
            mask = cv2.dilate(cv2.erode(mask, k), k, iterations=2)
        else:
            if cfg.open_px > 1:
                mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN,
                                        np.ones((cfg.open_px, cfg.open_px), np.uint8))
            if cfg.close_px > 1:
                mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE,
                                        np.ones((cfg.close_px, cfg.close_px), np.uint8))
        n, labels, stats, _ = _components(mask)
        out, failed = [], []
        min_area_small = cfg.min_area_px / (s * s)
        parts = {}                   # component -> its candidate (None: it passed no test)
        for i in range(1, n):
            x, y, w, h, area = (int(v) for v in stats[i])
            if area < min_area_small:
                continue
            fx, fy, fw, fh = (x + off[0]) * s, (y + off[1]) * s, w * s, h * s
            # a plaque thinner than the radius filter: a small two-colour sign's orange part
            thin = (color == 'orange' and cfg.extension and cfg.thin_min_radius_px > 0
                    and fh / 2.0 < cfg.min_radius_px <= fw / 2.0
                    and fh / 2.0 >= cfg.thin_min_radius_px and fw >= cfg.ext_min_aspect * fh)
            if (min(fw, fh) / 2.0 < cfg.min_radius_px and not thin) \
                    or max(fw, fh) / 2.0 > cfg.max_radius_px:
                continue
            comp = (labels[y:y + h, x:x + w] == i).astype(np.uint8)
            c = self._measure(bgr, comp, (fx, fy, fw, fh), color, s, thr_base, lboxes,
                              area / float(w * h), peel_t)
            if thin and (c is None or not c.extended):
                continue            # kept only with its white part below it
            if c is None and grow is not None:
                c = self._grown(i, labels, mask, grow, stats, bgr, off, s, thr_base, lboxes)
            parts[i] = c
            if c is not None:
                out.append(c)
            elif (prob is not None and color == 'orange' and cfg.peel
                  and area >= 4 * min_area_small):
                failed.append((area, i, comp, x, y, w, h))
        if (color == 'orange' and cfg.merge_fragments and cfg.method == 'learned'
                and peel_t is None and len(parts) > 1):
            out, merged = self._merge_fragments(parts, out, labels, stats, bgr, off, s,
                                                thr_base, lboxes)
            failed = [f for f in failed if f[1] not in merged]     # no peel of a piece
        # the largest failed blobs are peeled, at most ``peel_max`` per frame (a scene full
        # of warm surfaces would otherwise cost a pass per blob)
        for _, _, comp, x, y, w, h in sorted(failed, key=lambda f: f[:2], reverse=True):
            if self._peels_left <= 0:
                break
            self._peels_left -= 1
            out += self._peel(comp, prob[y:y + h, x:x + w], (x + off[0], y + off[1]),
                              bgr, s, thr_base, lboxes)
        return out

    def _grown(self, i: int, labels: np.ndarray, mask: np.ndarray, grow: tuple,
               stats: np.ndarray, bgr: np.ndarray, off: tuple[int, int], s: int,
               thr_base: np.ndarray, lboxes: list) -> Optional[Candidate]:
        """Blob ``i`` (of ``labels``, mask resolution) that passed no test, grown into the
        pixels whose likelihood is at least ``grow_level`` x the threshold (``grow``: the
        smoothed likelihood, thresholds and limit mask of the pass; opened as ``mask`` is)
        connected to it within ``grow_reach`` x its larger side beyond its box, and
        measured again at that level: the candidate when that gives a refined warning
        diamond (not the chroma fit's), else None."""
        cfg = self.config
        x, y, w, h, _ = (int(v) for v in stats[i])
        g = int(math.ceil(cfg.grow_reach * max(w, h)))
        H, W = labels.shape
        ya, yb, xa, xb = max(0, y - g), min(H, y + h + g), max(0, x - g), min(W, x + w + g)
        blob = labels[ya:yb, xa:xb] == i
        prob, thr, keep = (a[ya:yb, xa:xb] if a is not None else None for a in grow)
        part = cv2.compare(prob, cv2.convertScaleAbs(thr, alpha=cfg.grow_level), cv2.CMP_GE)
        if keep is not None:
            part &= keep
        if cfg.open_px > 1:
            # specks of a warm surface join nothing
            part = cv2.morphologyEx(part, cv2.MORPH_OPEN,
                                    np.ones((cfg.open_px, cfg.open_px), np.uint8))
        part = part | mask[ya:yb, xa:xb]
        lab = cv2.connectedComponents(part, connectivity=8)[1]
        r, c = np.unravel_index(int(np.argmax(blob)), blob.shape)
        comp = ((lab == lab[r, c]) | blob).astype(np.uint8)
        bx, by, bw, bh = cv2.boundingRect(comp)
        if bw * bh < 1.4 * w * h or max(bw, bh) * s / 2.0 > cfg.max_radius_px \
                or min(bw, bh) * s < cfg.grow_min_px:
            return None     # a rim (not a part of the face), past any sign's size, or small
        comp = comp[by:by + bh, bx:bx + bw]
        # only a diamond is kept: about square, its hull about half its box (checked again
        # at full resolution by the measure)
        hull = cv2.convexHull(cv2.findNonZero(comp))
        if max(bw / bh, bh / bw) >= cfg.ext_min_aspect or \
                cv2.contourArea(hull) >= cfg.diamond_hull_fill * bw * bh:
            return None
        box = ((xa + bx + off[0]) * s, (ya + by + off[1]) * s, bw * s, bh * s)
        # its face at full resolution to the same lower level
        cand = self._measure_orange(bgr, comp, box, s, thr_base, lboxes,
                                    t_scale=cfg.grow_level)
        if cand is not None and cand.kind == 'warning' and cand.refined \
                and not cand.chroma_fit:
            return cand
        return None

    def _merge_fragments(self, parts: dict, out: list[Candidate], labels: np.ndarray,
                         stats: np.ndarray, bgr: np.ndarray, off: tuple[int, int], s: int,
                         thr_base: np.ndarray, lboxes: list
                         ) -> tuple[list[Candidate], set]:
        """Two or three blobs that are the pieces of one warning diamond, measured together.

        A symbol that runs from edge to edge (the lane-ends arrow, a reverse curve) cuts a
        diamond's orange face into pieces; each is half a diamond, measured as a narrow sign
        or none.  Blobs (of the ``merge_max`` largest, no refined diamond among them) whose
        boxes lie within a quarter of their joint box of each other and whose joint box is
        about square are measured as one blob: when that gives a warning diamond whose
        edges the brightness confirms (a refined one), it replaces the pieces.  Then, with
        ``merge_triples``, three blobs the same way, refined pieces among them too when the
        joint diamond holds every piece's box (a bold legend in rain light cuts a face into
        three pieces, two of which refine as small diamonds of their own).  Returns the
        candidates and the components merged.
        """
        cfg = self.config
        # a piece boxed by the chroma fit alone (no edge measured) may be a fragment too
        keys = sorted((i for i, c in parts.items() if c is None or not c.refined
                       or c.chroma_fit),
                      key=lambda i: -int(stats[i, cv2.CC_STAT_AREA]))[:cfg.merge_max]
        used: set = set()
        for a, b in itertools.combinations(keys, 2):
            if a in used or b in used:
                continue
            c = self._merged((a, b), labels, stats, bgr, off, s, thr_base, lboxes)
            if c is None or (c.chroma_fit and any(
                    parts[i] is not None and parts[i].refined for i in (a, b))):
                continue
            used |= {a, b}
            out = [o for o in out if o is not parts[a] and o is not parts[b]] + [c]
        if not cfg.merge_triples:
            return out, used
        keys = sorted((i for i in parts if i not in used),
                      key=lambda i: -int(stats[i, cv2.CC_STAT_AREA]))[:cfg.merge_max]
        for trio in itertools.combinations(keys, 3):
            if used & set(trio):
                continue
            c = self._merged(trio, labels, stats, bgr, off, s, thr_base, lboxes)
            if c is None or c.chroma_fit:
                continue
            # the joint diamond holds every piece's box (to a mask pixel)
            px0, py0 = (stats[trio, 0] + off[0]) * s, (stats[trio, 1] + off[1]) * s
            px1, py1 = px0 + stats[trio, 2] * s, py0 + stats[trio, 3] * s
            if not ((px0 >= c.x - s).all() and (px1 <= c.x + c.w + s).all()
                    and (py0 >= c.y - s).all() and (py1 <= c.y + c.h + s).all()):
                continue
            used |= set(trio)
            out = [o for o in out if all(o is not parts[i] for i in trio)] + [c]
        return out, used

    def _merged(self, ids: tuple, labels: np.ndarray, stats: np.ndarray, bgr: np.ndarray,
                off: tuple[int, int], s: int, thr_base: np.ndarray, lboxes: list
                ) -> Optional[Candidate]:
        """Blobs ``ids`` measured as one (:meth:`_merge_fragments`): None unless each lies
        within a quarter of their joint box of the others, the joint box is about square and
        more than 1.25 x each blob's box, and the measure gives a refined diamond."""
        cfg = self.config
        boxes = [tuple(int(v) for v in stats[i, :4]) for i in ids]
        x0, y0 = min(b[0] for b in boxes), min(b[1] for b in boxes)
        x1 = max(b[0] + b[2] for b in boxes)
        y1 = max(b[1] + b[3] for b in boxes)
        w, h = x1 - x0, y1 - y0
        if not 0.7 <= w / h <= 1.4 or max(b[2] * b[3] for b in boxes) > 0.8 * w * h:
            return None

        def near(p: tuple, q: tuple) -> bool:
            gx = max(p[0], q[0]) - min(p[0] + p[2], q[0] + q[2])
            gy = max(p[1], q[1]) - min(p[1] + p[3], q[1] + q[3])
            return max(gx, 0) <= max(1, 0.25 * w) and max(gy, 0) <= max(1, 0.25 * h)

        # each piece next to another
        if not all(any(near(p, q) for q in boxes if q is not p) for p in boxes):
            return None
        fx, fy, fw, fh = (x0 + off[0]) * s, (y0 + off[1]) * s, w * s, h * s
        if max(fw, fh) / 2.0 > cfg.max_radius_px:
            return None
        sub = labels[y0:y1, x0:x1]
        comp = np.isin(sub, ids).astype(np.uint8)
        c = self._measure(bgr, comp, (fx, fy, fw, fh), 'orange', s, thr_base, lboxes,
                          float(np.count_nonzero(comp)) / (w * h), None, whole=True)
        return c if c is not None and c.refined else None

    def _peel(self, comp: np.ndarray, prob: np.ndarray, org: tuple[int, int],
              bgr: np.ndarray, s: int, thr_base: np.ndarray, lboxes: list
              ) -> list[Candidate]:
        """A blob that passed no test, judged again at higher likelihood levels: a sign
        merged with a surface of nearly its colour (an orange dusk sky, a brick wall) is
        where the likelihood is clearly higher.  Levels, lowest first, each at least
        ``peel_gap`` above the blob's median: Otsu's level over the blob's pixels, then
        ``peel_levels``; the first level whose cores give candidates wins."""
        vals = prob[comp > 0]
        floor = float(_median(vals)) + self.config.peel_gap * 255
        otsu, _ = cv2.threshold(vals.reshape(-1, 1), 0, 255,
                                cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        levels = sorted({lv for lv in [float(otsu)] + [255 * v for v in self.config.peel_levels]
                         if floor <= lv < 254})
        for level in levels:
            core = ((prob > level) & (comp > 0)).astype(np.uint8) * 255
            # the sign's orange around a legend or symbol, at the mask's resolution
            core = cv2.morphologyEx(core, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)) & \
                (comp * 255)
            out = self._blobs(core, bgr, 'orange', org, s, thr_base, lboxes,
                              peel_t=(level + 1) / 255.0)
            if out:
                return out
        return []

    def _measure(self, bgr: np.ndarray, comp: np.ndarray, box: tuple, color: str, s: int,
                 thr_base: np.ndarray, lboxes: list, blob_fill: float = 1.0,
                 peel_t: Optional[float] = None, whole: bool = False
                 ) -> Optional[Candidate]:
        """Refine a blob at full resolution, measure its shape, score and filter it.
        ``whole``: the blob's face is all its pieces (fragments of one sign), not the
        largest."""
        cfg = self.config
        if cfg.method == 'learned' and color == 'orange':
            # judged on colour alone first (LiDAR support never changes a box the colour
            # evidence already makes); only a blob that fails is re-judged with relaxed
            # filters inside its ROI, and must then lie mostly inside that ROI
            c = self._measure_orange(bgr, comp, box, s, thr_base, lboxes, peel_t=peel_t,
                                     whole=whole)
            roi = self._in_roi(box, s, lboxes) if c is None else None
            if roi is not None:
                c = self._measure_orange(bgr, comp, box, s, thr_base, lboxes, relaxed=True,
                                         peel_t=peel_t, whole=whole)
                if c is not None and _contained((c.x, c.y, c.w, c.h), roi) < cfg.roi_contain:
                    c = None
            return c
        H, W = bgr.shape[:2]
        fx, fy, fw, fh = box
        m = 2 * s + 1
        x0, y0 = max(0, fx - m), max(0, fy - m)
        x1, y1 = min(W, fx + fw + m), min(H, fy + fh + m)
        win = bgr[y0:y1, x0:x1]
        hsv = cv2.cvtColor(win, cv2.COLOR_BGR2HSV)
        region = np.zeros(win.shape[:2], np.uint8)
        up = cv2.resize(comp, (fw, fh), interpolation=cv2.INTER_NEAREST) if s > 1 else comp
        _paste(region, up, fy - y0, fx - x0)
        if s > 1:
            region = cv2.dilate(region, np.ones((4 * s + 1, 4 * s + 1), np.uint8))
        if cfg.method == 'learned':
            i = self._idx[color]
            like = _lookup(self.model.luts[i], hsv[..., 0], hsv[..., 1])
            like[hsv[..., 2] < self.model.v_min[i]] = 0.0
            # posterior threshold at full resolution: tau / prior, or the ROI threshold
            cy, cx = (fy + fh // 2) // s, (fx + fw // 2) // s
            cy, cx = min(cy, thr_base.shape[0] - 1), min(cx, thr_base.shape[1] - 1)
            t = thr_base[cy, cx] / _P_SCALE
            for bx0, by0, bx1, by1 in lboxes:
                if bx0 <= cx < bx1 and by0 <= cy < by1:
                    t = min(t, cfg.roi_threshold / cfg.roi_prior)
            pix = (like >= t - 1e-6) & (region > 0)
            post = like
        else:
            pix = np.zeros(win.shape[:2], bool)
            for h_lo, h_hi, s_lo, v_lo in HSV_RANGES[color]:
                pix |= cv2.inRange(hsv, (h_lo, s_lo, v_lo), (h_hi, 255, 255)) > 0
            pix &= region > 0
            post = pix.astype(np.float32)
        if cfg.refine and pix.any():
            ys, xs = np.nonzero(pix)
            bx0, by0, bx1, by1 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
        else:
            bx0, by0 = fx - x0, fy - y0
            bx1, by1 = bx0 + fw, by0 + fh
            pix = region > 0 if not pix.any() else pix
        bw, bh = int(bx1 - bx0), int(by1 - by0)
        if bw < 2 or bh < 2:
            return None
        gx, gy = cfg.border_scale
        area = float(np.count_nonzero(pix))
        if area < cfg.min_area_px:
            return None
        pts = cv2.findNonZero(pix.astype(np.uint8))
        hull_fill = float(cv2.contourArea(cv2.convexHull(pts))) / (bw * bh)
        # seed 004 compares the (dilated) blob's area with its box's
        fill = blob_fill if cfg.method == 'hsv' else area / (bw * bh)
        aspect = bw / bh
        if color == 'orange' and cfg.method == 'learned':
            if hull_fill < cfg.min_hull_fill or max(aspect, 1 / aspect) > cfg.max_aspect:
                return None
            kind = 'warning' if hull_fill < cfg.diamond_hull_fill else 'regulatory'
        else:
            # seed 004: width/height close to 1, blob fills much of its box
            if max(aspect, 1 / aspect) > cfg.general_max_aspect or fill < cfg.general_min_fill:
                return None
            if color == 'orange':
                kind = 'warning' if hull_fill < cfg.diamond_hull_fill else 'regulatory'
            else:
                kind = 'general'
        conf = _mode(post[pix]) if cfg.method == 'learned' else fill
        cand = Candidate(x0 + bx0, y0 + by0, bw, bh, color, conf, kind, area, hull_fill)
        if color == 'orange' and (gx != 1.0 or gy != 1.0):
            cand.x -= 0.5 * (gx - 1.0) * bw
            cand.y -= 0.5 * (gy - 1.0) * bh
            cand.w, cand.h = gx * bw, gy * bh
        if (color == 'orange' and cfg.method == 'learned' and cfg.extension
                and kind == 'regulatory' and aspect >= cfg.ext_min_aspect):
            self._extend(bgr, cand, hsv[by0:by1, bx0:bx1][pix[by0:by1, bx0:bx1]])
        return cand

    def _window(self, bgr: np.ndarray, x0: int, y0: int, x1: int, y1: int
                ) -> tuple[np.ndarray, int, int]:
        """``bgr[y0:y1, x0:x1]`` clipped to the frame and colour-balanced, and the clipped
        window's origin."""
        H, W = bgr.shape[:2]
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(W, x1), min(H, y1)
        win = bgr[y0:y1, x0:x1]
        if self._gains is not None:
            win = apply_gains(win, self._gains)
        return win, x0, y0

    def _value(self, bgr: np.ndarray, x0: int, y0: int, x1: int, y1: int,
               luma: bool = False) -> tuple[np.ndarray, int, int]:
        """The HSV value (max of the colour-balanced B, G, R), or with ``luma`` the luma
        (a weighted sum: linear in a blend of two colours, as the edge model is), of
        ``bgr[y0:y1, x0:x1]`` clipped to the frame, and the clipped window's origin."""
        win, x0, y0 = self._window(bgr, x0, y0, x1, y1)
        if luma:
            return cv2.cvtColor(np.ascontiguousarray(win), cv2.COLOR_BGR2GRAY), x0, y0
        return cv2.max(cv2.max(win[..., 0], win[..., 1]), win[..., 2]), x0, y0

    def _diamond_value(self, bgr: np.ndarray, window: tuple, bw: int, bh: int
                       ) -> tuple[np.ndarray, int, int]:
        """The brightness (:meth:`_value`, luma with ``diamond_luma``) a few pixels beyond
        the blob's window ``(x0, y0, x1, y1)`` (a quarter of the blob's size, + 3 px: a mask
        fit that is too large puts an edge's outer samples outside the window)."""
        return self._value(bgr, *_padded(window, bw, bh), self.config.diamond_luma)

    def _orange_like(self, hsv: np.ndarray) -> np.ndarray:
        """The orange table's likelihood of each pixel of ``hsv`` (0 below its brightness
        floor)."""
        i = self._idx['orange']
        like = _lookup(self.model.luts[i], hsv[..., 0], self._sat(hsv))
        like[hsv[..., 2] < self.model.v_min[i]] = 0.0
        return like

    def _sat(self, hsv: np.ndarray) -> np.ndarray:
        """The saturation channel as the orange table sees it (frame-normalised)."""
        s = hsv[..., 1]
        return s if self._sat_tab is None else cv2.LUT(s, self._sat_tab)

    @staticmethod
    def _in_roi(box: tuple, s: int, lboxes: list) -> Optional[tuple]:
        """The (expanded) LiDAR ROI, full-resolution (x, y, w, h), holding a box's centre."""
        cx, cy = (box[0] + box[2] / 2) / s, (box[1] + box[3] / 2) / s
        for x0, y0, x1, y1 in lboxes:
            if x0 <= cx < x1 and y0 <= cy < y1:
                return (x0 * s, y0 * s, (x1 - x0) * s, (y1 - y0) * s)
        return None

    def _measure_orange(self, bgr: np.ndarray, comp: np.ndarray, box: tuple, s: int,
                        thr_base: np.ndarray, lboxes: list, relaxed: bool = False,
                        t_override: Optional[float] = None,
                        peel_t: Optional[float] = None, whole: bool = False,
                        t_scale: float = 1.0) -> Optional[Candidate]:
        """The learned orange path: hysteresis region, sign structure, shape-derived box.

        1. At full resolution, pixels with likelihood >= tau (the posterior threshold of the
           blob's location) near the blob are the face; pixels >= ``weak_threshold`` next to
           them join (hysteresis); a closing bridges the thin black border line.
        2. Structure: solidity (pixels / hull area), hull fill (diamond ~0.5, rectangle ~1),
           aspect, and for blobs of ``structure_min_px`` or more a dark legend or border
           inside the hull.
        3. Box: the orange hull's bounding box; if the ring just outside it is dark (the
           sign's black border, with the thin outer orange margin lost to blending), the
           box grows by ``border_frac`` of the hull's size on every side.

        ``t_scale``: tau at this share of the location's (a blob grown to a lower level,
        :meth:`_grown`).
        """
        cfg = self.config
        H, W = bgr.shape[:2]
        fx, fy, fw, fh = box
        m = 2 * s + 1 + int(0.2 * max(fw, fh))
        x0, y0 = max(0, fx - m), max(0, fy - m)
        x1, y1 = min(W, fx + fw + m), min(H, fy + fh + m)
        win = bgr[y0:y1, x0:x1]
        raw = win
        if self._gains is not None:
            win = apply_gains(win, self._gains)
        hsv = cv2.cvtColor(win, cv2.COLOR_BGR2HSV)
        like = self._orange_like(hsv)
        vch = hsv[..., 2]
        cy, cx = (fy + fh // 2) // s, (fx + fw // 2) // s
        cy, cx = min(cy, thr_base.shape[0] - 1), min(cx, thr_base.shape[1] - 1)
        t = t_scale * thr_base[cy, cx] / _P_SCALE
        if relaxed:
            t = min(t, cfg.roi_threshold / cfg.roi_prior)
        if t_override is not None:
            t = t_override
        if peel_t is not None:
            t = max(t, peel_t)
        region = np.zeros(win.shape[:2], np.uint8)
        up = cv2.resize(comp, (fw, fh), interpolation=cv2.INTER_NEAREST) if s > 1 else comp
        _paste(region, up, fy - y0, fx - x0)
        if s > 1:
            region = cv2.dilate(region, np.ones((2 * s + 1, 2 * s + 1), np.uint8))
        strong = ((like >= t - 1e-6) & (region > 0)).astype(np.uint8)
        if not strong.any():
            return None
        weak_t, blur_t = min(cfg.weak_threshold, t), cfg.blur_like
        if peel_t is not None:
            weak_t = t             # no hysteresis back into the surface the core was peeled from
        rel = self._relative
        edge_t = None
        if rel is not None:
            # the box edge relative to this blob's own levels (model metadata ``measure``):
            # a smooth table scores a sign's blended edge anywhere between the face's level
            # and the background's, so the absolute thresholds (set for a step-shaped table)
            # would let the box grow into the blend.  Only the box moves: which blobs are
            # signs is still judged on the absolute face below.
            edge_t, blur_t = self._relative_levels(like, strong, region, rel)
        weak = (like >= weak_t).astype(np.uint8) | strong
        size = max(fw, fh)
        k = max(3, int(round(cfg.close_frac * size)) | 1)
        kern = np.ones((k, k), np.uint8)
        # weak pixels near the blob join it; the closing bridges border and legend strokes
        # (the face as one region; its orange pixels are ``weak`` inside it)
        near = cv2.dilate(strong, kern) & weak
        if cfg.clip_grow > 0:
            near |= _clipped_growth(raw, weak, strong, cfg.clip_grow, near)
        face = cv2.morphologyEx(near, cv2.MORPH_CLOSE, kern)
        n, lab, st, _ = _components(face)
        if n <= 1:
            return None
        if whole:
            # the pieces of one face (a symbol cuts it from edge to edge)
            region_j = face > 0
            bx0, by0, bw, bh = cv2.boundingRect(face)
        else:
            j = 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
            region_j = lab == j
            bx0, by0, bw, bh = (int(v) for v in st[j, :4])
        pix = (region_j & (weak > 0)).astype(np.uint8)
        area = float(np.count_nonzero(pix))
        if area < cfg.min_area_px:
            return None
        if bw < 2 or bh < 2:
            return None
        pts = cv2.findNonZero(pix)
        hull = cv2.convexHull(pts)
        hull_area = max(float(cv2.contourArea(hull)), 1.0)
        hull_fill = hull_area / (bw * bh)
        solidity = area / hull_area
        aspect = bw / bh
        if self.debug is not None:
            self.debug.append(dict(box=(x0 + bx0, y0 + by0, bw, bh), fill=hull_fill,
                                   sol=solidity, aspect=aspect, t=t))
        # a LiDAR-supported blob needs less colour evidence: looser shape filters, no legend
        # test and no mounting-height test (the LiDAR found a flat retro-reflective panel)
        relax = cfg.roi_relax if relaxed else 1.0
        if (hull_fill < relax * cfg.min_hull_fill or solidity < relax * cfg.min_solidity
                or max(aspect, 1 / aspect) > cfg.max_aspect / relax):
            return None
        geo = self._geometry
        pix_fit = None              # fit_diamond(pix), when the mounting test needed it
        # no legend seen, or an unclear face below the usual mounting: kept only if its
        # diamond outline is measured in the brightness below (``outline_evidence``)
        needs_outline = False
        needs_white = False         # no legend seen on a plaque: kept only with a white part
        if geo is not None and self._ref_row is not None and not relaxed:
            # signs are mounted high: their bottom edge is above the prior's reference row
            # (drums, cones and vehicles stand on the road below it); in units of box height.
            # Below the usual mounting (soft limit; portable stands stand low) only a clear
            # diamond face passes; below the lowest training sign (hard limit) nothing does.
            rel = (y0 + by0 + bh - self._ref_row) / bh
            if self.debug is not None:
                self.debug[-1]['mount'] = rel
            if rel > geo[1]:
                return None
            if rel > geo[2]:
                if cfg.diamond_trim >= 0:
                    # the diamond test fits ``pix`` either way; the trim below reuses it
                    pix_fit = fit_diamond(pix)
                if not self._clear_diamond(pix, pix_fit):
                    if not (cfg.outline_evidence and cfg.diamond_refine):
                        return None
                    needs_outline = True      # a face behind a guardrail: its edges may tell
        hmask = np.zeros_like(pix)
        cv2.fillConvexPoly(hmask, hull, 1)
        v_ref = float(_median(vch[pix > 0]))
        if cfg.max_surround_like < 1.0 and not relaxed:
            # a sign is an object on its own: beyond its border the background is not the
            # sign's colour on average; a patch of a larger sign-coloured surface (dirt, a
            # brick wall, a vehicle's panel) is
            sl, sh = self._surround_like(hmask, like, max(bw, bh), t - 1e-6)
            if self.debug is not None:
                self.debug[-1].update(surround=sl, surround_face=sh)
            if sl > cfg.max_surround_like and sh > cfg.min_surround_face:
                return None
        dark = vch < cfg.dark_rel * v_ref
        if min(bw, bh) >= cfg.structure_min_px and not relaxed:
            inside = hmask > 0
            dfrac = np.count_nonzero(dark & inside) / max(np.count_nonzero(inside), 1)
            if self.debug is not None:
                self.debug[-1]['dark'] = dfrac
            if dfrac < cfg.min_dark_inside:
                if cfg.white_part_evidence and cfg.extension and not needs_outline \
                        and aspect >= cfg.ext_min_aspect:
                    needs_white = True      # a plaque: its white part below may tell
                elif not (cfg.outline_evidence and cfg.diamond_refine):
                    return None
                else:
                    needs_outline = True
        if cfg.band_test and bh >= cfg.band_min_px and not relaxed:
            if self._banded(bgr, x0 + bx0, y0 + by0, bw, bh, pix, v_ref, t):
                if self.debug is not None:
                    self.debug[-1]['banded'] = True
                # a drum or cone (the fusion's channelizer evidence): one per place
                self.channelizers.add(((x0 + bx0 + bw // 2) // 16, (y0 + by0 + bh // 2) // 16))
                return None
        cut, row_fit = None, None
        if cfg.diamond_trim >= 0 and aspect < cfg.ext_min_aspect:
            # rows beyond a fitted diamond's corners are not the face (a portable stand's
            # orange flags above the top corner): shape, kind and box go without them
            trimmed, row_fit = self._trim_to_diamond(pix, cfg.diamond_trim, pix_fit)
            if cfg.neck_trim:
                # flags the fit took for part of the face (a cut face fits badly): the rows
                # above the neck between them and the diamond's top corner
                necked = self._neck_trim(pix if trimmed is None else trimmed)
                if necked is not None:
                    trimmed = necked
            if trimmed is not None:
                row_fit = None
                # the cut-off part must not come back as the border's blur rings
                cut = (pix > 0) & (trimmed == 0)
                like = np.where(cut, np.float32(0), like)
                pix = trimmed
                hull = cv2.convexHull(cv2.findNonZero(pix))
                bx0, by0, bw, bh = (int(v) for v in cv2.boundingRect(hull))
                hmask = np.zeros_like(pix)
                cv2.fillConvexPoly(hmask, hull, 1)
                hull_fill = max(float(cv2.contourArea(hull)), 1.0) / (bw * bh)
                aspect = bw / bh
        # diamonds are about square; a wide blob is a rectangle (or the orange top of one)
        kind = ('warning' if hull_fill < cfg.diamond_hull_fill
                and max(aspect, 1 / aspect) < cfg.ext_min_aspect else 'regulatory')
        if needs_outline and kind != 'warning':
            return None
        conf = _mode(like[pix > 0])
        face_px = pix
        if edge_t is not None:
            # the box from the face's core: its pixels at least ``edge_rel`` of the way
            # from the background's likelihood level to the face's
            core = (region_j & (like >= edge_t)).astype(np.uint8)
            if np.count_nonzero(core) >= 3:
                hull = cv2.convexHull(cv2.findNonZero(core))
                bx0, by0, bw, bh = (int(v) for v in cv2.boundingRect(hull))
                hmask = np.zeros_like(pix)
                cv2.fillConvexPoly(hmask, hull, 1)
                face_px = core
                row_fit = None
        grow, feats = self._border_growth(hmask, dark, like, min(bw, bh), blur_t)
        if self.debug is not None:
            self.debug[-1].update(hull_box=(x0 + bx0, y0 + by0, bw, bh), vref=v_ref,
                                  relaxed=relaxed, **feats)
        cand = Candidate(x0 + bx0, y0 + by0, bw, bh, 'orange', conf, kind, area, hull_fill)
        outer = sub = None
        refine = cfg.diamond_refine and cfg.border_frac > 0 and cfg.diamond_scale > 0
        search = refine and cfg.diamond_search and min(bw, bh) >= cfg.search_min_px
        searched = larger = False
        if kind == 'warning' and cfg.diamond_scale > 0:
            # the box of the diamond fitted to the face (its corners extrapolated from the
            # straight edges), scaled out by the border; never further out than
            # ``diamond_clamp`` x the half-diagonal beyond the face seen (an occluded or
            # cut-off corner is not invented)
            if row_fit is None:
                row_fit = fit_diamond(face_px)
            fd = fit_diamond_2d(face_px, rows=row_fit)
            # an occluder across the face's lower part (a guardrail in front of a sign on
            # a stand): its edges are measured above it, from the rows' own diamond
            cut_row = self._cut_row(face_px, row_fit)
            sub = None
            if refine:
                # the brightness a few pixels beyond the blob's window (a mask fit that is
                # too large puts the edge's outer samples outside it)
                value, ox, oy = self._diamond_value(bgr, (x0, y0, x1, y1), bw, bh)
                dx, dy = x0 - ox, y0 - oy
                # start from the mask's diamond, else from the diamond in the hull's box (a
                # big symbol that cuts the face leaves the mask's corners far off), else
                # from the rows' own diamond (a rail or a car across the face's lower part
                # cuts its columns, which the mask's diamond takes its height from)
                starts = [fd[:4]] if fd is not None and fd[4] >= 0.5 else []
                starts.append((bx0 + 0.5 * bw, by0 + 0.5 * bh, 0.5 * bw, 0.5 * bh))
                if row_fit is not None and row_fit[4] >= 0.5:
                    starts.append(row_fit[:4])
                # else from the hull's box grown (a faded or rain-washed face whose mask,
                # or a peeled core, covers less than the face); such a fit on a whole blob
                # needs a clear line (``search_min_contrast``: the sign's outer edge
                # against a dark background is no face's edge against its line)
                n_mask = len(starts)
                starts += [(bx0 + 0.5 * bw, by0 + 0.5 * bh, 0.5 * g * bw, 0.5 * g * bh)
                           for g in cfg.diamond_grown_starts]
                # above a cut: first from the rows' diamond (the others take the face's
                # height from its cut columns), then as without one (a tip thinned by blur
                # looks cut too; its lower edges are then measured all the same)
                passes = [(None, list(enumerate(starts)))]
                if cut_row is not None:         # (a cut is found on a row fit only)
                    passes.insert(0, (cut_row + dy, [(n_mask - 1, starts[n_mask - 1])] + [
                        (i_, st) for i_, st in enumerate(starts) if i_ != n_mask - 1]))
                for hidden, order in passes:
                    for i_, st in order:
                        mc_ = EDGE_MIN_CONTRAST if i_ < n_mask or peel_t is not None \
                            else cfg.search_min_contrast
                        sub = self._refine(value, (st[0] + dx, st[1] + dy, st[2], st[3]),
                                           mc_, hidden)
                        if sub is not None:
                            sub, held = self._held(bgr, hsv, face_px, sub, dx, dy,
                                                   (x0, y0, x1, y1), bw, bh)
                            if sub is not None:
                                larger = held == 'blended'
                                break
                    if sub is not None:
                        break
                    cut_row = None
                if sub is None and search:
                    # no start from the mask works: look for the face's outline in the
                    # brightness itself
                    sub = self._search_diamond(value, dx, dy, (bx0, by0, bw, bh), face_px,
                                              hsv)
                    searched = sub is not None
            blurred = None
            if sub is None and refine and cfg.blur_fit and not needs_outline:
                # no line to measure: the sign's blurred colour
                blurred = self._blur_fit(bgr, (x0, y0, x1, y1), (bx0, by0, bw, bh),
                                         fd if fd is not None and fd[4] >= 0.5 else None)
            if sub is None and blurred is None and refine and \
                    0 < cfg.shift_min_px <= min(bw, bh):
                # nothing measured: a large face whose mask's starts are a few pixels off
                # (the mask took in a surface of its colour beside it)
                held_args = (bgr, hsv, face_px, dx, dy, (x0, y0, x1, y1), bw, bh)
                got = refine_shifted(
                    [(st[0] + dx, st[1] + dy, st[2], st[3]) for st in starts[:n_mask]],
                    lambda st: self._refine(value, st),
                    lambda f: self._held_reaching(f, held_args, (x0 + bx0, y0 + by0)))
                if got is not None:
                    sub, larger = got[0], got[1] == 'blended'
            if self.debug is not None:
                self.debug[-1].update(refined=sub is not None, searched=searched,
                                      blur_fit=blurred is not None,
                                      cut=None if cut_row is None else y0 + cut_row)
            diamond = None
            if sub is not None:
                # the face's edges from the brightness profile; the sign is the face
                # scaled by the art's ratio (border line and margin outside the face);
                # the clamp allows a pixel more (blur eats about a pixel of a small face)
                diamond = (*sub, cfg.diamond_face_ratio, cfg.diamond_clamp_px)
            elif blurred is not None:
                diamond = (*blurred, cfg.blur_fit_ratio, cfg.diamond_clamp_px)
            elif fd is not None and fd[4] >= 0.5:
                k_ = cfg.diamond_scale
                if cfg.border_frac <= 0:
                    k_ = 1.0                    # configured: no border outside the face
                elif cfg.diamond_ring_test:
                    # the black border lies outside the fitted face when the ring just
                    # outside the diamond is darker than the ring just inside it
                    ri, ro = diamond_rings(pix.shape, fd,
                                           max(1.0, cfg.border_frac * 2 * fd[2]))
                    if np.count_nonzero(dark & ro) / max(np.count_nonzero(ro), 1) <= \
                            np.count_nonzero(dark & ri) / max(np.count_nonzero(ri), 1):
                        k_ = 1.0
                elif grow <= 0:
                    k_ = 1.0
                diamond = (*fd[:4], k_, 0.0)
            if diamond is not None:
                cut = cut_row is not None and sub is not None
                # (the frame below the blob's window: the occluder reaches past it)
                hidden_at = self._tip_hidden(
                    bgr[y0:, x0:x1], (diamond[0], diamond[1], diamond[4] * diamond[2],
                                      diamond[4] * diamond[3]), cut_row, t) \
                    if cut and cfg.tip_check else None
                if self.debug is not None and cut:
                    self.debug[-1]['hidden'] = None if hidden_at is None else y0 + hidden_at
                box_ = self._diamond_box(diamond, sub is not None or blurred is not None,
                                         (bx0, by0, bw, bh), peel_t, searched or larger,
                                         cut and hidden_at is None,
                                         self._box_bias(sub))
                if box_ is not None and hidden_at is not None and \
                        box_[1] + box_[3] > hidden_at:
                    # the occluder hides the tip: the sign's visible part ends at it
                    box_ = (box_[0], box_[1], box_[2], hidden_at - box_[1])
                if box_ is not None:
                    outer = (x0 + box_[0], y0 + box_[1], box_[2], box_[3])
        if outer is not None:
            cand.x, cand.y, cand.w, cand.h = outer
            cand.refined = kind == 'warning' and (sub is not None or blurred is not None)
            cand.chroma_fit = cand.refined and sub is None
        elif grow > 0:
            # the border's share of each side, plus the blur rings (px, the same on every
            # side: as a share of the shorter side they grew a wide blob's width by its
            # aspect times the blur)
            b_px = float(feats['blur']) if cfg.blur_px_growth else 0.0
            g_ = grow - b_px / float(min(bw, bh))
            gx, gy = g_ * bw + b_px, g_ * bh + b_px
            cand.x, cand.y = cand.x - gx, cand.y - gy
            cand.w, cand.h = bw + 2 * gx, bh + 2 * gy
        if needs_outline and not (outer is not None and sub is not None):
            # no legend and no diamond edges: a patch of a sign-coloured surface (peeled next)
            return None
        sx, sy = cfg.border_scale
        if sx != 1.0 or sy != 1.0:
            cand.x -= 0.5 * (sx - 1.0) * cand.w
            cand.y -= 0.5 * (sy - 1.0) * cand.h
            cand.w, cand.h = sx * cand.w, sy * cand.h
        entry = self.debug[-1] if self.debug is not None else None
        bands = None
        if cfg.extension and kind == 'regulatory' and aspect >= cfg.ext_min_aspect:
            bands = self._extend(bgr, cand, hsv[pix > 0])
        if needs_white and not (cand.extended and cand.white_level >= cfg.white_part_level):
            return None
        rect_failed = False
        if kind == 'regulatory' and cfg.rect_refine and cfg.border_frac > 0:
            # the orange part's left, right and top edges from the brightness profile; the
            # sign's outer edges lie the border line and margin further out (in units of
            # the sign's shorter side: the width of a two-colour sign)
            face_frac = 1.0 - 2.0 * (cfg.rect_border_rel + cfg.rect_margin_rel)
            size = (bw if cand.extended else min(bw, bh)) / face_frac
            # the brightness a few pixels beyond the blob's window, down over the white part
            # when the extension found it (its bottom edge is measured too)
            pad = 3 + int(0.05 * max(bw, bh))
            y_end = max(y1, int(cand.y + cand.h) + m) if cand.extended else y1
            value, ox, oy = self._value(bgr, x0 - pad, y0 - pad, x1 + pad, y_end + pad)
            dx, dy = x0 - ox, y0 - oy
            low = cand.y + cand.h - oy if cand.extended else None
            hx, hw = bx0 + dx, bw                   # the orange part's columns (window)
            sub = refine_rectangle(value, (hx, by0 + dy, hw, bh), size,
                                   cfg.rect_border_rel, cfg.rect_margin_rel,
                                   cfg.rect_max_change, bottom=low,
                                   free_top=cand.extended)
            span = cand.white_span
            sw = span[1] - span[0] if span is not None else 0.0
            tol_w = max(2.0, 0.1 * sw)
            face_w = sub[1] - sub[0] if sub is not None and sub[0] is not None \
                and sub[1] is not None else None
            wide = face_w is not None and face_w > sw + tol_w
            # one side far inside the white part's and the other not (the face is inside
            # the white columns by its line and margin on both sides alike)
            narrow = face_w is not None and face_w < sw and abs(
                (sub[0] - (span[0] - ox)) - ((span[1] - ox) - sub[1])) > max(3.0, 0.2 * sw)
            if cfg.rect_white_span and span is not None and sw >= max(6.0, 0.6 * bw) and (
                    (sub is None or wide) and sw <= bw - max(2.0, 0.1 * bw) or narrow):
                # the orange blob took in a surface of its colour beside the sign (a dusk
                # sky): its edges lie past the search, or were measured on the blob's; or
                # the plaque's fit took a legend stroke for a side: the white part below
                # shows the sign's columns
                sub2 = refine_rectangle(value, (span[0] - ox, by0 + dy, sw, bh),
                                        sw / face_frac, cfg.rect_border_rel,
                                        cfg.rect_margin_rel, cfg.rect_max_change, bottom=low,
                                        free_top=True)
                if entry is not None:
                    entry['white_span'] = (span, wide, narrow, sub2 is not None)
                if sub2 is not None and (not narrow or (
                        sub2[0] is not None and sub2[1] is not None
                        and sub2[1] - sub2[0] <= sw + tol_w
                        and abs(sub2[1] - sub2[0] - sw) < abs(face_w - sw))):
                    sub, hx, hw = sub2, span[0] - ox, sw
                    size = hw / face_frac
            if sub is None and cfg.rect_inward and cand.extended:
                # no side on either start's search: a pale wall right beside the sign took
                # the hull (and the white part) past the side, whose edge then lies inside
                # the search: the lost side's stretches moved in.  Kept when the sign has a
                # catalogue shape and its white part does not run on past a side
                starts3 = [(hx, hw, size)]
                if cfg.rect_white_span and span is not None and sw >= max(6.0, 0.6 * bw):
                    starts3.append((span[0] - ox, sw, sw / face_frac))
                for sx3, sw3, size3 in starts3:
                    sub3 = refine_rectangle(value, (sx3, by0 + dy, sw3, bh), size3,
                                            cfg.rect_border_rel, cfg.rect_margin_rel,
                                            cfg.rect_max_change, bottom=low, free_top=True,
                                            inward=cfg.rect_inward)
                    if sub3 is None or sub3[0] is None or sub3[1] is None or sub3[3] is None:
                        continue
                    top3 = sub3[2] if sub3[2] is not None else by0 + dy
                    r_out = (sub3[3] - top3) / max(sub3[1] - sub3[0], 1.0) * face_frac \
                        + 1.0 - face_frac
                    fl, fr = ox + sub3[0], ox + sub3[1]
                    ok = _ratio_error(np.array([r_out]), 1.0)[0] <= cfg.ext_ratio_tol \
                        and not white_beyond(bgr, (fl, fr), (y0 + by0 + bh, oy + sub3[3]),
                                             max(2.0, 0.1 * (fr - fl)))
                    if entry is not None:
                        entry.setdefault('inward', []).append((round(r_out, 3), ok))
                    if ok:
                        sub, hx, hw, size = sub3, sx3, sw3, size3
                        break
            if entry is not None:
                entry['rect_refined'] = sub is not None
            rect_failed = sub is None
            if sub is not None:
                left, right, top, low = sub            # in the brightness window
                q = cfg.rect_edge_bias
                qs = q - _taper(cfg.rect_dim_bias, v_ref)
                qb = q
                if cfg.rect_clip_bias > 0:
                    # clipped faces: the blurred edge's half level is above 255, so the
                    # clipped ramp puts the edge further out than it is
                    face_v = raw[pix > 0].max(axis=1)
                    qs += cfg.rect_clip_bias * float(np.count_nonzero(face_v >= 250)) / max(
                        float(face_v.size), 1.0)
                    if low is not None:
                        wy0 = int(max(y0 + by0 + bh, oy + low - 0.4 * (low - (by0 + dy + bh))))
                        wy1 = int(oy + low - 1)
                        wx0, wx1 = int(ox + hx + 0.2 * hw), int(math.ceil(ox + hx + 0.8 * hw))
                        part = bgr[wy0:wy1, wx0:wx1]
                        if part.size:
                            qb += cfg.rect_clip_bias * float((part.max(axis=2) >= 250).mean())
                # a side off the image: the hull's (the box is clipped to the image below)
                left = hx if left is None else left + qs
                right = hx + hw if right is None else right - qs
                out = (cfg.rect_border_rel + cfg.rect_margin_rel) * (
                    (right - left) / face_frac if cand.extended else size)
                bottom = cand.y + cand.h if low is None else oy + low - qb + out
                cand.x, cand.w = ox + left - out, right - left + 2 * out
                if top is not None:
                    cand.y = oy + top + qs - out
                else:
                    # the orange part's top as its hull's, moved out like the sides (not a
                    # diamond fit's box: the part may have been taken for one)
                    cand.y = y0 + by0 - out
                if cfg.ext_rechoose and bands is not None:
                    bottom = self._rechoose_bottom(bands, cand, bottom, entry)
                cand.h = bottom - cand.y
                if cfg.white_ends and cand.extended and low is not None:
                    self._white_ends(bgr, cand, out, y0 + by0 + bh, entry)
                if cfg.rect_lean and cand.extended and top is not None and low is not None \
                        and sub[0] is not None and sub[1] is not None:
                    self._lean(value, cand, (ox, oy), out, by0 + dy + 0.5 * bh, size, entry)
                # no further than the image (labels are the visible part's box)
                x_a, y_a = max(cand.x, 0.0), max(cand.y, 0.0)
                cand.w = min(cand.x + cand.w, float(W)) - x_a
                cand.h = min(cand.y + cand.h, float(H)) - y_a
                cand.x, cand.y = x_a, y_a
                if cfg.pixel_boxes:
                    cand.x, cand.y, cand.w, cand.h = pixel_box(cand.x, cand.y, cand.w, cand.h)
                return cand
        if kind == 'regulatory' and search and not cand.extended:
            # neither a two-colour sign nor a measured rectangle: a diamond merged with a
            # surface of about its colour (an orange dusk sky above or beside it) is a
            # rectangle to the hull
            value, ox, oy = self._diamond_value(bgr, (x0, y0, x1, y1), bw, bh)
            sub = self._search_diamond(value, x0 - ox, y0 - oy, (bx0, by0, bw, bh), face_px,
                                       hsv)
            box_ = None if sub is None else self._diamond_box(
                (*sub, cfg.diamond_face_ratio, cfg.diamond_clamp_px), True,
                (bx0, by0, bw, bh), peel_t, True, bias=self._box_bias(sub))
            if entry is not None:
                entry['searched'] = box_ is not None
            if box_ is not None:
                cand.x, cand.y, cand.w, cand.h = x0 + box_[0], y0 + box_[1], box_[2], box_[3]
                cand.kind, cand.refined = 'warning', True
        if cfg.rect_needs_edges and rect_failed and cand.kind == 'regulatory' \
                and not cand.extended and not relaxed:
            return None
        return cand

    def _white_ends(self, bgr: np.ndarray, cand: Candidate, out: float, white_top: float,
                    entry: Optional[dict]) -> None:
        """Widen a measured two-colour sign's box ``cand`` to its white part's ends where
        the part runs on past the sides (:func:`white_part_ends`; the orange part was cut
        into pieces), within half the box's width beyond each side and to a width no more
        than the box's height (two-colour signs are taller than wide).  ``out``: the border
        line and margin outside the face (px); ``white_top``: the white part's first
        row."""
        face = (cand.x + out, cand.x + cand.w - out)
        ends = white_part_ends(bgr, face, (white_top, cand.y + cand.h - out),
                               0.5 * (face[1] - face[0]), max(2.0, 0.1 * (face[1] - face[0])))
        if entry is not None:
            entry['white_ends'] = ends
        new_l = face[0] if ends[0] is None else ends[0]
        new_r = face[1] if ends[1] is None else ends[1]
        if (new_l, new_r) == face or new_r - new_l + 2 * out > cand.h:
            return
        # the orange part runs on over the white part's new columns too (its other piece),
        # else the white beside the sign is the background's
        r0, r1 = int(math.ceil(cand.y + out)), int(white_top)
        if r1 - r0 < 2:
            return
        hsv = cv2.cvtColor(bgr[r0:r1, int(new_l):int(math.ceil(new_r))], cv2.COLOR_BGR2HSV)
        cols = np.arange(int(new_l), int(math.ceil(new_r))) + 0.5
        old = (cols > face[0]) & (cols < face[1])
        if not old.any() or old.all():
            return
        h_old, s_old = _median(hsv[:, old, 0]), float(_median(hsv[:, old, 1]))
        for side in (cols < face[0], cols > face[1]):
            if side.any() and not (abs(float(_median(hsv[:, side, 0])) - float(h_old)) <= 12
                                   and float(_median(hsv[:, side, 1])) >= 0.5 * s_old):
                return
        cand.x, cand.w = new_l - out, new_r - new_l + 2 * out

    def _lean(self, value: np.ndarray, cand: Candidate, org: tuple[float, float], out: float,
              y_sides: float, size: float, entry: Optional[dict]) -> None:
        """Widen a measured two-colour sign's box ``cand`` to its face turned in the image
        plane (a leaning post): the bounding box of the face whose sides lean as measured
        by :func:`rectangle_lean` (both alike, by at least ``rect_lean_min``).  ``value``:
        the brightness window at ``org`` (x, y); ``out``: the border line and margin
        outside the face (px); ``y_sides``: the row (in the window) at which the box's
        sides were measured."""
        cfg = self.config
        ox, oy = org
        face = (cand.x - ox + out, cand.y - oy + out, cand.x + cand.w - ox - out,
                cand.y + cand.h - oy - out)
        slopes = rectangle_lean(value, face, size, cfg.rect_border_rel, cfg.rect_margin_rel)
        if entry is not None:
            entry['lean'] = slopes
        if slopes is None:
            return
        sl, sr = slopes
        s = 0.5 * (sl + sr)
        if sl * sr <= 0 or abs(sl - sr) > cfg.rect_lean_agree or abs(s) < cfg.rect_lean_min:
            return
        # the sides (measured at y_sides) at the box's top and bottom rows; the top and
        # bottom (measured about the middle) at its corners
        ends = (s * (cand.y - oy - y_sides), s * (cand.y + cand.h - oy - y_sides))
        dl, dr = min(0.0, *ends), max(0.0, *ends)
        dv = 0.5 * abs(s) * (face[2] - face[0])
        cand.x, cand.w = cand.x + dl, cand.w - dl + dr
        cand.y, cand.h = cand.y - dv, cand.h + 2 * dv

    def _diamond_box(self, diamond: tuple, refined: bool, blob: tuple,
                     peel_t: Optional[float], larger: bool, cut: bool = False,
                     bias: float = 0.0) -> Optional[tuple]:
        """The sign's box ``(x, y, w, h)`` in the blob's window from ``diamond = (cx, cy, a,
        b, scale, pad)`` (the face and the sign / face ratio): no side further out than the
        clamp (``diamond_clamp``, ``peel_clamp`` for a peeled core, ``refined_clamp`` for a
        refined face, x the half-diagonal, + ``pad``) beyond the blob's box ``blob``; a
        refined outline in whole pixels (``pixel_boxes``).  None when far from the blob's
        own box (it may be ``larger`` than the sign when it took in a surface or a blended
        rim beyond it: a searched face, or one :meth:`_holds` calls blended).  ``cut``: the
        outline was measured above an occluder across the face's lower part; its bottom
        is not clamped (a guardrail in front of a sign on a stand hides a band of the face,
        and the labels, which are the visible pixels' box, take in the tip below it).
        ``bias``: the face's half-diagonals less this (px) for the box only
        (``diamond_box_bias``, the operating point; the checks before took the face as
        measured)."""
        cfg = self.config
        bx0, by0, bw, bh = blob
        cx_, cy_, a_, b_, k_, pad = diamond
        a_, b_ = a_ - bias, b_ - bias
        if refined and not cut and abs(a_ - b_) * 2 * k_ <= cfg.diamond_square_px and \
                (a_ + b_) * k_ < cfg.diamond_square_max:
            # a far sign seen about face on: its width and height are one measurement
            a_ = b_ = 0.5 * (a_ + b_)
        # a peeled core lost the face's parts nearest the surface's colour: its own box
        # bounds the sign more loosely
        cl_ = cfg.diamond_clamp if peel_t is None else max(cfg.diamond_clamp, cfg.peel_clamp)
        if refined:
            # a refined outline is the sign's from its own edges: a hidden tip (a guardrail
            # across the lower corner) is extrapolated further
            cl_ = max(cl_, cfg.refined_clamp)
        ca, cb = cl_ * a_ + pad, cl_ * b_ + pad
        if refined and cfg.pixel_boxes:
            # whole pixels, as box labels are drawn (the window's origin is a whole pixel)
            l_, t_, r_, u_ = diamond_pixel_box(cx_, cy_, k_ * a_, k_ * b_)
            l_, t_ = max(l_, round(bx0 - ca)), max(t_, round(by0 - cb))
            r_ = min(r_, round(bx0 + bw + ca))
            if not cut:
                u_ = min(u_, round(by0 + bh + cb))
        else:
            l_ = max(cx_ - k_ * a_, bx0 - ca)
            r_ = min(cx_ + k_ * a_, bx0 + bw + ca)
            t_ = max(cy_ - k_ * b_, by0 - cb)
            u_ = cy_ + k_ * b_ if cut else min(cy_ + k_ * b_, by0 + bh + cb)
        lo_ = 0.0 if larger else 0.8
        if lo_ * bw <= r_ - l_ <= 1.5 * bw + 2 and lo_ * bh <= u_ - t_ <= 1.5 * bh + 2:
            return l_, t_, r_ - l_, u_ - t_
        return None

    def _box_bias(self, face: Optional[Sequence[float]]) -> float:
        """``diamond_box_bias`` for a face :meth:`_refine` measured on sharp edges this
        frame, else 0: heavily blurred faces have their own bias (``diamond_blur_bias``),
        and there 0.15 px more cost winter signs 0.01 of recall for 0.003 of precision on
        120xx-123xx (sunny gained 0.006 of precision)."""
        if face is None or (float(face[2]), float(face[3])) not in self._sharp_faces:
            return 0.0
        return self.config.diamond_box_bias

    def _held_reaching(self, sub: Sequence[float], held_args: tuple, blob_xy: tuple
                       ) -> tuple[Optional[tuple], Optional[str]]:
        """:meth:`_held` (``held_args``: its arguments but ``sub``) of a fit from a moved
        start (:func:`refine_shifted`); of a blob (its box's corner ``blob_xy`` in the frame)
        the frame's edge cuts, only when the sign's diamond reaches past each edge the blob
        touches (a smaller whole diamond inside the frame fits part of the sign)."""
        bgr, hsv, face_px, dx, dy, window, bw, bh = held_args
        got = self._held(bgr, hsv, face_px, sub, dx, dy, window, bw, bh)
        if got[0] is None:
            return got
        x0, y0 = window[0], window[1]
        H, W = bgr.shape[:2]
        cut = frame_edges(blob_xy[0], blob_xy[1], bw, bh, W, H)
        if not any(cut):
            return got
        cx, cy, a, b = got[0]
        k = self.config.diamond_face_ratio
        reach = frame_edges(x0 + cx - k * a, y0 + cy - k * b, 2 * k * a, 2 * k * b, W, H, 1.0)
        return got if all(r for c, r in zip(cut, reach) if c) else (None, None)

    def _held(self, bgr: np.ndarray, hsv: np.ndarray, face_px: np.ndarray,
              sub: Sequence[float], dx: float, dy: float, window: tuple, bw: int, bh: int
              ) -> tuple[Optional[tuple], Optional[str]]:
        """A refined face ``sub`` (brightness window offset by ``dx, dy``) moved to the
        blob's window, and :meth:`_holds`'s verdict; ``(None, None)`` when the catalogue's
        outline does not hold the sign's orange pixels (a sign whose border line lies
        further in, a wider margin, is not measured so) or the mask stops short of a faded
        sign and so does this outline (:meth:`_inside_sign`).  ``'blended'``: the blob took
        in a blended rim and is larger than the sign."""
        sub = (sub[0] - dx, sub[1] - dy, sub[2], sub[3])
        held = self._holds(hsv, face_px, sub)
        if held == 'holds' and self._inside_sign(bgr, window, sub, bw, bh):
            held = None
        return (sub, held) if held else (None, None)

    def _holds(self, hsv: np.ndarray, face_px: np.ndarray, sub: Sequence[float],
               searched: bool = False) -> Optional[str]:
        """Whether the refined face ``sub`` (the blob's window) is the sign's.

        Yes when the catalogue's outline holds the blob's orange (:func:`diamond_holds`).
        Otherwise the orange it leaves out must be a background blended into, or merged
        with, the blob's edge (a dusk sky, rain haze; 5-30 % of a blob's pixels beyond a
        correct outline on tuning renders), not the face's own orange: fewer than half of
        the blob's pixels beyond the outline, and fewer than half of the ring half a pixel
        to a pixel and a half beyond it on each of the four sides, are as saturated as
        ``hold_sat`` x the face's median and not dark.  A fit on a line further in than the
        catalogue's (a wider margin, a symbol's edge) leaves the face's orange out.  A
        ``searched`` face (:func:`diamond_starts`) is always judged so: the search also
        finds diamonds inside a larger face.  Returns ``'holds'``, ``'blended'`` (the blob
        is larger than the sign) or None."""
        cfg = self.config
        k = cfg.diamond_face_ratio
        if not searched and diamond_holds(face_px, sub, k, cfg.diamond_hold):
            return 'holds'
        if cfg.hold_sat <= 0:
            return None
        cx, cy, a, b = (float(v) for v in sub[:4])
        h, w = face_px.shape
        ys, xs = np.arange(h)[:, None], np.arange(w)[None, :]      # (broadcast: np.mgrid's)
        rel = np.abs(xs + 0.5 - cx) / a + np.abs(ys + 0.5 - cy) / b
        dist = (rel - k) * (a * b / math.hypot(a, b))      # px beyond the outline
        ring = (dist >= 0.5) & (dist <= 1.5)
        inside = (face_px > 0) & (rel <= 0.9)               # the face's own orange
        if not ring.any() or not inside.any():
            return None
        sat, val = hsv[..., 1], hsv[..., 2]
        # the face's own orange: as saturated and not dark (a legend stroke is neither)
        face_like = (sat >= cfg.hold_sat * float(_median(sat[inside]))) & (
            val >= cfg.dark_rel * float(_median(val[inside])))
        # the blob's pixels beyond the outline: a background blended in or merged with the
        # sign is not the face's orange; a fit inside a larger face leaves that face out
        beyond = (face_px > 0) & (dist >= 0.5)
        if np.count_nonzero(face_like & beyond) >= 0.5 * max(np.count_nonzero(beyond), 1):
            return None
        # and on every side the ring just beyond the outline is not the face's orange
        for right in (False, True):
            for low in (False, True):
                side = ring & ((xs + 0.5 > cx) == right) & ((ys + 0.5 > cy) == low)
                if np.count_nonzero(face_like & side) >= 0.5 * max(np.count_nonzero(side), 1):
                    return None
        return 'blended'

    def _tip_hidden(self, win: np.ndarray, sign: tuple, cut: int, level: float
                    ) -> Optional[int]:
        """The row where an occluder across a warning sign's lower part (see
        :meth:`_cut_row`) begins when it hides the sign's tip, else None: it lies across
        the face and reaches past the sign's bottom.

        ``sign = (cx, cy, a, b)``: the sign's whole outline in the window ``win`` (reaching
        down past the sign); ``cut``: the first row hidden.  Across: on the two rows below
        the cut the pixels inside the outline differ from those 1-3 px beside it by less
        than 0.3 x the face's own difference just above the cut (the largest channel
        difference of the means).  Reaching past the bottom: every row from the cut to a
        row below the sign's bottom corner, over the sign's width, differs from those first
        two rows by less than that too (a vehicle's side, not a guardrail with the tip
        showing below it), or (``tip_colour``; an occluder of two tones, a vehicle's pale
        side over its dark sill) no pixel inside the outline below those two rows has the
        sign's colour (orange likelihood >= ``level``, the blob's threshold: a tip
        showing below a rail is the face's colour).  The occluder begins at ``cut`` or,
        when that row is a blend of the face and the occluder (blur, the camera's chroma;
        ``cut_blend_rows``), at the first of the rows after it that are across: the
        labels end where the face covers less than half of a row's pixels."""
        cx, cy, a, b = sign
        h, w = win.shape[:2]
        end = int(math.ceil(cy + b)) + 1
        if cy + b - cut < self.config.tip_min_cut * b or end >= h or cut < 3:
            return None
        img = win[:end + 1].astype(np.float32)          # (the rows looked at)
        xs = np.abs(np.arange(w) + 0.5 - cx)

        def split(r: int) -> tuple:
            hw = a * (1.0 - abs(r + 0.5 - cy) / b)
            ins = xs <= max(hw, 0.5)
            fl = (xs >= hw + 1.0) & (xs <= hw + 3.0)
            if not ins.any() or np.count_nonzero(fl) < 2:
                return None, None
            return img[r, ins].mean(axis=0), img[r, fl].mean(axis=0)

        faces = [split(r) for r in range(cut - 3, cut)]
        face = [float(np.abs(i - f).max()) for i, f in faces if i is not None]
        if not face or not np.median(face) > 0:
            return None
        tol = 0.3 * float(np.median(face))

        rows_seen: dict = {}

        def across(r: int) -> bool:
            if r not in rows_seen:
                rows_seen[r] = split(r)
            i, f = rows_seen[r]
            return i is not None and float(np.abs(i - f).max()) < tol

        start = next((r for r in range(cut, cut + 1 + self.config.cut_blend_rows)
                      if r + 1 <= end and across(r) and across(r + 1)), None)
        if start is None:
            return None
        occ = np.mean([0.5 * (i + f) for i, f in (rows_seen[start], rows_seen[start + 1])],
                      axis=0)
        span = img[start:end + 1, np.abs(np.arange(w) + 0.5 - cx) <= a].mean(axis=1)
        if (np.abs(span - occ).max(axis=1) < tol).all():
            return start
        if not self.config.tip_colour or end < start + 2:
            return None
        rows = win[start + 2:end + 1]
        like = self._orange_like(cv2.cvtColor(
            rows if self._gains is None else apply_gains(rows, self._gains), cv2.COLOR_BGR2HSV))
        ry = np.arange(start + 2, end + 1)[:, None] + 0.5
        outline = xs[None, :] <= a * (1.0 - np.abs(ry - cy) / b)
        return None if (outline & (like >= level)).any() else start

    def _cut_row(self, face: np.ndarray, row_fit: Optional[tuple]) -> Optional[int]:
        """The row where an occluder across a warning face's lower part begins, or None.

        The face's rows fit a diamond (:func:`fit_diamond`, ``row_fit``) whose bottom corner
        lies at least ``max(2, 0.15 b)`` px below the face's last row, and one of its last
        three rows, below the diamond's middle, is at least ``cut_min_width`` x as wide as
        the diamond there (the rows after it blend into the occluder): a straight
        horizontal cut, not a tip thinned by blur.  The cut is the row after that one."""
        frac = self.config.cut_min_width
        if frac <= 0 or row_fit is None or row_fit[4] < 0.5:
            return None
        cx, cy, a, b = row_fit[:4]
        yc, left, right = _row_extents(face)
        if yc.size < 3 or yc[-1] + 0.5 > cy + b - max(2.0, 0.15 * b):
            return None
        for k in range(yc.size - 1, yc.size - 4, -1):
            if yc[k] <= cy:
                break
            if right[k] - left[k] >= frac * 2 * a * (1 - (yc[k] - cy) / b):
                return int(yc[k] + 0.5)
        return None

    def _refine(self, value: np.ndarray, start: Sequence[float],
                min_contrast: float = EDGE_MIN_CONTRAST, hidden: Optional[float] = None,
                strokes: bool = True) -> Optional[tuple[float, float, float, float]]:
        """:func:`refine_diamond` with this detector's settings; the face's half-diagonals
        less ``diamond_edge_bias`` (a blurred border line puts the measured edge that far
        out, whatever the sign's size), or less ``diamond_blur_bias`` when the edges' fitted
        blur is ``diamond_blur_sigma`` px or more; the height at most ``diamond_tall_max`` x
        the width and the width at most ``diamond_wide_max`` x the height.  ``strokes``:
        leave out the edge stretches a stroke runs into (``diamond_stroke_steps``); not for
        the search's starts, which are guesses: with fewer stretches a small diamond inside a
        symbol's strokes can pass."""
        cfg = self.config
        info: dict = {}
        sub = refine_diamond(value, start, cfg.diamond_border_rel, cfg.diamond_margin_rel,
                             cfg.diamond_max_change, min_contrast, info=info,
                             hidden_below=hidden,
                             stroke_steps=cfg.diamond_stroke_steps if strokes else 0,
                             bright_bias=cfg.diamond_bright_bias)
        if sub is None:
            return None
        bias = cfg.diamond_edge_bias
        sharp = info.get('blur', 0.0) < cfg.diamond_blur_sigma
        if not sharp:
            bias = cfg.diamond_blur_bias          # heavily blurred edges (defocus, motion)
        a, b = self._plausible(sub[2] - bias, sub[3] - bias)
        if sharp:
            self._sharp_faces.add((a, b))
        return sub[0], sub[1], a, b

    def _plausible(self, a: float, b: float) -> tuple[float, float]:
        """Half-diagonals ``a, b`` of a measured face cut back to a plausible shape: a square
        sign facing the road is as tall as wide, taller when turned away
        (``diamond_tall_max``), wider only a little (``diamond_wide_max``)."""
        b = min(b, self.config.diamond_tall_max * a)
        return min(a, self.config.diamond_wide_max * b), b

    def _chroma(self, bgr: np.ndarray, x0: int, y0: int, x1: int, y1: int
                ) -> tuple[np.ndarray, int, int]:
        """The chroma R - B (float32, colour-balanced; linear in a blend of two colours) of
        ``bgr[y0:y1, x0:x1]`` clipped to the frame, and the clipped window's origin."""
        win, x0, y0 = self._window(bgr, x0, y0, x1, y1)
        return win[..., 2].astype(np.float32) - win[..., 0].astype(np.float32), x0, y0

    def _inside_sign(self, bgr: np.ndarray, window: tuple, sub: Sequence[float], bw: int,
                     bh: int) -> bool:
        """Whether the sign outline of the face ``sub`` (the blob's window ``(x0, y0, x1,
        y1)``) lies inside a sign that goes on: the chroma of the ring 0.5-1.5 px beyond it
        is on average more than ``rim_chroma`` of the way from the background's (3-6 px
        beyond) to the face's (its middle's upper quartile)."""
        cfg = self.config
        if cfg.rim_chroma <= 0:
            return False
        # a few pixels beyond the blob's window, as :meth:`_diamond_value`
        chroma, ox, oy = self._chroma(bgr, *_padded(window, bw, bh))
        cx, cy = sub[0] + window[0] - ox, sub[1] + window[1] - oy
        a, b = float(sub[2]), float(sub[3])
        k = cfg.diamond_face_ratio
        h, w = chroma.shape
        # a column and a row of coordinates, broadcast (np.mgrid's full grids hold the same
        # values on every row and column)
        ys, xs = np.arange(h)[:, None], np.arange(w)[None, :]
        dx, dy = np.abs(xs + 0.5 - cx), np.abs(ys + 0.5 - cy)
        rel = dx / (k * a) + dy / (k * b)
        dist = (rel - 1.0) * (k * a * k * b / math.hypot(k * a, k * b))
        ring = (dist >= 0.5) & (dist <= 1.5)
        back = (dist >= 3.0) & (dist <= 6.0)
        middle = dx / a + dy / b < 0.6
        if not (ring.any() and back.any() and middle.any()):
            return False
        bg = float(_median(chroma[back]))
        # (np.percentile(..., 75)'s value, without its generic machinery)
        face = float(_quantile(chroma[middle], 0.75))
        if face <= bg:
            return False
        return float(chroma[ring].mean()) - bg > cfg.rim_chroma * (face - bg)

    def _blur_fit(self, bgr: np.ndarray, window: tuple, blob: tuple, fd: Optional[tuple]
                  ) -> Optional[tuple[float, float, float, float]]:
        """The sign's diamond ``(cx, cy, a, b)`` (the blob's window ``(x0, y0, x1, y1)``) by
        :func:`fit_blurred_diamond` on the chroma R - B of the colour-balanced frame, from the
        mask's diamond ``fd`` or the blob's box ``blob``, less ``blur_fit_bias``; None when the
        blob touches the frame's edge, the fit fails, its centre lies outside the blob's box
        or the sign would be smaller than the blob's box by more than a pixel a side."""
        cfg = self.config
        x0, y0, x1, y1 = window
        bx, by, bw, bh = blob
        pad = 3 + int(0.3 * max(bw, bh))
        H, W = bgr.shape[:2]
        if any(frame_edges(x0 + bx, y0 + by, bw, bh, W, H, 1.0)):
            return None             # cut off by the frame's edge: no whole diamond to fit
        chroma, wx0, wy0 = self._chroma(bgr, x0 + bx - pad, y0 + by - pad,
                                        x0 + bx + bw + pad, y0 + by + bh + pad)
        dx, dy = x0 - wx0, y0 - wy0
        if fd is not None:
            start = (fd[0] + dx, fd[1] + dy, fd[2], fd[3])
        else:
            start = (bx + 0.5 * bw + dx, by + 0.5 * bh + dy, 0.5 * bw, 0.5 * bh)
        fit = fit_blurred_diamond(chroma, start, cfg.blur_fit_max_sigma)
        if fit is None:
            return None
        cx, cy = fit[0] - dx, fit[1] - dy
        bias = cfg.blur_fit_bias / cfg.blur_fit_ratio
        a, b = fit[2] - bias, fit[3] - bias
        # the sign holds its own orange: a fit on an edge inside the mask (a line further
        # in than the catalogue's, the orange margin outside it left out) is no sign's
        k = cfg.blur_fit_ratio
        if not (bx <= cx <= bx + bw and by <= cy <= by + bh
                and 2 * k * a >= bw - 2 and 2 * k * b >= bh - 2):
            return None
        return (cx, cy, *self._plausible(a, b))      # the shape limits of a refined face

    def _search_diamond(self, value: np.ndarray, dx: int, dy: int, box: tuple,
                        face_px: np.ndarray, hsv: np.ndarray
                        ) -> Optional[tuple[float, float, float, float]]:
        """The face diamond refined from :func:`diamond_starts` in the blob's box (``box`` and
        ``face_px`` in the blob's window, ``value`` offset from it by ``(dx, dy)``), or None.

        Kept only when :meth:`_refine` converges from a start with a clear line
        (``search_min_contrast``), the face lies inside the blob's box (a pixel for the
        blend, ``diamond_clamp_px`` for a small blurred face's mask), the sign is at least
        ``search_min_share`` of the blob's shorter side, and the orange the outline leaves
        out is not the face's own (:meth:`_holds`)."""
        cfg = self.config
        bx, by, bw, bh = box
        shrink = start_shrink(cfg.diamond_border_rel, cfg.diamond_margin_rel)
        for cx, cy, a, _, _ in diamond_starts(value, (bx + dx, by + dy, bw, bh),
                                              0.3 * min(bw, bh), 0.6 * max(bw, bh)):
            # refine_diamond shrinks its start from an outline to the face: undo that; a
            # clear line: the sign's outer edge against dark asphalt is no face's edge
            sub = self._refine(value, (cx, cy, a / shrink, a / shrink), cfg.search_min_contrast,
                               strokes=False)
            if sub is None:
                continue
            sub = (sub[0] - dx, sub[1] - dy, sub[2], sub[3])
            k, (scx, scy, sa, sb) = cfg.diamond_face_ratio, sub
            # the face (orange) within the blob's box, a pixel for the blend and the pixel
            # blur eats of a small face's mask (``diamond_clamp_px``): a face larger than its
            # blob is a fragment's (merge_fragments measures those) or the sign's outer edge
            # against a dark background taken for the face's
            e_ = 1.0 + cfg.diamond_clamp_px
            if (scx - sa >= bx - e_ and scx + sa <= bx + bw + e_
                    and scy - sb >= by - e_ and scy + sb <= by + bh + e_
                    and 2 * k * min(sa, sb) >= cfg.search_min_share * min(bw, bh)
                    and self._holds(hsv, face_px, sub, searched=True)):
                return sub
        return None

    def _surround_like(self, hmask: np.ndarray, like: np.ndarray, size: int, level: float
                       ) -> tuple[float, float]:
        """(mean likelihood, share of pixels of likelihood >= ``level``) of the ring from
        ``surround_in`` to ``surround_out`` x ``size`` outside the blob's hull (beyond a
        sign's border and the blur of its edge); zeros when the ring is empty."""
        cfg = self.config
        r1 = max(1, int(round(cfg.surround_in * size)))
        r2 = max(r1 + 1, int(round(cfg.surround_out * size)))
        d1 = cv2.dilate(hmask, np.ones((2 * r1 + 1, 2 * r1 + 1), np.uint8))
        d2 = cv2.dilate(hmask, np.ones((2 * r2 + 1, 2 * r2 + 1), np.uint8))
        ring = (d2 > 0) & (d1 == 0)
        if not ring.any():
            return 0.0, 0.0
        lr = like[ring]
        return float(lr.mean()), float(np.count_nonzero(lr >= level) / lr.size)

    def _banded(self, bgr: np.ndarray, bx: int, by: int, bw: int, bh: int, pix: np.ndarray,
                v_ref: float, t: float) -> bool:
        """:func:`banded_rows` (and the cone cap) on a strip over the blob's middle half of
        columns, reaching a blob height and two blends above and below it (a drum's stripes
        are as high as its orange ones).  Orange: likelihood at least ``t``; white: see
        ``band_test``, and not a row whose white runs on past both of the blob's sides
        (half its width either side: the background); dark relative to ``v_ref``."""
        cfg = self.config
        H, W = bgr.shape[:2]
        # the strip's columns: the middle half of the blob's (a cone's tip is narrow), with
        # flanks of half the blob's width either side
        q = max(1, bw // 4)
        c0, c1 = max(0, bx + q), min(W, bx + bw - q)
        f0, f1 = max(0, bx - bw // 2), min(W, bx + bw + bw // 2)
        gap = max(2, int(round(0.15 * bh)))
        reach = bh + 2 * gap + 2             # a band as high as the blob, blend either side
        r0, r1 = max(0, by - reach), min(H, by + bh + reach)
        if c1 <= c0 or r1 <= r0:
            return False
        wide = bgr[r0:r1, f0:f1]
        if self._gains is not None:
            wide = apply_gains(wide, self._gains)
        # one conversion of the flanked window; the strip is a view of it
        whsv = cv2.cvtColor(wide, cv2.COLOR_BGR2HSV)
        wluma = cv2.cvtColor(wide, cv2.COLOR_BGR2GRAY)
        hsv = whsv[:, c0 - f0:c1 - f0]
        i = self._idx['orange']
        like = _lookup(self.model.luts[i], hsv[..., 0], self._sat(hsv))
        v = hsv[..., 2]
        # the orange beyond a band (a cone's tip) at the blob's own threshold
        orange = (like >= t - 1e-6) & (v >= self.model.v_min[i])
        # white sheeting reflects every channel: brighter (luma) than the orange face under
        # the same light, where a legend or a grey patch lifted by rain or fog is not
        luma = wluma[:, c0 - f0:c1 - f0]
        face = orange[by - r0:by + bh - r0]
        if not face.any():
            return False
        y_ref = float(_median(luma[by - r0:by + bh - r0][face]))
        white = (hsv[..., 1] <= cfg.white_s_max) & (luma >= cfg.band_white_luma * y_ref)
        # a band is the object's own: bounded by its silhouette; white that runs on past
        # the blob's sides on both flanks is the background (an overcast sky, snow, a
        # wall), e.g. above a sign's top corner, below its portable stand's flags
        wwhite = (whsv[..., 1] <= cfg.white_s_max) & (wluma >= cfg.band_white_luma * y_ref)
        lf, rf = wwhite[:, :max(0, bx - f0)], wwhite[:, min(f1, bx + bw) - f0:]
        open_rows = open_background_rows(lf, rf, max(1, bw // 4))
        if open_rows is not None:
            white = white & ~open_rows[:, None]
        dark = v < cfg.dark_rel * v_ref
        # MUTCD bands: a cone's narrower band (4 in.) is about a quarter of the orange part
        # below it with the base (less the blend of its two edges when small), a drum's
        # stripes are as high as its orange ones; a sign's white outline or margin is a few
        # per cent of its size
        run = max(2, int(round(cfg.band_min_rows * bh)))
        # the orange beyond: a cone's tip is thin and blurred, half a band's rows will do
        beyond = max(3, int(round(0.1 * bh)))
        if banded_rows(orange, white, dark, by - r0, by + bh - r0, run, gap, bh + gap, beyond):
            return True
        # a cone whose tip is white or lost: a white band right over a blob that is taller
        # than wide and widens downward (a diamond is symmetric; a diamond's top half alone
        # is twice as wide as high)
        return (bh >= bw and row_taper(pix) <= cfg.cone_taper
                and white_cap(white, by - r0, run, gap))

    def _clear_diamond(self, pix: np.ndarray, row_fit: Optional[tuple] = None) -> bool:
        """Whether a blob is a clear diamond face, what may stand below the usual mounting
        height (a portable stand's sign): about square, diamond-filled, its rows and
        columns each a two-sided tent (:func:`fit_diamond`; its corners about the blob's
        middle: a triangle's rows follow a one-sided tent, its apex at the base), and solid
        (``low_min_solidity``) or following the tents on ``low_min_inliers`` of its rows and
        columns (a large black symbol, a lane-shift arrow, cuts the orange face but not its
        outline).  A blob whose rows beyond the fitted diamond's corners (a stand's flags)
        spoil this is judged without them.  ``row_fit``: :func:`fit_diamond` of ``pix``
        when already known."""
        cfg = self.config
        for k in range(2):
            if k == 1:
                if cfg.diamond_trim < 0:
                    return False
                pix, _ = self._trim_to_diamond(pix, cfg.diamond_trim, row_fit)
                if pix is None:
                    return False
                row_fit = None
            pts = cv2.findNonZero(pix)
            if pts is None or len(pts) < 5:
                return False
            hull = cv2.convexHull(pts)
            hull_area = max(float(cv2.contourArea(hull)), 1.0)
            # the hull's box is the pixels' box
            x, y, w, h = cv2.boundingRect(hull)
            solidity, fill = len(pts) / hull_area, hull_area / (w * h)
            if fill >= cfg.diamond_hull_fill or max(w / h, h / w) > cfg.low_max_aspect:
                continue
            fr = row_fit if row_fit is not None else fit_diamond(pix)
            fc = fit_diamond(np.ascontiguousarray(pix.T))
            if fr is None or fc is None:
                continue
            centred = (abs(fr[1] - (y + 0.5 * h)) <= 0.15 * h
                       and abs(fc[1] - (x + 0.5 * w)) <= 0.15 * w)
            if centred and (solidity >= cfg.low_min_solidity
                            or min(fr[4], fc[4]) >= cfg.low_min_inliers):
                return True
        return False

    @staticmethod
    def _trim_to_diamond(pix: np.ndarray, tol: float, row_fit: Optional[tuple] = None
                         ) -> tuple[Optional[np.ndarray], Optional[tuple]]:
        """(``pix`` without the rows beyond the fitted diamond's corners, or None when none
        are; :func:`fit_diamond`'s row fit of ``pix``).

        Rows further than ``0.5 + tol x b`` px above the top corner or below the bottom
        corner of :func:`fit_diamond`'s diamond are dropped (the margin keeps a corner that
        the fit's noisy slope put a little short).  ``row_fit``: :func:`fit_diamond` of
        ``pix`` when already known.
        """
        fd = row_fit if row_fit is not None else fit_diamond(pix)
        if fd is None:
            return None, fd
        _, cy, _, b, inl = fd
        if inl < 0.5:
            return None, fd
        margin = 0.5 + tol * b
        lo, hi = int(math.floor(cy - b - margin)), int(math.ceil(cy + b + margin))
        rows = np.nonzero(pix.any(axis=1))[0]
        if rows.size == 0 or (rows[0] >= lo and rows[-1] < hi):
            return None, fd
        out = pix.copy()
        out[:max(lo, 0)] = 0
        out[max(hi, 0):] = 0
        if np.count_nonzero(out) < 0.5 * np.count_nonzero(pix):
            return None, fd
        return out, fd

    @staticmethod
    def _neck_trim(pix: np.ndarray) -> Optional[np.ndarray]:
        """``pix`` without its rows above a neck, or None when it has none.

        A portable stand's orange flags merged with the diamond below them by blur: the
        rows' extents narrow from the flags' width to the diamond's top corner and widen
        again.  A neck: a row in the upper half of the blob at most half as wide as the
        widest row below it, with a row above it at least 1.5 x as wide (the flags) that
        tapers into it (the widest row at least two rows up, the row just above at most
        0.8 x as wide: not a diamond's widening upper half over a row that a legend line
        cut short), and the part from it down about as tall as wide (0.7-1.4) and ending in
        a corner (its last row at most 0.6 x its widest: a diamond).
        """
        rows, left, right = _row_extents(pix)
        n = rows.size
        if n < 12 or rows[-1] - rows[0] + 1 != n:
            return None
        ext = right - left
        # per candidate row k (2 .. n / 2): the widest row above it (the first such) and
        # the widest below it, from running maxima (this runs on every blob not wide)
        idx = np.arange(n)
        top_max = np.maximum.accumulate(ext)
        first = np.maximum.accumulate(np.where(ext > np.r_[-np.inf, top_max[:-1]], idx, 0))
        low_max = np.maximum.accumulate(ext[::-1])[::-1]
        k = np.arange(2, n // 2 + 1)
        above, j, width = top_max[k - 1], first[k - 1], low_max[k + 1]
        ok = (ext[k] <= 0.5 * width) & (above >= 1.5 * ext[k])
        # the flags taper into the neck; a row cut short by a legend line under a
        # diamond's widening upper half does not
        ok &= (k - j >= 2) & (ext[k - 1] <= 0.8 * above)
        ratio = (n - k) / width
        ok &= (ratio >= 0.7) & (ratio <= 1.4) & (ext[-1] <= 0.6 * width)
        if not ok.any():
            return None
        cand = k[ok]
        # the narrowest neck, the lowest of equals
        best = int(cand[np.flatnonzero(ext[cand] == ext[cand].min())[-1]])
        out = pix.copy()
        out[:int(rows[best] - 0.5)] = 0
        return out

    @staticmethod
    def _relative_levels(like: np.ndarray, strong: np.ndarray, region: np.ndarray,
                         rel: tuple) -> tuple[float, float]:
        """(edge, blur) likelihood thresholds of one blob from its own levels.

        The face level is the mode of the blob's strong pixels' likelihood (the blob's
        confidence, eq. 2), the background level the median likelihood of the measuring
        window outside the (dilated) blob.  An edge blurred by the optics or by resampling
        goes from one level to the other; ``rel = (edge_rel, blur_rel)`` place the core's
        edge and the blur-ring thresholds at ``base + rel x (face - base)`` (0.5: the
        half-maximum rule).
        """
        face = _mode(like[strong > 0])
        outside = like[region == 0]
        base = min(float(_median(outside)) if outside.size else 0.0, face)
        span = face - base
        return base + rel[0] * span, base + rel[1] * span

    def _border_growth(self, hmask: np.ndarray, dark: np.ndarray, like: np.ndarray,
                       size: int, blur_like: Optional[float] = None) -> tuple[float, dict]:
        """Per-side box growth of one blob from its own edge profile (fraction of its size).

        The sign art has a thin outer orange margin and a black border line inside it.  Two
        bands of ``border_frac`` x size are compared: just inside the orange hull and just
        outside it.  If the black line lies outside the hull (the outer band is darker than
        the inner one) the hull stops at the line's inner edge, the margin and line are
        missing and the box grows by ``border_frac``; if the line is inside the hull (the
        margin was found, or bright light pulled the surroundings in) it does not grow.
        ``border_dark`` > 0 replaces the comparison by "outer band dark share >= it";
        ``border_mode='always'`` always grows (the old behaviour).
        """
        cfg = self.config
        blur_like = cfg.blur_like if blur_like is None else blur_like
        r = max(1, int(round(cfg.border_frac * size)))
        k = np.ones((2 * r + 1, 2 * r + 1), np.uint8)
        outer = (cv2.dilate(hmask, k) > 0) & (hmask == 0)
        inner = (hmask > 0) & (cv2.erode(hmask, k) == 0)
        no, ni = np.count_nonzero(outer), np.count_nonzero(inner)
        out_dark = np.count_nonzero(dark & outer) / max(no, 1)
        in_dark = np.count_nonzero(dark & inner) / max(ni, 1)
        # blur width: 1-px rings outside the hull whose mean likelihood still shows the
        # sign's colour blended with the background (soft edges: rain, fog, small signs)
        blur, prev, ring_k = 0, hmask, np.ones((3, 3), np.uint8)
        for _ in range(int(cfg.blur_max_frac * size) + 2):
            nxt = cv2.dilate(prev, ring_k)
            ring = (nxt > 0) & (prev == 0)
            if not ring.any() or float(like[ring].mean()) < blur_like:
                break
            blur, prev = blur + 1, nxt
        feats = dict(ring=out_dark, inner=in_dark, blur=blur)
        if cfg.border_mode == 'always':
            return cfg.border_frac, feats
        if no == 0:
            return 0.0, feats
        line_out = (out_dark >= cfg.border_dark) if cfg.border_dark > 0 else out_dark >= in_dark
        if self._relative is not None and in_dark >= 0.5:
            # a smooth table's face reaches over the border line: a band just inside the
            # hull that is mostly dark is the line itself, nothing is missing outside it
            line_out = False
        return (cfg.border_frac if line_out else 0.0) + blur / float(size), feats

    def _extend(self, bgr: np.ndarray, cand: Candidate, orange_hsv: np.ndarray
                ) -> Optional[tuple[int, list]]:
        """Seed 000's regulatory two-colour extension: grow the box over a white bottom.
        Returns, when the white part's end was looked for among several dark bands and
        none gave a catalogue shape by the blob's width (:meth:`_bottom_border`), the
        strip's top row and those bands' rows (after it) for :meth:`_measure_orange` to
        choose again with the measured width; else None."""
        cfg = self.config
        H = bgr.shape[0]
        x0, x1 = int(cand.x), int(cand.x + cand.w)
        y_top = int(cand.y + cand.h)
        # reach: ``ext_max_ratio`` x the orange height, or (a thin plaque over a tall white
        # sign, R2-1 + G20-5aP) up to ``ext_max_wratio`` x the width
        y_max = min(H, int(y_top + max(cfg.ext_max_ratio * cand.h, cfg.ext_max_wratio * cand.w)))
        if y_max - y_top < 2:
            return None
        strip = bgr[y_top:y_max, max(0, x0):x1]
        if strip.size == 0:
            return None
        raw_s = None
        if self._gains is not None:
            # white is judged both as the camera balanced it and after the grey-world gains:
            # the gains remove a dusk cast from white sheeting, but under a blue sky they
            # tint white sheeting yellow (S ~ 40..60) and the white part would be lost
            raw_s = cv2.cvtColor(strip, cv2.COLOR_BGR2HSV)[..., 1]
            strip = apply_gains(strip, self._gains)
        strip = cv2.cvtColor(strip, cv2.COLOR_BGR2HSV)
        sat = strip[..., 1] if raw_s is None else np.minimum(strip[..., 1], raw_s)
        v_ref = float(_median(orange_hsv[:, 2])) if orange_hsv.size else 200.0
        white = (sat <= cfg.white_s_max) & (strip[..., 2] >= cfg.white_v_rel * v_ref)
        # black legend rows inside the white part: judge rows on a short running window
        frac = white.mean(axis=1)
        k = max(1, int(round(cand.h * 0.25)))
        gap = max(k, int(round(cfg.ext_gap_w * cand.w)))
        run = self._white_run(white, frac, strip, sat, v_ref, k, gap)
        if cfg.white_own_rel > 0 and y_top + run >= y_max - 1:
            # white to the end of the reach: the sign's own white part (bright sheeting)
            # may be followed by a duller grey background that passed for white by the
            # orange's level (under a grey sky a dull orange is little brighter than the
            # road, verge or snow): judged again against the white part's own level, the
            # part ends at the sign's bottom, and the rest of the reach (a few rows at
            # least) is not white (a background as bright as the sheeting, snow, is left to
            # the bottom border)
            white2, frac2 = self._own_white(white, frac, strip[..., 2], k)
            run2 = self._white_run(white2, frac2, strip, sat, v_ref, k, gap)
            if run2 >= 0.3 * cand.h and y_max - y_top - run2 >= max(3, 2 * k) \
                    and frac2[run2:].mean() < 0.3:
                white, frac, run = white2, frac2, run2
        cuts: list = []
        if cfg.ext_frame and y_top + run >= y_max - 1:
            # white (or what the legend-gap rule bridged) to the end of the reach: snow, a
            # pale sky or wall behind the sign.  The white part ends with its black bottom
            # border
            end = self._bottom_border(white[:run], strip[:run, :, 2], cand.h, cand.w, cuts)
            if end:
                run = end
        if cfg.ext_overlong > 0 and y_top + run < y_max - 1 and cand.h + run > max(
                _TWO_COLOUR_RATIOS) * (1.0 + cfg.ext_overlong) * cand.w:
            # white far past any two-colour sign's height for the width, ending before the
            # reach: a pale wall right behind the sign (in rain as bright as white by the
            # orange's level) continued the white part past its black bottom border, which
            # the legend-gap rule bridged.  The part ends after the bridged row (under 45 %
            # white) that gives the height nearest a two-colour sign's, within
            # ``ext_overlong`` (the box is still grown by the blur here)
            low = np.flatnonzero(frac[:run] < 0.45)
            low = low[low + 1 >= 0.3 * cand.h]
            done = False
            if low.size:
                err = _ratio_error(cand.h + low + 1, cand.w)
                if err.min() <= cfg.ext_overlong:
                    run = int(low[int(np.argmin(err))]) + 1
                    done = True
            if not done and cfg.ext_overlong_border > 0:
                share = _dark_share(strip[:run, :, 2], cfg.ext_border_rel)
                rows = np.flatnonzero(share >= cfg.ext_overlong_border)
                rows = rows[rows + 1 >= 0.3 * cand.h]
                if rows.size:
                    cut = _bands(rows)[1] + 1            # the row after each dark band
                    err = _ratio_error(cand.h + cut, cand.w)
                    if err.min() <= cfg.ext_overlong:
                        run = int(cut[int(np.argmin(err))])
        if self.debug is not None:
            self.debug.append(dict(ext_run=run, ext_rows=y_max - y_top,
                                   ext_frac=np.round(frac, 2).tolist()))
        if run < 0.3 * cand.h or y_top + run >= y_max - 1:
            return None         # too short, or no bottom edge found (sky, a white wall)
        # a sign's white part carries a black legend and border; sky and walls do not
        # (dark relative to the white part itself: under overcast light the legend is grey)
        part = strip[:run]
        v_white = float(_median(part[..., 2][white[:run]])) if white[:run].any() else v_ref
        dark = part[..., 2] < cfg.dark_rel * v_white
        if dark.mean() < cfg.ext_min_dark:
            return None
        cand.h = float(run + cand.h)
        cand.extended = True
        cand.white_level = v_white / max(v_ref, 1.0)
        # (its upper half: an extension that ran on past the sign's bottom took in
        # background rows there)
        top_half = slice(0, max(2, (run + 1) // 2))
        cand.white_span = _white_span(white[top_half][frac[top_half] >= 0.45], max(0, x0))
        return (y_top, cuts) if cuts else None

    def _white_run(self, white: np.ndarray, frac: np.ndarray, strip: np.ndarray,
                   sat: np.ndarray, v_ref: float, k: int, gap: int) -> int:
        """How many rows of the HSV ``strip`` under the orange part the white part runs
        (:meth:`_extend`): rows at least 45 % ``white`` (``frac``) on a running window of
        ``k`` rows, across rows of a black legend up to ``gap`` rows when they are
        achromatic (:meth:`_achromatic_rows`; ``sat``: the saturation as judged for white,
        ``v_ref``: the orange's brightness), less the rows at its end that are not white."""
        cfg = self.config
        smooth = np.convolve(frac, np.ones(k) / k, mode='full')[:len(frac)]
        # rows of a large black legend (speed-limit numerals) are not white, but they are
        # achromatic like the sheeting around them: such rows may separate white rows by up
        # to ``ext_gap_w`` x the width (background rows, foliage or sky, are coloured)
        # (judged on the row's bright pixels: a dark legend stroke's saturation is noise, a
        # row of large numerals would otherwise look coloured)
        achrom = self._achromatic_rows(strip, sat, v_ref)
        run, cols_judged, achrom_cols = 0, False, None
        for j, f in enumerate(smooth):
            if f >= 0.45 or (j < k and frac[: j + 1].mean() >= 0.45):
                run = j + 1
            elif j - run > k and (j - run > gap or not achrom[run:j + 1].all()):
                if j - run > gap or not cfg.ext_gap_cols or run == 0:
                    break
                # the blob (and so the strip) may be wider than the sign (a dusk
                # background of its colour beside it): judge the gap's rows again on the
                # white part's own columns
                if not cols_judged:
                    # (judged once, on the white rows before the first such gap)
                    cols_judged = True
                    rows = white[:run][frac[:run] >= 0.45]
                    cols = rows.mean(axis=0) >= 0.5 if len(rows) else None
                    if cols is not None and cols.sum() >= 3:
                        # bright: against the white sheeting's own level (at dusk it is
                        # far brighter than the orange; noise makes dim pixels coloured)
                        v_w = float(_median(strip[:run, cols, 2][white[:run, cols]]))
                        achrom_cols = self._achromatic_rows(strip[:, cols], sat[:, cols],
                                                            v_ref, max(v_ref, v_w))
                    else:
                        achrom_cols = None
                if achrom_cols is None or not achrom_cols[run:j + 1].all():
                    break
                if frac[j] >= 0.45:
                    run = j + 1     # white again after the numerals (too short a strip for
                    #                 the running window)
        # trim rows at the bottom that are not white themselves
        while run > 0 and frac[run - 1] < 0.3:
            run -= 1
        return run

    def _own_white(self, white: np.ndarray, frac: np.ndarray, value: np.ndarray, k: int
                   ) -> tuple[np.ndarray, np.ndarray]:
        """``white`` and its row shares ``frac`` with the pixels darker than
        ``white_own_rel`` x the white part's own level removed.  The level: the median
        brightness ``value`` of the white pixels in the strip's first white rows (from the
        first row at least 45 % white to the first after it that is not, at most ``k`` + 2
        rows: the part right under the orange one).  Unchanged when no row is white."""
        rows = np.flatnonzero(frac >= 0.45)
        if rows.size == 0:
            return white, frac
        r0 = int(rows[0])
        r1 = r0 + 1
        while r1 < len(frac) and r1 - r0 < k + 2 and frac[r1] >= 0.45:
            r1 += 1
        # (row r0 is at least 45 % white: the level has pixels to be taken from)
        level = float(_median(value[r0:r1][white[r0:r1]]))
        white = white & (value >= self.config.white_own_rel * level)
        return white, white.mean(axis=1)

    def _achromatic_rows(self, strip: np.ndarray, sat: np.ndarray, v_ref: float,
                         v_bright: Optional[float] = None) -> np.ndarray:
        """Per row of an HSV ``strip`` (``sat``: its saturation as judged for white): an
        achromatic row, like a large black legend's inside the white part; background rows
        (foliage, sky) are coloured.  Judged on the row's bright pixels (a dark legend
        stroke's saturation is noise: a row of large numerals would otherwise look
        coloured): their median saturation at most ``ext_gap_s``; or a bold legend row of a
        small sign ("BEGINS"), ink nearly across: too few bright pixels to judge by, but
        black (below ``dark_rel`` of the face's brightness ``v_ref``)."""
        cfg = self.config
        bright = strip[..., 2] >= 0.5 * (v_ref if v_bright is None else v_bright)
        n = np.count_nonzero(bright, axis=1)
        # the median of each row's bright pixels' saturation (numpy's nanmedian, sorted)
        srt = np.sort(np.where(bright, sat.astype(np.int32), 256), axis=1)
        rows = np.arange(len(n))
        med_b = 0.5 * (srt[rows, np.maximum(n - 1, 0) // 2] + srt[rows, n // 2])
        return ((n >= 3) & (med_b <= cfg.ext_gap_s)) | ((n < 3) & (
            _median(strip[..., 2], axis=1) < cfg.dark_rel * v_ref))

    def _rechoose_bottom(self, bands: tuple[int, list], cand: Candidate, bottom: float,
                         entry: Optional[dict]) -> float:
        """The white part's end chosen again among :meth:`_extend`'s dark bands with the
        sign's measured top and width (``cand``): the orange blob of a dim sign is narrower
        than the sign, and with its width a bold legend row ("BEGINS") could pass for the
        bottom border.  ``bottom``: the measured bottom, kept when it gives a catalogue
        shape (within ``ext_ratio_tol``), when no band does, or when the band nearest one
        is the chosen one."""
        tol = self.config.ext_ratio_tol
        if _ratio_error(np.array([bottom - cand.y]), cand.w)[0] <= tol:
            return bottom                   # a catalogue shape as measured
        y_top, cuts = bands
        rows = y_top + np.array(cuts, float)
        err = _ratio_error(rows - cand.y, cand.w)
        k = int(np.argmin(err))
        if entry is not None:
            entry['rechosen'] = (round(bottom, 2), float(rows[k]), round(float(err[k]), 3))
        if err[k] > tol or abs(rows[k] - bottom) <= 1.5:
            return bottom
        return float(rows[k])

    def _bottom_border(self, white: np.ndarray, value: np.ndarray, orange_h: float,
                       width: float = 0.0, cuts: Optional[list] = None) -> int:
        """The row just after the white part's black bottom border (0: none seen).

        ``white``, ``value``: the white mask and brightness of the strip below the orange
        part.  A border row is dark (below ``dark_rel`` x the white sheeting's level, the
        strip's 90th percentile of brightness) across at least ``ext_border_share`` of
        the width (its outer tenth on each side left out: the strip may reach past the
        sign); a legend's strokes, however bold, leave gaps, but on a small blurred sign a
        bold legend row can look like a border too.  Of the border rows at least ``0.3``
        orange heights down, the one that makes the sign's height / ``width`` nearest a
        two-colour sign's in the catalogue (within ``ext_ratio_tol``) ends the white part,
        else the first.  The candidates: each dark band's last row and, for a band at least
        ``ext_band_long`` orange heights (and 3 rows) long, its first (the border line
        merged with a darker background below the sign).  ``cuts``, when given, receives
        those candidates (rows after the strip's top) when there are several and none
        gives a catalogue shape (the first row was taken).
        """
        cfg = self.config
        w = white.shape[1]
        if w < 4 or white.shape[0] < 2:
            return 0
        share = _dark_share(value, cfg.ext_border_rel)
        if self.debug is not None:
            self.debug.append(dict(border_share=np.round(share, 2).tolist()))
        rows = np.nonzero(share >= cfg.ext_border_share)[0]
        rows = rows[rows + 1 >= 0.3 * orange_h]
        if not rows.size:
            return 0
        if width > 0 and cfg.ext_ratio_tol > 0:
            # the row after each dark band (a border or a legend row is several rows) and,
            # for a long band (a background darker than the sheeting continuing the
            # bottom border), the row after its first
            starts, ends = _bands(rows)
            long = ends - starts + 1 >= max(3.0, cfg.ext_band_long * orange_h)
            cut = np.concatenate([ends + 1, starts[long] + 1])
            err = _ratio_error(orange_h + cut, width)
            if err.min() <= cfg.ext_ratio_tol:
                return int(cut[int(np.argmin(err))])
            if cuts is not None and cut.size > 1:
                cuts.extend(int(c) for c in cut)
        return int(rows[0] + 1)

    # -- seed 002 MSER path --
    def _mser_blobs(self, count: np.ndarray, bgr: np.ndarray, off: tuple[int, int],
                    s: int) -> list[Candidate]:
        cfg = self.config
        img = (np.minimum(count, 5) * 50).astype(np.uint8)
        # min_diversity=0: OpenCV 5.0.0 rejects every stable grey-level region otherwise
        # (opencv/opencv#29652, fixed by #29653); 0 restores the 4.x behaviour.
        mser = cv2.MSER_create(cfg.mser_delta, max(4, int(cfg.min_area_px / (s * s))),
                               max(5, int(img.size * 0.25)), 0.25, 0.0)
        # MSER finds dark-on-bright regions; the passing pixels are bright
        _, bboxes = mser.detectRegions(255 - img)
        out = []
        for x, y, w, h in (bboxes if len(bboxes) else []):
            fx, fy, fw, fh = (x + off[0]) * s, (y + off[1]) * s, w * s, h * s
            if min(fw, fh) / 2.0 < cfg.min_radius_px or max(fw, fh) / 2.0 > cfg.max_radius_px:
                continue
            fill = float(np.count_nonzero(count[y:y + h, x:x + w])) / (w * h)
            out.append(Candidate(fx, fy, fw, fh, 'orange', fill, 'unknown', fill * fw * fh))
        return out

    # -- LiDAR fusion --
    def _fuse(self, cands: list[Candidate], rois: Sequence[Roi], bgr: np.ndarray,
              thr_base: np.ndarray) -> list[Candidate]:
        """Mark LiDAR-supported blobs; add LiDAR-only detections (seed 004, as fusion).

        A colour blob whose centre lies in an (expanded) ROI gets the ROI's id, both sources
        and a noisy-OR confidence; an unsupported blob keeps its own.  An ROI that no colour
        blob explains is examined at full resolution (``_lidar_only``).
        """
        cfg = self.config
        used = set()
        for c in cands:
            best, best_score = None, 0.0
            for j, r in enumerate(rois):
                mx, my = r.box.w * cfg.roi_margin, r.box.h * cfg.roi_margin
                inside = (r.box.x - mx <= c.x + c.w / 2 <= r.box.x2 + mx
                          and r.box.y - my <= c.y + c.h / 2 <= r.box.y2 + my)
                score = max(_iou((c.x, c.y, c.w, c.h), (r.box.x, r.box.y, r.box.w,
                                                         r.box.h))[0], 0.01 if inside else 0.0)
                if score > best_score:
                    best, best_score = j, score
            if best is not None:
                used.add(best)
                c.sources = ['color', 'lidar']
                c.roi_id = int(rois[best].candidate_id)
                c.confidence = 1.0 - (1.0 - c.confidence) * (1.0 - cfg.lidar_confidence)
        if cfg.lidar_only and cfg.method == 'learned' and 'orange' in self._idx:
            for j, r in enumerate(rois):
                if j in used:
                    continue
                c = self._lidar_only(bgr, r, thr_base)
                if c is not None and all(_iou((c.x, c.y, c.w, c.h), (k.x, k.y, k.w, k.h))[1]
                                         <= cfg.nms_contain for k in cands):
                    cands.append(c)
        return cands

    def _lidar_only(self, bgr: np.ndarray, roi: Roi, thr_base: np.ndarray
                    ) -> Optional[Candidate]:
        """A detection from a LiDAR ROI whose colour evidence alone was too weak.

        Inside the ROI (full resolution) the pixels with likelihood >= ``lidar_only_threshold``
        are grouped; the largest group must span ``lidar_only_min_share`` ..
        ``lidar_only_max_share`` of the ROI's larger side (the projector sizes ROIs from the
        candidate's radius and range, so a sign is a predictable share of it: a few orange
        pixels or a whole orange ROI are not a sign) and pass the relaxed shape filters.
        The box is measured like a colour blob's; sources ``lidar`` only.
        """
        cfg = self.config
        H, W = bgr.shape[:2]
        x0, y0 = max(0, int(roi.box.x)), max(0, int(roi.box.y))
        x1, y1 = min(W, int(math.ceil(roi.box.x2))), min(H, int(math.ceil(roi.box.y2)))
        if x1 - x0 < 4 or y1 - y0 < 4:
            return None
        win = bgr[y0:y1, x0:x1]
        if self._gains is not None:
            win = apply_gains(win, self._gains)
        hsv = cv2.cvtColor(win, cv2.COLOR_BGR2HSV)
        i = self._idx['orange']
        like = _lookup(self.model.luts[i], hsv[..., 0], self._sat(hsv))
        like[hsv[..., 2] < self.model.v_min[i]] = 0.0
        mask = (cv2.blur(like, (3, 3)) >= cfg.lidar_only_threshold).astype(np.uint8)
        n, lab, st, _ = _components(mask)
        if n <= 1:
            return None
        j = 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
        bx, by, bw, bh, area = (int(v) for v in st[j])
        share = max(bw, bh) / float(max(x1 - x0, y1 - y0))
        if area < cfg.min_area_px or not (cfg.lidar_only_min_share <= share
                                          <= cfg.lidar_only_max_share):
            return None
        comp = (lab[by:by + bh, bx:bx + bw] == j).astype(np.uint8)
        c = self._measure_orange(bgr, comp, (x0 + bx, y0 + by, bw, bh), 1, thr_base, [],
                                 relaxed=True, t_override=cfg.lidar_only_threshold)
        if (c is None or _contained((c.x, c.y, c.w, c.h), (x0, y0, x1 - x0, y1 - y0))
                < cfg.roi_contain or min(c.w, c.h) < 2 * cfg.min_radius_px + 4):
            return None
        c.sources = ['lidar']
        c.roi_id = int(roi.candidate_id)
        c.confidence = cfg.lidar_only_confidence
        return c
