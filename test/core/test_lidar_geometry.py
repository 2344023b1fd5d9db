"""Tests for core/lidar_geometry.py: mounting, axes, ground-plane fit, beam spacing."""
import math

import numpy as np
import pytest

from workzone_ros.core.lidar_geometry import (
    GroundPlane,
    LidarGeometryError,
    Mount,
    beam_spacing,
    describe_axes,
    fit_ground,
)


def test_mount_axes_and_height():
    m = Mount.from_list([1.0, 0.0, 1.84, 0.0, 0.0, -math.pi / 2])    # x right, y forward
    assert describe_axes(m.rot) == 'x right, y forward, z up'
    # 10 m ahead of the car and 1 m up is lidar (0, 10, 1 - 1.84): y is forward.
    lvl = m.to_level(np.array([[0.0, 10.0, -0.84]]))
    assert lvl[0] == pytest.approx([10.0, 0.0, 1.0], abs=1e-9)
    assert m.to_lidar(lvl)[0] == pytest.approx([0.0, 10.0, -0.84], abs=1e-9)
    assert '1.84 m above the road' in m.describe()


@pytest.mark.parametrize('values, needle', [
    ([1.0, 0.0, 1.95], 'needs 6 values'),
    ([1.0, 0.0, -1.95, 0, 0, 0], 'height of the sensor above'),
    ([1.0, 0.0, 1.95, 0, 0, 90.0], 'degrees'),
    ([1.0, 0.0, float('nan'), 0, 0, 0], 'not finite'),
])
def test_bad_mountings_are_one_line_errors(values, needle):
    with pytest.raises(LidarGeometryError, match=needle) as err:
        Mount.from_list(values)
    assert '\n' not in str(err.value)


def _ground(pitch_deg=0.0, offset=0.0, n=4000, seed=0):
    """Road returns in the level frame of a sensor pitched by ``pitch_deg`` (nose down: the
    road seems to rise ahead) whose configured height is ``offset`` m off."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-40, 40, n), rng.uniform(-12, 12, n)
    z = offset + math.tan(math.radians(pitch_deg)) * x + rng.normal(0, 0.02, n)
    return np.column_stack([x, y, z])


def test_ground_fit_recovers_pitch_and_height_error_through_clutter():
    road = _ground(pitch_deg=1.2, offset=-0.3)
    rng = np.random.default_rng(1)
    cars = np.column_stack([rng.uniform(10, 14, 800), rng.uniform(-5, -3, 800),
                            rng.uniform(0.2, 1.5, 800)])              # a car's side and rear
    curb = np.column_stack([rng.uniform(0, 40, 600), rng.uniform(11, 12, 600),
                            np.full(600, 0.15)])                       # a sidewalk edge
    g = fit_ground(np.vstack([road, cars, curb]))
    assert g.source == 'fit'
    assert math.degrees(math.atan(g.a)) == pytest.approx(1.2, abs=0.1)
    assert g.c == pytest.approx(-0.3, abs=0.03) and abs(g.b) < 0.005
    # A point 1.55 m above the road 60 m ahead is 1.55 m up, though it seems 2.5 m lower.
    p = np.array([[60.0, 0.0, -0.3 + math.tan(math.radians(1.2)) * 60 + 1.55]])
    assert g.height(p)[0] == pytest.approx(1.55, abs=0.1)


def test_no_ground_falls_back_to_the_prior_then_the_mounting():
    wall = np.column_stack([np.full(500, 8.0), np.linspace(-5, 5, 500), np.full(500, 0.1)])
    assert fit_ground(wall).source == 'mount'
    prior = GroundPlane(0.01, 0.0, -0.1, 900, 'fit')
    back = fit_ground(wall[:10], prior)
    assert back.source == 'prior' and back.c == -0.1
    steep = _ground(pitch_deg=12.0)                    # not a road: the mounting wins
    assert fit_ground(steep).source == 'mount'


def test_beam_spacing_from_the_ring_field():
    el = np.radians(np.linspace(-15, 15, 16))          # a VLP-16
    ring = np.repeat(np.arange(16), 50)
    az = np.tile(np.linspace(-1, 1, 50), 16)
    r = 20.0
    xyz = np.column_stack([r * np.cos(az), r * np.sin(az),
                           r * np.tan(el[ring])])
    assert math.degrees(beam_spacing(xyz, ring)) == pytest.approx(2.0, abs=1e-6)
    assert math.isnan(beam_spacing(xyz, None))
