"""The debug image: a frame with its signs' boxes, track ids, classes and scores, and a banner.

What ``/workzone/debug_image`` shows, so that a person can watch the graph in any image
viewer: work-zone signs in orange, general signs in green, unknown (unclassifiable) boxes in
grey and rejected boxes (background) as thin grey outlines; the banner across the top gives
the phase of ``/workzone/state`` (with the speed limit and lanes) when that topic exists.
No rclpy import.
"""
from __future__ import annotations

from typing import Optional, Sequence

import cv2
import numpy as np

from workzone_ros.interfaces import Box, Sign, WorkzoneState

__all__ = ['draw_debug', 'banner_text']

_COLORS = {'workzone': (0, 140, 255), 'general': (60, 200, 60), 'unknown': (170, 170, 170)}
_PHASE_COLORS = {'unknown': (120, 120, 120), 'none': (90, 90, 90),
                 'approaching': (0, 200, 255), 'inside': (0, 110, 255),
                 'leaving': (200, 160, 0)}
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def _label(sign: Sign) -> str:
    tid = '' if sign.track_id is None else f'#{sign.track_id} '
    if sign.category == 'unknown':
        return f'{tid}unknown'
    speed = f' {sign.speed_limit_mph}mph' if sign.speed_limit_mph is not None else ''
    dist = f' {sign.distance_m:.0f}m' if sign.distance_m is not None else ''
    return f'{tid}{sign.code} {sign.score:.2f}{speed}{dist}'


def _box(img: np.ndarray, box: Box, color, thickness: int) -> tuple[int, int]:
    p0 = (int(round(box.x)), int(round(box.y)))
    cv2.rectangle(img, p0, (int(round(box.x2)), int(round(box.y2))), color, thickness)
    return p0


def banner_text(state: Optional[WorkzoneState]) -> str:
    """The banner's line: phase, likelihood, speed limit and lanes of ``state``."""
    if state is None:
        return 'work zone: no state yet'
    parts = [f'work zone: {state.phase.upper()}', f'p={state.likelihood:.2f}']
    if state.speed_limit_mph is not None:
        parts.append(f'{state.speed_limit_mph} mph')
    if state.lane_shift != 'none':
        parts.append(f'shift {state.lane_shift}')
    if state.lanes_closed:
        parts.append('closed ' + '+'.join(state.lanes_closed))
    if state.stale_inputs:
        parts.append('STALE ' + ','.join(state.stale_inputs))
    return '  '.join(parts)


def draw_debug(frame_bgr: np.ndarray, signs: Sequence[Sign], rejected: Sequence[Box] = (),
               state: Optional[WorkzoneState] = None, show_banner: bool = True) -> np.ndarray:
    """A copy of ``frame_bgr`` with the overlays (the input is not modified)."""
    img = np.ascontiguousarray(frame_bgr).copy()
    for box in rejected:
        _box(img, box, _COLORS['unknown'], 1)
    for sign in signs:
        color = _COLORS.get(sign.category, _COLORS['unknown'])
        x, y = _box(img, sign.box, color, 2)
        text = _label(sign)
        (tw, th), _ = cv2.getTextSize(text, _FONT, 0.45, 1)
        y_text = y - 4 if y - th - 6 >= 0 else int(round(sign.box.y2)) + th + 4
        cv2.rectangle(img, (x, y_text - th - 3), (x + tw + 2, y_text + 3), color, -1)
        cv2.putText(img, text, (x + 1, y_text), _FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    if show_banner:
        phase = state.phase if state is not None else 'unknown'
        cv2.rectangle(img, (0, 0), (img.shape[1], 24), _PHASE_COLORS.get(phase, (90, 90, 90)),
                      -1)
        cv2.putText(img, banner_text(state), (6, 17), _FONT, 0.55, (255, 255, 255), 1,
                    cv2.LINE_AA)
    return img
