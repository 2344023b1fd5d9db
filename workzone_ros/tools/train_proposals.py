"""``workzone-ros train proposals``: learn how the colour proposals rank their candidates.

The recall-first colour stage (:mod:`workzone_ros.core.proposals`) keeps the best
``max_candidates`` orange blobs of a frame.  This tool runs it over the same ``images/`` +
``masks/`` folders the colour table is trained from (``workzone-ros synth pixels``,
``workzone-ros real-pixels``), labels each candidate by its overlap with the mask's sign faces
(IoU >= 0.3 is a sign; mask value 255 is a face, see ``train color``), fits a class-balanced
logistic regression over the candidate measurements and writes a copy of the colour model
with the ranker inside (extra ``proposal_ranker``; metadata ``proposal_ranker`` says what
trained it and its top-K recall on the training frames).

Example::

    workzone-ros train proposals config/models/color_orange.npz /tmp/pix /tmp/real_pix \\
        -o config/models/color_orange.npz
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Optional

import numpy as np

__all__ = ['main', 'collect']


def collect(proposer, pairs, progress: bool = True) -> tuple[np.ndarray, np.ndarray, list]:
    """(features, labels, per-frame candidate groups) of every candidate of ``pairs``."""
    import cv2

    from workzone_ros.core.proposals import candidate_labels
    from workzone_ros.tools.train_color import IGNORE
    feats, labels, groups = [], [], []
    t0 = time.perf_counter()
    for k, (ip, mp) in enumerate(pairs):
        img = cv2.imread(str(ip), cv2.IMREAD_COLOR)
        mask = cv2.imread(str(mp), cv2.IMREAD_GRAYSCALE)
        if img is None or mask is None:
            raise ValueError(f'unreadable pair {ip} / {mp}')
        face = ((mask > 0) & (mask != IGNORE)).astype(np.uint8)
        n, _, st, _ = cv2.connectedComponentsWithStats(face)
        truth = [tuple(float(v) for v in st[i, :4]) for i in range(1, n) if st[i, 4] >= 20]
        boxes, f = proposer.candidates(img)
        lab = candidate_labels(boxes, truth)
        feats.append(f)
        labels.append(lab)
        groups.append((len(truth), len(boxes)))
        if progress and (k + 1) % 100 == 0:
            print(f'  {k + 1}/{len(pairs)} frames, {time.perf_counter() - t0:.0f} s',
                  file=sys.stderr, flush=True)
    return np.concatenate(feats), np.concatenate(labels), groups


def main(argv: Optional[list[str]] = None) -> int:
    """Entry point (module docstring)."""
    from workzone_ros.core import color_model as cm
    from workzone_ros.core.proposals import FEATURES, ProposalConfig, SignProposer, fit_ranker
    from workzone_ros.tools.train_color import load_pairs
    p = argparse.ArgumentParser(prog='workzone-ros train proposals', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('model', help='colour model (.npz) to add the ranker to')
    p.add_argument('data', nargs='+', help='folder(s) with images/ and masks/')
    p.add_argument('-o', '--output', required=True, help='the model with its ranker (.npz)')
    p.add_argument('--c', type=float, default=1.0, help='inverse regularisation (default 1)')
    args = p.parse_args(argv)
    try:
        model = cm.load_model(args.model)
        pairs = load_pairs(args.data)
    except (cm.ModelError, FileNotFoundError) as exc:
        print(f'workzone-ros train proposals: {exc}', file=sys.stderr)
        return 2
    if not pairs:
        print('workzone-ros train proposals: no image/mask pairs found', file=sys.stderr)
        return 2
    extras = {k: v for k, v in model.extras.items() if k != 'proposal_ranker'}
    model = replace(model, extras=extras)
    proposer = SignProposer(model, ProposalConfig())
    x, y, _ = collect(proposer, pairs)
    try:
        ranker = fit_ranker(x, y, args.c)
    except ValueError as exc:
        print(f'workzone-ros train proposals: {exc}', file=sys.stderr)
        return 2
    meta = dict(model.metadata)
    meta['proposal_ranker'] = {
        'trained_on': [str(Path(d).resolve()) for d in args.data], 'frames': len(pairs),
        'candidates': int(len(y)), 'sign_candidates': int(y.sum()), 'features': list(FEATURES),
        'c': args.c, 'created': time.strftime('%Y-%m-%dT%H:%M:%S')}
    out = replace(model, metadata=meta, extras={**extras, 'proposal_ranker': ranker.to_array()})
    cm.save_model(out, args.output)
    print(f'{len(pairs)} frames, {len(y)} candidates ({int(y.sum())} on signs); '
          f'weights {dict(zip(FEATURES, np.round(ranker.coef, 2).tolist()))}; '
          f'wrote {args.output}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
