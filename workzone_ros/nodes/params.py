"""Node parameters: the declared table (:class:`Param`: default, type, range, choices,
description), the table of a core configuration dataclass (:func:`params_from_dataclass`,
from its :func:`~workzone_ros.core.knobs.knob` fields) and the parameter-file helpers the
base uses to warn about keys no node declares.  rclpy types only for the descriptors; no
node logic.
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any, Collection, Mapping, Optional, Sequence

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

__all__ = ['ConfigError', 'Param', 'image_params', 'params_from_dataclass', 'params_files',
           'yaml_sections', 'section_matches']

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
            if got == 'bool' and scalar == 'str' and self.choices is not None:
                return (f'{self.name} must be one of {", ".join(map(repr, self.choices))}, got '
                        f'the boolean {v!r} (YAML reads unquoted on, off, yes, no, true and '
                        'false as booleans: quote the value)')
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


def image_params(compressed_note: str = '') -> tuple[Param, Param]:
    """``image_topic`` and ``compressed``: the parameters of a node that reads camera images
    through ``WorkzoneNode.image_subscription`` (raw, or compressed as image_transport
    publishes it); ``compressed_note`` ends the ``compressed`` description."""
    return (Param('image_topic', '/camera/image_raw', 'input camera image (sensor QoS)',
                  read_only=True),
            Param('compressed', False, 'only <image_topic>/compressed (false: raw, or '
                  f'compressed while no raw image arrives{compressed_note})', read_only=True))


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


# --- parameters of a core configuration dataclass ------------------------------------------

_SCALARS = (bool, int, float, str)


def _parameter_default(value: Any) -> Optional[Any]:
    """The Param default of a field default: a scalar, a list for a tuple of scalars, else
    None (not a parameter)."""
    if isinstance(value, _SCALARS):
        return value
    if isinstance(value, (tuple, list)) and value and all(isinstance(v, _SCALARS)
                                                          for v in value):
        return list(value)
    return None


def params_from_dataclass(cls: type, *, only: Optional[Collection[str]] = None,
                          skip: Collection[str] = (), prefix: str = '',
                          defaults: Optional[Mapping[str, Any]] = None) -> tuple[Param, ...]:
    """One :class:`Param` per field of the configuration dataclass ``cls``, in field order.

    Every field whose default is a scalar (bool, int, float, str) or a non-empty tuple of
    scalars (a list parameter) becomes the parameter ``prefix + name`` with that default and
    the field's metadata as :func:`workzone_ros.core.knobs.knob` stores it: ``doc`` (the
    description, required), ``min`` / ``max`` (converted to the default's type) and
    ``choices``.  Other fields (no default, nested objects) are not parameters.

    Args:
        cls: a dataclass (its fields are read, it is not instantiated).
        only: just these fields (each must be a parameter field of ``cls``).
        skip: fields left out (the node declares them itself, or they are not for users).
        prefix: put before every parameter name (``'fusion.'`` -> attribute ``fusion_x``).
        defaults: node defaults that differ from the dataclass's, by field name; the
            description then ends with the dataclass default.

    Raises:
        ConfigError: a parameter field without ``doc`` (at the node module's import, so an
            undocumented knob never ships), or a name in ``only`` / ``skip`` / ``defaults``
            that is no parameter field of ``cls``.
    """
    if not dataclasses.is_dataclass(cls):
        raise ConfigError(f'{cls!r} is not a dataclass')
    defaults = dict(defaults or {})
    table: dict[str, tuple[Any, dataclasses.Field]] = {}
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        if f.default is not dataclasses.MISSING:
            value = f.default
        elif f.default_factory is not dataclasses.MISSING:
            value = f.default_factory()
        else:
            continue
        value = _parameter_default(value)
        if value is not None:
            table[f.name] = (value, f)
    unknown = sorted((set(only or ()) | set(skip) | set(defaults)) - set(table))
    if unknown:
        raise ConfigError(f'{cls.__name__}: {", ".join(unknown)} not a parameter field '
                          f'(parameter fields: {", ".join(table)})')
    out = []
    for name, (value, f) in table.items():
        if name in skip or (only is not None and name not in only):
            continue
        meta = f.metadata or {}
        doc = meta.get('doc')
        if not isinstance(doc, str) or not doc.strip():
            raise ConfigError(f'{cls.__name__}.{name} has no description: declare it with '
                              f'knob(default, doc, ...) (workzone_ros.core.knobs)')
        if name in defaults:
            core, value = value, _parameter_default(defaults[name])
            doc = f'{doc} [{cls.__name__} default: {core}]'
        kind = Param(prefix + name, value, doc).kind().removesuffix('[]')
        bounds = {}
        for key in ('min', 'max'):
            bound = meta.get(key)
            if bound is not None:
                bounds[key] = {'int': int, 'float': float}.get(kind, lambda b: b)(bound)
        choices = meta.get('choices')
        out.append(Param(prefix + name, value, doc, choices=tuple(choices)
                         if choices is not None else None, **bounds))
    return tuple(out)


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
