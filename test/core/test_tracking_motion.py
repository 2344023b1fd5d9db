"""The mean-shift tracker's use of the perspective trend on hand-drawn sequences: the size
predicted from the detections' inverse-size trend, and the motion cue (a static sign
approached in perspective runs on its own, a vehicle ahead that keeps its place and size
does not; perspective candidates; the physical threshold on any camera and frame rate).
The drawings: ``tracking_helpers.py``.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from tracking_helpers import H, W, background, det, draw_diamond, path

from workzone_ros.core.track import (
    MultiTracker,
    TrackerConfig,
    TrackingError,
    approach_rate,
    box_iou,
)

# --- size prediction from the detections' perspective trend --------------------------------

def test_predicted_size_follows_the_inverse_size_trend_and_ignores_one_outlier():
    from workzone_ros.core.track import predicted_size
    w = lambda t: 1.0 / (1 / 20.0 - 0.0015 * t)                      # noqa: E731
    hist = [(t, w(t), 0.8 * w(t)) for t in range(0, 8)]
    hist[5] = (5, 1.6 * w(5), 1.6 * 0.8 * w(5))                      # one too-wide detection
    pw, ph = predicted_size(hist, 9)
    assert abs(pw - w(9)) < 0.3 and abs(ph - 0.8 * w(9)) < 0.3, (pw, ph, w(9))
    assert predicted_size(hist[:2], 9) is None                       # too few detections
    assert predicted_size([(1, 10, 10), (1, 12, 12), (1, 11, 11)], 5) is None


@pytest.mark.parametrize('history', [8, 0])
def test_a_track_that_took_a_too_wide_box_takes_the_next_good_detection(history):
    """The size-consistency factor of ``fuse`` also accepts the size the detections'
    1/size trend predicts (``size_history``), not only the track's last box:
    a track whose box became too wide (it took a detection merging the sign with its
    surroundings) accepts the next correct detection; with the last box as the reference
    (``size_history=0``) the wide track outvotes it."""
    bg = background(10)
    tracker = MultiTracker(TrackerConfig(size_history=history))
    for i in range(7):
        img = bg.copy()
        cx, cy, size = path(i)
        gt = draw_diamond(img, cx, cy, size)
        tracker.step(img, [det(gt)])
    tr = tracker._tracks[0]
    a, b = tr.anchor, tr.box
    k = 1.4
    tr.anchor = (a[0] - (k - 1) / 2 * a[2], a[1] - (k - 1) / 2 * a[3], k * a[2], k * a[3])
    tr.box = (b[0] - (k - 1) / 2 * b[2], b[1] - (k - 1) / 2 * b[3], k * b[2], k * b[3])
    tr.target = replace(tr.target, anchor=tr.anchor)
    img = bg.copy()
    cx, cy, size = path(7)
    gt = draw_diamond(img, cx, cy, size)
    out = tracker.step(img, [det(gt)])
    iou = box_iou(tracker._tracks[0].anchor, gt)
    assert len(out) == 1
    if history:
        assert iou > 0.88, iou
    else:
        assert iou < 0.85, iou


# --- motion cue: a vehicle ahead vs a static sign ---------------------------------------------

def _perspective(t, s0=24.0, rate=1.5e-3, direction=(0.83, -0.55), ratio=4.0):
    """A static sign approached at constant speed: ``1 / size`` falls by ``rate`` per frame
    and its offset from the focus of expansion (the image centre) is ``ratio`` sizes."""
    s = 1.0 / (1.0 / s0 - rate * t)
    return W / 2 + direction[0] * ratio * s, H / 2 + direction[1] * ratio * s, s


def test_approach_rate_is_the_fall_of_the_inverse_size():
    """:func:`approach_rate`: a static sign's inverse size falls linearly (``v / (f S)`` per
    frame), measured from its size alone or from its offset from the focus of expansion; a
    vehicle ahead at the ego speed (same size, same place) gives about 0; a short history
    gives None."""
    hist = [(float(t), *_perspective(t)[:2], _perspective(t)[2], _perspective(t)[2])
            for t in range(12)]
    assert approach_rate(hist) == pytest.approx(1.5e-3, rel=1e-6)            # size alone
    assert approach_rate(hist, (W / 2, H / 2)) == pytest.approx(1.5e-3, rel=1e-6)
    # The offset estimate: the same sign whose size the tracker did not follow.
    flat = [(t, cx, cy, 30.0, 30.0) for t, cx, cy, _, _ in hist]
    assert approach_rate(flat) == pytest.approx(0.0, abs=1e-9)
    assert approach_rate(flat, (W / 2, H / 2)) > 1e-3
    rng = np.random.default_rng(0)
    ahead = [(float(t), 320 + rng.normal(0, 1), 260 + rng.normal(0, 1),
              40 + rng.normal(0, 1), 20 + rng.normal(0, 0.5)) for t in range(15)]
    assert abs(approach_rate(ahead, (W / 2, H / 2))) < 3e-4
    assert approach_rate(hist[:5], (W / 2, H / 2)) is None                  # 4 frames


@pytest.mark.parametrize('cue', [True, False])
def test_a_target_that_keeps_its_place_and_size_is_not_published_on_its_own(cue):
    """Motion cue (``min_approach_speed``): an orange target that stays at the same image
    place and size for a second (a vehicle driving ahead) is not published while the
    detector misses it; a sign approached in perspective (growing, moving away from the
    focus of expansion) is.  Detections pass unchanged either way.  Without the cue
    (``min_approach_speed=0``) both are published (the test fails without the rule)."""
    cfg = TrackerConfig() if cue else TrackerConfig(min_approach_speed=0.0)
    assert cfg.min_approach_speed > 0 or not cue
    bg = background(2)
    for moving in (False, True):
        tracker = MultiTracker(cfg)
        sources = []
        for i in range(14):
            img = bg.copy()
            cx, cy, size = _perspective(i) if moving else (200.0, 180.0, 40.0)
            gt = draw_diamond(img, cx, cy, size)
            out = tracker.step(img, [det(gt)] if i < 10 else [])
            sources.append([t.source for t in out])
            if i >= 10 and out:
                assert box_iou((out[0].box.x, out[0].box.y, out[0].box.w, out[0].box.h),
                               gt) > 0.6
        assert all(s == ['detection'] for s in sources[:10]), sources
        alone = [s == ['tracking'] for s in sources[10:]]
        if moving or not cue:
            assert all(alone), (moving, cue, sources[10:])
        else:
            assert not any(alone), sources[10:]
            assert tracker.active_ids == [1]          # it still runs, ready for a detection


@pytest.mark.parametrize('perspective', [True, False])
def test_a_sign_near_the_camera_is_followed_as_it_grows_faster_than_the_kernels(perspective):
    """Perspective scale (``perspective_scale``): near the camera a static sign grows by
    more per frame (here 5-9 %) than the candidate kernels span (3 %); the candidates are
    centred on the size the Theil-Sen trend of the track's detected sizes predicts, so the
    tracked box keeps up while the detector misses.  Without it the box falls behind (the
    test fails without the rule)."""
    bg = background(24)
    tracker = MultiTracker(TrackerConfig(perspective_scale=perspective))
    ious = []
    for i in range(14):
        img = bg.copy()
        cx, cy, size = _perspective(i, s0=30.0, rate=1.5e-3, ratio=1.5)
        gt = draw_diamond(img, cx, cy, size)
        out = tracker.step(img, [det(gt)] if i < 7 else [])
        if i >= 7:
            b = [(t.box.x, t.box.y, t.box.w, t.box.h) for t in out if t.track_id == 1]
            ious.append(box_iou(b[0], gt) if b else 0.0)
    if perspective:
        assert min(ious) > 0.7, np.round(ious, 2)
    else:
        assert min(ious) < 0.5, np.round(ious, 2)


@pytest.mark.parametrize('from_dets', [True, False])
def test_the_motion_cue_also_reads_the_detected_sizes(from_dets):
    """Motion cue (``approach_from_detections``): a track whose own box stopped growing (it
    started too wide and lags: its history says 'same size, same place') is still
    published when its detections grew in perspective (``1 / size`` falling 1.5e-3 per
    frame): the detected sizes measure the same rate, free of the tracker's lag.  Without
    the rule the cue blocks the sign (the test fails without it)."""
    tracker = MultiTracker(TrackerConfig(approach_from_detections=from_dets))
    img = background(25)
    tracker.step(img, [det(draw_diamond(img, 300.0, 200.0, 40))])
    tr = tracker._tracks[0]
    tracker.frames = 20
    tr.det_sizes = [(float(t), _perspective(t)[2], _perspective(t)[2]) for t in range(0, 12, 2)]
    tr.motion = [(float(t), 300.0, 200.0, 40.0, 40.0) for t in range(5, 21)]
    assert tracker._approaching(tr, W, H) == from_dets
    # A vehicle ahead: its detections keep their size too, so it stays blocked either way.
    tr.det_sizes = [(float(t), 40.0, 40.0) for t in range(0, 12, 2)]
    assert not tracker._approaching(tr, W, H)


@pytest.mark.parametrize('limit', [0.5, 1.0])
def test_no_perspective_candidates_for_a_target_like_its_surroundings(limit):
    """``perspective_max_background``: the second candidate set runs only for targets that
    stand out from their surroundings (background similarity <= 0.5); on a target like
    its surroundings (a dusk sign on orange-brown ground) a bigger box costs the score
    little and the set made the box grow past the sign.  Off (1.0) it runs for both."""
    tracker = MultiTracker(TrackerConfig(perspective_max_background=limit))
    bg = background(26)
    for i in range(7):
        img = bg.copy()
        cx, cy, size = _perspective(i, s0=30.0, rate=1.5e-3, ratio=1.5)
        tracker.step(img, [det(draw_diamond(img, cx, cy, size))])
    tr = tracker._tracks[0]
    tracker.frames += 3                 # three missed frames later: the sign grew ~15 %
    assert tr.target.background_similarity < 0.5
    assert tracker._perspective_scale(tr) > 1.03          # a sign that stands out: runs
    tr.target = replace(tr.target, background_similarity=0.7)
    assert (tracker._perspective_scale(tr) == 1.0) == (limit < 0.7)


def test_motion_cue_threshold_is_physical_on_any_camera_and_frame_rate():
    """The motion cue's per-frame minimum is ``v / (f S fps)``: 0.001 / px per frame for the
    simulator's camera (640 px, 60 deg, f 554 px) at 15 fps and 10 m/s; half of it at 30 fps
    (the frame rate read from the stamps), so a sign approached at urban speed by a 30 fps
    dashcam still passes; a wider image has a longer focal length at the same field of
    view."""
    tracker = MultiTracker(TrackerConfig())
    assert tracker.approach_threshold(640) == pytest.approx(0.001, rel=0.01)
    frame = background(3)
    for i in range(5):
        tracker.step(frame, [], stamp=100.0 + i / 30.0)
    assert tracker.frame_rate == pytest.approx(30.0)
    assert tracker.approach_threshold(640) == pytest.approx(0.0005, rel=0.01)
    assert tracker.approach_threshold(1280) == pytest.approx(0.00025, rel=0.01)
    tracker.reset()
    assert tracker.frame_rate == 15.0
    with pytest.raises(TrackingError, match='camera_hfov_deg'):
        TrackerConfig(camera_hfov_deg=0.0)


def test_sign_at_30_fps_runs_on_its_own_where_a_vehicle_ahead_does_not():
    """A 30 fps stream of a sign approached at 10 m/s (the inverse size falls by
    ``10 / (554 x 1.2 x 30)`` per frame, under the 15 fps minimum) is published on its own
    once the stamps tell the frame rate; without stamps (15 fps assumed) it is not."""
    rate = 10.0 / (554.3 * 1.2 * 30.0) * 1.05
    bg = background(2)
    for stamped in (True, False):
        tracker = MultiTracker(TrackerConfig())
        sources = []
        for i in range(24):
            img = bg.copy()
            cx, cy, size = _perspective(i, s0=30.0, rate=rate)
            gt = draw_diamond(img, cx, cy, size)
            out = tracker.step(img, [det(gt)] if i < 14 else [],
                               stamp=5.0 + i / 30.0 if stamped else None)
            sources.append([t.source for t in out])
        alone = [s == ['tracking'] for s in sources[14:]]
        if stamped:
            assert all(alone), sources[14:]
        else:
            assert not any(alone), sources[14:]
