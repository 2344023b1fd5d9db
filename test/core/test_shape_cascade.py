"""The sign-shape cascade of Balali and Golparvar-Fard (workzone_ros.core.general.shapes): the
shipped model labels rendered sign art, rejects a drum, and its file is versioned and checked."""
from __future__ import annotations

import json
import shutil
import zipfile

import numpy as np
import pytest

from workzone_ros.core.general import shapes as sh
from workzone_ros.resources import config_path
from workzone_ros.sim import signart

MODEL = config_path(sh.DEFAULT_MODEL)


@pytest.fixture(scope='module')
def cascade() -> sh.ShapeCascade:
    return sh.ShapeCascade.load(MODEL)


def _crop(face_bgra: np.ndarray, side: int = 48, ground=(70, 110, 60)) -> np.ndarray:
    """The face centred on a green roadside background with a grey post, ``side`` px."""
    img = np.empty((side, side, 3), np.float32)
    img[:] = ground
    img[: side // 3] = (200, 190, 170)                        # sky
    h, w = face_bgra.shape[:2]
    y0, x0 = (side - h) // 2, (side - w) // 2
    img[y0 + h // 2:, side // 2 - 1:side // 2 + 2] = 110      # post
    img[y0:y0 + h, x0:x0 + w] = signart.over(face_bgra, img[y0:y0 + h, x0:x0 + w])
    return np.clip(img, 0, 255).astype(np.uint8)


def _sign(key: str, size: int = 38) -> np.ndarray:
    return _crop(signart.sign_face(key, size))


def _drum(side: int = 48) -> np.ndarray:
    """A channelizing drum (orange with white bands, rounded top) on the road."""
    import cv2
    img = np.full((side, side, 3), (95, 95, 100), np.uint8)
    tex = cv2.resize(signart.drum_texture(), (24, 36))
    x0, y0 = (side - 24) // 2, (side - 36) // 2
    img[y0:y0 + 36, x0:x0 + 24] = tex
    cv2.ellipse(img, (side // 2, y0), (12, 4), 0, 0, 360, signart.ORANGE, -1)
    return img


_DNE_XFAIL = pytest.mark.xfail(strict=True, reason='known limit (docs/shapes.md): the red '
                               'square with a white bar reads as an octagon')


@pytest.mark.parametrize('key,shape', [('stop', 'octagon'), ('yield', 'triangle'),
                                       ('road_work_ahead', 'diamond'),
                                       ('warning_diamond', 'diamond'),
                                       ('speed_limit', 'rectangle'),
                                       pytest.param('do_not_enter', 'rectangle',
                                                    marks=_DNE_XFAIL)])
def test_shipped_cascade_labels_rendered_signs(cascade, key, shape):
    label, score = cascade.classify(_sign(key))
    assert label == shape, (key, label, score)
    assert score > 0


def test_a_drum_is_not_a_diamond(cascade):
    label, _ = cascade.classify(_drum())
    assert label != 'diamond'


def test_scan_reports_a_scale_and_a_plain_patch_is_none(cascade):
    frame = np.full((120, 160, 3), (70, 110, 60), np.uint8)
    frame[30:78, 60:108] = _sign('stop')
    label, score, scale = cascade.scan(frame, (60, 30, 48, 48))
    assert label == 'octagon' and scale in sh.DEFAULT_SCALES
    assert cascade.classify(np.full((40, 40, 3), (70, 110, 60), np.uint8))[0] == 'none'


def test_model_records_its_training_data(cascade):
    md = cascade.metadata
    assert md['schema'] == sh.SCHEMA and md['version'] == sh.VERSION
    assert md['training_sources']['renders']['seeds']
    assert md['false_alarm_rate'] == 0.2 and md['stages'] == 5
    assert MODEL.stat().st_size < 1_000_000


def test_save_load_round_trip(cascade, tmp_path):
    path = tmp_path / 'c.npz'
    cascade.save(path)
    again = sh.ShapeCascade.load(path)
    crops = [_sign('stop'), _sign('yield'), _drum()]
    for c in crops:
        assert again.classify(c) == cascade.classify(c)


def _rewrite(src, dst, change):
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    np.savez_compressed(dst, **arrays)


def test_missing_file_is_a_one_line_error(tmp_path):
    with pytest.raises(FileNotFoundError, match='nope.npz'):
        sh.ShapeCascade.load(tmp_path / 'nope.npz')


def test_truncated_file_is_a_one_line_error(tmp_path):
    bad = tmp_path / 'cut.npz'
    bad.write_bytes(MODEL.read_bytes()[:2000])
    with pytest.raises(sh.ShapeModelError, match='truncated or corrupt') as err:
        sh.ShapeCascade.load(bad)
    assert '\n' not in str(err.value) and 'cut.npz' in str(err.value)


def test_tampered_file_fails_its_integrity_check(tmp_path):
    bad = tmp_path / 'tampered.npz'

    def flip(a):
        a['s_threshold'] = a['s_threshold'] + 1.0
    _rewrite(MODEL, bad, flip)
    with pytest.raises(sh.ShapeModelError, match='integrity') as err:
        sh.ShapeCascade.load(bad)
    assert '\n' not in str(err.value) and 'tampered.npz' in str(err.value)


def test_other_version_is_refused(tmp_path):
    bad = tmp_path / 'v9.npz'

    def bump(a):
        md = json.loads(str(a['metadata']))
        md['version'] = 9
        a['metadata'] = np.array(json.dumps(md))
    _rewrite(MODEL, bad, bump)
    with pytest.raises(sh.ShapeModelError, match='version 9') as err:
        sh.ShapeCascade.load(bad)
    assert '\n' not in str(err.value)


def test_not_a_zip_and_pickles_are_refused(tmp_path):
    junk = tmp_path / 'junk.npz'
    junk.write_text('not a model')
    with pytest.raises(sh.ShapeModelError):
        sh.ShapeCascade.load(junk)
    obj = tmp_path / 'obj.npz'
    with zipfile.ZipFile(obj, 'w') as zf:
        with np.load(MODEL, allow_pickle=False) as z:
            for k in z.files:
                with zf.open(f'{k}.npy', 'w') as fh:
                    np.lib.format.write_array(fh, z[k])
        with zf.open('evil.npy', 'w') as fh:
            np.lib.format.write_array(fh, np.array([{'a': 1}], dtype=object),
                                      allow_pickle=True)
    with pytest.raises(sh.ShapeModelError):
        sh.ShapeCascade.load(obj)


def test_train_cascade_on_a_toy_set(tmp_path):
    rng = np.random.default_rng(0)
    crops, labels = [], []
    for key, shape in (('stop', 'octagon'), ('yield', 'triangle'),
                       ('warning_diamond', 'diamond'), ('speed_limit', 'rectangle')):
        for size in (30, 34, 38, 42):
            crops.append(_sign(key, size))
            labels.append(shape)
    for _ in range(24):
        crops.append(rng.integers(0, 255, (48, 48, 3), dtype=np.uint8))
        labels.append('none')
    model = sh.train_cascade(crops, labels, n_candidates=300, n_features=40, stages=2,
                             max_stumps=5)
    model.save(tmp_path / 'toy.npz')
    back = sh.ShapeCascade.load(tmp_path / 'toy.npz')
    assert back.classify(crops[0])[0] in sh.SHAPES + (sh.NONE,)
    with pytest.raises(ValueError, match='no crops of shape'):
        sh.train_cascade(crops[:4], labels[:4])
    shutil.rmtree(tmp_path)
