"""The motion cue: a static sign's size over time as the camera approaches it.

``1 / size`` of a static sign falls linearly with time (by ``v / (f S)`` per second, whatever
its distance); a Theil-Sen fit of a track's detected sizes predicts the next size and gives
the approach rate that tells a sign from a vehicle driving ahead.
"""
from __future__ import annotations

import statistics
from typing import Optional, Sequence

import numpy as np

__all__ = ['predicted_size', 'inverse_size_fit', 'size_from_fit', 'approach_rate']


def predicted_size(history: Sequence[tuple[float, float, float]],
                   frame: float) -> Optional[tuple[float, float]]:
    """Anchor size (w, h) expected at ``frame`` from detected sizes ``(frame, w, h)``.

    A static sign's image size is ``f S / d`` with ``d`` falling at the ego speed, so
    ``1 / size`` is linear in time.  Fitted per side with Theil-Sen (median of the pairwise
    slopes, median intercept): robust to one or two wrong detections.

    Returns:
        The predicted size, or None with fewer than three distinct frames or a prediction
        that is not positive.
    """
    fit = inverse_size_fit(history)
    return None if fit is None else size_from_fit(fit, frame)


def inverse_size_fit(history: Sequence[tuple[float, float, float]]
                     ) -> Optional[tuple[float, float, float, float]]:
    """Theil-Sen fit of :func:`predicted_size`: ``(slope_w, icpt_w, slope_h, icpt_h)`` of
    ``1 / size`` over the frame number, or None with fewer than three distinct frames."""
    if len({h[0] for h in history}) < 3:
        return None
    t = [float(h[0]) for h in history]
    n = len(t)
    pairs = [(a, b) for a in range(n) for b in range(a + 1, n) if t[a] != t[b]]
    out: list[float] = []
    for k in (1, 2):            # plain Python: a handful of points (numpy's overhead rules)
        inv = [1.0 / max(float(h[k]), 1.0) for h in history]
        slope = statistics.median((inv[b] - inv[a]) / (t[b] - t[a]) for a, b in pairs)
        out += [slope, statistics.median(v - slope * x for v, x in zip(inv, t))]
    return out[0], out[1], out[2], out[3]


def size_from_fit(fit: tuple[float, float, float, float],
                  frame: float) -> Optional[tuple[float, float]]:
    """The size (w, h) an :func:`inverse_size_fit` gives at ``frame`` (None when it is not
    positive)."""
    vw, vh = fit[1] + fit[0] * frame, fit[3] + fit[2] * frame
    if vw <= 1e-4 or vh <= 1e-4:
        return None
    return 1.0 / vw, 1.0 / vh


def _theil_sen(t: np.ndarray, v: np.ndarray) -> float:
    """Median of the pairwise slopes of ``v`` over ``t`` (distinct ``t`` only)."""
    i, j = np.triu_indices(len(t), 1)
    ok = t[j] != t[i]
    return float(np.median((v[j][ok] - v[i][ok]) / (t[j][ok] - t[i][ok])))


def approach_rate(history: Sequence[tuple[float, float, float, float, float]],
                  focus: Optional[tuple[float, float]] = None, window: int = 15,
                  min_frames: int = 8, min_offset: float = 1.5) -> Optional[float]:
    """How fast the camera approaches a target, from its image track alone: the fall per
    frame of ``1 / size`` (1/px per frame), which is constant for a static object.

    A static object of size ``S`` at distance ``Z`` has the image size ``s = f S / Z``; with
    the camera approaching at speed ``v``, ``d(1/s)/dt = -v / (f S)``, whatever the distance.
    Its offset ``r`` from the focus of expansion (the image point straight ahead) scales
    like ``s`` (``r = f X / Z``, X its distance from the camera's axis), so
    ``-d(1/r)/dt * (r / s)`` is the same ``v / (f S)``; that estimate is the more precise one
    when the object is far off-centre (``r`` several times ``s``: a pixel of error is a
    smaller share of it), the size estimate the one free of the focus and of camera yaw.
    A vehicle ahead driving at the ego speed keeps its distance: both are near 0.

    Args:
        history: ``(frame, cx, cy, w, h)`` of the target's box, oldest first.
        focus: focus of expansion in pixels, or None for the size estimate alone.
        window: use the entries of the last ``window`` frames.
        min_frames: None when those entries span fewer frames than this.
        min_offset: the offset estimate counts only when the offset is at least this many
            sizes (median of ``r / s``; otherwise an error of the focus dominates it).

    Returns:
        The larger of the size and (where it counts) offset estimates, Theil-Sen fitted;
        None when the history is too short to tell.
    """
    if not history:
        return None
    last = history[-1][0]
    h = np.array([e for e in history if e[0] >= last - window], float)
    if len(h) < 3 or h[-1, 0] - h[0, 0] < min_frames:
        return None
    t = h[:, 0]
    size = np.sqrt(np.maximum(h[:, 3], 1.0) * np.maximum(h[:, 4], 1.0))
    rate = -_theil_sen(t, 1.0 / size)
    if focus is not None:
        r = np.hypot(h[:, 1] - focus[0], h[:, 2] - focus[1])
        ratio = float(np.median(r / size))          # X / S, constant for a static object
        if ratio >= min_offset and r.min() > 0:
            rate = max(rate, -_theil_sen(t, 1.0 / r) * ratio)
    return rate
