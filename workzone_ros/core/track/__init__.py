"""Kernel-based mean-shift sign tracking (Lee et al., section III.B) and its track life.

Modules: :mod:`.config` (parameters), :mod:`.meanshift` (histograms, mean-shift and
CamShift localisation), :mod:`.appearance` (the target model and the sign-likeness gates),
:mod:`.motion` (the approach cue), :mod:`.multi` (:class:`MultiTracker`, track life),
:mod:`.confirmation` (the classifier's answers decide which tracks run on their own),
:mod:`.boxes` (box geometry).

The target is a hue-saturation histogram of ``nh x ns = 20 x 20`` bins weighted by a kernel
that multiplies the Epanechnikov profile by the detection's shape mask over normalized pixel
coordinates (Lee et al., Fig. 2 and eq. 1).  In the next frame five candidates (kernels 0, 2, 5,
7 and 10 % larger) are each moved by mean-shift (Lee et al., eq. 3, weights
``sqrt(t_u / c_u(z))``) until the shift is below a threshold or a maximum number of iterations
is reached; the candidate with the highest Bhattacharyya coefficient is the result.

Beyond the seed (``perspective_scale``): once a track has a few detections, a second set of
candidates starts at the size the Theil-Sen trend of its detected sizes predicts for a static
sign (``1 / size`` falls linearly with time) and competes with the first; near the camera a
sign grows faster per frame than the kernels span.

Everything runs on a *search window* around the track, sub-sampled on a regular pixel grid so
that a track costs the same whatever the sign's size (positions stay in full-resolution pixel
units, so the weighted means of eq. 3 are sub-pixel).  The colour conversion and the bin index
are computed once per window; a mean-shift iteration is a ``bincount`` and two dot products.

Track life (:class:`MultiTracker`): a track starts from a detection; detections are associated
to tracks by IoU, then by histogram similarity; every live track is localised by mean-shift
on every frame.  With Lee et al.'s rule (``association='overwrite'``) an associated detection
replaces the track's box.  Ours (``'fuse'``): for a confident track the detection is scored
like a mean-shift candidate with the track's model (Bhattacharyya coefficient minus the
surround term, plus ``fuse_bias``) and by its size consistency with the track's recent growth;
the tracked box is scored the same way and the two are averaged (or, disjoint, chosen) with
those weights, so a fragmentary detection box no longer overwrites a good tracked box; a
detection that agrees (anchors overlapping, weight >= 1/2) and is complete gives the box
outright (``prefer_detection``: the colour detector's boxes are now usually the better ones)
and its geometry, which a track then running on its own keeps.  When
the detector misses, the tracker runs on its own; the track ends when the similarity stays
below a threshold, the box leaves the image or grows past a size limit, and (drift guards,
not in the seed) when the target's colour continues all around the box (a large orange
vehicle) or the box grows past the perspective trend of the track's own detections.
:func:`seed_config` gives Lee et al.'s exact rule.

Regulatory two-colour boxes (orange top, white bottom; ``work_zone_begin``,
``work_zone_speed_limit``): white has no usable hue and almost no saturation, so in a
hue-saturation histogram it is indistinguishable from grey road, sky or concrete; a model
built on the whole box mostly describes "achromatic" and slides over background.  The seed
tracked the orange top and grew the box heuristically by an aspect ratio, which over-cropped.
Here every track is anchored on the coloured part of the detection (the convex hull of the
dominant-hue pixels: the shape mask), and the *measured* geometry of the detection box
relative to that anchor (offset and size ratios, refreshed by each agreeing detection) maps
the tracked anchor back to the full box.  For a diamond the anchor is the orange face inside
the black border and the relation is close to identity; for a two-colour box it is the orange
band and the relation restores the white part exactly as the detector saw it, scaled with the
tracked anchor.  The guard acts only on a detection that is not already extended (its box
does not reach well below the coloured part): the colour detector now extends regulatory
boxes itself, and its extension is kept; and only when the box is also short for the sign
(height / width well below the track's box, ``truncated_aspect``): in dim light the
dominant hue often covers the whole face, a complete detection then has no box below its
anchor either and must not be extended.  A complete detection's box is never replaced
(``prefer_detection``); the relation matters while the track runs on its own, and it is
always the last detection's own.  ``anchor_on_color=False`` tracks the whole box
instead (the ablation).  A track is published on its own only when its target does not look
like its surroundings nor has white bands (drums, cones): ``max_coast_*``; and (sign-likeness)
its face is more saturated and more colourful (chroma) than its surroundings
(``min_saturation_contrast``, ``min_chroma_contrast``); and (motion cue) its own history
shows the camera approaching it (``min_approach_speed``): a static sign grows and moves away
from the focus of expansion as it is approached (``1 / size`` falls by ``v / (f S)`` per
second, whatever its distance), a vehicle driving ahead at the ego speed keeps its size and
place, whatever its colour (the rear of an orange truck at dusk).  A track
whose anchor lies inside another track's box (an orange-top track next to the whole sign)
is a duplicate and the one with fewer hits ends (``duplicate_containment``).

A CamShift peer (``method='camshift'``: ``cv2.CamShift`` on a hue back-projection of the same
search window, same anchors and starts, same track life) is provided for comparison.
"""
from workzone_ros.core.track.appearance import (
    TargetModel,
    build_target,
    chroma_contrast,
    saturation_contrast,
    shape_mask,
)
from workzone_ros.core.track.config import (
    ASSOCIATIONS,
    METHODS,
    MODES,
    OUR_SCALES,
    SCALES,
    TrackerConfig,
    TrackingError,
    seed_config,
)
from workzone_ros.core.track.meanshift import (
    SearchWindow,
    bhattacharyya,
    camshift_localise,
    meanshift_localise,
    score_box,
)
from workzone_ros.core.track.motion import approach_rate, predicted_size
from workzone_ros.core.track.multi import MultiTracker, box_iou

__all__ = [
    'TrackerConfig', 'TrackingError', 'TargetModel', 'SearchWindow', 'MultiTracker',
    'MODES', 'METHODS', 'ASSOCIATIONS', 'SCALES', 'OUR_SCALES', 'seed_config', 'bhattacharyya',
    'shape_mask', 'build_target', 'meanshift_localise', 'camshift_localise', 'score_box',
    'box_iou', 'saturation_contrast', 'chroma_contrast', 'approach_rate', 'predicted_size',
]
