"""DetectorConfig's ranges: one generic check of its knobs' metadata (core.knobs.check_knobs),
the same values accepted and refused as by the hand-written checks it replaced."""
from __future__ import annotations

import dataclasses
import math

import pytest

from workzone_ros.core.detect import DetectorConfig
from workzone_ros.core.detect.config import METHODS
from workzone_ros.core.knobs import check_knobs, knob

INF = math.inf

#: Every range DetectorConfig enforces itself, as the hand-written checks had it:
#: field -> (lo, hi, lo excluded, hi excluded); None: unbounded.  int fields are compared
#: as int(value) unless listed in INTEGER (a whole number in lo..hi).
RANGES = {
    'threshold': (0.0, 1.0, True, True),
    'scale': (1, None, False, False),
    'foreign_prior': (0.0, 1.0, False, False),
    'diamond_max_change': (0.0, 1.0, True, False),
    'diamond_stroke_steps': (0, 4, False, False),
    'diamond_edge_bias': (-1.0, 2.0, False, False),
    'diamond_blur_bias': (-1.0, 2.0, False, False),
    'diamond_blur_sigma': (0.0, None, True, False),
    'diamond_tall_max': (1.0, 2.0, False, False),
    'diamond_wide_max': (1.0, 2.0, False, False),
    'cut_min_width': (0.0, 1.0, False, False),
    'diamond_box_bias': (-1.0, 2.0, False, False),
    'diamond_square_px': (0.0, None, False, False),
    'diamond_square_max': (0.0, None, False, False),
    'white_own_rel': (0.0, 1.0, False, True),
    'refined_clamp': (0.0, 2.0, False, False),
    'hold_sat': (0.0, 1.5, False, False),
    'blur_fit_ratio': (0.5, 2.0, False, False),
    'blur_fit_max_sigma': (0.3, 10.0, True, False),
    'max_blur_fits': (0, 50, False, False),
    'max_grown': (0, 100, False, False),
    'max_shifted': (0, 50, False, False),
    'blur_fit_bias': (-3.0, 3.0, False, False),
    'rim_chroma': (0.0, 1.0, False, False),
    'search_min_contrast': (0.0, 1.0, True, True),
    'shift_min_px': (0.0, None, False, False),
    'diamond_hold': (0.0, 1.0, True, False),
    'v_hysteresis': (0.0, 1.0, False, False),
    'grow_level': (0.0, 1.0, False, False),
    'grow_reach': (0.0, None, False, False),
    'grow_min_px': (0.0, None, False, False),
    'thin_min_radius_px': (0.0, None, False, False),
    'ext_band_long': (0.0, None, True, False),
    'clip_grow': (0.0, None, False, False),
    'ext_overlong_border': (0.0, 1.0, False, False),
    'rect_clip_bias': (0.0, None, False, False),
    'ext_overlong': (0.0, None, False, False),
    'ext_ratio_tol': (0.0, None, False, False),
}
INTEGER = {'diamond_stroke_steps', 'max_blur_fits', 'max_grown', 'max_shifted'}
FIELDS = {f.name: f for f in dataclasses.fields(DetectorConfig)}


def _refused(**kwargs) -> bool:
    try:
        DetectorConfig(**kwargs)
    except ValueError:
        return True
    return False


def _checked_range(f):
    """(lo, hi) DetectorConfig checks for field ``f`` per its metadata, or None."""
    check = f.metadata.get('check', True)
    if check is False:
        return None
    lo, hi = (f.metadata['min'], f.metadata['max']) if check is True else check
    return None if lo is None and hi is None else (lo, hi)


def test_every_field_is_a_documented_knob_and_the_defaults_are_valid():
    config = DetectorConfig()
    for f in dataclasses.fields(DetectorConfig):
        assert f.metadata['doc'].strip(), f.name
    check_knobs(config)                                  # no error
    assert dataclasses.replace(config) == config


def test_the_metadata_ranges_are_exactly_the_checked_ones():
    got = {}
    for name, f in FIELDS.items():
        r = _checked_range(f)
        if r is not None:
            got[name] = (*r, bool(f.metadata.get('open_lo')), bool(f.metadata.get('open_hi')))
    assert got == RANGES
    assert {n for n, f in FIELDS.items() if f.metadata.get('integer')} == INTEGER


@pytest.mark.parametrize('name', sorted(RANGES))
def test_bounds_and_just_outside(name):
    lo, hi, open_lo, open_hi = RANGES[name]
    f = FIELDS[name]
    if type(f.default) is int:
        if lo is not None:
            assert _refused(**{name: lo}) is False, name
            assert _refused(**{name: lo - 1}), name
        if hi is not None:
            assert _refused(**{name: hi}) is False, name
            assert _refused(**{name: hi + 1}), name
        if name in INTEGER:
            assert _refused(**{name: lo + 0.5}), name
            assert _refused(**{name: float(lo)}) is False, name
        else:                                            # int(value) as before: truncated
            assert _refused(**{name: lo + 0.5}) is False, name
        return
    for bound, excluded, outward in ((lo, open_lo, -INF), (hi, open_hi, INF)):
        if bound is None:
            assert _refused(**{name: outward}) is False, name     # unbounded that way
            continue
        assert _refused(**{name: bound}) is excluded, (name, bound)
        assert _refused(**{name: math.nextafter(bound, outward)}), (name, bound)
        assert _refused(**{name: math.nextafter(bound, -outward)}) is False, (name, bound)
    assert _refused(**{name: math.nan}), name            # NaN is in no range


def test_the_message_names_the_field_its_range_and_unit():
    cases = {
        'threshold': (1.0, 'threshold must be in (0, 1) (a posterior probability), got 1.0'),
        'white_own_rel': (1.0, 'white_own_rel must be in [0, 1) (a share of the level of the '
                               'white part itself; 0: off), got 1.0'),
        'clip_grow': (-0.5, "clip_grow must be >= 0 (a share of the core's size; 0: off), "
                            'got -0.5'),
        'ext_band_long': (0.0, 'ext_band_long must be > 0 (orange heights), got 0.0'),
        'diamond_stroke_steps': (7, 'diamond_stroke_steps must be an integer in 0..4 (steps '
                                    'of the edge blur grid; 0 = off), got 7'),
        'foreign_prior': (1.5, "foreign_prior must be in [0, 1] (0: the model prior's mean), "
                               'got 1.5'),
        'scale': (0, 'scale must be >= 1 (an integer downscale factor), got 0'),
    }
    for name, (value, message) in cases.items():
        with pytest.raises(ValueError) as err:
            DetectorConfig(**{name: value})
        assert str(err.value) == message
    with pytest.raises(ValueError, match=r"method 'cnn' is not one of \('learned'"):
        DetectorConfig(method='cnn')
    for m in METHODS:
        assert DetectorConfig(method=m).method == m


def test_node_ranges_are_not_the_dataclass_ones():
    """The node parameters' ranges (min / max) of the fields marked ``check=False`` are not
    enforced by DetectorConfig itself (the tools sweep outside them), as before."""
    unchecked = sorted(n for n, f in FIELDS.items() if f.metadata.get('check') is False)
    assert unchecked == sorted([
        'open_px', 'close_px', 'min_radius_px', 'max_radius_px', 'min_area_px', 'nms_iou',
        'ext_min_aspect', 'roi_prior', 'roi_threshold', 'roi_margin', 'roi_relax',
        'lidar_confidence', 'lidar_only_threshold', 'lidar_only_confidence', 'smooth_px',
        'border_frac'])
    for name in unchecked:
        f = FIELDS[name]
        assert f.metadata['min'] is not None, name          # a node range all the same
        beyond = f.metadata['max'] + 1 if f.metadata['max'] is not None else -1
        assert _refused(**{name: beyond}) is False, name
    # threshold's node range is [0.01, 0.99]; the dataclass takes all of (0, 1)
    assert (FIELDS['threshold'].metadata['min'], FIELDS['threshold'].metadata['max']) == \
        (0.01, 0.99)
    assert DetectorConfig(threshold=0.001).threshold == 0.001
    assert DetectorConfig(scale=8).scale == 8                # node: 1..4


def test_the_hand_written_checks_remain():
    for bad, name in (({'colors': ('orange', 'blue')}, 'unknown colours'),
                      ({'diamond_grown_starts': (1.2, 3.5)}, 'diamond_grown_starts'),
                      ({'rect_dim_bias': (0.3, 170.0, 80.0)}, 'rect_dim_bias'),
                      ({'diamond_bright_bias': (2.5, 0.47, 0.95)}, 'diamond_bright_bias'),
                      ({'rect_inward': (0.0,)}, 'rect_inward')):
        with pytest.raises(ValueError, match=name):
            DetectorConfig(**bad)
    assert DetectorConfig(rect_inward=(), diamond_grown_starts=()).rect_inward == ()


@dataclasses.dataclass(frozen=True)
class Toy:
    share: float = knob(0.5, 'a share', 0.0, 1.0, open_hi=True, note='0: off')
    steps: int = knob(1, 'steps', 0, 3, integer=True)
    count: int = knob(2, 'a count', min=1)
    node_only: float = knob(0.5, 'node range only', 0.0, 1.0, check=False)
    wider: float = knob(0.5, 'checked wider', 0.1, 0.9, check=(0.0, None), open_lo=True)
    mode: str = knob('a', 'a mode', choices=('a', 'b'))
    plain: float = 7.0                                   # no knob: not checked

    def __post_init__(self):
        check_knobs(self, KeyError)


def test_check_knobs_semantics():
    Toy(share=0.0, steps=3, count=1, node_only=5.0, wider=1e9, mode='b', plain=math.nan)
    for kwargs, message in (
            ({'share': 1.0}, 'share must be in [0, 1) (0: off), got 1.0'),
            ({'steps': 2.5}, 'steps must be an integer in 0..3, got 2.5'),
            ({'count': 0}, 'count must be >= 1, got 0'),
            ({'count': 'two'}, "count must be >= 1, got 'two'"),
            ({'wider': 0.0}, 'wider must be > 0, got 0.0'),
            ({'mode': 'c'}, "mode 'c' is not one of ('a', 'b')")):
        with pytest.raises(KeyError) as err:             # the error class is the caller's
            Toy(**kwargs)
        assert err.value.args[0] == message
    assert Toy(count=1.9).count == 1.9                   # int(1.9) = 1: in range
