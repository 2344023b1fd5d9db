"""Node parameters: the declared table (:class:`Param`: default, type, range, choices,
description) and the parameter-file helpers the base uses to warn about keys no node
declares.  rclpy types only for the descriptors; no node logic.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Optional, Sequence

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

__all__ = ['ConfigError', 'Param', 'params_files', 'yaml_sections', 'section_matches']

_INT_MIN, _INT_MAX = -2 ** 63, 2 ** 63 - 1


class ConfigError(ValueError):
    """A parameter table or parameter value that prevents the node from starting."""


@dataclass(frozen=True)
class Param:
    """One declared parameter: name, default (fixes the type), description and constraints.

    Attributes:
        name: parameter name; dots allowed (the attribute in ``params`` uses ``_``).
        default: default value; bool, int, float, str or a list/tuple of one of them.
        description: shown by ``ros2 param describe`` and in the start-up log.
        min, max: numeric range (inclusive); either may be omitted.
        choices: allowed values of a string parameter.
        read_only: reject every change after start-up.
    """

    name: str
    default: Any
    description: str
    min: Optional[float] = None
    max: Optional[float] = None
    choices: Optional[tuple] = None
    read_only: bool = False

    @property
    def attr(self) -> str:
        """The attribute name in the node's ``params``."""
        return self.name.replace('.', '_')

    def kind(self) -> str:
        """'bool', 'int', 'float', 'str' or '<scalar>[]'."""
        value = self.default
        if isinstance(value, (list, tuple)):
            if not value:
                raise ConfigError(f'parameter {self.name!r}: an empty list default has no type')
            kinds = {_scalar_kind(v) for v in value}
            if kinds == {'int', 'float'}:
                kinds = {'float'}
            if len(kinds) != 1:
                raise ConfigError(f'parameter {self.name!r}: mixed list default {value!r}')
            return kinds.pop() + '[]'
        return _scalar_kind(value)

    def check(self, value: Any) -> Optional[str]:
        """Why ``value`` is not acceptable for this parameter, or None when it is."""
        kind = self.kind()
        scalar = kind[:-2] if kind.endswith('[]') else kind
        values = value if kind.endswith('[]') else [value]
        if kind.endswith('[]') and not isinstance(value, (list, tuple)):
            return f'{self.name} must be a list of {scalar}, got {value!r}'
        for v in values:
            got = _scalar_kind(v, strict=False)
            if got != scalar and not (scalar == 'float' and got == 'int'):
                return f'{self.name} must be {scalar}, got {type(v).__name__} {v!r}'
            if scalar in ('int', 'float'):
                if scalar == 'float' and not math.isfinite(float(v)) and (
                        self.min is not None or self.max is not None):
                    return f'{self.name} = {v} is not finite'
                if self.min is not None and v < self.min:
                    return f'{self.name} = {v} is below the minimum {self.min}'
                if self.max is not None and v > self.max:
                    return f'{self.name} = {v} is above the maximum {self.max}'
            if self.choices is not None and v not in self.choices:
                return (f'{self.name} = {v!r} is not one of '
                        f'{", ".join(repr(c) for c in self.choices)}')
        return None

    def normalise(self, value: Any) -> Any:
        """The value as stored in ``params``: floats as float, lists as tuples."""
        kind = self.kind()
        if kind == 'float':
            return float(value)
        if kind == 'float[]':
            return tuple(float(v) for v in value)
        if kind.endswith('[]'):
            return tuple(value)
        return value

    def descriptor(self) -> ParameterDescriptor:
        """The ``ParameterDescriptor`` this parameter is declared with."""
        kind = self.kind()
        text = self.description
        if self.choices is not None:
            text += f' (one of: {", ".join(str(c) for c in self.choices)})'
        desc = ParameterDescriptor(description=text, read_only=self.read_only)
        if self.choices is not None:
            desc.additional_constraints = 'one of: ' + ', '.join(str(c) for c in self.choices)
        # Floats accept integers too (YAML `1` for a float is the classic start-up failure);
        # the on-set callback checks the type instead of rclpy.
        desc.dynamic_typing = kind in ('float', 'float[]')
        if (self.min is not None or self.max is not None) and kind in ('int', 'float'):
            if kind == 'int':
                desc.integer_range = [IntegerRange(
                    from_value=int(self.min) if self.min is not None else _INT_MIN,
                    to_value=int(self.max) if self.max is not None else _INT_MAX, step=0)]
            else:
                desc.floating_point_range = [FloatingPointRange(
                    from_value=float(self.min) if self.min is not None else -math.inf,
                    to_value=float(self.max) if self.max is not None else math.inf,
                    step=0.0)]
        return desc


def _scalar_kind(value: Any, strict: bool = True) -> str:
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        return 'int'
    if isinstance(value, float):
        return 'float'
    if isinstance(value, str):
        return 'str'
    if strict:
        raise ConfigError(f'unsupported parameter default {value!r}')
    return type(value).__name__


# --- params-file parsing ------------------------------------------------------------------

def params_files(args: Sequence[str]) -> list[str]:
    """The ``--params-file`` paths inside the ``--ros-args`` parts of ``args``."""
    out, in_ros, it = [], False, iter(list(args))
    for arg in it:
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--':
            in_ros = False
        elif in_ros and arg == '--params-file':
            path = next(it, None)
            if path:
                out.append(path)
    return out


def _flatten(params: Any, prefix: str = '') -> list[str]:
    if not isinstance(params, dict):
        return [prefix] if prefix else []
    out = []
    for key, value in params.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        out += _flatten(value, name) if isinstance(value, dict) else [name]
    return out


def yaml_sections(doc: Any, path: str = '') -> list[tuple[str, list[str]]]:
    """(node pattern, flattened parameter names) for every ``ros__parameters`` block."""
    out = []
    if not isinstance(doc, dict):
        return out
    for key, value in doc.items():
        if key == 'ros__parameters':
            out.append((path or '/', _flatten(value)))
        elif isinstance(value, dict):
            sub = str(key) if str(key).startswith('/') else '/' + str(key)
            out += yaml_sections(value, (path.rstrip('/') + sub) if path else sub)
    return out


def section_matches(pattern: str, fqn: str) -> bool:
    """Match a params-file node key like rcl: `*` one token, `**` any, `/**` every node."""
    if pattern in ('/**', '**'):
        return True
    regex = ''
    for part in re.split('(\\*\\*|\\*)', pattern.rstrip('/') or '/'):
        regex += {'**': '.*', '*': '[^/]*'}.get(part, re.escape(part))
    return re.fullmatch(regex, fqn) is not None
