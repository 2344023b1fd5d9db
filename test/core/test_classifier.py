"""core.classifier: training on sign-art crops, the predictor rebuilt from arrays, model files."""
import json
import warnings
import zipfile

import numpy as np
import pytest

from workzone_ros.core import classifier as cl
from workzone_ros.core import features as ft
from workzone_ros.core.model_files import digest
from workzone_ros.sim import signart

#: Visually distinct classes (orange diamond, orange/white rectangle, red octagon, green
#: guide sign, yellow diamond) and the reject class.
KEYS = ('road_work_ahead', 'work_zone_begin', 'stop', 'guide', 'warning_diamond',
        'background')


def _background(rng, side):
    """Grass / asphalt / sky texture, or a channelizing drum (a hard negative)."""
    img = np.empty((side, side, 3), np.float32)
    img[:] = rng.choice([(70, 110, 60), (110, 110, 112), (200, 170, 140)])
    if rng.random() < 0.4:
        drum = signart.drum_texture(side // 2, side).astype(np.float32)
        x = int(rng.integers(0, side // 2))
        img[:, x:x + side // 2] = drum
    return img + rng.normal(0, 8, img.shape)


def art_crop(key, rng, side=48):
    """A detector-like crop of the simulator's sign art: scale, shift, exposure, noise."""
    img = _background(rng, side)
    if key != 'background':
        face = signart.sign_face(key, int(side * rng.uniform(0.65, 0.9)))
        h, w = face.shape[:2]
        y0 = (side - h) // 2 + int(rng.integers(-3, 4))
        x0 = (side - w) // 2 + int(rng.integers(-3, 4))
        y0, x0 = min(max(y0, 0), side - h), min(max(x0, 0), side - w)
        a = face[..., 3:4].astype(np.float32) / 255.0
        img[y0:y0 + h, x0:x0 + w] = img[y0:y0 + h, x0:x0 + w] * (1 - a) + face[..., :3]
    img *= rng.uniform(0.6, 1.2)
    return np.clip(img, 0, 255).astype(np.uint8)


def dataset(n_per_class, seed, keys=KEYS):
    rng = np.random.default_rng(seed)
    crops, labels = [], []
    for key in keys:
        for _ in range(n_per_class):
            crops.append(art_crop(key, rng))
            labels.append(key)
    return crops, labels


@pytest.fixture(scope='module')
def model():
    crops, labels = dataset(14, seed=0)
    return cl.fit(crops, labels, KEYS, features='logpolar-centred+color', cv=2,
                  metadata={'training_sources': 'test sign art'})


def test_tiny_model_classifies_held_out_crops(model):
    crops, labels = dataset(6, seed=1)
    preds = model.classify(crops)
    acc = np.mean([p.class_key == t for p, t in zip(preds, labels)])
    assert acc >= 0.9
    p = preds[0]
    assert set(p.probabilities) == set(KEYS)
    assert sum(p.probabilities.values()) == pytest.approx(1.0)
    assert p.score == pytest.approx(max(p.probabilities.values()))
    md = model.metadata
    assert md['n_components'] == 10 and 0.5 < md['pca_variance_held'] <= 1.0
    assert md['schema'] == cl.SCHEMA and md['training_sources'] == 'test sign art'


def test_seed_pipeline_and_baselines_train(model):
    crops, labels = dataset(8, seed=2, keys=KEYS[:3])
    test_crops, test_labels = dataset(4, seed=3, keys=KEYS[:3])
    for method in cl.METHODS:
        m = cl.fit(crops, labels, KEYS[:3], features='logpolar', method=method, cv=2)
        acc = np.mean([p.class_key == t for p, t in zip(m.classify(test_crops), test_labels)])
        assert acc >= 0.75, method


def test_probabilities_match_libsvm():
    # Our predictor from arrays == scikit-learn's SVC(probability=True) given its sigmoids
    from sklearn.svm import SVC
    rng = np.random.default_rng(0)
    k = 4
    X = np.vstack([rng.normal(0, 1, (30, 5)) + [i, 0.5 * i, 0, 0, 0] for i in range(k)])
    y = np.repeat(np.arange(k), 30)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        try:
            svc = SVC(C=3.0, gamma=0.2, probability=True, random_state=0).fit(X, y)
        except TypeError:
            pytest.skip('this scikit-learn has no SVC(probability=True)')
        expected = svc.predict_proba(X)
    arrays = {'pca_mean': np.zeros(5, np.float32), 'pca_components': np.eye(5, dtype=np.float32),
              'extra_mean': np.zeros(0), 'extra_scale': np.zeros(0),
              'support_vectors': svc.support_vectors_, 'dual_coef': svc._dual_coef_,
              'n_support': svc._n_support, 'intercept': svc._intercept_,
              'prob_a': svc._probA, 'prob_b': svc._probB, 'gamma': np.array(0.2)}
    clf = cl.SignClassifier([f'c{i}' for i in range(k)], arrays,
                            {'method': 'svm', 'features': 'logpolar'})
    got = clf.predict_proba_reduced(clf.reduce(X.astype(np.float32), None))
    # libsvm stops its coupling iteration at 0.005 / k; we solve it exactly
    assert np.abs(got - expected).max() < 0.01


def test_lda_and_knn_heads_match_scikit_learn():
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
    from sklearn.neighbors import KNeighborsClassifier
    rng = np.random.default_rng(1)
    X = np.vstack([rng.normal(0, 1, (25, 12)) + i for i in range(3)]).astype(np.float32)
    labels = [f'c{i}' for i in np.repeat(np.arange(3), 25)]
    y = np.repeat(np.arange(3), 25)
    for method, ref in (('lda', LinearDiscriminantAnalysis()),
                        ('knn', KNeighborsClassifier(10))):
        clf = cl.fit_arrays(X, None, labels, ['c0', 'c1', 'c2'], method=method,
                            n_components=4, features='logpolar')
        z = clf.reduce(X, None)
        assert np.allclose(clf.predict_proba_reduced(z), ref.fit(z, y).predict_proba(z),
                           atol=1e-6)


def test_classify_boxes_crops_and_skips_boxes_outside(model):
    rng = np.random.default_rng(5)
    frame = np.full((120, 200, 3), (70, 110, 60), np.uint8)
    frame[20:68, 30:78] = art_crop('stop', rng)
    frame[40:88, 120:168] = art_crop('road_work_ahead', rng)
    out = model.classify_boxes(frame, [(34, 24, 40, 40), (124, 44, 40, 40), (500, 10, 9, 9)],
                               margin=0.05)
    assert [p.class_key if p else None for p in out] == ['stop', 'road_work_ahead', None]
    assert model.classify_boxes(frame, []) == []
    assert model.classify([]) == []


def _one_line_error(path, match):
    with pytest.raises(cl.ModelError, match=match) as info:
        cl.load_model(path)
    assert '\n' not in str(info.value) and str(path) in str(info.value)


def test_model_file_round_trip(model, tmp_path):
    path = tmp_path / 'm.npz'
    cl.save_model(model, path)
    back = cl.load_model(path)
    crops, _ = dataset(2, seed=4)
    assert back.classes == model.classes
    assert np.allclose(back.predict_proba(crops), model.predict_proba(crops))
    assert back.metadata['training_sources'] == 'test sign art'
    with np.load(path, allow_pickle=False) as z:             # arrays only, no pickles
        assert all(z[k].dtype != object for k in z.files)


def test_bad_model_files_are_refused_with_one_line(model, tmp_path):
    good = tmp_path / 'good.npz'
    cl.save_model(model, good)
    _one_line_error(tmp_path / 'missing.npz', 'does not exist')
    truncated = tmp_path / 'truncated.npz'
    truncated.write_bytes(good.read_bytes()[:2000])
    _one_line_error(truncated, 'truncated or corrupt')
    text = tmp_path / 'text.npz'
    text.write_text('hello')
    _one_line_error(text, 'truncated or corrupt|not a')
    with np.load(good, allow_pickle=False) as z:
        files = {k: z[k] for k in z.files}
    # tampered: one support vector nudged, metadata untouched
    tampered = dict(files)
    sv = tampered['p_support_vectors'].copy()
    sv[0, 0] += 0.5
    tampered['p_support_vectors'] = sv
    np.savez_compressed(tmp_path / 'tampered.npz', **tampered)
    _one_line_error(tmp_path / 'tampered.npz', 'integrity')
    # another schema version (hash recomputed, so only the version is wrong)
    md = json.loads(str(files['metadata']))
    md['version'] = cl.VERSION + 1
    arrays = {k: v for k, v in files.items() if k != 'metadata'}
    md['sha256'] = digest(arrays, md)
    np.savez_compressed(tmp_path / 'v2.npz', metadata=np.array(json.dumps(md)), **arrays)
    _one_line_error(tmp_path / 'v2.npz', 'version')
    # another model kind altogether (the colour model's schema)
    np.savez_compressed(tmp_path / 'other.npz', schema=np.array('workzone_ros/ColorModel'))
    _one_line_error(tmp_path / 'other.npz', 'not a workzone_ros sign classifier')
    assert zipfile.is_zipfile(good)


def test_training_refuses_classes_without_crops():
    crops, labels = dataset(3, seed=0, keys=KEYS[:2])
    with pytest.raises(ValueError, match=r'stop \(0\)'):
        cl.fit(crops, labels, KEYS[:3], cv=2)
    with pytest.raises(ValueError, match=r'work_zone_begin \(1\)'):
        cl.fit(crops[:4], labels[:4], KEYS[:2], cv=2)
    with pytest.raises(ValueError, match='unknown method'):
        cl.fit(crops, labels, KEYS[:2], method='tree')


def test_default_model_path_is_under_config_models():
    assert cl.DEFAULT_MODEL.startswith('models/sign_classifier')
    assert ft.FEATURE_KINDS[0] == 'logpolar'
