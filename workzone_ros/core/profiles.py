"""Row and band profiles of a blob: the cone / drum band tests.

Traffic cones and drums carry white retro-reflective bands across their width between orange
parts (MUTCD 6F.63, 6F.64); a sign face has none.  These tests work on boolean masks of a
strip of columns over a blob and are shared by the colour detector (which rejects such blobs)
and the tracker (which stops a track that slid onto one).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from workzone_ros.core.profile_kernels import banded_kernel, row_share_at_least, taper_kernel

__all__ = ['row_extents', 'row_taper', 'open_background_rows', 'white_cap', 'banded_rows']


def row_extents(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row centre, left edge, right edge) of every non-empty row of a binary mask.

    Edges in continuous coordinates (pixel ``i`` spans ``[i, i + 1)``).
    """
    m = mask > 0
    rows = np.nonzero(m.any(axis=1))[0]
    if rows.size == 0:
        return rows.astype(float), rows.astype(float), rows.astype(float)
    sub = m[rows]
    left = np.argmax(sub, axis=1).astype(float)
    right = (m.shape[1] - np.argmax(sub[:, ::-1], axis=1)).astype(float)
    return rows + 0.5, left, right


def row_taper(mask: np.ndarray) -> float:
    """A blob's mean width over its upper rows (15-40 % of its height from the top) over its
    mean width over its lower rows (60-85 %): about 1 for a diamond or a rectangle (symmetric
    about the middle row), about 0.7-0.8 for the orange part of a traffic cone below its
    band (a truncated cone, its top about a fifth of its base: MUTCD 6F.63).  1.0 for a blob
    of fewer than 5 rows."""
    return float(taper_kernel(mask))      # (compiled: the numpy form is in its test)


def open_background_rows(left: np.ndarray, right: np.ndarray, min_cols: int
                         ) -> Optional[np.ndarray]:
    """Rows whose white runs on past a blob on both flanks (``left``, ``right``: the white
    masks beside it): the background (an overcast sky, snow, a wall), not a band of the
    object's own.  A flank cut by the image border (narrower than ``min_cols``) does not
    count, the other one decides (a sign leaving the frame with its stand's flags over the
    sky); None when neither flank is in the frame."""
    sides = [row_share_at_least(m, 0.5) for m in (left, right) if m.shape[1] >= min_cols]
    return np.logical_and.reduce(sides) if sides else None


def white_cap(white: np.ndarray, top: int, min_run: int, gap: int, min_white: float = 0.5
              ) -> bool:
    """True when at least ``min_run`` rows at least ``min_white`` white lie right above row
    ``top`` of a strip (within ``gap`` rows of it): a cone's white band over its orange
    body."""
    w = float(max(white.shape[1], 1))
    is_w = white.sum(axis=1) / w >= min_white
    n = 0
    for i in range(top - 1, max(-1, top - 1 - gap - min_run - 1), -1):
        if is_w[i]:
            n += 1
            if n >= min_run:
                return True
        elif n:
            break
    return False


def banded_rows(orange: np.ndarray, white: np.ndarray, dark: np.ndarray, top: int, bottom: int,
                min_run: int, gap: int, max_band: int, min_beyond: int = 3,
                min_white: float = 0.5,
                min_orange: float = 0.2, line: float = 0.9) -> bool:
    """True when a white band separates the blob from more orange above or below it.

    ``orange``, ``white``, ``dark``: boolean masks of a strip of columns over a blob (its
    orange, white and dark pixels; the strip's rows reach beyond the blob above and
    below); the blob spans rows ``top`` .. ``bottom - 1``.  Traffic cones and drums (MUTCD
    6F.63, 6F.64) carry horizontal white retro-reflective bands across their whole width
    between orange parts.  From the blob's top edge upward (and from its bottom edge
    downward): at most ``gap`` rows of blend, then a band of at most ``max_band`` rows
    holding at least ``min_run`` rows that are at least ``min_white`` white, then at least
    ``min_beyond`` consecutive rows that are at least ``min_orange`` orange (fewer are part of
    the band: a legend's edges blended with a reddish light); or, inside the blob, such a
    band between orange rows.  A row at least ``line`` dark ends the search (a two-colour
    sign's white part ends at its black border line).
    """
    n = orange.shape[0]
    if n == 0 or orange.shape[1] == 0:
        return False
    # (compiled: the numpy form is in its test)
    return bool(banded_kernel(orange, white, dark, top, bottom, min_run, gap, max_band,
                              min_beyond, min_white, min_orange, line))
