"""core.pointcloud: field layouts at any offset / datatype / endianness, padding, errors."""
import numpy as np
import pytest

from workzone_ros.core import pointcloud as pc


def test_round_trip_packed_fields():
    pts = pc.make_points(x=np.arange(5, dtype=np.float32), y=np.ones(5, np.float32),
                         z=np.zeros(5, np.float32), intensity=np.full(5, 7, np.float32),
                         ring=np.arange(5, dtype=np.uint16))
    fields = pc.dtype_to_fields(pts.dtype)
    assert [f.datatype for f in fields] == [pc.FLOAT32] * 4 + [pc.UINT16]
    view = pc.cloud_view(pts.tobytes(), fields, pts.dtype.itemsize, 5, 1, 5 * pts.dtype.itemsize)
    np.testing.assert_array_equal(view['ring'], np.arange(5))
    np.testing.assert_array_equal(pc.xyz_array(view)[:, 0], np.arange(5))


def test_odd_offsets_big_endian_and_row_padding():
    fields = [pc.FieldSpec('intensity', 0, pc.UINT8), pc.FieldSpec('x', 3, pc.FLOAT64),
              pc.FieldSpec('y', 11, pc.FLOAT64), pc.FieldSpec('z', 19, pc.INT16)]
    point_step, width, height, row_step = 24, 3, 2, 24 * 3 + 5
    dt = pc.fields_to_dtype(fields, point_step, is_bigendian=True)
    rows = np.zeros((height, row_step), np.uint8)
    pts = np.zeros(width * height, dt)
    pts['x'] = np.arange(6) * 1.5
    pts['z'] = -np.arange(6)
    rows[:, : width * point_step] = pts.view(np.uint8).reshape(height, -1)
    view = pc.cloud_view(rows.tobytes(), fields, point_step, width, height, row_step, True)
    np.testing.assert_array_equal(view['x'], np.arange(6) * 1.5)
    np.testing.assert_array_equal(view['z'], -np.arange(6))


def test_nan_points_dropped_on_request():
    pts = pc.make_points(x=np.array([1, np.nan], np.float32), y=np.zeros(2, np.float32),
                         z=np.zeros(2, np.float32))
    assert pc.xyz_array(pts).shape == (1, 3)
    assert pc.xyz_array(pts, drop_nan=False).shape == (2, 3)


@pytest.mark.parametrize('kwargs, fragment', [
    (dict(data=b'\0' * 10, width=4, height=1, row_step=16), 'data has 10 bytes'),
    (dict(data=b'\0' * 64, width=4, height=1, row_step=8), 'row_step'),
])
def test_inconsistent_sizes(kwargs, fragment):
    fields = [pc.FieldSpec('x', 0, pc.FLOAT32)]
    with pytest.raises(pc.PointCloudError, match=fragment):
        pc.cloud_view(kwargs['data'], fields, 4, kwargs['width'], kwargs['height'],
                      kwargs['row_step'])


def test_bad_layouts():
    with pytest.raises(pc.PointCloudError, match='unknown datatype 42'):
        pc.fields_to_dtype([pc.FieldSpec('x', 0, 42)], 4)
    with pytest.raises(pc.PointCloudError, match='does not fit'):
        pc.fields_to_dtype([pc.FieldSpec('x', 2, pc.FLOAT32)], 4)
    with pytest.raises(pc.PointCloudError, match='no y/z field'):
        pc.xyz_array(pc.make_points(x=np.zeros(2, np.float32)))
