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


@pytest.mark.parametrize('box,on', [
    ((10, 10, 40, 40), True),          # the sign itself
    ((20, 20, 8, 6), True),            # a piece of its legend (IoU far under 0.05)
    ((0, 0, 200, 200), True),          # a flagger's box holding the small sign
    ((40, 40, 30, 30), True),          # a tenth of the candidate on the sign
    ((47, 47, 30, 30), False),         # a corner touching it, under a tenth
    ((100, 100, 20, 20), False),
])
def test_a_candidate_on_a_sign_or_a_piece_of_it_is_never_background(box, on):
    assert mb._on_sign(box, (10, 10, 40, 40)) is on


def test_labelled_boxes_keep_candidates_out_before_and_after_their_labels(tmp_path):
    """``--labels``: a keyframe file's boxes, interpolated, keep candidates out of every
    frame they cover and ``HOLD`` frames either side (a sign leaving the frame is often
    unlabelled there), and nowhere else."""
    path = tmp_path / 'labels.csv'
    path.write_text('clip,frame,x,y,w,h,visible\nc.mp4,20,5,5,30,30,1\nc.mp4,30,25,5,30,30,1\n')
    signs = mb._sign_boxes(mb.INDEX)
    mb._add_labelled_boxes(signs, [path])
    assert (15.0, 5.0, 30.0, 30.0) in signs['c'][25]                  # interpolated
    assert signs['c'][30 + mb.HOLD] == [(25.0, 5.0, 30.0, 30.0)]
    assert signs['c'][20 - mb.HOLD] == [(5.0, 5.0, 30.0, 30.0)]
    assert not signs['c'][31 + mb.HOLD] and not signs['c'][19 - mb.HOLD]
    # the clip's proposal (5, 5, 30, 30) on frames 0, 3, 6, 9: 9 is held out (20 - HOLD = 8)
    assert _mine(tmp_path, None, signs=signs['c']) == [(0, 'proposal'), (3, 'proposal'),
                                                      (6, 'proposal')]


def test_the_shipped_label_files_keep_every_labelled_sign_out():
    """Every frame of houston's STOP sign as it leaves the frame edge (labelled in
    real_general_sign_boxes.csv where the crop index stops) is kept out."""
    signs = mb._sign_boxes(mb.INDEX)
    mb._add_labelled_boxes(signs, [mb.RANGES.parent / 'real_general_sign_boxes.csv'])
    assert all(signs['houston'][k] for k in range(180, 208))
