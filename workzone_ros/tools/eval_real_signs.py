"""``workzone-ros evaluate real_signs``: detector + tracker + classifier on the real dashcam clips.

Per clip of ``../shared/realdata/us_workzone_video`` (camera only, native size), every frame
goes through the colour detector, the mean-shift tracker and the classifier node's rules
(:class:`workzone_ros.core.recognition.SignRecognizer`), and the published signs are compared
with the hand-made labels (evaluation only, never trained on):

* ``sign_share``: of the frames where the labelled work-zone sign is visible
  (``tools/data/real_sign_boxes.csv``), the share where a work-zone class is reported on a
  box with IoU >= 0.3 with the label (the issue's target: >= 0.8);
* ``false_per_frame``: work-zone signs reported per frame in the frames outside every
  ``workzone_sign`` range of ``tools/data/real_clip_ranges.csv`` (target <= 0.05).

Say which data trained the model: a model trained on a clip's crops is not measured on it.
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path
from typing import Optional

from workzone_ros.resources import config_path
from workzone_ros.tools.eval_color import load_real_labels

__all__ = ['evaluate_clip', 'main']

REAL_DEFAULT = Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata' \
    / 'us_workzone_video'
RANGES = Path(__file__).resolve().parent / 'data' / 'real_clip_ranges.csv'
CLIPS = ('charlotte', 'denver', 'houston', 'minneapolis', 'chicago', 'san_francisco')


def sign_ranges(path: Path = RANGES) -> dict[str, list[tuple[int, int]]]:
    """clip file -> frame ranges where a work-zone sign is in view."""
    out: dict[str, list[tuple[int, int]]] = {}
    with open(path) as fh:
        for row in csv.DictReader(line for line in fh if not line.startswith('#')):
            if row['content'] == 'workzone_sign':
                out.setdefault(row['clip'], []).append((int(row['first_frame']),
                                                        int(row['last_frame'])))
    return out


def evaluate_clip(path: Path, model, hfov_deg: float, max_frames: int = 0) -> dict:
    """The figures of one clip (module docstring)."""
    import cv2

    from workzone_ros.core.recognition import SignRecognizer
    from workzone_ros.core.sign_distance import focal_from_fov
    from workzone_ros.core.tracking import MultiTracker, TrackerConfig
    from workzone_ros.tools.eval_tracker import _ColorDetector
    labels = load_real_labels().get(path.name, {})
    ranges = sign_ranges().get(path.name, [])
    det, tracker = _ColorDetector(None), MultiTracker(TrackerConfig())
    recognizer = SignRecognizer(model)
    cap = cv2.VideoCapture(str(path))
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    n = hits = free = false = k = 0
    while not max_frames or k < max_frames:
        ok, img = cap.read()
        if not ok:
            break
        tracks = tracker.step(img, [d for d in det(img, None) if d.color == 'orange'],
                              stamp=k / fps)
        signs, _ = recognizer.recognize(img, tracks, focal_from_fov(img.shape[1], hfov_deg))
        wz = [s for s in signs if s.category == 'workzone']
        label = labels.get(k)
        if label and label[1]:
            n += 1
            hits += any(s.box.iou(label[0]) >= 0.3 for s in wz)
        if not any(a <= k <= b for a, b in ranges):
            free += 1
            false += len(wz)
        k += 1
    cap.release()
    return {'frames': k, 'sign_frames': n,
            'sign_share': round(hits / n, 3) if n else None,
            'free_frames': free, 'false_per_frame': round(false / free, 3) if free else None}


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point; prints one line per clip and the JSON figures."""
    import json

    from workzone_ros.core.classifier import DEFAULT_MODEL, ModelError, load_model
    p = argparse.ArgumentParser(prog='workzone-ros evaluate real_signs', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--model', default=str(config_path(DEFAULT_MODEL)))
    p.add_argument('--real', default=str(REAL_DEFAULT), help='folder of the clips')
    p.add_argument('--clips', nargs='*', default=list(CLIPS))
    p.add_argument('--hfov', type=float, default=60.0, help='stated field of view (deg)')
    p.add_argument('--max-frames', type=int, default=0)
    p.add_argument('--json', metavar='OUT')
    args = p.parse_args(argv)
    folder = Path(args.real)
    if not folder.is_dir():
        print(f'workzone-ros evaluate real_signs: no such folder: {folder}', file=sys.stderr)
        return 2
    try:
        model = load_model(args.model)
    except ModelError as exc:
        print(f'workzone-ros evaluate real_signs: {exc}', file=sys.stderr)
        return 2
    out = {'model': args.model, 'trained_on': model.metadata.get('sources'), 'clips': {}}
    for name in args.clips:
        path = folder / f'{name}.mp4'
        if not path.exists():
            print(f'{name}: {path} not found, skipped', file=sys.stderr)
            continue
        r = evaluate_clip(path, model, args.hfov, args.max_frames)
        out['clips'][name] = r
        print(f"{name:14s} sign frames {r['sign_frames']:4d} share {r['sign_share']}  "
              f"false work-zone signs / frame {r['false_per_frame']} over "
              f"{r['free_frames']} frames", file=sys.stderr, flush=True)
    text = json.dumps(out, indent=2, default=str)
    print(text)
    if args.json:
        Path(args.json).write_text(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
