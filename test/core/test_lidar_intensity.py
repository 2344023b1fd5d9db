"""Tests for core/lidar_intensity.py: the learned intensity scale and the silence warning."""
import numpy as np
import pytest

from workzone_ros.core.lidar_intensity import (
    IntensityScale,
    SilenceWatch,
    finite_max,
    infer_encoding,
)


@pytest.mark.parametrize('dtype, top, expected', [
    ('f4', 0.97, 'unit'), ('f4', 1.0, 'unit'), ('f4', 254.0, '8bit'), ('f8', 37.0, '8bit'),
    ('u1', 0.0, '8bit'), ('u2', 250.0, '8bit'), ('u2', 65000.0, '16bit'),
    ('f4', 4000.0, '16bit'), ('f4', float('nan'), 'unit')])
def test_encoding_from_datatype_and_values(dtype, top, expected):
    assert infer_encoding(np.dtype(dtype), top) == expected


def test_learned_scale_is_said_once_and_revised_when_values_disagree():
    s = IntensityScale()
    assert s.update(np.array([0.1, 0.9, np.nan], np.float32)) == pytest.approx(255.0)
    lines = s.pop_messages()
    assert len(lines) == 1 and 'reflectance 0-1' in lines[0] and 'x255' in lines[0]
    s.update(np.array([0.2, 0.8], np.float32))
    assert s.pop_messages() == []
    for _ in range(3):
        s.update(np.array([0.5], np.float32))
    # a 0-255 sensor after all: revised when three scans in a row say so, not on one
    assert s.update(np.array([3.0, 200.0], np.float32)) == pytest.approx(255.0)
    assert s.update(np.array([0.5], np.float32)) == pytest.approx(255.0)
    for _ in range(2):
        assert s.update(np.array([3.0, 200.0], np.float32)) == pytest.approx(255.0)
    assert s.update(np.array([3.0, 200.0], np.float32)) == 1.0
    assert 'revised to 0-255' in s.pop_messages()[0]


def test_uint16_and_fixed_scales():
    s = IntensityScale()
    assert s.update(np.array([10, 60000], np.uint16)) == pytest.approx(255 / 65535)
    fixed = IntensityScale(fixed=2.0)
    assert fixed.update(np.array([0.5], np.float32)) == 2.0
    assert 'as given' in fixed.pop_messages()[0]
    with pytest.raises(ValueError):
        IntensityScale(fixed=-1.0)


def test_finite_max_ignores_nan_and_inf():
    assert finite_max(np.array([np.nan, 3.0, np.inf, 1.0])) == 3.0
    assert np.isnan(finite_max(np.array([np.nan, np.nan])))
    assert finite_max(np.array([7, 2], np.uint8)) == 7.0


def test_silence_watch_reports_the_observed_range_every_n_scans():
    w = SilenceWatch(n=3)
    raw = np.linspace(0.0, 0.4, 1000).astype(np.float32)
    got = [w.update(1000, 0, raw, 255.0, 120.0) for _ in range(6)]
    assert got[:2] == [None, None] and got[3:5] == [None, None]
    assert 'min_intensity 120' in got[2] and '0..0.4' in got[2] and 'up to 102' in got[2]
    assert 'intensity_scale' in got[2] and got[5] is not None
    assert w.update(1000, 5, raw, 255.0, 120.0) is None and w.run == 0
    assert w.update(0, 0, raw[:0], 255.0, 120.0) is None          # an empty cloud says nothing
