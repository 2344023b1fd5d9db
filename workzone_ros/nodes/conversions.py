"""rclpy messages <-> numpy for Image, CompressedImage, PointCloud2, CameraInfo and payloads.

The package has no cv_bridge and no sensor_msgs_py: this module is what the nodes use instead
(DESIGN.md, "Install").  Reading is zero-copy: rclpy hands ``msg.data`` over as an
``array.array('B')``, and ``np.frombuffer`` views it, so the returned arrays alias the
message (copy them before keeping them past the callback if the message is reused).  Writing
costs exactly one copy: the array is copied into an ``array.array('B')`` with ``frombytes``
and assigned to a message built with ``check_fields=True``, whose ``data`` setter then keeps
that array as is (the default setter copies it a second time, and assigning ``bytes`` to a
checked message walks every byte in Python).

Every malformed input raises :class:`ConversionError` (an :class:`InputError`) whose one-line
message names the problem; the node base counts it as a dropped message and logs it, rate
limited.
"""
from __future__ import annotations

import array
from dataclasses import dataclass
from typing import Any, Optional, Union

import cv2
import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2, PointField
from std_msgs.msg import Header as HeaderMsg
from std_msgs.msg import String

from workzone_ros import interfaces
from workzone_ros.core.pointcloud import (
    FieldSpec,
    PointCloudError,
    cloud_view,
    dtype_to_fields,
)

__all__ = [
    'InputError', 'ConversionError', 'ENCODINGS', 'image_to_numpy', 'numpy_to_image',
    'compressed_to_numpy', 'compressed_image_size', 'MAX_COMPRESSED_PIXELS',
    'numpy_to_compressed', 'pointcloud2_to_array',
    'array_to_pointcloud2', 'CameraInfoData', 'DISTORTION_MODELS', 'camera_info_to_numpy',
    'numpy_to_camera_info', 'stamp_to_time', 'time_to_stamp', 'header_to_payload',
    'payload_to_header', 'make_header', 'payload_to_string', 'string_to_payload',
]


class InputError(ValueError):
    """An input message that cannot be used: the node drops it, counts it and keeps running."""


class ConversionError(InputError):
    """A message that does not convert to/from numpy; the message names the problem."""


#: Supported 8-bit image encodings -> channel count.  ``8UC1``/``8UC3``/``8UC4`` are read as
#: mono8/bgr8/bgra8 (OpenCV's channel order).
ENCODINGS: dict[str, int] = {
    'mono8': 1, 'bgr8': 3, 'rgb8': 3, 'bgra8': 4, 'rgba8': 4,
    '8UC1': 1, '8UC3': 3, '8UC4': 4,
}
_ALIASES = {'8UC1': 'mono8', '8UC3': 'bgr8', '8UC4': 'bgra8'}

# (source, target) -> cv2 colour conversion code.
_CVT = {
    ('rgb8', 'bgr8'): cv2.COLOR_RGB2BGR, ('bgra8', 'bgr8'): cv2.COLOR_BGRA2BGR,
    ('rgba8', 'bgr8'): cv2.COLOR_RGBA2BGR, ('mono8', 'bgr8'): cv2.COLOR_GRAY2BGR,
    ('bgr8', 'rgb8'): cv2.COLOR_BGR2RGB, ('bgra8', 'rgb8'): cv2.COLOR_BGRA2RGB,
    ('rgba8', 'rgb8'): cv2.COLOR_RGBA2RGB, ('mono8', 'rgb8'): cv2.COLOR_GRAY2RGB,
    ('bgr8', 'mono8'): cv2.COLOR_BGR2GRAY, ('rgb8', 'mono8'): cv2.COLOR_RGB2GRAY,
    ('bgra8', 'mono8'): cv2.COLOR_BGRA2GRAY, ('rgba8', 'mono8'): cv2.COLOR_RGBA2GRAY,
    ('bgr8', 'bgra8'): cv2.COLOR_BGR2BGRA, ('rgb8', 'bgra8'): cv2.COLOR_RGB2BGRA,
    ('mono8', 'bgra8'): cv2.COLOR_GRAY2BGRA, ('rgba8', 'bgra8'): cv2.COLOR_RGBA2BGRA,
}

StampLike = Union[TimeMsg, interfaces.Time, None]
HeaderLike = Union[HeaderMsg, interfaces.Header, None]


# --- helpers ------------------------------------------------------------------------------

def _u8(data: Any) -> np.ndarray:
    """A flat uint8 view of a message buffer (array.array, bytes, memoryview or ndarray)."""
    if isinstance(data, np.ndarray):
        return data.reshape(-1).view(np.uint8)
    return np.frombuffer(data, dtype=np.uint8)


def _to_data(arr: np.ndarray) -> array.array:
    """Copy a contiguous array's bytes into the ``array.array('B')`` rclpy stores (one copy)."""
    out = array.array('B')
    out.frombytes(np.ascontiguousarray(arr).reshape(-1).view(np.uint8))
    return out


def _new(msg_cls: type) -> Any:
    """A message whose array setters keep an ``array.array`` without copying it again."""
    try:
        return msg_cls(check_fields=True)
    except (TypeError, AssertionError):    # a rosidl without check_fields
        return msg_cls()


def _canonical(encoding: str) -> str:
    return _ALIASES.get(encoding, encoding)


# --- stamps, headers, payloads ------------------------------------------------------------

def stamp_to_time(stamp: TimeMsg) -> interfaces.Time:
    """``builtin_interfaces/Time`` -> :class:`interfaces.Time`.

    Raises:
        ConversionError: ``nanosec`` outside [0, 1e9).
    """
    if not 0 <= stamp.nanosec < 1_000_000_000:
        raise ConversionError(f'stamp nanosec {stamp.nanosec} is outside [0, 1e9)')
    return interfaces.Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec))


def time_to_stamp(time: interfaces.Time) -> TimeMsg:
    """:class:`interfaces.Time` -> ``builtin_interfaces/Time``."""
    return TimeMsg(sec=int(time.sec), nanosec=int(time.nanosec))


def header_to_payload(header: HeaderMsg) -> interfaces.Header:
    """``std_msgs/Header`` -> :class:`interfaces.Header` (for the JSON payloads).

    Raises:
        ConversionError: an invalid stamp.
    """
    return interfaces.Header(stamp=stamp_to_time(header.stamp), frame_id=header.frame_id)


def payload_to_header(header: interfaces.Header) -> HeaderMsg:
    """:class:`interfaces.Header` -> ``std_msgs/Header``."""
    return HeaderMsg(stamp=time_to_stamp(header.stamp), frame_id=header.frame_id)


def make_header(header: HeaderLike = None, *, stamp: StampLike = None,
                frame_id: Optional[str] = None) -> HeaderMsg:
    """Build a ``std_msgs/Header`` from a header (message or payload) and/or stamp and frame.

    Args:
        header: a ``std_msgs/Header`` or :class:`interfaces.Header` to start from.
        stamp: overrides the stamp (``builtin_interfaces/Time`` or :class:`interfaces.Time`).
        frame_id: overrides the frame.

    Returns:
        A new ``std_msgs/Header`` (the input is not modified).
    """
    if isinstance(header, interfaces.Header):
        out = payload_to_header(header)
    elif header is not None:
        out = HeaderMsg(stamp=TimeMsg(sec=header.stamp.sec, nanosec=header.stamp.nanosec),
                        frame_id=header.frame_id)
    else:
        out = HeaderMsg()
    if stamp is not None:
        out.stamp = time_to_stamp(stamp) if isinstance(stamp, interfaces.Time) \
            else TimeMsg(sec=stamp.sec, nanosec=stamp.nanosec)
    if frame_id is not None:
        out.frame_id = str(frame_id)
    return out


def payload_to_string(payload: Any) -> String:
    """A :mod:`workzone_ros.interfaces` payload -> ``std_msgs/String`` with its JSON."""
    return String(data=interfaces.encode(payload))


def string_to_payload(msg: String, cls: Optional[type] = None) -> Any:
    """``std_msgs/String`` -> validated payload of class ``cls`` (any known schema if None).

    Raises:
        ConversionError: the JSON is malformed or fails validation (same text as
            :class:`interfaces.PayloadError`).
    """
    try:
        if cls is None:
            return interfaces.decode_any(msg.data)
        return interfaces.decode(msg.data, cls)
    except interfaces.PayloadError as exc:
        raise ConversionError(str(exc)) from None


# --- Image --------------------------------------------------------------------------------

def image_to_numpy(msg: Image, desired_encoding: Optional[str] = None) -> np.ndarray:
    """View a ``sensor_msgs/Image`` as an (H, W, C) or (H, W) uint8 array.

    Without conversion the result is a view of ``msg.data`` (no copy, row padding skipped
    through strides).  With ``desired_encoding`` different from the message's, OpenCV converts
    into a new contiguous array.

    Args:
        msg: the image; encodings in :data:`ENCODINGS`, rows ``step`` bytes apart.
        desired_encoding: ``None`` (as sent), ``'bgr8'``, ``'rgb8'``, ``'mono8'`` or
            ``'bgra8'``.

    Returns:
        (H, W) for one channel, else (H, W, C), dtype uint8.

    Raises:
        ConversionError: zero size, unknown encoding, invalid ``is_bigendian``, ``step``
            smaller than a row, or data length different from ``step * height``.
    """
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if height <= 0 or width <= 0:
        raise ConversionError(f'Image has zero size ({width}x{height})')
    channels = ENCODINGS.get(msg.encoding)
    if channels is None:
        raise ConversionError(f'Image encoding {msg.encoding!r} is not supported '
                              f'(supported: {", ".join(ENCODINGS)})')
    if msg.is_bigendian not in (0, 1):
        raise ConversionError(f'Image is_bigendian must be 0 or 1, got {msg.is_bigendian}')
    row = width * channels
    if step < row:
        raise ConversionError(f'Image step {step} is smaller than width*channels {row} '
                              f'({width}x{channels} {msg.encoding})')
    buf = _u8(msg.data)
    if buf.size != step * height:
        raise ConversionError(f'Image data has {buf.size} bytes but step*height is '
                              f'{step * height} ({step}x{height})')
    img = buf.reshape(height, step)
    if step != row:
        img = img[:, :row]
    img = img.reshape(height, width) if channels == 1 else img.reshape(height, width, channels)
    source = _canonical(msg.encoding)
    if desired_encoding is None or _canonical(desired_encoding) == source:
        return img
    target = _canonical(desired_encoding)
    code = _CVT.get((source, target))
    if code is None:
        raise ConversionError(f'cannot convert Image from {msg.encoding!r} to '
                              f'{desired_encoding!r}')
    return cv2.cvtColor(img, code)


def numpy_to_image(arr: np.ndarray, encoding: str = 'bgr8', header: HeaderLike = None, *,
                   stamp: StampLike = None, frame_id: Optional[str] = None) -> Image:
    """Build a dense ``sensor_msgs/Image`` (``step = width * channels``) from a uint8 array.

    Args:
        arr: (H, W) or (H, W, 1) for one channel, (H, W, C) otherwise; dtype uint8.
        encoding: one of :data:`ENCODINGS`; the channel count must agree with ``arr``.
        header: ``std_msgs/Header`` or :class:`interfaces.Header`.
        stamp: overrides the header's stamp.
        frame_id: overrides the header's frame.

    Returns:
        The message (its data is a copy of ``arr``).

    Raises:
        ConversionError: unknown encoding, wrong dtype or a shape that does not match.
    """
    channels = ENCODINGS.get(encoding)
    if channels is None:
        raise ConversionError(f'Image encoding {encoding!r} is not supported '
                              f'(supported: {", ".join(ENCODINGS)})')
    arr = np.asarray(arr)
    if arr.dtype != np.uint8:
        raise ConversionError(f'Image array must be uint8, got {arr.dtype}')
    got = 1 if arr.ndim == 2 else (arr.shape[2] if arr.ndim == 3 else -1)
    if got != channels or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ConversionError(f'array of shape {arr.shape} does not hold a non-empty '
                              f'{encoding} image ({channels} channel(s))')
    msg = _new(Image)
    msg.header = make_header(header, stamp=stamp, frame_id=frame_id)
    msg.height, msg.width = int(arr.shape[0]), int(arr.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = int(arr.shape[1]) * channels
    msg.data = _to_data(arr)
    return msg


# --- CompressedImage ----------------------------------------------------------------------

#: Largest image a CompressedImage may declare, in pixels (a 12k x 5k panorama): a 600-byte
#: JPEG can declare 30000 x 30000, which OpenCV allocates (2.7 GB, 12 s) before it finds that
#: the data is missing.
MAX_COMPRESSED_PIXELS = 64 * 2 ** 20

_PNG = b'\x89PNG\r\n\x1a\n'
# JPEG start-of-frame markers (C4 DHT, C8 JPG and CC DAC are not frames)
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


def _jpeg_size(b: memoryview) -> Optional[tuple[int, int]]:
    """(width, height) from the first start-of-frame segment, or None."""
    i, n = 2, len(b)
    while i + 4 <= n:
        if b[i] != 0xFF:
            return None
        marker = b[i + 1]
        if marker == 0xFF:                                 # fill byte
            i += 1
        elif marker == 0x01 or 0xD0 <= marker <= 0xD7:     # no length
            i += 2
        elif marker in _SOF:
            return ((b[i + 7] << 8) | b[i + 8], (b[i + 5] << 8) | b[i + 6]) \
                if i + 9 <= n else None
        elif marker == 0xDA:                               # a scan before any frame
            return None
        else:
            i += 2 + ((b[i + 2] << 8) | b[i + 3])
    return None


def compressed_image_size(msg: CompressedImage) -> tuple[int, int]:
    """(width, height) that a JPEG or PNG ``CompressedImage`` declares, without decoding it.

    Raises:
        ConversionError: empty data, neither JPEG nor PNG, or no size in the header.
    """
    buf = memoryview(_u8(msg.data))
    if len(buf) == 0:
        raise ConversionError(f'CompressedImage ({msg.format!r}) has no data')
    size = None
    if bytes(buf[:2]) == b'\xff\xd8':
        size = _jpeg_size(buf)
    elif bytes(buf[:8]) == _PNG:
        size = (int.from_bytes(buf[16:20], 'big'), int.from_bytes(buf[20:24], 'big')) \
            if len(buf) >= 24 and bytes(buf[12:16]) == b'IHDR' else None
    else:
        raise ConversionError(f'CompressedImage ({msg.format!r}, {len(buf)} bytes) is neither '
                              f'JPEG nor PNG')
    if size is None:
        raise ConversionError(f'CompressedImage ({msg.format!r}, {len(buf)} bytes) has no '
                              f'image size in its header')
    return size


def compressed_to_numpy(msg: CompressedImage) -> np.ndarray:
    """Decode a jpeg/png ``sensor_msgs/CompressedImage`` into a BGR (H, W, 3) uint8 array.

    Raises:
        ConversionError: empty data, a compressedDepth image, neither JPEG nor PNG, a header
            declaring more than :data:`MAX_COMPRESSED_PIXELS`, or data OpenCV cannot decode.
    """
    if 'compresseddepth' in msg.format.lower().replace(' ', ''):
        raise ConversionError(f'CompressedImage format {msg.format!r} is not supported '
                              f'(jpeg or png only)')
    width, height = compressed_image_size(msg)
    if width * height > MAX_COMPRESSED_PIXELS:
        raise ConversionError(f'CompressedImage declares a {width}x{height} image, more than '
                              f'{MAX_COMPRESSED_PIXELS} pixels: not decoded')
    buf = _u8(msg.data)
    img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    if img is None:
        raise ConversionError(f'CompressedImage ({msg.format!r}, {buf.size} bytes) could not '
                              f'be decoded')
    return img


def numpy_to_compressed(arr: np.ndarray, fmt: str = 'jpeg', quality: int = 90,
                        header: HeaderLike = None, *, stamp: StampLike = None,
                        frame_id: Optional[str] = None) -> CompressedImage:
    """Encode a BGR (H, W, 3) or mono (H, W) uint8 array as a ``sensor_msgs/CompressedImage``.

    The ``format`` field follows image_transport: ``'bgr8; jpeg compressed bgr8'``.

    Args:
        arr: the image.
        fmt: ``'jpeg'`` (or ``'jpg'``) or ``'png'``.
        quality: jpeg quality 1..100 (ignored for png).
        header: ``std_msgs/Header`` or :class:`interfaces.Header`.
        stamp: overrides the header's stamp.
        frame_id: overrides the header's frame.

    Raises:
        ConversionError: unknown format, wrong dtype/shape, or encoding failed.
    """
    fmt = fmt.lower()
    if fmt not in ('jpeg', 'jpg', 'png'):
        raise ConversionError(f'compressed format {fmt!r} is not supported (jpeg or png)')
    arr = np.asarray(arr)
    if arr.dtype != np.uint8 or arr.ndim not in (2, 3) or (arr.ndim == 3
                                                           and arr.shape[2] not in (1, 3)):
        raise ConversionError(f'cannot compress an array of shape {arr.shape} and dtype '
                              f'{arr.dtype} (need uint8 (H, W) or (H, W, 3))')
    if fmt == 'png':
        ok, enc = cv2.imencode('.png', arr, [cv2.IMWRITE_PNG_COMPRESSION, 3])
        fmt = 'png'
    else:
        ok, enc = cv2.imencode('.jpg', arr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
        fmt = 'jpeg'
    if not ok:
        raise ConversionError(f'OpenCV could not encode the image as {fmt}')
    encoding = 'mono8' if arr.ndim == 2 or arr.shape[2] == 1 else 'bgr8'
    msg = _new(CompressedImage)
    msg.header = make_header(header, stamp=stamp, frame_id=frame_id)
    msg.format = f'{encoding}; {fmt} compressed {encoding}'
    msg.data = _to_data(enc)
    return msg


# --- PointCloud2 --------------------------------------------------------------------------

def pointcloud2_to_array(msg: PointCloud2, require_xyz: bool = True) -> np.ndarray:
    """View a ``sensor_msgs/PointCloud2`` as a flat structured array.

    Fields may sit at any offset with any PointField datatype and count; the big-endian flag
    gives the byte order of the dtype; ``row_step`` padding is skipped (a copy is made only in
    that case); NaN points are kept (drop them with ``core.pointcloud.xyz_array``).

    Args:
        msg: the cloud.
        require_xyz: raise when the cloud has no ``x``, ``y`` or ``z`` field.

    Returns:
        A 1-D structured array of ``width * height`` points, aliasing ``msg.data`` when rows
        are dense.

    Raises:
        ConversionError: unknown datatype, field outside ``point_step``, sizes that do not
            agree with the data, or missing x/y/z.
    """
    fields = [FieldSpec(f.name, int(f.offset), int(f.datatype), int(f.count))
              for f in msg.fields]
    if require_xyz:
        names = {f.name for f in fields}
        missing = [c for c in 'xyz' if c not in names]
        if missing:
            raise ConversionError(f'PointCloud2 has no {"/".join(missing)} field '
                                  f'(fields: {", ".join(f.name for f in fields) or "none"})')
        multi = [f'{f.name} (count {f.count})' for f in fields
                 if f.name in ('x', 'y', 'z') and f.count > 1]
        if multi:
            raise ConversionError(f'PointCloud2 field {", ".join(multi)} must hold one value '
                                  f'per point')
    n = int(msg.width) * int(msg.height)
    if n > 0 and msg.point_step <= 0:
        raise ConversionError(f'PointCloud2 has {n} points but point_step {msg.point_step}')
    try:
        return cloud_view(msg.data, fields, int(msg.point_step), int(msg.width),
                          int(msg.height), int(msg.row_step), bool(msg.is_bigendian))
    except PointCloudError as exc:
        raise ConversionError(f'PointCloud2 {exc}') from None


def array_to_pointcloud2(arr: np.ndarray, header: HeaderLike = None, *,
                         frame_id: Optional[str] = None,
                         stamp: StampLike = None) -> PointCloud2:
    """Build a dense little-endian ``sensor_msgs/PointCloud2`` from a structured array.

    A 1-D array gives an unorganised cloud (height 1); a 2-D array an organised one
    (height, width = ``arr.shape``).  Padding in the dtype (e.g. from ``fields_to_dtype``) is
    kept as ``point_step``; big-endian fields are converted to little-endian.

    Args:
        arr: structured array (see ``core.pointcloud.make_points``).
        header: ``std_msgs/Header`` or :class:`interfaces.Header`.
        frame_id: overrides the header's frame.
        stamp: overrides the header's stamp.

    Raises:
        ConversionError: not structured, more than 2 dimensions, or a field type that
            PointCloud2 cannot hold.
    """
    arr = np.asarray(arr)
    if arr.ndim not in (1, 2):
        raise ConversionError(f'point array must be 1-D or 2-D, got shape {arr.shape}')
    try:
        specs = dtype_to_fields(arr.dtype)
    except PointCloudError as exc:
        raise ConversionError(str(exc)) from None
    if any(arr.dtype.fields[name][0].base.byteorder == '>' for name in arr.dtype.names):
        arr = arr.astype(arr.dtype.newbyteorder('<'))
    height, width = (1, arr.shape[0]) if arr.ndim == 1 else arr.shape
    msg = _new(PointCloud2)
    msg.header = make_header(header, stamp=stamp, frame_id=frame_id)
    msg.height, msg.width = int(height), int(width)
    msg.fields = [PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
                  for f in specs]
    msg.is_bigendian = False
    msg.point_step = int(arr.dtype.itemsize)
    msg.row_step = int(arr.dtype.itemsize) * int(width)
    msg.is_dense = False
    msg.data = _to_data(arr)
    return msg


# --- CameraInfo ---------------------------------------------------------------------------

#: Supported distortion models -> accepted coefficient counts ('' means "not given").
DISTORTION_MODELS: dict[str, tuple[int, ...]] = {
    'plumb_bob': (5,), 'rational_polynomial': (8, 12, 14), 'equidistant': (4,), '': (),
}


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class CameraInfoData:
    """Validated camera calibration (``sensor_msgs/CameraInfo`` without the header).

    Construct it directly for :func:`numpy_to_camera_info`: ``D`` may be empty (no
    distortion: zeros of the model's length), ``R`` defaults to identity, ``P`` to
    ``[K | 0]`` (also when a driver sends them all zero).  Arrays are float64 and read-only.

    Attributes:
        width: image width in pixels.
        height: image height in pixels.
        K: (3, 3) intrinsic matrix.
        D: (n,) distortion coefficients of ``distortion_model``.
        R: (3, 3) rectification rotation.
        P: (3, 4) projection matrix.
        distortion_model: 'plumb_bob', 'rational_polynomial', 'equidistant' or ''.

    Raises:
        ConversionError: on construction, when the calibration is unusable.
    """

    width: int
    height: int
    K: Any
    D: Any = ()
    R: Any = None
    P: Any = None
    distortion_model: str = 'plumb_bob'

    def __post_init__(self) -> None:
        """Normalise and validate the calibration."""
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        if int(self.width) <= 0 or int(self.height) <= 0:
            raise ConversionError(f'CameraInfo has zero size ({self.width}x{self.height})')
        put('width', int(self.width))
        put('height', int(self.height))
        k = np.array(self.K, dtype=np.float64).reshape(-1)
        if k.size != 9:
            raise ConversionError(f'CameraInfo K must have 9 values, got {k.size}')
        if not np.any(k):
            raise ConversionError('CameraInfo has no intrinsics (K is zero)')
        k = k.reshape(3, 3)
        if not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
            raise ConversionError(f'CameraInfo K has invalid focal lengths '
                                  f'(fx {k[0, 0]}, fy {k[1, 1]})')
        model = str(self.distortion_model)
        if model not in DISTORTION_MODELS:
            raise ConversionError(
                f'CameraInfo distortion_model {model!r} is not supported '
                f'(plumb_bob, rational_polynomial, equidistant or empty)')
        d = np.array(self.D, dtype=np.float64).reshape(-1)
        counts = DISTORTION_MODELS[model]
        if d.size == 0 and counts:
            d = np.zeros(counts[0])
        elif counts and d.size not in counts:
            raise ConversionError(f'CameraInfo distortion_model {model!r} needs '
                                  f'{" or ".join(map(str, counts))} coefficients, got {d.size}')
        r = np.eye(3) if self.R is None else np.array(self.R, dtype=np.float64).reshape(-1)
        if r.size != 9:
            raise ConversionError(f'CameraInfo R must have 9 values, got {r.size}')
        r = r.reshape(3, 3)
        if not np.any(r):
            r = np.eye(3)         # many drivers leave R zero for a monocular camera
        if self.P is None:
            p = np.hstack([k, np.zeros((3, 1))])
        else:
            p = np.array(self.P, dtype=np.float64).reshape(-1)
            if p.size != 12:
                raise ConversionError(f'CameraInfo P must have 12 values, got {p.size}')
            p = p.reshape(3, 4)
            if not np.any(p):
                p = np.hstack([k, np.zeros((3, 1))])
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(r)) and np.all(np.isfinite(p))):
            raise ConversionError('CameraInfo has non-finite values in D, R or P')
        put('K', _readonly(k))
        put('D', _readonly(d))
        put('R', _readonly(r))
        put('P', _readonly(p))
        put('distortion_model', model)


def camera_info_to_numpy(msg: CameraInfo) -> CameraInfoData:
    """``sensor_msgs/CameraInfo`` -> validated :class:`CameraInfoData`.

    Raises:
        ConversionError: zero size, K all zeros ("CameraInfo has no intrinsics (K is zero)"),
            an unsupported distortion model or a wrong number of coefficients.
    """
    return CameraInfoData(width=int(msg.width), height=int(msg.height), K=np.asarray(msg.k),
                          D=np.asarray(msg.d, dtype=np.float64), R=np.asarray(msg.r),
                          P=np.asarray(msg.p), distortion_model=msg.distortion_model)


def numpy_to_camera_info(info: CameraInfoData, header: HeaderLike = None, *,
                         stamp: StampLike = None,
                         frame_id: Optional[str] = None) -> CameraInfo:
    """:class:`CameraInfoData` -> ``sensor_msgs/CameraInfo`` (no binning, full-image ROI).

    Args:
        info: the calibration.
        header: ``std_msgs/Header`` or :class:`interfaces.Header`.
        stamp: overrides the header's stamp.
        frame_id: overrides the header's frame.
    """
    msg = CameraInfo()
    msg.header = make_header(header, stamp=stamp, frame_id=frame_id)
    msg.width, msg.height = info.width, info.height
    msg.distortion_model = info.distortion_model
    msg.d = array.array('d', info.D)
    msg.k = info.K.reshape(-1)
    msg.r = info.R.reshape(-1)
    msg.p = info.P.reshape(-1)
    return msg

