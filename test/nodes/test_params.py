"""Node parameters generated from the core configuration dataclasses (one source of truth)."""
from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest
import yaml
from rclpy.parameter import Parameter

from workzone_ros.core.detect import DetectorConfig
from workzone_ros.core.fusion import FusionConfig
from workzone_ros.core.knobs import knob
from workzone_ros.core.lidar_clustering import ClusterParams
from workzone_ros.core.track import TrackerConfig
from workzone_ros.nodes import (
    classifier,
    color_detector,
    fusion,
    lidar_cluster,
    projector,
    tracker,
)
from workzone_ros.nodes.params import ConfigError, params_from_dataclass
from workzone_ros.resources import config_path


@dataclasses.dataclass(frozen=True)
class Toy:
    gain: float = knob(0.5, 'a gain', min=0, max=2)
    count: int = knob(3, 'a count', min=1.0, max=10.0)
    mode: str = knob('fast', 'a mode', choices=('fast', 'slow'))
    on: bool = knob(True, 'a switch')
    pair: tuple[float, float] = knob((0.5, 0.25), 'an (x, y) pair')
    nested: dict = dataclasses.field(default_factory=dict)       # not a parameter
    cache: int = dataclasses.field(default=0, init=False)         # not a parameter


def test_a_param_per_scalar_or_tuple_field_from_its_knob():
    params = {p.name: p for p in params_from_dataclass(Toy)}
    assert list(params) == ['gain', 'count', 'mode', 'on', 'pair']
    gain, count = params['gain'], params['count']
    assert (gain.default, gain.description, gain.min, gain.max) == (0.5, 'a gain', 0.0, 2.0)
    # bounds take the default's type (an int range for an int, a float range for a float)
    assert type(gain.min) is float and type(count.min) is int and count.max == 10
    assert params['mode'].choices == ('fast', 'slow') and params['mode'].kind() == 'str'
    assert params['on'].min is None and params['on'].kind() == 'bool'
    assert params['pair'].default == [0.5, 0.25] and params['pair'].kind() == 'float[]'
    assert params['gain'].check(3.0) == 'gain = 3.0 is above the maximum 2.0'


def test_only_skip_prefix_and_node_defaults():
    assert [p.name for p in params_from_dataclass(Toy, only=('mode', 'gain'))] == ['gain',
                                                                                    'mode']
    assert 'gain' not in {p.name for p in params_from_dataclass(Toy, skip=('gain',))}
    p = params_from_dataclass(Toy, only=('gain',), prefix='toy.')[0]
    assert (p.name, p.attr) == ('toy.gain', 'toy_gain')
    p = params_from_dataclass(Toy, only=('gain',), defaults={'gain': 0.0})[0]
    assert p.default == 0.0 and p.description == 'a gain [Toy default: 0.5]'
    for kwargs in ({'only': ('gian',)}, {'skip': ('nested',)}, {'defaults': {'cache': 1}}):
        with pytest.raises(ConfigError, match='not a parameter field'):
            params_from_dataclass(Toy, **kwargs)
    with pytest.raises(ConfigError, match='not a dataclass'):
        params_from_dataclass(int)


def test_an_undocumented_field_is_an_error():
    @dataclasses.dataclass
    class Bare:
        documented: float = knob(1.0, 'fine')
        forgotten: float = 2.0

    with pytest.raises(ConfigError, match=r'Bare\.forgotten has no description'):
        params_from_dataclass(Bare)
    assert [p.name for p in params_from_dataclass(Bare, skip=('forgotten',))] == ['documented']
    with pytest.raises(ValueError, match='doc must say what it does'):
        knob(1.0, '  ')


def test_knobs_and_the_core_configs_import_without_rclpy():
    code = ('import sys; import workzone_ros.core.knobs, workzone_ros.core.track.config, '
            'workzone_ros.core.fusion, workzone_ros.core.lidar_clustering, '
            'workzone_ros.core.detect.config; '
            "assert 'rclpy' not in sys.modules, 'rclpy imported'")
    subprocess.run([sys.executable, '-c', code], check=True)


#: Node defaults that deliberately differ from the dataclass (see nodes/tracker.py).
NODE_DEFAULTS = {'tracker': {'min_approach_speed': 0.0}}
#: Fields that are no node parameter: the tracker evaluation's switches.
NOT_PARAMETERS = {'tracker': tracker.EVALUATION_ONLY}


@pytest.mark.parametrize('section,cls,table', [
    ('tracker', TrackerConfig, tracker._CORE_PARAMS),
    ('fusion', FusionConfig, fusion._CORE_PARAMS),
    ('lidar_cluster', ClusterParams, lidar_cluster.CORE_PARAMS),
])
def test_every_config_field_is_a_node_parameter_with_its_knob(section, cls, table):
    node_class = {'tracker': tracker, 'fusion': fusion,
                  'lidar_cluster': lidar_cluster}[section].NODE_CLASS
    declared = {p.name: p for p in node_class.PARAMS}
    fields = [f for f in dataclasses.fields(cls) if f.name not in NOT_PARAMETERS.get(section, ())]
    assert [p.name for p in table] == [f.name for f in fields]
    assert not set(NOT_PARAMETERS.get(section, ())) & set(declared)
    for f in fields:
        p = declared[f.name]
        want = NODE_DEFAULTS.get(section, {}).get(f.name, f.default)
        assert p.default == (list(want) if isinstance(want, tuple) else want), f.name
        assert type(p.default) is (list if isinstance(want, tuple) else type(want)), f.name
        assert len(p.description) > 10 and p.description.startswith(f.metadata['doc'])
        assert (p.min, p.max) == (f.metadata['min'], f.metadata['max']), f.name
        assert p.choices == f.metadata['choices'], f.name
        if p.min is not None:
            assert p.check(p.min) is None and p.check(p.min - 1) is not None, f.name
        if p.max is not None:
            assert p.check(p.max) is None and p.check(p.max + 1) is not None, f.name
        if p.choices:
            assert p.check('not-a-choice') is not None, f.name


def test_the_params_file_sets_only_what_differs_from_the_defaults():
    doc = yaml.safe_load(config_path('workzone.yaml').read_text())
    # the extrinsics every vehicle edits are kept even at the simulator's values
    kept_on_purpose = {('lidar_cluster', 'lidar_in_base'), ('projector', 'lidar_in_base'),
                       ('projector', 'lidar_to_camera')}
    for section, module in (('tracker', tracker), ('fusion', fusion),
                            ('lidar_cluster', lidar_cluster),
                            ('color_detector', color_detector), ('projector', projector),
                            ('classifier', classifier)):
        declared = {p.name: p for p in module.NODE_CLASS.PARAMS}
        for key, value in (doc[section]['ros__parameters'] or {}).items():
            assert key in declared, f'{section}.{key} is not a parameter'
            p = declared[key]
            assert p.check(value) is None, f'{section}.{key}: {p.check(value)}'
            same = p.normalise(value) == p.normalise(p.default)
            assert not same or (section, key) in kept_on_purpose, \
                f'{section}.{key} = {value!r} is the default: drop it from the params file'


def test_the_color_detector_table_is_the_detector_config_knobs_for_its_names():
    """The node's DetectorConfig parameters come from the fields' knobs (a chosen subset:
    the other fields are measured refinement constants); none is declared twice by hand."""
    declared = {p.name: p for p in color_detector.NODE_CLASS.PARAMS}
    fields = {f.name: f for f in dataclasses.fields(DetectorConfig)}
    assert [p.name for p in color_detector._CORE_PARAMS] == \
        [n for n in fields if n in color_detector._CORE]
    assert set(declared) & set(fields) == set(color_detector._CORE)
    for name in color_detector._CORE:
        p, f = declared[name], fields[name]
        want = f.default
        assert p.default == (list(want) if isinstance(want, tuple) else want), name
        assert type(p.default) is (list if isinstance(want, tuple) else type(want)), name
        assert p.description == f.metadata['doc'] and '``' not in p.description, name
        assert (p.min, p.max, p.choices) == (f.metadata['min'], f.metadata['max'],
                                             f.metadata['choices']), name
        for bound, step in ((p.min, -1), (p.max, 1)):
            if bound is not None:
                assert p.check(bound) is None and p.check(bound + step) is not None, name
                # the node's range lies inside what DetectorConfig itself accepts
                DetectorConfig(**{name: bound})
        if p.choices:
            assert p.check('not-a-choice') is not None, name
    # the node builds its DetectorConfig from exactly these parameters
    assert DetectorConfig(**{p.attr: p.normalise(p.default)
                             for p in color_detector._CORE_PARAMS}) == DetectorConfig()


def test_color_detector_ranges_are_enforced_on_a_live_set(ros):
    node = ros.add(color_detector.NODE_CLASS(context=ros.context))
    assert node._detector.config == DetectorConfig()

    def reason(name, value):
        result = node.set_parameters([Parameter(name, value=value)])[0]
        return None if result.successful else result.reason

    assert 'out of range' in reason('threshold', 0.995)
    assert 'out of range' in reason('scale', 5)
    assert 'out of range' in reason('nms_iou', 1.5)
    assert 'out of range' in reason('foreign_prior', -0.1)
    assert "is not one of 'learned', 'rgb_lp', 'hsv'" in reason('method', 'cnn')
    assert node._detector.config == DetectorConfig()        # nothing applied
    for name, value in (('threshold', 0.99), ('scale', 1), ('grow_level', 0.0),
                        ('colors', ['orange']), ('method', 'hsv')):
        assert reason(name, value) is None, name
    want = dataclasses.replace(DetectorConfig(), threshold=0.99, scale=1, grow_level=0.0,
                               colors=('orange',), method='hsv')
    assert node._detector.config == want


NODE_MODULES = (classifier, color_detector, fusion, lidar_cluster, projector, tracker)


@pytest.mark.parametrize('module', NODE_MODULES, ids=lambda m: m.__name__.rsplit('.', 1)[-1])
def test_topics_are_fixed_at_start_up(module):
    # a node subscribes and advertises once: a live topic change would be accepted and
    # silently do nothing, so every topic parameter refuses it
    topics = [p.name for p in module.NODE_CLASS.PARAMS if p.name.endswith('_topic')]
    assert topics
    assert [t for t in topics
            if not next(p for p in module.NODE_CLASS.PARAMS if p.name == t).read_only] == []


def test_a_live_topic_change_is_refused_with_the_reason(ros):
    node = ros.add(tracker.NODE_CLASS(context=ros.context))
    for name, value in (('image_topic', '/other/image'), ('image_buffer', 20)):
        result = node.set_parameters([Parameter(name, value=value)])[0]
        assert not result.successful and 'read-only' in result.reason
    assert node.params.image_topic == '/camera/image_raw'
    assert node.set_parameters([Parameter('min_similarity', value=0.5)])[0].successful
