"""The mean-shift tracker's publication gates and guards on hand-drawn sequences (beyond
Lee et al.'s seed): saturation and chroma contrast against tinted patches, dusk skies,
sunlit trees and vivid vegetation; the growth guard and coasting; duplicate tracks on a
two-colour sign's orange top; the two-colour guard on whole-face anchors; the white gate
against drum bands; the ring drift guard among a stand's flags; tracks that lost their
lock.  The drawings: ``tracking_helpers.py``.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from tracking_helpers import (
    BLACK,
    ORANGE,
    SLOW,
    WHITE,
    H,
    W,
    _banded,
    background,
    center,
    det,
    draw_diamond,
    draw_regulatory,
    path,
)

from workzone_ros.core.track import MultiTracker, TrackerConfig, box_iou, build_target

# --- publication gates, growth guard, duplicates (beyond the seed) --------------------------

def dusk_background(seed: int = 20) -> np.ndarray:
    """A textured backdrop of many hues, all about as saturated as a dusk sky (S ~ 120)."""
    rng = np.random.default_rng(seed)
    small = rng.integers(40, 200, (H // 8, W // 8, 3)).astype(np.uint8)
    bg = cv2.GaussianBlur(cv2.resize(small, (W, H)), (0, 0), 3)
    hsv = cv2.cvtColor(bg, cv2.COLOR_BGR2HSV)
    hsv[..., 1] = np.clip(rng.normal(115, 6, hsv.shape[:2]), 0, 255).astype(np.uint8)
    hsv[..., 2] = np.clip(hsv[..., 2], 90, 200)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)


def tinted_patch(img, box):
    """Paint an orange patch as saturated as the backdrop (a tinted-sky false alarm)."""
    x, y, w, h = (int(v) for v in box)
    hsv = np.full((h, w, 3), (12, 118, 160), np.uint8)
    img[y:y + h, x:x + w] = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)


def test_saturation_contrast_tells_a_sign_face_from_a_tinted_patch():
    from workzone_ros.core.track import saturation_contrast
    img = dusk_background()
    gt = draw_diamond(img, 320.0, 240.0, 40)
    tinted_patch(img, (100.0, 100.0, 40.0, 40.0))
    sign = build_target(img, gt, TrackerConfig())
    patch = build_target(img, (100.0, 100.0, 40.0, 40.0), TrackerConfig())
    assert sign.saturation_contrast >= 0.3, sign.saturation_contrast
    assert patch.colored                                 # the detector's kind of false alarm
    assert abs(patch.saturation_contrast) < 0.1, patch.saturation_contrast
    # the function itself, on a window of the frame: same number as the model's
    from workzone_ros.core.track.meanshift import SearchWindow, _luts
    win = SearchWindow(img, 260, 180, 381, 301, 1, _luts(20, 20))
    cx, cy = center(gt)
    assert saturation_contrast(win, cx, cy, 20.0, 20.0) >= 0.3


@pytest.mark.parametrize('gate', [True, False])
def test_a_tinted_patch_never_runs_on_its_own_but_a_sign_on_it_does(gate):
    """Sign-likeness gate: a false detection on a patch of tinted sky (as saturated as its
    surroundings) is not published without a detection; a sign face on the same backdrop
    is, after a single detection.  Without the gate the patch would be (the test can fail)."""
    cfg = TrackerConfig(max_coast_background_similarity=1.0, min_chroma_contrast=0.0,
                        min_saturation_contrast=0.2 if gate else -1.0)
    tracker = MultiTracker(cfg)
    bg = dusk_background(21)
    patch = (120.0, 90.0, 30.0, 30.0)
    alone = {'sign': 0, 'patch': 0}
    for i in range(8):
        img = bg.copy()
        cx, cy, size = path(i)
        gt = draw_diamond(img, cx, cy, 0.5 * size)
        tinted_patch(img, patch)
        out = tracker.step(img, [det(gt), det(patch)] if i == 0 else [])
        for t in out:
            if t.source == 'tracking':
                b = (t.box.x, t.box.y, t.box.w, t.box.h)
                alone['sign' if box_iou(b, gt) > 0.5 else 'patch'] += 1
    assert alone['sign'] == 7
    assert (alone['patch'] == 0) == gate, alone


@pytest.mark.parametrize('needs_trend', [True, False])
def test_a_single_detection_is_followed_while_the_sign_grows(needs_trend):
    """A track started by one detection runs on its own along a perspective path (3 % per
    frame) within 2 px; the growth guard waits for a measured trend (without that rule the
    real growth counts as drift and the track ends)."""
    bg = background(22)
    tracker = MultiTracker(TrackerConfig(growth_guard_needs_trend=needs_trend, **SLOW))
    errors = []
    for i in range(16):
        img = bg.copy()
        cx, cy, size = 300 + 2.5 * i, 220 - 0.8 * i, 30 * 1.03 ** i
        draw_diamond(img, cx, cy, size)
        gt = (cx - size / 2, cy - size / 2, size, size)
        out = tracker.step(img, [det(gt)] if i == 0 else [])
        if i and out:
            assert [t.source for t in out] == ['tracking'] and out[0].track_id == 1
            ex, ey = center(out[0].box)
            errors.append(np.hypot(ex - cx, ey - cy))
    if needs_trend:
        assert len(errors) == 15 and max(errors) <= 2.0, np.round(errors, 2)
    else:
        assert len(errors) < 15


def test_coasting_through_two_missed_frames_on_a_growing_path_stays_within_2px():
    bg = background(23)
    tracker = MultiTracker(TrackerConfig(**SLOW))
    for i in range(16):
        img = bg.copy()
        cx, cy, size = path(i)
        gt = draw_diamond(img, cx, cy, size)
        missed = i in (10, 11)
        out = tracker.step(img, [] if missed else [det(gt)])
        assert [t.track_id for t in out] == [1]
        assert out[0].source == ('tracking' if missed else 'detection')
        if missed:
            ex, ey = center(out[0].box)
            assert np.hypot(ex - cx, ey - cy) <= 2.0, (i, center(out[0].box), (cx, cy))
            assert abs(out[0].box.w / size - 1) <= 0.08


@pytest.mark.parametrize('containment', [0.5, 1.0])
def test_no_duplicate_track_on_the_orange_top_of_a_two_colour_sign(containment):
    """The detector reports a regulatory sign twice (the whole box and, separately, its
    orange top): the orange-top track is a duplicate of the sign's track and ends at once,
    so only the sign's track runs on its own afterwards (without the containment rule the
    orange top keeps a second track: the test can fail)."""
    bg = background(24)
    tracker = MultiTracker(TrackerConfig(duplicate_containment=containment))
    for i in range(10):
        img = bg.copy()
        gt = draw_regulatory(img, 330 + 2 * i, 220 - 0.6 * i, 40 * 1.02 ** i)
        top = (gt[0] + 1, gt[1] + 1, gt[2] - 2, 0.3 * gt[3])
        dets = [det(gt, kind='regulatory')] if i < 3 else []
        if i == 3:
            dets = [det(gt, kind='regulatory'), det(top, kind='regulatory')]
        out = tracker.step(img, dets)
        if i > 3:
            ids = sorted(t.track_id for t in out)
            if containment < 1.0:
                assert ids == [1], (i, out)
                b = out[0].box
                assert box_iou((b.x, b.y, b.w, b.h), gt) > 0.8
            else:
                assert ids == [1, 2], (i, out)
    assert tracker.active_ids == ([1] if containment < 1.0 else [1, 2])


def test_seed_config_keeps_the_seed_rule():
    from workzone_ros.core.track import SCALES, seed_config
    s = seed_config()
    assert s.scales == SCALES and s.association == 'overwrite' and not s.use_velocity
    assert s.min_hits_to_coast == 2 and s.min_saturation_contrast == -1.0
    assert s.min_chroma_contrast == 0.0 and s.min_hits_after_loss == 1
    assert s.duplicate_containment == 1.0 and s.max_coast_background_similarity == 1.0
    assert s.ring_margin < 0 and s.size_history == 0
    ours = TrackerConfig()
    assert ours.min_hits_to_coast == 1 and ours.min_saturation_contrast > 0
    assert ours.duplicate_containment < 1.0 and ours.growth_guard_needs_trend


@pytest.mark.parametrize('min_hits', [1, 2])
def test_a_one_detection_track_does_not_outvote_the_next_detection(min_hits):
    """``min_hits_to_fuse``: a track started by one detection is overwritten by the next
    detection even when it disagrees (a fragment of the sign); with ``min_hits_to_fuse=1``
    the same track outvotes the fragment and keeps its tracked box (the test can fail)."""
    bg = background(25)
    tracker = MultiTracker(TrackerConfig(min_hits_to_fuse=min_hits))
    img = bg.copy()
    gt = draw_diamond(img, *path(0))
    tracker.step(img, [det(gt)])
    img = bg.copy()
    gt = draw_diamond(img, *path(1))
    frag = (gt[0], gt[1] + 0.2 * gt[3], 0.55 * gt[2], 0.6 * gt[3])
    out = tracker.step(img, [det(frag)])
    assert len(out) == 1 and out[0].source == 'detection'
    b = (out[0].box.x, out[0].box.y, out[0].box.w, out[0].box.h)
    if min_hits == 2:
        assert box_iou(b, frag) > 0.99, (b, frag)
    else:
        assert box_iou(b, gt) > 0.7 and box_iou(b, frag) < 0.6, (b, gt, frag)


def _tinted_regulatory(img, cx, cy, width):
    """A regulatory sign whose white part is tinted orange (dim light): the whole face has
    the dominant hue, so its coloured anchor is the whole box."""
    n = int(round(width))
    m = int(round(1.5 * width))
    x0, y0 = int(round(cx - n / 2)), int(round(cy - m / 2))
    img[y0:y0 + m, x0:x0 + n] = (60, 140, 230)
    img[y0:y0 + int(0.3 * m), x0:x0 + n] = ORANGE
    cv2.putText(img, '45', (x0 + n // 5, y0 + int(0.8 * m)), cv2.FONT_HERSHEY_SIMPLEX,
                n / 40, BLACK, 2)
    return (float(x0), float(y0), float(n), float(m))


@pytest.mark.parametrize('aspect', [0.7, 0.0])
def test_a_complete_detection_whose_anchor_is_the_whole_face_is_not_extended(aspect):
    """Two-colour guard: a track learnt an orange-band anchor and the white part below it;
    then the whole face takes the dominant hue (dim light) so a complete detection has no
    box below its anchor.  Its box is short for the relation but not for the sign (same
    height / width as the track's box): it is kept, not extended by the relation
    (``truncated_aspect``; with 0, the previous rule, it tripled the box: the test can
    fail).  The detection corrects the track directly (as when the tracked box is lost, or
    with Lee et al.'s ``overwrite``), not through the fusion."""
    bg = background(26)
    tracker = MultiTracker(TrackerConfig(truncated_aspect=aspect, association='overwrite',
                                         anchor_kind_ratio=0.0))
    for i, b, gt, iou in _tinted_face_run(tracker, bg):
        if aspect > 0:
            assert iou > 0.9, (i, b, gt)
        else:
            assert iou < 0.6, (i, b, gt)


def _tinted_face_run(tracker, bg):
    """A regulatory sign approaching for 8 frames, its whole face orange-tinted from frame 4,
    detected every frame; yields (frame, box, truth, IoU) for the tinted frames."""
    for i in range(8):
        img = bg.copy()
        cx, cy, w = 330 + 2 * i, 220 - 0.6 * i, 40 * 1.02 ** i
        gt = draw_regulatory(img, cx, cy, w) if i < 4 else _tinted_regulatory(img, cx, cy, w)
        out = tracker.step(img, [det(gt, kind='regulatory')])
        assert [t.track_id for t in out] == [1]
        if i >= 4:
            b = out[0].box
            yield i, b, gt, box_iou((b.x, b.y, b.w, b.h), gt)


@pytest.mark.parametrize('share', [0.9, 2.0])
def test_a_white_bottom_runs_on_its_own_but_drum_bands_do_not(share):
    """White gate: a regulatory face whose coloured shape covers its white bottom (orange
    side borders) is very white, like a drum's bands; its white lies below the colour
    (``white_bottom_share``) so it may run on its own, a drum's alternating bands may not
    (with the exemption off, the sign is not published on its own either: can fail)."""
    bg = background(27)
    tracker = MultiTracker(TrackerConfig(white_bottom_share=share))
    alone = {'sign': 0, 'drum': 0}
    for i in range(6):
        img = bg.copy()
        sign = _banded(img, (300 + 2 * i, 180, 36, 54), [ORANGE, ORANGE, WHITE, WHITE, WHITE,
                                                        WHITE])
        x, y, w, h = (int(v) for v in sign)
        img[y:y + h, x:x + 4] = ORANGE                      # orange side borders
        img[y:y + h, x + w - 4:x + w] = ORANGE
        cv2.putText(img, '45', (x + 8, y + 45), cv2.FONT_HERSHEY_SIMPLEX, 0.6, BLACK, 2)
        drum = _banded(img, (150 + 2 * i, 250, 30, 45), [ORANGE, WHITE, ORANGE, WHITE,
                                                        ORANGE])
        for t in tracker.step(img, [det(sign), det(drum)] if i < 2 else []):
            if t.source == 'tracking':
                b = (t.box.x, t.box.y, t.box.w, t.box.h)
                alone['sign' if box_iou(b, sign) > 0.5 else 'drum'] += 1
    assert alone['drum'] == 0, alone
    assert (alone['sign'] == 4) == (share <= 1.0), alone


@pytest.mark.parametrize('ratio', [1.5, 0.0])
def test_a_whole_face_anchor_is_not_extended_by_the_orange_band_relation(ratio):
    """Two-colour guard, independent of the box aspect check (``truncated_aspect`` off): the
    track learnt the orange band as its anchor; then the whole face takes the dominant hue,
    so the detection's anchor is much taller for its width than the band.  It is another
    part of the sign, the band's relation does not apply to it and the complete detection
    is kept (``anchor_kind_ratio``); with 0 (off) the relation triples the box (can fail)."""
    bg = background(28)
    tracker = MultiTracker(TrackerConfig(anchor_kind_ratio=ratio, truncated_aspect=0.0,
                                         association='overwrite'))
    for i, b, gt, iou in _tinted_face_run(tracker, bg):
        if ratio > 0:
            assert iou > 0.9, (i, b, gt)
        else:
            assert iou < 0.6, (i, b, gt)


def _flags(img, box, width=0.15, col=(0, 110, 245)):
    """Sign-coloured flags left and right of a sign's box (a stand's flags)."""
    x, y, w, h = box
    for fx in (x - width * w, x + w):
        cv2.rectangle(img, (int(fx), int(y + 0.2 * h)), (int(fx + width * w), int(y + 0.8 * h)),
                      col, -1)


@pytest.mark.parametrize('margin', [0.1, -1.0])
def test_a_sign_among_its_flags_runs_on_its_own_but_a_drift_into_orange_ends(margin):
    """Ring drift guard relative to the ring at the detections (``ring_margin``): a sign
    whose stand's flags make its ring high while it is detected keeps running on its own
    through detector misses (the absolute threshold alone loses it); a track whose ring
    jumps when an orange region surrounds it (a vehicle) still ends.  (Without the
    perspective candidates, which with the ablation's absolute threshold keep one more
    frame by a box that takes the flags in: the test isolates the ring guard.)"""
    bg = background(10)
    for scene in ('flags', 'vehicle'):
        tracker = MultiTracker(TrackerConfig(ring_margin=margin, perspective_scale=False,
                                             **SLOW))
        sources = []
        for i in range(9):
            img = bg.copy()
            cx, cy, size = path(i)
            box = (cx - size / 2, cy - size / 2, size, size)
            if scene == 'flags':
                _flags(img, box)
            elif i >= 5:
                cv2.rectangle(img, (int(cx - 1.5 * size), int(cy - 1.5 * size)),
                              (int(cx + 1.5 * size), int(cy + 1.5 * size)), (0, 110, 245), -1)
            gt = draw_diamond(img, cx, cy, size)
            out = tracker.step(img, [det(gt)] if i < 5 else [])
            sources.append(''.join(t.source[0] for t in out))
        assert sources[:5] == ['d'] * 5
        if scene == 'flags' and margin >= 0:
            assert sources[5:] == ['t'] * 4, sources
        else:
            assert sources[5:] == [''] * 4, (scene, sources)


def sunny_background(seed: int = 0) -> np.ndarray:
    """Sunlit trees: dark green, fully saturated (HSV saturation is high on dark pixels)."""
    rng = np.random.default_rng(seed)
    hsv = np.zeros((H, W, 3), np.uint8)
    hsv[..., 0] = 55
    hsv[..., 1] = np.clip(rng.normal(180, 40, (H, W)), 0, 255).astype(np.uint8)
    hsv[..., 2] = np.clip(rng.normal(45, 10, (H, W)), 0, 255).astype(np.uint8)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)


def stand_flags(img, gt):
    """Two fluorescent orange flags on top of the sign's stand (in its surroundings)."""
    x, y, w, h = (int(round(v)) for v in gt)
    f = max(3, w // 3)
    for fx in (x - f // 2, x + w - f // 2):
        img[max(0, y - f - 2):y - 2, fx:fx + f] = (0, 110, 255)


def test_sign_in_front_of_sunlit_trees_with_flags_runs_on_its_own():
    """Sunny paper_c: the surroundings' upper decile of saturation is the flags' and the
    dark trees' full saturation, as high as the face's, so the previous rule (upper decile
    against upper decile, ``saturation_reference=90``) never let the sign run on its own;
    against the surroundings' median it does, and its chroma stands out (the test fails
    with the previous rule)."""
    from workzone_ros.core.track import chroma_contrast
    results = {}
    for ref in (90.0, 50.0):
        cfg = TrackerConfig(saturation_reference=ref, max_coast_background_similarity=1.0)
        tracker = MultiTracker(cfg)
        bg = sunny_background(3)
        alone = 0
        for i in range(6):
            img = bg.copy()
            cx, cy, size = path(i)
            gt = draw_diamond(img, cx, cy, 0.5 * size)
            stand_flags(img, gt)
            out = tracker.step(img, [det(gt)] if i == 0 else [])
            alone += sum(t.source == 'tracking' and box_iou(
                (t.box.x, t.box.y, t.box.w, t.box.h), gt) > 0.5 for t in out)
            if i == 0:
                target = tracker._tracks[0].target
        results[ref] = alone
        assert target.chroma_contrast >= 1.5, target.chroma_contrast
    assert results[90.0] == 0 and results[50.0] == 5, results
    # the function on its own: a dark saturated patch of the same trees is not colourful
    from workzone_ros.core.track.meanshift import SearchWindow, _luts
    img = sunny_background(4)
    win = SearchWindow(img, 260, 180, 381, 301, 1, _luts(20, 20))
    assert chroma_contrast(win, 320.0, 240.0, 20.0, 20.0) < 1.3


def test_a_dim_saturated_patch_in_bright_surroundings_never_runs_on_its_own():
    """Chroma gate: a dark orange patch (fully saturated, dim) on a bright, moderately
    saturated backdrop passes the saturation test against the median but is not more
    colourful than its surroundings; without ``min_chroma_contrast`` it would run on its
    own (the test can fail)."""
    bg = dusk_background(5)
    patch = (300.0, 220.0, 30.0, 30.0)
    for gate in (True, False):
        cfg = TrackerConfig(max_coast_background_similarity=1.0,
                            min_chroma_contrast=1.5 if gate else 0.0)
        tracker = MultiTracker(cfg)
        alone = 0
        for i in range(5):
            img = bg.copy()
            img[220:250, 300:330] = cv2.cvtColor(np.full((30, 30, 3), (12, 255, 70), np.uint8),
                                                 cv2.COLOR_HSV2BGR)
            out = tracker.step(img, [det(patch)] if i == 0 else [])
            alone += sum(t.source == 'tracking' for t in out)
        t = tracker._tracks[0].target if tracker._tracks else None
        assert t is not None and t.saturation_contrast >= 0.2, t
        assert (alone == 0) == gate, (gate, alone, t.chroma_contrast)


@pytest.mark.parametrize('min_hits', [1, 2])
def test_a_one_detection_track_that_lost_its_lock_waits_for_a_detection(min_hits):
    """``min_hits_after_loss``: a track started by a single detection that lost its target
    (similarity below ``min_similarity``) and regained a lock without a detection is not
    published on its own until a detection confirms it (2); the previous rule (1) publishes
    it again (the test fails without the rule).  Tracks detected more often are published
    after an occlusion as before (test_occluded_frame_does_not_kill_the_track)."""
    bg = background(1)
    tracker = MultiTracker(TrackerConfig(min_hits_after_loss=min_hits, **SLOW))
    alone = []
    for i in range(8):
        img = bg.copy()
        cx, cy, size = path(i)
        gt = draw_diamond(img, cx, cy, size)
        if i == 3:      # hidden for one frame: the track is lost
            x, y, w, h = (int(v) for v in gt)
            cv2.rectangle(img, (x - 15, y - 15), (x + w + 15, y + h + 15), (90, 90, 95), -1)
        out = tracker.step(img, [det(gt)] if i == 0 else [])
        alone.append(sum(t.source == 'tracking' for t in out))
        if i == 3:
            assert out == [] and tracker.active_ids == [1]
    assert alone[1:3] == [1, 1]                      # before the loss: runs on its own
    assert alone[4:] == ([1] * 4 if min_hits == 1 else [0] * 4), alone
    assert tracker.active_ids == [1]                 # still running, ready for a detection
    img = bg.copy()
    gt = draw_diamond(img, *path(8))
    tracker.step(img, [det(gt)])                     # a detection confirms it
    img = bg.copy()
    draw_diamond(img, *path(9))
    assert [t.source for t in tracker.step(img, [])] == ['tracking']


def _pale_with_vegetation(seed: int = 27) -> np.ndarray:
    """A pale, low-chroma backdrop (S ~ 15) with blocks of vivid green vegetation: about a
    fifth of it is more colourful than a sign face in flat light."""
    rng = np.random.default_rng(seed)
    hsv = np.zeros((H, W, 3), np.uint8)
    hsv[..., 0] = 100
    hsv[..., 1] = np.clip(rng.normal(15, 4, (H, W)), 0, 255).astype(np.uint8)
    hsv[..., 2] = np.clip(rng.normal(190, 6, (H, W)), 0, 255).astype(np.uint8)
    for y in range(0, H, 40):
        for x in range(20 * ((y // 40) % 2), W, 60):
            hsv[y:y + 18, x:x + 18] = (60, 240, 235)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)


@pytest.mark.parametrize('reference', [50.0, 90.0])
def test_a_sign_among_vivid_vegetation_passes_the_chroma_gate(reference):
    """``chroma_reference``: the chroma gate compares the face with the median of its
    surroundings, not their most colourful tenth, which a fifth of sunlit vegetation (or a
    stand's flags, an orange-brown facade) sets (tuning bags: a sunny sign on vivid green
    and a rain sign beside a brown facade, 12 detector misses).  The face is published on
    its own after one detection; with the upper decile (90, the previous rule) it is not
    (the test fails without the rule).  The dim-patch test keeps the gate's purpose."""
    tracker = MultiTracker(TrackerConfig(chroma_reference=reference, **SLOW))
    bg = _pale_with_vegetation()
    alone = 0
    for i in range(8):
        img = bg.copy()
        cx, cy, size = path(i)
        gt = draw_diamond(img, cx, cy, size)
        out = tracker.step(img, [det(gt)] if i == 0 else [])
        alone += sum(t.source == 'tracking' and box_iou(
            (t.box.x, t.box.y, t.box.w, t.box.h), gt) > 0.5 for t in out)
    c = tracker._tracks[0].target.chroma_contrast
    assert alone == (7 if reference == 50.0 else 0), (alone, c)
