"""Documented configuration fields: one source of truth for a knob's default, text and range.

A core configuration dataclass declares each tunable field with :func:`knob`; the node
wrapping it turns every such field into a ROS parameter with that default, description and
range (:func:`workzone_ros.nodes.params.params_from_dataclass`), so a new knob is a node
parameter, documented, without a second table to keep in step.  The dataclass checks its
own fields' ranges with :func:`check_knobs`.  No rclpy here.
"""
from __future__ import annotations

import math
from dataclasses import field, fields
from typing import Any, Optional, Sequence

__all__ = ['knob', 'check_knobs']


def knob(default: Any, doc: str, min: Optional[float] = None, max: Optional[float] = None,
         choices: Optional[Sequence] = None, **extra: Any) -> Any:
    """A dataclass field with its description and range in ``metadata``.

    Args:
        default: the default value (a scalar, or a tuple of scalars for a list parameter).
        doc: one line on what the knob does: the node parameter's description (required).
        min, max: inclusive numeric range of the node parameter (None: unbounded).
        choices: the allowed values of a string knob.
        extra: further metadata for the dataclass's own validation (:func:`check_knobs`
            reads ``check``, ``open_lo``, ``open_hi``, ``integer`` and ``note``).

    Raises:
        ValueError: an empty ``doc`` (nobody adds an undocumented knob).
    """
    if not isinstance(doc, str) or not doc.strip():
        raise ValueError(f'knob with default {default!r}: doc must say what it does')
    meta = {'doc': doc, 'min': min, 'max': max,
            'choices': tuple(choices) if choices is not None else None, **extra}
    return field(default=default, metadata=meta)


def check_knobs(obj: Any, error: type[Exception] = ValueError) -> None:
    """Check every scalar knob of the dataclass instance ``obj`` against its metadata.

    The range checked is the knob's ``min`` / ``max`` unless its metadata says otherwise:

    * ``check``: ``False``: no range check here (``min`` / ``max`` are the node parameter's
      range alone); ``(lo, hi)``: this range instead of ``min`` / ``max`` (None: unbounded).
    * ``open_lo`` / ``open_hi``: the lower / upper bound itself is excluded (the node
      parameter's range, always inclusive, stays closed).
    * ``integer``: the value must be a whole number in ``lo..hi`` (``x in range(lo, hi + 1)``).
      Otherwise an int field's value is compared as ``int(value)``, a float field's as is.
    * ``note``: the unit and what special values (0: off) mean, put in the message.

    NaN is never in a range.  ``choices``: the value must be one of them.  Tuple fields and
    relations between fields are the dataclass's own ``__post_init__`` business.

    Raises:
        error: ``'<field> must be in [lo, hi] (<note>), got <value>'`` for the first field out
            of its range, ``'<field> <value> is not one of (...)'`` for a choice.
    """
    for f in fields(obj):
        meta = f.metadata
        if 'doc' not in meta:
            continue
        value = getattr(obj, f.name)
        choices = meta.get('choices')
        if choices is not None and value not in choices:
            raise error(f'{f.name} {value!r} is not one of {tuple(choices)}')
        check = meta.get('check', True)
        if check is False:
            continue
        lo, hi = (meta.get('min'), meta.get('max')) if check is True else check
        if lo is None and hi is None:
            continue
        if not _in_range(value, lo, hi, meta, type(f.default) is int):
            raise error(f'{f.name} must be {_range_text(lo, hi, meta)}'
                        + (f' ({meta["note"]})' if meta.get('note') else '')
                        + f', got {value!r}')


def _in_range(value: Any, lo: Any, hi: Any, meta: Any, is_int: bool) -> bool:
    try:
        if meta.get('integer'):
            return value in range(int(lo), int(hi) + 1)
        v = int(value) if is_int else value
        if isinstance(v, float) and math.isnan(v):
            return False
        return ((lo is None or (v > lo if meta.get('open_lo') else v >= lo))
                and (hi is None or (v < hi if meta.get('open_hi') else v <= hi)))
    except (TypeError, ValueError, OverflowError):
        return False


def _range_text(lo: Any, hi: Any, meta: Any) -> str:
    if meta.get('integer'):
        return f'an integer in {lo}..{hi}'
    if hi is None:
        return f'{">" if meta.get("open_lo") else ">="} {lo:g}'
    if lo is None:
        return f'{"<" if meta.get("open_hi") else "<="} {hi:g}'
    return (f'in {"(" if meta.get("open_lo") else "["}{lo:g}, {hi:g}'
            f'{")" if meta.get("open_hi") else "]"}')
