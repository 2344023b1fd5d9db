"""``workzone-ros bench classifier``: sign classifier ms per crop, vs the raw-intensity baseline.

On one core (process pinned, OpenCV and BLAS / OpenMP pools at one thread) the shipped model
(``--model``, default the shipped CNN ``config/models/sign_classifier_cnn.npz``; the SVM is
``config/models/sign_classifier.npz``) classifies crops cut from the frames of the tracker
benchmark's synthetic sequence (orange diamonds of 24-180 px), timed

* one crop at a time (``classify([crop])``): p50 / p99 ms per crop;
* in batches of ``--batch`` (20) crops (``classify(crops)``): p50 / p99 ms per batch and
  per crop;
* ``classify_boxes`` on a frame with ``--batch`` boxes (cropping included);
* the classifier node's debug image (``debug_image: true``): :func:`draw_debug` of the frame
  with five signs and the phase banner, and its conversion to a ``sensor_msgs/Image``
  (``debug_image_ms``; sending it costs what ``bench transport`` measures for an image,
  and only when something subscribes).

In the same run two models trained on the same rendered crops (two library scenarios,
seed 0, rendered once into the crop cache) -- log-polar + PCA + SVM (the seed) and 100 x 100
raw intensity + PCA + SVM (the seed's baseline) -- are timed the same way; the figure is
their ratio (raw / log-polar).  Speed is measured here, never asserted in tests.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import cv2
import numpy as np

__all__ = ['add_arguments', 'run']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the benchmark."""
    parser.add_argument('--model', help='model file (default: the shipped one)')
    parser.add_argument('--batch', type=int, default=20, help='crops per batch (default 20)')
    parser.add_argument('--repeats', type=int, default=300,
                        help='timed calls per measurement (default 300)')
    parser.add_argument('--no-baseline', action='store_true',
                        help='skip training and timing the raw-intensity baseline pair')
    parser.add_argument('--cpu-time', action='store_true',
                        help='time with the thread CPU clock (for a loaded machine)')


def _crops(n_frames: int = 40):
    """Frames, boxes and crops of the tracker benchmark's synthetic sequence."""
    from workzone_ros.core.features import crop_sign
    from workzone_ros.tools.bench_tracker import make_sequence
    images, boxes = make_sequence(n_frames, 5, seed=0)
    crops = [crop_sign(img, b)[0] for img, bb in zip(images, boxes) for b in bb]
    return images, boxes, [c for c in crops if c is not None]


def _stats(ms: np.ndarray) -> dict:
    return {'p50': round(float(np.percentile(ms, 50)), 4),
            'p99': round(float(np.percentile(ms, 99)), 4),
            'mean': round(float(ms.mean()), 4)}


def _time(fn, args_list, clock) -> np.ndarray:
    fn(*args_list[0])                      # warm-up
    out = np.empty(len(args_list))
    for i, a in enumerate(args_list):
        t0 = clock()
        fn(*a)
        out[i] = (clock() - t0) * 1e3
    return out


def _measure(model, crops, images, boxes, batch: int, repeats: int, clock) -> dict:
    rng = np.random.default_rng(0)
    singles = [([crops[int(rng.integers(len(crops)))]],) for _ in range(repeats)]
    batches = [([crops[int(k)] for k in rng.integers(0, len(crops), batch)],)
               for _ in range(max(20, repeats // 5))]
    frames = []
    for _ in range(max(20, repeats // 5)):
        f = int(rng.integers(len(images)))
        bb = [boxes[f][int(k)] for k in rng.integers(0, len(boxes[f]), batch)]
        frames.append((images[f], bb))
    one = _time(model.classify, singles, clock)
    many = _time(model.classify, batches, clock)
    boxed = _time(model.classify_boxes, frames, clock)
    return {'one_crop_ms': _stats(one), f'batch_{batch}_ms': _stats(many),
            f'batch_{batch}_ms_per_crop_p50': round(float(np.percentile(many, 50)) / batch, 4),
            f'classify_boxes_{batch}_ms': _stats(boxed)}


def _debug_image(images, boxes, repeats: int, clock) -> dict:
    """ms per frame of the classifier node's debug image: the overlay and the message."""
    from workzone_ros import interfaces as I
    from workzone_ros.core.overlay import draw_debug
    from workzone_ros.nodes.conversions import numpy_to_image
    state = I.WorkzoneState(header=I.Header(stamp=I.Time(sec=0)), active=True,
                            phase='approaching', likelihood=0.9)
    frames = []
    for img, bb in zip(images, boxes):
        signs = [I.Sign(box=I.Box(*(float(v) for v in b)), class_key='road_work_ahead',
                        code='W20-1', category='workzone', score=0.9, track_id=k)
                 for k, b in enumerate(bb)]
        frames.append((img, signs))

    def one(img, signs):
        numpy_to_image(draw_debug(img, signs, (), state), 'bgr8')

    picks = [frames[k % len(frames)] for k in range(max(20, repeats // 5))]
    return {'frame': f'{images[0].shape[1]}x{images[0].shape[0]}',
            'signs': len(frames[0][1]), **_stats(_time(one, picks, clock))}


def _baseline_pair(progress=print):
    """Log-polar and raw-intensity SVMs trained on the same rendered crops."""
    from workzone_ros.core import classifier as clf_mod
    from workzone_ros.tools import train_classifier as tc
    specs = [s for s in tc.synth_specs([0], 0) if s[0].name in ('demo', 'paper_b')]
    data = tc.render_crops(specs, 20, progress=None)
    counts = data.counts()
    data = data.subset(i for i, lab in enumerate(data.labels) if counts[lab] >= 6)
    classes = sorted(set(data.labels))
    out = {}
    for kind in ('logpolar', 'raw'):
        t0 = time.monotonic()
        out[kind] = clf_mod.fit(data.crops, data.labels, classes, features=kind)
        progress(f'baseline pair: {kind} model trained on {len(data)} crops '
                 f'({time.monotonic() - t0:.0f} s)')
    return out, len(data)


def _single_thread() -> str:
    cv2.setNumThreads(1)
    for var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
        os.environ[var] = '1'
    try:
        from threadpoolctl import threadpool_limits
        threadpool_limits(1)
    except ImportError:
        pass
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        return 'pinned to one core'
    except (AttributeError, OSError):
        return 'not pinned'


def run(args: argparse.Namespace) -> dict:
    """Run the benchmark; returns its figures."""
    from workzone_ros.core import classifier as clf_mod
    from workzone_ros.resources import config_path
    core = _single_thread()
    clock = time.thread_time if getattr(args, 'cpu_time', False) else time.perf_counter
    path = Path(args.model) if args.model else config_path(clf_mod.DEFAULT_MODEL)
    model = clf_mod.load_model(path)
    images, boxes, crops = _crops()
    sides = [max(c.shape[:2]) for c in crops]
    out = {'cpu': core, 'opencv_threads': cv2.getNumThreads(),
           'clock': 'thread CPU time' if clock is time.thread_time else 'wall (perf_counter)',
           'crops': len(crops), 'crop_side_px': [int(min(sides)), int(max(sides))],
           'model': str(path), 'features': model.features, 'method': model.method,
           'classes': len(model.classes),
           'support_vectors': int(model.arrays.get('support_vectors', np.zeros((0,))).shape[0]),
           'shipped': _measure(model, crops, images, boxes, args.batch, args.repeats, clock),
           'debug_image_ms': _debug_image(images, boxes, args.repeats, clock)}
    if not args.no_baseline:
        pair, n = _baseline_pair()
        same = {k: _measure(m, crops, images, boxes, args.batch, args.repeats, clock)
                for k, m in pair.items()}
        key = f'batch_{args.batch}_ms'
        out['same_data_pair'] = {
            'training_crops': n, **same,
            'raw_over_logpolar_one_crop_p50': round(
                same['raw']['one_crop_ms']['p50'] / same['logpolar']['one_crop_ms']['p50'], 2),
            f'raw_over_logpolar_batch_{args.batch}_p50': round(
                same['raw'][key]['p50'] / same['logpolar'][key]['p50'], 2)}
    s = out['shipped']
    out['targets'] = {'one_crop_p50_ms': 1.0, f'batch_{args.batch}_p50_ms': 3.0}
    out['meets_targets'] = (s['one_crop_ms']['p50'] <= 1.0
                            and s[f'batch_{args.batch}_ms']['p50'] <= 3.0)
    return out


if __name__ == '__main__':
    p = argparse.ArgumentParser()
    add_arguments(p)
    print(run(p.parse_args()))
