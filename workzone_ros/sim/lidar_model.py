"""The simulated LiDAR sensor: its parameters (:class:`LidarModel`), the datasheet presets
(:data:`LIDAR_PRESETS`, :func:`lidar_preset`) and the scan the caster returns (:class:`Scan`).

The presets' datasheet values and the conventions of a scan are in the docstring of
:mod:`workzone_ros.sim.lidar` (the caster).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

__all__ = ['LidarError', 'LidarModel', 'LIDAR_PRESETS', 'DEFAULT_PRESET', 'Scan',
           'lidar_preset']


class LidarError(ValueError):
    """An invalid LiDAR model or a scene object the caster cannot intersect."""


@dataclass(frozen=True)
class LidarModel:
    """A spinning multi-beam LiDAR (defaults: Velodyne HDL-64E at 10 Hz).

    Attributes:
        n_beams: number of lasers (rings), at most 65535.
        fov_up_deg: elevation of the highest beam.
        fov_down_deg: elevation of the lowest beam (ring 0).
        azimuth_res_deg: azimuth step between columns.
        rate_hz: revolutions per second.
        max_range: farthest return in metres.
        min_range: nearest return in metres.
        range_noise_m: standard deviation of the Gaussian range noise.
        dropout: probability that a return is randomly lost.
    """

    n_beams: int = 64
    fov_up_deg: float = 2.0
    fov_down_deg: float = -24.8        # HDL-64E: vertical angles spread over +2 .. -24.8
    azimuth_res_deg: float = 0.17      # ~2118 columns x 64 = ~135k rays
    rate_hz: float = 10.0
    max_range: float = 120.0
    min_range: float = 1.0
    range_noise_m: float = 0.02
    dropout: float = 0.02              # random point dropout probability

    def __post_init__(self) -> None:
        if not 1 <= self.n_beams <= 65535:
            raise LidarError(f'n_beams must be in 1..65535, got {self.n_beams}')
        if self.n_beams > 1 and not self.fov_down_deg < self.fov_up_deg:
            raise LidarError(f'fov_down_deg ({self.fov_down_deg}) must be below fov_up_deg '
                             f'({self.fov_up_deg})')
        if not 0.01 <= self.azimuth_res_deg <= 10.0:
            raise LidarError(f'azimuth_res_deg must be in 0.01..10, got {self.azimuth_res_deg}')
        if self.rate_hz <= 0 or not 0 <= self.min_range < self.max_range:
            raise LidarError('need rate_hz > 0 and 0 <= min_range < max_range')
        if self.range_noise_m < 0 or not 0 <= self.dropout < 1:
            raise LidarError('need range_noise_m >= 0 and 0 <= dropout < 1')

    @property
    def n_columns(self) -> int:
        """Columns (firings per beam) in one revolution."""
        return max(int(round(360.0 / self.azimuth_res_deg)), 1)

    def elevations(self) -> np.ndarray:
        """Beam elevations in radians, ascending: index = ring (ring 0 is the lowest)."""
        return np.radians(np.linspace(self.fov_down_deg, self.fov_up_deg, self.n_beams))

    def azimuths(self) -> np.ndarray:
        """Column azimuths in radians in the lidar frame (clockwise spin from the rear)."""
        return np.pi - 2.0 * np.pi * np.arange(self.n_columns) / self.n_columns


#: Sensor presets by name (see the docstring of sim/lidar.py for the datasheet values).
LIDAR_PRESETS: dict[str, LidarModel] = {
    'hdl64': LidarModel(),
    'hdl32': LidarModel(n_beams=32, fov_up_deg=10.67, fov_down_deg=-30.67, azimuth_res_deg=0.16,
                        max_range=100.0),
    'vlp16': LidarModel(n_beams=16, fov_up_deg=15.0, fov_down_deg=-15.0, azimuth_res_deg=0.2,
                        max_range=100.0, range_noise_m=0.03),
}
DEFAULT_PRESET = 'hdl64'


def lidar_preset(name: str = DEFAULT_PRESET, max_range: float | None = None) -> LidarModel:
    """The sensor of a preset, optionally with a shorter (or longer) ``max_range``.

    Args:
        name: a key of :data:`LIDAR_PRESETS` (``hdl64``, ``hdl32``, ``vlp16``).
        max_range: farthest return in metres (None: the preset's datasheet range).

    Raises:
        LidarError: unknown preset or a ``max_range`` not above the preset's ``min_range``.
    """
    try:
        model = LIDAR_PRESETS[name]
    except (KeyError, TypeError):
        raise LidarError(f'unknown lidar model {name!r}; known: '
                         f'{", ".join(LIDAR_PRESETS)}') from None
    if max_range is None or float(max_range) == model.max_range:
        return model
    return replace(model, max_range=float(max_range))


@dataclass
class Scan:
    """One revolution of the LiDAR.

    Attributes:
        points: structured array with fields x, y, z, intensity (float32) and ring (uint16),
            in the lidar frame at each point's firing time (no deskew); misses are omitted.
        object_ids: int32 per point, the ``object_id`` of the object hit, -1 for the ground
            and the tree line.
        sign_hits: sign ``object_id`` -> int64 indices into ``points`` of the returns on the
            sign's front face.  Signs without returns are absent.
    """

    points: np.ndarray
    object_ids: np.ndarray
    sign_hits: dict[int, np.ndarray]
