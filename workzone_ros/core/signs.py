"""Sign catalogue: class keys, MUTCD-style codes, face sizes, colors and their effect on state.

The work-zone classes are the classifier targets of Seo et al.; the general classes come
from Balali and Golparvar-Fard and from Cahail et al. and never change the work-zone state
(DESIGN.md, "Sign catalogue").
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    'SignClass', 'CATALOGUE', 'BY_KEY', 'WORKZONE_KEYS', 'GENERAL_KEYS', 'CLASSIFIER_KEYS',
    'UnknownSignError', 'get', 'class_id',
]


class UnknownSignError(KeyError):
    """A sign key that is not in the catalogue."""


@dataclass(frozen=True)
class SignClass:
    """One entry of the catalogue.

    Attributes:
        key: stable class key used in every payload.
        code: MUTCD-style code (``W20-1``).
        category: ``workzone``, ``general`` or ``background``.
        shape: ``diamond``, ``rectangle``, ``octagon``, ``triangle``, ``square`` or ``none``.
        colors: dominant face colors, first is the main one (``orange``, ``white``, ...).
        width_m: face width in metres (a diamond's side length for diamonds).
        height_m: face height in metres (a diamond's side length for diamonds).
        effect: what the sign means for the work-zone state (``none`` for general signs).
        legend: the text a person reads on the face (for sign art and reports).
    """

    key: str
    code: str
    category: str
    shape: str
    colors: tuple[str, ...]
    width_m: float
    height_m: float
    effect: str
    legend: str

    @property
    def regulatory_two_color(self) -> bool:
        """True for orange-top / white-bottom regulatory work-zone signs (Seo et al. III.A)."""
        return self.category == 'workzone' and self.colors[:2] == ('orange', 'white')


CATALOGUE: tuple[SignClass, ...] = (
    # Work-zone signs (classifier targets, Seo et al.).
    SignClass('road_work_ahead', 'W20-1', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'approaching', 'ROAD WORK AHEAD'),
    SignClass('work_zone_begin', 'R22-1', 'workzone', 'rectangle', ('orange', 'white'),
              1.2, 1.5, 'begin', 'WORK ZONE BEGINS'),
    SignClass('end_road_work', 'G20-2', 'workzone', 'rectangle', ('orange', 'black'),
              1.2, 0.6, 'end', 'END ROAD WORK'),
    SignClass('work_zone_speed_limit', 'R2-1+G20-5aP', 'workzone', 'rectangle',
              ('orange', 'white'), 1.2, 2.1, 'speed_limit', 'WORK ZONE / SPEED LIMIT 45'),
    SignClass('lane_shift', 'W1-4', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'lane_shift', 'double reverse curve'),
    SignClass('lane_shift_left', 'W1-4L', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'lane_shift_left', 'reverse curve to the left'),
    SignClass('lane_shift_right', 'W1-4R', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'lane_shift_right', 'reverse curve to the right'),
    SignClass('left_lane_ends', 'W4-2L', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'lane_closed_left', 'left lane ends (merge right)'),
    SignClass('right_lane_ends', 'W4-2R', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'lane_closed_right', 'right lane ends (merge left)'),
    SignClass('left_lane_closed_ahead', 'W20-5L', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'lane_closed_left', 'LEFT LANE CLOSED AHEAD'),
    SignClass('right_lane_closed_ahead', 'W20-5R', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'lane_closed_right', 'RIGHT LANE CLOSED AHEAD'),
    SignClass('other_workzone', 'W20-4/W20-7/W21-5', 'workzone', 'diamond', ('orange', 'black'),
              1.2, 1.2, 'in_zone', 'ONE LANE ROAD AHEAD / FLAGGER / SHOULDER WORK'),
    # General signs (Balali and Golparvar-Fard; Cahail et al.): recognised, reported, never
    # change the state.
    SignClass('stop', 'R1-1', 'general', 'octagon', ('red', 'white'), 0.9, 0.9, 'none', 'STOP'),
    SignClass('yield', 'R1-2', 'general', 'triangle', ('red', 'white'), 0.9, 0.78, 'none',
              'YIELD'),
    SignClass('do_not_enter', 'R5-1', 'general', 'square', ('red', 'white'), 0.9, 0.9, 'none',
              'DO NOT ENTER'),
    SignClass('warning_diamond', 'W1-2', 'general', 'diamond', ('yellow', 'black'), 1.2, 1.2,
              'none', 'curve ahead (yellow, not a work zone)'),
    SignClass('speed_limit', 'R2-1', 'general', 'rectangle', ('white', 'black'), 0.9, 1.2,
              'none', 'SPEED LIMIT 65'),
    SignClass('guide', 'D1-1', 'general', 'rectangle', ('green', 'white'), 2.4, 1.2, 'none',
              'exit / destination guide sign'),
    SignClass('mile_marker', 'D10-1', 'general', 'rectangle', ('green', 'white'), 0.3, 0.75,
              'none', 'MILE 123'),
    # Not a sign: drums, cones, orange vehicles, foliage (classifier reject class).
    SignClass('background', '-', 'background', 'none', (), 0.0, 0.0, 'none', 'not a sign'),
)

BY_KEY: dict[str, SignClass] = {c.key: c for c in CATALOGUE}
WORKZONE_KEYS: tuple[str, ...] = tuple(c.key for c in CATALOGUE if c.category == 'workzone')
GENERAL_KEYS: tuple[str, ...] = tuple(c.key for c in CATALOGUE if c.category == 'general')
#: Classifier targets in Seo et al.'s order, with the reject class last.
CLASSIFIER_KEYS: tuple[str, ...] = WORKZONE_KEYS + ('background',)


def get(key: str) -> SignClass:
    """Return the catalogue entry for ``key``.

    Raises:
        UnknownSignError: ``key`` is not in the catalogue.
    """
    try:
        return BY_KEY[key]
    except KeyError:
        raise UnknownSignError(
            f'unknown sign class {key!r}; known: {", ".join(BY_KEY)}') from None


def class_id(key: str) -> int:
    """Stable integer id of ``key`` (its position in the catalogue)."""
    get(key)
    return next(i for i, c in enumerate(CATALOGUE) if c.key == key)
