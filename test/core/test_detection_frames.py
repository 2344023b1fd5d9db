"""The shipped colour detector as a user runs it: labelled camera frames from the simulator
(``test/data``), the simulator's sign art on plain and textured backgrounds, and the
simulator's cones and drums."""
from pathlib import Path

import cv2
import numpy as np
import pytest
from detection_helpers import _default_detector, _foliage, _plain, _render_art_sign

from workzone_ros.interfaces import Box
from workzone_ros.sim.lens import Lens
from workzone_ros.sim.painter import ObjectPainter
from workzone_ros.sim.weather import WEATHERS
from workzone_ros.sim.world import BASE_TO_CAMERA_ROT, CAMERA_IN_BASE, CameraModel, Cone, Cylinder

#: Simulator frames as the camera's JPEGs (``test/data``): file, labelled box (x, y, w, h),
#: the sign's kind; every sign is orange.  The scene seed and frame of each file:
#: underexposed_plaque 11601/160, winter_begins_legend 10902/327, winter_grey_ground_begins
#: 12205/356, winter_small_sign_bright_ground 12302/148, rain_dim_speed_limit 12407/297,
#: rain_pale_wall_speed_limit 13005/301, rain_wall_below_sign 13006/140,
#: rain_wall_beside_plaque 13006/142, sunny_clipped_plaque 13003/290, sunny_clipped_sign
#: 12103/290.
LABELLED_FRAMES = (
    ('underexposed_plaque.jpg', (419, 198, 19, 34), 'regulatory'),
    ('winter_begins_legend.jpg', (486, 205, 21, 26), 'regulatory'),
    ('winter_grey_ground_begins.jpg', (482, 204, 20, 26), 'regulatory'),
    ('winter_small_sign_bright_ground.jpg', (417, 214, 18, 18), 'warning'),
    ('rain_dim_speed_limit.jpg', (449, 203, 17, 27), 'regulatory'),
    ('rain_pale_wall_speed_limit.jpg', (505, 182, 26, 45), 'regulatory'),
    ('rain_wall_below_sign.jpg', (509, 183, 24, 43), 'regulatory'),
    ('rain_wall_beside_plaque.jpg', (537, 176, 28, 49), 'regulatory'),
    ('sunny_clipped_plaque.jpg', (446, 207, 18, 23), 'regulatory'),
    ('sunny_clipped_sign.jpg', (447, 208, 17, 23), 'regulatory'),
)


def _data_frame(name):
    """A camera frame (JPEG) from ``test/data``."""
    data = np.fromfile(Path(__file__).parent.parent / 'data' / name, np.uint8)
    return cv2.imdecode(data, cv2.IMREAD_COLOR)


def _edge_error(box, gt):
    """The largest distance (px) between a side of ``box`` and the same side of ``gt``."""
    return max(abs(box.x - gt.x), abs(box.y - gt.y), abs(box.x2 - gt.x2), abs(box.y2 - gt.y2))


def frame_scores(det):
    """Per labelled frame: (name, IoU of the best-matching detection, its largest side error
    in px, whether its kind and colour are the label's, detections not on the sign)."""
    rows = []
    for name, label, kind in LABELLED_FRAMES:
        gt = Box(*map(float, label))
        dets = det.detect(_data_frame(name))
        best = max(dets, key=lambda d: d.box.iou(gt), default=None)
        if best is None or best.box.iou(gt) == 0.0:
            rows.append((name, 0.0, np.inf, False, len(dets)))
            continue
        rows.append((name, best.box.iou(gt), _edge_error(best.box, gt),
                     best.kind == kind and best.color == 'orange', len(dets) - 1))
    return rows


def check_frame_scores(rows):
    """What a user of the detector gets on the labelled frames (all deterministic; measured
    on the current detector: every sign found, mean IoU 0.95, 9 of 10 boxes with every side
    within a pixel, the tenth 4 px off at its top, no other detection)."""
    table = '\n'.join(f'{n:38s} IoU {iou:.3f} edge {e:.1f} class ok {ok} others {o}'
                      for n, iou, e, ok, o in rows)
    assert all(r[1] >= 0.8 and r[3] for r in rows), f'a sign missed (IoU < 0.8, kind)\n{table}'
    assert np.mean([r[1] for r in rows]) >= 0.94, f'mean IoU under 0.94\n{table}'
    assert sum(r[2] <= 1.0 for r in rows) >= 9, f'under 9 boxes within a pixel\n{table}'
    assert max(r[2] for r in rows) <= 4.0, f'a box side more than 4 px off\n{table}'
    assert sum(r[4] for r in rows) == 0, f'other detections reported\n{table}'


def test_labelled_camera_frames_boxed():
    """The default detector on the labelled simulator frames of ``test/data`` (winter,
    rain, sun, under-exposure; pale walls and grey ground behind two-colour signs, clipped
    sheeting): every sign found as its kind, boxed tightly, and nothing else reported."""
    check_frame_scores(frame_scores(_default_detector()))


def _texture(seed=0, shape=(480, 640)):
    """Roadside clutter: green-grey with blotches a few pixels across."""
    rng = np.random.default_rng(seed)
    n = cv2.GaussianBlur(rng.normal(0, 1, shape).astype(np.float32), (0, 0), 3)
    img = np.empty((*shape, 3), np.float32)
    img[:] = (70, 95, 80)
    img += (18 * n / n.std())[..., None]
    return np.clip(img + rng.integers(0, 10, img.shape), 0, 255).astype(np.uint8)


@pytest.mark.parametrize('key, kind, min_exact', [
    ('road_work_ahead', 'warning', 36),
    ('work_zone_begin', 'regulatory', 32),
    ('work_zone_speed_limit', 'regulatory', 32)])
def test_rendered_signs_boxed_on_plain_and_textured_backgrounds(key, kind, min_exact):
    """The simulator's art of a sign, 20-44 px, at sub-pixel positions where the camera
    sees roadside signs, over grey, foliage and a blotchy texture (36 frames): the
    detector reports it as its kind with every side within a pixel of the label, in all
    36 frames for the warning diamond and in at least 32 for the two-colour signs (the
    misses are 20-30 px signs), and reports nothing away from the sign."""
    det = _default_detector()
    exact = 0
    for bg in (_plain((120, 122, 120), 8, 1), _foliage(), _texture()):
        for size in (20, 30, 44):
            for x, y in ((420.3, 170.6), (470.5, 150.2), (520.7, 185.4), (560.4, 160.5)):
                img, label = _render_art_sign(bg, x, y, size, key=key)
                gt = Box(*map(float, label))
                dets = det.detect(img)
                assert not [d for d in dets if d.box.iou(gt) < 0.1], (size, x, y, dets)
                hits = [d for d in dets if d.box.iou(gt) >= 0.5]
                assert all(d.kind == kind and d.color == 'orange' for d in hits), hits
                exact += bool(hits) and _edge_error(hits[0].box, gt) <= 1.0
    assert exact >= min_exact, exact


def _sim_road(objects, weather):
    """Objects of the simulator (cones, drums) painted as its camera sees them from the
    vehicle over a sky, tree line and asphalt, blurred a little like the camera."""
    lens = Lens(CameraModel(dist=(0.0, 0.0, 0.0, 0.0, 0.0)))
    painter = ObjectPainter(lens, WEATHERS[weather], 1)
    mx, my = lens.margin
    img = _plain((205, 175, 150), 16, 0)
    img[240:] = _plain((85, 88, 84), 16, 1)[240:]
    img[210:240] = (50, 105, 60)
    canvas = cv2.copyMakeBorder(img, my, my, mx, mx, cv2.BORDER_REPLICATE)
    label = np.zeros(canvas.shape[:2], np.uint8)
    for k, o in enumerate(sorted(objects, key=lambda o: -o.base[0])):
        painter.draw_object(canvas, label, o, CAMERA_IN_BASE, BASE_TO_CAMERA_ROT,
                            float(o.base[0] - CAMERA_IN_BASE[0]), k + 1)
    return cv2.GaussianBlur(canvas[my:my + 480, mx:mx + 640], (0, 0), 0.7)


@pytest.mark.parametrize('weather', ['spring_sunny', 'winter_overcast'])
def test_cones_and_drums_are_not_signs(weather):
    """Channelizing drums (three white bands) and traffic cones (one band) of the
    simulator, 6-18 m ahead on both sides of the lane: none is reported; a warning sign at
    the roadside in the same frame is."""
    det = _default_detector()
    for ahead in (6.0, 8.0, 12.0, 18.0):
        things = [Cylinder(1, 'drum', np.array([ahead, side, 0.0]), 0.29, 0.95, 'drum_orange',
                           [(0.18, 0.30, 'drum_band'), (0.42, 0.54, 'drum_band'),
                            (0.66, 0.78, 'drum_band')]) for side in (-3.5, -2.0)]
        things += [Cone(2, 'cone', np.array([ahead, side, 0.0]), 0.18, 0.71, 'cone_orange',
                        [(0.40, 0.52, 'drum_band')]) for side in (2.5, 4.0)]
        img, label = _render_art_sign(_sim_road(things, weather), 520.7, 170.4, 36)
        gt = Box(*map(float, label))
        dets = det.detect(img)
        assert [d.kind for d in dets if d.box.iou(gt) >= 0.8] == ['warning'], (ahead, dets)
        assert len(dets) == 1, (ahead, dets)

