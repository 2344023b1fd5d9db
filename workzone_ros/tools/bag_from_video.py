"""``workzone-ros bag-from-video``: turn a video file into a camera-only rosbag2 (MCAP).

Usage::

    workzone-ros bag-from-video VIDEO -o OUT_BAG [--hfov DEG] [--raw] [--jpeg-quality Q]
        [--start-time SEC] [--fps FPS] [--max-frames N] [--every N] [--resize WxH]
        [--frame-id camera] [--overwrite] [-q]

Writes ``/camera/image_raw/compressed`` (sensor_msgs/CompressedImage, JPEG re-encoded at
quality 90 by default) or, with ``--raw``, ``/camera/image_raw`` (bgr8), plus
``/camera/camera_info`` for every frame: plumb_bob with zero distortion and ``K`` from the
*stated* horizontal field of view ``--hfov`` (default 60 deg; square pixels, principal point
at the image centre).  The field of view is an assumption, not a calibration: a dashcam clip
carries no intrinsics.  Frame ``k`` (of the video, before ``--every``) is stamped
``start_time + k / fps``; the default start time is the simulator's epoch (1700000000 s), so
the same video and options give the same bag.  No LiDAR, no odometry: replay it with
``workzone-ros launch --bag OUT_BAG --nodes color_detector,tracker`` (or ``play``).

Errors (missing or unreadable video, a video without frames, a bad option, an existing
output without ``--overwrite``) are one line on stderr and exit status 2.  Progress lines go
to stderr about every 2 s.
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Optional

import numpy as np

__all__ = ['VideoBagError', 'VideoBagOptions', 'camera_model', 'convert', 'main']

PROG = 'workzone-ros bag-from-video'
IMAGE_TOPIC = '/camera/image_raw'
COMPRESSED_TOPIC = '/camera/image_raw/compressed'
INFO_TOPIC = '/camera/camera_info'
DEFAULT_HFOV = 60.0


class VideoBagError(RuntimeError):
    """The video cannot be converted (one line)."""


@dataclass(frozen=True)
class VideoBagOptions:
    """How to convert a video.

    Attributes:
        hfov_deg: stated horizontal field of view of the output frames (degrees).
        raw: write raw bgr8 images instead of JPEG.
        jpeg_quality: JPEG quality (1-100) without ``raw``.
        start_ns: stamp of the video's first frame (ns); None = the simulator's epoch.
        fps: frame rate for the stamps; None = the video's.
        max_frames: stop after writing this many frames (None = all).
        every: keep every N-th frame of the video.
        resize: output ``(width, height)``; None = the video's size.
        frame_id: header frame id.
    """

    hfov_deg: float = DEFAULT_HFOV
    raw: bool = False
    jpeg_quality: int = 90
    start_ns: Optional[int] = None
    fps: Optional[float] = None
    max_frames: Optional[int] = None
    every: int = 1
    resize: Optional[tuple[int, int]] = None
    frame_id: str = 'camera'


def camera_model(width: int, height: int, hfov_deg: float, src_size=None):
    """The pinhole camera of frames ``width`` x ``height`` with a stated horizontal fov.

    Args:
        width: output width (px).
        height: output height (px).
        hfov_deg: horizontal field of view of the output (degrees, in (0, 180)).
        src_size: ``(width, height)`` of the video before a resize: pixels of the source are
            square, so a resize to another aspect ratio gives ``fy != fx``.

    Returns:
        A :class:`~workzone_ros.sim.world.CameraModel` with zero distortion.

    Raises:
        VideoBagError: a field of view outside (0, 180) degrees.
    """
    from workzone_ros.core.sign_distance import focal_from_fov
    from workzone_ros.sim.world import CameraModel
    try:
        fx = focal_from_fov(int(width), float(hfov_deg))
    except ValueError as exc:
        raise VideoBagError(str(exc)) from None
    sw, sh = src_size if src_size else (width, height)
    fy = fx * (height / sh) / (width / sw)
    return CameraModel(int(width), int(height), fx, fy, width / 2.0, height / 2.0,
                       (0.0, 0.0, 0.0, 0.0, 0.0))


def _frames(cap, every: int) -> Iterator[tuple[int, np.ndarray]]:
    k = -1
    while True:
        if every > 1 and k >= 0:
            for _ in range(every - 1):      # grab without decoding the skipped frames
                if not cap.grab():
                    return
                k += 1
        ok, img = cap.read()
        if not ok or img is None:
            return
        k += 1
        yield k, img


def _check_request(video: Path, out: Path, opts: VideoBagOptions, overwrite: bool) -> None:
    """Raise :class:`VideoBagError` for a missing video, an existing output or bad options."""
    if not video.is_file():
        raise VideoBagError(f'{video} not found')
    if out.exists() and not overwrite:
        raise VideoBagError(f'{out} exists (use --overwrite)')
    if opts.every < 1 or (opts.max_frames is not None and opts.max_frames < 1):
        raise VideoBagError('--every and --max-frames must be >= 1')
    if not 1 <= opts.jpeg_quality <= 100:
        raise VideoBagError(f'JPEG quality must be in [1, 100], got {opts.jpeg_quality}')


def _open_frames(cap, video: Path, opts: VideoBagOptions
                 ) -> tuple[float, int, tuple[int, np.ndarray], Iterator[tuple[int, np.ndarray]]]:
    """The frame rate, the frame count the container states (0: unknown), the first frame
    and the frames after it.

    Raises:
        VideoBagError: an unreadable video, no usable frame rate, no decodable frame.
    """
    import cv2
    if not cap.isOpened():
        raise VideoBagError(f'cannot read {video}: not a video OpenCV can decode')
    fps = opts.fps or float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    if not (math.isfinite(fps) and 0.1 <= fps <= 1000.0):
        raise VideoBagError(f'{video} states no usable frame rate ({fps}); give --fps')
    total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    frames = _frames(cap, opts.every)
    first = next(frames, None)
    if first is None:
        raise VideoBagError(f'{video} has no frames OpenCV can decode')
    return fps, total, first, frames


def _expected_frames(total: int, opts: VideoBagOptions) -> int:
    """The frames the bag will get, from the container's count ``total`` (0: unknown)."""
    want = -(-total // opts.every) if total > 0 else 0      # the container's count
    if opts.max_frames:
        want = min(want, opts.max_frames) if want else opts.max_frames
    return want


def _frame_message(msgs, img: np.ndarray, k: int, t_ns: int, opts: VideoBagOptions) -> bytes:
    """The serialised image message of frame ``k`` (raw bgr8, or JPEG re-encoded)."""
    import cv2
    if opts.raw:
        return msgs.image(t_ns, img, frame=opts.frame_id)
    ok, buf = cv2.imencode('.jpg', img, [cv2.IMWRITE_JPEG_QUALITY, int(opts.jpeg_quality)])
    if not ok:
        raise VideoBagError(f'JPEG encoding of frame {k} failed')
    return msgs.compressed(t_ns, buf.tobytes(), frame=opts.frame_id)


def _write_frames(bag, frames: Iterator[tuple[int, np.ndarray]], cam, fps: float,
                  opts: VideoBagOptions, status: Optional[Callable[[int], None]]) -> int:
    """Write the image and CameraInfo messages of ``frames``; returns the frames written."""
    import cv2

    from workzone_ros.sim.writer import EPOCH_NS, SensorMessages
    start_ns = EPOCH_NS if opts.start_ns is None else int(opts.start_ns)
    msgs = SensorMessages()
    topic = IMAGE_TOPIC if opts.raw else COMPRESSED_TOPIC
    bag.add_topic(topic, 'sensor_msgs/msg/Image' if opts.raw
                  else 'sensor_msgs/msg/CompressedImage')
    bag.add_topic(INFO_TOPIC, 'sensor_msgs/msg/CameraInfo')
    n = 0
    for k, img in frames:
        if (img.shape[1], img.shape[0]) != (cam.width, cam.height):
            img = cv2.resize(img, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
        t_ns = start_ns + int(round(k * 1e9 / fps))
        bag.write(topic, t_ns, _frame_message(msgs, img, k, t_ns, opts))
        bag.write(INFO_TOPIC, t_ns, msgs.camera_info(t_ns, cam, frame=opts.frame_id))
        n += 1
        if status is not None:
            status(n)
        if opts.max_frames and n >= opts.max_frames:
            break
    return n


def _progress_lines(video: Path, want: int, started: float,
                    progress: Optional[Callable[[str], None]]
                    ) -> Optional[Callable[[int], None]]:
    """A per-frame callback calling ``progress`` with a status line about every 2 s."""
    if progress is None:
        return None
    last = started

    def status(n: int) -> None:
        nonlocal last
        now = time.monotonic()
        if now - last >= 2.0:
            last = now
            progress(f'bag-from-video {video.name}: {n}/{want or "?"} frames, '
                     f'{now - started:.0f} s elapsed')
    return status


def convert(video: str | Path, out: str | Path, opts: VideoBagOptions = VideoBagOptions(),
            overwrite: bool = False,
            progress: Optional[Callable[[str], None]] = None) -> dict:
    """Write the frames of ``video`` to the bag ``out``.

    Args:
        video: a video file OpenCV can read.
        out: bag directory to create.
        opts: conversion options.
        overwrite: replace an existing bag directory (never anything else).
        progress: called with a status line about every 2 s (None: silent).

    Returns:
        A summary: ``frames``, ``width``, ``height``, ``fps``, ``hfov_deg``, ``K``,
        ``bytes``, ``seconds``, ``path``.

    Raises:
        VideoBagError: missing / unreadable video, no frames, bad options, output exists.
    """
    # FFmpeg's own log ("moov atom not found" ...) would add lines to our one-line errors;
    # read when OpenCV first opens a video in this process
    os.environ.setdefault('OPENCV_FFMPEG_LOGLEVEL', '8')            # AV_LOG_FATAL
    import cv2

    from workzone_ros.bagio import BagError, BagWriter

    started = time.monotonic()
    video, out = Path(video), Path(out)
    _check_request(video, out, opts, overwrite)
    cap = cv2.VideoCapture(str(video))
    try:
        fps, total, first, frames = _open_frames(cap, video, opts)
        src_h, src_w = first[1].shape[:2]
        width, height = opts.resize or (src_w, src_h)
        cam = camera_model(width, height, opts.hfov_deg, (src_w, src_h))
        want = _expected_frames(total, opts)
        try:
            bag = BagWriter(out, overwrite=overwrite)
        except BagError as exc:
            raise VideoBagError(str(exc)) from None
        try:
            n = _write_frames(bag, _chain(first, frames), cam, fps, opts,
                              _progress_lines(video, want, started, progress))
            bag.close()
        except (BagError, VideoBagError) as exc:
            bag.abort()
            shutil.rmtree(out, ignore_errors=True)
            raise VideoBagError(str(exc)) from None
        except BaseException:
            bag.abort()
            shutil.rmtree(out, ignore_errors=True)
            raise
    finally:
        cap.release()
    size = sum(p.stat().st_size for p in out.iterdir() if p.is_file())
    return {'path': out, 'frames': n, 'width': width, 'height': height, 'fps': fps,
            'hfov_deg': float(opts.hfov_deg), 'K': cam.K, 'bytes': size,
            'seconds': time.monotonic() - started}


def _chain(first, rest):
    yield first
    yield from rest


# --- command line ---------------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        print(f'{self.prog}: error: {message}', file=sys.stderr)
        raise SystemExit(2)


def _number(kind: type, name: str, lo: float, hi: float):
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'{name} must be a number, got {text!r}') from None
        if not (math.isfinite(value) and lo <= value <= hi):
            raise argparse.ArgumentTypeError(f'{name} must be in [{lo}, {hi}], got {text!r}')
        return value
    return parse


def _hfov(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'--hfov must be degrees, got {text!r}') from None
    if not 1.0 <= value <= 179.0:
        raise argparse.ArgumentTypeError(f'--hfov must be in [1, 179] degrees, got {text!r}')
    return value


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split('x'))
    except ValueError:
        raise argparse.ArgumentTypeError(f'--resize must be WxH, e.g. 640x360, got {text!r}') \
            from None
    if not (8 <= w <= 8192 and 8 <= h <= 8192):
        raise argparse.ArgumentTypeError(f'--resize sides must be in [8, 8192], got {text!r}')
    return w, h


def build_parser() -> argparse.ArgumentParser:
    """The ``workzone-ros bag-from-video`` argument parser."""
    p = _Parser(prog=PROG, description='Turn a video file (e.g. a dashcam clip) into a '
                'camera-only rosbag2 (MCAP) with CameraInfo, for `workzone-ros play` / '
                '`launch --bag`.')
    p.add_argument('video', help='video file (anything OpenCV reads: mp4, avi, mov, ...)')
    p.add_argument('-o', '--output', required=True, help='bag directory to create')
    p.add_argument('--hfov', type=_hfov, default=DEFAULT_HFOV, metavar='DEG',
                   help='horizontal field of view of the output frames, in degrees '
                   f'(default {DEFAULT_HFOV:g}); CameraInfo K is derived from it with square '
                   'pixels, the principal point at the centre and zero distortion. It is '
                   'STATED, not calibrated: a phone clip carries no intrinsics')
    p.add_argument('--raw', action='store_true',
                   help=f'write raw bgr8 {IMAGE_TOPIC} instead of JPEG {COMPRESSED_TOPIC}')
    p.add_argument('--jpeg-quality', type=_number(int, '--jpeg-quality', 1, 100), default=90,
                   metavar='Q', help='JPEG quality of the re-encoded frames (default 90)')
    p.add_argument('--start-time', type=_number(float, '--start-time', 0.0, 4e9),
                   metavar='SEC', help='stamp of the first frame in seconds since the epoch '
                   "(default 1700000000, the simulator's: deterministic output)")
    p.add_argument('--fps', type=_number(float, '--fps', 0.1, 1000.0),
                   help="frame rate for the stamps (default: the video's)")
    p.add_argument('--max-frames', type=_number(int, '--max-frames', 1, 10 ** 9), metavar='N',
                   help='stop after writing N frames')
    p.add_argument('--every', type=_number(int, '--every', 1, 10 ** 6), default=1, metavar='N',
                   help='keep every N-th frame (stamps stay those of the video)')
    p.add_argument('--resize', type=_size, metavar='WxH', help='scale the frames to WxH')
    p.add_argument('--frame-id', default='camera', help='header frame id (default camera)')
    p.add_argument('--overwrite', action='store_true', help='replace an existing bag')
    p.add_argument('-q', '--quiet', action='store_true', help='no progress lines')
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point of ``workzone-ros bag-from-video``; returns 0, or 2 on an error."""
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    opts = VideoBagOptions(
        hfov_deg=args.hfov, raw=args.raw, jpeg_quality=args.jpeg_quality,
        start_ns=None if args.start_time is None else int(round(args.start_time * 1e9)),
        fps=args.fps, max_frames=args.max_frames, every=args.every, resize=args.resize,
        frame_id=args.frame_id)
    try:
        res = convert(args.video, args.output, opts, overwrite=args.overwrite,
                      progress=None if args.quiet else
                      (lambda line: print(line, file=sys.stderr, flush=True)))
    except (VideoBagError, OSError) as exc:
        print(f'{PROG}: error: {" ".join(str(exc).split())}', file=sys.stderr)
        return 2
    K = res['K']
    print(f'wrote {res["path"]}: {res["frames"]} frames {res["width"]}x{res["height"]} at '
          f'{res["fps"]:g} fps, hfov {res["hfov_deg"]:g} deg stated (fx {K[0, 0]:.1f}, '
          f'fy {K[1, 1]:.1f} px), {res["bytes"] / 1e6:.1f} MB in {res["seconds"]:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
