"""Stale inputs: each input's limit follows its own rate, between a floor and a ceiling."""
from __future__ import annotations

import pytest

from workzone_ros.core.liveness import InputLiveness, LivenessConfig


def _feed(live, name, t0, period, n):
    for k in range(n):
        live.seen(name, t0 + k * period)
    return t0 + (n - 1) * period


def test_a_fast_input_is_stale_within_half_a_second_a_slow_one_does_not_flicker():
    live = InputLiveness(LivenessConfig(min_s=0.25, max_s=1.0, periods=2.0))
    last_cam = _feed(live, 'camera', 0.0, 1 / 15, 60)           # 15 Hz
    last_sig = _feed(live, 'signs', 0.0, 0.3, 14)               # a loaded sign chain
    assert live.limit('camera') == 0.25
    assert abs(live.limit('signs') - 0.6) < 1e-6
    now = last_sig + 0.35                                        # both quiet a little
    assert live.stale(now) == ['camera'] and now - last_cam < 0.5
    assert live.stale(last_sig + 0.7) == ['camera', 'signs']


def test_limits_before_enough_intervals_and_at_the_ceiling():
    live = InputLiveness(LivenessConfig(min_s=0.25, max_s=1.0, periods=2.0, min_intervals=5))
    live.seen('lidar', 0.0)
    assert live.limit('lidar') == 1.0 and live.stale(0.9) == []
    assert live.stale(1.01) == ['lidar']
    _feed(live, 'odom', 0.0, 2.0, 10)                            # slower than the ceiling
    assert live.limit('odom') == 1.0
    assert live.stale(100.0) == ['lidar', 'odom'] and 'never' not in live.stale(100.0)
    live.reset()
    assert live.stale(100.0) == [] and live.last_seen('odom') is None


def test_a_clock_that_steps_back_adds_no_interval():
    live = InputLiveness()
    live.seen('camera', 10.0)
    live.seen('camera', 5.0)
    assert live.limit('camera') == live.config.max_s and live.last_seen('camera') == 5.0


@pytest.mark.parametrize('kw', [dict(min_s=0.0), dict(min_s=2.0, max_s=1.0),
                                dict(periods=0.0), dict(window=1)])
def test_bad_limits_are_refused(kw):
    with pytest.raises(ValueError):
        LivenessConfig(**kw)
