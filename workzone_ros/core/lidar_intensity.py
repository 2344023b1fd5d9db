"""The intensity scale of a LiDAR, and a warning when nothing is bright enough.

Drivers encode the return strength differently: the Velodyne ROS driver and our simulator
publish 0-255 (float32), KITTI-style reflectance is a 0-1 float, Livox and Hesai 0-255 in a
uint8, others 0-65535 in a uint16.  The candidate thresholds are in 0-255 units (the
retroreflective sheeting of a sign returns ~200-250, paint and car bodies < 100), so the
raw values are multiplied by a scale:

* ``intensity_scale > 0``: that factor, as given;
* ``0`` (auto): from the field's datatype and the values seen over the first scans
  (:func:`infer_encoding`): integers of 8 bits are 0-255; floats up to 1 are reflectance
  0-1 (x 255); values up to 255 are 0-255 (x 1); anything larger is 0-65535 (x 255/65535).
  :class:`IntensityScale` holds the choice and says which it made, and revises it (with a
  message) if later scans hold values its encoding cannot have, 3 scans in a row.

:class:`SilenceWatch` reports when no point reached the threshold for ``n`` scans in a row
while the clouds were not empty: the observed raw range, the scale in use and what to set.

No rclpy here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

__all__ = ['Encoding', 'ENCODINGS', 'infer_encoding', 'IntensityScale', 'SilenceWatch',
           'intensity_summary', 'finite_max']


@dataclass(frozen=True)
class Encoding:
    """One intensity encoding: its name, full scale and factor to 0-255 units."""

    name: str
    full_scale: float
    scale: float


ENCODINGS = {
    'unit': Encoding('reflectance 0-1', 1.0, 255.0),
    '8bit': Encoding('0-255', 255.0, 1.0),
    '16bit': Encoding('0-65535', 65535.0, 255.0 / 65535.0),
}
_ORDER = ('unit', '8bit', '16bit')
_MAX_RAW = ENCODINGS['16bit'].full_scale + 0.5      # the largest raw value of any encoding
REVISE_SCANS = 3            # scans in a row beyond the learned encoding that revise it


def infer_encoding(dtype: np.dtype, max_value: float) -> str:
    """The encoding key of a field from its datatype and the largest value seen.

    Args:
        dtype: the intensity field's numpy dtype.
        max_value: the largest finite value seen (NaN or -inf when none).

    Returns:
        'unit', '8bit' or '16bit' (see :data:`ENCODINGS`).
    """
    kind = np.dtype(dtype).kind
    if kind in 'iu' and np.dtype(dtype).itemsize == 1:
        return '8bit'
    if not np.isfinite(max_value):
        return '8bit' if kind in 'iu' else 'unit'
    if kind == 'f' and max_value <= 1.0 + 1e-6:
        return 'unit'
    if max_value <= 255.0 + 0.5:
        return '8bit'
    return '16bit'


def finite_max(values: np.ndarray) -> float:
    """The largest finite value (NaN when there is none), without a copy or a warning."""
    v = np.asarray(values)
    if v.size == 0:
        return float('nan')
    if v.dtype.kind != 'f':
        return float(v.max())
    top = float(np.fmax.reduce(v))
    if not np.isfinite(top) and top > 0:          # +inf present: ignore it
        fin = v[np.isfinite(v)]
        return float(fin.max()) if fin.size else float('nan')
    return top


def intensity_summary(values: np.ndarray) -> Optional[tuple[float, float, float, float]]:
    """(min, median, p99, max) of the finite values, or None when there are none."""
    v = np.asarray(values)
    if v.dtype.kind == 'f':
        v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    if v.size > 200_000:
        v = v[:: v.size // 100_000]
    lo, med, p99, hi = np.percentile(v, [0, 50, 99, 100])
    return float(lo), float(med), float(p99), float(hi)


class IntensityScale:
    """The factor from raw intensity to 0-255 units: fixed, or learned over the first scans.

    Args:
        fixed: a factor > 0 to use as given; 0 learns it.
        learn_scans: scans over which the encoding is learned (the first scan is already
            used with its own guess).
    """

    def __init__(self, fixed: float = 0.0, learn_scans: int = 3) -> None:
        if fixed < 0 or not np.isfinite(fixed):
            raise ValueError(f'intensity_scale must be 0 (auto) or a factor > 0, got {fixed}')
        self.fixed = float(fixed)
        self.learn_scans = max(int(learn_scans), 1)
        self.scans = 0
        self.max_seen = -np.inf
        self.encoding: Optional[str] = None
        self._beyond = 0                # learned: scans in a row beyond the encoding
        self._messages: list[str] = []
        if self.fixed > 0:
            self._messages.append(f'intensity: scale x{self.fixed:g} (intensity_scale, as '
                                  'given)')

    @property
    def scale(self) -> float:
        """The current factor (1.0 before any scan in auto mode)."""
        if self.fixed > 0:
            return self.fixed
        return ENCODINGS[self.encoding].scale if self.encoding else 1.0

    def pop_messages(self) -> list[str]:
        """Lines to log (the choice, and any later revision), once each."""
        out, self._messages = self._messages, []
        return out

    def update(self, values: np.ndarray) -> float:
        """Feed one scan's raw intensity column; returns the factor to use for it."""
        if self.fixed > 0:
            return self.fixed
        v = np.asarray(values)
        # Once learned, a strided look is enough to notice values the encoding cannot have.
        sample = v if self.scans < self.learn_scans else v[::8]
        top = finite_max(sample)
        if top > _MAX_RAW:
            # no encoding holds it (a FLT_MAX fill, a broken driver): one such scan must not
            # turn the scale down for good, so only the plausible values teach anything
            sample = np.asarray(sample, dtype=np.float64)
            top = finite_max(sample[sample <= _MAX_RAW])
        self.scans += 1
        if self.encoding is not None and self.scans > self.learn_scans:
            # Learned: values the encoding cannot hold revise it only when they come back
            # REVISE_SCANS scans in a row (a real mismatch does; one garbage scan, say
            # byte-swapped floats, must not turn the scale down for good).
            beyond = np.isfinite(top) and _ORDER.index(
                infer_encoding(v.dtype, top)) > _ORDER.index(self.encoding)
            self._beyond = self._beyond + 1 if beyond else 0
            if self._beyond < REVISE_SCANS:
                return self.scale
        if np.isfinite(top):
            self.max_seen = max(self.max_seen, top)
        new = infer_encoding(v.dtype, self.max_seen)
        if self.encoding is None or (new != self.encoding and (
                self.scans <= self.learn_scans or _ORDER.index(new) > _ORDER.index(
                    self.encoding))):
            enc = ENCODINGS[new]
            what = 'chose' if self.encoding is None else 'revised to'
            self._messages.append(
                f'intensity: {v.dtype} values up to {self.max_seen:g} -> {what} {enc.name}, '
                f'scale x{enc.scale:.6g} to 0-255 units (set intensity_scale to override)')
            self.encoding = new
        return self.scale


class SilenceWatch:
    """Says so when ``n`` non-empty scans in a row had no point bright enough.

    Args:
        n: scans in a row before the first report (and again every ``n`` scans).
    """

    def __init__(self, n: int = 20) -> None:
        self.n = max(int(n), 1)
        self.run = 0

    def update(self, n_points: int, n_bright: int, raw: np.ndarray, scale: float,
               threshold: float) -> Optional[str]:
        """Feed one scan's counts; returns a warning line every ``n`` silent scans in a row.

        Args:
            n_points: finite points in the scan.
            n_bright: points at or above the threshold.
            raw: the raw intensity column (summarised in the message).
            scale: factor in use.
            threshold: ``min_intensity`` in 0-255 units.
        """
        if n_points == 0 or n_bright > 0:
            self.run = 0
            return None
        self.run += 1
        if self.run % self.n:
            return None
        s = intensity_summary(raw)
        if s is None:
            seen = 'no finite intensity values'
        else:
            seen = (f'raw intensity {s[0]:g}..{s[3]:g} (median {s[1]:g}, p99 {s[2]:g}), '
                    f'x{scale:.6g} = up to {s[3] * scale:.0f} in 0-255 units')
        return (f'no point reached min_intensity {threshold:g} (0-255 units) in the last '
                f'{self.run} scans ({n_points} points in the last): {seen}; if the encoding '
                f'is wrong set intensity_scale (raw -> 0-255 factor), else lower min_intensity')
