"""The classifier's confirmation of tracks (``TrackerConfig.needs_confirmation``), and the
end of a track whose box drifted to twice its size (``TrackerConfig.max_size_ratio``).

One false detection must not become a long track: with a classifier reporting back
(``MultiTracker.confirm``), a track started by a single detection runs on its own only once
the classifier confirmed it as a sign (or after a second detection), never while it rejected
it as background.  The drawings come from ``test_tracking``.
"""
from __future__ import annotations

import pytest
from tracking_helpers import (
    ORANGE,
    SLOW,
    _banded,
    background,
    det,
    draw_diamond,
    path,
)

from workzone_ros.core.track import MultiTracker, TrackerConfig, TrackingError, box_iou
from workzone_ros.core.track.confirmation import classifier_verdicts
from workzone_ros.interfaces import Box, Sign

#: Dirty reflective bands: dark, not white, so the white gate does not stop the drum.
GREY = (70, 70, 75)


def _drum(img, i):
    """An orange drum drifting right, its bands dark; returns its box."""
    return _banded(img, (200 + i, 260, 30, 45), [ORANGE, GREY, ORANGE, GREY, ORANGE])


def _drum_run(needs: bool, answer: str, frames: int = 7) -> tuple[list[int], MultiTracker]:
    """The drum detected once (frame 0), then frames without a detection; the classifier's
    ``answer`` on its track after frame 0 (``nothing``: it reports, nothing on this track;
    ``sign``; ``background``; ``no classifier``: confirm is never called).  Returns the
    frames 1.. on which the drum's track was published running on its own."""
    tracker = MultiTracker(TrackerConfig(needs_confirmation=needs, **SLOW))
    bg = background(31)
    alone = []
    for i in range(frames):
        img = bg.copy()
        box = _drum(img, i)
        out = tracker.step(img, [det(box)] if i == 0 else [])
        if i == 0:
            assert [(t.track_id, t.source, t.hits) for t in out] == [(1, 'detection', 1)]
            if answer == 'sign':
                tracker.confirm(signs=[1])
            elif answer == 'background':
                tracker.confirm(rejected=[1])
            elif answer == 'nothing':
                tracker.confirm()
            continue
        mine = [t for t in out if t.source == 'tracking'
                and box_iou((t.box.x, t.box.y, t.box.w, t.box.h), box) > 0.5]
        if mine:
            alone.append(i)
    return alone, tracker


@pytest.mark.parametrize('needs,answer,published', [
    (False, 'nothing', True),      # the previous rule: one detection is enough
    (False, 'background', True),   # knob off: exactly the previous rule
    (True, 'nothing', False),      # no confirmation: not published on its own
    (True, 'sign', True),          # confirmed by the classifier
    (True, 'background', False),   # rejected as background
    (True, 'no classifier', True),  # nobody reports: the rule does not apply
])
def test_a_single_false_detection_on_a_drum_runs_on_its_own_only_when_confirmed(
        needs, answer, published):
    """The drum passes every other gate (it runs on its own with the knob off), so only the
    classifier's confirmation keeps it from becoming a 6-frame track (the test fails without
    the rule).  An unpublished track still runs, ready for a detection."""
    alone, tracker = _drum_run(needs, answer)
    assert alone == ([1, 2, 3, 4, 5, 6] if published else []), alone
    assert tracker.active_ids == [1]


def test_a_rejected_track_runs_on_its_own_again_after_a_new_detection():
    """A rejection holds until a new detection; a track confirmed, then rejected (it
    drifted off the sign) stops being published on its own: the latest answer counts."""
    tracker = MultiTracker(TrackerConfig(**SLOW))
    bg = background(31)
    sources = []
    for i in range(9):
        img = bg.copy()
        box = _drum(img, i)
        out = tracker.step(img, [det(box)] if i in (0, 3) else [])
        sources.append([t.source for t in out])
        if i == 0:
            tracker.confirm(signs=[1])
        if i == 1:
            tracker.confirm(rejected=[1])          # latest answer: background
    assert sources[1] == ['tracking']              # confirmed
    assert sources[2] == []                        # rejected
    assert sources[3] == ['detection']             # a detection is published as before
    assert sources[4:] == [['tracking']] * 5       # two detections: runs on its own again


def test_a_sign_detected_twice_runs_on_its_own_as_before():
    """Repeated detections are enough without the classifier's confirmation: the same
    tracks, frame by frame, with and without the rule."""
    bg = background(23)
    runs = []
    for needs in (True, False):
        tracker = MultiTracker(TrackerConfig(needs_confirmation=needs, **SLOW))
        got = []
        for i in range(10):
            img = bg.copy()
            gt = draw_diamond(img, *path(i))
            out = tracker.step(img, [det(gt)] if i < 2 else [])
            tracker.confirm()                      # the classifier says nothing on it
            got.append([(t.track_id, t.source, t.hits, t.box) for t in out])
        runs.append(got)
    assert runs[0] == runs[1]
    assert [s for _, s, _, _ in sum(runs[0][2:], [])] == ['tracking'] * 8


def test_classifier_verdicts_read_the_signs_of_a_frame():
    """A sign of category workzone or general confirms its track; unknown (too small) is no
    answer; a given track without any sign was rejected (the classifier does not publish
    background); boxes without a track (0, None) are never rejected."""
    box = Box(x=0.0, y=0.0, w=10.0, h=10.0)

    def sign(tid, category, key='road_work_ahead'):
        return Sign(box=box, class_key=key, code='-', category=category, score=0.9,
                    track_id=tid)

    signs = [sign(1, 'workzone'), sign(2, 'general', 'stop'), sign(3, 'unknown', 'unknown'),
             sign(None, 'general', 'stop')]
    assert classifier_verdicts([1, 2, 3, 4, 0, None], signs) == ({1, 2}, {4})
    assert classifier_verdicts([], signs) == ({1, 2}, set())


def _growing_run(**config) -> tuple[list[float], MultiTracker]:
    """A diamond detected once (frame 0, confirmed by the classifier), then growing 3 % a
    frame for 45 frames without a detection; the published widths relative to the detected
    one, frame by frame (0: not published)."""
    tracker = MultiTracker(TrackerConfig(**SLOW, **config))
    bg = background(23)
    widths = []
    for i in range(46):
        img = bg.copy()
        gt = draw_diamond(img, 320, 240, 40 * 1.03 ** i)
        out = tracker.step(img, [det(gt)] if i == 0 else [])
        if i == 0:
            tracker.confirm(signs=[1])
            first = gt[2]
        widths.append(out[0].box.w / first if out else 0.0)
    return widths, tracker


def test_a_track_of_one_detection_ends_when_its_box_has_doubled():
    """A track of one detection has no measured perspective trend, so the growth guard
    cannot judge its growth; the size cap does: the box is never published at twice its
    detected size and the track ends there.  Without the cap the same track runs on its own
    for all 45 frames (max_coast_frames) and ends over three times its detected size."""
    widths, tracker = _growing_run()
    alone = [w for w in widths[1:] if w > 0]
    assert 20 <= len(alone) < 30 and max(alone) < 2.0, widths
    assert widths[len(alone) + 1:] == [0.0] * (45 - len(alone))
    assert tracker.active_ids == []

    widths, tracker = _growing_run(max_size_ratio=0.0)
    assert all(w > 0 for w in widths) and widths[-1] > 3.0, widths


def test_max_size_ratio_is_off_or_above_one():
    with pytest.raises(TrackingError, match='max_size_ratio'):
        TrackerConfig(max_size_ratio=0.8)
    assert TrackerConfig(max_size_ratio=0.0).max_size_ratio == 0.0
