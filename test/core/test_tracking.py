"""Tests of the kernel-based mean-shift tracker (Lee et al., III.B) on hand-drawn sequences:
the target model, following a sign (occlusions, neighbours, featureless regions, the end of
a track), the modes, the two-colour box and the CamShift peer, the association rule, and
the open-background rows of ``core.profiles``.  The drawings: ``tracking_helpers.py``; the
publication gates and guards: ``test_tracking_guards.py``; the size prediction and the
motion cue: ``test_tracking_motion.py``.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from tracking_helpers import (
    SLOW,
    H,
    W,
    background,
    center,
    det,
    draw_diamond,
    draw_regulatory,
    path,
)

from workzone_ros.core.profiles import open_background_rows
from workzone_ros.core.track import (
    MultiTracker,
    TrackerConfig,
    TrackingError,
    bhattacharyya,
    box_iou,
    build_target,
    shape_mask,
)

# --- the target model -----------------------------------------------------------------------

def test_shape_mask_is_the_diamond_hull_and_none_on_grey():
    img = background()
    box = draw_diamond(img, 200.0, 200.0, 60)
    x, y, w, h = (int(v) for v in box)
    hsv = cv2.cvtColor(img[y:y + h, x:x + w], cv2.COLOR_BGR2HSV)
    m = shape_mask(hsv)
    assert m is not None
    assert m[h // 2, w // 2] == 1                 # the black legend is inside the shape
    assert m[2, 2] == 0 and m[-3, -3] == 0        # the box corners are background
    assert 0.35 < m.mean() < 0.6                  # a diamond fills half its box
    grey = np.full((40, 40, 3), 128, np.uint8)
    assert shape_mask(cv2.cvtColor(grey, cv2.COLOR_BGR2HSV)) is None


def test_target_histogram_is_normalised_and_distinct_from_background():
    img = background()
    box = draw_diamond(img, 200.0, 200.0, 60)
    t = build_target(img, box, TrackerConfig())
    assert t is not None and t.colored
    assert t.q.shape == (400,) and abs(t.q.sum() - 1) < 1e-9
    assert bhattacharyya(t.q, t.q) == pytest.approx(1.0)
    assert t.background_similarity < 0.5
    assert box_iou(t.box_from_anchor(t.anchor), box) > 0.99


# --- following a sign -----------------------------------------------------------------------

def test_sign_moving_and_growing_is_followed_within_2px():
    bg = background()
    tracker = MultiTracker(TrackerConfig(**SLOW))
    errors, size_err = [], []
    for i in range(40):
        img = bg.copy()
        cx, cy, size = path(i)
        gt = draw_diamond(img, cx, cy, size)
        out = tracker.step(img, [det(gt)] if i < 3 else [])
        assert len(out) == 1
        t = out[0]
        assert t.track_id == 1
        assert t.source == ('detection' if i < 3 else 'tracking')
        if i >= 3:
            ex, ey = center(t.box)
            errors.append(np.hypot(ex - cx, ey - cy))
            size_err.append(abs(t.box.w / size - 1))
            assert t.similarity >= 0.75
            assert t.age == i + 1 and t.hits == 3
    assert max(errors) <= 2.0, f'centre errors {np.round(errors, 2)}'
    assert max(size_err) <= 0.12, f'size errors {np.round(size_err, 3)}'


def test_occluded_frame_does_not_kill_the_track():
    bg = background(1)
    tracker = MultiTracker(TrackerConfig(**SLOW))
    for i in range(20):
        img = bg.copy()
        cx, cy, size = path(i)
        gt = draw_diamond(img, cx, cy, size)
        if i == 9:      # a truck passes in front: the whole sign is hidden for one frame
            x, y, w, h = (int(v) for v in gt)
            cv2.rectangle(img, (x - 15, y - 15), (x + w + 15, y + h + 15), (90, 90, 95), -1)
        out = tracker.step(img, [det(gt)] if i < 3 else [])
        if i == 9:
            assert out == [] and tracker.active_ids == [1]
            continue
        assert [t.track_id for t in out] == [1]
        ex, ey = center(out[0].box)
        assert np.hypot(ex - cx, ey - cy) <= 2.0, f'frame {i}'


def test_two_signs_side_by_side_keep_their_ids():
    bg = background(2)
    rng = np.random.default_rng(3)
    tracker = MultiTracker(TrackerConfig(**SLOW))
    ids = {}
    for i in range(30):
        img = bg.copy()
        size = 44 * 1.01 ** i
        left = draw_diamond(img, 250 + 1.5 * i, 220 - 0.5 * i, size, 'ROAD')
        right = draw_diamond(img, 250 + 1.5 * i + size + 8, 220 - 0.5 * i, size, 'WORK')
        dets = []
        # the detector sees both signs in the first frames, then only now and then, jittered
        for gt in (left, right):
            if i < 3 or rng.random() < 0.3:
                j = rng.normal(0, 1.5, 4)
                dets.append(det((gt[0] + j[0], gt[1] + j[1], gt[2] + j[2], gt[3] + j[2])))
        out = tracker.step(img, dets[::-1] if i % 2 else dets)
        assert len(out) == 2, f'frame {i}: {out}'
        for t in out:
            side = 'left' if box_iou((t.box.x, t.box.y, t.box.w, t.box.h), left) > \
                box_iou((t.box.x, t.box.y, t.box.w, t.box.h), right) else 'right'
            assert ids.setdefault(side, t.track_id) == t.track_id, f'frame {i}: {side}'
            gt = left if side == 'left' else right
            assert box_iou((t.box.x, t.box.y, t.box.w, t.box.h), gt) > 0.5
    assert ids['left'] != ids['right']


def test_track_on_a_featureless_region_ends():
    bg = background(4)
    cfg = TrackerConfig()
    tracker = MultiTracker(cfg)
    for i in range(5):                      # a tracked sign ...
        img = bg.copy()
        gt = draw_diamond(img, *path(i))
        assert len(tracker.step(img, [det(gt)] if i < 3 else [])) == 1
    wall = np.full_like(bg, 150)            # ... then only a featureless grey wall
    ended_after = None
    for k in range(cfg.max_lost_frames + 3):
        out = tracker.step(wall, [])
        assert out == []
        if not tracker.active_ids:
            ended_after = k + 1
            break
    assert ended_after is not None and ended_after <= cfg.max_lost_frames + 1


def test_detection_on_a_featureless_region_never_runs_on_its_own():
    grey = np.full((H, W, 3), 128, np.uint8)
    cv2.randn(grey, 128, 3)
    tracker = MultiTracker(TrackerConfig())
    box = (300.0, 200.0, 50.0, 50.0)
    for i in range(6):
        out = tracker.step(grey, [det(box)] if i < 3 else [])
        assert all(t.source == 'detection' for t in out)
        if i >= 3:
            assert out == []


def test_track_ends_when_the_sign_leaves_the_image():
    bg = background(5)
    tracker = MultiTracker(TrackerConfig())
    seen_after = 0
    for i in range(40):
        img = bg.copy()
        gt = draw_diamond(img, 520 + 8 * i, 240.0, 50)
        out = tracker.step(img, [det(gt)] if i < 3 else [])
        if gt[0] + 0.5 * gt[2] > W + 0.1 * gt[2]:    # more than 60 % outside
            seen_after += len(out)
    assert seen_after == 0
    assert tracker.active_ids == []


def test_track_ends_when_the_box_grows_past_the_limit():
    bg = background(6)
    tracker = MultiTracker(TrackerConfig(max_box_fraction=0.3))
    for i in range(30):
        img = bg.copy()
        gt = draw_diamond(img, 320.0, 240.0, 60 * 1.08 ** i)
        out = tracker.step(img, [det(gt)] if i < 3 else [])
        for t in out:
            assert t.box.h <= 0.3 * H + 1
    assert tracker.active_ids == []


# --- modes, the two-colour guard, the peer --------------------------------------------------

def test_detection_only_mode_emits_only_detections():
    bg = background(7)
    tracker = MultiTracker(TrackerConfig(mode='detection_only'))
    for i in range(12):
        img = bg.copy()
        gt = draw_diamond(img, *path(i))
        has = i % 3 == 0
        out = tracker.step(img, [det(gt)] if has else [])
        assert all(t.source == 'detection' for t in out)
        assert len(out) == (1 if has else 0)
        if has:
            assert box_iou((out[0].box.x, out[0].box.y, out[0].box.w, out[0].box.h), gt) > 0.99


@pytest.mark.parametrize('anchor', [True, False])
def test_regulatory_two_colour_box_keeps_its_white_part(anchor):
    bg = background(8)
    tracker = MultiTracker(TrackerConfig(anchor_on_color=anchor, **SLOW))
    ious = []
    for i in range(25):
        img = bg.copy()
        gt = draw_regulatory(img, 330 + 2 * i, 220 - 0.6 * i, 40 * 1.02 ** i)
        out = tracker.step(img, [det(gt, kind='regulatory')] if i < 3 else [])
        if i >= 3 and out:
            t = out[0].box
            ious.append(box_iou((t.x, t.y, t.w, t.h), gt))
    if anchor:        # the guard: orange band tracked, the box geometry kept
        assert len(ious) == 22 and min(ious) > 0.8, np.round(ious, 3)
    else:             # the ablation is only required to produce boxes, not good ones
        assert all(0 <= v <= 1 for v in ious)


def test_camshift_peer_follows_the_same_sign():
    bg = background(9)
    tracker = MultiTracker(TrackerConfig(method='camshift', **SLOW))
    ious = []
    for i in range(20):
        img = bg.copy()
        gt = draw_diamond(img, *path(i))
        out = tracker.step(img, [det(gt)] if i < 3 else [])
        if i >= 3 and out:
            ious.append(box_iou((out[0].box.x, out[0].box.y, out[0].box.w, out[0].box.h), gt))
    assert len(ious) >= 10 and np.median(ious) > 0.6


def test_bad_inputs_are_rejected():
    with pytest.raises(TrackingError):
        TrackerConfig(mode='tracking_only')
    with pytest.raises(TrackingError):
        TrackerConfig(method='kalman')
    with pytest.raises(TrackingError):
        MultiTracker().step(np.zeros((10, 10), np.uint8), [])
    # a detection outside the image is published but starts no track
    out = MultiTracker().step(background(), [det((-100.0, -100.0, 30.0, 30.0))])
    assert len(out) == 1 and out[0].track_id == 0


# --- the association rule -------------------------------------------------------------------

def test_fuse_keeps_the_tracked_box_against_a_poor_detection_and_overwrite_does_not():
    """A confident track meets a detection that holds only part of the sign (a blob cut in
    two): ``fuse`` scores both boxes with the target model and keeps the tracked one;
    Lee et al.'s ``overwrite`` takes the detection.  A good detection is taken by both."""
    bg = background(10)
    results = {}
    for assoc in ('fuse', 'overwrite'):
        tracker = MultiTracker(TrackerConfig(association=assoc))
        ious = []
        for i in range(12):
            img = bg.copy()
            cx, cy, size = path(i)
            gt = draw_diamond(img, cx, cy, size)
            if i < 4 or i == 11:
                d = gt                                         # good detections
            else:                                              # the left 55 % of the sign
                d = (gt[0], gt[1] + 0.2 * gt[3], 0.55 * gt[2], 0.6 * gt[3])
            out = tracker.step(img, [det(d)])
            assert [t.track_id for t in out] == [1] and out[0].source == 'detection'
            b = out[0].box
            ious.append(box_iou((b.x, b.y, b.w, b.h), gt))
            if i >= 4 and i < 11:
                assert box_iou(d, gt) < 0.5                    # a detector miss at tau 0.5
        results[assoc] = ious
    assert min(results['fuse'][4:11]) > 0.7, np.round(results['fuse'], 2)
    assert max(results['overwrite'][4:11]) < 0.5, np.round(results['overwrite'], 2)
    assert results['fuse'][11] > 0.9 and results['overwrite'][11] > 0.9


@pytest.mark.parametrize('association', ['fuse', 'overwrite'])
def test_two_colour_guard_extends_only_truncated_detections(association):
    """The guard restores the white part of a detection that holds only the orange top, but
    a detection that is already extended (the detector extends regulatory boxes itself) is
    taken as it is, even when its extension differs from the one the track knows."""
    bg = background(11)
    tracker = MultiTracker(TrackerConfig(association=association))
    for i in range(14):
        img = bg.copy()
        gt = draw_regulatory(img, 330 + 2 * i, 220 - 0.6 * i, 40 * 1.02 ** i)
        if i < 4:
            d = gt                                             # full boxes: geometry learnt
        elif i < 9:
            d = (gt[0], gt[1], gt[2], 0.3 * gt[3])             # orange top only: truncated
        else:
            d = (gt[0], gt[1], gt[2], 0.7 * gt[3])             # extended, shorter than known
        out = tracker.step(img, [det(d, kind='regulatory')])
        assert [t.track_id for t in out] == [1]
        b = out[0].box
        got = (b.x, b.y, b.w, b.h)
        if 4 <= i < 9:
            assert box_iou(got, gt) > 0.8, (i, got, gt)        # white part restored
        elif i >= 9:
            assert box_iou(got, d) > 0.95, (i, got, d)         # the detection's own box


def test_open_background_rows_are_rows_with_background_on_both_sides():
    """Rows whose left and right flanks are open background (a sign at the frame edge is
    judged on its visible flank: an empty flank counts as open)."""
    left = np.ones((10, 8), bool)
    assert open_background_rows(left, np.zeros((10, 0), bool), 4).all()
    assert open_background_rows(left, np.zeros((10, 8), bool), 4).sum() == 0
    assert open_background_rows(np.zeros((10, 1), bool), np.zeros((10, 0), bool), 4) is None
