"""Colour sign detection: posterior mask -> blobs -> filtered, scored, extended boxes.

:class:`ColorDetector` (:mod:`.detector`) composes the stages, one module each:
:mod:`.config` (parameters), :mod:`.mask` (table, prior, threshold, hysteresis),
:mod:`.blobs` (morphology, components, filters), :mod:`.candidates` (candidates and NMS),
:mod:`.measure` (the sign measurement), :mod:`.filters` (false-positive filters),
:mod:`.warning` with :mod:`.diamond`, :mod:`.diamond_search` and :mod:`.edges` (the diamond
fit), :mod:`.rectangle` (the rectangle fit), :mod:`.plaque` (the two-colour extension),
:mod:`.recovery` (growth of a blob paler in part), :mod:`.lidar` (LiDAR fusion) and
:mod:`.baselines` (RGB-LP with MSER).  The row and band profiles the detector shares with
the tracker are in :mod:`workzone_ros.core.profiles`.

Main path (``method='learned'``, Seo et al. section III.A, Lee et al. section III.A):

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
   used, so a sign the colour model half-sees is still found (Cahail et al.'s two-layer idea,
   done as fusion), while blobs outside those ROIs never merge differently.  A blob inside
   an ROI also needs less shape evidence (``roi_relax``: looser hull-fill / solidity /
   aspect, no legend and no mounting-height test) as long as it lies mostly inside the ROI
   (``roi_contain``); outside ROIs nothing changes.
3. Erosion then dilation (opening, Cahail et al. 3.4.2) and a closing, connected components
   (``cv2.connectedComponentsWithStats``), radius filters (Seo et al. footnote 2: centroid to
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
   margin is already inside the hull does not grow.  Warning diamonds and the orange part of
   regulatory rectangles then get their edges at sub-pixel precision from the brightness
   (:func:`refine_diamond`, :func:`refine_rectangle`; ``diamond_refine``, ``rect_refine``):
   the colour table cannot place them, because a blend of the orange face and its black
   border line keeps the face's hue and saturation; the mask-based box stays the fallback
   when an edge shows no face-to-border step.  A diamond is fitted to its eight edge points
   (:func:`fit_rhombus`, outliers dropped) measured on the luma (``diamond_luma``: linear in
   a blend of two colours, as the edge model), cut back to a plausible shape (a square sign
   facing the road: ``diamond_tall_max``, ``diamond_wide_max``), and refined boxes are given
   in whole pixels,
   the pixels the measured outline covers more than half, as box labels are drawn
   (``pixel_boxes``).  The confidence
   is the mode of the blob's pixels' probabilities (eq. 2: mode of g(f(x_j))).  The seed
   takes the mode over all pixels of the box; we take it over the blob's pixels, because
   on a diamond half of the box is background and the mode would be the background's.
5. The regulatory two-colour extension (Seo et al.): a wide orange rectangle with white rows
   under it (orange top, white bottom: R22-1, R2-1 + G20-5aP) is extended down over the
   white part; the aspect ratio selects the candidates, the white rows decide how far.
6. Non-maximum suppression; unlike the seed (which keeps the largest box) every sign in the
   frame is kept.  Each detection lists its sources: ``color``, ``lidar`` or both.  A blob
   no LiDAR candidate supports keeps its own confidence (the LiDAR misses signs too); a
   supported one is raised by noisy-OR with ``lidar_confidence``; a LiDAR ROI with no
   colour blob is examined at full resolution and reported as a ``lidar``-only detection
   (``lidar_only``) when it holds a sign-coloured region of plausible size and shape.

Alternatives, selectable with ``method``:

- ``rgb_lp`` (Balali and Golparvar-Fard, "Color-based Candidate Detection"): the OR of
  linear RGB thresholds alpha R + beta G + lambda B >= t (eq. 1), the subset chosen by a Boolean
  linear program minimising FP + w FN (eq. 2, ``scipy.optimize.milp``), pixels grouped by MSER.
- ``hsv`` (Cahail et al., section 3.4.2): fixed HSV ranges, erosion then dilation, aspect-ratio
  and fill-ratio filters.
"""
from workzone_ros.core.detect.baselines import (
    RgbLpModel,
    candidate_rgb_thresholds,
    fit_rgb_lp,
    rgb_histograms,
)
from workzone_ros.core.detect.candidates import Candidate, box_metrics, dominant_color, nms
from workzone_ros.core.detect.config import METHODS, DetectorConfig
from workzone_ros.core.detect.detector import ColorDetector

__all__ = [
    'METHODS', 'DetectorConfig', 'Candidate', 'ColorDetector', 'RgbLpModel',
    'candidate_rgb_thresholds', 'fit_rgb_lp', 'rgb_histograms', 'nms', 'box_metrics',
    'dominant_color',
]
