"""core.color_model: boosted stumps -> LUT (Seo et al. eq. 2), prior, versioned model file."""
import json

import cv2
import numpy as np
import pytest

from workzone_ros.core import color_model as cm

ORANGE = (0, 110, 245)


def _training_images(n=6, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        img = np.empty((120, 160, 3), np.uint8)
        img[:60] = (200, 170, 140)                         # sky
        img[60:] = (70, 110, 60)                           # grass
        img = cv2.add(img, rng.integers(0, 30, img.shape, dtype=np.uint8))
        mask = np.zeros(img.shape[:2], np.uint8)
        x, y = int(rng.integers(10, 110)), int(rng.integers(5, 60))
        col = (np.array(ORANGE) * rng.uniform(0.6, 1.0)).tolist()
        cv2.rectangle(img, (x, y), (x + 30, y + 30), col, -1)
        cv2.rectangle(mask, (x, y), (x + 30, y + 30), 1, -1)
        cv2.circle(img, (150, 110), 6, (30, 80, 150), -1)       # a brown, orange-ish stone
        img = cv2.add(img, rng.integers(0, 12, img.shape, dtype=np.uint8))
        out.append((img, mask, (x, y, 31, 31)))
    return out


@pytest.fixture(scope='module')
def trained():
    pos = np.zeros((cm.H_BINS, cm.S_BINS))
    neg = np.zeros_like(pos)
    for img, mask, _ in _training_images():
        p, n = cm.histogram_from_pixels(cv2.cvtColor(img, cv2.COLOR_BGR2HSV), mask, v_min=40)
        pos += p
        neg += n
    return cm.fit_boosted(pos, neg, n_estimators=15)


def test_logistic_link_is_the_seed_formula():
    f = np.linspace(-30, 30, 61)
    ref = np.exp(f) / (np.exp(f) + np.exp(-f))
    np.testing.assert_allclose(cm.logistic_link(f), ref, atol=1e-12)
    assert cm.logistic_link(np.array([1e4]))[0] == 1.0          # no overflow


def test_lut_equals_boosted_model_on_every_bin(trained):
    lut = cm.boosted_lut(trained)
    assert lut.shape == (180, 256) and lut.dtype == np.float32
    h, s = np.meshgrid(np.arange(180), np.arange(256), indexing='ij')
    X = np.column_stack([h.ravel(), s.ravel()])
    # independent reference: stump by stump, f = sum alpha_i h_i, g(f) = e^f / (e^f + e^-f)
    ref = cm.logistic_link(cm.stump_margin(trained, X)).reshape(180, 256)
    np.testing.assert_allclose(lut, ref, atol=1e-6)
    # and scikit-learn's predict_proba ranks every bin the same way (same sign of the margin)
    pp = trained.predict_proba(X)[:, 1].reshape(180, 256)
    np.testing.assert_array_equal(lut > 0.5, pp > 0.5)


def test_learned_model_separates_orange(trained):
    lut = cm.boosted_lut(trained)
    hsv = cv2.cvtColor(np.array([[ORANGE, (200, 170, 140), (70, 110, 60)]], np.uint8),
                       cv2.COLOR_BGR2HSV)[0]
    p = [lut[h, s] for h, s, _ in hsv]
    assert p[0] > 0.5 and p[1] < 0.5 and p[2] < 0.5


def test_prior_heat_map_and_roi():
    boxes = [(400, 100, 40, 40), (420, 120, 30, 30), (500, 80, 60, 60)]
    prior = cm.fit_prior(boxes, (640, 480))
    img = prior.prior_image(640, 480)
    assert img.shape == (480, 640)
    assert img[130, 430] > 0.9 and abs(img[470, 10] - prior.floor) < 1e-3
    x, y, w, h = prior.roi
    assert x <= 400 and y <= 80 and x + w >= 560 and y + h >= 140 and y + h < 480
    u = cm.SpatialPrior.uniform()
    assert np.all(u.prior_image(64, 48) == 1.0)


def test_save_load_round_trip(tmp_path, trained):
    prior = cm.fit_prior([(400, 100, 40, 40)], (640, 480))
    model = cm.default_model(cm.boosted_lut(trained), 40, prior, {'images': 6})
    path = tmp_path / 'models' / 'color_orange.npz'
    cm.save_model(model, path)
    back = cm.load_model(path)
    assert back.classes == ('orange', 'red', 'yellow')
    np.testing.assert_array_equal(back.luts, model.luts)
    np.testing.assert_array_equal(back.prior.heat, prior.heat)
    assert back.prior.roi == prior.roi and back.v_min == model.v_min
    assert back.metadata == {'images': 6}
    assert path.stat().st_size < 400_000


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(cm.ModelError, match='does not exist'):
        cm.load_model(tmp_path / 'nope.npz')


def test_truncated_file_is_a_clear_error(tmp_path):
    path = tmp_path / 'm.npz'
    cm.save_model(cm.default_model(), path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(cm.ModelError, match='truncated or corrupt'):
        cm.load_model(path)
    path.write_bytes(b'not a zip at all')
    with pytest.raises(cm.ModelError):
        cm.load_model(path)


def test_other_version_is_a_clear_error(tmp_path):
    path = tmp_path / 'm.npz'
    cm.save_model(cm.default_model(), path)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays['version'] = np.array(cm.VERSION + 1)
    np.savez(path, **arrays)
    with pytest.raises(cm.ModelError, match='version 2'):
        cm.load_model(path)
    arrays['schema'] = np.array('someone/Else')
    np.savez(path, **arrays)
    with pytest.raises(cm.ModelError, match='schema'):
        cm.load_model(path)


def test_model_file_never_unpickles(tmp_path):
    path = tmp_path / 'm.npz'
    cm.save_model(cm.default_model(), path)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays['metadata'] = np.array([{'evil': 1}], dtype=object)
    np.savez(path, **arrays)
    with pytest.raises(cm.ModelError):
        cm.load_model(path)


def test_hsv_range_tables():
    lut, v_min = cm.hsv_range_lut(cm.HSV_RANGES['red'])
    assert lut[0, 200] > 0.9 and lut[175, 200] > 0.9 and lut[60, 200] == 0 and lut[0, 20] == 0
    assert v_min == 60
    m = cm.default_model()
    bgr = np.full((4, 4, 3), (40, 35, 195), np.uint8)
    assert np.all(m.likelihood(bgr, 'red') > 0.9) and np.all(m.likelihood(bgr, 'orange') == 0)
    assert json.dumps(dict(m.metadata)) == '{}'


def test_gray_world_removes_a_tint_and_is_clipped():
    grey = np.full((8, 8, 3), 120, np.uint8)
    tinted = cm.apply_gains(grey, (0.7, 0.9, 1.3))             # dusk: orange cast
    back = cm.apply_gains(tinted, cm.gray_world_gains(tinted))
    b, g, r = back[0, 0].astype(int)
    assert max(b, g, r) - min(b, g, r) <= 2                   # neutral again, same brightness
    assert abs(int(back.mean()) - int(tinted.mean())) <= 2
    orange = np.full((8, 8, 3), ORANGE, np.uint8)              # a frame filled by one truck
    gains = cm.gray_world_gains(orange)
    assert min(gains) >= 0.6 and max(gains) <= 1.6


def _clear_day(cast=(1.0, 1.0, 1.0)):
    """A clear-day road frame: blue sky, green verges, grey asphalt, lane paint, a sign."""
    img = np.empty((240, 320, 3), np.uint8)
    img[:100] = (235, 170, 90)                                 # blue sky
    img[100:140] = (50, 120, 60)                               # green verges
    img[140:] = (92, 95, 98)                                   # asphalt, nearly neutral
    img[200:204, 40:280] = (225, 228, 230)                     # lane paint
    img[60:90, 150:180] = ORANGE                               # a sign face
    return cm.apply_gains(img, cast)


def _sat(bgr, rows, cols):
    return float(np.median(cv2.cvtColor(bgr[rows, cols], cv2.COLOR_BGR2HSV)[..., 1]))


def test_low_chroma_balance_leaves_a_clear_day_alone_where_grey_world_tints_the_road():
    img = _clear_day()
    road = (slice(150, 240), slice(0, 320))
    by_mean = cm.apply_gains(img, cm.gray_world_gains(img))
    by_low = cm.apply_gains(img, cm.low_chroma_gains(img))
    assert _sat(by_mean, *road) > 60                           # grey world: orange asphalt
    assert _sat(by_low, *road) < 15                            # low chroma: grey asphalt
    assert _sat(by_low, slice(62, 88), slice(152, 178)) > 200  # the sign keeps its colour


def test_low_chroma_balance_removes_a_cast_and_is_clipped():
    img = _clear_day(cast=(0.7, 0.9, 1.3))                    # dusk / white-balance error
    road = (slice(150, 240), slice(0, 320))
    assert _sat(img, *road) > 80
    gains = cm.low_chroma_gains(img)
    assert _sat(cm.apply_gains(img, gains), *road) < 15
    assert min(cm.low_chroma_gains(np.full((64, 64, 3), ORANGE, np.uint8))) >= 0.6
    assert cm.low_chroma_gains(np.zeros((64, 64, 3), np.uint8)) == (1.0, 1.0, 1.0)


def test_white_balance_from_model_metadata():
    lut = np.zeros((cm.H_BINS, cm.S_BINS), np.float32)
    img = _clear_day()
    assert cm.default_model(lut, metadata={}).balance_gains(img) is None
    old = cm.default_model(lut, metadata={'gray_world': True})    # models before the key
    assert old.white_balance == 'grey_world'
    assert old.balance_gains(img) == cm.gray_world_gains(img)
    new = cm.default_model(lut, metadata={'gray_world': True, 'white_balance': 'low_chroma'})
    assert new.balance_gains(img) == cm.low_chroma_gains(img)
    with pytest.raises(cm.ModelError, match='unknown white_balance'):
        cm.default_model(lut, metadata={'gray_world': True, 'white_balance': 'max_rgb'}
                         ).balance_gains(img)


def test_prior_saturation():
    boxes = [(400, 100, 40, 40)] * 10 + [(200, 120, 40, 40)]
    peaked = cm.fit_prior(boxes, (640, 480))
    flat = cm.fit_prior(boxes, (640, 480), saturate=0.05)
    assert peaked.prior_image(640, 480)[140, 220] < 0.6
    assert flat.prior_image(640, 480)[140, 220] > 0.99
    assert flat.prior_image(640, 480)[470, 10] == pytest.approx(flat.floor, abs=1e-3)


def test_saturation_norm_stretches_washed_out_frames_only():
    norm = cm.SatNorm(quantile=0.9, ref=120.0, max_gain=4.0)
    dull = np.full((40, 40, 3), (150, 150, 160), np.uint8)             # haze: S ~ 16
    dull[:8, :8] = (110, 130, 170)                                    # a washed-out sign
    hsv = cv2.cvtColor(dull, cv2.COLOR_BGR2HSV)
    g = cm.saturation_gain(hsv, norm, v_min=30)
    assert g == pytest.approx(4.0)                                    # clipped at max_gain
    vivid = np.full((40, 40, 3), (200, 120, 40), np.uint8)           # blue sky, S ~ 204
    assert cm.saturation_gain(cv2.cvtColor(vivid, cv2.COLOR_BGR2HSV), norm) == 1.0
    mid = np.full((40, 40, 3), (120, 150, 180), np.uint8)             # S = 85
    gm = cm.saturation_gain(cv2.cvtColor(mid, cv2.COLOR_BGR2HSV), norm)
    assert gm == pytest.approx(120.0 / 85.0, rel=0.02)
    tab = cm.saturation_table(2.5)
    assert tab.dtype == np.uint8 and tab[0] == 0 and tab[40] == 100 and tab[200] == 255
    # too dark to count (value gate): no gain from black pixels
    assert cm.saturation_gain(np.zeros((4, 4, 3), np.uint8), norm, v_min=30) == 1.0


def test_model_applies_its_saturation_norm(tmp_path):
    """A table that accepts only S >= 150 sees a hazy sign (S ~ 60) after the frame's
    saturation is stretched, while warm grey asphalt (S ~ 60) on a colourful frame stays
    below it."""
    lut = np.zeros((cm.H_BINS, cm.S_BINS), np.float32)
    lut[8:20, 150:] = 0.99
    meta = {'sat_norm': cm.SatNorm(0.9, 120.0, 4.0).to_dict()}
    model = cm.default_model(lut, 30, None, meta)
    path = tmp_path / 'm.npz'
    cm.save_model(model, path)
    model = cm.load_model(path)
    assert model.sat_norm == cm.SatNorm(0.9, 120.0, 4.0)
    hazy = np.full((40, 40, 3), (165, 160, 158), np.uint8)
    hazy[10:20, 10:20] = (110, 135, 160)                              # orange hue, S ~ 80
    assert model.likelihood(hazy)[15, 15] > 0.9
    assert model.with_prior(model.prior).sat_norm is not None
    plain = cm.default_model(lut, 30)
    assert plain.sat_norm is None and plain.likelihood(hazy)[15, 15] == 0.0
    sunny = np.full((40, 40, 3), (220, 140, 40), np.uint8)            # blue sky
    sunny[20:] = (118, 132, 150)                                      # warm asphalt, S ~ 54
    assert model.likelihood(sunny)[30, 5] == 0.0
    bad = cm.default_model(lut, 30, None, {'sat_norm': {'ref': 'x'}})
    with pytest.raises(cm.ModelError, match='sat_norm'):
        bad.sat_norm


def test_prior_camera_jitter_widens_the_roi():
    boxes = [(420, 150, 30, 30)] * 20
    fixed = cm.fit_prior(boxes, (640, 480), saturate=0.1)
    other = cm.fit_prior(boxes, (640, 480), saturate=0.1, camera_jitter=(0.1, 0.05, 0.25))
    fx, fy, fw, fh = fixed.roi
    ox, oy, ow, oh = other.roi
    assert oy + oh >= fy + fh + 40 and oy <= fy - 40          # +- 10 % of the height
    assert ox <= fx and ox + ow >= fx + fw
    # a sign lower in the image (another camera's horizon) has full prior only with jitter
    assert fixed.prior_image(640, 480)[235, 435] < 0.5
    assert other.prior_image(640, 480)[235, 435] > 0.99


def test_prior_expected_value_and_flat_prior():
    """The location-free prior is the heat map's mean over its ROI; a flat prior is that
    value everywhere; a uniform prior's expected value is 1."""
    prior = cm.fit_prior([(380, 100, 80, 80)] * 5, (640, 480), floor=0.2)
    x, y, w, h = prior.roi
    img = prior.prior_image(640, 480)
    assert prior.expected() == pytest.approx(float(img[y:y + h, x:x + w].mean()), rel=1e-6)
    assert 0.2 < prior.expected() < 1.0
    assert cm.SpatialPrior.uniform(722, 406).expected() == pytest.approx(1.0)
    flat = cm.SpatialPrior.flat(0.4, 722, 406)
    assert np.allclose(flat.prior_image(361, 203), 0.4)
    assert flat.roi_for(722, 406) == (0, 0, 722, 406)


def test_model_camera_and_same_camera():
    """Without camera metadata the training camera is the prior's image size (only that
    exact size matches); with recorded intrinsics the normalised ones decide, so a resized
    stream of the same camera matches and another lens of the same size does not."""
    prior = cm.fit_prior([(380, 100, 80, 80)], (640, 480))
    old = cm.default_model(prior=prior)
    assert old.camera == {'width': 640.0, 'height': 480.0}
    assert old.same_camera(640, 480)
    assert not old.same_camera(722, 406)
    assert not old.same_camera(1280, 960)
    assert old.same_camera(640, 480, (554.0, 554.0, 320.0, 240.0))   # no intrinsics recorded
    meta = {'camera': {'width': 640, 'height': 480, 'fx': 554.26, 'fy': 554.26, 'cx': 320,
                       'cy': 240}}
    new = cm.default_model(prior=prior, metadata=meta)
    assert new.same_camera(640, 480)
    assert new.same_camera(640, 480, (554.26, 554.26, 320.0, 240.0))
    assert new.same_camera(1280, 960, (1108.5, 1108.5, 640.0, 480.0))    # resized stream
    assert not new.same_camera(640, 480, (400.0, 400.0, 320.0, 240.0))    # wider lens
    assert not new.same_camera(640, 480, (554.26, 554.26, 320.0, 300.0))  # other pitch
    assert not new.same_camera(722, 406)
    bad = cm.default_model(prior=prior, metadata={'camera': {'width': 'x'}})
    with pytest.raises(cm.ModelError, match='camera'):
        bad.camera


def test_fast_quantile_equals_numpy():
    rng = np.random.default_rng(3)
    for n in list(range(1, 10)) + [100, 2401]:
        for dtype in (np.float32, np.float64):
            v = (rng.integers(0, 9, n) / 7.0).astype(dtype)          # ties
            w = rng.random(n).astype(dtype)
            for q in (0.0, 0.1, 0.2, 0.5, 0.9, 1.0):
                for x in (v, w):
                    got, ref = cm._quantile(x, q), np.quantile(x, q)
                    assert got == ref and got.dtype == ref.dtype
