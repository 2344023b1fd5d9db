"""PointCloud2 field layouts <-> numpy structured dtypes, with no rclpy import.

A field is described by a plain :class:`FieldSpec` (name, offset, datatype, count) with the
``sensor_msgs/PointField`` datatype codes, so the simulator, the bag tools and the nodes share
one implementation (modelled on common_interfaces' ``sensor_msgs_py/point_cloud2.py``).
Views into the message buffer are made without copies.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

__all__ = [
    'PointCloudError', 'FieldSpec', 'INT8', 'UINT8', 'INT16', 'UINT16', 'INT32', 'UINT32',
    'FLOAT32', 'FLOAT64', 'DATATYPES', 'fields_to_dtype', 'dtype_to_fields', 'cloud_view',
    'xyz_array', 'make_points',
]


class PointCloudError(ValueError):
    """A point cloud whose layout or size is inconsistent; the message names the problem."""


INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)

#: sensor_msgs/PointField datatype code -> numpy scalar type (little-endian base).
DATATYPES: dict[int, np.dtype] = {
    INT8: np.dtype('i1'), UINT8: np.dtype('u1'), INT16: np.dtype('i2'),
    UINT16: np.dtype('u2'), INT32: np.dtype('i4'), UINT32: np.dtype('u4'),
    FLOAT32: np.dtype('f4'), FLOAT64: np.dtype('f8'),
}
_CODES = {v.str[1:]: k for k, v in DATATYPES.items()}


class FieldSpec(NamedTuple):
    """One ``sensor_msgs/PointField``: name, byte offset, datatype code, element count."""

    name: str
    offset: int
    datatype: int
    count: int = 1


def fields_to_dtype(fields: Sequence[FieldSpec], point_step: int,
                    is_bigendian: bool = False) -> np.dtype:
    """Build the structured dtype of one point.

    Args:
        fields: the message's fields, at any offsets and of any datatype.
        point_step: bytes per point (padding after the last field is allowed).
        is_bigendian: the message's big-endian flag.

    Returns:
        A structured dtype with ``itemsize == point_step``.

    Raises:
        PointCloudError: unknown datatype, duplicate names, or a field past ``point_step``.
    """
    if not 0 <= point_step < 2 ** 31:           # numpy's itemsize is a C int
        raise PointCloudError(f'point_step {point_step} is out of range (0 to 2^31 - 1)')
    order = '>' if is_bigendian else '<'
    names, formats, offsets = [], [], []
    for f in fields:
        if f.datatype not in DATATYPES:
            raise PointCloudError(f'field {f.name!r} has unknown datatype {f.datatype}')
        if f.name in names:
            raise PointCloudError(f'field {f.name!r} appears twice')
        base = DATATYPES[f.datatype].newbyteorder(order)
        count = max(int(f.count), 1)
        size = base.itemsize * count
        if f.offset < 0 or f.offset + size > point_step:
            raise PointCloudError(
                f'field {f.name!r} (offset {f.offset}, {size} bytes) does not fit in '
                f'point_step {point_step}')
        if count > 2 ** 20:
            raise PointCloudError(f'field {f.name!r} has count {count}: at most 2^20 values '
                                  f'per point')
        fmt = base if count == 1 else np.dtype((base, (count,)))
        names.append(f.name)
        formats.append(fmt)
        offsets.append(int(f.offset))
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets,
                     'itemsize': int(point_step)})


def dtype_to_fields(dtype: np.dtype) -> list[FieldSpec]:
    """Inverse of :func:`fields_to_dtype` for a structured dtype.

    Raises:
        PointCloudError: a field type that PointCloud2 cannot express.
    """
    if dtype.names is None:
        raise PointCloudError('point dtype must be structured (named fields)')
    out = []
    for name in dtype.names:
        fmt, offset = dtype.fields[name][:2]
        base, count = (fmt.base, int(np.prod(fmt.shape))) if fmt.shape else (fmt, 1)
        code = _CODES.get(base.str[1:])
        if code is None:
            raise PointCloudError(f'field {name!r} has dtype {base} that PointCloud2 cannot hold')
        out.append(FieldSpec(name, int(offset), code, count))
    return out


def cloud_view(data, fields: Sequence[FieldSpec], point_step: int, width: int, height: int,
               row_step: int, is_bigendian: bool = False) -> np.ndarray:
    """View a PointCloud2 buffer as a flat structured array (no copy when rows are dense).

    Args:
        data: the message's ``data`` (bytes, bytearray, memoryview, array.array or ndarray).
        fields, point_step, width, height, row_step, is_bigendian: the message's layout.

    Returns:
        A 1-D structured array of ``width * height`` points.

    Raises:
        PointCloudError: sizes that do not agree with each other or with the buffer.
    """
    dtype = fields_to_dtype(fields, point_step, is_bigendian)
    buf = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) \
        else data.view(np.uint8).reshape(-1)
    n = int(width) * int(height)
    if n == 0:
        return np.zeros(0, dtype=dtype)
    if row_step < width * point_step:
        raise PointCloudError(
            f'row_step {row_step} is smaller than width*point_step {width * point_step}')
    if buf.size < row_step * height:
        raise PointCloudError(
            f'data has {buf.size} bytes but height*row_step is {row_step * height} '
            f'(width*height = {n} points of {point_step} bytes)')
    if row_step == width * point_step:
        return buf[: n * point_step].view(dtype)
    rows = buf[: row_step * height].reshape(height, row_step)[:, : width * point_step]
    return np.ascontiguousarray(rows).reshape(-1).view(dtype)


def xyz_array(points: np.ndarray, drop_nan: bool = True) -> np.ndarray:
    """Return an (N, 3) float32 array of x, y, z, optionally without non-finite points.

    Raises:
        PointCloudError: the cloud has no x, y or z field.
    """
    missing = [c for c in 'xyz' if points.dtype.names is None or c not in points.dtype.names]
    if missing:
        raise PointCloudError(f'point cloud has no {"/".join(missing)} field')
    out = np.empty((points.shape[0], 3), dtype=np.float32)
    out[:, 0] = points['x']
    out[:, 1] = points['y']
    out[:, 2] = points['z']
    if drop_nan:
        finite = np.isfinite(out[:, 0]) & np.isfinite(out[:, 1]) & np.isfinite(out[:, 2])
        if not finite.all():
            out = out[finite]
    return out


def make_points(**columns: np.ndarray) -> np.ndarray:
    """Pack equal-length 1-D columns into a packed structured array (in the given order).

    Example: ``make_points(x=x, y=y, z=z, intensity=i, ring=r.astype(np.uint16))``.
    """
    lengths = {len(v) for v in columns.values()}
    if len(lengths) > 1:
        raise PointCloudError(f'columns have different lengths: {sorted(lengths)}')
    n = lengths.pop() if lengths else 0
    dtype = np.dtype([(k, np.asarray(v).dtype) for k, v in columns.items()])
    out = np.empty(n, dtype=dtype)
    for k, v in columns.items():
        out[k] = v
    return out
