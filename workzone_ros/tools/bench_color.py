"""``workzone-ros bench color``: the colour detector per 640x480 frame, and LUT vs boosting.

With ``--real [DIR]`` also real dashcam frames (every 10th frame of each clip in ``DIR``, at
their native size): the rule-based detector, the recall-first proposals
(:mod:`workzone_ros.core.proposals`) and both (``detector+proposals``: what the default
``color_detector`` does with a frame of a camera other than the colour model's, as these
are: the detector measured lean beside the proposals; ``full_detector+proposals`` with
``lean_beside_proposals: false``), p50 / p99 / max wall and CPU milliseconds per frame,
beside the renders' figures of the same run (key ``real``).

Figures (one core: ``cv2.setNumThreads(1)``; run it on a quiet machine):

* ``frame_ms``: the main path per frame (resize, HSV, table lookup, posterior threshold,
  morphology, connected components, filters, refinement, NMS) for the orange model alone and
  for orange + red + yellow, p50 / p99 over ``--frames`` frames, and each bench frame's median
  (``per_frame_p50``; ``detections_by_frame``: the orange detections on each).  The frames
  are synthetic renders when the simulator is importable (a sign in view), else a drawn
  test frame.
* ``cpu_ms``: the same frames' CPU time on the benchmark's thread (``time.thread_time``).
  When it is as high as the wall clock, a slow p99 is the core's own speed (a virtual
  machine's CPU time varies by half from run to run), not other processes preempting it.
* ``per_pixel_ns``: P(x | sign) per pixel by the boosted model (scikit-learn
  ``predict_proba`` over (hue, saturation)) vs the lookup table, and their ratio.  The
  boosted model is fitted here on the frame (H = ``--estimators`` stumps) so the figure does
  not depend on a model file.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from workzone_ros.core import color_model as cm
from workzone_ros.core import detect as dt
from workzone_ros.resources import config_path

__all__ = ['add_arguments', 'run']

MODEL = config_path('models/color_orange.npz')
PROPOSALS = config_path('models/color_proposals.npz')
REAL = Path(__file__).resolve().parents[2].parent / 'shared' / 'realdata' / 'us_workzone_video'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``workzone-ros bench color``."""
    parser.add_argument('--model', default=str(MODEL), help='colour model (.npz)')
    parser.add_argument('--frames', type=int, default=300, help='timed frames (default 300)')
    parser.add_argument('--estimators', type=int, default=40, help='stumps for predict_proba')
    parser.add_argument('--scale', type=int, default=2, help='mask downscale (default 2)')
    parser.add_argument('--real', nargs='?', const=str(REAL), default=None, metavar='DIR',
                        help='also time real dashcam frames (every 10th frame of the clips in '
                             f'DIR, default {REAL}): the rule-based detector, the recall-first '
                             'proposals and both, beside the renders')
    parser.add_argument('--proposals-model', default=str(PROPOSALS),
                        help='colour model with the proposal ranker')


def _frames(n: int = 8) -> list[np.ndarray]:
    """A few 640x480 frames with signs: simulator renders if available, else drawn."""
    try:
        from workzone_ros.sim.scenario import load_scenario
        from workzone_ros.sim.writer import SynthOptions, _World
        world = _World(load_scenario('demo', 3), SynthOptions(seed=3, workers=0))
        out = []
        for k in np.linspace(150, 450, n).astype(int):
            t = k / 15.0
            out.append(world.renderer.render(t, world.ego.base_pose(t), int(k)).image)
        return out
    except Exception:  # noqa: BLE001 - the simulator is optional here
        rng = np.random.default_rng(0)
        img = np.empty((480, 640, 3), np.uint8)
        img[:240] = (205, 175, 150)
        img[240:] = (85, 88, 84)
        img = cv2.add(img, rng.integers(0, 20, img.shape, dtype=np.uint8))
        pts = np.array([[420, 110], [460, 150], [420, 190], [380, 150]], np.int32)
        cv2.fillConvexPoly(img, pts, (0, 110, 245))
        return [img]


def _time(fn, frames, n) -> tuple[np.ndarray, np.ndarray]:
    """Wall-clock and this thread's CPU milliseconds of ``fn`` on each of ``n`` frames
    (``frames`` in turn, after one untimed pass over them)."""
    for f in frames:
        fn(f)
    ts, cs = [], []
    for i in range(n):
        f = frames[i % len(frames)]
        c0, t0 = time.thread_time(), time.perf_counter()
        fn(f)
        ts.append(time.perf_counter() - t0)
        cs.append(time.thread_time() - c0)
    return np.array(ts) * 1e3, np.array(cs) * 1e3


def _real_frames(folder: Path, every: int = 10) -> list[np.ndarray]:
    """Every ``every``-th frame of each clip of ``folder`` at its native size."""
    out = []
    for video in sorted(folder.glob('*.mp4')):
        cap = cv2.VideoCapture(str(video))
        k = 0
        while True:
            ok, img = cap.read()
            if not ok:
                break
            if k % every == 0:
                out.append(img)
            k += 1
        cap.release()
    return out


def _stats(ms: np.ndarray) -> dict:
    return {'p50': float(np.percentile(ms, 50)), 'p99': float(np.percentile(ms, 99)),
            'max': float(ms.max())}


def run_real(args: argparse.Namespace, model) -> dict:
    """The real-frame figures of ``--real`` (one pass over every chosen frame)."""
    from workzone_ros.core.proposals import ProposalConfig, SignProposer
    folder = Path(args.real)
    frames = _real_frames(folder)
    if not frames:
        return {'skipped': f'no readable clips in {folder}'}
    det = dt.ColorDetector(model, dt.DetectorConfig(colors=('orange',), scale=args.scale))
    prop = SignProposer(cm.load_model(args.proposals_model), ProposalConfig())
    out: dict = {'folder': str(folder), 'frames': len(frames),
                 'frame': f'{frames[0].shape[1]}x{frames[0].shape[0]}'}
    for label, fn in (('detector', det.detect),
                      # as the node measures a frame when it has fallen behind its camera
                      ('detector_lean', lambda f: det.detect(f, lean=True)),
                      ('proposals', prop.propose),
                      # the default graph on another camera's frames: the detector
                      # measures lean beside the proposals, which reuse its shrunk,
                      # white-balanced frame
                      ('detector+proposals',
                       lambda f: (det.detect(f, lean=True),
                                  prop.propose(f, prop.view_of(det)))),
                      ('full_detector+proposals',
                       lambda f: (det.detect(f), prop.propose(f, prop.view_of(det))))):
        ms, cpu = _time(fn, frames, len(frames))
        out[f'frame_ms_{label}'] = _stats(ms)
        out[f'cpu_ms_{label}'] = _stats(cpu)
    return out


def run(args: argparse.Namespace) -> dict:
    """Run the benchmark; returns the figures."""
    cv2.setNumThreads(1)
    try:
        model = cm.load_model(args.model)
        source = args.model
    except cm.ModelError:
        model, source = cm.default_model(), 'Cahail et al. HSV ranges (no model file)'
    frames = _frames()
    out: dict = {'model': source, 'frame': '640x480', 'scale': args.scale,
                 'threads': cv2.getNumThreads()}
    for label, colors in (('orange', ('orange',)), ('orange+red+yellow',
                                                     ('orange', 'red', 'yellow'))):
        det = dt.ColorDetector(model, dt.DetectorConfig(colors=colors, scale=args.scale))
        ms, cpu = _time(det.detect, frames, args.frames)
        out[f'frame_ms_{label}'] = {'p50': float(np.percentile(ms, 50)),
                                    'p99': float(np.percentile(ms, 99)),
                                    # each bench frame's median (a frame with a sign costs
                                    # its refinement; the p99 is those frames' tail)
                                    'per_frame_p50': [float(np.median(ms[i::len(frames)]))
                                                      for i in range(len(frames))]}
        out[f'cpu_ms_{label}'] = {'p50': float(np.percentile(cpu, 50)),
                                  'p99': float(np.percentile(cpu, 99))}
    if getattr(args, 'real', None):
        out['real'] = run_real(args, model)
    det = dt.ColorDetector(model, dt.DetectorConfig(colors=('orange',), scale=args.scale))
    counts = [len(det.detect(f)) for f in frames]
    out['detections_per_frame'] = float(np.mean(counts))
    out['detections_by_frame'] = counts
    # per-pixel cost: boosted model (predict_proba) vs the table
    img = frames[0]
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    mask = (model.likelihood(img, 'orange') >= 0.5)
    if mask.sum() < 10 or (~mask).sum() < 10:
        mask = hsv[..., 1] > 150
    pos, neg = cm.histogram_from_pixels(hsv, mask)
    clf = cm.fit_boosted(pos, neg, args.estimators)
    X = hsv[..., :2].reshape(-1, 2).astype(np.float64)
    t0 = time.perf_counter()
    clf.predict_proba(X)
    t_boost = time.perf_counter() - t0
    lut = cm.boosted_lut(clf)
    lut_u8 = np.round(lut * 254).astype(np.uint8).reshape(-1)
    idx = cv2.merge([hsv[..., 1], hsv[..., 0]]).view(np.uint16)[..., 0]
    reps = 50
    t0 = time.perf_counter()
    for _ in range(reps):
        np.take(lut_u8, idx)
    t_lut = (time.perf_counter() - t0) / reps
    n = X.shape[0]
    out['per_pixel_ns'] = {'boosted_predict_proba': t_boost / n * 1e9,
                           'lut': t_lut / n * 1e9,
                           'ratio': t_boost / max(t_lut, 1e-12),
                           'stumps': int(len(clf.estimators_))}
    return out
