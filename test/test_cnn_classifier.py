"""core.cnn_classifier: the shipped CNN sign classifier run by cv2.dnn, without PyTorch.

The model is ``config/models/sign_classifier_cnn.npz`` (``workzone-ros train cnn``; see
docs/classifier.md for what trained it).  Nothing here imports torch or onnx.
"""
import json
import sys

import cv2
import numpy as np
import pytest

from workzone_ros.core import classifier as cl
from workzone_ros.core import cnn_classifier as cnn
from workzone_ros.core.features import crop_sign
from workzone_ros.core.model_files import digest
from workzone_ros.resources import config_path
from workzone_ros.sim import signart

CNN_PATH = config_path(cnn.DEFAULT_MODEL)


@pytest.fixture(scope='module')
def model():
    return cl.load_model(CNN_PATH)


def _scene(rng, side=96):
    """A roadside-like backdrop: grass, asphalt or sky with noise."""
    img = np.empty((side, side, 3), np.float32)
    img[:] = rng.choice([(70, 110, 60), (110, 110, 112), (200, 170, 140)])
    img[side * 2 // 3:] = (95, 95, 98)
    return img + rng.normal(0, 5, img.shape)


def sign_crop(key, rng, side=64, fill=0.8):
    """The simulator's sign art on a backdrop, framed as classify_boxes frames a box."""
    img = _scene(rng, side)
    face = signart.sign_face(key, int(side * fill))
    h, w = face.shape[:2]
    y0, x0 = (side - h) // 2, (side - w) // 2
    a = face[..., 3:4].astype(np.float32) / 255.0
    img[y0:y0 + h, x0:x0 + w] = img[y0:y0 + h, x0:x0 + w] * (1 - a) + face[..., :3] * a
    return np.clip(img, 0, 255).astype(np.uint8)


def drum_crop(rng, side=64):
    """A channelizing drum (orange / white bands) on a backdrop: a hard negative."""
    img = _scene(rng, side)
    drum = signart.drum_texture(side // 2, side * 3 // 4).astype(np.float32)
    img[side // 8:side // 8 + drum.shape[0], side // 4:side // 4 + drum.shape[1]] = drum
    return np.clip(img, 0, 255).astype(np.uint8)


def test_torch_is_not_needed_to_run_the_model(model):
    assert isinstance(model, cnn.CnnSignClassifier)
    assert 'torch' not in sys.modules and 'onnx' not in sys.modules
    assert 'background' in model.classes and len(model.classes) >= 10
    md = model.metadata
    assert md['schema'] == cnn.SCHEMA and md['version'] == cnn.VERSION
    assert md['training_sources'] and md['input_size'] == model.input_size
    assert CNN_PATH.stat().st_size < 1_000_000


@pytest.mark.parametrize('key', ['stop', 'work_zone_begin', 'end_road_work',
                                 'lane_shift_left', 'lane_shift_right'])
def test_classifies_a_rendered_sign(model, key):
    rng = np.random.default_rng(1)
    preds = model.classify([sign_crop(key, rng) for _ in range(4)])
    assert sum(p.class_key == key for p in preds) >= 3, [p.class_key for p in preds]


def test_blank_and_drum_crops_are_background(model):
    rng = np.random.default_rng(2)
    crops = [np.full((40, 40, 3), v, np.uint8) for v in (40, 128, 220)]
    crops += [np.clip(_scene(rng, 48), 0, 255).astype(np.uint8) for _ in range(3)]
    preds = model.classify(crops)
    assert [p.class_key for p in preds] == ['background'] * len(crops)
    # drums: the hard negative (orange and white like a W20-3 / work-zone-begin panel);
    # the model calls 2-3 % of the renders' background crops a sign, so one miss is allowed
    drums = model.classify([drum_crop(rng) for _ in range(4)])
    assert sum(p.class_key == 'background' for p in drums) >= 3


def test_probabilities_and_batched_equals_one_at_a_time(model):
    rng = np.random.default_rng(3)
    crops = [sign_crop(k, rng, side=int(rng.integers(20, 150)))
             for k in ('stop', 'road_work_ahead', 'warning_diamond', 'guide')]
    crops += [drum_crop(rng, 30), np.full((9, 31, 3), 90, np.uint8),
              cv2.cvtColor(crops[0], cv2.COLOR_BGR2GRAY)]
    batch = model.predict_proba(crops)
    single = np.vstack([model.predict_proba([c]) for c in crops])
    assert batch.shape == (len(crops), len(model.classes))
    assert np.allclose(batch.sum(1), 1.0)
    assert np.allclose(batch, single, atol=1e-5)
    preds = model.classify(crops)
    assert preds[0].score == pytest.approx(max(preds[0].probabilities.values()))
    assert list(preds[0].probabilities) == list(model.classes)
    assert model.predict_proba([]).shape == (0, len(model.classes))
    assert model.classify([]) == []


def test_classify_boxes_crops_like_the_svm_in_one_pass(model, monkeypatch):
    rng = np.random.default_rng(4)
    frame = np.clip(_scene(rng, 480), 0, 255).astype(np.uint8)
    frame = cv2.resize(frame, (640, 480))
    frame[100:160, 300:360] = sign_crop('stop', rng, side=60, fill=0.9)
    boxes = [(303, 103, 54, 54), (-30, 200, 50, 50), (700, 10, 20, 20), (600, 440, 80, 80)]
    calls = []
    forward = model._forward
    monkeypatch.setattr(model, '_forward', lambda blob: calls.append(len(blob)) or
                        forward(blob))
    preds = model.classify_boxes(frame, boxes)
    assert calls == [3]                            # one forward pass, the three visible boxes
    assert preds[2] is None and preds[0].class_key == 'stop'
    crops = [crop_sign(frame, b, model.margin, square=True)[0] for b in boxes]
    for p, c in zip(preds, crops):
        if c is not None:
            assert p.probabilities == model.classify([c])[0].probabilities


def test_load_model_dispatches_on_the_file(model, tmp_path):
    # a CNN file gives the CNN, an SVM file the SVM, through the one load_model
    rng = np.random.default_rng(6)
    keys = ('stop', 'background')
    crops = [sign_crop('stop', rng) for _ in range(6)] + [drum_crop(rng) for _ in range(6)]
    svm = cl.fit(crops, ['stop'] * 6 + ['background'] * 6, keys, cv=2)
    cl.save_model(svm, tmp_path / 'svm.npz')
    assert type(cl.load_model(tmp_path / 'svm.npz')) is cl.SignClassifier
    assert type(cl.load_model(CNN_PATH)) is cnn.CnnSignClassifier
    assert type(cnn.load_model(CNN_PATH)) is cnn.CnnSignClassifier
    with pytest.raises(cl.ModelError, match='not a CNN') as info:
        cnn.load_model(tmp_path / 'svm.npz')
    assert '\n' not in str(info.value)
    # the shipped default is one of the two kinds and loads
    default = cl.load_model(config_path(cl.DEFAULT_MODEL))
    assert isinstance(default, (cl.SignClassifier, cnn.CnnSignClassifier))


def test_model_file_round_trip(model, tmp_path):
    path = tmp_path / 'cnn.npz'
    cnn.save_model(model, path)
    back = cl.load_model(path)
    rng = np.random.default_rng(5)
    crops = [sign_crop('road_work_ahead', rng), drum_crop(rng)]
    assert back.classes == model.classes and back.input_size == model.input_size
    assert np.array_equal(back.predict_proba(crops), model.predict_proba(crops))
    assert back.metadata['training_sources'] == model.metadata['training_sources']
    with np.load(path, allow_pickle=False) as z:              # arrays only, no pickles
        assert all(z[k].dtype != object for k in z.files)
        assert z['onnx'].dtype == np.uint8


def _one_line_error(path, match):
    with pytest.raises(cl.ModelError, match=match) as info:
        cl.load_model(path)
    assert '\n' not in str(info.value) and str(path) in str(info.value)


def test_bad_files_are_refused_with_one_line(model, tmp_path):
    good = tmp_path / 'good.npz'
    cnn.save_model(model, good)
    _one_line_error(tmp_path / 'missing.npz', 'does not exist')
    truncated = tmp_path / 'truncated.npz'
    truncated.write_bytes(good.read_bytes()[:5000])
    _one_line_error(truncated, 'truncated or corrupt')
    with np.load(good, allow_pickle=False) as z:
        files = {k: z[k] for k in z.files}
    arrays = {k: v for k, v in files.items() if k != 'metadata'}
    md = json.loads(str(files['metadata']))
    # tampered: one weight byte of the network changed, metadata untouched
    onnx = arrays['onnx'].copy()
    onnx[len(onnx) // 2] ^= 0x55
    np.savez_compressed(tmp_path / 'tampered.npz', **{**files, 'onnx': onnx})
    _one_line_error(tmp_path / 'tampered.npz', 'integrity')
    # tampered metadata: the input size changed
    md2 = {**md, 'input_size': md['input_size'] + 8}
    np.savez_compressed(tmp_path / 'md.npz', **{**files, 'metadata': np.array(json.dumps(md2))})
    _one_line_error(tmp_path / 'md.npz', 'integrity')
    # another version (hash recomputed, so only the version is wrong)
    md3 = {**md, 'version': cnn.VERSION + 1}
    md3['sha256'] = digest(arrays, md3)
    np.savez_compressed(tmp_path / 'v2.npz', metadata=np.array(json.dumps(md3)), **arrays)
    _one_line_error(tmp_path / 'v2.npz', 'version')
    # a consistent hash over bytes that are not a network
    junk = {**arrays, 'onnx': np.frombuffer(b'not an onnx graph' * 20, np.uint8)}
    md4 = dict(md)
    md4['sha256'] = digest(junk, md4)
    np.savez_compressed(tmp_path / 'junk.npz', metadata=np.array(json.dumps(md4)), **junk)
    _one_line_error(tmp_path / 'junk.npz', 'malformed')
    # a network whose output does not match the class list
    fewer = {**arrays, 'classes': arrays['classes'][:-1]}
    md5 = {**md, 'classes': list(arrays['classes'][:-1])}
    md5['sha256'] = digest(fewer, md5)
    np.savez_compressed(tmp_path / 'fewer.npz', metadata=np.array(json.dumps(md5)), **fewer)
    _one_line_error(tmp_path / 'fewer.npz', 'malformed')


def test_trainer_without_torch_is_a_one_line_error(monkeypatch, capsys):
    from workzone_ros.tools import train
    with pytest.raises(SystemExit) as info:
        train.main(['cnn', '--help'])
    assert info.value.code == 0 and '--exclude-clip' in capsys.readouterr().out
    monkeypatch.setitem(sys.modules, 'torch', None)         # as on a machine without it
    assert train.main(['cnn', '--synth', '0', '--data', 'nowhere']) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'pip install' in err and '[cnn]' in err
