"""``workzone-ros evaluate color``: Seo et al. Table I metrics on held-out bags; real clips.

Synthetic bags (``--bags``; never the ones the model was trained or tuned on): every camera
frame is run through the detector and matched to ``/groundtruth/signs``:

* a ground-truth work-zone sign is *eligible* when its box is at least ``--min-px`` on its
  shorter side and at least ``--min-visible`` visible (Lee et al. ignores signs under 30 px);
* a detection matches a sign when IoU > tau = 0.5 (one to one, best IoU first);
* for a matched pair, area precision = |o n g| / |o| and recall = |o n g| / |g| (Seo et al.);
  Table I macro-averages them over the test images (per image first, then over images),
  separately for warning (diamond) and regulatory (rectangular) signs;
* we also report what Table I leaves out: the share of eligible signs matched at all
  (detection rate) and the false detections per frame (a detection overlapping no sign of
  any kind, IoU < 0.1; drums, cones and orange vehicles are the usual ones).

Methods: ``learned`` (Seo et al.), ``rgb_lp`` (Balali and Golparvar-Fard), ``hsv`` (Cahail et al.),
each with LiDAR guidance off; ``learned`` also with it on.  LiDAR ROIs come from the real LiDAR
chain run offline on the bag's ``/lidar/points``, ``/odom`` and ``/camera/camera_info`` with the
``lidar_cluster`` and ``projector`` defaults (:func:`lidar_chain_rois`; no ground truth).

Pixel accuracy of the colour model: ``--pixels DIR`` (a held-out ``synth pixels`` folder).

Real clips (``--real DIR``, default ../shared/realdata/us_workzone_video), native frame
size: per clip, the share of frames in the sign's range where *the sign* is detected (an
orange detection with IoU >= 0.3 against hand-made approximate boxes, ``data/
real_sign_boxes.csv``, labelled by eye on keyframes and interpolated; also the looser
"contains the box centre" share), and orange detections per frame in the README's sign-free
range.  The clips and the labels are evaluation data only.  ``learned-nogeo`` is the learned
detector without the mounting-height test (``use_geometry`` false), which is calibrated
on our camera's height and horizon.

Usage::

    workzone-ros evaluate color --model config/models/color_orange.npz \
        --bags /tmp/bags/paper_c_7 ... --pixels /tmp/pix_eval --real --json out.json \
        --sheet out.png
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path
from typing import Any, Iterable, Optional, Sequence

import cv2
import numpy as np

from workzone_ros import interfaces
from workzone_ros.core import color_model as cm
from workzone_ros.core import detect as dt
from workzone_ros.core import signs as catalogue
from workzone_ros.interfaces import Box
from workzone_ros.resources import config_path
from workzone_ros.tools.clips import interpolate_keyframes
from workzone_ros.tools.outputs import print_json, write_contact_sheet

__all__ = ['main', 'match_frame', 'TableI', 'REAL_CLIPS', 'draw']

REPO = Path(__file__).resolve().parents[2]
REALDATA = REPO.parent / 'shared' / 'realdata'
#: Clip -> (sign frame range, sign-free frame range) from the realdata README (approximate,
#: read by eye there): the sign is visible in the first range, no sign in the second.
REAL_CLIPS = {'charlotte.mp4': ((0, 110), (120, 533)), 'denver.mp4': ((0, 165), (240, 454))}
#: Hand-made approximate sign boxes on keyframes of the real clips (evaluation only).
REAL_LABELS = Path(__file__).resolve().parent / 'data' / 'real_sign_boxes.csv'


def kind_of(class_key: str) -> str:
    """``warning`` (diamond) or ``regulatory`` (rectangle) for a work-zone class."""
    return 'warning' if catalogue.get(class_key).shape == 'diamond' else 'regulatory'


SIZE_BINS = ('<24', '24-32', '32-48', '48-80', '>=80')


def size_bin(px: float) -> str:
    """The ``by_size`` bin of a sign whose shorter side is ``px`` pixels."""
    for edge, name in zip((24, 32, 48, 80), SIZE_BINS):
        if px < edge:
            return name
    return SIZE_BINS[-1]


def match_frame(dets: Sequence[Box], gts: Sequence[Box], tau: float = 0.5
                ) -> list[tuple[int, int, float, float, float]]:
    """Greedy one-to-one matching, best IoU first; pairs (det, gt, iou, precision, recall)."""
    pairs = []
    for i, d in enumerate(dets):
        for j, g in enumerate(gts):
            iou, p, r = dt.box_metrics(d, g)
            if iou > tau:
                pairs.append((iou, i, j, p, r))
    pairs.sort(reverse=True)
    used_d, used_g, out = set(), set(), []
    for iou, i, j, p, r in pairs:
        if i in used_d or j in used_g:
            continue
        used_d.add(i)
        used_g.add(j)
        out.append((i, j, iou, p, r))
    return out


class TableI:
    """Accumulates Seo et al. Table I quantities per (group, kind)."""

    def __init__(self) -> None:
        # group -> kind -> list of per-image (mean precision, mean recall)
        self.images: dict = defaultdict(lambda: defaultdict(list))
        self.eligible: dict = defaultdict(lambda: defaultdict(int))
        self.matched: dict = defaultdict(lambda: defaultdict(int))
        self.false: dict = defaultdict(int)
        self.frames: dict = defaultdict(int)
        # kind -> size bin -> [eligible, matched, sum precision, sum recall] (per sign)
        self.sizes: dict = defaultdict(lambda: defaultdict(lambda: [0, 0, 0.0, 0.0]))

    def add(self, groups: Iterable[str], dets: Sequence[Box], gts: Sequence[tuple[Box, str]],
            all_signs: Sequence[Box], tau: float = 0.5) -> None:
        """One frame: detections, eligible (box, kind) ground truth, every sign box."""
        pairs = match_frame(dets, [g for g, _ in gts], tau)
        per_kind: dict = defaultdict(list)
        for _, j, _, p, r in pairs:
            per_kind[gts[j][1]].append((p, r))
        matched_d = {i for i, *_ in pairs}
        false = sum(1 for i, d in enumerate(dets) if i not in matched_d
                    and all(dt.box_metrics(d, s)[0] < 0.1 for s in all_signs))
        got = {j: (p, r) for _, j, _, p, r in pairs}
        for j, (g, k) in enumerate(gts):
            cell = self.sizes[k][size_bin(min(g.w, g.h))]
            cell[0] += 1
            if j in got:
                cell[1] += 1
                cell[2] += got[j][0]
                cell[3] += got[j][1]
        for group in groups:
            self.frames[group] += 1
            self.false[group] += false
            for _, k in gts:
                self.eligible[group][k] += 1
            for k, v in per_kind.items():
                self.matched[group][k] += len(v)
                self.images[group][k].append(tuple(np.mean(v, axis=0)))

    def summary(self) -> dict:
        """group -> {warning: {...}, regulatory: {...}, false_per_frame, frames}; and
        ``by_size``: kind -> size bin -> eligible, found share, mean area precision and
        recall per matched sign."""
        out = {}
        for group in sorted(self.frames):
            row: dict[str, Any] = {'frames': self.frames[group],
                                   'false_per_frame': self.false[group] / self.frames[group]}
            for k in ('warning', 'regulatory'):
                ims = self.images[group][k]
                row[k] = {
                    'precision': float(np.mean([p for p, _ in ims])) if ims else None,
                    'recall': float(np.mean([r for _, r in ims])) if ims else None,
                    'images': len(ims), 'eligible': self.eligible[group][k],
                    'detection_rate': (self.matched[group][k] / self.eligible[group][k]
                                       if self.eligible[group][k] else None)}
            out[group] = row
        if out:
            # per sign (not per image) by the sign's shorter side: where boxes go wrong
            out['by_size'] = {k: {b: {'eligible': c[0], 'found': c[1] / c[0] if c[0] else None,
                                      'precision': c[2] / c[1] if c[1] else None,
                                      'recall': c[3] / c[1] if c[1] else None}
                                  for b, c in sorted(bins.items(), key=lambda kv: SIZE_BINS.index(
                                      kv[0]))}
                              for k, bins in self.sizes.items()}
        return out


def draw(img: np.ndarray, dets, gts=(), rois=(), label: str = '') -> np.ndarray:
    """An overlay: ground truth green, detections red (lidar-supported magenta), ROIs cyan."""
    out = img.copy()
    for r in rois:
        b = r.box
        cv2.rectangle(out, (int(b.x), int(b.y)), (int(b.x2), int(b.y2)), (255, 255, 0), 1)
    for g in gts:
        cv2.rectangle(out, (int(g.x), int(g.y)), (int(g.x2), int(g.y2)), (0, 255, 0), 1)
    for d in dets:
        b = d.box
        col = (255, 0, 255) if 'lidar' in d.sources else (0, 0, 255)
        cv2.rectangle(out, (int(b.x), int(b.y)), (int(b.x2), int(b.y2)), col, 2)
        cv2.putText(out, f'{d.color[0]}{d.kind[0]} {d.confidence:.2f}',
                    (int(b.x), max(10, int(b.y) - 3)), cv2.FONT_HERSHEY_SIMPLEX, 0.4, col, 1)
    if label:
        cv2.putText(out, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 2)
    return out


# --- synthetic bags -----------------------------------------------------------------------

def _image(msg) -> np.ndarray:
    if hasattr(msg, 'format'):                 # CompressedImage
        return cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
    data = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.height, msg.step)
    img = data[:, : msg.width * 3].reshape(msg.height, msg.width, 3)
    return cv2.cvtColor(img, cv2.COLOR_RGB2BGR) if msg.encoding == 'rgb8' else img


def _stamp(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def lidar_chain_rois(bag: str, config: Optional[str] = None) -> dict:
    """ROIs per image stamp from the real LiDAR chain, as the live graph makes them.

    ``lidar_cluster`` (core.lidar_clustering: ``cluster_cloud`` + ``CandidateTracker``
    persistence with odometry at scan stamp + 50 ms) on ``/lidar/points``, then the
    ``projector`` (core.sync.NearestSync with its defaults: slop 0.1 s, max_wait 0.15 s,
    forward time; core.projection.candidates_to_rois with ego-motion compensation from
    ``/odom`` and the ``/camera/camera_info`` intrinsics).  Candidates arrive 110 ms after
    their scan stamp, images 5 ms after theirs (``eval_lidar sync``'s defaults).  The
    parameters are the ``lidar_cluster`` / ``projector`` sections of ``config/workzone.yaml``.
    No ground truth is used.

    Returns:
        ``{image_stamp_ns: [Roi, ...]}`` for the images the projector paired.
    """
    import yaml

    from workzone_ros.core import lidar_clustering as lc
    from workzone_ros.core import projection as pj
    from workzone_ros.core.lidar_rois import size_rois
    from workzone_ros.tools.eval_lidar import _load_bag, _Odom, pair_stream
    data = yaml.safe_load(Path(config or config_path('workzone.yaml')).read_text()) or {}
    ccfg = (data.get('lidar_cluster') or {}).get('ros__parameters', {}) or {}
    pcfg = (data.get('projector') or {}).get('ros__parameters', {}) or {}
    params = lc.ClusterParams.from_mapping(ccfg)
    tracker = lc.CandidateTracker(int(ccfg.get('persistence_k', 2)),
                                  int(ccfg.get('persistence_n', 3)))
    frames: list = []
    scans, _, odom, info = _load_bag(Path(bag), frames)
    if info is None:
        return {}
    camera = pj.CameraModel(int(info.width), int(info.height),
                            np.asarray(info.k, float).reshape(3, 3), np.asarray(info.d, float),
                            info.distortion_model or 'plumb_bob')
    l2c = pj.extrinsics_from_list(pcfg.get('lidar_to_camera', [
        0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, -0.5, 1.0, 0.0, 0.0, -0.6, 0, 0, 0, 1]))
    lb = list(pcfg.get('lidar_in_base', [1.0, 0.0, 1.95, 0.0, 0.0, 0.0])) + [0.0] * 6
    od = _Odom(odom, pj.euler_matrix(tuple(lb[:3]), tuple(lb[3:6])))
    rp = pj.RoiParams(margin=pcfg.get('crop_margin', 1.5),
                      min_radius=pcfg.get('crop_min_radius', 0.6),
                      pad_px=pcfg.get('crop_pad_px', 6.0), pad_m=pcfg.get('crop_pad_m', 0.3))
    events = []
    for stamp, pts in scans:
        res = lc.cluster_cloud(pts, params)
        cands = tracker.update(res.candidates, od.lidar(stamp + 50_000_000))
        events.append((stamp + 110_000_000, 0, 'cands', stamp, lc.candidates_to_array(cands)))
    for stamp, _ in frames:
        events.append((stamp + 5_000_000, 1, 'image', stamp, None))
    events.sort(key=lambda e: (e[0], e[1], e[3]))
    pairs = pair_stream([(a, k, t, p) for a, _, k, t, p in events], 'nearest',
                        int(float(pcfg.get('slop', 0.1)) * 1e9), queue_size=5,
                        age_penalty=0.1, period_ns=int(1e9 / rp.lidar_rate_hz),
                        max_wait_ns=int(float(pcfg.get('max_wait', 0.15)) * 1e9),
                        time_offset_ns=pj.forward_time_offset(rp))
    out = {}
    for t_img, (t_set, arr, _) in pairs.items():
        rois, _ = pj.candidates_to_rois(arr, t_set, t_img, camera, l2c, od.lidar, rp)
        out[t_img] = size_rois(rois, arr, camera)
    return out


def evaluate_bags(bags: Sequence[str], detectors: dict, args, tiles: list) -> dict:
    """Table I per method and weather over ``bags``."""
    from workzone_ros.bagio import read_messages
    tables = {name: TableI() for name in detectors}
    timing = defaultdict(list)
    for bag in bags:
        gts: dict[int, interfaces.GtSigns] = {}
        for topic, _, msg in read_messages(bag, ['/groundtruth/signs']):
            g = interfaces.decode(msg.data, interfaces.GtSigns)
            gts[g.header.stamp.to_ns()] = g
        chain = lidar_chain_rois(bag) if any(v[1] for v in detectors.values()) else {}
        for det, _ in detectors.values():
            det.reset()            # a new clip
        n = 0
        topics = ['/camera/image_raw', '/camera/image_raw/compressed']
        for topic, _, msg in read_messages(bag, topics):
            ns = _stamp(msg.header)
            g = gts.get(ns)
            if g is None:
                continue
            n += 1
            if args.every > 1 and n % args.every:
                continue
            img = _image(msg)
            wz = [s for s in g.signs if s.category == 'workzone']
            elig = [(s.box, kind_of(s.class_key)) for s in wz
                    if min(s.box.w, s.box.h) >= args.min_px
                    and s.visible_fraction >= args.min_visible]
            all_boxes = [s.box for s in g.signs]
            # ineligible work-zone signs are "don't care": detections on them are not false
            rois = chain.get(ns, [])
            groups = ('all', g.weather or 'unknown')
            for name, (det, lidar) in detectors.items():
                t0 = time.perf_counter()
                dets = [d for d in det.detect(img, rois if lidar else ())
                        if d.color == 'orange']
                timing[name].append(time.perf_counter() - t0)
                tables[name].add(groups, [d.box for d in dets], elig, all_boxes)
                if name == args.sheet_method and tiles is not None and elig and \
                        len(tiles) < args.sheet_n and n % args.sheet_every == 0:
                    tiles.append(draw(img, dets, [b for b, _ in elig],
                                      rois if lidar else (),
                                      f'{Path(bag).name} {g.weather} #{n}'))
        print(f'{bag}: {n} frames', file=sys.stderr, flush=True)
    out = {name: t.summary() for name, t in tables.items()}
    for name, ts in timing.items():
        out[name]['ms_per_frame_p50'] = float(np.median(ts) * 1e3) if ts else None
    return out


# --- pixels -------------------------------------------------------------------------------

def evaluate_pixels(model: cm.ColorModel, folder: str, threshold: float) -> dict:
    """Pixel accuracy of P(x | sign) >= threshold against held-out masks, per weather."""
    import csv

    from workzone_ros.tools.train_color import pixel_metrics
    root = Path(folder)
    by_weather = defaultdict(list)
    with open(root / 'index.csv') as fh:
        for row in csv.DictReader(fh):
            by_weather[row.get('weather', 'unknown')].append((root / row['image'],
                                                              root / row['mask']))
    lut = model.lut('orange')
    v = model.v_min[model.index('orange')]
    gw, sn, wb = model.gray_world, model.sat_norm, model.white_balance or 'grey_world'
    out = {w: pixel_metrics(lut, v, pairs, threshold, gw, sn, wb)
           for w, pairs in by_weather.items()}
    out['all'] = pixel_metrics(lut, v, [p for ps in by_weather.values() for p in ps],
                               threshold, gw, sn, wb)
    return out


# --- real clips ---------------------------------------------------------------------------

def load_sign_labels(path: Path = REAL_LABELS) -> dict:
    """clip -> {frame: [(box, visible), ...]}: every labelled sign of the hand-made keyframe
    CSV, each linearly interpolated between its own keyframes (column ``sign``, 1 when the
    file has none; a sign's box is never interpolated towards another sign's).  Rows of
    class ``background`` (a ``make-crops`` labels file) are left out.

    The boxes are approximate (labelled by eye) and for evaluation only.
    """
    import csv
    keys: dict = defaultdict(list)
    with open(path) as fh:
        for row in csv.DictReader(line for line in fh if not line.startswith('#')):
            if (row.get('class_key') or '').strip() == 'background':
                continue            # a make-crops labels file also holds what is no sign
            keys[(row['clip'], int(row.get('sign') or 1))].append(
                (int(row['frame']), *(float(row[k]) for k in 'xywh'), int(row['visible'])))
    out: dict = defaultdict(lambda: defaultdict(list))
    for (clip, _), ks in sorted(keys.items()):
        for f, box, vis in interpolate_keyframes(ks):
            out[clip][f].append((Box(*box), vis))
    return {clip: dict(frames) for clip, frames in out.items()}


def load_real_labels(path: Path = REAL_LABELS) -> dict:
    """clip -> {frame: (box, visible)}: :func:`load_sign_labels` of a file with one sign in
    any frame (ValueError naming the clip and frame otherwise)."""
    out = {}
    for clip, frames in load_sign_labels(path).items():
        for f, signs in frames.items():
            if len(signs) > 1:
                raise ValueError(f'{path}: {clip} frame {f} has {len(signs)} labelled signs; '
                                 'use load_sign_labels')
        out[clip] = {f: signs[0] for f, signs in frames.items()}
    return out


def evaluate_real(folder: Path, detectors: dict, args, tiles: list) -> dict:
    """Per clip: share of labelled sign frames where the sign is detected; false detections.

    A labelled frame counts as detected when an orange detection has IoU >= 0.3 with the
    hand-made box (``detected_share``); ``centre_share`` uses the looser rule "a detection
    contains the labelled box centre".  False detections: every orange detection in the
    README's sign-free range (``false_per_frame``), and detections matching no label in the
    sign range (``other_per_frame_in_range``).  Frames are used at their native size.
    """
    labels = load_real_labels()
    out = {}
    for clip, (_, (f0, f1)) in REAL_CLIPS.items():
        path = folder / clip
        if not path.exists():
            out[clip] = {'skipped': f'{path} not found'}
            continue
        lab = labels.get(clip, {})
        for det, _ in detectors.values():
            det.reset()
        cap = cv2.VideoCapture(str(path))
        res = {name: defaultdict(int) for name in detectors}
        k = -1
        while True:
            ok, img = cap.read()
            if not ok:
                break
            k += 1
            in_sign = k in lab
            free = f0 <= k <= f1
            if not (in_sign or free):
                continue
            for name, (det, _) in detectors.items():
                dets = [d for d in det.detect(img) if d.color == 'orange']
                r = res[name]
                if in_sign:
                    box, vis = lab[k]
                    hit = [d for d in dets if d.box.iou(box) >= 0.3]
                    cx, cy = box.x + box.w / 2, box.y + box.h / 2
                    cen = [d for d in dets if d.box.x <= cx <= d.box.x2
                           and d.box.y <= cy <= d.box.y2]
                    key = 'visible' if vis else 'occluded'
                    r[f'{key}_frames'] += 1
                    r[f'{key}_detected'] += bool(hit)
                    r[f'{key}_centre'] += bool(cen)
                    r['in_range_other'] += sum(1 for d in dets if d.box.iou(box) < 0.1)
                else:
                    r['free_frames'] += 1
                    r['false_detections'] += len(dets)
                if name == args.sheet_method and tiles is not None and k % 24 == 5:
                    gts = [lab[k][0]] if in_sign else []
                    tiles.append(draw(img, dets, gts, label=f'{clip} #{k}'))
        cap.release()
        for name, r in res.items():
            r = dict(r)
            for key in ('visible', 'occluded'):
                n = r.get(f'{key}_frames', 0)
                r[f'{key}_detected_share'] = r.get(f'{key}_detected', 0) / n if n else None
                r[f'{key}_centre_share'] = r.get(f'{key}_centre', 0) / n if n else None
            n_in = r.get('visible_frames', 0) + r.get('occluded_frames', 0)
            r['other_per_frame_in_range'] = r.get('in_range_other', 0) / max(n_in, 1)
            r['false_per_frame'] = r.get('false_detections', 0) / max(r.get('free_frames', 0), 1)
            res[name] = r
        out[clip] = res
    return out


def build_detectors(model: cm.ColorModel, methods: Sequence[str], lidar: bool,
                    threshold: float) -> dict:
    """name -> (ColorDetector, uses_lidar) for the requested methods."""
    lp = None
    if 'rgb_lp_thresholds' in model.extras:
        lp = dt.RgbLpModel(model.extras['rgb_lp_thresholds'])
    out = {}
    for m in methods:
        if m == 'rgb_lp' and lp is None:
            print('rgb_lp: the model file has no RGB thresholds of Balali and Golparvar-Fard '
                  '(train with --rgb-lp); skipped', file=sys.stderr)
            continue
        if m == 'learned':
            cfg = dt.DetectorConfig(colors=('orange',), threshold=threshold)
        else:        # the seeds' baselines: no prior (they have none), full resolution
            cfg = dt.DetectorConfig(method=m, colors=('orange',), use_prior=False, scale=1)
        out[m] = (dt.ColorDetector(model, cfg, lp), False)
        if m == 'learned' and lidar:
            out['learned+lidar'] = (dt.ColorDetector(model, cfg, lp), True)
    return out


def main(argv: Optional[list[str]] = None) -> int:
    """Run the evaluation; prints JSON, returns the exit status."""
    p = argparse.ArgumentParser(prog='workzone-ros evaluate color', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--model', default=str(config_path('models/color_orange.npz')))
    p.add_argument('--bags', nargs='*', default=[], help='held-out synthetic bags')
    p.add_argument('--pixels', help='held-out `synth pixels` folder (pixel accuracy)')
    p.add_argument('--real', nargs='?', const=str(REALDATA / 'us_workzone_video'),
                   help='real clips folder (default ../shared/realdata/us_workzone_video)')
    p.add_argument('--methods', nargs='+', default=['learned', 'rgb_lp', 'hsv'],
                   choices=dt.METHODS)
    p.add_argument('--no-lidar', action='store_true', help='skip the LiDAR-guided run')
    p.add_argument('--threshold', type=float, default=0.5, help='posterior threshold tau')
    p.add_argument('--min-px', type=float, default=16.0, help='eligible GT: shorter side')
    p.add_argument('--min-visible', type=float, default=0.9, help='eligible GT: visible share')
    p.add_argument('--every', type=int, default=1, help='use every n-th frame')
    p.add_argument('--json', help='write the report here')
    p.add_argument('--sheet', help='PNG contact sheet of synthetic overlays')
    p.add_argument('--real-sheet', help='PNG contact sheet of real-clip overlays')
    p.add_argument('--sheet-method', default='learned+lidar')
    p.add_argument('--sheet-n', type=int, default=12)
    p.add_argument('--sheet-every', type=int, default=25)
    args = p.parse_args(argv)
    cv2.setNumThreads(1)
    try:
        model = cm.load_model(args.model)
    except cm.ModelError as exc:
        print(f'workzone-ros evaluate color: {exc}', file=sys.stderr)
        return 2
    report: dict[str, Any] = {'model': args.model, 'model_metadata': dict(model.metadata),
                              'tau': 0.5, 'min_px': args.min_px,
                              'min_visible': args.min_visible, 'threshold': args.threshold,
                              'rois': 'real LiDAR chain: core.lidar_clustering + persistence, '
                                      'projector nearest sync + core.projection (no GT)'}
    report['model_metadata'].pop('metrics', None)
    detectors = build_detectors(model, args.methods, not args.no_lidar, args.threshold)
    if args.bags:
        tiles: list = []
        report['bags'] = list(args.bags)
        report['synthetic'] = evaluate_bags(args.bags, detectors, args, tiles)
        if args.sheet:
            write_contact_sheet(tiles, args.sheet, width=480)
    if args.pixels:
        report['pixels'] = evaluate_pixels(model, args.pixels, args.threshold)
    if args.real:
        tiles = []
        real_dets = {k: v for k, v in detectors.items() if not v[1]}
        if 'learned' in real_dets:
            # the mounting-height test is tied to the training camera's height and horizon;
            # on another camera it is the part to recalibrate, so report both
            real_dets['learned-nogeo'] = (real_dets['learned'][0].with_config(
                use_geometry=False), False)
        args_real = argparse.Namespace(**vars(args))
        args_real.sheet_method = 'learned'
        report['real'] = evaluate_real(Path(args.real), real_dets, args_real, tiles)
        if args.real_sheet:
            write_contact_sheet(tiles, args.real_sheet, width=480)
    print_json(report, args.json, default=float)
    return 0


if __name__ == '__main__':
    sys.exit(main())
