"""Tests of workzone_ros.nodes.conversions: round trips, zero copy, and rejected inputs."""
import array
import time

import cv2
import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Time as TimeMsg
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2, PointField
from std_msgs.msg import Header as HeaderMsg
from std_msgs.msg import String

from workzone_ros import interfaces
from workzone_ros.core.pointcloud import FLOAT32, FLOAT64, INT16, UINT8, xyz_array
from workzone_ros.nodes.conversions import (
    CameraInfoData,
    ConversionError,
    InputError,
    array_to_pointcloud2,
    camera_info_to_numpy,
    compressed_to_numpy,
    header_to_payload,
    image_to_numpy,
    make_header,
    numpy_to_camera_info,
    numpy_to_compressed,
    numpy_to_image,
    payload_to_header,
    payload_to_string,
    pointcloud2_to_array,
    stamp_to_time,
    string_to_payload,
    time_to_stamp,
)

RNG = np.random.default_rng(7)


def _img(h=6, w=5, c=3):
    shape = (h, w) if c == 1 else (h, w, c)
    return RNG.integers(0, 256, size=shape, dtype=np.uint8)


def _raw_image(arr, encoding, step=None, data=None):
    """An Image built by hand (possibly malformed), rows padded to ``step``."""
    h, w = arr.shape[:2]
    ch = 1 if arr.ndim == 2 else arr.shape[2]
    step = w * ch if step is None else step
    if data is None:
        rows = np.full((h, step), 0xAB, dtype=np.uint8)
        rows[:, :w * ch] = arr.reshape(h, w * ch)
        data = rows.tobytes()
    msg = Image(height=h, width=w, encoding=encoding, step=step)
    msg.data = array.array('B', data)
    return msg


# --- Image --------------------------------------------------------------------------------

@pytest.mark.parametrize('encoding,channels', [
    ('bgr8', 3), ('rgb8', 3), ('mono8', 1), ('bgra8', 4), ('rgba8', 4), ('8UC1', 1),
    ('8UC3', 3), ('8UC4', 4)])
def test_image_round_trip_every_encoding(encoding, channels):
    arr = _img(c=channels)
    msg = numpy_to_image(arr, encoding, stamp=interfaces.Time(3, 4), frame_id='camera')
    assert msg.step == arr.shape[1] * channels and msg.encoding == encoding
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == \
        (3, 4, 'camera')
    out = image_to_numpy(msg)
    np.testing.assert_array_equal(out, arr)
    assert np.shares_memory(out, np.frombuffer(msg.data, np.uint8))     # a view, no copy


@pytest.mark.parametrize('encoding,channels', [('bgr8', 3), ('mono8', 1), ('bgra8', 4)])
def test_image_padded_rows(encoding, channels):
    arr = _img(7, 5, channels)
    msg = _raw_image(arr, encoding, step=5 * channels + 3)
    out = image_to_numpy(msg)
    np.testing.assert_array_equal(out, arr)
    assert np.shares_memory(out, np.frombuffer(msg.data, np.uint8))
    bgr = image_to_numpy(msg, 'bgr8')          # cv2 reads the strided view correctly
    assert bgr.shape == (7, 5, 3)


def test_image_desired_encoding_bgr8():
    bgr = _img()
    rgb = np.ascontiguousarray(bgr[..., ::-1])
    np.testing.assert_array_equal(image_to_numpy(numpy_to_image(rgb, 'rgb8'), 'bgr8'), bgr)
    bgra = cv2.cvtColor(bgr, cv2.COLOR_BGR2BGRA)
    np.testing.assert_array_equal(image_to_numpy(numpy_to_image(bgra, 'bgra8'), 'bgr8'), bgr)
    gray = _img(c=1)
    out = image_to_numpy(numpy_to_image(gray, 'mono8'), 'bgr8')
    assert out.shape == (6, 5, 3)
    np.testing.assert_array_equal(out[..., 1], gray)
    same = numpy_to_image(bgr, 'bgr8')
    assert np.shares_memory(image_to_numpy(same, 'bgr8'), np.frombuffer(same.data, np.uint8))


@pytest.mark.parametrize('mutate,text', [
    (lambda m: setattr(m, 'data', m.data[:-1]), 'data has 89 bytes but step\\*height is 90'),
    (lambda m: setattr(m, 'encoding', 'yuv422'), "encoding 'yuv422' is not supported"),
    (lambda m: setattr(m, 'step', 14), 'step 14 is smaller than width\\*channels 15'),
    (lambda m: setattr(m, 'width', 0), 'Image has zero size'),
    (lambda m: setattr(m, 'is_bigendian', 3), 'is_bigendian must be 0 or 1'),
])
def test_image_rejects_corrupt(mutate, text):
    msg = numpy_to_image(_img(), 'bgr8')
    msg = _raw_image(image_to_numpy(msg), 'bgr8')       # unchecked message we can break
    mutate(msg)
    with pytest.raises(ConversionError, match=text) as info:
        image_to_numpy(msg)
    assert isinstance(info.value, InputError) and '\n' not in str(info.value)


def test_numpy_to_image_rejects_bad_arrays():
    with pytest.raises(ConversionError, match='uint8'):
        numpy_to_image(np.zeros((4, 4, 3), np.float32))
    with pytest.raises(ConversionError, match='does not hold'):
        numpy_to_image(np.zeros((4, 4), np.uint8), 'bgr8')
    with pytest.raises(ConversionError, match='not supported'):
        numpy_to_image(np.zeros((4, 4), np.uint8), 'mono16')


# --- CompressedImage ----------------------------------------------------------------------

def test_compressed_png_lossless_and_jpeg_close():
    bgr = cv2.GaussianBlur(_img(32, 40), (5, 5), 0)
    png = numpy_to_compressed(bgr, 'png', frame_id='cam')
    assert png.format == 'bgr8; png compressed bgr8' and png.header.frame_id == 'cam'
    np.testing.assert_array_equal(compressed_to_numpy(png), bgr)
    jpg = numpy_to_compressed(bgr, 'jpeg', quality=95)
    assert 'jpeg' in jpg.format
    out = compressed_to_numpy(jpg)
    assert out.shape == bgr.shape and np.abs(out.astype(int) - bgr).mean() < 8
    gray = compressed_to_numpy(numpy_to_compressed(_img(c=1), 'png'))
    assert gray.shape == (6, 5, 3)


def test_compressed_rejects_garbage():
    msg = CompressedImage(format='jpeg')
    msg.data = array.array('B', b'not a jpeg at all')
    with pytest.raises(ConversionError, match='neither JPEG nor PNG'):
        compressed_to_numpy(msg)
    msg.data = array.array('B', bytes(numpy_to_compressed(_img()).data)[:300])
    with pytest.raises(ConversionError, match='could not be decoded'):
        compressed_to_numpy(msg)
    with pytest.raises(ConversionError, match='no data'):
        compressed_to_numpy(CompressedImage(format='jpeg'))
    with pytest.raises(ConversionError, match='not supported'):
        numpy_to_compressed(_img(), 'webp')


# --- PointCloud2 --------------------------------------------------------------------------

def _cloud(n=50):
    pts = np.zeros(n, dtype=[('x', 'f4'), ('y', 'f4'), ('z', 'f4'), ('intensity', 'f4'),
                             ('ring', 'u2')])
    for name in ('x', 'y', 'z', 'intensity'):
        pts[name] = RNG.normal(size=n)
    pts['ring'] = np.arange(n) % 16
    return pts


def test_pointcloud_round_trip_zero_copy():
    pts = _cloud()
    pts['x'][3] = np.nan
    msg = array_to_pointcloud2(pts, frame_id='lidar', stamp=TimeMsg(sec=5, nanosec=6))
    assert (msg.height, msg.width, msg.point_step) == (1, 50, pts.dtype.itemsize)
    assert [f.name for f in msg.fields] == ['x', 'y', 'z', 'intensity', 'ring']
    assert msg.header.frame_id == 'lidar' and msg.header.stamp.sec == 5
    out = pointcloud2_to_array(msg)
    assert np.shares_memory(out, np.frombuffer(msg.data, np.uint8))
    for name in pts.dtype.names:
        np.testing.assert_array_equal(out[name], pts[name])
    assert np.isnan(out['x'][3])                          # NaN points are kept ...
    assert xyz_array(out).shape == (49, 3)                # ... and dropped by the caller


def _manual_cloud(fields, point_step, rows, row_step, width, height, bigendian=False):
    msg = PointCloud2(height=height, width=width, point_step=point_step, row_step=row_step,
                      is_bigendian=bigendian)
    msg.fields = [PointField(name=n, offset=o, datatype=d, count=c) for n, o, d, c in fields]
    msg.data = array.array('B', rows)
    return msg


def test_pointcloud_odd_offsets_datatypes_bigendian_padding():
    # x f64 at 1, y f32 at 9, z i16 at 13, tag u8 at 15; point_step 20; rows padded by 7 bytes.
    width, height, point_step, row_step = 3, 2, 20, 3 * 20 + 7
    layout = [('x', 1, FLOAT64, 1), ('y', 9, FLOAT32, 1), ('z', 13, INT16, 1),
              ('tag', 15, UINT8, 1), ('rgb', 16, UINT8, 3)]
    for big in (False, True):
        order = '>' if big else '<'
        dt = np.dtype({'names': ['x', 'y', 'z', 'tag', 'rgb'],
                       'formats': [order + 'f8', order + 'f4', order + 'i2', 'u1', ('u1', 3)],
                       'offsets': [1, 9, 13, 15, 16], 'itemsize': point_step})
        pts = np.zeros(width * height, dtype=dt)
        pts['x'] = np.arange(6) + 0.5
        pts['y'] = [np.nan, 1, 2, 3, 4, 5]
        pts['z'] = -np.arange(6)
        pts['tag'] = 200
        pts['rgb'] = [[1, 2, 3]] * 6
        raw = np.full((height, row_step), 0xEE, np.uint8)
        raw[:, :width * point_step] = pts.view(np.uint8).reshape(height, -1)
        msg = _manual_cloud(layout, point_step, raw.tobytes(), row_step, width, height, big)
        out = pointcloud2_to_array(msg)
        assert out.shape == (6,)
        np.testing.assert_array_equal(out['x'], pts['x'])
        np.testing.assert_array_equal(out['z'], np.array(-np.arange(6), dtype=np.int16))
        assert np.isnan(out['y'][0]) and out['y'][5] == 5
        np.testing.assert_array_equal(out['tag'], 200)
        np.testing.assert_array_equal(out['rgb'][4], [1, 2, 3])
        back = pointcloud2_to_array(array_to_pointcloud2(out))    # re-encoded little-endian
        np.testing.assert_array_equal(back['z'], out['z'])


@pytest.mark.parametrize('mutate,text', [
    (lambda m: (setattr(m, 'width', 60), setattr(m, 'row_step', 60 * m.point_step)),
     'width\\*height = 60 points'),
    (lambda m: setattr(m, 'fields', m.fields[1:]), 'no x field'),
    (lambda m: setattr(m, 'fields', [PointField(name='x', offset=0, datatype=9, count=1)]
                       + list(m.fields[1:])), 'unknown datatype 9'),
    (lambda m: setattr(m, 'row_step', 5), 'row_step 5 is smaller'),
])
def test_pointcloud_rejects_corrupt(mutate, text):
    src = array_to_pointcloud2(_cloud())
    msg = _manual_cloud([(f.name, f.offset, f.datatype, f.count) for f in src.fields],
                        src.point_step, bytes(src.data), src.row_step, src.width, 1)
    mutate(msg)
    with pytest.raises(ConversionError, match=text):
        pointcloud2_to_array(msg)


def test_pointcloud_without_xyz_allowed_when_not_required():
    pts = np.zeros(4, dtype=[('intensity', 'f4'), ('ring', 'u2')])
    msg = array_to_pointcloud2(pts)
    assert pointcloud2_to_array(msg, require_xyz=False).shape == (4,)
    with pytest.raises(ConversionError, match='no x/y/z field'):
        pointcloud2_to_array(msg)
    with pytest.raises(ConversionError, match='cannot hold'):
        array_to_pointcloud2(np.zeros(3, dtype=[('x', 'c8')]))


def test_pointcloud_organised_2d():
    pts = _cloud(12).reshape(3, 4)
    msg = array_to_pointcloud2(pts)
    assert (msg.height, msg.width, msg.row_step) == (3, 4, 4 * pts.dtype.itemsize)
    np.testing.assert_array_equal(pointcloud2_to_array(msg)['ring'], pts['ring'].reshape(-1))


# --- CameraInfo ---------------------------------------------------------------------------

K = np.array([[500.0, 0, 320], [0, 510, 240], [0, 0, 1]])


def test_camera_info_round_trip():
    info = CameraInfoData(640, 480, K, D=[0.1, -0.2, 0.001, 0.002, 0.0])
    msg = numpy_to_camera_info(info, frame_id='camera')
    assert msg.header.frame_id == 'camera' and msg.distortion_model == 'plumb_bob'
    back = camera_info_to_numpy(msg)
    np.testing.assert_array_equal(back.K, K)
    np.testing.assert_array_equal(back.D, info.D)
    np.testing.assert_array_equal(back.R, np.eye(3))
    np.testing.assert_array_equal(back.P[:, :3], K)
    assert back.P.shape == (3, 4) and not back.K.flags.writeable
    fish = camera_info_to_numpy(numpy_to_camera_info(
        CameraInfoData(100, 80, K, D=[0.1, 0.2, 0.3, 0.4], distortion_model='equidistant')))
    assert fish.D.shape == (4,)


def test_camera_info_defaults_from_drivers():
    msg = CameraInfo(width=640, height=480, distortion_model='plumb_bob')
    msg.k = K.reshape(-1)                      # D empty, R and P all zeros
    info = camera_info_to_numpy(msg)
    np.testing.assert_array_equal(info.D, np.zeros(5))
    np.testing.assert_array_equal(info.R, np.eye(3))
    np.testing.assert_array_equal(info.P[:, :3], K)


@pytest.mark.parametrize('change,text', [
    (dict(k=np.zeros(9)), 'CameraInfo has no intrinsics \\(K is zero\\)'),
    (dict(distortion_model='fisheye_magic'), "distortion_model 'fisheye_magic' is not "
                                             'supported'),
    (dict(d=array.array('d', [0.1, 0.2])), 'needs 5 coefficients, got 2'),
    (dict(width=0), 'zero size'),
])
def test_camera_info_rejects(change, text):
    msg = numpy_to_camera_info(CameraInfoData(640, 480, K))
    for key, value in change.items():
        setattr(msg, key, value)
    with pytest.raises(ConversionError, match=text):
        camera_info_to_numpy(msg)


# --- stamps, headers and payloads ---------------------------------------------------------

def test_stamps_headers_payloads():
    t = interfaces.Time(sec=12, nanosec=345)
    assert stamp_to_time(time_to_stamp(t)) == t
    hdr = HeaderMsg(stamp=TimeMsg(sec=1, nanosec=2), frame_id='camera')
    payload_header = header_to_payload(hdr)
    assert payload_header == interfaces.Header(stamp=interfaces.Time(1, 2), frame_id='camera')
    assert payload_to_header(payload_header) == hdr
    assert make_header(payload_header, frame_id='x').frame_id == 'x'
    dets = interfaces.Detections(header=payload_header, detections=[])
    msg = payload_to_string(dets)
    assert isinstance(msg, String)
    assert string_to_payload(msg, interfaces.Detections) == dets
    assert string_to_payload(msg) == dets
    with pytest.raises(ConversionError, match='is not workzone_ros/Tracks/1'):
        string_to_payload(msg, interfaces.Tracks)
    with pytest.raises(ConversionError, match='invalid'):
        string_to_payload(String(data='{not json'), interfaces.Detections)


# --- over DDS -----------------------------------------------------------------------------

def test_round_trip_over_dds():
    """Messages built here survive a real publish/subscribe and convert zero-copy there."""
    ctx = Context()
    rclpy.init(context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    got = {}
    nodes = []
    try:
        pub_node = rclpy.create_node('conv_pub', context=ctx)
        sub_node = rclpy.create_node('conv_sub', context=ctx)
        nodes = [pub_node, sub_node]
        for node in nodes:
            executor.add_node(node)
        img_pub = pub_node.create_publisher(Image, 'conv/image', 10)
        pc_pub = pub_node.create_publisher(PointCloud2, 'conv/points', 10)
        sub_node.create_subscription(Image, 'conv/image', lambda m: got.setdefault('img', m), 10)
        sub_node.create_subscription(PointCloud2, 'conv/points',
                                     lambda m: got.setdefault('pc', m), 10)
        arr = _img(48, 64)
        pts = _cloud(1000)
        img_msg, pc_msg = numpy_to_image(arr), array_to_pointcloud2(pts)
        deadline = time.monotonic() + 10.0
        while len(got) < 2 and time.monotonic() < deadline:
            img_pub.publish(img_msg)
            pc_pub.publish(pc_msg)
            executor.spin_once(timeout_sec=0.1)
        assert len(got) == 2, 'nothing received over DDS'
        assert isinstance(got['img'].data, array.array)
        out = image_to_numpy(got['img'])
        np.testing.assert_array_equal(out, arr)
        assert np.shares_memory(out, np.frombuffer(got['img'].data, np.uint8))
        np.testing.assert_array_equal(pointcloud2_to_array(got['pc'])['ring'], pts['ring'])
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
