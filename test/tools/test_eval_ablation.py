"""The ablation of the colour stage's switches: which are listed, and how a verdict is made."""
from __future__ import annotations

import dataclasses

from workzone_ros.tools.eval_ablation import (
    BASELINE,
    default_on_switches,
    markdown,
    summarise,
    verdicts,
)


def _synthetic(p, r, found, false):
    kind = {'precision': p, 'recall': r, 'eligible': 10, 'detection_rate': found, 'images': 5}
    return {'all': {'warning': kind, 'regulatory': dict(kind), 'false_per_frame': false},
            'ms_per_frame_p50': 2.0}


def _real(frames, detected, free, false):
    return {'visible_frames': frames, 'visible_detected': detected, 'free_frames': free,
            'false_detections': false}


def test_every_default_on_boolean_switch_is_listed_and_nothing_else():
    @dataclasses.dataclass(frozen=True)
    class Config:
        method: str = 'learned'
        refine: bool = True
        experiment: bool = False
        threshold: float = 0.5
        peel: bool = True
    assert default_on_switches(Config) == ['refine', 'peel']
    assert 'refine' in default_on_switches()        # the real DetectorConfig


def test_a_switch_is_removable_only_when_nothing_gets_worse():
    synthetic = {BASELINE: _synthetic(0.90, 0.80, 0.95, 0.10),
                 'a=off': _synthetic(0.898, 0.80, 0.95, 0.10),      # within tolerance
                 'b=off': _synthetic(0.90, 0.70, 0.95, 0.10),       # recall lost
                 'c=off': _synthetic(0.90, 0.80, 0.95, 0.10)}       # renders equal ...
    real = {'clip.mp4': {BASELINE: _real(100, 80, 50, 5), 'a=off': _real(100, 80, 50, 5),
                         'b=off': _real(100, 80, 50, 5),
                         'c=off': _real(100, 79, 50, 5)}}            # ... but a real loss
    rows = summarise(synthetic, real)
    assert rows[BASELINE]['real_found'] == 0.8 and rows[BASELINE]['real_false_per_frame'] == 0.1
    v = verdicts(rows, tolerance=0.005)
    assert v == {'a=off': 'removable', 'b=off': 'costs recall',
                 'c=off': 'costs real_found'}
    table = markdown(rows, v)
    assert table.splitlines()[2].startswith(f'| {BASELINE} |')
    assert '(-0.100)' in table and 'removable' in table
