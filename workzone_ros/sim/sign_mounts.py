"""Sign mounts of the scene builder: the height of a sign face above the road, whether it is
on a post or a portable stand (:func:`sign_mount`), and the mast, legs and flags of a stand
(:func:`stand_parts`).  The mount rules are in the docstring of :mod:`workzone_ros.sim.scenario`.
"""
from __future__ import annotations

import math

import numpy as np

from workzone_ros.sim.scenario_spec import STAND_BOTTOM_RANGE
from workzone_ros.sim.world import Cylinder, Quad, SignPanel

__all__ = ['STAND_FOOT', 'sign_bottom', 'sign_mount', 'stand_parts']


STAND_FOOT = 0.3          # lateral reach of a stand's legs from the mast (m)
_STAND_BACK = 0.06        # mast and legs this far behind the face
_FLAG_BACK = 0.09         # flags this far behind the face
_FLAG_SIDE = 0.36         # flag size (m); real ones are 16 in = 0.41 m


def sign_bottom(sign: SignPanel) -> float:
    """Height (m) of the bottom of the face's untilted bounding rectangle above the road."""
    return float(sign.center[2] - sign.height / 2)


def sign_mount(sign: SignPanel) -> str:
    """``'stand'`` for a face whose bottom is in :data:`STAND_BOTTOM_RANGE`, else ``'post'``."""
    return 'stand' if sign_bottom(sign) <= STAND_BOTTOM_RANGE[1] + 1e-9 else 'post'


def stand_parts(sign: SignPanel, flags: bool, new_id) -> list:
    """The portable stand under ``sign``: a mast, two splayed legs and optionally two flags.

    The mast is a thin vertical :class:`Cylinder` (kind ``stand``, behind the face up to near
    its top, or just above it when the stand carries flags); the legs are thin slanted
    :class:`Quad` strips (kind ``stand_leg``) in a plane behind the face, from feet
    :data:`STAND_FOOT` to either side up to the mast; the flags are two orange squares (kind
    ``stand_flag``) leaning out above the face.  Nothing covers the face from the front.

    Args:
        sign: the face (its ``center`` z already at bottom + height / 2).
        flags: add the two flags.
        new_id: callable returning fresh object ids.

    Returns:
        The objects, to append to ``Scene.objects``.
    """
    yaw, h = sign.yaw, sign.height
    right = np.array([-math.sin(yaw), math.cos(yaw), 0.0])     # viewer's right
    up = np.array([0.0, 0.0, 1.0])
    bottom = sign_bottom(sign)
    top = bottom + h
    base = np.asarray(sign.center, float) - sign.normal * _STAND_BACK
    base[2] = 0.0

    def at(origin, u, z):
        return origin + u * right + z * up

    mast_top = top + 0.1 if flags else bottom + 0.85 * h
    out: list = [Cylinder(new_id(), 'stand', base, 0.022, mast_top, 'post')]
    join = min(0.45, 0.8 * bottom)
    for side in (-1.0, 1.0):
        foot, knee = np.array([side * STAND_FOOT, 0.0]), np.array([0.0, join])
        n = np.array([knee[1] - foot[1], foot[0] - knee[0]])
        n *= 0.018 / np.linalg.norm(n)
        out.append(Quad(new_id(), 'stand_leg', np.array(
            [at(base, *(knee + n)), at(base, *(knee - n)), at(base, *(foot - n)),
             at(base, *(foot + n))]), 'post'))
    if flags:
        fb = np.asarray(sign.center, float) - sign.normal * _FLAG_BACK
        fb[2] = 0.0
        c30, s30 = math.cos(math.radians(30)), math.sin(math.radians(30))
        for side in (-1.0, 1.0):
            a = np.array([side * 0.2, top + 0.06])
            e1 = _FLAG_SIDE * np.array([side * c30, s30])
            e2 = _FLAG_SIDE * np.array([-side * s30, c30])
            out.append(Quad(new_id(), 'stand_flag', np.array(
                [at(fb, *(a + e2)), at(fb, *(a + e1 + e2)), at(fb, *(a + e1)), at(fb, *a)]),
                'cone_orange'))
    return out
