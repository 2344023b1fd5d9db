"""The in-process pipelines tell the tracker the classifier's answers, as the node graph does
(``/workzone/signs`` -> ``tracker``): ``evaluate workzone --signs pipeline`` / ``inventory``
(``PipelineSource``) and ``evaluate real_signs``."""
from __future__ import annotations

import os
from collections import defaultdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from workzone_ros.core.track import MultiTracker, TrackerConfig
from workzone_ros.interfaces import Box, Detection, Header, Sign, Time
from workzone_ros.tools import workzone_pipeline as wp

REAL = Path(os.environ.get('WORKZONE_REALDATA')
            or Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata') \
    / 'us_workzone_video'


def _drum_frame(i: int) -> tuple[np.ndarray, tuple]:
    """A grey textured frame with an orange drum body (dark bands) drifting right."""
    rng = np.random.default_rng(3)
    img = np.clip(rng.normal(110, 12, (240, 320, 3)), 0, 255).astype(np.uint8)
    x, y, w, h = 120 + i, 100, 30, 45
    for j, col in enumerate([(0, 110, 245), (70, 70, 75)] * 2 + [(0, 110, 245)]):
        img[y + j * h // 5:y + (j + 1) * h // 5, x:x + w] = col
    return img, (float(x), float(y), float(w), float(h))


class _Detector:
    """The drum detected on frame 0 only (no channelizer count)."""

    det = None

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, image, gt):
        self.calls += 1
        if self.calls > 1:
            return []
        _, b = _drum_frame(0)
        return [Detection(box=Box(x=b[0], y=b[1], w=b[2], h=b[3]), confidence=0.9)]


class _Recognizer:
    """Every track a work-zone sign (``sign``) or background (not published)."""

    def __init__(self, answer: str) -> None:
        self.answer = answer
        self.given: list[int] = []             # boxes given per frame

    def recognize(self, frame, items, focal, rois=()):
        self.given.append(len(items))
        if self.answer == 'background':
            return [], [it.box for it in items]
        return [Sign(box=it.box, class_key='road_work_ahead', code='W20-1', category='workzone',
                     score=0.9, track_id=it.track_id) for it in items], []


@pytest.mark.parametrize('answer', ['sign', 'background'])
def test_pipeline_source_passes_the_classifier_answers_to_the_tracker(answer):
    """One detection of a drum: classified as a sign, its track runs on its own (and is
    classified again); rejected, it is not given to the classifier again."""
    src = object.__new__(wp.PipelineSource)
    src.detector = _Detector()
    src.tracker = MultiTracker(TrackerConfig(min_approach_speed=0.0))
    src.recognizer = _Recognizer(answer)
    src.timings = defaultdict(list)
    src.general, src.general_every, src._frames = None, 3, 0
    counts = []
    for i in range(5):
        img, _ = _drum_frame(i)
        gt = SimpleNamespace(header=Header(stamp=Time(sec=10, nanosec=i * 66_666_666)))
        signs, _ = src(gt, img, 500.0)
        counts.append(len(signs))
    assert counts == ([1] * 5 if answer == 'sign' else [0] * 5)
    assert src.recognizer.given == ([1] * 5 if answer == 'sign' else [1, 0, 0, 0, 0])
    assert src.tracker._verdicts.active and src.tracker.active_ids == [1]
    assert src.tracker._verdicts.verdict(1) is (answer == 'sign')


@pytest.mark.skipif(not (REAL / 'charlotte.mp4').exists(), reason=f'no clips in {REAL}')
def test_evaluate_real_signs_tells_the_tracker_every_frame(monkeypatch):
    """``evaluate real_signs`` calls ``MultiTracker.confirm`` once per frame with the
    frame's answers (and not without the tracker)."""
    from workzone_ros.core.classifier import DEFAULT_MODEL, load_model
    from workzone_ros.resources import config_path
    from workzone_ros.tools import eval_real_signs as ers
    calls = []
    orig = MultiTracker.confirm

    def confirm(self, signs=(), rejected=()):
        calls.append((set(signs), set(rejected)))
        orig(self, signs, rejected)

    monkeypatch.setattr(MultiTracker, 'confirm', confirm)
    model = load_model(config_path(DEFAULT_MODEL))
    ers.evaluate_clip(REAL / 'charlotte.mp4', model, 60.0, max_frames=4)
    assert len(calls) == 4
    ers.evaluate_clip(REAL / 'charlotte.mp4', model, 60.0, max_frames=2, track=False)
    assert len(calls) == 4
