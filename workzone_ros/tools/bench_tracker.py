"""``workzone-ros bench tracker``: mean-shift ms per track per frame, vs OpenCV CamShift.

A synthetic 640x480 sequence (textured background, several orange diamond signs with black
borders and legends, of different sizes, drifting outward and growing 2 % per frame, as when
driving towards them) is tracked by both methods from the same starts: the first three frames
carry exact detections, the rest none, so every later frame is a tracking frame for every
track.  The figure is the time of the per-track localisation (search window, colour
conversion, the five mean-shift candidates or CamShift, similarity), measured per track and
frame on one core (OpenCV threads 1), p50/p99 over all track-frames; association and
track-life bookkeeping per frame are reported separately.
"""
from __future__ import annotations

import argparse
import os
import time

import cv2
import numpy as np

__all__ = ['add_arguments', 'run', 'make_sequence']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the benchmark."""
    parser.add_argument('--frames', type=int, default=60, help='frames per run (default 60)')
    parser.add_argument('--signs', type=int, default=4, help='signs in view (default 4)')
    parser.add_argument('--repeats', type=int, default=3, help='runs per method (default 3)')
    parser.add_argument('--seed', type=int, default=0, help='sequence seed')
    parser.add_argument('--cpu-time', action='store_true',
                        help='time with the thread CPU clock (for a loaded machine)')


def textured_background(rng: np.random.Generator, w: int = 640, h: int = 480) -> np.ndarray:
    """Muted, blurred colour texture with pixel noise (road / vegetation / sky like)."""
    small = rng.integers(40, 200, (h // 8, w // 8, 3)).astype(np.uint8)
    bg = cv2.GaussianBlur(cv2.resize(small, (w, h)), (0, 0), 3)
    hsv = cv2.cvtColor(bg, cv2.COLOR_BGR2HSV)
    hsv[..., 1] //= 3
    bg = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR).astype(np.float64)
    return np.clip(bg + rng.normal(0, 6, bg.shape), 0, 255).astype(np.uint8)


def _diamond(img: np.ndarray, cx: float, cy: float, size: float) -> tuple:
    s = size / 2
    pts = np.array([[cx, cy - s], [cx + s, cy], [cx, cy + s], [cx - s, cy]]) - 0.5
    p = np.round(pts * 16).astype(np.int32)
    cv2.fillConvexPoly(img, p, (0, 110, 245), cv2.LINE_AA, 4)
    cv2.polylines(img, [p], True, (20, 20, 20), max(1, int(size * 0.04)), cv2.LINE_AA, 4)
    cv2.putText(img, 'WORK', (int(cx - 0.3 * size), int(cy + 0.05 * size)),
                cv2.FONT_HERSHEY_SIMPLEX, size / 150, (20, 20, 20), max(1, int(size / 40)),
                cv2.LINE_AA)
    return (cx - s, cy - s, size, size)


def make_sequence(frames: int, signs: int, seed: int = 0):
    """Frames and ground-truth boxes of the benchmark sequence.

    Returns:
        ``(images, boxes)``: lists per frame; ``boxes[i]`` has one ``(x, y, w, h)`` per sign.
    """
    rng = np.random.default_rng(seed)
    bg = textured_background(rng)
    starts = []
    for k in range(signs):
        size = 24 + 70 * k / max(1, signs - 1)       # 24 .. 94 px at the start
        starts.append((90 + 470 * (k + 0.5) / signs, 140 + 60 * (k % 2), size))
    images, boxes = [], []
    for i in range(frames):
        img = bg.copy()
        bb = []
        for k, (x, y, size) in enumerate(starts):
            g = 1.015 ** i
            cx = 320 + (x - 320) * g
            cy = 240 + (y - 240) * g
            bb.append(_diamond(img, cx, cy, size * g))
        images.append(img)
        boxes.append(bb)
    return images, boxes


def _measure(method: str, images, boxes, repeats: int):
    from workzone_ros.core.track import MultiTracker, TrackerConfig
    from workzone_ros.interfaces import Box, Detection
    per_track, per_frame, ious = [], [], []
    for _ in range(repeats):
        tracker = MultiTracker(TrackerConfig(method=method, max_box_fraction=0.9,
                                             max_coast_frames=10_000))
        for i, (img, bb) in enumerate(zip(images, boxes)):
            dets = [Detection(box=Box(x=b[0], y=b[1], w=b[2], h=b[3]), confidence=0.9)
                    for b in bb] if i < 3 else []
            t0 = time.perf_counter()
            out = tracker.step(img, dets)
            dt = time.perf_counter() - t0
            if i >= 3:
                per_track += tracker.last_localise_s
                per_frame.append(dt - sum(tracker.last_localise_s))
                for t in out:
                    b = t.box
                    ious.append(max(_iou((b.x, b.y, b.w, b.h), g) for g in bb))
    return np.array(per_track) * 1e3, np.array(per_frame) * 1e3, np.array(ious)


def _iou(a, b) -> float:
    iw = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    ih = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    if iw <= 0 or ih <= 0:
        return 0.0
    return iw * ih / (a[2] * a[3] + b[2] * b[3] - iw * ih)


def run(args: argparse.Namespace) -> dict:
    """Run the benchmark; returns its figures."""
    cv2.setNumThreads(1)
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        core = 'pinned to one core'
    except (AttributeError, OSError):
        core = 'not pinned'
    from workzone_ros.core.track import multi
    clock = 'wall (perf_counter)'
    if getattr(args, 'cpu_time', False):
        multi._clock = time.thread_time
        clock = 'thread CPU time'
    images, boxes = make_sequence(args.frames, args.signs, args.seed)
    out = {'frames': args.frames, 'signs': args.signs, 'repeats': args.repeats,
           'image': '640x480', 'cpu': core, 'opencv_threads': cv2.getNumThreads(), 'clock': clock}
    for method in ('meanshift', 'camshift'):
        _measure(method, images[:6], boxes[:6], 1)         # warm-up
        tr, fr, iou = _measure(method, images, boxes, args.repeats)
        out[method] = {
            'track_frames': int(tr.size),
            'ms_per_track_frame_p50': round(float(np.percentile(tr, 50)), 4),
            'ms_per_track_frame_p99': round(float(np.percentile(tr, 99)), 4),
            'ms_per_track_frame_mean': round(float(tr.mean()), 4),
            'ms_bookkeeping_per_frame_p50': round(float(np.percentile(fr, 50)), 4),
            'published_tracks_per_frame': round(iou.size / max(1, fr.size), 3),
            'iou_with_truth_median': round(float(np.median(iou)), 3) if iou.size else None,
        }
    out['target_ms_per_track_frame_p50'] = 1.0
    out['meets_target'] = out['meanshift']['ms_per_track_frame_p50'] <= 1.0
    return out


if __name__ == '__main__':
    p = argparse.ArgumentParser()
    add_arguments(p)
    print(run(p.parse_args()))
