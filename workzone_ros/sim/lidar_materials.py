"""Materials and sign shapes as the LiDAR caster sees them: material indices, reflectivity and
retroreflection tables, the road paint layout, and the real outline of a sign face
(:func:`sign_shape_contains`).
"""
from __future__ import annotations

import numpy as np

from ..core.signs import BY_KEY
from .lidar_model import LidarError
from .world import MATERIALS, SignPanel

__all__ = ['sign_shape_contains']

_MAT_NAMES = list(MATERIALS)
_MAT = {name: i for i, name in enumerate(_MAT_NAMES)}
_REFL = np.array([MATERIALS[n].reflectivity for n in _MAT_NAMES])
_REFL32 = _REFL.astype(np.float32)
_RETRO = np.array([MATERIALS[n].retroreflective for n in _MAT_NAMES])

_PAINT_HALF_WIDTH = 0.075        # 6 in (0.15 m) lines
_DASH_LINE_D = 1.5 * 3.7 - 3.7   # 1.85 m: lane boundaries between the three lanes
_DASH_PERIOD, _DASH_LENGTH = 12.0, 3.0     # the dash is a quarter of the period

_SHAPES = {'diamond', 'rectangle', 'square', 'octagon', 'triangle', 'circle'}


def _mat_index(name: str) -> int:
    try:
        return _MAT[name]
    except KeyError:
        raise LidarError(f'unknown material {name!r}; known: {", ".join(_MAT_NAMES)}') from None


def _sign_shape(sign: SignPanel) -> str:
    entry = BY_KEY.get(sign.class_key)
    shape = entry.shape if entry is not None else 'rectangle'
    return shape if shape in _SHAPES else 'rectangle'


def sign_shape_contains(shape: str, u: np.ndarray, v: np.ndarray, half_w: float,
                        half_h: float) -> np.ndarray:
    """Whether face coordinates lie inside a sign's real shape.

    The shape is inscribed in the sign's bounding rectangle: a diamond is the rhombus through
    the edge midpoints, an octagon the regular octagon whose sides touch the rectangle, a
    triangle (yield) points down, a circle is the inscribed ellipse.

    Args:
        shape: ``diamond``, ``rectangle``, ``square``, ``octagon``, ``triangle`` or ``circle``.
        u: coordinates towards the viewer's right, from the face centre (m).
        v: coordinates upwards in the face plane, from the face centre (m).
        half_w: half the bounding rectangle's width.
        half_h: half the bounding rectangle's height.

    Returns:
        Boolean array shaped like ``u``.
    """
    a, b = np.abs(u) / half_w, np.abs(v) / half_h
    if shape == 'diamond':
        return a + b <= 1.0
    if shape == 'octagon':
        return (a <= 1.0) & (b <= 1.0) & (a + b <= np.sqrt(2.0))
    if shape == 'triangle':
        return (v <= half_h) & (a <= (v / half_h + 1.0) / 2.0)
    if shape == 'circle':
        return a * a + b * b <= 1.0
    return (a <= 1.0) & (b <= 1.0)
