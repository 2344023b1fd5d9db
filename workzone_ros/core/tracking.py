"""Kernel-based mean-shift sign tracking (seed 001, section III.B) and its track life.

The target is a hue-saturation histogram of ``nh x ns = 20 x 20`` bins weighted by a kernel
that multiplies the Epanechnikov profile by the detection's shape mask over normalized pixel
coordinates (seed 001, Fig. 2 and eq. 1).  In the next frame five candidates (kernels 0, 2, 5,
7 and 10 % larger) are each moved by mean-shift (seed 001, eq. 3, weights
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
on every frame.  With seed 001's rule (``association='overwrite'``) an associated detection
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
:func:`seed_config` gives seed 001's exact rule.

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
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field, replace
from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core.detection import banded_rows, open_background_rows, row_taper, white_cap
from workzone_ros.interfaces import Box, Detection, Track

__all__ = [
    'TrackerConfig', 'TrackingError', 'TargetModel', 'SearchWindow', 'MultiTracker',
    'MODES', 'METHODS', 'ASSOCIATIONS', 'SCALES', 'OUR_SCALES', 'seed_config', 'bhattacharyya',
    'shape_mask', 'build_target', 'meanshift_localise', 'camshift_localise', 'score_box',
    'box_iou', 'saturation_contrast', 'chroma_contrast', 'approach_rate', 'cone_like',
]

MODES = ('detection_only', 'detection_and_tracking')
METHODS = ('meanshift', 'camshift')
#: How an associated detection updates a confident track: ``fuse`` (ours) weighs the tracked
#: and the detected box by their agreement with the target model and the track's scale;
#: ``overwrite`` (seed 001) replaces the track's box by the detection's.
ASSOCIATIONS = ('fuse', 'overwrite')
#: Kernel sizes of the candidates relative to the previous box (seed 001, III.B).
SCALES = (1.0, 1.02, 1.05, 1.07, 1.10)
#: Ours: around the previous size, shrinking allowed.  With only-larger kernels a box can
#: never shrink, so scale noise ratchets it up whenever a detection does not reset it (on
#: development bags the tracked box ran 11-17 % wider than the sign; 1-2 % with these).
OUR_SCALES = (0.97, 1.0, 1.03)
#: Clock of the per-track timing (``last_localise_s``); the bench may use CPU time instead.
_clock = time.perf_counter
_MASK_GRID = 32          # resolution of the shape mask over normalized coordinates [-1, 1]^2


class TrackingError(ValueError):
    """An invalid tracker configuration or input (wrong image type, bad mode, ...)."""


@dataclass(frozen=True)
class TrackerConfig:
    """Tracker parameters (the node's ``tracker`` section maps onto these one to one).

    Attributes:
        mode: ``detection_only`` (seed 001's baseline) or ``detection_and_tracking``.
        method: ``meanshift`` (seed 001) or ``camshift`` (OpenCV peer).
        hue_bins: nh (seed: 20).
        sat_bins: ns (seed: 20).
        scales: candidate kernel sizes relative to the previous box (seed: 0/2/5/7/10 %,
            :data:`SCALES`; ours :data:`OUR_SCALES`).
        max_iterations: mean-shift iterations per candidate.
        shift_threshold_px: stop iterating when the centre moves less than this.
        max_samples: pixels sampled inside a box (the grid stride grows with the box).
        search_margin: search window half-size beyond the largest candidate, in half-boxes.
        use_velocity: start mean-shift from the constant-velocity prediction (not in the seed).
        min_similarity: Bhattacharyya coefficient below which the track is lost.
        max_lost_frames: consecutive frames below ``min_similarity`` before the track ends.
        max_coast_frames: frames without an agreeing detection before the track ends.
        min_hits_to_coast: detections a track needs before it may run on its own (ours 1:
            with the sign-likeness gate ``min_saturation_contrast`` a single detection is
            enough; 2 on the tuning bags left most dusk misses uncovered; seed rule 2).
        min_hits_to_fuse: detections a track needs before its tracked box may outvote a
            detection (``fuse``); before, every associated detection overwrites it.
        max_background_similarity: a target whose model resembles its surroundings more than
            this is not trackable (a featureless region): it never runs on its own.
        iou_gate: IoU at which a detection belongs to a track (it starts no new track).
        agree_iou: IoU with the tracked box at which the detection corrects the track; a
            detection that belongs to the track but overlaps it less (a fragment of the
            sign, a box that lost the white part) does not replace a confidently tracked
            box (similarity >= ``min_similarity``).  0 (default) disables this: on held-out
            paper_c it covered more detector misses (12 vs 6 of 39) but lost regulatory
            boxes and added false tracks on drums, so it stays an option.
        similarity_gate: histogram similarity at which an overlapping detection agrees.
        model_update: weight of a correcting detection's histogram in the model (1 = replace).
        max_box_fraction: end the track when the box is wider/taller than this image fraction.
        min_inside_fraction: end the track when less of the box than this is in the image.
        min_box_px: ignore detections smaller than this (either side).
        anchor_on_color: track the coloured part and keep the box geometry (two-colour guard).
        duplicate_iou: two tracks overlapping more than this: the one with fewer hits ends.
        duplicate_containment: two tracks are also duplicates when at least this share of
            the smaller one's coloured anchor lies inside the larger one's box (the orange
            top of a two-colour sign tracked next to the whole sign; 1 = off, seed rule).
        duplicate_area_ratio: ... unless the larger box is more than this many times larger
            (a detection merging a sign with a tinted sky does not swallow the sign's track).
        background_weighting: scale the mean-shift weights of bins that are common in the
            target's surroundings down (corrected background-weighted histogram, Ning et al.
            2012; not in seed 001, whose plain ``sqrt(t_u / c_u)`` weights give every bin
            present in the target, including its background fringe, the same pull).
        surround_weight: candidate score = ``B(t, c) - surround_weight * B(t, ring)`` where
            ring is the band outside the candidate's shape up to ``surround_size`` times its
            box: a too-small candidate leaves sign colour in its ring (0 = seed 001: the
            best Bhattacharyya coefficient alone, which prefers the smallest kernel).
        surround_size: outer size of that band relative to the candidate box.
        association: ``fuse`` or ``overwrite`` (seed 001), see :data:`ASSOCIATIONS`.  With
            ``fuse``, a detection associated with a confident track (``min_hits_to_fuse``
            hits, tracked similarity >= ``min_similarity``) is scored like a mean-shift
            candidate with the track's model at the detection's anchor (Bhattacharyya
            coefficient minus ``surround_weight`` times the ring's); the tracked box is
            scored the same way.  Each gets the weight ``exp(score / fuse_temperature)``
            times a size-consistency factor ``exp(-d^2 / (2 size_sigma^2))`` where d is the
            log-size difference from the track's predicted size (previous size times its
            recent per-frame growth).  Boxes overlapping by ``fuse_iou`` or more are
            averaged with these weights, otherwise the heavier one wins; the model and the
            box geometry are refreshed in proportion to the detection's weight.
        fuse_temperature: score scale of the fusion weights.
        size_sigma: log-size tolerance of the size-consistency factor.
        size_history: with ``fuse``, the size-consistency factor also accepts the size the
            last ``size_history`` detected anchor sizes predict (besides the track's last
            size times its growth; the closer of the two counts): a static sign's inverse
            size falls linearly with time, so ``1 / size`` is fitted robustly (Theil-Sen:
            median slope, median intercept) and extrapolated to the current frame.  A track
            that took a too-wide box then still accepts the next correct detection.  Needs
            three detections; 0 = the last size alone (as before).
        fuse_iou: anchor IoU at which the two boxes are averaged rather than chosen.
        fuse_bias: added to the detection's score: on development bags the colour score
            alone predicted poorly which box was better (correlation 0.1 with the IoU
            difference; the tracked box is the score's own optimum, the detection is not).
        fuse_min_px: tracks smaller than this (either side) are overwritten, not fused.
        prefer_detection: with ``fuse``, a detection whose anchor overlaps the tracked anchor
            (``fuse_iou``) gives the box outright unless it is truncated (the two-colour
            guard fires): the colour detector's boxes (it extends regulatory boxes itself)
            are better than the tracked box, and blending made them worse than detection
            only on development bags.  The weights still decide between disjoint boxes and
            how much of the detection's histogram enters the model; the box geometry
            (``relation``) is the detection's own, so a track that then runs on its own
            keeps the geometry of its last good detection.  False: PR 6a5d439's blend.
        truncated_aspect: two-colour guard: a detection whose box ends above the part the
            track knows is extended by the track's geometry only when its height / width is
            also below this times that of the track's box (0 = off: the previous rule, which
            the seed rule keeps).  The coloured anchor alone does not tell a truncated box
            from a complete one: in dim light the dominant hue covers the whole face, so a
            complete detection has no box below its anchor either; on tuning paper_c 1111
            the previous rule tripled such boxes (two-colour match 0.38 vs 0.58 detection
            only; 0.62 with this check).
        anchor_kind_ratio: two-colour guard: a detection is extended only when its coloured
            anchor is the same part of the sign as the track's, i.e. its height / width is at
            most this times that of the track's anchor (0 = off, seed rule).  The anchor of
            one sign switches between the orange band and the whole face (the hull of the
            dominant hue covers the white part in some frames): extending a whole-face
            anchor by the band's relation made the box three times too tall and, the
            relation being kept, locked the track there (tuning paper_c 1121: match 0.47 vs
            0.91 detection only; 0.89 with this check, no other tuning bag changed).
        max_coast_background_similarity: a track whose model resembles its surroundings
            more than this is published only with a detection, never on its own (on
            development bags every track that ran on its own on a sign stayed below 0.47;
            false tracks on vehicles and background reached 0.6-0.86).  1 = off.
        max_coast_white_fraction: with ``anchor_on_color``, a track whose coloured shape is
            more than this white (a drum's or cone's bands) never runs on its own (signs on
            development bags: at most 0.25).  1 = off.
        white_bottom_share: ... unless at least this share of that white lies below the
            lowest row where the colour dominates (``TargetModel.white_below``): a regulatory
            face whose coloured shape covers its white bottom (dusk tuning bags: white
            fraction 0.48, sign lost while the detector missed it), not a drum's or cone's
            alternating bands (> 1 = off).
        min_saturation_contrast: sign-likeness gate (not in the seed): a track is published
            on its own only when the upper decile of its anchor's saturation exceeds that
            of its surroundings (their ``saturation_reference`` percentile) by this
            (saturation / 255; :func:`saturation_contrast`).
            Fluorescent sign faces stand out (tuning bags: 0.2-0.5, pale dusk signs 0.1-0.2);
            patches of a tinted dusk sky or road, which the colour detector finds, do not
            (mostly below 0.1).  -1 = off.
        saturation_reference: percentile of the surroundings' saturation the sign-likeness
            gate compares the face's upper decile with (:func:`saturation_contrast`; 90 = the
            previous rule).  The median: a sign's stand flags or a neighbouring sign in the
            surroundings and sunlit vegetation clipped at full saturation set their upper
            decile, and sunlit signs then failed the gate (sunny tuning paper_c 2100: 3 of 31
            detector misses covered, 21 with the median and ``min_chroma_contrast``).
        min_chroma_contrast: sign-likeness gate (not in the seed): a track is published on
            its own only when the upper decile of its anchor's chroma (``S * V``) is at least
            this many times that of its surroundings (:func:`chroma_contrast`; 0 = off).
            Sign faces on the tuning bags: 1.7 or more in every weather (5 % quantile);
            a tinted dusk sky as saturated as the face passes the median rule alone.
        chroma_reference: percentile of the surroundings' chroma the chroma gate compares
            the face's upper decile with (:func:`chroma_contrast`; 90 = the previous rule).
            The median, as for saturation: the surroundings' upper decile is set by the
            few most colourful things around a sign (sunlit vegetation, its stand's
            flags, an orange-brown facade beside it), and 12 detector misses on the
            tuning bags (a sunny sign on vivid green, a rain sign next to a brown facade)
            were blocked at ratios 1.1-1.4 with it.  A dim saturated patch in bright
            surroundings still fails (1.1 against the median).
        min_hits_after_loss: a track that lost its target since its last detection
            (similarity below ``min_similarity``) and found a match again is published on
            its own again only when it has at least this many detections (1 = the previous
            rule, the seed's).  A track started by a single detection that loses its lock
            and regains it without a detection is often on something else of the target's
            colour (rain tuning random 2107: a yellow vehicle's side, 9 false tracking
            frames); it keeps running (a detection may still associate with it) but is
            published only once a detection confirms it.  A sign detected more often is
            published again after an occlusion.
        max_ring_similarity: drift guard: a track running on its own whose surroundings
            (the ``surround_size`` ring) look like its target more than this sits in a
            region much larger than its box (an orange vehicle): it is lost (1 = off).
        ring_margin: with ``ring_margin`` >= 0 the drift guard also needs the ring to exceed
            the ring the track's model had at its last detection by this margin: a sign
            that stands among sign-coloured things (its stand's flags, a second sign) has a
            high ring while it is detected too and keeps it, a track drifting into an orange
            vehicle's region gains one (< 0 = off: the absolute threshold alone).  Only for
            tracks with ``ring_margin_min_hits`` detections or more (a detector's false alarm
            on an orange truck has a high ring from its first detection on).
        max_growth_excess: drift guard: a track running on its own whose anchor grew more
            than this fraction beyond the growth its detections showed (perspective: the
            inverse size of a static sign falls linearly with time) ends (0 = off).
        growth_guard_needs_trend: the growth guard acts only once two detections measured
            the trend (the first measurement is taken as it is, not averaged with 0); a track
            started by one detection would otherwise count its real perspective growth as
            drift and end after a few frames (False: the previous rule).
        min_approach_speed: motion cue (not in the seed): a track is published on its own
            only when its own history (anchor centre and size on its detected and tracked
            frames, :func:`approach_rate`) shows the camera approaching it at least this
            fast (m/s).  A static object of size ``S`` approached at speed ``v`` has
            ``size = f S / Z``, so ``1 / size`` falls by ``v / (f S)`` per second whatever
            its distance; the fall is also measured from its offset from the focus of
            expansion, which scales like its size.  The per-frame threshold is
            ``min_approach_speed / (f sign_size_m fps)`` with ``f`` from the image width and
            ``camera_hfov_deg`` and ``fps`` from the frames' stamps (``frame_rate`` without
            them), so the cue means the same on any camera and frame rate.  A vehicle
            driving ahead at the ego speed keeps its image size and place (about 0): colour
            cannot tell the rear of an orange truck at dusk from a dusk sign (chroma ratio
            1.59-1.79 vs 1.55-2.05), its motion can.  10 m/s with the simulator's camera
            (f 554 px, 15 fps) is 0.001 / px per frame (signs on the tuning bags, at 20-27
            m/s: 0.0017-0.004; the truck ahead on dusk tuning random 2100: -0.0006-0.0004,
            up to 0.0012 on a track's first frames).  A sign approached slower than that
            (ego stopped or crawling) is not published on its own either.  Histories
            shorter than ``motion_min_frames`` are not judged (published).  0 = off (seed
            rule).
        sign_size_m: the nominal sign face size ``S`` of the motion cue (48-in diamond).
        camera_hfov_deg: horizontal field of view for the cue's focal length (the
            simulator's camera: 60 deg, f 554 px at 640 px).
        frame_rate: frames per second assumed when :meth:`MultiTracker.step` gets no stamps.
        motion_window: frames of history the motion cue fits (Theil-Sen; 15 = 1 s).
        motion_min_frames: the motion cue judges a track only when its history in the
            window spans at least this many frames.
        focus_of_expansion: the image point straight ahead, as fractions of the image width
            and height (the simulator's camera looks level: its centre).
        radial_min_offset: the offset estimate counts only when the target's offset from the
            focus of expansion is at least this many sizes (closer to it, an error of the
            focus or a yaw of the camera dominates the estimate; the size estimate is free
            of both).
        approach_from_detections: the motion cue also reads the Theil-Sen trend of the
            track's detected sizes (``size_history``; size estimate of
            :func:`approach_rate` over them) and takes the larger of the two rates.  The
            tracked history alone under-reads a sign whose box started too wide and then
            grew too slowly (dusk tuning curve_dusk 3509: 5 detector misses blocked at
            0.0009-0.00097 while the detections said 0.0015; with the rule the cue costs
            no covered frame on the 16 tuning bags).  A vehicle ahead keeps its detected
            size too (about 0).  False: the tracked history alone.
        perspective_scale: mean-shift also runs a second set of candidates (the same
            ``scales``) around the anchor size that a static sign has now by the Theil-Sen
            trend of the track's detected sizes (:func:`predicted_size`: ``1 / size`` falls
            linearly with time), and the better-scoring set wins (same score: Bhattacharyya
            coefficient minus the surround term).  Not in the seed: near the camera a sign
            grows by more per frame than the kernels span (5-9 % at 40-80 px on the tuning
            bags vs 3 %), so the tracked box fell behind the sign, slid onto a part of it or
            onto its stand's flags and stopped matching (tuning random 3506: 2 -> 10 of 15
            detector misses covered).  The second set competes rather than replaces, so a
            wrong trend (a detector's biased box sizes) costs little.  False = seed rule.
        perspective_min, perspective_max: the predicted over the current anchor size is
            clipped to this range (a set within the ``scales`` span is not run twice).
        perspective_min_detections: detections (distinct frames) the trend needs; it is
            also extrapolated no further past the last detection than the detections span
            (anchor sizes are quantised by the sampling grid: three detections one frame
            apart predicted a 2 %/frame sign 80 % too tall 13 frames later).  The
            detected sizes are those kept for ``size_history`` (0: no trend, rule off).
        perspective_max_background: ... and only for targets whose background similarity
            is at most this (a target like its surroundings, a dusk sign on orange-brown
            ground, makes a bigger box cost the score little: the set grew the box past the
            sign, dusk tuning curve_dusk 3509 19 -> 14 covered; 1 = always).
        cone_test: a track running on its own is published only when :func:`cone_like`
            finds no drum or cone around its anchor (not in the seed): the colour
            detector's intermittent false detections of a cone's body (often the orange
            part right below its white band, which lies outside the box, so the white gate
            inside the shape does not see it) coasted on real dashcam clips (charlotte /
            denver sign-free ranges: 0.37 / 1.48 tracking-only outputs per frame, 0.25 /
            0.56 with the test).  Off by default (opt-in for camera-only use among cones):
            it also fires on signs, e.g. a diamond over its grey post with dry tan grass
            below (tuning random 3613: 7 -> 5 detector misses covered; fresh held-out bags
            144 -> 128 of 209).
        cone_min_px: ... for anchors at least this high (a band of a couple of rows and
            the taper of a small blob are noise: a 10 px diamond in front of pale sky
            passed the cap test).
        cone_strip: the test's strip over the box's columns (share of its width) around
            the box's centre and around its orange pixels' median column (a cone's band
            above its body is narrower than the body).
        cone_sat_rel, cone_hue_tolerance, cone_min_saturation: orange is within
            ``cone_hue_tolerance`` of the face's (saturation-weighted) hue mode and at
            least ``max(cone_min_saturation, cone_sat_rel x`` the face's median
            saturation) (pale or brownish ground of a similar hue is not the object's).
        cone_white_s_max, cone_white_luma: white is at most ``cone_white_s_max``
            saturated and at least ``cone_white_luma`` times as bright (luma) as the
            orange face (the detector's ``white_s_max``, ``band_white_luma``).
        cone_band_rows: a band holds at least this times the anchor's height of rows at
            least half white (the detector's ``band_min_rows`` is 0.12 of its blob; a
            tracked box also holds a cone's base and blur).
        cone_taper: the white cap counts over an anchor taller than wide whose
            :func:`~workzone_ros.core.detection.row_taper` is at most this.
        cone_dark_rel: a row at least 90 % darker than this times the face's value ends
            the search (a regulatory sign's white bottom ends at its black border line).
        cone_sticky: a track judged a cone stays so (not published on its own) until its
            next detection (the test flickers with the band's blur; real clips 0.29 / 0.71
            without).
    """

    mode: str = 'detection_and_tracking'
    method: str = 'meanshift'
    hue_bins: int = 20
    sat_bins: int = 20
    scales: tuple[float, ...] = OUR_SCALES
    max_iterations: int = 10
    shift_threshold_px: float = 0.3
    max_samples: int = 900
    search_margin: float = 0.6
    use_velocity: bool = True
    min_similarity: float = 0.75
    max_lost_frames: int = 2
    max_coast_frames: int = 45
    min_hits_to_coast: int = 1
    min_hits_to_fuse: int = 2
    max_background_similarity: float = 0.9
    iou_gate: float = 0.3
    agree_iou: float = 0.0
    similarity_gate: float = 0.8
    model_update: float = 0.7
    max_box_fraction: float = 0.5
    min_inside_fraction: float = 0.6
    min_box_px: int = 6
    anchor_on_color: bool = True
    duplicate_iou: float = 0.6
    duplicate_containment: float = 0.5
    duplicate_area_ratio: float = 4.0
    background_weighting: bool = True
    surround_weight: float = 0.5
    surround_size: float = 1.2
    association: str = 'fuse'
    fuse_temperature: float = 0.05
    size_sigma: float = 0.15
    fuse_iou: float = 0.3
    fuse_bias: float = 0.1
    fuse_min_px: float = 0.0
    prefer_detection: bool = True
    truncated_aspect: float = 0.7
    max_coast_background_similarity: float = 0.8
    max_coast_white_fraction: float = 0.35
    white_bottom_share: float = 0.9
    min_saturation_contrast: float = 0.2
    saturation_reference: float = 50.0
    min_chroma_contrast: float = 1.5
    chroma_reference: float = 50.0
    anchor_kind_ratio: float = 1.5
    growth_guard_needs_trend: bool = True
    max_ring_similarity: float = 0.6
    ring_margin: float = 0.1
    ring_margin_min_hits: int = 3
    max_growth_excess: float = 0.3
    size_history: int = 8
    min_hits_after_loss: int = 2
    min_approach_speed: float = 10.0
    sign_size_m: float = 1.2
    camera_hfov_deg: float = 60.0
    frame_rate: float = 15.0
    motion_window: int = 15
    motion_min_frames: int = 8
    focus_of_expansion: tuple[float, float] = (0.5, 0.5)
    radial_min_offset: float = 1.5
    approach_from_detections: bool = True
    perspective_scale: bool = True
    perspective_min: float = 0.9
    perspective_max: float = 1.3
    perspective_min_detections: int = 3
    perspective_max_background: float = 0.5
    cone_test: bool = False
    cone_min_px: int = 16
    cone_strip: float = 0.33
    cone_sat_rel: float = 0.5
    cone_sticky: bool = True
    cone_hue_tolerance: int = 12
    cone_min_saturation: int = 70
    cone_white_s_max: int = 45
    cone_white_luma: float = 1.25
    cone_band_rows: float = 0.08
    cone_taper: float = 0.88
    cone_dark_rel: float = 0.6

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise TrackingError(f'mode {self.mode!r} is not one of {MODES}')
        if self.method not in METHODS:
            raise TrackingError(f'method {self.method!r} is not one of {METHODS}')
        if self.association not in ASSOCIATIONS:
            raise TrackingError(f'association {self.association!r} is not one of '
                                f'{ASSOCIATIONS}')
        if self.fuse_temperature <= 0 or self.size_sigma <= 0:
            raise TrackingError('fuse_temperature and size_sigma must be positive')
        if self.hue_bins < 1 or self.sat_bins < 1:
            raise TrackingError('hue_bins and sat_bins must be positive')
        if not self.scales or min(self.scales) <= 0:
            raise TrackingError(f'scales must be positive, got {self.scales!r}')
        if self.max_samples < 16:
            raise TrackingError('max_samples must be at least 16')
        if self.min_approach_speed < 0 or self.sign_size_m <= 0 or self.frame_rate <= 0 \
                or not 1.0 <= self.camera_hfov_deg <= 179.0:
            raise TrackingError('min_approach_speed must be >= 0, sign_size_m and frame_rate '
                                '> 0, camera_hfov_deg in [1, 179]')
        if self.motion_window < 2 or self.motion_min_frames < 2:
            raise TrackingError('motion_window and motion_min_frames must be at least 2')
        if len(self.focus_of_expansion) != 2:
            raise TrackingError('focus_of_expansion must be (x, y) image fractions')


def seed_config(config: Optional['TrackerConfig'] = None) -> 'TrackerConfig':
    """Seed 001's exact rule on top of ``config``: plain ``sqrt(t_u / c_u)`` weights (eq. 3),
    the best Bhattacharyya coefficient alone picks the kernel size, mean-shift starts at
    the previous centre, an associated detection overwrites the track and no drift guards,
    publication gates or containment duplicates (``min_hits_to_coast`` = 2, as before).
    The regulatory two-colour guard stays (``anchor_on_color``) as it was committed
    (``truncated_aspect=0``), so the baseline does not change."""
    return replace(config or TrackerConfig(), scales=SCALES, background_weighting=False,
                   surround_weight=0.0,
                   use_velocity=False, association='overwrite', max_ring_similarity=1.0,
                   max_growth_excess=0.0, max_coast_background_similarity=1.0,
                   max_coast_white_fraction=1.0, min_saturation_contrast=-1.0,
                   min_chroma_contrast=0.0,
                   truncated_aspect=0.0, anchor_kind_ratio=0.0,
                   min_hits_to_coast=2, min_hits_to_fuse=2, duplicate_containment=1.0,
                   ring_margin=-1.0, size_history=0, min_hits_after_loss=1,
                   min_approach_speed=0.0, perspective_scale=False, cone_test=False)


# --- histograms ---------------------------------------------------------------------------

def _luts(nh: int, ns: int) -> np.ndarray:
    """(1, 256, 3) uint8 look-up table: hue -> hue bin, saturation -> saturation bin."""
    if nh > 256 or ns > 256:
        raise TrackingError('at most 256 hue and saturation bins')
    v = np.arange(256)
    lut = np.zeros((1, 256, 3), np.uint8)
    lut[0, :, 0] = np.minimum(v, 179) * nh // 180        # OpenCV 8-bit hue is 0..179
    lut[0, :, 1] = v * ns // 256
    return lut


def bhattacharyya(p: np.ndarray, q: np.ndarray) -> float:
    """Bhattacharyya coefficient of two normalized histograms (seed 001, B(t, c))."""
    return float(np.sqrt(p * q).sum())


def box_iou(a: Sequence[float], b: Sequence[float]) -> float:
    """IoU of two ``(x, y, w, h)`` boxes (0 when either is empty)."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    inter = iw * ih
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


class SearchWindow:
    """A sub-sampled HSV view of a frame region and its hue-saturation bin index.

    Attributes:
        x0, y0: full-resolution pixel of grid sample (0, 0).
        stride: grid spacing in pixels.
        xs, ys: full-resolution coordinates of the grid columns / rows (float64).
        hsv: (ny, nx, 3) uint8 HSV samples.
        bins: (ny, nx) intp hue-saturation bin of each sample.
    """

    __slots__ = ('x0', 'y0', 'stride', 'xs', 'ys', 'hsv', 'bins', 'nx', 'ny')

    def __init__(self, frame: np.ndarray, x0: int, y0: int, x1: int, y1: int, stride: int,
                 luts: np.ndarray) -> None:
        h, w = frame.shape[:2]
        x0, y0 = max(0, int(x0)), max(0, int(y0))
        x1, y1 = min(w, int(x1)), min(h, int(y1))
        self.x0, self.y0, self.stride = x0, y0, int(stride)
        if x1 <= x0 or y1 <= y0:
            self.hsv = np.zeros((0, 0, 3), np.uint8)
        else:
            sub = np.ascontiguousarray(frame[y0:y1:self.stride, x0:x1:self.stride])
            self.hsv = cv2.cvtColor(sub, cv2.COLOR_BGR2HSV)
        self.ny, self.nx = self.hsv.shape[:2]
        # Pixel centres in continuous image coordinates (pixel j covers [j, j + 1)).
        self.xs = x0 + 0.5 + self.stride * np.arange(self.nx, dtype=np.float64)
        self.ys = y0 + 0.5 + self.stride * np.arange(self.ny, dtype=np.float64)
        if self.hsv.size:
            hb, sb, _ = cv2.split(cv2.LUT(self.hsv, luts))
            ns = int(luts[0, 255, 1]) + 1
            self.bins = cv2.addWeighted(hb, ns, sb, 1, 0, dtype=cv2.CV_16U)
        else:
            self.bins = np.zeros((0, 0), np.uint16)

    def span(self, zx: float, zy: float, ax: float, ay: float) -> tuple[int, int, int, int]:
        """Grid index ranges ``(kx0, kx1, ky0, ky1)`` of the box centred at z, half-size a."""
        s = self.stride
        kx0 = max(0, math.ceil((zx - ax - self.x0 - 0.5) / s))
        kx1 = min(self.nx, math.floor((zx + ax - self.x0 - 0.5) / s) + 1)
        ky0 = max(0, math.ceil((zy - ay - self.y0 - 0.5) / s))
        ky1 = min(self.ny, math.floor((zy + ay - self.y0 - 0.5) / s) + 1)
        return kx0, kx1, ky0, ky1


def _stride(ax: float, ay: float, max_samples: int) -> int:
    """Grid spacing so that a box of half-size (ax, ay) holds at most ``max_samples``."""
    return max(1, math.ceil(math.sqrt(4.0 * ax * ay / max_samples)))


def _kernel(win: SearchWindow, mask: np.ndarray, zx: float, zy: float, ax: float,
            ay: float):
    """Kernel of eq. 1 at centre z: Epanechnikov profile times the shape mask.

    Returns:
        ``(bins, k, xs, ys)`` of the samples inside the box, or None when it holds fewer than
        four samples.
    """
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return None
    xs, ys = win.xs[kx0:kx1], win.ys[ky0:ky1]
    px = (xs - zx) / ax
    py = (ys - zy) / ay
    g = mask.shape[0]
    ix = np.minimum(((px + 1.0) * (g / 2)).astype(np.intp), g - 1)   # px is in [-1, 1]
    iy = np.minimum(((py + 1.0) * (g / 2)).astype(np.intp), g - 1)
    k = (1.0 - py * py)[:, None] - (px * px)[None, :]       # Epanechnikov profile 1 - |p|^2
    np.maximum(k, 0.0, out=k)
    k *= mask.take(iy, axis=0).take(ix, axis=1)
    return win.bins[ky0:ky1, kx0:kx1], k, xs, ys


def _surround(win: SearchWindow, mask: np.ndarray, zx: float, zy: float, ax: float,
              ay: float, size: float, nb: int) -> Optional[np.ndarray]:
    """Normalized histogram of the samples outside the candidate's shape, inside ``size``
    times its box (uniform weights)."""
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax * size, ay * size)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return None
    px = (win.xs[kx0:kx1] - zx) / ax
    py = (win.ys[ky0:ky1] - zy) / ay
    g = mask.shape[0]
    inx = np.abs(px) < 1.0
    iny = np.abs(py) < 1.0
    ix = np.minimum(np.maximum(((px + 1.0) * (g / 2)).astype(np.intp), 0), g - 1)
    iy = np.minimum(np.maximum(((py + 1.0) * (g / 2)).astype(np.intp), 0), g - 1)
    shape = mask.take(iy, axis=0).take(ix, axis=1) > 0
    shape &= iny[:, None]
    shape &= inx[None, :]
    ring = win.bins[ky0:ky1, kx0:kx1][~shape]
    if ring.size < 4:
        return None
    h = np.bincount(ring, minlength=nb).astype(np.float64)
    return h / ring.size


def _histogram(bins: np.ndarray, k: np.ndarray, nb: int) -> Optional[np.ndarray]:
    p = np.bincount(bins.ravel(), k.ravel(), nb)
    total = p.sum()
    if total <= 0:
        return None
    return p / total


def saturation_contrast(win: SearchWindow, zx: float, zy: float, ax: float,
                        ay: float, reference: float = 90.0) -> float:
    """Sign-likeness of the box centred at z, half-size a: the upper decile of its
    saturation minus the ``reference`` percentile of that of the rest of the window, in
    [-1, 1].

    Work-zone sign faces are fluorescent orange: more saturated than what surrounds them,
    whatever the light (upper decile, so a legend or a white part does not matter).  Patches
    of a tinted sky, road or vegetation (dusk) are as saturated as their surroundings; the
    inside of a large orange vehicle is as saturated as the rest of the vehicle.  The
    tracker compares with the surroundings' median (``TrackerConfig.saturation_reference``):
    their upper decile is set by the few most saturated things around a sign (its stand's
    orange flags, a neighbouring sign, sunlit or shaded vegetation, which reaches the
    255 that a sunlit face is clipped at), so it fell to 0-0.1 for most sunlit signs
    (sunny tuning paper_c 2100: 3 of 31 detector misses covered).

    Returns:
        The contrast, or 0 when the box or the rest of the window holds fewer than four
        samples.
    """
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return 0.0
    sat = win.hsv[..., 1]
    inside = np.zeros(sat.shape, bool)
    inside[ky0:ky1, kx0:kx1] = True
    out = sat[~inside]
    if out.size < 4:
        return 0.0
    s_in = np.percentile(sat[ky0:ky1, kx0:kx1], 90)
    return float(s_in - np.percentile(out, reference)) / 255.0


def chroma_contrast(win: SearchWindow, zx: float, zy: float, ax: float, ay: float,
                    reference: float = 90.0) -> float:
    """Sign-likeness of the box centred at z, half-size a: the upper decile of its chroma
    over the ``reference`` percentile of that of the rest of the window (a ratio; the
    tracker uses the median, ``TrackerConfig.chroma_reference``).

    Chroma is ``S * V / 255`` (HSV; the spread ``max - min`` of the RGB channels): how
    colourful a pixel is.  HSV saturation alone is ``(max - min) / max``, which is high on
    dark pixels whatever their colour (shaded vegetation, dark trees in sun reach the
    saturation of a fluorescent face), while their chroma stays low.  A ratio (not a
    difference) does not depend on the light level: rain and dusk lower the chroma of
    everything.  With :func:`saturation_contrast` against the surroundings' median, it
    keeps dim targets in bright, moderately saturated surroundings (patches of a tinted
    dusk sky, dark-orange clutter) from running on their own.

    Returns:
        The ratio, or 0 when the box or the rest of the window holds fewer than four samples.
    """
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    if kx1 - kx0 < 2 or ky1 - ky0 < 2:
        return 0.0
    hsv = win.hsv
    chroma = hsv[..., 1].astype(np.float32) * hsv[..., 2].astype(np.float32) / 255.0
    inside = np.zeros(chroma.shape, bool)
    inside[ky0:ky1, kx0:kx1] = True
    out = chroma[~inside]
    if out.size < 4:
        return 0.0
    c_in = float(np.percentile(chroma[ky0:ky1, kx0:kx1], 90))
    return c_in / max(float(np.percentile(out, reference)), 1.0)


# --- target model -------------------------------------------------------------------------

def shape_mask(hsv: np.ndarray, min_saturation: int = 70, min_value: int = 50,
               hue_tolerance: int = 12, min_fraction: float = 0.08) -> Optional[np.ndarray]:
    """Shape mask of a detection (seed 001, Fig. 2): convex hull of its dominant-hue pixels.

    The dominant hue is the mode of the chromatic pixels near the box centre; the mask is the
    filled convex hull of the pixels within ``hue_tolerance`` of it (so a black legend and the
    inside of a border belong to the shape).

    Args:
        hsv: (h, w, 3) uint8 HSV patch of the detection box.
        min_saturation: saturation below which a pixel has no usable hue.
        min_value: value below which a pixel has no usable hue.
        hue_tolerance: half-width of the accepted hue range (OpenCV hue units, 0..179).
        min_fraction: fewer dominant-hue pixels than this fraction of the box: no mask.

    Returns:
        uint8 mask (h, w) with 1 inside the shape, or None for an achromatic/featureless box.
    """
    h, w = hsv.shape[:2]
    if h < 2 or w < 2:
        return None
    hue = hsv[..., 0].astype(np.int16)
    chroma = (hsv[..., 1] >= min_saturation) & (hsv[..., 2] >= min_value)
    yy, xx = np.ogrid[:h, :w]
    inner = (((xx - (w - 1) / 2) / (w / 2)) ** 2 + ((yy - (h - 1) / 2) / (h / 2)) ** 2) < 1.0
    sel = chroma & inner
    if sel.sum() < max(3, min_fraction * h * w):
        return None
    mode = int(np.argmax(np.bincount(hue[sel] // 6, minlength=30))) * 6 + 3
    diff = np.abs(hue - mode)
    diff = np.minimum(diff, 180 - diff)
    on = chroma & (diff <= hue_tolerance)
    if on.sum() < max(3, min_fraction * h * w):
        return None
    pts = cv2.findNonZero(on.astype(np.uint8))
    hull = cv2.convexHull(pts)
    mask = np.zeros((h, w), np.uint8)
    cv2.fillConvexPoly(mask, hull, 1)
    return mask


@dataclass
class TargetModel:
    """What a track follows: the anchor box, its shape mask and its histogram (eq. 1).

    Attributes:
        q: target histogram t_b (nh * ns, normalized).
        qw: the histogram the mean-shift weights use: ``q`` with the bins common in the
            surroundings scaled down when ``background_weighting`` is on, else ``q``.
        mask: (32, 32) float32 shape mask over normalized anchor coordinates.
        relation: the output box relative to the anchor: ``(dx, dy, rw, rh)`` with
            ``box = (ax0 + dx * aw, ay0 + dy * ah, rw * aw, rh * ah)``.
        anchor: anchor box ``(x, y, w, h)`` in the frame it was built from.
        background_similarity: Bhattacharyya coefficient of the model and its surroundings.
        colored: a shape mask was found (False: featureless or achromatic box).
        hue_hist: hue histogram for the CamShift peer (float32, 180 bins, max 255).
        dark_fraction: share of the shape that is much darker than its colour (legend,
            border): signs have one, drums, cones and orange vehicles mostly do not.
        white_fraction: share of the shape that is white (a drum's or cone's bands).
        white_below: share of that white below the lowest row where the colour dominates
            (a regulatory sign's white bottom: near 1; a drum's or cone's bands: low).
        saturation_contrast: :func:`saturation_contrast` of the anchor in its frame
            (sign-likeness: sign faces are more saturated than their surroundings).
        chroma_contrast: :func:`chroma_contrast` of the anchor in its frame (sign faces are
            more colourful than their surroundings).
    """

    q: np.ndarray
    qw: np.ndarray
    mask: np.ndarray
    relation: tuple[float, float, float, float]
    anchor: tuple[float, float, float, float]
    background_similarity: float
    colored: bool
    hue_hist: np.ndarray
    dark_fraction: float = 0.0
    white_fraction: float = 0.0
    white_below: float = 0.0
    saturation_contrast: float = 0.0
    chroma_contrast: float = 0.0

    def box_from_anchor(self, anchor: Sequence[float]) -> tuple[float, float, float, float]:
        """The output box for an anchor ``(x, y, w, h)``."""
        dx, dy, rw, rh = self.relation
        return (anchor[0] + dx * anchor[2], anchor[1] + dy * anchor[3], rw * anchor[2],
                rh * anchor[3])


def build_target(frame: np.ndarray, box: Sequence[float], cfg: TrackerConfig,
                 luts: Optional[np.ndarray] = None) -> Optional[TargetModel]:
    """Target model of a detection box (seed 001, eq. 1) with its anchor and shape mask.

    Args:
        frame: BGR uint8 image.
        box: detection ``(x, y, w, h)`` in pixels.
        cfg: tracker configuration.
        luts: bin look-up tables (computed from ``cfg`` when None).

    Returns:
        The model, or None when the box is (almost) outside the image.
    """
    luts = _luts(cfg.hue_bins, cfg.sat_bins) if luts is None else luts
    H, W = frame.shape[:2]
    x, y, w, h = (float(v) for v in box)
    xi0, yi0 = max(0, int(math.floor(x))), max(0, int(math.floor(y)))
    xi1, yi1 = min(W, int(math.ceil(x + w))), min(H, int(math.ceil(y + h)))
    if xi1 - xi0 < 2 or yi1 - yi0 < 2:
        return None
    s = _stride(w / 2, h / 2, 4 * cfg.max_samples)
    patch = cv2.cvtColor(np.ascontiguousarray(frame[yi0:yi1:s, xi0:xi1:s]), cv2.COLOR_BGR2HSV)
    m = shape_mask(patch)
    colored = m is not None
    dark = white = white_below = 0.0
    if colored:
        dark, white, white_below = _content(patch, m)
    anchor = (x, y, w, h)
    if colored and cfg.anchor_on_color:
        ys_, xs_ = np.nonzero(m)
        ax0, ax1 = xi0 + s * xs_.min(), xi0 + s * (xs_.max() + 1)
        ay0, ay1 = yi0 + s * ys_.min(), yi0 + s * (ys_.max() + 1)
        anchor = (float(ax0), float(ay0), float(ax1 - ax0), float(ay1 - ay0))
        sub = m[ys_.min():ys_.max() + 1, xs_.min():xs_.max() + 1]
    elif colored:
        ox0, oy0 = int(round((x - xi0) / s)), int(round((y - yi0) / s))
        sub = m[max(0, oy0):, max(0, ox0):]
    else:
        sub = np.ones((2, 2), np.uint8)
    mask = cv2.resize(sub.astype(np.float32), (_MASK_GRID, _MASK_GRID),
                      interpolation=cv2.INTER_AREA)
    mask = (mask >= 0.5).astype(np.float32)
    if mask.sum() < 4:
        mask[:] = 1.0
    aw, ah = max(anchor[2], 1.0), max(anchor[3], 1.0)
    relation = ((x - anchor[0]) / aw, (y - anchor[1]) / ah, w / aw, h / ah)
    ax, ay = aw / 2, ah / 2
    zx, zy = anchor[0] + ax, anchor[1] + ay
    stride = _stride(ax, ay, cfg.max_samples)
    win = SearchWindow(frame, zx - 2 * ax, zy - 2 * ay, zx + 2 * ax + 1, zy + 2 * ay + 1,
                       stride, luts)
    nb = cfg.hue_bins * cfg.sat_bins
    kern = _kernel(win, mask, zx, zy, ax, ay)
    q = None if kern is None else _histogram(kern[0], kern[1], nb)
    if q is None:
        return None
    # Surroundings: the window outside the anchor box (seed 001 has no such check).
    inside = np.zeros(win.bins.shape, bool)
    kx0, kx1, ky0, ky1 = win.span(zx, zy, ax, ay)
    inside[ky0:ky1, kx0:kx1] = True
    ring = win.bins[~inside]
    sat_contrast = saturation_contrast(win, zx, zy, ax, ay, cfg.saturation_reference)
    chroma = chroma_contrast(win, zx, zy, ax, ay, cfg.chroma_reference)
    bg_sim = 1.0
    qw = q
    if ring.size >= 8:
        bg = np.bincount(ring, minlength=nb).astype(np.float64)
        bg /= bg.sum()
        bg_sim = bhattacharyya(q, bg)
        if cfg.background_weighting:
            # Corrected background-weighted histogram: v_u = min(o* / o_u, 1).
            nz = bg[bg > 0]
            v = np.ones(nb)
            v[bg > 0] = np.minimum(nz.min() / nz, 1.0)
            qw = q * v
            qw = qw / qw.sum() if qw.sum() > 0 else q
    # CamShift peer model: hue histogram of the chromatic anchor samples.
    hsv_in = win.hsv[ky0:ky1, kx0:kx1]
    valid = ((hsv_in[..., 1] >= 60) & (hsv_in[..., 2] >= 32)).astype(np.uint8)
    hue_hist = cv2.calcHist([np.ascontiguousarray(hsv_in)], [0], valid, [180], [0, 180])
    cv2.normalize(hue_hist, hue_hist, 0, 255, cv2.NORM_MINMAX)
    return TargetModel(q=q, qw=qw, mask=mask, relation=relation, anchor=anchor,
                       background_similarity=bg_sim, colored=colored, hue_hist=hue_hist,
                       dark_fraction=dark, white_fraction=white, white_below=white_below,
                       saturation_contrast=sat_contrast, chroma_contrast=chroma)


def _content(hsv: np.ndarray, mask: np.ndarray) -> tuple[float, float, float]:
    """Dark and white shares of the shape, relative to the brightness of its colour, and the
    share of its white below the lowest row where the colour dominates (``white_below``:
    about 1 for a regulatory sign's white bottom, low for a drum's or cone's bands, which
    have colour below them)."""
    inside = mask > 0
    n = int(inside.sum())
    if n == 0:
        return 0.0, 0.0, 0.0
    s, v = hsv[..., 1].astype(np.int16), hsv[..., 2].astype(np.int16)
    colour = (s >= 100) & inside
    ref = float(np.median(v[colour])) if colour.any() else float(np.median(v[inside]))
    dark = float(np.count_nonzero((v < 0.5 * ref) & inside)) / n
    white_px = (s < 60) & (v >= 0.75 * ref) & inside
    n_white = int(np.count_nonzero(white_px))
    below = 0.0
    if n_white:
        rows_c = colour.sum(axis=1)
        rows_w = white_px.sum(axis=1)
        dom = np.nonzero(rows_c > rows_w)[0]
        last = int(dom.max()) if dom.size else -1
        below = float(rows_w[last + 1:].sum()) / n_white
    return dark, n_white / n, below


def cone_like(frame: np.ndarray, box: Sequence[float], cfg: TrackerConfig) -> bool:
    """A drum or cone test around a coloured box (not only inside it, like ``_content``).

    Traffic cones and drums (MUTCD 6F.63, 6F.64) carry white retro-reflective bands across
    their whole width between orange parts; the colour detector's false detections of them
    are often one orange part, e.g. a cone's body right below its band.  The colour
    detector's band test (:func:`~workzone_ros.core.detection.banded_rows`; the cone cap,
    :func:`~workzone_ros.core.detection.white_cap` over a body taller than wide that widens
    downward, :func:`~workzone_ros.core.detection.row_taper`) runs on strips of
    ``cone_strip`` of the box's width (around its centre and around its orange pixels'
    median column) reaching a box height and two blends above and below it, with simple
    HSV masks: orange within ``cone_hue_tolerance`` of the face's saturation-weighted hue
    mode, at least ``max(cone_min_saturation, cone_sat_rel x`` the face's median
    saturation); white at most ``cone_white_s_max`` saturated and at least
    ``cone_white_luma`` times as bright (luma) as the orange face, not in rows whose white
    runs on past both of the box's sides (the background: sky, a wall); dark below
    ``cone_dark_rel`` times the face's value (a regulatory sign's white bottom ends at its
    black border line, and has no orange beyond it).  The box's top and bottom first move
    in past white rows and out through orange ones (a tracked box lags or holds part of
    the object or of its band).

    Args:
        frame: BGR uint8 image.
        box: the coloured part ``(x, y, w, h)`` in pixels (a track's anchor).
        cfg: tracker configuration (``cone_*``).

    Returns:
        True when a band separates the box from more orange above or below it (or inside
        it), or a white band caps a box taller than wide that widens downward; False for a
        box less than ``cone_min_px`` high or without enough orange.
    """
    H, W = frame.shape[:2]
    bx, by = int(round(box[0])), int(round(box[1]))
    bw, bh = int(round(box[2])), int(round(box[3]))
    bx0, by0 = max(0, bx), max(0, by)
    bx1, by1 = min(W, bx + bw), min(H, by + bh)
    if bh < cfg.cone_min_px or bx1 - bx0 < 2 or by1 - by0 < 2:
        return False
    f0, f1 = max(0, bx - bw // 2), min(W, bx + bw + bw // 2)
    gap = max(2, int(round(0.15 * bh)))
    reach = bh + 2 * gap + 2
    r0, r1 = max(0, by - reach), min(H, by + bh + reach)
    wide = np.ascontiguousarray(frame[r0:r1, f0:f1])
    hsv = cv2.cvtColor(wide, cv2.COLOR_BGR2HSV)
    luma = cv2.cvtColor(wide, cv2.COLOR_BGR2GRAY)
    fy0, fy1, fx0, fx1 = by0 - r0, by1 - r0, bx0 - f0, bx1 - f0
    # the face's colour: the saturation-weighted hue mode over the box's middle (a target
    # model's hue can be that of the surroundings its first box held) and the median
    # saturation there; orange: that hue range, at least cone_sat_rel as saturated (a
    # pale or brownish background of a similar hue is not the object's)
    mid = hsv[fy0 + (fy1 - fy0) // 4:fy1 - (fy1 - fy0) // 4,
              fx0 + (fx1 - fx0) // 4:fx1 - (fx1 - fx0) // 4].reshape(-1, 3)
    mid = mid[(mid[:, 1] >= cfg.cone_min_saturation) & (mid[:, 2] >= 50)]
    if mid.shape[0] < 4:
        return False
    hist = np.bincount(mid[:, 0] // 4, weights=mid[:, 1].astype(np.float64), minlength=45)
    hue = int(np.argmax(hist)) * 4 + 2

    def near(h: np.ndarray) -> np.ndarray:
        d = np.abs(h.astype(np.int16) - hue)
        return np.minimum(d, 180 - d) <= cfg.cone_hue_tolerance

    s_face = float(np.median(mid[near(mid[:, 0]), 1]))
    orange = near(hsv[..., 0]) & (hsv[..., 2] >= 50) & (
        hsv[..., 1] >= max(cfg.cone_min_saturation, cfg.cone_sat_rel * s_face))
    face = orange[fy0:fy1, fx0:fx1]
    if np.count_nonzero(face) < 4:
        return False
    y_ref = float(np.median(luma[fy0:fy1, fx0:fx1][face]))
    v_ref = float(np.median(hsv[fy0:fy1, fx0:fx1, 2][face]))
    white = (hsv[..., 1] <= cfg.cone_white_s_max) & (luma >= cfg.cone_white_luma * y_ref)
    open_rows = open_background_rows(white[:, :fx0], white[:, fx1:], max(1, bw // 4))
    if open_rows is not None:
        white = white & ~open_rows[:, None]
    dark = hsv[..., 2] < cfg.cone_dark_rel * v_ref
    # the strip: the middle third of the box's columns (a cone's band above its body is
    # narrower than the body: its top is about a fifth of its base) around the box's centre
    # or around the face's colour (the box may hold some background of a similar hue)
    half = max(1, int(round(bw * cfg.cone_strip / 2)))
    centres = {(fx0 + fx1) // 2, int(round(float(np.median(np.nonzero(face)[1])))) + fx0}
    run = max(2, int(round(cfg.cone_band_rows * bh)))
    beyond = max(3, int(round(0.1 * bh)))
    for cx in sorted(centres):
        s0, s1 = max(0, cx - half), min(wide.shape[1], cx + half + 1)
        o_s, w_s = orange[:, s0:s1], white[:, s0:s1]
        # a tracked box need not end where the object's colour ends (it lags, holds only
        # part of the object or part of its band): its edges move out through the rows
        # that are still orange and in past the white ones
        is_w = w_s.mean(axis=1) >= 0.5
        is_o = (o_s.mean(axis=1) >= 0.2) & ~is_w
        top, bottom = fy0, fy1
        while top < bottom - 1 and is_w[top]:
            top += 1
        while bottom - 1 > top and is_w[bottom - 1]:
            bottom -= 1
        while top > 0 and is_o[top - 1]:
            top -= 1
        while bottom < is_o.size and is_o[bottom]:
            bottom += 1
        if banded_rows(o_s, w_s, dark[:, s0:s1], top, bottom, run, gap, bh + gap, beyond):
            return True
        if bh >= bw and row_taper(face.astype(np.uint8)) <= cfg.cone_taper \
                and white_cap(w_s, fy0, run, gap):
            return True
    return False


# --- localisation -------------------------------------------------------------------------

def meanshift_localise(win: SearchWindow, target: TargetModel, zx: float, zy: float,
                       ax: float, ay: float, cfg: TrackerConfig
                       ) -> tuple[float, float, float, float, float]:
    """Seed 001's multi-scale mean-shift: five kernel sizes, eq. 3, best Bhattacharyya.

    Args:
        win: search window of the current frame.
        target: the track's model.
        zx, zy: start centre (previous or predicted anchor centre).
        ax, ay: previous anchor half-size.
        cfg: tracker configuration (scales, iterations, threshold).

    Returns:
        ``(cx, cy, half_w, half_h, rho, ring)`` of the best candidate: rho = 0 when none
        converged; ring is the Bhattacharyya coefficient of the target and the candidate's
        surroundings (None when ``surround_weight`` is 0: the seed's rule does not look).
    """
    nb = target.q.size
    q, qw, mask = target.q, target.qw, target.mask
    eps2 = cfg.shift_threshold_px ** 2
    best = (zx, zy, ax, ay, 0.0, None)
    best_score = -math.inf
    start = (zx, zy)
    for scale in cfg.scales:
        bx, by = ax * scale, ay * scale
        cx, cy = start
        rho = 0.0
        converged = False
        for _ in range(cfg.max_iterations):
            kern = _kernel(win, mask, cx, cy, bx, by)
            if kern is None:
                break
            bins, k, xs, ys = kern
            p = _histogram(bins, k, nb)
            if p is None:
                break
            rho = bhattacharyya(p, q)
            ratio = np.sqrt(qw / np.maximum(p, 1e-12))
            wts = ratio.take(bins)
            wts *= k > 0                                    # eq. 3: w_i * mask on the support
            total = wts.sum()
            if total <= 0:
                break
            nx = float(wts.sum(axis=0) @ xs) / total
            ny = float(wts.sum(axis=1) @ ys) / total
            moved2 = (nx - cx) ** 2 + (ny - cy) ** 2
            cx, cy = nx, ny
            if moved2 < eps2:
                converged = True      # rho of the last evaluation stands (moved < threshold)
                break
        if not converged:
            kern = _kernel(win, mask, cx, cy, bx, by)
            if kern is not None:
                p = _histogram(kern[0], kern[1], nb)
                rho = bhattacharyya(p, q) if p is not None else 0.0
            else:
                rho = 0.0
        score = rho
        ring_sim = None
        if cfg.surround_weight > 0 and rho > 0:
            ring = _surround(win, mask, cx, cy, bx, by, cfg.surround_size, nb)
            if ring is not None:
                ring_sim = bhattacharyya(ring, q)
                score -= cfg.surround_weight * ring_sim
        if score > best_score:
            best, best_score = (cx, cy, bx, by, rho, ring_sim), score
        if scale == cfg.scales[0]:
            start = (cx, cy)          # the other sizes start where the first one converged
    return best


def camshift_localise(win: SearchWindow, target: TargetModel, zx: float, zy: float,
                      ax: float, ay: float, cfg: TrackerConfig
                      ) -> tuple[float, float, float, float, float]:
    """OpenCV CamShift on the hue back-projection of the same search window (the peer).

    The similarity reported is the same kernel Bhattacharyya coefficient as mean-shift's, at
    the CamShift box, so both methods share the track-life rules.

    Returns:
        ``(cx, cy, half_w, half_h, rho, None)`` (ring: see :func:`meanshift_localise`).
    """
    if win.nx < 2 or win.ny < 2:
        return zx, zy, ax, ay, 0.0, None
    s = win.stride
    hsv = win.hsv
    bp = cv2.calcBackProject([hsv], [0], target.hue_hist, [0, 180], 1)
    bp[(hsv[..., 1] < 60) | (hsv[..., 2] < 32)] = 0
    gx0 = int(round((zx - ax - win.x0) / s))
    gy0 = int(round((zy - ay - win.y0) / s))
    gw = max(1, int(round(2 * ax / s)))
    gh = max(1, int(round(2 * ay / s)))
    gx0 = min(max(gx0, 0), win.nx - 1)
    gy0 = min(max(gy0, 0), win.ny - 1)
    gw, gh = min(gw, win.nx - gx0), min(gh, win.ny - gy0)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, cfg.max_iterations,
            max(cfg.shift_threshold_px / s, 0.1))
    _, (x, y, w, h) = cv2.CamShift(bp, (gx0, gy0, gw, gh), crit)
    if w <= 0 or h <= 0:
        return zx, zy, ax, ay, 0.0, None
    cx = win.x0 + s * (x + w / 2.0)
    cy = win.y0 + s * (y + h / 2.0)
    bx, by = s * w / 2.0, s * h / 2.0
    kern = _kernel(win, target.mask, cx, cy, bx, by)
    rho = 0.0
    if kern is not None:
        p = _histogram(kern[0], kern[1], target.q.size)
        rho = bhattacharyya(p, target.q) if p is not None else 0.0
    return cx, cy, bx, by, rho, None


def score_box(win: SearchWindow, target: TargetModel, cx: float, cy: float, bx: float,
              by: float, cfg: TrackerConfig) -> tuple[float, float]:
    """Target agreement of the box centred at (cx, cy), half-size (bx, by), as mean-shift
    scores its candidates: ``(rho, ring)``, the Bhattacharyya coefficients of the target
    with the kernel histogram (eq. 1 with the target's shape mask) and with the
    surroundings up to ``surround_size`` times the box (0 when either is empty)."""
    nb = target.q.size
    rho = ring_sim = 0.0
    kern = _kernel(win, target.mask, cx, cy, bx, by)
    if kern is not None:
        p = _histogram(kern[0], kern[1], nb)
        rho = bhattacharyya(p, target.q) if p is not None else 0.0
    ring = _surround(win, target.mask, cx, cy, bx, by, cfg.surround_size, nb)
    if ring is not None:
        ring_sim = bhattacharyya(ring, target.q)
    return rho, ring_sim


def predicted_size(history: Sequence[tuple[float, float, float]],
                   frame: float) -> Optional[tuple[float, float]]:
    """Anchor size (w, h) expected at ``frame`` from detected sizes ``(frame, w, h)``.

    A static sign's image size is ``f S / d`` with ``d`` falling at the ego speed, so
    ``1 / size`` is linear in time.  Fitted per side with Theil-Sen (median of the pairwise
    slopes, median intercept): robust to one or two wrong detections.

    Returns:
        The predicted size, or None with fewer than three distinct frames or a prediction
        that is not positive.
    """
    fit = inverse_size_fit(history)
    return None if fit is None else size_from_fit(fit, frame)


def inverse_size_fit(history: Sequence[tuple[float, float, float]]
                     ) -> Optional[tuple[float, float, float, float]]:
    """Theil-Sen fit of :func:`predicted_size`: ``(slope_w, icpt_w, slope_h, icpt_h)`` of
    ``1 / size`` over the frame number, or None with fewer than three distinct frames."""
    if len({h[0] for h in history}) < 3:
        return None
    t = [float(h[0]) for h in history]
    n = len(t)
    pairs = [(a, b) for a in range(n) for b in range(a + 1, n) if t[a] != t[b]]
    out: list[float] = []
    for k in (1, 2):            # plain Python: a handful of points (numpy's overhead rules)
        inv = [1.0 / max(float(h[k]), 1.0) for h in history]
        slope = statistics.median((inv[b] - inv[a]) / (t[b] - t[a]) for a, b in pairs)
        out += [slope, statistics.median(v - slope * x for v, x in zip(inv, t))]
    return out[0], out[1], out[2], out[3]


def size_from_fit(fit: tuple[float, float, float, float],
                  frame: float) -> Optional[tuple[float, float]]:
    """The size (w, h) an :func:`inverse_size_fit` gives at ``frame`` (None when it is not
    positive)."""
    vw, vh = fit[1] + fit[0] * frame, fit[3] + fit[2] * frame
    if vw <= 1e-4 or vh <= 1e-4:
        return None
    return 1.0 / vw, 1.0 / vh


def _theil_sen(t: np.ndarray, v: np.ndarray) -> float:
    """Median of the pairwise slopes of ``v`` over ``t`` (distinct ``t`` only)."""
    i, j = np.triu_indices(len(t), 1)
    ok = t[j] != t[i]
    return float(np.median((v[j][ok] - v[i][ok]) / (t[j][ok] - t[i][ok])))


def approach_rate(history: Sequence[tuple[float, float, float, float, float]],
                  focus: Optional[tuple[float, float]] = None, window: int = 15,
                  min_frames: int = 8, min_offset: float = 1.5) -> Optional[float]:
    """How fast the camera approaches a target, from its image track alone: the fall per
    frame of ``1 / size`` (1/px per frame), which is constant for a static object.

    A static object of size ``S`` at distance ``Z`` has the image size ``s = f S / Z``; with
    the camera approaching at speed ``v``, ``d(1/s)/dt = -v / (f S)``, whatever the distance.
    Its offset ``r`` from the focus of expansion (the image point straight ahead) scales
    like ``s`` (``r = f X / Z``, X its distance from the camera's axis), so
    ``-d(1/r)/dt * (r / s)`` is the same ``v / (f S)``; that estimate is the more precise one
    when the object is far off-centre (``r`` several times ``s``: a pixel of error is a
    smaller share of it), the size estimate the one free of the focus and of camera yaw.
    A vehicle ahead driving at the ego speed keeps its distance: both are near 0.

    Args:
        history: ``(frame, cx, cy, w, h)`` of the target's box, oldest first.
        focus: focus of expansion in pixels, or None for the size estimate alone.
        window: use the entries of the last ``window`` frames.
        min_frames: None when those entries span fewer frames than this.
        min_offset: the offset estimate counts only when the offset is at least this many
            sizes (median of ``r / s``; otherwise an error of the focus dominates it).

    Returns:
        The larger of the size and (where it counts) offset estimates, Theil-Sen fitted;
        None when the history is too short to tell.
    """
    if not history:
        return None
    last = history[-1][0]
    h = np.array([e for e in history if e[0] >= last - window], float)
    if len(h) < 3 or h[-1, 0] - h[0, 0] < min_frames:
        return None
    t = h[:, 0]
    size = np.sqrt(np.maximum(h[:, 3], 1.0) * np.maximum(h[:, 4], 1.0))
    rate = -_theil_sen(t, 1.0 / size)
    if focus is not None:
        r = np.hypot(h[:, 1] - focus[0], h[:, 2] - focus[1])
        ratio = float(np.median(r / size))          # X / S, constant for a static object
        if ratio >= min_offset and r.min() > 0:
            rate = max(rate, -_theil_sen(t, 1.0 / r) * ratio)
    return rate


def _ioa(a: Sequence[float], b: Sequence[float]) -> float:
    """Share of box ``b``'s area inside box ``a`` (0 when ``b`` is empty)."""
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0 or b[2] <= 0 or b[3] <= 0:
        return 0.0
    return iw * ih / (b[2] * b[3])


def _blend(a: Sequence[float], b: Sequence[float], wb: float) -> tuple[float, float, float,
                                                                       float]:
    """Weighted mean of two ``(x, y, w, h)`` boxes (corners averaged; ``wb`` is b's weight)."""
    wa = 1.0 - wb
    x0 = wa * a[0] + wb * b[0]
    y0 = wa * a[1] + wb * b[1]
    x1 = wa * (a[0] + a[2]) + wb * (b[0] + b[2])
    y1 = wa * (a[1] + a[3]) + wb * (b[1] + b[3])
    return (x0, y0, x1 - x0, y1 - y0)


# --- track life ---------------------------------------------------------------------------

@dataclass
class _Track:
    track_id: int
    target: TargetModel
    anchor: tuple[float, float, float, float]
    box: tuple[float, float, float, float]
    kind: str
    color: str
    confidence: float
    age: int = 1
    hits: int = 1
    lost: int = 0
    coast: int = 0
    similarity: float = 1.0
    velocity: tuple[float, float] = (0.0, 0.0)
    pred_anchor: Optional[tuple[float, float, float, float]] = None
    pred_box: Optional[tuple[float, float, float, float]] = None
    pred_rho: float = 0.0
    pred_ring: float = 0.0
    growth: float = 0.0              # log anchor-size change per frame (EMA)
    inv_rate: float = 0.0            # fall of 1 / anchor width per frame, from detections
    ref_width: float = 0.0           # anchor width at the last detection-led update
    since_ref: int = 0               # frames since then
    trend_known: bool = False        # inv_rate / growth measured between two detections
    fused_share: float = 1.0         # detection's weight in the last update
    ref_ring: float = 0.0            # ring similarity at the last detection
    det_sizes: list = field(default_factory=list)   # (frame, anchor w, anchor h) detected
    was_lost: bool = False           # similarity below min_similarity since the last detection
    motion: list = field(default_factory=list)      # (frame, cx, cy, w, h) of the anchor
    approach: Optional[float] = None  # last approach_rate (None: not judged)
    size_fit: Optional[tuple] = None  # (key, inverse_size_fit of det_sizes), cached
    cone: bool = False               # looked like part of a drum or cone (cone_like)


@dataclass
class _DetModel:
    det: Detection
    box: tuple[float, float, float, float]
    target: Optional[TargetModel]


class MultiTracker:
    """Track life around the per-track localiser (see the module docstring).

    Usage::

        tracker = MultiTracker(TrackerConfig())
        for frame, detections in stream:
            tracks = tracker.step(frame, detections)     # list of interfaces.Track
    """

    def __init__(self, config: Optional[TrackerConfig] = None) -> None:
        """Create an empty tracker.

        Args:
            config: parameters (defaults when None).
        """
        self.config = config or TrackerConfig()
        self._luts = _luts(self.config.hue_bins, self.config.sat_bins)
        self._tracks: list[_Track] = []
        self._next_id = 1
        self.frames = 0
        self._frame: Optional[np.ndarray] = None
        self._stamps: list[float] = []       # the last frames' stamps (s), for the frame rate
        self._fps: Optional[float] = None     # frame rate of those stamps (None: not known)
        #: seconds spent in localisation per track in the last step (for the bench).
        self.last_localise_s: list[float] = []

    def reconfigure(self, config: TrackerConfig) -> None:
        """Use new parameters from the next frame on (keeps the tracks)."""
        self.config = config
        self._luts = _luts(config.hue_bins, config.sat_bins)

    def reset(self) -> None:
        """Drop every track (e.g. when the bag loops or time jumps back)."""
        self._tracks.clear()
        self._stamps.clear()
        self._fps = None

    @property
    def active_ids(self) -> list[int]:
        """Ids of the live tracks."""
        return [t.track_id for t in self._tracks]

    # -- per-track localisation ----------------------------------------------------------

    def _localise(self, frame: np.ndarray, tr: _Track) -> None:
        cfg = self.config
        x, y, w, h = tr.anchor
        ax, ay = w / 2.0, h / 2.0
        zx, zy = x + ax, y + ay
        if cfg.use_velocity:
            zx += tr.velocity[0]
            zy += tr.velocity[1]
        g = self._perspective_scale(tr) if cfg.method == 'meanshift' else 1.0
        alt = not min(cfg.scales) <= g <= max(cfg.scales)
        big = max(g, 1.0) if alt else 1.0          # the window holds both candidate sets
        smax = max(cfg.scales) * big
        mx = ax * (smax + cfg.search_margin) + 2
        my = ay * (smax + cfg.search_margin) + 2
        stride = _stride(ax * big, ay * big, cfg.max_samples)
        win = SearchWindow(frame, zx - mx, zy - my, zx + mx + 1, zy + my + 1, stride,
                           self._luts)
        fn = meanshift_localise if cfg.method == 'meanshift' else camshift_localise
        best = fn(win, tr.target, zx, zy, ax, ay, cfg)
        if alt:
            # Perspective: the candidates around the predicted size compete with those
            # around the previous size (same score: rho minus the surround term).
            other = fn(win, tr.target, zx, zy, ax * g, ay * g, cfg)
            sw = cfg.surround_weight
            if other[4] - sw * (other[5] or 0.0) > best[4] - sw * (best[5] or 0.0):
                best = other
        cx, cy, bx, by, rho, ring = best
        if ring is None and (cfg.association == 'fuse' or cfg.max_ring_similarity < 1.0):
            ring = score_box(win, tr.target, cx, cy, bx, by, cfg)[1]
        tr.pred_anchor = (cx - bx, cy - by, 2 * bx, 2 * by)
        tr.pred_box = tr.target.box_from_anchor(tr.pred_anchor)
        tr.pred_rho = rho
        tr.pred_ring = ring or 0.0

    # -- the frame step ------------------------------------------------------------------

    def step(self, frame: np.ndarray, detections: Sequence[Detection] = (),
             stamp: Optional[float] = None) -> list[Track]:
        """Process one frame and its detections; returns the tracks to publish.

        Args:
            frame: BGR uint8 image (H, W, 3).
            detections: the detector's output for this very frame (empty when it missed).
            stamp: the frame's time in seconds (the image header), for the frame rate the
                motion cue needs (``TrackerConfig.frame_rate`` when never given).

        Returns:
            One :class:`~workzone_ros.interfaces.Track` per published track, detections first
            in input order, then tracks running on their own.

        Raises:
            TrackingError: ``frame`` is not an (H, W, 3) uint8 image.
        """
        if not isinstance(frame, np.ndarray) or frame.ndim != 3 or frame.shape[2] != 3 \
                or frame.dtype != np.uint8:
            raise TrackingError('frame must be an (H, W, 3) uint8 BGR image, got '
                                f'{getattr(frame, "shape", None)} '
                                f'{getattr(frame, "dtype", type(frame).__name__)}')
        cfg = self.config
        self.frames += 1
        self._frame = frame
        if stamp is not None:
            self._stamps.append(float(stamp))
            del self._stamps[:-31]
            gaps = np.diff(self._stamps)
            gaps = gaps[gaps > 0]
            self._fps = float(1.0 / np.median(gaps)) if gaps.size else None
        H, W = frame.shape[:2]
        tracking = cfg.mode == 'detection_and_tracking'
        self.last_localise_s = []

        # 1. Localise every live track in this frame.
        if tracking:
            for tr in self._tracks:
                t0 = _clock()
                self._localise(frame, tr)
                self.last_localise_s.append(_clock() - t0)
        else:
            for tr in self._tracks:
                tr.pred_anchor, tr.pred_box, tr.pred_rho = tr.anchor, tr.box, 0.0

        # 2. Detection models.
        dets: list[_DetModel] = []
        for d in detections:
            b = d.box
            if b.w < cfg.min_box_px or b.h < cfg.min_box_px:
                continue
            box = (float(b.x), float(b.y), float(b.w), float(b.h))
            dets.append(_DetModel(d, box, build_target(frame, box, cfg, self._luts)))

        # 3. Associate: IoU first, then histogram similarity (greedy on the combined score).
        pairs = []
        for ti, tr in enumerate(self._tracks):
            ref = tr.pred_box if tr.pred_box is not None else tr.box
            ref_anchor = tr.pred_anchor if tr.pred_anchor is not None else tr.anchor
            for di, dm in enumerate(dets):
                # The anchor term lets a detection of only the orange top of a two-colour box
                # agree with the track of the whole box.
                iou = max(box_iou(ref, dm.box), box_iou(tr.box, dm.box),
                          box_iou(ref_anchor, dm.box))
                if iou <= 0.0:
                    continue
                sim = bhattacharyya(tr.target.q, dm.target.q) if dm.target is not None else 0.0
                if iou >= cfg.iou_gate or sim >= cfg.similarity_gate:
                    pairs.append((iou + sim, iou, sim, ti, di))
        pairs.sort(reverse=True)
        t_match: dict[int, tuple[int, float]] = {}
        d_used: set[int] = set()
        for _, iou, sim, ti, di in pairs:
            if ti in t_match or di in d_used:
                continue
            d_used.add(di)
            tr = self._tracks[ti]
            if tracking and iou < cfg.agree_iou and tr.pred_rho >= cfg.min_similarity \
                    and tr.pred_box is not None:
                continue          # belongs to the track but disagrees: the tracker keeps it
            t_match[ti] = (di, sim)

        out_det: list[tuple[int, Track]] = []
        out_trk: list[Track] = []
        survivors: list[_Track] = []
        for ti, tr in enumerate(self._tracks):
            tr.age += 1
            tr.since_ref += 1
            if ti in t_match:
                di, sim = t_match[ti]
                dm = dets[di]
                tr.cone = False          # judged afresh when it runs on its own again
                if tracking and cfg.association == 'fuse' and dm.target is not None \
                        and self._confident(tr) \
                        and min(tr.pred_box[2], tr.pred_box[3]) >= cfg.fuse_min_px:
                    t0 = _clock()
                    self._fuse(frame, tr, dm, sim)
                    self.last_localise_s[ti] += _clock() - t0
                else:
                    self._correct(tr, dm, sim)
                survivors.append(tr)
                out_det.append((di, self._payload(tr, 'detection')))
                continue
            if not tracking:
                tr.lost += 1
                if tr.lost <= cfg.max_lost_frames:
                    survivors.append(tr)
                continue
            # The detector missed: the track runs on its own.
            tr.coast += 1
            if tr.coast > cfg.max_coast_frames:
                continue
            if tr.pred_rho < cfg.min_similarity:
                # Lost (occluded?): not published; the box coasts on the velocity and the
                # next frame searches there again, until max_lost_frames.
                tr.lost += 1
                tr.was_lost = True
                if tr.lost <= cfg.max_lost_frames:
                    vx, vy = tr.velocity
                    a, b = tr.anchor, tr.box
                    tr.anchor = (a[0] + vx, a[1] + vy, a[2], a[3])
                    tr.box = (b[0] + vx, b[1] + vy, b[2], b[3])
                    survivors.append(tr)
                continue
            if tr.pred_ring > cfg.max_ring_similarity and (
                    cfg.ring_margin < 0 or tr.hits < cfg.ring_margin_min_hits
                    or tr.pred_ring > tr.ref_ring + cfg.ring_margin):
                # Drift guard: the target's colour continues all around the box (the box sits
                # in a much larger region of sign colour, e.g. an orange vehicle): not a sign
                # anymore; coast blind like an occlusion and end unless a detection returns.
                tr.lost += 1
                if tr.lost <= cfg.max_lost_frames:
                    survivors.append(tr)
                continue
            pb = tr.pred_box
            if not self._inside(pb, W, H) or pb[2] > cfg.max_box_fraction * W \
                    or pb[3] > cfg.max_box_fraction * H or self._overgrown(tr):
                continue
            self._advance(tr, tr.pred_anchor, pb)
            tr.similarity = tr.pred_rho
            tr.lost = 0
            survivors.append(tr)
            if tr.hits >= cfg.min_hits_to_coast and self._may_coast(tr.target) \
                    and (not tr.was_lost or tr.hits >= cfg.min_hits_after_loss) \
                    and self._approaching(tr, W, H) and not self._cone(frame, tr):
                out_trk.append(self._payload(tr, 'tracking'))

        # 4. Unmatched detections start tracks.
        for di, dm in enumerate(dets):
            if di in d_used or dm.target is None:
                if di not in d_used:
                    out_det.append((di, self._det_only(dm)))
                continue
            tr = _Track(self._next_id, dm.target, dm.target.anchor, dm.box, dm.det.kind,
                        dm.det.color, dm.det.confidence,
                        ref_width=max(dm.target.anchor[2], 1.0))
            self._record_size(tr, dm.target.anchor)
            self._record_motion(tr)
            if tracking and cfg.ring_margin >= 0:
                tr.ref_ring = self._ring_at(frame, dm.target, dm.target.anchor)
            self._next_id += 1
            survivors.append(tr)
            out_det.append((di, self._payload(tr, 'detection')))

        # 5. Duplicates: two tracks on one sign -> the one with fewer hits ends.  Besides
        # overlapping boxes (IoU), a track whose coloured anchor lies inside another's box
        # (the orange top of a two-colour sign next to the whole sign) is a duplicate
        # (``duplicate_containment``, not in the seed).
        contain = tracking and cfg.duplicate_containment < 1.0
        survivors.sort(key=lambda t: (-t.hits, t.track_id))
        kept: list[_Track] = []
        for tr in survivors:
            if any(self._duplicate(tr, k, contain) for k in kept):
                continue
            kept.append(tr)
        kept_ids = {t.track_id for t in kept}
        self._tracks = sorted(kept, key=lambda t: t.track_id)
        out_det.sort(key=lambda p: p[0])
        return [t for _, t in out_det] + [t for t in out_trk if t.track_id in kept_ids]

    # -- helpers -------------------------------------------------------------------------

    def _duplicate(self, a: _Track, b: _Track, contain: bool) -> bool:
        """Tracks ``a`` and ``b`` follow one sign: their boxes overlap by more than
        ``duplicate_iou`` or (``contain``) the smaller box's coloured anchor lies at least
        ``duplicate_containment`` inside the larger box, which is at most
        ``duplicate_area_ratio`` times larger (a big box merging a sign with its
        surroundings does not swallow the sign's own track)."""
        cfg = self.config
        if box_iou(a.box, b.box) > cfg.duplicate_iou:
            return True
        if not contain:
            return False
        area_a = a.box[2] * a.box[3]
        area_b = b.box[2] * b.box[3]
        small, big = (a, b) if area_a <= area_b else (b, a)
        if max(area_a, area_b) > cfg.duplicate_area_ratio * max(min(area_a, area_b), 1e-9):
            return False
        return _ioa(big.box, small.anchor) >= cfg.duplicate_containment

    def _inside(self, box: Sequence[float], W: int, H: int) -> bool:
        """At least ``min_inside_fraction`` of ``box`` is inside the image."""
        x, y, w, h = box
        if w <= 0 or h <= 0:
            return False
        iw = max(0.0, min(x + w, W) - max(x, 0.0))
        ih = max(0.0, min(y + h, H) - max(y, 0.0))
        return iw * ih >= self.config.min_inside_fraction * w * h

    def _advance(self, tr: _Track, anchor, box) -> None:
        ox = tr.anchor[0] + tr.anchor[2] / 2
        oy = tr.anchor[1] + tr.anchor[3] / 2
        nx = anchor[0] + anchor[2] / 2
        ny = anchor[1] + anchor[3] / 2
        vx, vy = tr.velocity
        tr.velocity = (0.5 * vx + 0.5 * (nx - ox), 0.5 * vy + 0.5 * (ny - oy))
        tr.anchor, tr.box = anchor, box
        self._record_motion(tr)

    @property
    def frame_rate(self) -> float:
        """Frames per second: the median gap of the last stamps given to :meth:`step`
        (``TrackerConfig.frame_rate`` before two increasing stamps); updated once per
        step."""
        return self.config.frame_rate if self._fps is None else self._fps

    def approach_threshold(self, width: int) -> float:
        """The motion cue's minimum fall of ``1 / size`` per frame (1/px) for frames
        ``width`` pixels wide: ``min_approach_speed / (f sign_size_m fps)``."""
        cfg = self.config
        f = 0.5 * width / math.tan(math.radians(cfg.camera_hfov_deg) / 2.0)
        return cfg.min_approach_speed / (f * cfg.sign_size_m * self.frame_rate)

    def _record_motion(self, tr: _Track) -> None:
        """Remember the anchor of this frame for :func:`approach_rate`."""
        cfg = self.config
        if cfg.min_approach_speed <= 0:
            return
        a = tr.anchor
        tr.motion.append((float(self.frames), a[0] + a[2] / 2, a[1] + a[3] / 2, a[2], a[3]))
        while tr.motion and tr.motion[0][0] < self.frames - cfg.motion_window:
            del tr.motion[0]

    def _approaching(self, tr: _Track, W: int, H: int) -> bool:
        """Motion cue: the track does not behave like a vehicle driving ahead (see
        ``TrackerConfig.min_approach_speed``)."""
        cfg = self.config
        if cfg.min_approach_speed <= 0:
            return True
        minimum = self.approach_threshold(W)
        fx, fy = cfg.focus_of_expansion
        tr.approach = approach_rate(tr.motion, (fx * W, fy * H), cfg.motion_window,
                                    cfg.motion_min_frames, cfg.radial_min_offset)
        if cfg.approach_from_detections and tr.approach is not None \
                and tr.approach < minimum:
            # The detected sizes measure the same rate, free of the tracker's own scale lag
            # (a box that started too wide grows too slowly).
            det = approach_rate([(f, 0.0, 0.0, w, h) for f, w, h in tr.det_sizes], None,
                                max(cfg.motion_window, self.frames), cfg.motion_min_frames)
            if det is not None:
                tr.approach = max(tr.approach, det)
        return tr.approach is None or tr.approach >= minimum

    def _may_coast(self, target: TargetModel) -> bool:
        """The track may be published while it runs on its own: a coloured target that does
        not look like its surroundings, nor like a drum or cone (white bands in the shape)."""
        cfg = self.config
        bg = target.background_similarity
        if not target.colored or bg > min(cfg.max_background_similarity,
                                          cfg.max_coast_background_similarity):
            return False
        if target.saturation_contrast < cfg.min_saturation_contrast \
                or target.chroma_contrast < cfg.min_chroma_contrast:
            return False
        if target.white_below >= cfg.white_bottom_share:
            return True       # white bottom under an orange top: a regulatory sign's face
        return not (cfg.anchor_on_color and target.white_fraction > cfg.max_coast_white_fraction)

    def _cone(self, frame: np.ndarray, tr: _Track) -> bool:
        """The track's coloured anchor looks like part of a drum or cone
        (:func:`cone_like` around it, ``cone_test``)."""
        cfg = self.config
        if not cfg.cone_test or not tr.target.colored:
            return False
        if tr.cone and cfg.cone_sticky:
            return True
        tr.cone = cone_like(frame, tr.anchor, cfg)
        return tr.cone

    def _confident(self, tr: _Track) -> bool:
        """The track may outvote a detection: detected often enough, tracked well."""
        cfg = self.config
        return tr.pred_box is not None and tr.hits >= cfg.min_hits_to_fuse \
            and tr.target.colored and tr.pred_rho >= cfg.min_similarity \
            and tr.target.background_similarity <= cfg.max_background_similarity

    def _lost_white_part(self, tr: _Track, new: TargetModel,
                         box: Sequence[float]) -> bool:
        """Two-colour guard: the track knows a box reaching well beyond its coloured anchor
        (the white part of a regulatory sign) and this detection (``new``, box ``box``)
        covers much less of it."""
        cfg = self.config
        if not cfg.anchor_on_color:
            return False
        rel = tr.target.relation
        top = -rel[1]                            # box above the anchor, in anchor heights
        bottom = rel[1] + rel[3] - 1.0           # box below the anchor: the white part
        two_colour = bottom >= 0.4 and bottom >= 3.0 * max(top, 0.02)
        if not two_colour:
            return False
        # Only a detection that is not already extended (its box does not reach well below
        # the coloured part) is truncated: the colour detector now extends regulatory boxes
        # itself, and replacing its extension by the track's older one lost accuracy.
        new_bottom = new.relation[1] + new.relation[3] - 1.0
        if new_bottom >= 0.5 * bottom:
            return False
        # ... and only when the detection's coloured anchor is the same part of the sign as
        # the one the relation was measured on: an anchor much taller for its width than the
        # track's (the whole face took the dominant hue, the track knows the orange band)
        # already holds the white part, and the band's relation would triple its box.
        if cfg.anchor_kind_ratio > 0:
            ta, na = tr.anchor, new.anchor
            aspect_t = ta[3] / max(ta[2], 1e-6)
            aspect_n = na[3] / max(na[2], 1e-6)
            if aspect_n > cfg.anchor_kind_ratio * aspect_t:
                return False
        # ... and only when the box itself is short for the sign: its height over width
        # well below that of the track's box.  The coloured anchor is not a stable measure
        # of the orange part (in dim light the hull of the dominant hue often covers the
        # whole face), so a complete detection whose anchor is the whole face also has no
        # box below its anchor; extending it by the relation of an orange-band anchor
        # tripled its height (tuning paper_c 1111).
        if cfg.truncated_aspect > 0:
            tb = tr.box
            aspect_t = tb[3] / max(tb[2], 1e-6)
            aspect_d = box[3] / max(box[2], 1e-6)
            if aspect_d >= cfg.truncated_aspect * aspect_t:
                return False
        return True

    def _overgrown(self, tr: _Track) -> bool:
        """Drift guard: the tracked anchor grew past what perspective and the track's own
        detections allow.  A static sign's inverse image size falls linearly with time
        (size = f S / d, d falling at the ego speed); ``inv_rate`` is that slope measured
        between detections."""
        excess = self.config.max_growth_excess
        if excess <= 0 or tr.ref_width <= 0 or tr.pred_anchor is None:
            return False
        if not tr.trend_known and self.config.growth_guard_needs_trend:
            return False
        inv = 1.0 / tr.ref_width - tr.since_ref * tr.inv_rate
        expected = 1.0 / max(inv, 1e-3)
        return tr.pred_anchor[2] > (1.0 + excess) * expected + 2.0

    def _perspective_scale(self, tr: _Track) -> float:
        """Second candidate size for this frame, relative to the track's anchor: the
        anchor size a static sign has now by the Theil-Sen trend of the track's detected
        sizes (``perspective_scale``) over the anchor's size; 1 without a usable trend (too
        few detections, or further past the last one than they span) or with the rule off.
        """
        cfg = self.config
        if not cfg.perspective_scale \
                or tr.target.background_similarity > cfg.perspective_max_background:
            return 1.0
        sizes = tr.det_sizes
        if len(sizes) < cfg.perspective_min_detections \
                or self.frames - sizes[-1][0] > sizes[-1][0] - sizes[0][0]:
            return 1.0
        key = (len(sizes), sizes[-1][0])
        if tr.size_fit is None or tr.size_fit[0] != key:
            tr.size_fit = (key, inverse_size_fit(sizes))       # refit only after a detection
        fit = tr.size_fit[1]
        if fit is None or len({d[0] for d in sizes}) < cfg.perspective_min_detections:
            return 1.0
        pred = size_from_fit(fit, self.frames)
        if pred is None:
            return 1.0
        g = math.sqrt(pred[0] * pred[1] / max(tr.anchor[2] * tr.anchor[3], 1.0))
        return min(max(g, cfg.perspective_min), cfg.perspective_max)

    def _measure_growth(self, tr: _Track) -> None:
        """After a detection-led update: the per-frame growth and inverse-size slope."""
        aw = max(tr.anchor[2], 1.0)
        if tr.ref_width > 0 and tr.since_ref > 0:
            n = tr.since_ref
            g = min(max(math.log(aw / tr.ref_width) / n, -0.05), 0.2)
            inv = max((1.0 / tr.ref_width - 1.0 / aw) / n, 0.0)
            tr.growth = 0.6 * tr.growth + 0.4 * g
            if tr.trend_known or not self.config.growth_guard_needs_trend:
                tr.inv_rate = 0.6 * tr.inv_rate + 0.4 * inv
            else:
                tr.inv_rate = inv             # the first measured trend, not averaged with 0
            tr.trend_known = True
        tr.ref_width = aw
        tr.since_ref = 0

    def _fuse(self, frame: np.ndarray, tr: _Track, dm: _DetModel, sim: float) -> None:
        """Association rule ``fuse``: weigh the tracked and the detected box (see
        :class:`TrackerConfig`) and update the track with the result."""
        cfg = self.config
        new = dm.target
        ad = new.anchor
        ax, ay = max(ad[2], 1.0) / 2, max(ad[3], 1.0) / 2
        cx, cy = ad[0] + ax, ad[1] + ay
        m = cfg.surround_size
        win = SearchWindow(frame, cx - m * ax - 2, cy - m * ay - 2, cx + m * ax + 3,
                           cy + m * ay + 3, _stride(ax, ay, cfg.max_samples), self._luts)
        rho_d, ring_d = score_box(win, tr.target, cx, cy, ax, ay, cfg)
        tr.ref_ring = ring_d
        s_d = rho_d - cfg.surround_weight * ring_d + cfg.fuse_bias
        s_t = tr.pred_rho - cfg.surround_weight * tr.pred_ring
        g = math.exp(tr.growth)
        refs = [(max(tr.anchor[2], 1.0) * g, max(tr.anchor[3], 1.0) * g)]
        pred = predicted_size(tr.det_sizes, self.frames) if cfg.size_history > 0 else None
        if pred is not None:
            refs.append(pred)
        self._record_size(tr, ad)

        def size_factor(a) -> float:
            d2 = min(math.log(max(a[2], 1.0) / pw) ** 2 + math.log(max(a[3], 1.0) / ph) ** 2
                     for pw, ph in refs)
            return math.exp(-0.5 * d2 / cfg.size_sigma ** 2)

        top = max(s_d, s_t)
        w_d = math.exp((s_d - top) / cfg.fuse_temperature) * size_factor(ad)
        w_t = math.exp((s_t - top) / cfg.fuse_temperature) * size_factor(tr.pred_anchor)
        share = w_d / (w_d + w_t) if w_d + w_t > 0 else 1.0
        box_d = dm.box
        truncated = self._lost_white_part(tr, new, box_d)
        if truncated:
            box_d = tr.target.box_from_anchor(ad)        # two-colour guard (see _correct)
        at, bt = tr.pred_anchor, tr.pred_box
        overlap = box_iou(at, ad) >= cfg.fuse_iou
        if not overlap:
            share = 1.0 if share >= 0.5 else 0.0         # disjoint: one of them, not between
        anchor = _blend(at, ad, share)
        box = _blend(bt, box_d, share)
        if overlap and cfg.prefer_detection and not truncated and share >= 0.5:
            box = box_d                                  # agreeing and complete: its box
        base = new if share >= 0.5 else tr.target
        a = cfg.model_update * share
        q = (1 - a) * tr.target.q + a * new.q
        qw = (1 - a) * tr.target.qw + a * new.qw
        aw, ah = max(anchor[2], 1.0), max(anchor[3], 1.0)
        rel = ((box[0] - anchor[0]) / aw, (box[1] - anchor[1]) / ah, box[2] / aw, box[3] / ah)
        tr.target = replace(base, q=q / q.sum(), qw=qw / qw.sum(), relation=rel,
                            anchor=anchor)
        self._advance(tr, anchor, box)
        if share >= 0.5:
            self._measure_growth(tr)
        tr.fused_share = share
        tr.hits += 1
        tr.lost = 0
        tr.was_lost = False
        tr.coast = 0
        tr.similarity = min(1.0, max(0.0, sim))
        tr.kind, tr.color, tr.confidence = dm.det.kind, dm.det.color, dm.det.confidence

    def _ring_at(self, frame: np.ndarray, target: TargetModel,
                 anchor: Sequence[float]) -> float:
        """Ring similarity (:func:`score_box`) of ``target`` around ``anchor``."""
        cfg = self.config
        ax, ay = max(anchor[2], 1.0) / 2, max(anchor[3], 1.0) / 2
        cx, cy = anchor[0] + ax, anchor[1] + ay
        m = cfg.surround_size
        win = SearchWindow(frame, cx - m * ax - 2, cy - m * ay - 2, cx + m * ax + 3,
                           cy + m * ay + 3, _stride(ax, ay, cfg.max_samples), self._luts)
        return score_box(win, target, cx, cy, ax, ay, cfg)[1]

    def _record_size(self, tr: _Track, anchor: Sequence[float]) -> None:
        """Remember a detected anchor size for :func:`predicted_size`."""
        n = self.config.size_history
        if n > 0:
            tr.det_sizes.append((float(self.frames), float(anchor[2]), float(anchor[3])))
            del tr.det_sizes[:-n]

    def _correct(self, tr: _Track, dm: _DetModel, sim: float) -> None:
        cfg = self.config
        tracking = cfg.mode == 'detection_and_tracking'
        new = dm.target
        if new is not None:
            self._record_size(tr, new.anchor)
            a = cfg.model_update
            q = (1 - a) * tr.target.q + a * new.q
            qw = (1 - a) * tr.target.qw + a * new.qw
            box = dm.box
            rel = tr.target.relation
            if tracking and self._lost_white_part(tr, new, box):
                # Two-colour guard: this detection covers only the coloured part of a box
                # whose full extent the track knows (the detector missed the white bottom):
                # keep the measured geometry instead of shrinking the box to the orange top.
                new = replace(new, relation=rel)
                box = new.box_from_anchor(new.anchor)
            tr.target = replace(new, q=q / q.sum(), qw=qw / qw.sum())
            self._advance(tr, new.anchor, box)
            if tracking and cfg.ring_margin >= 0:
                tr.ref_ring = self._ring_at(self._frame, tr.target, new.anchor)
            self._measure_growth(tr)
        else:
            tr.box = dm.box           # no model from this box (mostly outside): keep the old
        tr.hits += 1
        tr.lost = 0
        tr.was_lost = False
        tr.coast = 0
        tr.similarity = min(1.0, max(0.0, sim))
        tr.kind, tr.color, tr.confidence = dm.det.kind, dm.det.color, dm.det.confidence

    def _payload(self, tr: _Track, source: str) -> Track:
        x, y, w, h = tr.box
        return Track(track_id=tr.track_id, box=Box(x=float(x), y=float(y), w=float(max(w, 0)),
                                                   h=float(max(h, 0))),
                     source=source, age=tr.age, hits=tr.hits,
                     similarity=float(min(1.0, max(0.0, tr.similarity))),
                     confidence=float(min(1.0, max(0.0, tr.confidence))), kind=tr.kind,
                     color=tr.color)

    def _det_only(self, dm: _DetModel) -> Track:
        """A detection that cannot start a track (outside the image): published, id 0."""
        return Track(track_id=0, box=dm.det.box, source='detection', age=1, hits=1,
                     similarity=0.0, confidence=dm.det.confidence, kind=dm.det.kind,
                     color=dm.det.color)
