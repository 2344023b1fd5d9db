"""Metres travelled, from a stream of odometry positions.

The fusion propagates work-zone evidence over distance (a car that slows down in a zone must
not lose it), so it needs the cumulative path length from ``nav_msgs/Odometry``.  This
accumulates the planar distance between consecutive positions, ignores steps that are not
finite or implausibly long (a pose reset, a glitch: counted in ``rejected``) and restarts
when the stamps jump backwards (a looping bag).  No rclpy import.
"""
from __future__ import annotations

import math
from typing import Optional

__all__ = ['TravelledDistance']


class TravelledDistance:
    """Cumulative planar path length of odometry positions.

    Args:
        max_speed_mps: steps faster than this are glitches (not added, counted).
    """

    def __init__(self, max_speed_mps: float = 80.0) -> None:
        if not max_speed_mps > 0:
            raise ValueError(f'max_speed_mps must be positive, got {max_speed_mps}')
        self.max_speed_mps = float(max_speed_mps)
        self.distance_m = 0.0
        self.rejected = 0
        self.resets = 0
        self._last: Optional[tuple[float, float, float]] = None

    def reset(self) -> None:
        """Forget the path (the distance restarts at 0)."""
        self.distance_m = 0.0
        self._last = None

    def update(self, stamp_s: float, x: float, y: float) -> float:
        """Add the position at ``stamp_s``; returns the distance travelled so far (m).

        Raises:
            ValueError: a non-finite stamp or position (the state is kept).
        """
        if not all(math.isfinite(v) for v in (stamp_s, x, y)):
            self.rejected += 1
            raise ValueError(f'odometry position ({x}, {y}) at {stamp_s} is not finite')
        if self._last is not None and stamp_s < self._last[0]:
            self.resets += 1
            self.reset()
        if self._last is not None:
            t0, x0, y0 = self._last
            step = math.hypot(x - x0, y - y0)
            dt = stamp_s - t0
            if step > self.max_speed_mps * max(dt, 0.02):
                self.rejected += 1
            else:
                self.distance_m += step
        self._last = (stamp_s, x, y)
        return self.distance_m
