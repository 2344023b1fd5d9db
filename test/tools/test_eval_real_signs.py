"""``evaluate real_signs``: the per-frame real-clip figures (clips optional), clear errors."""
import os
from pathlib import Path

import numpy as np
import pytest

from workzone_ros.tools import eval_real_signs as ers

REAL = Path(os.environ.get('WORKZONE_REALDATA')
            or Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata') \
    / 'us_workzone_video'


def test_the_sign_ranges_cover_the_labelled_work_zone_signs():
    ranges = ers.sign_ranges()
    assert ranges['charlotte.mp4'][0] == (0, 102)
    assert 'chicago.mp4' not in ranges          # no work-zone sign in view


def test_missing_folder_and_model_are_one_line_errors(tmp_path, capsys):
    assert ers.main(['--real', str(tmp_path / 'nope')]) == 2
    assert 'no such folder' in capsys.readouterr().err
    assert ers.main(['--real', str(tmp_path), '--model', str(tmp_path / 'm.npz')]) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'm.npz' in err


@pytest.mark.skipif(not (REAL / 'charlotte.mp4').exists(), reason=f'no clips in {REAL}')
def test_a_few_frames_of_a_real_clip_give_the_figures():
    from workzone_ros.core.classifier import DEFAULT_MODEL, load_model
    from workzone_ros.resources import config_path
    r = ers.evaluate_clip(REAL / 'charlotte.mp4', load_model(config_path(DEFAULT_MODEL)), 60.0,
                          max_frames=6)
    assert r['frames'] == 6 and r['sign_frames'] == 6 and 0.0 <= r['sign_share'] <= 1.0
    assert r['boxes']['proposal'] == 0 and r['sign_boxes']['rule'] <= r['boxes']['rule']


def test_the_measured_prior_is_the_log_odds_ratio_of_the_two_box_sources():
    """Rule boxes 1 sign in 3 (odds 1/2), proposals 1 in 21 (odds 1/20): ln 10; a source
    without signs (or all signs) has no finite prior."""
    clips = {'a': {'boxes': {'rule': 2, 'proposal': 11}, 'sign_boxes': {'rule': 1, 'proposal': 0}},
             'b': {'boxes': {'rule': 1, 'proposal': 10}, 'sign_boxes': {'rule': 0, 'proposal': 1}}}
    assert ers.proposal_prior(clips) == round(float(np.log(10.0)), 2)
    clips['b']['sign_boxes']['proposal'] = 0
    assert ers.proposal_prior(clips) is None


def test_signs_of_one_clip_are_interpolated_each_between_its_own_keyframes(tmp_path):
    """Two signs of a clip (column ``sign``): each box comes from its own keyframes, never
    from the other sign's, and a frame where both are labelled lists both;
    ``load_real_labels`` refuses such a file with the frame named."""
    from workzone_ros.tools.eval_color import load_real_labels, load_sign_labels
    csv = tmp_path / 'boxes.csv'
    csv.write_text('# two signs\nclip,sign,frame,x,y,w,h,visible\n'
                   'a.mp4,1,0,10,10,20,20,1\na.mp4,1,10,20,10,20,20,1\n'
                   'a.mp4,2,8,100,50,30,30,1\na.mp4,2,12,104,50,30,30,0\n')
    frames = load_sign_labels(csv)['a.mp4']
    assert sorted(frames) == list(range(13))
    assert [b.x for b, _ in frames[5]] == [15.0]
    assert [(b.x, v) for b, v in frames[9]] == [(19.0, True), (101.0, False)]
    assert [(b.x, v) for b, v in frames[8]] == [(18.0, True), (100.0, True)]
    assert [v for _, v in frames[12]] == [False]
    with pytest.raises(ValueError, match='frame 8'):
        load_real_labels(csv)


def test_unreadable_labels_are_a_one_line_error(tmp_path, capsys):
    bad = tmp_path / 'bad.csv'
    bad.write_text('clip,frame\na.mp4,1\n')
    for path in (tmp_path / 'none.csv', bad):
        assert ers.main(['--labels', str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert '\n' not in err and path.name in err


def test_a_make_crops_labels_file_measures_its_signs_not_its_background(tmp_path):
    from workzone_ros.tools.eval_color import load_sign_labels
    csv = tmp_path / 'my_labels.csv'
    csv.write_text('clip,frame,x,y,w,h,visible,sign,class_key,shape\n'
                   'mine,0,10,10,20,20,1,1,road_work_ahead,diamond\n'
                   'mine,4,14,10,20,20,1,1,road_work_ahead,diamond\n'
                   'mine,0,200,50,60,30,1,2,background,\n'
                   'mine,4,200,50,60,30,1,2,background,\n')
    frames = load_sign_labels(csv)['mine']
    assert sorted(frames) == [0, 1, 2, 3, 4]
    assert all(len(boxes) == 1 and boxes[0][0].x < 20 for boxes in frames.values())


def test_missing_ranges_are_a_one_line_error(tmp_path, capsys):
    assert ers.main(['--ranges', str(tmp_path / 'none.csv')]) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'none.csv' in err


def test_a_clip_is_found_by_its_name_with_any_video_extension(tmp_path):
    from workzone_ros.tools.clips import find_video, list_videos
    for name in ('a.mp4', 'b.AVI', 'c.txt', 'd.mkv'):
        (tmp_path / name).write_bytes(b'')
    assert [p.name for p in list_videos(tmp_path)] == ['a.mp4', 'b.AVI', 'd.mkv']
    assert find_video(tmp_path, 'b').name == 'b.AVI'
    assert find_video(tmp_path, 'a.mp4').name == 'a.mp4'
    with pytest.raises(FileNotFoundError, match='no video c'):
        find_video(tmp_path, 'c')
