"""Real-pixel colour training data and mined background crops (tools.real_pixels,
tools.mine_background, the ignore value of tools.train_color)."""
import csv
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from workzone_ros.tools import clips
from workzone_ros.tools import real_pixels as rp
from workzone_ros.tools import train_color as tc

REAL = Path(os.environ.get('WORKZONE_REALDATA')
            or Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata') \
    / 'us_workzone_video'


def _row(key, shape, x, y, w, h):
    return {'class_key': key, 'shape': shape, 'x': x, 'y': y, 'w': w, 'h': h}


def test_a_frame_mask_marks_sign_faces_and_ignores_orange_non_signs():
    rows = [_row('other_workzone', 'diamond', 10, 10, 20, 20),
            _row('background', '', 50, 10, 10, 20),          # a cone: ignored
            _row('stop', 'octagon', 70, 10, 20, 20)]          # red: background for orange
    m = rp.frame_mask((100, 40), rows, {'other_workzone'})
    assert m[20, 20] == rp.FACE and m[10, 10] == 0            # diamond centre / box corner
    assert m[20, 55] == rp.IGNORE
    assert m[20, 80] == 0
    with pytest.raises(ValueError, match='shape'):
        rp.face_polygon('circle', 0, 0, 5, 5)


def test_train_color_leaves_ignored_pixels_out(tmp_path):
    img = np.zeros((4, 4, 3), np.uint8)
    mask = np.array([[0, 128, 255, 7]] * 4, np.uint8)
    cv2.imwrite(str(tmp_path / 'i.png'), img)
    cv2.imwrite(str(tmp_path / 'm.png'), mask)
    _, face, ignored = tc._read(tmp_path / 'i.png', tmp_path / 'm.png')
    assert face[0].tolist() == [False, False, True, True]
    assert ignored[0].tolist() == [False, True, False, False]


def test_crops_are_grown_and_bounded():
    img = np.zeros((400, 700, 3), np.uint8)
    assert clips.crop_box(img, 100, 100, 40, 20).shape[:2] == (30, 60)
    assert max(clips.crop_box(img, 100, 100, 200, 100).shape[:2]) == clips.MAX_SIDE
    assert clips.crop_box(img, 680, 380, 40, 40).shape[:2] == (30, 30)     # clipped at the edge


def test_missing_index_is_a_one_line_error(tmp_path, capsys):
    assert rp.main(['-o', str(tmp_path / 'o'), '--index', str(tmp_path / 'no.csv')]) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'no.csv' in err


def test_an_orange_sign_without_its_shape_is_a_one_line_error(tmp_path, capsys):
    index = tmp_path / 'index.csv'
    index.write_text('path,class_key,clip,frame,x,y,w,h,source,shape\n'
                     'background/a_0000_0.png,background,a,0,1,2,3,4,hand,\n'
                     'other_workzone/a_0000_1.png,other_workzone,a,0,5,6,7,8,hand,\n')
    assert rp.main(['-o', str(tmp_path / 'o'), '--index', str(index)]) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'index.csv line 3: an orange other_workzone needs its shape' in err


@pytest.mark.skipif(not (REAL / 'charlotte.mp4').exists(), reason=f'no clips in {REAL}')
def test_real_pixels_of_one_clip(tmp_path):
    index = tmp_path / 'index.csv'
    with open(index, 'w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(['path', 'class_key', 'clip', 'frame', 'x', 'y', 'w', 'h', 'source', 'shape'])
        w.writerow(['a.png', 'other_workzone', 'charlotte', 30, 470, 200, 50, 50, 'hand',
                    'diamond'])
    assert rp.main(['-o', str(tmp_path / 'o'), '--index', str(index),
                    '--videos', str(REAL)]) == 0
    m = cv2.imread(str(tmp_path / 'o' / 'masks' / 'charlotte_0030.png'), 0)
    assert m.shape == (406, 722) and (m == rp.FACE).sum() > 1000
