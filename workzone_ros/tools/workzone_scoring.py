"""The figures of ``workzone-ros evaluate workzone``: the ground-truth phase of every frame
(:func:`truth_phases`), every figure of one bag (:func:`score`: zone bounds, driving-condition
changes, Table IV sign precision / recall, sign confusion, flicker) and the figures pooled over
bags (:func:`summarise`, with the pooled per-stage figures of
:mod:`workzone_ros.tools.workzone_stages`).  The definitions are in the docstring of
:mod:`workzone_ros.tools.eval_workzone`.
"""
from __future__ import annotations

from collections import Counter
from typing import Any, Optional

import numpy as np

from workzone_ros.core.fusion import ACTIVE_PHASES
from workzone_ros.interfaces import GtWorkzone
from workzone_ros.tools.eval_tracker import _iou
from workzone_ros.tools.workzone_run import Frame
from workzone_ros.tools.workzone_stages import pool_stages

__all__ = ['PHASES_ORDER', 'IOU', 'truth_phases', 'sign_confusion', 'score', 'stage_summary',
           'pooled_stage_ms', 'summarise']

PHASES_ORDER = ('unknown', 'none', 'approaching', 'inside', 'leaving')
IOU = 0.5


# --- ground truth phases --------------------------------------------------------------------

def _first_legible(frames: list[Frame]) -> dict[int, float]:
    out: dict[int, float] = {}
    for f in frames:
        for sid, _, _ in f.gt:
            out.setdefault(sid, f.t)
    return out


def truth_phases(frames: list[Frame], gtw: GtWorkzone, legible_px: float) -> dict:
    """Set ``Frame.truth`` (module docstring); returns the onsets {phase: t}."""
    onsets: dict[str, Optional[float]] = {}
    if gtw.begin_t is None:
        return onsets
    seen = _first_legible(frames)
    begin = next(e for e in gtw.events if e.kind == 'zone_begin')
    before = [e for e in gtw.events if e.x_m <= begin.x_m and e.sign_id in seen]
    approach = min((seen[e.sign_id] for e in before), default=gtw.begin_t)
    onsets['approaching'] = min(approach, gtw.begin_t)
    onsets['inside'] = gtw.begin_t
    end = next((e for e in gtw.events if e.kind == 'zone_end'), None)
    end_t = gtw.end_t if gtw.end_t is not None else float('inf')
    leave = seen.get(end.sign_id, end_t) if end is not None else end_t
    onsets['leaving'] = max(leave, gtw.begin_t)
    onsets['none'] = end_t
    for f in frames:
        f.truth = ('none' if f.t < onsets['approaching'] or f.t >= end_t
                   else 'approaching' if f.t < onsets['inside']
                   else 'inside' if f.t < onsets['leaving'] else 'leaving')
    return onsets


# --- scoring --------------------------------------------------------------------------------

def _r(v: Optional[float], nd: int = 3) -> Optional[float]:
    return None if v is None else round(float(v), nd)


def _odom_at(frames: list[Frame], t: float) -> float:
    """Odometry metres at bag time ``t`` (linear between frames)."""
    prev = frames[0]
    for f in frames:
        if f.t >= t:
            if f.t == prev.t:
                return f.odom_m
            a = (t - prev.t) / (f.t - prev.t)
            return prev.odom_m + a * (f.odom_m - prev.odom_m)
        prev = f
    return frames[-1].odom_m


def _bounds(frames: list[Frame], gtw: GtWorkzone, tol: float) -> tuple[dict, dict]:
    """zone_begin / zone_end: predicted times, errors, recognised."""
    k_on = next((i for i, f in enumerate(frames) if f.phase in ACTIVE_PHASES), None)
    k_off = None if k_on is None else next(
        (i for i in range(k_on, len(frames)) if frames[i].phase not in ACTIVE_PHASES), None)
    out = []
    for truth, k in ((gtw.begin_t, k_on), (gtw.end_t, k_off)):
        row: dict[str, Any] = {'truth_t': _r(truth), 'pred_t': None, 'error_s': None,
                               'error_m': None, 'recognised': None}
        if truth is not None:
            row['recognised'] = False
            if k is not None:
                p = frames[k].t
                row.update(pred_t=_r(p), error_s=_r(p - truth),
                           error_m=_r(frames[k].odom_m - _odom_at(frames, truth), 2),
                           recognised=abs(p - truth) <= tol)
        out.append(row)
    return out[0], out[1]


def _changes(gtw: GtWorkzone) -> list[dict]:
    """Driving-condition changes; the two signs of one lane closure are one change."""
    out: list[dict] = []
    for e in sorted(gtw.events, key=lambda e: e.t):
        if e.kind not in ('speed_limit', 'lane_shift', 'lane_closed'):
            continue
        if out and e.kind == 'lane_closed' and out[-1]['kind'] == 'lane_closed' \
                and out[-1]['value'] == e.value:
            out[-1]['sign_ids'].append(e.sign_id)
            out[-1]['t_last'] = e.t
            continue
        out.append({'kind': e.kind, 'value': e.value, 'sign_ids': [e.sign_id],
                    't_first': e.t, 't_last': e.t})
    return out


def _shows(f: Frame, kind: str, value) -> bool:
    if kind == 'speed_limit':
        return f.speed == value
    if kind == 'lane_shift':
        return f.lane_shift == value
    return value in f.lanes_closed


def _sign_pr(frames: list[Frame], sign_ids: list) -> dict:
    """Table IV's sign images / precision / recall for the signs of one event."""
    ids = set(sign_ids)
    classes = {c for f in frames for sid, c, _ in f.gt if sid in ids}
    images = tp_frames = tp = fp = 0
    for f in frames:
        mine = [(sid, c, b) for sid, c, b in f.gt if sid in ids]
        others = [b for sid, c, b in f.gt if sid not in ids and c in classes]
        images += len(mine)
        for _, c, b in mine:
            tp_frames += any(pc == c and _iou(pb, b) >= IOU for pc, pb, _ in f.pred)
        for pc, pb, _ in f.pred:
            if pc not in classes:
                continue
            if any(_iou(pb, b) >= IOU for _, _, b in mine):
                tp += 1
            elif not any(_iou(pb, b) >= IOU for b in others):
                fp += 1
    return {'images': images, 'precision': _r(tp / (tp + fp)) if tp + fp else None,
            'recall': _r(tp_frames / images) if images else None,
            'classes': sorted(classes)}


def _change_rows(frames: list[Frame], gtw: GtWorkzone, tol: float) -> list[dict]:
    seen = _first_legible(frames)
    rows = []
    for ch in _changes(gtw):
        onset = min((seen[s] for s in ch['sign_ids'] if s in seen), default=ch['t_first'])
        hit = next((f for f in frames if onset <= f.t <= ch['t_last'] + tol
                    and _shows(f, ch['kind'], ch['value'])), None)
        rows.append({'kind': ch['kind'], 'value': ch['value'], 'sign_ids': ch['sign_ids'],
                     'truth_t': _r(ch['t_first']), 'recognised': hit is not None,
                     'delay_s': None if hit is None else _r(hit.t - ch['t_first']),
                     **_sign_pr(frames, ch['sign_ids'])})
    return rows


def _time_to_correct(frames: list[Frame], onsets: dict) -> dict:
    order = sorted((t, p) for p, t in onsets.items() if t is not None and t != float('inf'))
    out = {}
    for i, (t, p) in enumerate(order):
        nxt = order[i + 1][0] if i + 1 < len(order) else float('inf')
        hit = next((f.t for f in frames if t <= f.t < nxt and f.phase == p), None)
        out[p] = None if hit is None else _r(hit - t)
    return out


def sign_confusion(frames: list[Frame]) -> dict[str, dict[str, int]]:
    """Per-frame truth class -> predicted class counts (IoU >= 0.5, best first).

    A legible GT sign no prediction matches counts as ``missed``; a prediction that
    matches no legible GT sign counts under truth ``no sign``.
    """
    out: dict[str, Counter] = {}
    for f in frames:
        used: set[int] = set()
        for _, c, b in f.gt:
            best, j = max(((_iou(pb, b), i) for i, (_, pb, _) in enumerate(f.pred)
                           if i not in used), default=(0.0, -1))
            if best >= IOU:
                used.add(j)
                out.setdefault(c, Counter())[f.pred[j][0]] += 1
            else:
                out.setdefault(c, Counter())['missed'] += 1
        for i, (pc, _, _) in enumerate(f.pred):
            if i not in used:
                out.setdefault('no sign', Counter())[pc] += 1
    return {k: dict(v) for k, v in sorted(out.items())}


def _changes_count(seq: list[str]) -> int:
    seq = list(seq)
    while seq and seq[0] == 'unknown':
        seq.pop(0)
    return sum(1 for a, b in zip(seq, seq[1:]) if a != b)


def score(frames: list[Frame], gtw: GtWorkzone, tol: float, legible_px: float) -> dict:
    """Every figure of one bag (module docstring)."""
    onsets = truth_phases(frames, gtw, legible_px)
    n = len(frames)
    conf: dict[str, Counter] = {}
    for f in frames:
        conf.setdefault(f.truth, Counter())[f.phase] += 1
    begin, end = _bounds(frames, gtw, tol)
    zone_ids = {e.kind: e.sign_id for e in gtw.events if e.kind in ('zone_begin', 'zone_end')}
    for row, kind in ((begin, 'zone_begin'), (end, 'zone_end')):
        row.update(_sign_pr(frames, [zone_ids[kind]]) if kind in zone_ids
                   else {'images': 0, 'precision': None, 'recall': None, 'classes': []})
    pred_changes = _changes_count([f.phase for f in frames])
    truth_changes = _changes_count([f.truth for f in frames])
    inside = [f.likelihood for f in frames if f.truth in ACTIVE_PHASES]
    outside = [f.likelihood for f in frames if f.truth == 'none']
    return {
        'frames': n, 'scenario': gtw.scenario, 'seed': gtw.seed, 'weather': gtw.weather,
        'phase_accuracy': _r(sum(f.phase == f.truth for f in frames) / n, 4),
        'active_accuracy': _r(sum((f.phase in ACTIVE_PHASES) == (f.truth in ACTIVE_PHASES)
                                  for f in frames) / n, 4),
        'unknown_frames': sum(f.phase == 'unknown' for f in frames),
        'confusion_phase': {t: dict(c) for t, c in sorted(conf.items())},
        'zone_begin': begin, 'zone_end': end,
        'changes': _change_rows(frames, gtw, tol),
        'time_to_correct': _time_to_correct(frames, onsets),
        'onsets': {k: _r(v) for k, v in onsets.items() if v != float('inf')},
        'phase_changes': pred_changes, 'truth_changes': truth_changes,
        'flicker': max(0, pred_changes - truth_changes),
        'likelihood_inside': _r(sum(inside) / len(inside)) if inside else None,
        'likelihood_outside': _r(sum(outside) / len(outside)) if outside else None,
        'sign_confusion': sign_confusion(frames),
    }


# --- pooled figures -------------------------------------------------------------------------

def stage_summary(ms: list[float]) -> dict:
    """Frames, p50, p99 and max (ms) of one stage's processing times."""
    if not ms:
        return {'frames': 0, 'p50': None, 'p99': None, 'max': None}
    a = np.asarray(ms, float)
    return {'frames': int(a.size), 'p50': _r(float(np.percentile(a, 50)), 2),
            'p99': _r(float(np.percentile(a, 99)), 2), 'max': _r(float(a.max()), 2)}


def pooled_stage_ms(results: list[dict]) -> dict[str, list[float]]:
    """Every bag's per-frame processing times, per stage, in pipeline order."""
    out: dict[str, list[float]] = {}
    for r in results:
        for k, v in r.get('_stage_ms', {}).items():
            out.setdefault(k, []).extend(v)
    return out


def summarise(results: list[dict]) -> dict:
    """Figures pooled over the bags that could be evaluated."""
    ok = [r for r in results if 'error' not in r]
    bounds = [r[k] for r in ok for k in ('zone_begin', 'zone_end') if r[k]['truth_t'] is not None]
    changes = [c for r in ok for c in r['changes']]

    def errs(key: str) -> list[float]:
        return [abs(r[key]['error_s']) for r in ok if r[key]['error_s'] is not None]
    out: dict[str, Any] = {
        'bags': len(ok), 'failed': len(results) - len(ok),
        'bounds_recognised': sum(b['recognised'] for b in bounds), 'bounds': len(bounds),
        'changes_recognised': sum(c['recognised'] for c in changes), 'changes': len(changes),
        'flicker': sum(r['flicker'] for r in ok),
        'frames': sum(r['frames'] for r in ok),
        'phase_accuracy': _r(sum(r['phase_accuracy'] * r['frames'] for r in ok)
                             / max(1, sum(r['frames'] for r in ok)), 4),
        'stage_ms': {k: stage_summary(v) for k, v in pooled_stage_ms(ok).items()},
        'stages': pool_stages([r.get('stages') for r in ok]),
    }
    for key in ('zone_begin', 'zone_end'):
        e = errs(key)
        out[f'{key}_abs_error_s_mean'] = _r(sum(e) / len(e)) if e else None
        out[f'{key}_abs_error_s_max'] = _r(max(e)) if e else None
        out[f'{key}_within_1s'] = sum(x <= 1.0 for x in e)
    return out
