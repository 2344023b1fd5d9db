"""bag-from-video: a small video becomes a camera-only bag the player reads; errors are one
line."""
from __future__ import annotations

import filecmp
import math

import cv2
import numpy as np
import pytest

from workzone_ros import cli
from workzone_ros.bagio import open_reader
from workzone_ros.sim.writer import EPOCH_NS
from workzone_ros.tools import bag_from_video

W, H, N, FPS = 64, 48, 7, 10.0


def _frame(k: int) -> np.ndarray:
    img = np.zeros((H, W, 3), np.uint8)
    img[:, :, 1] = 40 + 25 * k                          # brightness tells the frames apart
    cv2.rectangle(img, (8 + 4 * k, 10), (20 + 4 * k, 30), (0, 128, 255), -1)
    return img


@pytest.fixture(scope='module')
def video(tmp_path_factory):
    path = tmp_path_factory.mktemp('video') / 'clip.avi'
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*'MJPG'), FPS, (W, H))
    assert writer.isOpened()
    for k in range(N):
        writer.write(_frame(k))
    writer.release()
    return path


def _read(bag):
    out: dict = {}
    with open_reader(bag) as reader:
        for m in reader.messages():
            out.setdefault(m.topic, []).append((m.timestamp_ns, reader.deserialize(m)))
    return out


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec


def test_compressed_bag(video, tmp_path, capsys):
    out = tmp_path / 'bag'
    assert cli.main(['bag-from-video', str(video), '-o', str(out), '-q']) == 0
    assert 'wrote' in capsys.readouterr().out
    msgs = _read(out)
    assert sorted(msgs) == ['/camera/camera_info', '/camera/image_raw/compressed']
    images, infos = msgs['/camera/image_raw/compressed'], msgs['/camera/camera_info']
    assert len(images) == len(infos) == N
    stamps = [t for t, _ in images]
    assert stamps[0] == EPOCH_NS and np.all(np.diff(stamps) == 10 ** 8)
    for (t, img), (ti, info) in zip(images, infos):
        assert _stamp(img) == t == ti == _stamp(info)
        assert img.header.frame_id == info.header.frame_id == 'camera'
    f = W / 2 / math.tan(math.radians(30.0))                  # the stated 60 deg default
    _, info = infos[0]
    assert (info.width, info.height, info.distortion_model) == (W, H, 'plumb_bob')
    assert np.allclose(np.asarray(info.k).reshape(3, 3),
                       [[f, 0, W / 2], [0, f, H / 2], [0, 0, 1]])
    assert not np.any(info.d) and np.allclose(np.asarray(info.p).reshape(3, 4)[:, :3],
                                              np.asarray(info.k).reshape(3, 3))
    for k, (_, m) in enumerate(images):
        assert 'jpeg' in m.format
        img = cv2.imdecode(np.asarray(m.data, np.uint8), cv2.IMREAD_COLOR)
        assert img.shape == (H, W, 3)
        assert abs(float(img[:, 40:, 1].mean()) - (40 + 25 * k)) < 12   # frame order kept


def test_options_and_determinism(video, tmp_path):
    args = ['--raw', '--every', '2', '--max-frames', '2', '--resize', '32x32', '--hfov', '90',
            '--start-time', '10.5', '--frame-id', 'dashcam', '-q']
    a, b = tmp_path / 'a' / 'bag', tmp_path / 'b' / 'bag'
    assert bag_from_video.main([str(video), '-o', str(a), *args]) == 0
    assert bag_from_video.main([str(video), '-o', str(b), *args]) == 0
    assert filecmp.cmp(a / 'bag.mcap', b / 'bag.mcap', shallow=False)
    msgs = _read(a)
    assert sorted(msgs) == ['/camera/camera_info', '/camera/image_raw']
    images = msgs['/camera/image_raw']
    # frames 0 and 2 of the video, stamped with their own times
    assert [t for t, _ in images] == [10_500_000_000, 10_700_000_000]
    _, img = images[1]
    assert (img.width, img.height, img.encoding, img.header.frame_id) == (32, 32, 'bgr8',
                                                                         'dashcam')
    assert abs(float(np.asarray(img.data).reshape(32, 32, 3)[:, 20:, 1].mean()) - 90) < 12
    # 90 deg over the 32 px width; rows squeezed 48 -> 32 and columns 64 -> 32: fy = 4/3 fx
    K = np.asarray(msgs['/camera/camera_info'][0][1].k).reshape(3, 3)
    assert K[0, 0] == pytest.approx(16.0) and K[1, 1] == pytest.approx(16.0 * 4 / 3)
    assert (K[0, 2], K[1, 2]) == (16.0, 16.0)


def _one_line_error(capsys, needle):
    err = capsys.readouterr().err
    assert needle in err and err.count('\n') == 1, err


def test_errors_are_one_line(video, tmp_path, capsys):
    main = bag_from_video.main
    assert main([str(tmp_path / 'missing.mp4'), '-o', str(tmp_path / 'x')]) == 2
    _one_line_error(capsys, 'missing.mp4 not found')
    junk = tmp_path / 'junk.mp4'
    junk.write_text('not a video\n')
    assert main([str(junk), '-o', str(tmp_path / 'x')]) == 2
    _one_line_error(capsys, 'not a video OpenCV can decode')
    empty = tmp_path / 'empty.avi'
    cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*'MJPG'), FPS, (W, H)).release()
    assert main([str(empty), '-o', str(tmp_path / 'x')]) == 2
    _one_line_error(capsys, 'has no frames')
    assert not (tmp_path / 'x').exists()
    for bad in ('0', '180', 'wide'):
        with pytest.raises(SystemExit) as exc:
            main([str(video), '-o', str(tmp_path / 'x'), '--hfov', bad])
        assert exc.value.code == 2
        _one_line_error(capsys, '--hfov must be')
    out = tmp_path / 'bag'
    assert main([str(video), '-o', str(out), '-q', '--max-frames', '1']) == 0
    capsys.readouterr()
    assert main([str(video), '-o', str(out), '-q']) == 2
    _one_line_error(capsys, 'exists (use --overwrite)')
    assert main([str(video), '-o', str(out), '-q', '--overwrite']) == 0
    assert len(_read(out)['/camera/image_raw/compressed']) == N
    (tmp_path / 'precious').mkdir()
    (tmp_path / 'precious' / 'notes.txt').write_text('x')
    assert main([str(video), '-o', str(tmp_path / 'precious'), '-q', '--overwrite']) == 2
    _one_line_error(capsys, 'not a bag directory')
    assert (tmp_path / 'precious' / 'notes.txt').exists()
