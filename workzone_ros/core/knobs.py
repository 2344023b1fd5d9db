"""Documented configuration fields: one source of truth for a knob's default, text and range.

A core configuration dataclass declares each tunable field with :func:`knob`; the node
wrapping it turns every such field into a ROS parameter with that default, description and
range (:func:`workzone_ros.nodes.params.params_from_dataclass`), so a new knob is a node
parameter, documented, without a second table to keep in step.  No rclpy here.
"""
from __future__ import annotations

from dataclasses import field
from typing import Any, Optional, Sequence

__all__ = ['knob']


def knob(default: Any, doc: str, min: Optional[float] = None, max: Optional[float] = None,
         choices: Optional[Sequence] = None, **extra: Any) -> Any:
    """A dataclass field with its description and range in ``metadata``.

    Args:
        default: the default value (a scalar, or a tuple of scalars for a list parameter).
        doc: one line on what the knob does: the node parameter's description (required).
        min, max: inclusive numeric range of the node parameter (None: unbounded).
        choices: the allowed values of a string knob.
        extra: further metadata for the dataclass's own validation (e.g. ``open_lo``).

    Raises:
        ValueError: an empty ``doc`` (nobody adds an undocumented knob).
    """
    if not isinstance(doc, str) or not doc.strip():
        raise ValueError(f'knob with default {default!r}: doc must say what it does')
    meta = {'doc': doc, 'min': min, 'max': max,
            'choices': tuple(choices) if choices is not None else None, **extra}
    return field(default=default, metadata=meta)
