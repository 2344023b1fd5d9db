"""Tests for core/projection.py: pixels by hand (Cahail et al. s2.4.2), crops, ego motion."""
import numpy as np
import pytest

from workzone_ros.core.lidar_clustering import CANDIDATE_DTYPE
from workzone_ros.core.projection import (
    CameraModel,
    ProjectionError,
    RoiParams,
    candidates_to_rois,
    compensate,
    crop_boxes,
    euler_matrix,
    extrinsics_from_list,
    forward_time_offset,
    invert,
    point_times,
    project_points,
)

K = np.array([[554.26, 0, 320.0], [0, 554.26, 240.0], [0, 0, 1]])
D = np.array([-0.08, 0.02, 0.0005, -0.0003, 0.001])
CAM = CameraModel(640, 480, K, D)
# Lidar (x fwd, y left, z up) -> camera optical (x right, y down, z fwd), camera 0.6 m ahead
# and 0.5 m below the lidar (the simulator's extrinsics).
T = extrinsics_from_list([0, -1, 0, 0, 0, 0, -1, -0.5, 1, 0, 0, -0.6, 0, 0, 0, 1])


def by_hand(p_lidar, k=K, d=D, t=T):
    """Cahail et al., section 2.4.2, written out: x' = x/z, radial + tangential distortion,
    u = fx x'' + cx."""
    x, y, z = t[:3, :3] @ p_lidar + t[:3, 3]
    xp, yp = x / z, y / z
    k1, k2, p1, p2, k3 = d
    r2 = xp * xp + yp * yp
    radial = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
    xpp = xp * radial + 2 * p1 * xp * yp + p2 * (r2 + 2 * xp * xp)
    ypp = yp * radial + p1 * (r2 + 2 * yp * yp) + 2 * p2 * xp * yp
    return np.array([k[0, 0] * xpp + k[0, 2], k[1, 1] * ypp + k[1, 2]])


def test_projection_matches_hand_computed_pixels_with_distortion():
    pts = np.array([[20.0, -6.0, 0.8], [30.0, 0.0, 0.5], [10.0, 3.0, -1.0], [60.0, -9.0, 2.0]])
    proj = project_points(pts, T, CAM)
    for p, uv in zip(pts, proj.uv):
        assert uv == pytest.approx(by_hand(p), abs=1e-3)
    # Distortion matters here: far from the centre it moves the pixel by several pixels.
    nodist = project_points(pts, T, CameraModel(640, 480, K, np.zeros(5)))
    assert np.abs(nodist.uv[2] - proj.uv[2]).max() > 1.0
    assert proj.in_image.all()


def test_point_straight_ahead_lands_on_the_principal_point():
    proj = project_points(np.array([[50.0, 0.0, -0.5]]), T, CAM)   # camera height
    assert proj.uv[0] == pytest.approx([320.0, 240.0], abs=1e-6)
    assert proj.depth[0] == pytest.approx(49.4)


def test_points_behind_the_camera_and_outside_the_image():
    pts = np.array([[-10.0, 0.0, 0.0], [0.3, 0.0, 0.0], [5.0, -40.0, 0.0], [20.0, -13.0, 0.0]])
    proj = project_points(pts, T, CAM)
    assert not proj.in_front[0] and not proj.in_front[1]
    assert np.isnan(proj.uv[:3]).all()        # behind, too close, far outside the view
    assert proj.in_front[3] and not proj.in_image[3] and np.isfinite(proj.uv[3]).all()


def test_real_calibration_json_layout():
    # PJLab scene_sign_board calibration (row-major lidar->camera, 5 coefficients).
    t = extrinsics_from_list([0.00382471, -0.999992, -0.00070554, -0.0125114,
                              -0.0132276, 0.000654817, -0.999912, -0.379526,
                              0.999905, 0.00383377, -0.0132251, -0.551037, 0, 0, 0, 1])
    k = np.array([[2117.31, 0, 924.681], [0, 2113.29, 656.457], [0, 0, 1]])
    d = np.array([-0.102933, -0.040925, 0.00057951, -0.00419933, 0.429959])
    p = np.array([97.1, 0.5, 5.2])
    proj = project_points(p[None], t, CameraModel(1920, 1200, k, d))
    assert proj.uv[0] == pytest.approx(by_hand(p, k, d, t), abs=1e-3)
    assert 880 < proj.uv[0, 0] < 965 and 480 < proj.uv[0, 1] < 530   # on the board


def test_extrinsics_validation():
    with pytest.raises(ProjectionError, match='16'):
        extrinsics_from_list([1, 0, 0])
    with pytest.raises(ProjectionError, match='rotation'):
        extrinsics_from_list([2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])
    assert extrinsics_from_list(list(T[:3].ravel())) == pytest.approx(T)


def test_crop_size_scales_with_radius_and_range():
    uv = np.array([[320.0, 240.0], [320.0, 240.0], [320.0, 240.0]])
    boxes = crop_boxes(uv, np.array([20.0, 40.0, 20.0]), np.array([0.8, 0.8, 1.6]), CAM,
                       margin=1.5, min_radius=0.6, pad_px=0.0, pad_m=0.0, min_px=0.0)
    half = 1.5 * 0.8 * 554.26 / 20.0
    assert boxes[0, 2] == pytest.approx(2 * half)
    assert boxes[1, 2] == pytest.approx(half)            # twice the range: half the size
    assert boxes[2, 2] == pytest.approx(4 * half)        # twice the radius: twice the size
    small = crop_boxes(uv[:1], np.array([20.0]), np.array([0.05]), CAM, margin=1.0,
                       min_radius=0.6, pad_px=0.0, pad_m=0.0, min_px=0.0)
    assert small[0, 2] == pytest.approx(2 * 0.6 * 554.26 / 20.0)   # never below a sign


def test_crop_is_clipped_to_the_image():
    box = crop_boxes(np.array([[630.0, 5.0]]), np.array([10.0]), np.array([1.0]), CAM)[0]
    x, y, w, h = box
    assert x >= 0 and y == 0 and x + w == 640 and h > 0


def test_compensation_of_forward_motion():
    # Scan at t0, image 50 ms later at 27 m/s: a static point is 1.35 m closer.
    p = np.array([[40.0, -8.0, 0.8]])
    scan, image = np.eye(4), np.eye(4)
    image[0, 3] = 27.0 * 0.05
    out = compensate(p, scan, image)
    assert out[0] == pytest.approx([40.0 - 1.35, -8.0, 0.8])
    yaw = euler_matrix((1.0, 0.0, 0.0), (0.0, 0.0, 0.1))
    back = compensate(compensate(p, np.eye(4), yaw), yaw, np.eye(4))
    assert back == pytest.approx(p)
    assert invert(yaw) @ yaw == pytest.approx(np.eye(4))


def test_point_times_of_a_clockwise_spin_from_the_rear():
    pts = np.array([[10.0, 0.0, 0.0], [0.0, -10.0, 0.0], [-10.0, 0.001, 0.0]])
    t = point_times(pts, 1_000_000_000, 10.0)
    assert t[0] == 1_050_000_000            # forward: half a spin after the stamp
    assert t[1] == 1_075_000_000            # right: three quarters
    assert abs(t[2] - 1_000_000_000) < 10_000   # just past the seam behind


def _cands(rows):
    a = np.zeros(len(rows), CANDIDATE_DTYPE)
    for i, (x, y, z, r) in enumerate(rows):
        a[i] = (x, y, z, r, 200.0, 25, 7 + i)
    return a


def test_candidates_to_rois_several_per_frame_and_behind():
    cands = _cands([(20.0, -6.0, 0.8, 0.8), (40.0, -7.0, 1.0, 0.9), (-15.0, 0.0, 0.0, 0.8)])
    rois, comp = candidates_to_rois(cands, 0, 0, CAM, T)
    assert [r.candidate_id for r in rois] == [7, 8] and not comp
    assert rois[0].center == pytest.approx(tuple(by_hand(np.array([20.0, -6.0, 0.8]))),
                                           abs=1e-3)
    assert rois[0].box.w > rois[1].box.w


def test_candidates_to_rois_compensates_with_the_pose_function():
    speed = 27.0

    def pose(t_ns):          # odom <- lidar moving forward along x
        m = np.eye(4)
        m[0, 3] = speed * t_ns * 1e-9
        return m

    sign = np.array([40.0, -7.0, 1.0])
    # Scan stamped at 0 (start of spin), the sign fires at ~+50 ms; the image is at +100 ms.
    fired = point_times(sign[None], 0, 10.0)[0]
    measured = sign - [speed * fired * 1e-9, 0, 0]
    cands = _cands([tuple(measured) + (0.8,)])
    image_ns = 100_000_000
    rois, comp = candidates_to_rois(cands, 0, image_ns, CAM, T, pose, RoiParams())
    truth = by_hand(sign - [speed * image_ns * 1e-9, 0, 0])
    assert comp and rois[0].center == pytest.approx(tuple(truth), abs=0.05)
    raw, comp2 = candidates_to_rois(cands, 0, image_ns, CAM, T, None)
    assert not comp2 and np.hypot(*(np.array(raw[0].center) - truth)) > 3.0
    # No pose at these times: not compensated, and said so.
    none, comp3 = candidates_to_rois(cands, 0, image_ns, CAM, T, lambda t: None)
    assert not comp3 and len(none) == 1


@pytest.mark.parametrize('image_ms', [-60, 20, 50, 250])
def test_compensation_for_any_gap_the_pairing_leaves(image_ms):
    # nearest may pair an image with a later scan (image before the firing), latest with a
    # much older one: the candidate is moved to the image time either way.
    speed = 27.0

    def pose(t_ns):
        m = np.eye(4)
        m[0, 3] = speed * t_ns * 1e-9
        return m

    sign = np.array([30.0, -6.0, 1.0])
    fired = point_times(sign[None], 0, 10.0)[0]
    cands = _cands([tuple(sign - [speed * fired * 1e-9, 0, 0]) + (0.8,)])
    image_ns = image_ms * 1_000_000
    rois, comp = candidates_to_rois(cands, 0, image_ns, CAM, T, pose, RoiParams())
    truth = by_hand(sign - [speed * image_ns * 1e-9, 0, 0])
    assert comp and rois[0].center == pytest.approx(tuple(truth), abs=0.05)


def test_forward_time_offset_follows_the_spin_model():
    assert forward_time_offset(RoiParams()) == 50_000_000          # half a 10 Hz spin
    assert forward_time_offset(RoiParams(lidar_rate_hz=20.0)) == 25_000_000
    assert forward_time_offset(RoiParams(spin_timing=False)) == 0
