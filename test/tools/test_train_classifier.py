"""tools.train_classifier: folder datasets, clip exclusion, one-line errors, a tiny CLI run."""
import csv
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from workzone_ros.core import classifier as cl
from workzone_ros.tools import eval_classifier as ev
from workzone_ros.tools import train_classifier as tc

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'core'))
from test_classifier import art_crop  # noqa: E402

KEYS = ('road_work_ahead', 'stop', 'background')


def _folder(root, n=10, seed=0, clips=('clipA', 'clipB')):
    """``root/<class>/*.png`` with an index.csv assigning crops to clips in turn."""
    rng = np.random.default_rng(seed)
    rows = []
    for key in KEYS:
        (root / key).mkdir(parents=True)
        for i in range(n):
            name = f'{key}/{i:03d}.png'
            cv2.imwrite(str(root / name), art_crop(key, rng))
            rows.append([name, key, clips[i % len(clips)]])
    with open(root / 'index.csv', 'w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(['path', 'class_key', 'clip'])
        w.writerows(rows)
    return root


def _run(capsys, *argv):
    code = tc.main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_missing_folder_is_one_line_error(tmp_path, capsys):
    code, _, err = _run(capsys, '--synth', '0', '--data', str(tmp_path / 'nope'),
                        '-o', str(tmp_path / 'm.npz'))
    assert code == 2
    assert err.strip().count('\n') == 0 and 'does not exist' in err and 'nope' in err
    assert not (tmp_path / 'm.npz').exists()


def test_unknown_class_folder_is_one_line_error(tmp_path, capsys):
    root = _folder(tmp_path / 'data', n=2)
    (root / 'stopp').mkdir()
    code, _, err = _run(capsys, '--synth', '0', '--data', str(root), '-o',
                        str(tmp_path / 'm.npz'))
    assert code == 2
    assert err.strip().count('\n') == 0 and 'unknown class folder(s) stopp' in err


def test_no_sources_and_missing_classes_are_errors(tmp_path, capsys):
    code, _, err = _run(capsys, '--synth', '0', '-o', str(tmp_path / 'm.npz'))
    assert code == 2 and 'no training crops' in err
    root = _folder(tmp_path / 'data', n=2)
    code, _, err = _run(capsys, '--synth', '0', '--data', str(root), '--classes', 'workzone',
                        '-o', str(tmp_path / 'm.npz'))
    assert code == 2 and 'no crops of class(es)' in err and err.strip().count('\n') == 0


def test_load_folder_excludes_clips(tmp_path):
    root = _folder(tmp_path / 'data', n=4)
    every = tc.load_folder(root)
    assert len(every) == 12 and set(every.clip) == {'clipA', 'clipB'}
    kept = tc.load_folder(root, exclude_clips=['clipA'])
    assert len(kept) == 6 and set(kept.clip) == {'clipB'}
    only = tc.load_folder(root, only_clips=['clipA'])
    assert set(only.clip) == {'clipA'} and len(only) == 6


def test_general_sign_crops_become_background_without_their_class():
    assert tc.map_labels(['stop', 'road_work_ahead'], tc.class_list('workzone')) == [
        'background', 'road_work_ahead']
    assert tc.map_labels(['stop'], tc.class_list('all')) == ['stop']


def test_visible_part_of_an_export_crop_leaving_the_frame():
    patch = np.zeros((64, 64, 3), np.uint8)
    row = {'crop_x': '600', 'crop_y': '100', 'crop_w': '64', 'crop_h': '64'}
    part = tc._visible_part(patch, row, (640, 480))
    assert part.shape[:2] == (64, 40)                      # 40 of 64 px inside the frame
    row['crop_x'] = '620'                                  # under half inside: dropped
    assert tc._visible_part(patch, row, (640, 480)) is None
    row['crop_x'] = '10'
    assert tc._visible_part(patch, row, (640, 480)) is patch


def test_cli_trains_a_model_from_a_folder(tmp_path, capsys):
    root = _folder(tmp_path / 'data', n=10)
    out = tmp_path / 'model.npz'
    code, stdout, err = _run(capsys, '--synth', '0', '--data', str(root), '--classes',
                             'present', '--exclude-clip', 'clipB', '--cv', '2', '-o', str(out))
    assert code == 0, err
    assert 'model written to' in stdout and 'PCA 10 components hold' in err
    model = cl.load_model(out)
    md = model.metadata
    assert model.classes == ('road_work_ahead', 'stop', 'background')
    assert md['train_counts'] == {k: 5 for k in model.classes}        # clipB left out
    src = md['training_sources']
    assert src['renders'] is None and src['excluded_clips'] == ['clipB']
    assert src['folders'][0]['clips'] == ['clipA'] and src['folders'][0]['crops'] == 15
    assert md['features'] == tc.DEFAULT_FEATURES and md['method'] == 'svm'


def test_evaluation_helpers_count_what_they_say():
    classes = ['lane_shift_left', 'lane_shift_right', 'stop', 'background']
    truth = ['lane_shift_left'] * 4 + ['lane_shift_right'] * 4 + ['background'] * 5
    pred = (['lane_shift_left'] * 3 + ['lane_shift_right'] + ['lane_shift_right'] * 4
            + ['background'] * 4 + ['stop'])
    conf = ev.scores(truth, pred, classes)['confusion']
    pair = ev.mirror_separation(conf, classes)['lane_shift_left/lane_shift_right']
    assert pair == {'crops': 8, 'swapped': 1, 'separation': 0.875}
    bg = ev.background_fp(truth, pred)
    assert bg['false_sign_rate'] == 0.2 and bg['false_workzone_rate'] == 0.0
    # splits never share a group
    labels = ['a'] * 30 + ['b'] * 30
    groups = [f'g{i // 3}' for i in range(60)]
    for tr, te in ev.grouped_splits(labels, groups, 3):
        assert not {groups[i] for i in tr} & {groups[i] for i in te}
        assert len(te) in range(15, 26)


@pytest.mark.parametrize('argv', [['--help']])
def test_help_exits_zero(argv, capsys):
    with pytest.raises(SystemExit) as info:
        tc.main(argv)
    assert info.value.code == 0
    assert 'train classifier' in capsys.readouterr().out


def test_evaluation_cli_writes_table_iii_and_leave_one_clip_out(tmp_path, capsys):
    import json
    clips = ('clip0', 'clip1', 'clip2')
    root = _folder(tmp_path / 'data', n=9, clips=clips)
    out = tmp_path / 'eval.json'
    code = ev.main(['--synth', '0', '--data', str(root), '--classes', 'present', '--splits',
                    '1', '--variants', '--features', 'logpolar', '--real', str(root),
                    '--json', str(out), '--report', str(tmp_path / 'report')])
    capsys.readouterr()
    assert code == 0
    res = json.loads(out.read_text())
    cell = res['table_iii']['logpolar']['svm']
    assert set(res['table_iii']) == {'logpolar', 'raw'}
    assert set(res['table_iii']['raw']) == {'svm', 'lda', 'knn'}
    assert len(cell['precision']) == 2 and 0 <= cell['precision'][0] <= 1     # mean, std
    assert res['crops'] == 27 and res['splits'] == 1
    assert set(res['leave_one_clip_out']) == set(clips)
    assert res['leave_one_clip_out']['clip0']['background']['background_crops'] == 3
    assert (tmp_path / 'report' / 'table3_logpolar_confusion.png').is_file()


TINY_SCENARIO = """
description: four signs on a straight road
duration: 15.0
weather: spring_sunny
road: {curves: [[600, 0.0]], overpasses: []}
ego: {speed: 22.4, lane: middle}
signs:
  - {class: road_work_ahead, s: 130}
  - {class: warning_diamond, s: 175}
  - {class: guide, s: 220}
  - {class: work_zone_begin, s: 265}
distractors: {vehicles: 1, orange_vehicles: 1, yellow_vehicles: 0, cones: 1, drums: 1,
              general_signs: 0, mile_markers: false}
"""


def test_model_trained_on_renders_classifies_a_held_out_render(tmp_path):
    # the simulator renders a short scenario three times (render seeds 0, 1, 2: other noise,
    # sheeting orange and box jitter); a tiny model trained on two classifies the third
    from workzone_ros.sim.scenario import load_scenario
    path = tmp_path / 'tiny.yaml'
    path.write_text(TINY_SCENARIO)
    train, test = [tc.render_crops([(load_scenario(str(path), s), s) for s in seeds], 20, 48,
                                   tmp_path / 'cache', progress=None)
                   for seeds in ((0, 1), (2,))]
    keys = ('road_work_ahead', 'warning_diamond', 'guide', 'work_zone_begin', 'background')
    assert set(train.labels) == set(keys) == set(test.labels)
    model = cl.fit(train.crops, train.labels, keys, features=tc.DEFAULT_FEATURES, cv=2)
    readable = [i for i, (lab, side) in enumerate(zip(test.labels, test.side))
                if side >= 12 or lab == 'background']          # the node's min_size
    pred = [p.class_key for p in model.classify([test.crops[i] for i in readable])]
    truth = [test.labels[i] for i in readable]
    assert len(truth) >= 40
    assert np.mean(np.array(pred) == np.array(truth)) >= 0.85
