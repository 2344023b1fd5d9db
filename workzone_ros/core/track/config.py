"""Tracker parameters and the baseline rule of the mean-shift tracker."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

from workzone_ros.core.knobs import knob

__all__ = [
    'MODES', 'METHODS', 'ASSOCIATIONS', 'SCALES', 'OUR_SCALES', 'TrackingError', 'TrackerConfig',
    'seed_config',
]


MODES = ('detection_only', 'detection_and_tracking')
METHODS = ('meanshift', 'camshift')
#: How an associated detection updates a confident track: ``fuse`` (ours) weighs the tracked
#: and the detected box by their agreement with the target model and the track's scale;
#: ``overwrite`` (Lee et al.) replaces the track's box by the detection's.
ASSOCIATIONS = ('fuse', 'overwrite')
#: Kernel sizes of the candidates relative to the previous box (Lee et al., III.B).
SCALES = (1.0, 1.02, 1.05, 1.07, 1.10)
#: Ours: around the previous size, shrinking allowed.  With only-larger kernels a box can
#: never shrink, so scale noise ratchets it up whenever a detection does not reset it (on
#: development bags the tracked box ran 11-17 % wider than the sign; 1-2 % with these).
OUR_SCALES = (0.97, 1.0, 1.03)


class TrackingError(ValueError):
    """An invalid tracker configuration or input (wrong image type, bad mode, ...)."""


@dataclass(frozen=True)
class TrackerConfig:
    """Tracker parameters (the node's ``tracker`` section maps onto these one to one).

    Each field is a :func:`~workzone_ros.core.knobs.knob`: its one-line description and range
    there are the ``tracker`` node parameter's (``ros2 param describe``); below, why each
    default is what it is.

    Attributes:
        mode: ``detection_only`` (Lee et al.'s baseline) or ``detection_and_tracking``.
        method: ``meanshift`` (Lee et al.) or ``camshift`` (OpenCV peer).
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
        needs_confirmation: with a classifier reporting back (:meth:`MultiTracker.confirm`,
            the ``tracker`` node's ``signs_topic``), a track running on its own is published
            only when the classifier's latest answer on it is a sign (workzone or general)
            or it has at least two detections, and never while its latest answer is
            ``background`` (until a new detection): one false detection on a drum no longer
            becomes a long track, classified again on every frame (the rules in
            :mod:`~workzone_ros.core.track.confirmation`).  Frames with a detection are
            published as before.  Without a classifier (no ``confirm`` call yet) and with
            False: the previous rule.
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
            2012; not in Lee et al., whose plain ``sqrt(t_u / c_u)`` weights give every bin
            present in the target, including its background fringe, the same pull).
        surround_weight: candidate score = ``B(t, c) - surround_weight * B(t, ring)`` where
            ring is the band outside the candidate's shape up to ``surround_size`` times its
            box: a too-small candidate leaves sign colour in its ring (0 = Lee et al.: the
            best Bhattacharyya coefficient alone, which prefers the smallest kernel).
        surround_size: outer size of that band relative to the candidate box.
        association: ``fuse`` or ``overwrite`` (Lee et al.), see :data:`ASSOCIATIONS`.  With
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
            keeps the geometry of its last good detection.  False: the weighted blend above.
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
        max_size_ratio: a track of one detection running on its own whose anchor reaches
            this multiple of its detected size (width or height) has drifted and ends.  It
            has no measured perspective trend, so the growth guard cannot judge it (a track
            with a trend is judged by the growth guard: a sign followed for 37 frames at 2 %
            a frame rightly doubles); 0 = off.
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
    """

    mode: str = knob(
        'detection_and_tracking', 'detection_only (Lee et al. baseline) or detection_and_tracking',
        choices=MODES)
    method: str = knob(
        'meanshift', 'meanshift (Lee et al.) or camshift (OpenCV peer)', choices=METHODS)
    hue_bins: int = knob(20, 'hue bins nh of the target histogram', min=2, max=180)
    sat_bins: int = knob(20, 'saturation bins ns of the target histogram', min=2, max=256)
    scales: tuple[float, ...] = knob(
        OUR_SCALES, 'candidate kernel sizes relative to the previous box (Lee et al.: 1.0 1.02 '
        '1.05 1.07 1.10)')
    max_iterations: int = knob(10, 'mean-shift iterations per candidate', min=1, max=100)
    shift_threshold_px: float = knob(0.3, 'stop when the centre moves less', min=0.0, max=10.0)
    max_samples: int = knob(900, 'pixels sampled inside a box', min=16, max=100000)
    search_margin: float = knob(
        0.6, 'search window beyond the largest candidate (half-boxes)', min=0.0, max=5.0)
    use_velocity: bool = knob(True, 'start from the constant-velocity prediction')
    min_similarity: float = knob(
        0.75, 'Bhattacharyya coefficient below which a track is lost', min=0.0, max=1.0)
    max_lost_frames: int = knob(2, 'lost frames before a track ends', min=0, max=100)
    max_coast_frames: int = knob(
        45, 'frames without a detection before a track ends', min=0, max=10000)
    min_hits_to_coast: int = knob(
        1, 'detections before a track may run on its own', min=1, max=100)
    needs_confirmation: bool = knob(
        True, 'with a classifier reporting back: a track runs on its own only once the classifier '
        'confirmed it as a sign or after two detections, never while it rejected it (false: the '
        'previous rule)')
    min_hits_to_fuse: int = knob(
        2, 'detections before the tracked box may outvote a detection (fuse)', min=1, max=100)
    max_background_similarity: float = knob(
        0.9, 'a target this similar to its surroundings never runs on its own', min=0.0, max=1.0)
    iou_gate: float = knob(0.3, 'IoU at which a detection agrees with a track', min=0.0, max=1.0)
    agree_iou: float = knob(
        0.0, 'IoU with the tracked box at which a detection corrects the track', min=0.0, max=1.0)
    similarity_gate: float = knob(
        0.8, 'histogram similarity at which an overlapping detection agrees', min=0.0, max=1.0)
    model_update: float = knob(
        0.7, 'weight of a correcting detection in the model', min=0.0, max=1.0)
    max_box_fraction: float = knob(
        0.5, 'end when the box is wider/taller than this image fraction', min=0.0, max=1.0)
    min_inside_fraction: float = knob(
        0.6, 'end when less of the box than this is inside the image', min=0.0, max=1.0)
    min_box_px: int = knob(6, 'ignore smaller detections', min=1, max=1000)
    anchor_on_color: bool = knob(
        True, 'track the coloured part and keep the box geometry (regulatory two-colour guard)')
    duplicate_iou: float = knob(
        0.6, 'overlap at which the weaker of two tracks ends', min=0.0, max=1.0)
    duplicate_containment: float = knob(
        0.5, "share of a track's anchor inside another track's box at which the weaker ends (1 = "
        'off)', min=0.0, max=1.0)
    duplicate_area_ratio: float = knob(
        4.0, 'containment duplicates only up to this box area ratio', min=1.0, max=1000.0)
    background_weighting: bool = knob(
        True, 'corrected background-weighted histogram in the mean-shift weights')
    surround_weight: float = knob(
        0.5, 'penalty of sign colour around a candidate in the scale choice (0 = seed)', min=0.0,
        max=5.0)
    surround_size: float = knob(1.2, 'outer size of that band', min=1.0, max=3.0)
    association: str = knob(
        'fuse', 'fuse (ours) or overwrite (Lee et al.): how an associated detection updates a '
        'confident track', choices=ASSOCIATIONS)
    fuse_temperature: float = knob(
        0.05, 'score scale of the fusion weights', min=1e-3, max=1000.0)
    size_sigma: float = knob(
        0.15, 'log-size tolerance of the size-consistency factor', min=1e-3, max=10.0)
    fuse_iou: float = knob(
        0.3, 'anchor IoU at which tracked and detected boxes are averaged rather than chosen',
        min=0.0, max=1.0)
    fuse_bias: float = knob(0.1, "added to the detection's score in the fusion", min=-1.0, max=1.0)
    fuse_min_px: float = knob(
        0.0, 'smaller tracks are overwritten, not fused', min=0.0, max=1000.0)
    prefer_detection: bool = knob(
        True, 'fuse: an agreeing, complete detection gives the box (false: blend)')
    truncated_aspect: float = knob(
        0.7, 'two-colour guard: a detection is truncated only when its height/width is below this '
        "times the track's (0 = off)", min=0.0, max=1.0)
    max_coast_background_similarity: float = knob(
        0.8, 'a target this similar to its surroundings is never published on its own (1 = off)',
        min=0.0, max=1.0)
    max_coast_white_fraction: float = knob(
        0.35, 'a coloured shape this white (drum, cone bands) is never published on its own (1 = '
        'off)', min=0.0, max=1.0)
    white_bottom_share: float = knob(
        0.9, 'a shape with at least this share of its white below its colour (regulatory white '
        'bottom) is exempt from the white gate (> 1 = off)', min=0.0, max=2.0)
    min_saturation_contrast: float = knob(
        0.2, 'sign-likeness: a target less saturated than this above its surroundings is never '
        'published on its own (-1 = off)', min=-1.0, max=1.0)
    saturation_reference: float = knob(
        50.0, "sign-likeness: percentile of the surroundings' saturation the face's upper decile "
        'is compared with (90 = the previous rule)', min=0.0, max=100.0)
    min_chroma_contrast: float = knob(
        1.5, 'sign-likeness: a target whose chroma (S*V) upper decile is less than this times '
        'that of its surroundings is never published on its own (0 = off)', min=0.0, max=100.0)
    chroma_reference: float = knob(
        50.0, "sign-likeness: percentile of the surroundings' chroma the face's upper decile is "
        'compared with (90 = the previous rule)', min=0.0, max=100.0)
    anchor_kind_ratio: float = knob(
        1.5, "two-colour guard: a detection is extended only when its coloured anchor's "
        "height/width is at most this times the track's (0 = off)", min=0.0, max=10.0)
    growth_guard_needs_trend: bool = knob(
        True, 'the growth guard acts only once two detections measured the trend')
    max_ring_similarity: float = knob(
        0.6, 'drift guard: surroundings this similar to the target lose a coasting track (1 = '
        'off)', min=0.0, max=1.0)
    ring_margin: float = knob(
        0.1, 'drift guard: the ring must also exceed the ring at the last detection by this (< 0 '
        '= off)', min=-1.0, max=1.0)
    ring_margin_min_hits: int = knob(
        3, 'ring_margin applies to tracks with this many detections', min=0, max=1000)
    max_growth_excess: float = knob(
        0.3, "drift guard: growth beyond the detections' perspective trend that ends a coasting "
        'track (0 = off)', min=0.0, max=10.0)
    max_size_ratio: float = knob(
        2.0, 'drift guard: a coasting track of one detection whose box reaches this multiple of '
        'its detected size ends (0 = off)', min=0.0, max=100.0)
    size_history: int = knob(
        8, 'fuse: detected sizes whose 1/size trend predicts the size the detection is compared '
        'with (0 = last size)', min=0, max=100)
    min_hits_after_loss: int = knob(
        2, 'a track that lost its target since its last detection is published on its own again '
        'only with this many detections (1 = always)', min=0, max=1000)
    min_approach_speed: float = knob(
        10.0, 'motion cue: a track that the camera approaches slower than this (m/s, from the '
        'fall of its inverse size or offset from the focus of expansion) is not published on its '
        'own (a vehicle ahead; 0 = off)', min=0.0, max=100.0)
    sign_size_m: float = knob(1.2, 'motion cue: nominal sign face size (m)', min=0.05, max=10.0)
    camera_hfov_deg: float = knob(
        60.0, "motion cue: the camera's horizontal field of view (deg) for its focal length",
        min=1.0, max=179.0)
    frame_rate: float = knob(
        15.0, 'motion cue: frames per second until the image stamps tell', min=0.1, max=1000.0)
    motion_window: int = knob(15, 'motion cue: frames of track history used', min=2, max=1000)
    motion_min_frames: int = knob(
        8, 'motion cue: judged only on a history spanning at least this many frames', min=2,
        max=1000)
    focus_of_expansion: tuple[float, float] = knob(
        (0.5, 0.5), 'motion cue: focus of expansion as image fractions [x, y] (straight ahead)')
    radial_min_offset: float = knob(
        1.5, 'motion cue: the offset estimate counts when the offset from the focus is at least '
        'this many box sizes', min=0.0, max=100.0)
    approach_from_detections: bool = knob(
        True, "motion cue: also the trend of the track's detected sizes (free of the tracker's "
        'own scale lag)')
    perspective_scale: bool = knob(
        True, "candidates also around the size the Theil-Sen trend of the track's detected sizes "
        'predicts (static-sign perspective)')
    perspective_min: float = knob(
        0.9, 'perspective scale: smallest predicted / current size used', min=0.1, max=1.0)
    perspective_max: float = knob(
        1.3, 'perspective scale: largest predicted / current size used', min=1.0, max=10.0)
    perspective_min_detections: int = knob(
        3, 'perspective scale: detections the trend needs (and it extrapolates no further than '
        'they span)', min=3, max=1000)
    perspective_max_background: float = knob(
        0.5, 'perspective scale: only for targets whose background similarity is at most this (1 '
        '= always)', min=0.0, max=1.0)

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
        if 0 < self.max_size_ratio <= 1:
            raise TrackingError(f'max_size_ratio must be 0 (off) or above 1, got '
                                f'{self.max_size_ratio}')
        if len(self.focus_of_expansion) != 2:
            raise TrackingError('focus_of_expansion must be (x, y) image fractions')


def seed_config(config: Optional['TrackerConfig'] = None) -> 'TrackerConfig':
    """Lee et al.'s exact rule on top of ``config``: plain ``sqrt(t_u / c_u)`` weights (eq. 3),
    the best Bhattacharyya coefficient alone picks the kernel size, mean-shift starts at
    the previous centre, an associated detection overwrites the track and no drift guards,
    publication gates or containment duplicates (``min_hits_to_coast`` = 2, as before).
    The regulatory two-colour guard stays (``anchor_on_color``) as it was committed
    (``truncated_aspect=0``), so the baseline does not change."""
    return replace(config or TrackerConfig(), scales=SCALES, background_weighting=False,
                   surround_weight=0.0,
                   use_velocity=False, association='overwrite', max_ring_similarity=1.0,
                   max_growth_excess=0.0, max_size_ratio=0.0,
                   max_coast_background_similarity=1.0,
                   max_coast_white_fraction=1.0, min_saturation_contrast=-1.0,
                   min_chroma_contrast=0.0,
                   truncated_aspect=0.0, anchor_kind_ratio=0.0,
                   min_hits_to_coast=2, min_hits_to_fuse=2, duplicate_containment=1.0,
                   ring_margin=-1.0, size_history=0, min_hits_after_loss=1,
                   min_approach_speed=0.0, perspective_scale=False)
