"""``workzone-ros mine-background``: which boxes of a clip become background crops."""
import csv
import io
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from workzone_ros.tools import mine_background as mb


def _clip(path, frames: int = 12):
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*'MJPG'), 10, (96, 48))
    for _ in range(frames):
        out.write(np.full((48, 96, 3), 120, np.uint8))
    out.release()
    return path


class _Proposer:
    def propose(self, img):
        return [SimpleNamespace(box=(5, 5, 30, 30))]


class _General:
    def candidate_boxes(self, img):
        return [((40, 10, 20, 20), 'red'), ((70, 10, 8, 8), 'red'), ((70, 20, 20, 20), 'white')]


def _mine(tmp_path, general, ranges=(), red_ranges=(), signs=None):
    (tmp_path / 'background').mkdir()
    buf = io.StringIO()
    n = mb.mine_clip(_clip(tmp_path / 'c.avi'), _Proposer(), signs or {}, list(ranges), 3,
                     16, tmp_path, csv.writer(buf), general, tuple(red_ranges))
    rows = list(csv.reader(io.StringIO(buf.getvalue())))
    assert n == len(rows)
    return [(int(r[3]), r[8]) for r in rows]


def test_red_candidates_are_mined_outside_red_sign_frames_and_off_labelled_signs(tmp_path):
    """The general detector's red candidates of 16 px and more become background, except in
    the frames where a red sign is in view and where they touch a labelled sign box; white
    candidates and small ones never do.  The proposals keep their own frame ranges."""
    rows = _mine(tmp_path, _General(), ranges=[(0, 5)], red_ranges=[(0, 5)],
                 signs={9: [(42, 12, 16, 16)]})
    assert rows == [(6, 'proposal'), (6, 'general_red'), (9, 'proposal')]
    crops = sorted(p.name for p in (tmp_path / 'background').iterdir())
    assert crops == ['c_0006_general_red_0.png', 'c_0006_proposal_0.png',
                     'c_0009_proposal_0.png']


def test_without_the_general_detector_only_proposals_are_mined(tmp_path):
    rows = _mine(tmp_path, None, ranges=[(3, 3)])
    assert rows == [(0, 'proposal'), (6, 'proposal'), (9, 'proposal')]


def test_red_ranges_are_read_by_content(tmp_path):
    path = tmp_path / 'r.csv'
    path.write_text('# note\nclip,first_frame,last_frame,content\n'
                    'a.mp4,0,9,red_sign\na.mp4,20,30,workzone_sign\n')
    assert mb._sign_ranges(path, 'red_sign') == {'a': [(0, 9)]}
    assert mb._sign_ranges(mb.RED_RANGES, 'red_sign')['houston'] == [(0, 208)]


def test_a_ranges_file_without_its_columns_is_a_clear_error(tmp_path):
    path = tmp_path / 'r.csv'
    path.write_text('a,b\n1,2\n')
    with pytest.raises(ValueError, match='needs the columns'):
        mb._sign_ranges(path, 'red_sign')
