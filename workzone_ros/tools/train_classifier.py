"""``workzone-ros train classifier``: the work-zone sign classifier (Seo et al., section III.B).

Sources (any mix):

* ``--synth N``: crops rendered by our simulator (``workzone_ros.sim.writer.export_crops``,
  detector-like box jitter of 10-20 %), at most N per class and scenario, from every library
  scenario for each ``--synth-seeds`` seed plus ``--synth-random R`` random scenarios per
  seed whose weathers cycle through all four presets.  Renders are cached under ``--cache``
  (one folder per scenario and seed) and reused.
* ``--data DIR``: a folder per class, ``DIR/<class_key>/*.png|jpg`` (class keys of
  ``workzone_ros.core.signs``; an unknown folder name is an error).  When ``DIR/index.csv``
  has ``path`` and ``clip`` columns (the hand-labelled real crops in ``test/data/real_crops``
  do), ``--exclude-clip NAME`` leaves that clip's crops out, so a clip that is reported is
  never trained on.

Classes (``--classes``): ``workzone`` = ``signs.CLASSIFIER_KEYS`` (the work-zone signs and
``background``; crops of general signs become ``background``, i.e. rejected), ``all`` =
those plus the general signs (stop, yield, warning diamond, ...) as classes of their own, or
``present`` = whatever classes the data has (a user's own subset).

Then the features (``--features``; ``logpolar`` is the seed's pure pipeline), PCA to
``--components`` (10) and the ``--method`` (``svm``: RBF, C and gamma by cross-validation,
Platt probabilities; ``lda`` and ``knn`` are the seed's baselines) are fitted and the model
is written (``-o``, default ``config/models/sign_classifier.npz``) with its training sources
in the metadata.

Example (the shipped model, docs/classifier.md)::

    workzone-ros train classifier --synth 20 --synth-seeds 0 1 2 3 4 5 --synth-random 4 \
        --data test/data/real_crops
"""
from __future__ import annotations

import argparse
import csv
import os
import shutil
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterable, Optional, Sequence

import cv2
import numpy as np

from workzone_ros.core import classifier as clf_mod
from workzone_ros.core import features as ft
from workzone_ros.core import signs

__all__ = ['DataError', 'CropSet', 'render_crops', 'load_folder', 'class_list', 'map_labels',
           'synth_specs', 'main']

DEFAULT_CACHE = Path('/tmp/workzone_ros_crops')
#: Features of the shipped model (docs/classifier.md has the measurements behind the choice).
DEFAULT_FEATURES = 'logpolar-centred+color+mirror'
IMAGE_EXT = ('.png', '.jpg', '.jpeg', '.bmp')


class DataError(ValueError):
    """A training source that cannot be used (missing folder, unknown class, ...)."""


@dataclass
class CropSet:
    """Crops with their labels and provenance, one entry per crop.

    ``group`` names the physical object a crop shows (a sign instance of a scenario, a
    background frame, a real clip's object), so splits never put views of one object on
    both sides; ``clip`` is the real video a crop came from (``''`` for renders);
    ``side`` is the shorter side of the object's box in the frame (px, NaN if unknown).
    """

    crops: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    groups: list = field(default_factory=list)
    weather: list = field(default_factory=list)
    source: list = field(default_factory=list)
    clip: list = field(default_factory=list)
    side: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.crops)

    def subset(self, idx: Iterable[int]) -> 'CropSet':
        """The entries at ``idx``."""
        idx = list(idx)
        return CropSet(*[[getattr(self, f)[i] for i in idx] for f in _FIELDS])

    def extend(self, other: 'CropSet') -> 'CropSet':
        """Append ``other``'s entries; returns self."""
        for f in _FIELDS:
            getattr(self, f).extend(getattr(other, f))
        return self

    def counts(self) -> dict[str, int]:
        """Crops per label."""
        keys, n = np.unique(np.array(self.labels, dtype=str), return_counts=True)
        return {str(k): int(v) for k, v in zip(keys, n)}


_FIELDS = ('crops', 'labels', 'groups', 'weather', 'source', 'clip', 'side')


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


# --- renders -------------------------------------------------------------------------------

def synth_specs(seeds: Sequence[int], n_random: int, library: bool = True) -> list:
    """(spec, seed) pairs: every library scenario per seed plus ``n_random`` random ones.

    Random scenario ``r`` of seed ``s`` is ``random`` drawn from ``1000 * s + r + 1`` with
    its weather set to ``WEATHERS[r % 4]``, so every weather is rendered.
    """
    from workzone_ros.sim.scenario import WEATHERS, list_scenarios, load_scenario
    names = [n for n in list_scenarios() if n != 'random'] if library else []
    out = []
    for s in seeds:
        out += [(load_scenario(n, s), s) for n in names]
        for r in range(n_random):
            spec = load_scenario('random', 1000 * s + r + 1)
            out.append((replace(spec, weather=WEATHERS[r % len(WEATHERS)]), s))
    return out


def _render_one(spec, seed: int, per_class: int, size: int, cache: Path) -> Path:
    """Render (or reuse) one scenario's crops; returns their folder."""
    from workzone_ros.sim.writer import export_crops
    out = cache / f'{spec.name}_{spec.weather}_s{seed}_n{per_class}_z{size}'
    if not (out / 'index.csv').is_file():
        tmp = out.with_name(f'{out.name}.part{os.getpid()}')
        shutil.rmtree(tmp, ignore_errors=True)
        export_crops(tmp, [spec], seed=seed, per_class=per_class, size=size, progress=None)
        try:
            tmp.rename(out)
        except OSError:                       # another process rendered it meanwhile
            shutil.rmtree(tmp, ignore_errors=True)
    return out


def _read(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise DataError(f'unreadable image {path}')
    return img


def _visible_part(patch: np.ndarray, row: dict, frame_size: tuple[int, int],
                  min_visible: float = 0.5) -> Optional[np.ndarray]:
    """The part of an exported crop that was inside the frame (as ``crop_sign`` cuts it).

    ``export_crops`` pads a crop box that leaves the frame by mirroring the image, which
    shows a mirrored sign (a W4-2R as a W4-2L); at run time such a box is clipped to the
    frame instead.  Returns ``None`` when less than ``min_visible`` of the box was inside.
    """
    x, y, w, h = (float(row[k]) for k in ('crop_x', 'crop_y', 'crop_w', 'crop_h'))
    W, H = frame_size
    x0, y0, x1, y1 = max(x, 0.0), max(y, 0.0), min(x + w, W), min(y + h, H)
    if x1 <= x0 or y1 <= y0 or (x1 - x0) * (y1 - y0) < min_visible * w * h:
        return None
    if (x0, y0, x1, y1) == (x, y, x + w, y + h):
        return patch
    ph, pw = patch.shape[:2]
    c0, c1 = int(round((x0 - x) / w * pw)), int(round((x1 - x) / w * pw))
    r0, r1 = int(round((y0 - y) / h * ph)), int(round((y1 - y) / h * ph))
    return patch[r0:r1, c0:c1] if c1 - c0 >= 4 and r1 - r0 >= 4 else None


def render_crops(specs: Sequence, per_class: int, size: int = 64,
                 cache: Path = DEFAULT_CACHE,
                 progress: Optional[Callable[[str], None]] = _say) -> CropSet:
    """Rendered crops of every (spec, seed), read back with their provenance.

    Crop boxes that left the frame are cut to their visible part (:func:`_visible_part`).
    """
    from workzone_ros.sim.world import DEFAULT_CAMERA
    frame_size = (DEFAULT_CAMERA.width, DEFAULT_CAMERA.height)
    out = CropSet()
    t0 = time.monotonic()
    for n, (spec, seed) in enumerate(specs, 1):
        folder = _render_one(spec, seed, per_class, size, Path(cache))
        with open(folder / 'index.csv', newline='') as fh:
            rows = list(csv.DictReader(fh))
        for r in rows:
            obj = r['object_id']
            crop = _visible_part(_read(folder / r['path']), r, frame_size)
            if crop is None:
                continue
            out.crops.append(crop)
            out.labels.append(r['class_key'])
            out.groups.append(f'{spec.name}:{obj}' if obj != '-1'
                              else f'{spec.name}:bg{r["frame"]}')
            out.weather.append(spec.weather)
            out.source.append(f'synth:{spec.name}:s{seed}')
            out.clip.append('')
            out.side.append(min(float(r['box_w']), float(r['box_h'])))
        if progress:
            progress(f'renders {n}/{len(specs)}: {spec.name} ({spec.weather}, seed {seed}) '
                     f'{len(rows)} crops, {time.monotonic() - t0:.0f} s')
    return out


# --- folders -------------------------------------------------------------------------------

def _clip_index(root: Path) -> dict[str, tuple[str, float]]:
    """``relative path -> (clip, shorter box side)`` from ``root/index.csv``.

    Empty when there is no index or it has no ``clip`` column; the side is NaN without
    ``w`` / ``h`` columns.
    """
    index = root / 'index.csv'
    if not index.is_file():
        return {}
    with open(index, newline='') as fh:
        reader = csv.DictReader(fh)
        cols = reader.fieldnames or []
        if 'clip' not in cols:
            return {}
        key = 'path' if 'path' in cols else ('file' if 'file' in cols else None)
        if key is None:
            raise DataError(f'{index} has a clip column but no path column')
        sized = 'w' in cols and 'h' in cols
        return {Path(r[key]).as_posix(): (r['clip'], min(float(r['w']), float(r['h']))
                                          if sized else float('nan')) for r in reader}


def load_folder(root: str | Path, exclude_clips: Sequence[str] = (),
                only_clips: Optional[Sequence[str]] = None) -> CropSet:
    """Crops of a folder-per-class dataset ``root/<class_key>/*.png|jpg``.

    Args:
        root: the dataset folder.
        exclude_clips: clips (``index.csv`` column ``clip``) to leave out.
        only_clips: keep only these clips (``None``: all).

    Raises:
        DataError: missing folder, a class folder that is not a catalogue key, no images.
    """
    root = Path(root)
    if not root.is_dir():
        raise DataError(f'data folder {root} does not exist')
    folders = sorted(p for p in root.iterdir() if p.is_dir())
    unknown = [p.name for p in folders if p.name not in signs.BY_KEY]
    if unknown:
        raise DataError(f'{root}: unknown class folder(s) {", ".join(unknown)}; class folders '
                        f'must be keys of workzone_ros.core.signs ({", ".join(signs.BY_KEY)})')
    clips = _clip_index(root)
    out = CropSet()
    for folder in folders:
        for img in sorted(folder.iterdir()):
            if img.suffix.lower() not in IMAGE_EXT:
                continue
            rel = img.relative_to(root).as_posix()
            clip, side = clips.get(rel, ('', float('nan')))
            if clip in exclude_clips or (only_clips is not None and clip not in only_clips):
                continue
            out.crops.append(_read(img))
            out.labels.append(folder.name)
            out.groups.append(f'{root.name}:{clip or rel}')
            out.weather.append('real' if clip else 'unknown')
            out.source.append(f'data:{root.name}')
            out.clip.append(clip)
            out.side.append(side)
    if not out.crops:
        raise DataError(f'{root} holds no crops (expected {root}/<class_key>/*.png)')
    return out


# --- classes -------------------------------------------------------------------------------

CLASS_SETS = ('workzone', 'all', 'present')


def class_list(mode: str, labels: Sequence[str] = ()) -> tuple[str, ...]:
    """The model's classes: ``workzone`` (CLASSIFIER_KEYS), ``all`` (+ general signs) or
    ``present`` (the catalogue keys among ``labels``, in catalogue order)."""
    if mode == 'workzone':
        return signs.CLASSIFIER_KEYS
    if mode == 'all':
        return signs.WORKZONE_KEYS + signs.GENERAL_KEYS + ('background',)
    if mode == 'present':
        have = set(labels)
        return tuple(k for k in class_list('all') if k in have)
    raise DataError(f'unknown class set {mode!r} ({", ".join(CLASS_SETS)})')


def map_labels(labels: Sequence[str], classes: Sequence[str]) -> list[str]:
    """Labels of classes the model does not have become ``background`` (rejected)."""
    have = set(classes)
    return [lab if lab in have else 'background' for lab in labels]


# --- command line --------------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        print(f'{self.prog}: {message}', file=sys.stderr)
        raise SystemExit(2)


def add_source_arguments(p: argparse.ArgumentParser, synth_default: int) -> None:
    """The data-source options shared by the trainer and the evaluation."""
    p.add_argument('--synth', type=int, default=synth_default, metavar='N_PER_CLASS',
                   help='rendered crops per class and scenario (0: none; default '
                        f'{synth_default})')
    p.add_argument('--synth-seeds', type=int, nargs='+', default=[0, 1, 2, 3], metavar='SEED',
                   help='scenario / render seeds (default 0 1 2 3)')
    p.add_argument('--synth-random', type=int, default=4, metavar='R',
                   help='random scenarios per seed, weathers cycling (default 4)')
    p.add_argument('--no-library', action='store_true',
                   help='render only random scenarios, not the library ones')
    p.add_argument('--size', type=int, default=64, help='rendered crop side (default 64)')
    p.add_argument('--cache', default=str(DEFAULT_CACHE),
                   help=f'render cache folder (default {DEFAULT_CACHE}; delete it after '
                        'changing the simulator)')
    p.add_argument('--data', nargs='+', default=[], metavar='DIR',
                   help='folder-per-class datasets DIR/<class_key>/*.png')
    p.add_argument('--exclude-clip', nargs='+', default=[], metavar='NAME',
                   help="leave out the crops of these clips (index.csv column 'clip')")
    p.add_argument('--classes', choices=CLASS_SETS, default='all',
                   help='workzone: CLASSIFIER_KEYS, general signs become background; all: '
                        'also the general signs as classes; present: the classes the data '
                        'has (default all)')


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog='workzone-ros train classifier', description=__doc__,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    add_source_arguments(p, synth_default=20)
    p.add_argument('--features', choices=ft.FEATURE_KINDS, default=DEFAULT_FEATURES,
                   help=f'feature kind (logpolar: the seed; default {DEFAULT_FEATURES})')
    p.add_argument('--method', choices=clf_mod.METHODS, default='svm',
                   help='svm (the seed), lda or knn (baselines)')
    p.add_argument('--components', type=int, default=10, help='PCA components (default 10)')
    p.add_argument('--cv', type=int, default=3, help='CV folds for C / gamma (default 3)')
    p.add_argument('--margin', type=float, default=0.1,
                   help='crop margin stored for classify_boxes (default 0.1)')
    p.add_argument('--seed', type=int, default=0, help='PCA / CV seed')
    p.add_argument('-o', '--output',
                   default=str(Path(__file__).resolve().parents[2] / 'config'
                               / clf_mod.DEFAULT_MODEL),
                   help='model file (default config/models/sign_classifier.npz)')
    return p


def gather(args: argparse.Namespace, progress=_say) -> CropSet:
    """Every crop the source options select (renders first, then the folders)."""
    data = CropSet()
    for d in args.data:              # check folders before spending minutes on renders
        data.extend(load_folder(d, exclude_clips=args.exclude_clip))
    out = CropSet()
    if args.synth > 0:
        specs = synth_specs(args.synth_seeds, args.synth_random, not args.no_library)
        out.extend(render_crops(specs, args.synth, args.size, Path(args.cache), progress))
    out.extend(data)
    if not len(out):
        raise DataError('no training crops: give --synth N and/or --data DIR')
    return out


def describe_sources(args: argparse.Namespace, data: CropSet) -> dict:
    """The metadata record of what trained a model."""
    src = {'renders': None, 'folders': [], 'excluded_clips': list(args.exclude_clip)}
    if args.synth > 0:
        src['renders'] = {'per_class_per_scenario': args.synth, 'seeds': args.synth_seeds,
                          'random_per_seed': args.synth_random,
                          'library': not args.no_library, 'size': args.size,
                          'crops': sum(s.startswith('synth:') for s in data.source),
                          'crops_by_weather': {w: sum(1 for s, x in zip(data.source,
                                                                         data.weather)
                                                      if s.startswith('synth:') and x == w)
                                               for w in sorted(set(data.weather))
                                               if w not in ('real', 'unknown')},
                          'scenarios': sorted({s.split(':', 1)[1] for s in data.source
                                               if s.startswith('synth:')})}
    for d in args.data:
        name = Path(d).name
        clips = sorted({c for c, s in zip(data.clip, data.source) if s == f'data:{name}'})
        src['folders'].append({'path': str(d), 'crops': data.source.count(f'data:{name}'),
                               'clips': [c for c in clips if c]})
    return src


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point; returns the exit status (2 with one line on stderr for bad input)."""
    args = _parser().parse_args(argv)
    try:
        data = gather(args)
        classes = class_list(args.classes, data.labels)
        labels = map_labels(data.labels, classes)
        missing = [c for c in classes if c not in set(labels)]
        if missing:
            raise DataError(f'no crops of class(es) {", ".join(missing)}; add renders '
                            '(--synth) or folders for them, or use --classes workzone')
    except DataError as exc:
        print(f'workzone-ros train classifier: {exc}', file=sys.stderr)
        return 2
    _say(f'training {args.method} on {args.features}: {len(data)} crops, '
         f'{len(classes)} classes ' + ', '.join(f'{k} {v}' for k, v in
                                                 sorted(data.counts().items())))
    t0 = time.monotonic()
    try:
        model = clf_mod.fit(data.crops, labels, classes, features=args.features,
                            method=args.method, n_components=args.components, seed=args.seed,
                            cv=args.cv, margin=args.margin,
                            metadata={'training_sources': describe_sources(args, data),
                                      'class_set': args.classes},
                            progress=_say)
    except ValueError as exc:
        print(f'workzone-ros train classifier: {exc}', file=sys.stderr)
        return 2
    clf_mod.save_model(model, args.output)
    md = model.metadata
    _say(f'PCA {md["n_components"]} components hold {md["pca_variance_held"]:.1%} of the '
         f'variance; trained in {time.monotonic() - t0:.0f} s')
    print(f'model written to {args.output} ({Path(args.output).stat().st_size / 1024:.0f} KiB)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
