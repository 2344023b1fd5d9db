"""Motion along the route: the lateral profile of the lanes (lane shifts, the merge off a closed
lane), the ego vehicle's trajectory (:class:`EgoTrajectory`) and vehicles that follow a lane
(:class:`LaneVehicle`).
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from workzone_ros.sim.scenario_spec import SHIFT_LENGTH, WorkzoneSpec
from workzone_ros.sim.speed_profile import SpeedProfile
from workzone_ros.sim.world import (
    CAMERA_IN_BASE,
    LANE_CENTERS,
    LANE_WIDTH,
    LIDAR_IN_BASE,
    Box,
    Pose,
    Road,
)

__all__ = ['EgoTrajectory', 'LaneVehicle', 'lane_profile', 'lateral_offset']


# --- lateral profiles -----------------------------------------------------------------------

def _smooth(x: np.ndarray) -> np.ndarray:
    """Quintic smoothstep (C2) of x clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


def _shift_moves(wz: Optional[WorkzoneSpec]) -> list[tuple[float, float]]:
    """(start_s, signed lateral move) of each lane shift; lanes stay within +-1 lane."""
    if wz is None:
        return []
    out, offset = [], 0.0
    for sh in wz.lane_shifts:
        move = sh.move or (sh.direction if sh.direction != 'unknown' else
                           ('right' if offset > 0 else 'left'))
        delta = sh.offset if move == 'left' else -sh.offset
        if abs(offset + delta) > LANE_WIDTH + 1e-6:
            delta = -delta
        offset += delta
        out.append((wz.taper_s + sh.at, delta))
    return out


def lateral_offset(wz: Optional[WorkzoneSpec], s: np.ndarray) -> np.ndarray:
    """Lateral offset of all lanes (m, left positive) at arc lengths ``s`` from lane shifts."""
    s = np.asarray(s, dtype=float)
    out = np.zeros_like(s)
    for s0, delta in _shift_moves(wz):
        out += delta * _smooth((s - s0) / SHIFT_LENGTH)
    return out


def _merge_target(lane: str, closed: Optional[str]) -> Optional[str]:
    if closed is None or lane != closed:
        return None
    return 'middle'


def lane_profile(wz: Optional[WorkzoneSpec], lane: str, s: np.ndarray) -> np.ndarray:
    """Lateral position (m) of a vehicle keeping ``lane``: shifts plus a merge off a closed
    lane (done 300-150 m before the taper)."""
    d = LANE_CENTERS[lane] + lateral_offset(wz, s)
    target = _merge_target(lane, wz.lane_closed if wz else None)
    if target is not None:
        s0 = wz.taper_s - 300.0
        d = d + (LANE_CENTERS[target] - LANE_CENTERS[lane]) * _smooth((s - s0) / 150.0)
    return d


# --- ego ------------------------------------------------------------------------------------

class EgoTrajectory:
    """The ego vehicle: speed along the route, lateral profile, pitch/roll jitter.

    Args:
        road: the road.
        speed: cruise speed (m/s); the speed at every time without a ``profile``.
        start_s: arc length at t = 0.
        s_grid: arc-length samples of the lateral profile.
        d_grid: lateral offsets (left positive) at ``s_grid``.
        jitter: scale of the pitch / roll oscillation (1.0 = about 0.25 / 0.2 degrees at
            cruise speed; with a ``profile`` it scales with the speed, none at a standstill).
        seed: phases of the oscillation.
        profile: slow-downs and stops (sim/speed_profile.py); None = constant ``speed``.
    """

    def __init__(self, road: Road, speed: float, start_s: float, s_grid: np.ndarray,
                 d_grid: np.ndarray, jitter: float = 1.0, seed: int = 0,
                 profile: Optional[SpeedProfile] = None):
        self.road = road
        self.speed = float(speed)
        self.start_s = float(start_s)
        self.profile = profile
        self._s = np.asarray(s_grid, dtype=float)
        self._d = np.asarray(d_grid, dtype=float)
        self._dd = np.gradient(self._d, self._s)
        rng = np.random.default_rng([seed, 0xe90])
        self._freq = np.array([0.9, 1.7, 2.9])
        self._pitch = jitter * np.array([0.0030, 0.0012, 0.0006])
        self._roll = jitter * np.array([0.0025, 0.0010, 0.0005])
        self._phase = rng.uniform(0, 2 * np.pi, size=(2, 3))

    def s(self, t):
        """Arc length at time ``t`` (s); non-decreasing."""
        if self.profile is not None:
            return self.profile.s(t)
        return self.start_s + self.speed * np.asarray(t, dtype=float)

    def t_at(self, s):
        """First time at which the ego reaches arc length ``s`` (its arrival at a stop)."""
        if self.profile is not None:
            return self.profile.t_at(s)
        return (np.asarray(s, dtype=float) - self.start_s) / self.speed

    def speed_at(self, t):
        """Speed along the route (ds/dt, m/s) at time ``t``."""
        if self.profile is not None:
            return self.profile.speed(t)
        return np.full(np.shape(t), self.speed)

    def d(self, t):
        """Lateral offset at time ``t``."""
        return np.interp(self.s(t), self._s, self._d)

    def base_pose(self, t: float) -> Pose:
        """base_link pose in the world (= odom) frame at time ``t``."""
        s = float(self.s(t))
        d = float(np.interp(s, self._s, self._d))
        x, y, h = self.road.pose_at(s, d)
        yaw = float(h) + math.atan(float(np.interp(s, self._s, self._dd)))
        w = 2 * np.pi * self._freq * t
        pitch = float(np.sum(self._pitch * np.sin(w + self._phase[0])))
        roll = float(np.sum(self._roll * np.sin(w + self._phase[1])))
        if self.profile is not None:            # the road shakes a moving car only
            k = float(self.profile.speed(t)) / self.speed
            pitch, roll = pitch * k, roll * k
        return Pose(np.array([float(x), float(y), 0.0]), yaw, pitch, roll)

    def _mounted(self, t: float, offset: np.ndarray) -> Pose:
        b = self.base_pose(t)
        return Pose(b.to_world(offset), b.yaw, b.pitch, b.roll)

    def lidar_pose(self, t: float) -> Pose:
        """LiDAR pose (base_link axes) at time ``t``."""
        return self._mounted(t, LIDAR_IN_BASE)

    def camera_pose(self, t: float) -> Pose:
        """Camera mount pose with base_link axes (the optical axes are BASE_TO_CAMERA_ROT)."""
        return self._mounted(t, CAMERA_IN_BASE)

    def velocity(self, t: float, dt: float = 1e-3) -> np.ndarray:
        """World-frame linear velocity (3,) of base_link at time ``t``."""
        return (self.base_pose(t + dt).position - self.base_pose(t - dt).position) / (2 * dt)

    def twist(self, t: float, dt: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
        """Body-frame (linear, angular) velocity of base_link at time ``t``."""
        p0, p1 = self.base_pose(t - dt), self.base_pose(t + dt)
        b = self.base_pose(t)
        lin = b.R.T @ ((p1.position - p0.position) / (2 * dt))
        dR = p0.R.T @ p1.R                       # body rotation over 2 dt
        ang = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / 2
        return lin, ang / (2 * dt)


class LaneVehicle(Box):
    """A vehicle that follows a lane of the road (merges and shifts included).

    The base :class:`Box` moves in a straight line; this subclass keeps the road's curvature:
    :meth:`at` returns a plain :class:`Box` at the lane position of time ``t``.
    """

    def __init__(self, *args, road: Road, s0: float, s_grid: np.ndarray, d_grid: np.ndarray,
                 **kwargs):
        super().__init__(*args, **kwargs)
        self.road = road
        self.s0 = float(s0)
        self.s_grid = s_grid
        self.d_grid = d_grid

    def at(self, t: float) -> Box:
        """The vehicle at time ``t`` as a plain Box."""
        s = self.s0 + self.speed * t
        d = float(np.interp(s, self.s_grid, self.d_grid))
        x, y, h = self.road.pose_at(s, d)
        return Box(self.object_id, self.kind, np.array([float(x), float(y), 0.0]), self.length,
                   self.width, self.height, float(h), self.material, self.speed, self.plate,
                   self.rear_material)
