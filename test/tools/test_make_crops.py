"""Training crops from keyframe-labelled videos (tools.make_crops, tools.clips)."""
import csv
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from workzone_ros.tools import clips
from workzone_ros.tools import make_crops as mc
from workzone_ros.tools.train_classifier import load_folder

REAL = Path(os.environ.get('WORKZONE_REALDATA')
            or Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata') \
    / 'us_workzone_video'
HEADER = 'clip,frame,x,y,w,h,visible,sign,class_key,shape\n'


def _video(path: Path, frames: int = 24, size=(160, 120)) -> list:
    """An MJPG video of an orange square that moves right 2 px and grows 1 px a frame."""
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*'MJPG'), 10, size)
    boxes = []
    for k in range(frames):
        img = np.full((size[1], size[0], 3), 90, np.uint8)
        x, y, s = 20 + 2 * k, 30, 16 + k
        img[y:y + s, x:x + s] = (0, 120, 250)
        out.write(img)
        boxes.append((x, y, s, s))
    out.release()
    return boxes


def _labels(tmp_path, text: str) -> Path:
    path = tmp_path / 'labels.csv'
    path.write_text('# hand-labelled keyframes\n' + HEADER + text)
    return path


def test_keyframes_interpolated_every_third_frame_with_visibility_and_min_side(tmp_path):
    labels = _labels(tmp_path, 'a,0,20,30,10,10,1,1,road_work_ahead,diamond\n'
                               'a,12,44,30,22,22,1,1,road_work_ahead,diamond\n'
                               'a,18,56,30,28,28,0,1,road_work_ahead,diamond\n'
                               'a,6,100,10,30,20,1,2,background,\n'
                               'a,9,100,10,30,20,1,2,background,\n')
    rows = mc.index_rows(mc.read_keyframes(labels), every=3, min_side=12)
    frames = [(r['frame'], r['class_key']) for r in rows]
    # frame 0 is under 12 px (10, growing 1 px a frame); 12 is a visible keyframe, 15 lies
    # between it and a hidden one
    assert frames == [(3, 'road_work_ahead'), (6, 'background'), (6, 'road_work_ahead'),
                      (9, 'background'), (9, 'road_work_ahead'), (12, 'road_work_ahead')]
    six = [r for r in rows if r['frame'] == 6]
    assert [(r['class_key'], r['x'], r['w']) for r in six] == [
        ('background', '100.0', '30.0'), ('road_work_ahead', '32.0', '16.0')]
    assert sorted(r['path'] for r in six) == ['background/a_0006_1.png',
                                              'road_work_ahead/a_0006_0.png']
    assert all(r['source'] == 'hand' for r in rows)


@pytest.mark.parametrize('text, says', [
    ('a,0,1,2,3\n', 'line 3: frame, x, y, w, h, visible and sign must be numbers'),
    ('a,0,1,2,3,4,1,1\n', "line 3: unknown class_key ''"),
    ('a,0,1,2,3,4,1,1,road_work_ahed,diamond\n', "unknown class_key 'road_work_ahed'"),
    ('a,0,1,2,3,4,1,1,road_work_ahead,circle\n', "shape 'circle' is not one of"),
    ('a,0,1,2,0,4,1,1,road_work_ahead,\n', 'a box without area'),
    ('a,0,1,2,3,4,1,1,road_work_ahead,\na,3,1,2,3,4,1,1,background,\n',
     "sign 1 of a was 'road_work_ahead' on an earlier row, here 'background'"),
])
def test_bad_labels_are_one_line_errors_naming_the_row(tmp_path, capsys, text, says):
    labels = _labels(tmp_path, text)
    code = mc.main(['--labels', str(labels), '--videos', str(tmp_path), '-o',
                    str(tmp_path / 'out')])
    err = capsys.readouterr().err.strip()
    assert code == 2 and '\n' not in err and says in err and 'labels.csv' in err


def test_a_labels_file_without_the_needed_columns(tmp_path, capsys):
    (tmp_path / 'l.csv').write_text('clip,frame,x,y,w,h\na,0,1,2,3,4\n')
    assert mc.main(['--labels', str(tmp_path / 'l.csv'), '--videos', str(tmp_path), '-o',
                    str(tmp_path / 'o')]) == 2
    assert 'no column visible, class_key' in capsys.readouterr().err


def test_crops_of_a_video_train_and_check_again(tmp_path, capsys):
    boxes = _video(tmp_path / 'clip1.avi')
    labels = _labels(tmp_path, ''.join(
        f'clip1,{k},{x},{y},{w},{h},1,1,road_work_ahead,diamond\n'
        for k, (x, y, w, h) in enumerate(boxes) if k in (0, 21)))
    out = tmp_path / 'crops'
    assert mc.main(['--labels', str(labels), '--videos', str(tmp_path), '-o', str(out)]) == 0
    with open(out / 'index.csv') as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r['frame']) for r in rows] == [0, 3, 6, 9, 12, 15, 18, 21]
    crop = cv2.imread(str(out / rows[2]['path']))
    # the box (22 px on frame 6) grown by a quarter per side: the orange square in the middle
    assert abs(crop.shape[0] - 33) <= 1 and crop.shape[0] == crop.shape[1]
    assert crop[16, 16, 2] > 200 and crop[2, 2, 2] < 150
    data = load_folder(out)                    # what train cnn / train classifier read
    assert len(data.crops) == 8 and set(data.labels) == {'road_work_ahead'}
    capsys.readouterr()
    assert mc.main(['--index', str(out / 'index.csv'), '--videos', str(tmp_path), '-o',
                    str(out), '--check']) == 0
    assert '8 crops checked, 0 differ' in capsys.readouterr().out
    cv2.imwrite(str(out / rows[0]['path']), np.zeros((5, 5, 3), np.uint8))
    assert mc.main(['--index', str(out / 'index.csv'), '--videos', str(tmp_path), '-o',
                    str(out), '--check']) == 1
    assert f'differs: {rows[0]["path"]}' in capsys.readouterr().out


def test_a_frame_past_the_end_of_the_video_or_a_missing_video(tmp_path, capsys):
    _video(tmp_path / 'clip1.avi', frames=10)
    labels = _labels(tmp_path, 'clip1,0,20,30,16,16,1,1,road_work_ahead,\n'
                               'clip1,30,20,30,16,16,1,1,road_work_ahead,\n')
    assert mc.main(['--labels', str(labels), '--videos', str(tmp_path), '-o',
                    str(tmp_path / 'o')]) == 2
    assert 'clip1: the video ends before frame 30' in capsys.readouterr().err
    assert mc.main(['--labels', str(labels), '--videos', str(tmp_path / 'none'), '-o',
                    str(tmp_path / 'o')]) == 2
    assert 'no video clip1 (.mp4/' in capsys.readouterr().err


def test_frames_of_gives_the_wanted_frames_in_order(tmp_path):
    _video(tmp_path / 'v.avi', frames=12)
    assert [k for k, _ in clips.frames_of(tmp_path / 'v.avi')] == list(range(12))
    assert [k for k, _ in clips.frames_of(tmp_path / 'v.avi', {2, 5, 30})] == [2, 5]
    assert [k for k, _ in clips.frames_of(tmp_path / 'v.avi', None, last=3)] == [0, 1, 2, 3]
    with pytest.raises(ValueError, match='cannot read'):
        next(clips.frames_of(tmp_path / 'missing.avi'))


@pytest.mark.skipif(not (REAL / 'charlotte.mp4').exists(), reason=f'no clips in {REAL}')
def test_the_stored_real_crops_are_what_the_tool_cuts(tmp_path, capsys):
    index = Path(__file__).resolve().parents[1] / 'data' / 'real_crops' / 'index.csv'
    with open(index) as fh:
        rows = [r for r in csv.DictReader(fh) if r['clip'] == 'charlotte']
    small = tmp_path / 'index.csv'
    with open(small, 'w', newline='') as fh:
        w = csv.DictWriter(fh, list(rows[0]), lineterminator='\n')
        w.writeheader()
        w.writerows(rows)
    assert mc.main(['--index', str(small), '--videos', str(REAL), '-o',
                    str(index.parent), '--check']) == 0
    assert f'{len(rows)} crops checked, 0 differ' in capsys.readouterr().out
