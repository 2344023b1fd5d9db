"""Hypothesis strategies of malformed ROS messages, for ``workzone-ros evaluate faults``.

Each strategy starts from a good message of the node under test (``good(stamp) -> msg``, so
every fault is stamped like live input) and draws one to three malformations of its type:

* ``PointCloud2``: wrong or duplicated field offsets, names, datatypes and counts, wrong
  ``point_step`` / ``row_step``, truncated or padded data, NaN/inf values, zero and huge
  sizes, big-endian (byte-swapped or not), missing fields, large valid clouds;
* ``Image``: wrong ``step`` or encoding, a size that does not match the data, zero and huge
  sizes, an invalid ``is_bigendian``, degenerate (1 px) and valid re-encoded images;
* ``CompressedImage``: garbage, truncated or corrupted JPEG, a JPEG/PNG header declaring a
  huge image (a decompression bomb), an empty buffer, odd ``format`` strings;
* ``CameraInfo``: zero, NaN, inf or negative K, a wrong D length, NaN or huge D, unknown
  distortion models, zero and huge sizes, NaN R/P;
* ``Odometry``: NaN/inf/huge positions, NaN, zero and non-unit quaternions, an invalid stamp;
* ``std_msgs/String`` payloads: invalid JSON, a wrong, unknown or missing schema, any field
  set to an out-of-range value or a wrong type, unknown and missing fields, very long strings
  and lists.

A :class:`Fault` carries a short ``kind`` (the report's category) and the drawn values, so a
failing example prints what to replay.  Imports hypothesis: a test/tool dependency only.
"""
from __future__ import annotations

import array
import copy
import json
import math
import struct
from dataclasses import dataclass, field
from typing import Any, Callable

import cv2
import numpy as np
from hypothesis import strategies as st

__all__ = ['Fault', 'pointcloud2_faults', 'image_faults', 'compressed_faults',
           'camera_info_faults', 'odometry_faults', 'payload_faults', 'faults_for']

Good = Callable[[Any], Any]          # stamp (builtin_interfaces/Time) -> a good message
U32 = 2 ** 32 - 1
_DATA_FIRST = {'NaN/inf values', 'big-endian', 'corrupted jpeg', 'huge declared size'}


@dataclass(frozen=True)
class Fault:
    """One malformed message: what is wrong with it and how to build it for a stamp."""

    kind: str
    steps: tuple = ()
    build: Callable[[Any], Any] = field(default=None, repr=False, compare=False)

    def __str__(self) -> str:
        return self.kind + (f' {list(self.steps)}' if self.steps else '')


def _fault(good: Good, steps: list, to_layout: Callable, from_layout: Callable) -> Fault:
    """A Fault that applies ``steps`` ((name, fn, args)) to the layout of a good message."""
    # value and re-encoding mutations need the good layout: they go first
    steps = sorted(steps, key=lambda s: 0 if s[0].endswith('(valid)') else
                   1 if s[0] in _DATA_FIRST else 2)

    def build(stamp: Any) -> Any:
        msg = good(stamp)
        layout = to_layout(msg)
        for _, fn, args in steps:
            fn(layout, *args)
        msg = from_layout(msg, layout)
        if layout.get('nanosec') is not None:
            msg.header.stamp.nanosec = layout['nanosec']
        return msg
    kind = ' + '.join(dict.fromkeys(name for name, _, _ in steps))
    return Fault(kind, tuple((name, args) for name, _, args in steps), build)


def _mutations(options: dict) -> st.SearchStrategy:
    """Draw one of ``options`` (name -> strategy of argument tuples) as (name, fn, args)."""
    return st.one_of([args.map(lambda a, n=name, f=fn: (n, f, a))
                      for name, (fn, args) in options.items()])


def _data(b: bytes) -> array.array:
    return array.array('B', b)


# --- PointCloud2 --------------------------------------------------------------------------

def _cloud_layout(msg: Any) -> dict:
    return dict(fields=[[f.name, int(f.offset), int(f.datatype), int(f.count)]
                        for f in msg.fields],
                point_step=int(msg.point_step), width=int(msg.width), height=int(msg.height),
                row_step=int(msg.row_step), is_bigendian=bool(msg.is_bigendian),
                data=bytes(msg.data))


def _cloud_msg(msg: Any, c: dict) -> Any:
    from sensor_msgs.msg import PointField
    msg.fields = [PointField(name=n, offset=o, datatype=d, count=k)
                  for n, o, d, k in c['fields']]
    msg.point_step, msg.width, msg.height = c['point_step'], c['width'], c['height']
    msg.row_step, msg.is_bigendian = c['row_step'], c['is_bigendian']
    msg.data = _data(c['data'])
    return msg


def _field(c: dict, i: int) -> list:
    return c['fields'][i % len(c['fields'])] if c['fields'] else ['x', 0, 7, 1]


def _cloud_dtype(c: dict, big: bool = False) -> np.dtype:
    from workzone_ros.core.pointcloud import DATATYPES
    return np.dtype({'names': [f[0] for f in c['fields']],
                     'formats': [DATATYPES[f[2]].newbyteorder('>' if big else '<')
                                 for f in c['fields']],
                     'offsets': [f[1] for f in c['fields']], 'itemsize': c['point_step']})


def _set_values(c: dict, value: float, every: int) -> None:
    arr = np.frombuffer(c['data'], dtype=_cloud_dtype(c)).copy()
    for name in arr.dtype.names:
        if arr.dtype[name].kind == 'f':
            arr[name][::every] = value
    c['data'] = arr.tobytes()


def _big_endian(c: dict, swap: bool) -> None:
    if swap:
        arr = np.frombuffer(c['data'], dtype=_cloud_dtype(c))
        c['data'] = arr.astype(_cloud_dtype(c, big=True)).tobytes()
    c['is_bigendian'] = True


def _retype(c: dict, name: str, code: int) -> None:
    """A valid cloud whose field ``name`` has another datatype (the values converted)."""
    from workzone_ros.core.pointcloud import DATATYPES
    arr = np.frombuffer(c['data'], dtype=_cloud_dtype(c))
    if name not in arr.dtype.names:
        return
    cols = [(n, DATATYPES[code] if n == name else arr.dtype[n]) for n in arr.dtype.names]
    out = np.zeros(arr.shape, np.dtype(cols))
    for n in arr.dtype.names:
        v = arr[n]
        if n == name and out.dtype[n].kind in 'iu':
            info = np.iinfo(out.dtype[n])
            v = np.clip(np.nan_to_num(v), info.min, info.max)
        out[n] = v
    offsets = [out.dtype.fields[n][1] for n in out.dtype.names]
    c['fields'] = [[n, o, code if n == name else f[2], 1]
                   for (n, o), f in zip(zip(out.dtype.names, offsets), c['fields'])]
    c['point_step'], c['row_step'] = out.dtype.itemsize, out.dtype.itemsize * c['width']
    c['data'] = out.tobytes()


def _large(c: dict, n: int) -> None:
    """A valid cloud of ``n`` random points with the same layout."""
    rng = np.random.default_rng(n)
    arr = np.zeros(n, dtype=_cloud_dtype(c))
    for name in arr.dtype.names:
        arr[name] = rng.uniform(-50, 50, n).astype(arr.dtype[name])
    c['width'], c['height'], c['data'] = n, 1, arr.tobytes()
    c['row_step'] = n * c['point_step']


def _set(key: str) -> Callable:
    def fn(c: dict, value: Any) -> None:
        c[key] = value
    return fn


def _field_set(slot: int) -> Callable:
    def fn(c: dict, i: int, value: Any) -> None:
        if c['fields']:
            _field(c, i)[slot] = value
    return fn


_I = st.integers(0, 15)
#: an invalid header stamp (every message type with a header)
_STAMP = (lambda c, v: c.__setitem__('nanosec', v), st.tuples(st.sampled_from([10 ** 9, U32])))
_CLOUD_MUTATIONS = {
    'stamp nanosec': _STAMP,
    'field offset': (_field_set(1), st.tuples(_I, st.one_of(
        st.integers(0, 40), st.sampled_from([2 ** 31, U32])))),
    'duplicated offset': (lambda c, i, j: c['fields'] and _field(c, i).__setitem__(
        1, _field(c, j)[1]), st.tuples(_I, _I)),
    'duplicated field': (lambda c, i: c['fields'].append(list(_field(c, i))),
                         st.tuples(_I)),
    'datatype': (_field_set(2), st.tuples(_I, st.integers(0, 255))),
    'count': (_field_set(3), st.tuples(_I, st.sampled_from([0, 2, 3, 2 ** 16, U32]))),
    'field name': (_field_set(0), st.tuples(_I, st.one_of(
        st.sampled_from(['', 'X', 'x ', 'rgb', 'ring']), st.text(max_size=200)))),
    'missing field': (lambda c, i: c['fields'] and c['fields'].pop(i % len(c['fields'])),
                      st.tuples(_I)),
    'point_step': (_set('point_step'), st.tuples(st.sampled_from(
        [0, 1, 3, 11, 15, 17, 2 ** 31, U32]))),
    'row_step': (_set('row_step'), st.tuples(st.sampled_from([0, 1, 2 ** 31, U32]))),
    'width': (_set('width'), st.tuples(st.sampled_from([0, 1, 2, 2 ** 31, U32]))),
    'height': (_set('height'), st.tuples(st.sampled_from([0, 2, 3, 2 ** 31, U32]))),
    'truncated data': (lambda c, frac: c.update(data=c['data'][:int(len(c['data']) * frac)]),
                       st.tuples(st.floats(0.0, 0.999))),
    'extra data': (lambda c, n: c.update(data=c['data'] + bytes(n)),
                   st.tuples(st.integers(1, 4096))),
    'NaN/inf values': (_set_values, st.tuples(
        st.sampled_from([math.nan, math.inf, -math.inf, 3.4e38, -3.4e38, 0.0]),
        st.integers(1, 7))),
    'big-endian': (_big_endian, st.tuples(st.booleans())),
    'field datatype (valid)': (_retype, st.tuples(
        st.sampled_from(['x', 'y', 'z', 'intensity', 'radius', 'id']), st.integers(1, 8))),
    'large cloud (valid)': (_large, st.tuples(st.sampled_from([20_000, 100_000]))),
    'empty cloud (valid)': (lambda c: c.update(width=0, height=1, row_step=0, data=b''),
                            st.tuples()),
}


def pointcloud2_faults(good: Good) -> st.SearchStrategy:
    """Malformed (and valid but unusual) ``sensor_msgs/PointCloud2`` from ``good``."""
    return st.lists(_mutations(_CLOUD_MUTATIONS), min_size=1, max_size=3).map(
        lambda steps: _fault(good, steps, _cloud_layout, _cloud_msg))


# --- Image --------------------------------------------------------------------------------

def _image_layout(msg: Any) -> dict:
    return dict(height=int(msg.height), width=int(msg.width), encoding=msg.encoding,
                step=int(msg.step), is_bigendian=int(msg.is_bigendian), data=bytes(msg.data))


def _image_msg(msg: Any, c: dict) -> Any:
    msg.height, msg.width, msg.encoding = c['height'], c['width'], c['encoding']
    msg.step, msg.is_bigendian, msg.data = c['step'], c['is_bigendian'], _data(c['data'])
    return msg


def _bgr(c: dict) -> np.ndarray:
    """The good image's pixels as BGR (after any earlier valid re-encoding)."""
    arr = np.frombuffer(c['data'], np.uint8).reshape(c['height'], c['step'])
    channels = c['step'] // c['width']
    arr = arr[:, :c['width'] * channels].reshape(c['height'], c['width'], channels)
    code = {1: cv2.COLOR_GRAY2BGR, 4: cv2.COLOR_BGRA2BGR}.get(channels)
    return np.ascontiguousarray(arr) if code is None else cv2.cvtColor(arr, code)


def _reencode(c: dict, encoding: str) -> None:
    """The same picture, validly, in another encoding."""
    bgr = _bgr(c)
    code = {'rgb8': cv2.COLOR_BGR2RGB, 'mono8': cv2.COLOR_BGR2GRAY, 'bgra8': cv2.COLOR_BGR2BGRA,
            'rgba8': cv2.COLOR_BGR2RGBA, '8UC1': cv2.COLOR_BGR2GRAY}.get(encoding)
    out = bgr if code is None else cv2.cvtColor(bgr, code)
    c.update(encoding=encoding, data=out.tobytes(),
             step=c['width'] * (1 if out.ndim == 2 else out.shape[2]))


def _padded(c: dict, pad: int) -> None:
    """Valid rows with ``pad`` bytes of padding each."""
    rows = np.frombuffer(c['data'], np.uint8).reshape(c['height'], -1)
    out = np.zeros((rows.shape[0], rows.shape[1] + pad), np.uint8)
    out[:, :rows.shape[1]] = rows
    c.update(step=out.shape[1], data=out.tobytes())


def _resized(c: dict, w: int, h: int) -> None:
    """A valid image of another size (degenerate ones included)."""
    out = cv2.resize(_bgr(c), (w, h), interpolation=cv2.INTER_AREA)
    c.update(width=w, height=h, encoding='bgr8', step=3 * w, data=out.tobytes())


def _noise(c: dict, w: int, h: int) -> None:
    rng = np.random.default_rng(w * h)
    c.update(width=w, height=h, encoding='bgr8', step=3 * w,
             data=rng.integers(0, 256, (h, w, 3), dtype=np.uint8).tobytes())


_SIZES = st.sampled_from([0, 1, 2, 2 ** 31 - 1, U32])
_IMAGE_MUTATIONS = {
    'stamp nanosec': _STAMP,
    'encoding': (_set('encoding'), st.tuples(st.one_of(
        st.sampled_from(['', 'yuv422', 'bayer_rggb8', '16UC1', 'mono16', '32FC1', 'rgb16',
                         'jpeg', 'BGR8', 'bgr8 ', 'mono8', 'bgra8', '8UC4']),
        st.text(max_size=100)))),
    'step': (_set('step'), st.tuples(st.sampled_from([0, 1, 959, 961, 2 ** 31, U32]))),
    'width': (_set('width'), st.tuples(_SIZES)),
    'height': (_set('height'), st.tuples(_SIZES)),
    'truncated data': (lambda c, frac: c.update(data=c['data'][:int(len(c['data']) * frac)]),
                       st.tuples(st.floats(0.0, 0.999))),
    'extra data': (lambda c, n: c.update(data=c['data'] + bytes(n)),
                   st.tuples(st.integers(1, 4096))),
    'is_bigendian': (_set('is_bigendian'), st.tuples(st.integers(1, 255))),
    'encoding (valid)': (_reencode, st.tuples(st.sampled_from(
        ['rgb8', 'mono8', 'bgra8', 'rgba8', '8UC1']))),
    'padded rows (valid)': (_padded, st.tuples(st.integers(1, 64))),
    'degenerate size (valid)': (_resized, st.tuples(st.sampled_from([1, 2, 7, 640]),
                                                    st.sampled_from([1, 2, 5, 480]))),
    'noise image (valid)': (_noise, st.tuples(st.sampled_from([64, 320, 1280]),
                                              st.sampled_from([48, 240, 720]))),
}


def image_faults(good: Good) -> st.SearchStrategy:
    """Malformed (and valid but unusual) ``sensor_msgs/Image`` from ``good``."""
    return st.lists(_mutations(_IMAGE_MUTATIONS), min_size=1, max_size=3).map(
        lambda steps: _fault(good, steps, _image_layout, _image_msg))


# --- CompressedImage ----------------------------------------------------------------------

def _compressed_layout(msg: Any) -> dict:
    return dict(format=msg.format, data=bytes(msg.data))


def _compressed_msg(msg: Any, c: dict) -> Any:
    msg.format, msg.data = c['format'], _data(c['data'])
    return msg


def _declare_size(c: dict, h: int, w: int) -> None:
    """Patch the JPEG SOF (or PNG IHDR) to declare an h x w image: a decompression bomb."""
    b = bytearray(c['data'])
    if b[:4] == b'\x89PNG':
        b[16:24] = struct.pack('>II', w, h)
    else:
        i = b.find(b'\xff\xc0')
        if i >= 0:
            b[i + 5:i + 9] = struct.pack('>HH', h, w)
    c['data'] = bytes(b)


def _corrupt(c: dict, start: float, n: int, value: int) -> None:
    b = bytearray(c['data'])
    i = int(len(b) * start)
    b[i:i + n] = bytes([value]) * len(b[i:i + n])
    c['data'] = bytes(b)


def _as_png(c: dict, depth16: bool, gray: bool, w: int, h: int) -> None:
    """A valid PNG of another size, bit depth or channel count."""
    img = cv2.imdecode(np.frombuffer(c['data'], np.uint8), cv2.IMREAD_COLOR)
    img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
    if gray:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if depth16:
        img = img.astype(np.uint16) * 257
    c['data'] = cv2.imencode('.png', img)[1].tobytes()


_COMPRESSED_MUTATIONS = {
    'stamp nanosec': _STAMP,
    'garbage bytes': (lambda c, b: c.update(data=b), st.tuples(st.binary(max_size=4096))),
    'truncated jpeg': (lambda c, frac: c.update(data=c['data'][:int(len(c['data']) * frac)]),
                       st.tuples(st.floats(0.0, 0.999))),
    'corrupted jpeg': (_corrupt, st.tuples(st.floats(0.0, 1.0), st.integers(1, 64),
                                           st.integers(0, 255))),
    'jpeg header + garbage': (lambda c, b: c.update(data=b'\xff\xd8\xff\xe0' + b),
                              st.tuples(st.binary(max_size=512))),
    'huge declared size': (_declare_size, st.tuples(st.sampled_from([20_000, 30_000, 65_500]),
                                                    st.sampled_from([20_000, 30_000, 65_500]))),
    'format': (_set('format'), st.tuples(st.one_of(
        st.sampled_from(['', 'png', 'rgb8; compressedDepth png', '16UC1; compressedDepth',
                         'tiff']), st.text(max_size=100)))),
    'png (valid)': (_as_png, st.tuples(st.booleans(), st.booleans(),
                                       st.sampled_from([1, 17, 320]),
                                       st.sampled_from([1, 9, 240]))),
}


def compressed_faults(good: Good) -> st.SearchStrategy:
    """Malformed ``sensor_msgs/CompressedImage`` from a good JPEG one."""
    return st.lists(_mutations(_COMPRESSED_MUTATIONS), min_size=1, max_size=2).map(
        lambda steps: _fault(good, steps, _compressed_layout, _compressed_msg))


# --- CameraInfo ---------------------------------------------------------------------------

def _info_layout(msg: Any) -> dict:
    return dict(width=int(msg.width), height=int(msg.height), model=msg.distortion_model,
                k=list(msg.k), d=list(msg.d), r=list(msg.r), p=list(msg.p))


def _info_msg(msg: Any, c: dict) -> Any:
    msg.width, msg.height, msg.distortion_model = c['width'], c['height'], c['model']
    msg.k, msg.d, msg.r, msg.p = c['k'], array.array('d', c['d']), c['r'], c['p']
    return msg


def _entries(key: str) -> Callable:
    def fn(c: dict, idx: list, value: float) -> None:
        for i in idx:
            if c[key]:
                c[key][i % len(c[key])] = value
    return fn


_VALUES = st.sampled_from([0.0, math.nan, math.inf, -math.inf, -1.0, 1e300, -1e300, 1e-300])
_INFO_MUTATIONS = {
    'stamp nanosec': _STAMP,
    'K zero': (lambda c: c.update(k=[0.0] * 9), st.tuples()),
    'K values': (_entries('k'), st.tuples(st.lists(st.integers(0, 8), min_size=1, max_size=9),
                                          _VALUES)),
    'D length': (lambda c, n: c.update(d=[0.01] * n), st.tuples(st.integers(0, 20))),
    'D values': (_entries('d'), st.tuples(st.lists(st.integers(0, 13), min_size=1,
                                                   max_size=5), _VALUES)),
    'distortion model': (_set('model'), st.tuples(st.one_of(
        st.sampled_from(['', 'fisheye', 'PLUMB_BOB', 'equidistant', 'rational_polynomial',
                         'plumb_bob ']), st.text(max_size=100)))),
    'R values': (_entries('r'), st.tuples(st.lists(st.integers(0, 8), min_size=1, max_size=9),
                                          _VALUES)),
    'P values': (_entries('p'), st.tuples(st.lists(st.integers(0, 11), min_size=1,
                                                   max_size=12), _VALUES)),
    'width': (_set('width'), st.tuples(_SIZES)),
    'height': (_set('height'), st.tuples(_SIZES)),
}


def camera_info_faults(good: Good) -> st.SearchStrategy:
    """Malformed ``sensor_msgs/CameraInfo`` from ``good``."""
    return st.lists(_mutations(_INFO_MUTATIONS), min_size=1, max_size=3).map(
        lambda steps: _fault(good, steps, _info_layout, _info_msg))


# --- Odometry -----------------------------------------------------------------------------

def _odom_layout(msg: Any) -> dict:
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    return dict(p=[p.x, p.y, p.z], q=[q.x, q.y, q.z, q.w], frame=None)


def _odom_msg(msg: Any, c: dict) -> Any:
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    p.x, p.y, p.z = c['p']
    q.x, q.y, q.z, q.w = c['q']
    if c['frame'] is not None:
        msg.header.frame_id = msg.child_frame_id = c['frame']
    return msg


_ODOM_MUTATIONS = {
    'position': (_entries('p'), st.tuples(st.lists(st.integers(0, 2), min_size=1, max_size=3),
                                          _VALUES)),
    'quaternion': (_entries('q'), st.tuples(st.lists(st.integers(0, 3), min_size=1,
                                                     max_size=4), _VALUES)),
    'quaternion zero': (lambda c: c.update(q=[0.0] * 4), st.tuples()),
    'quaternion not unit': (lambda c, s: c.update(q=[v * s for v in c['q']]),
                            st.tuples(st.sampled_from([1e-12, 1e-3, 0.5, 2.0, 1e6]))),
    'stamp nanosec': _STAMP,
    'frame ids': (_set('frame'), st.tuples(st.text(max_size=300))),
}


def odometry_faults(good: Good) -> st.SearchStrategy:
    """Malformed ``nav_msgs/Odometry`` from ``good``."""
    return st.lists(_mutations(_ODOM_MUTATIONS), min_size=1, max_size=2).map(
        lambda steps: _fault(good, steps, _odom_layout, _odom_msg))


# --- JSON payloads (std_msgs/String) ------------------------------------------------------

def _paths(obj: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path into a JSON document (containers and leaves), in document order."""
    out = [prefix] if prefix else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, prefix + (i,))
    return out


def _put(doc: Any, path: tuple, value: Any) -> None:
    for key in path[:-1]:
        doc = doc[key]
    doc[path[-1]] = value


_EXTREMES = st.sampled_from([
    None, True, -1, 0, 2 ** 31, 2 ** 63, 2 ** 64, -(2 ** 63) - 1, 10 ** 30, 1e308, -1e308,
    1e-320, -0.5, 1.5, math.nan, math.inf, '', 'x' * 10_000, [], {}, [1, 2, 3], {'a': 1}])


def _set_field(doc: dict, i: int, value: Any) -> None:
    paths = _paths(doc)
    if paths:
        _put(doc, paths[i % len(paths)], copy.deepcopy(value))


def _drop_field(doc: dict, i: int) -> None:
    paths = [p for p in _paths(doc) if isinstance(p[-1], str)]
    if paths:
        path = paths[i % len(paths)]
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        parent.pop(path[-1], None)


def _long_strings(doc: Any, n: int) -> None:
    """The first two strings (the frame id, a class key...) ``n`` characters long."""
    paths = [p for p in _paths(doc) if p[-1] != 'schema' and isinstance(_get(doc, p), str)]
    for path in paths[:2]:
        _put(doc, path, ('\u00e9x' * n)[:n])


def _many_items(doc: Any, n: int) -> None:
    """The first list of objects (detections, tracks, signs, ROIs) ``n`` items long."""
    for path in _paths(doc):
        value = _get(doc, path)
        if isinstance(value, list) and value and isinstance(value[0], dict):
            _put(doc, path, [copy.deepcopy(value[0]) for _ in range(n)])
            return


def _set_number(doc: dict, i: int, big_int: int, big_float: float) -> None:
    """A number of the document (not the stamp's nanosec) set to an extreme of its kind."""
    paths = [p for p in _paths(doc) if p[-1] != 'nanosec' and isinstance(
        _get(doc, p), (int, float)) and not isinstance(_get(doc, p), bool)]
    if paths:
        path = paths[i % len(paths)]
        _put(doc, path, big_int if isinstance(_get(doc, path), int) else big_float)


def _get(doc: Any, path: tuple) -> Any:
    for key in path:
        doc = doc[key]
    return doc


_DOC_MUTATIONS = {
    'field value': (_set_field, st.tuples(st.integers(0, 200), _EXTREMES)),
    'number out of range': (_set_number, st.tuples(
        st.integers(0, 200),
        st.sampled_from([-1, 2 ** 31, -(2 ** 31) - 1, 2 ** 63 - 1, -(2 ** 63), 10 ** 30]),
        st.sampled_from([1e308, -1e308, 1e-320, -0.0, 1e15, -1e15, 3.5e38]))),
    'unknown field': (lambda d, k: d.__setitem__(k, 1), st.tuples(st.text(max_size=20))),
    'missing field': (_drop_field, st.tuples(st.integers(0, 200))),
    'schema': (lambda d, s: d.__setitem__('schema', s), st.tuples(st.one_of(
        st.sampled_from(['workzone_ros/Rois/1', 'workzone_ros/Detections/1',
                         'workzone_ros/Tracks/1', 'workzone_ros/Signs/1',
                         'workzone_ros/WorkzoneState/1', 'workzone_ros/Signs/2',
                         'workzone_ros/Detections/0', 'workzone_ros/Unknown/1', '', 7]),
        st.text(max_size=40)))),
    'no schema': (lambda d: d.pop('schema', None), st.tuples()),
    'very long strings': (_long_strings, st.tuples(st.sampled_from([10_000, 1_000_000]))),
    'many items': (_many_items, st.tuples(st.sampled_from([100, 2000]))),
}


def _text_mutation(good: Good, name: str, fn: Callable, args: tuple) -> Fault:
    def build(stamp: Any) -> Any:
        msg = good(stamp)
        msg.data = fn(msg.data, *args)
        return msg
    return Fault(name, (args,), build)


def _doc_fault(good: Good, steps: list) -> Fault:
    # copies first, then long strings: at most two long strings in a document
    steps = sorted(steps, key=lambda s: s[0] != 'many items')

    def build(stamp: Any) -> Any:
        msg = good(stamp)
        doc = json.loads(msg.data)
        for _, fn, args in steps:
            fn(doc, *args)
        msg.data = json.dumps(doc)           # NaN/inf become NaN/Infinity: not JSON
        return msg
    kind = ' + '.join(dict.fromkeys(name for name, _, _ in steps))
    return Fault(kind, tuple((name, args) for name, _, args in steps), build)


def payload_faults(good: Good) -> st.SearchStrategy:
    """Malformed JSON payloads of ``workzone_ros.interfaces`` from a good ``String``."""
    texts = st.one_of(
        st.tuples(st.just('invalid JSON: text'), st.just(lambda _t, s: s),
                  st.tuples(st.text(max_size=300))),
        st.tuples(st.just('invalid JSON: truncated'),
                  st.just(lambda t, f: t[:int(len(t) * f)]), st.tuples(st.floats(0.0, 0.99))),
        st.tuples(st.just('invalid JSON: trailing garbage'), st.just(lambda t, s: t + s),
                  st.tuples(st.text(min_size=1, max_size=20))),
        st.tuples(st.just('invalid JSON: deep nesting'),
                  st.just(lambda _t, n: '[' * n + ']' * n), st.tuples(st.sampled_from(
                      [1000, 100_000]))),
    ).map(lambda m: _text_mutation(good, *m))
    docs = st.lists(_mutations(_DOC_MUTATIONS), min_size=1, max_size=3).map(
        lambda steps: _doc_fault(good, steps))
    return st.one_of(docs, texts)


def faults_for(msg_type: type, good: Good) -> st.SearchStrategy:
    """The strategy of malformed messages of ``msg_type`` around ``good``."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2
    from std_msgs.msg import String
    table = {PointCloud2: pointcloud2_faults, Image: image_faults,
             CompressedImage: compressed_faults, CameraInfo: camera_info_faults,
             Odometry: odometry_faults, String: payload_faults}
    return table[msg_type](good)
