"""The ego's speed along the route: slow-downs to a posted limit and stop-and-go episodes.

A :class:`SpeedProfile` is the ego's speed as a function of arc length ``s``, built as the
lowest of a few *envelopes* of ``v(s)^2``, each linear in ``s`` piece by piece (constant
acceleration):

- cruise: ``v = cruise`` everywhere;
- a slow zone ``(s_from, s_to, limit)``: from ``s_from`` (the work-zone speed limit sign)
  brake at ``decel`` down to ``limit``, hold it to ``s_to`` (the END ROAD WORK sign), then
  accelerate at ``accel`` back to cruise;
- a stop ``(at, stop_s)``: brake at ``decel`` to a standstill at ``at``, stand ``stop_s``
  seconds, accelerate at ``accel``.

The lower envelope of such functions has ``d(v^2)/ds`` in ``[-2 decel, 2 accel]``, so the ego
never brakes harder than ``decel`` nor accelerates harder than ``accel``.  ``v^2`` is sampled on
a 0.5 m grid that includes every envelope's corners; between two samples the acceleration is
constant, so times follow in closed form (``dt = 2 ds / (v0 + v1)``, finite even where the
ego comes to rest).  ``s(t)`` is non-decreasing, ``t_at(s)`` is the *first* time the ego
reaches ``s`` (a standstill's arrival, not its departure), and ``s(t_at(s)) == s``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ['MPH', 'SlowZone', 'Stop', 'SpeedProfile', 'SpeedProfileError']

MPH = 0.44704                    # m/s per mile per hour
_STEP = 0.5                      # arc-length sampling of v(s)^2 (m)


class SpeedProfileError(ValueError):
    """Profile inputs that cannot be driven (one line)."""


@dataclass(frozen=True)
class SlowZone:
    """Brake from ``s_from`` to ``limit`` (m/s), hold it to ``s_to``, then back to cruise."""

    s_from: float
    s_to: float
    limit: float


@dataclass(frozen=True)
class Stop:
    """Come to a standstill at arc length ``at`` and stand ``stop_s`` seconds."""

    at: float
    stop_s: float


class SpeedProfile:
    """Arc length over time of a vehicle whose speed is a function of arc length.

    Args:
        start_s: arc length at ``t = 0``.
        cruise: speed (m/s) outside slow zones and stops.
        zones: slow zones.
        stops: standstills (at most one per arc length; each after ``start_s``).
        decel: braking (m/s^2, > 0).
        accel: acceleration (m/s^2, > 0).

    Raises:
        SpeedProfileError: non-positive speeds or rates, a zone that ends before it starts,
            a stop at or before ``start_s``.
    """

    def __init__(self, start_s: float, cruise: float, zones: Sequence[SlowZone] = (),
                 stops: Sequence[Stop] = (), decel: float = 1.2, accel: float = 1.0):
        if not (cruise > 0 and decel > 0 and accel > 0):
            raise SpeedProfileError(f'cruise {cruise}, decel {decel} and accel {accel} '
                                    'must be > 0')
        for z in zones:
            if not (z.limit > 0 and z.s_to >= z.s_from):
                raise SpeedProfileError(f'slow zone {z} needs limit > 0 and s_to >= s_from')
        for st in stops:
            if not (st.at > start_s and st.stop_s >= 0):
                raise SpeedProfileError(f'stop at {st.at} m must lie after the start '
                                        f'({start_s} m) and last >= 0 s')
        self.start_s, self.cruise = float(start_s), float(cruise)
        self.decel, self.accel = float(decel), float(accel)
        self.zones, self.stops = tuple(zones), tuple(sorted(stops, key=lambda x: x.at))
        c2, b2, a2 = cruise ** 2, 2 * decel, 2 * accel
        corners = [start_s]
        for z in zones:
            lim = min(z.limit, cruise) ** 2
            corners += [z.s_from, z.s_from + (c2 - lim) / b2, z.s_to, z.s_to + (c2 - lim) / a2]
        for st in self.stops:
            corners += [st.at, st.at + c2 / a2, st.at - c2 / b2]
            corners += [st.at - min(z.limit, cruise) ** 2 / b2 for z in zones]
        end = max(corners) + 1.0
        grid = np.arange(start_s, end + _STEP, _STEP)
        s = np.unique(np.concatenate([grid, [c for c in corners if c >= start_s]]))
        v2 = np.full_like(s, c2)
        for z in zones:
            v2 = np.minimum(v2, self._zone_v2(z, s))
        for st in self.stops:
            v2 = np.minimum(v2, np.where(s <= st.at, b2 * (st.at - s), a2 * (s - st.at)))
        v = np.sqrt(np.maximum(v2, 0.0))
        dwell = np.zeros_like(s)
        for st in self.stops:
            i = int(np.searchsorted(s, st.at))
            v[i], dwell[i] = 0.0, st.stop_s
        if v[0] <= 0.0:
            raise SpeedProfileError('the ego would stand still at the start')
        seg = 2.0 * np.diff(s) / (v[:-1] + v[1:])          # constant acceleration per cell
        arrive = np.concatenate([[0.0], np.cumsum(seg + dwell[:-1])])
        self._s, self._v, self._arrive = s, v, arrive
        self._depart = arrive + dwell
        self._acc = (v[1:] ** 2 - v[:-1] ** 2) / (2.0 * np.diff(s))

    def _zone_v2(self, z: SlowZone, s: np.ndarray) -> np.ndarray:
        c2, lim = self.cruise ** 2, min(z.limit, self.cruise) ** 2
        braking = np.maximum(c2 - 2 * self.decel * (s - z.s_from), lim)
        at_end = max(c2 - 2 * self.decel * (z.s_to - z.s_from), lim)
        out = np.where(s < z.s_from, c2, braking)
        after = np.minimum(at_end + 2 * self.accel * (s - z.s_to), c2)
        return np.where(s > z.s_to, after, out)

    def s(self, t):
        """Arc length at time(s) ``t`` (s); before 0 and after the last corner at constant
        speed."""
        t = np.asarray(t, dtype=float)
        s, v, dep, arr, acc = self._s, self._v, self._depart, self._arrive, self._acc
        i = np.clip(np.searchsorted(dep, t, side='right') - 1, 0, len(s) - 2)
        tau = np.maximum(t - dep[i], 0.0)
        inside = np.minimum(s[i] + v[i] * tau + 0.5 * acc[i] * tau * tau, s[i + 1])
        out = np.where(t >= arr[i + 1], s[i + 1], inside)
        out = np.where(t < 0.0, self.start_s + v[0] * t, out)
        last = len(s) - 1
        return np.where(t > dep[last], s[last] + v[last] * (t - dep[last]), out)

    def t_at(self, s_query):
        """First time (s) the vehicle reaches arc length(s) ``s_query``."""
        q = np.asarray(s_query, dtype=float)
        s, v, dep, arr, acc = self._s, self._v, self._depart, self._arrive, self._acc
        i = np.clip(np.searchsorted(s, q, side='right') - 1, 0, len(s) - 2)
        ds = np.maximum(q - s[i], 0.0)
        vq = np.sqrt(np.maximum(v[i] ** 2 + 2.0 * acc[i] * ds, 0.0))
        with np.errstate(divide='ignore', invalid='ignore'):
            tau = np.where(ds > 0, 2.0 * ds / (v[i] + vq), 0.0)
        out = np.where(ds > 0, dep[i], arr[i]) + tau
        out = np.where(q < self.start_s, (q - self.start_s) / v[0], out)
        last = len(s) - 1
        return np.where(q > s[last], dep[last] + (q - s[last]) / v[last], out)

    def speed(self, t):
        """Speed (m/s) at time(s) ``t``: 0 while standing, constant before 0 / after the end."""
        t = np.asarray(t, dtype=float)
        s, v, dep, arr, acc = self._s, self._v, self._depart, self._arrive, self._acc
        i = np.clip(np.searchsorted(dep, t, side='right') - 1, 0, len(s) - 2)
        inside = np.clip(v[i] + acc[i] * np.maximum(t - dep[i], 0.0), 0.0, None)
        out = np.where(t >= arr[i + 1], v[i + 1], inside)        # v = 0 at a standstill
        out = np.where(t < 0.0, v[0], out)
        last = len(s) - 1
        return np.where(t > dep[last], v[last], out)

    def speed_at_s(self, s_query):
        """Speed (m/s) when passing arc length(s) ``s_query`` (0 at a stop)."""
        q = np.asarray(s_query, dtype=float)
        return np.interp(q, self._s, self._v ** 2, left=self._v[0] ** 2,
                         right=self._v[-1] ** 2) ** 0.5

