"""Which inputs have gone quiet: a staleness limit per input from its own rate (no rclpy).

A planner must learn within half a second that the camera, the LiDAR, odometry or the sign
chain stopped (``WorkzoneState.stale_inputs``).  One fixed limit cannot do that for every
input: a 15 Hz camera is clearly gone after 0.25 s, while the sign chain of a loaded machine
may legitimately answer only every 300 ms.  So each input's limit is ``periods`` times the
90th percentile of its own recent arrival intervals, clipped to ``[min_s, max_s]``: fast
inputs are declared stale quickly, an input that is slow all the time does not flicker in and
out of the list, and nothing waits longer than ``max_s``.  Until an input has a few intervals
its limit is ``max_s``.  Times are monotonic seconds.
"""
from __future__ import annotations

import collections
from dataclasses import dataclass
from typing import Optional

import numpy as np

__all__ = ['LivenessConfig', 'InputLiveness']


@dataclass(frozen=True)
class LivenessConfig:
    """Staleness limits (seconds) and how they follow each input's rate."""

    min_s: float = 0.25          # never stale sooner than this after the last message
    max_s: float = 1.0           # always stale this long after the last message
    periods: float = 2.0         # limit = periods x p90 of the input's recent intervals
    window: int = 50             # arrival intervals kept per input
    min_intervals: int = 5       # intervals needed before the limit follows the rate

    def __post_init__(self) -> None:
        if not 0.0 < self.min_s <= self.max_s:
            raise ValueError(f'need 0 < min_s <= max_s, got {self.min_s} and {self.max_s}')
        if self.periods <= 0 or self.window < 2 or self.min_intervals < 1:
            raise ValueError('periods must be > 0, window >= 2 and min_intervals >= 1')


class InputLiveness:
    """Arrival times per named input and the inputs silent for longer than their limit."""

    def __init__(self, config: LivenessConfig = LivenessConfig()) -> None:
        self.config = config
        self._last: dict[str, float] = {}
        self._gaps: dict[str, collections.deque] = {}

    def seen(self, name: str, now: float) -> None:
        """A message of input ``name`` arrived at monotonic time ``now``."""
        last = self._last.get(name)
        if last is not None and now >= last:
            self._gaps.setdefault(name, collections.deque(maxlen=self.config.window)).append(
                now - last)
        self._last[name] = now

    def limit(self, name: str) -> float:
        """The silence (s) after which ``name`` counts as stale."""
        cfg = self.config
        gaps = self._gaps.get(name)
        if not gaps or len(gaps) < cfg.min_intervals:
            return cfg.max_s
        p90 = float(np.percentile(np.fromiter(gaps, float), 90))
        return min(cfg.max_s, max(cfg.min_s, cfg.periods * p90))

    def stale(self, now: float) -> list[str]:
        """The inputs seen before and silent for longer than their limit, sorted."""
        return sorted(k for k, t in self._last.items() if now - t > self.limit(k))

    def last_seen(self, name: str) -> Optional[float]:
        """Monotonic time of the last message of ``name`` (None: never seen)."""
        return self._last.get(name)

    def reset(self) -> None:
        """Forget every input (a restart of the inputs, e.g. a looping bag)."""
        self._last.clear()
        self._gaps.clear()
