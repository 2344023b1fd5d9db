"""Minimal PCD (Point Cloud Library file format v0.7) reader: ascii, binary, binary_compressed.

ascii and binary are read with numpy alone.  binary_compressed stores the points column by
column (structure of arrays) compressed with LZF; its decompression needs the small C
extension ``python-lzf`` (``import lzf``), imported only when such a file is read.  The
result is a packed numpy structured array like the one ``core.pointcloud`` builds from a
PointCloud2, so the LiDAR chain runs unchanged on PCD files (the PJLab real scenes).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ['PcdError', 'read_pcd', 'parse_header']

_TYPES = {('F', 4): 'f4', ('F', 8): 'f8', ('U', 1): 'u1', ('U', 2): 'u2', ('U', 4): 'u4',
          ('U', 8): 'u8', ('I', 1): 'i1', ('I', 2): 'i2', ('I', 4): 'i4', ('I', 8): 'i8'}


class PcdError(ValueError):
    """A PCD file this reader cannot parse; the message names the problem."""


def parse_header(lines: list[str]) -> dict:
    """Parse the header lines (up to and including ``DATA``) into a dict of token lists."""
    header: dict = {}
    for line in lines:
        line = line.strip()
        if not line or line.startswith('#'):
            continue
        key, *values = line.split()
        header[key.upper()] = values
    for key in ('FIELDS', 'SIZE', 'TYPE', 'DATA'):
        if key not in header:
            raise PcdError(f'PCD header has no {key} line')
    return header


def _dtype(header: dict) -> np.dtype:
    names, sizes, types = header['FIELDS'], header['SIZE'], header['TYPE']
    counts = header.get('COUNT', ['1'] * len(names))
    if not len(names) == len(sizes) == len(types) == len(counts):
        raise PcdError('PCD header FIELDS/SIZE/TYPE/COUNT lengths differ')
    fmts = []
    for name, size, typ, count in zip(names, sizes, types, counts):
        base = _TYPES.get((typ.upper(), int(size)))
        if base is None:
            raise PcdError(f'PCD field {name!r} has unsupported TYPE {typ} SIZE {size}')
        fmts.append((name, '<' + base) if int(count) == 1 else (name, '<' + base, (int(count),)))
    seen: dict[str, int] = {}
    out = []
    for f in fmts:          # PCL pads with fields all named '_'
        n = seen.get(f[0], 0)
        seen[f[0]] = n + 1
        out.append((f[0] if n == 0 else f'{f[0]}_{n}',) + f[1:])
    return np.dtype(out)


def read_pcd(path: str | os.PathLike) -> np.ndarray:
    """Read a PCD file into a flat packed structured array (one field per PCD field).

    Args:
        path: the ``.pcd`` file.

    Returns:
        ``(POINTS,)`` structured array, little-endian fields in file order.

    Raises:
        PcdError: malformed header, unsupported DATA kind, truncated data, or
            binary_compressed without the ``lzf`` module (``pip install python-lzf``).
    """
    raw = Path(path).read_bytes()
    lines, pos = [], 0
    while True:
        end = raw.find(b'\n', pos)
        if end < 0:
            raise PcdError(f'{path}: no DATA line in the header')
        line = raw[pos:end].decode('ascii', errors='replace')
        lines.append(line)
        pos = end + 1
        if line.strip().upper().startswith('DATA'):
            break
    header = parse_header(lines)
    dtype = _dtype(header)
    n = int(header.get('POINTS', [0])[0]) if 'POINTS' in header else \
        int(header['WIDTH'][0]) * int(header['HEIGHT'][0])
    kind = header['DATA'][0].lower()
    body = raw[pos:]
    if kind == 'ascii':
        table = np.loadtxt(body.decode('ascii').splitlines(), ndmin=2, dtype=np.float64)
        out = np.zeros(table.shape[0], dtype=dtype)
        col = 0
        for name in dtype.names:
            width = int(np.prod(dtype[name].shape)) if dtype[name].shape else 1
            out[name] = table[:, col] if width == 1 else table[:, col:col + width]
            col += width
        return out
    if kind == 'binary':
        if len(body) < n * dtype.itemsize:
            raise PcdError(f'{path}: binary data has {len(body)} bytes, need {n * dtype.itemsize}')
        return np.frombuffer(body, dtype=dtype, count=n).copy()
    if kind == 'binary_compressed':
        try:
            import lzf  # python-lzf; only this DATA kind needs it
        except ImportError:
            raise PcdError(f'{path} is binary_compressed: reading it needs the LZF module '
                           f'(pip install python-lzf)') from None
        comp, size = np.frombuffer(body[:8], dtype='<u4')
        payload = lzf.decompress(body[8:8 + int(comp)], int(size))
        if payload is None or len(payload) != int(size):
            raise PcdError(f'{path}: LZF decompression failed')
        out = np.zeros(n, dtype=dtype)
        off = 0
        for name in dtype.names:           # structure of arrays: one column after another
            sub = dtype[name]
            nbytes = sub.itemsize * n
            out[name] = np.frombuffer(payload, dtype=sub.base, count=n * max(1, int(
                np.prod(sub.shape))), offset=off).reshape((n,) + sub.shape)
            off += nbytes
        return out
    raise PcdError(f'{path}: PCD DATA {kind!r} is not supported (ascii, binary, '
                   f'binary_compressed)')
