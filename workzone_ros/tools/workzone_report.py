"""The ``--report DIR`` of ``workzone-ros evaluate workzone``: Markdown and timeline PNGs.

``DIR/README.md`` holds the command, the pooled figures, Table IV per bag (Seo et al.: event
recognised o/x / sign images / precision / recall), the timing of each bag and, for
``--signs pipeline``, the per-frame sign confusion matrix and the per-stage accuracy table
(detection, tracking, classification; :mod:`workzone_ros.tools.workzone_stages`; "n/a" with
``--signs gt``).  ``DIR/<bag>_timeline.png`` is
Seo et al.'s Fig. 3 for one bag, drawn with OpenCV (no plotting library): frames on x, the
work-zone classes on y, legible ground-truth signs as green circles and the signs given to
the fusion as red crosses; under it the fusion's likelihood (orange) and two bands, truth
and prediction, shaded by phase.  ``DIR/stage_latency.png`` holds one histogram per stage
of its processing time per frame (in process, log scale, p50 and p99 marked), with the
table beside it in the Markdown.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from workzone_ros.core import signs as catalogue

__all__ = ['write_report', 'draw_timeline', 'draw_stage_histograms', 'PHASE_COLORS']

#: BGR colour of each phase in the bands.
PHASE_COLORS = {'unknown': (200, 200, 200), 'none': (245, 245, 245),
                'approaching': (120, 200, 255), 'inside': (60, 120, 255),
                'leaving': (200, 140, 220)}
_CLASSES = catalogue.WORKZONE_KEYS
_GREEN, _RED, _ORANGE = (40, 160, 40), (30, 30, 220), (0, 140, 255)
_W, _LEFT, _RIGHT = 1500, 190, 20
_ROW, _TOP = 22, 40


def _text(img, s: str, org, scale: float = 0.42, color=(0, 0, 0), thick: int = 1) -> None:
    import cv2
    cv2.putText(img, s, (int(org[0]), int(org[1])), cv2.FONT_HERSHEY_SIMPLEX, scale, color,
                thick, cv2.LINE_AA)


def draw_timeline(frames: Sequence, title: str) -> np.ndarray:
    """Seo et al. Fig. 3 for one bag (see the module docstring); a BGR image."""
    import cv2
    n = max(len(frames), 1)
    plot_w = _W - _LEFT - _RIGHT
    classes_h = _ROW * len(_CLASSES)
    lik_top = _TOP + classes_h + 20
    lik_h = 110
    band_top = lik_top + lik_h + 25
    height = band_top + 2 * 24 + 60
    img = np.full((height, _W, 3), 255, np.uint8)
    x = lambda k: int(_LEFT + k * plot_w / n)            # noqa: E731
    _text(img, title, (_LEFT, 24), 0.55, thick=1)
    for i, key in enumerate(_CLASSES):
        y = _TOP + i * _ROW + _ROW // 2
        cv2.line(img, (_LEFT, y), (_W - _RIGHT, y), (235, 235, 235), 1)
        _text(img, key, (8, y + 4), 0.4)
    row = {k: i for i, k in enumerate(_CLASSES)}
    for k, f in enumerate(frames):
        for _, c, _ in f.gt:
            if c in row:
                cv2.circle(img, (x(k), _TOP + row[c] * _ROW + _ROW // 2), 4, _GREEN, 1,
                           cv2.LINE_AA)
        for c, _, _ in f.pred:
            if c in row:
                cx, cy = x(k), _TOP + row[c] * _ROW + _ROW // 2
                cv2.line(img, (cx - 3, cy - 3), (cx + 3, cy + 3), _RED, 1, cv2.LINE_AA)
                cv2.line(img, (cx - 3, cy + 3), (cx + 3, cy - 3), _RED, 1, cv2.LINE_AA)
    _likelihood(img, frames, x, lik_top, lik_h)
    for j, (label, attr) in enumerate((('truth', 'truth'), ('predicted', 'phase'))):
        top = band_top + j * 24
        _text(img, label, (8, top + 16), 0.45)
        for k, f in enumerate(frames):
            cv2.rectangle(img, (x(k), top), (x(k + 1), top + 20),
                          PHASE_COLORS.get(getattr(f, attr), (0, 0, 0)), -1)
        cv2.rectangle(img, (_LEFT, top), (_W - _RIGHT, top + 20), (120, 120, 120), 1)
    _axis(img, n, x, band_top + 2 * 24 + 4)
    _legend(img, height - 18)
    return img


def _likelihood(img, frames, x, top: int, h: int) -> None:
    import cv2
    cv2.rectangle(img, (_LEFT, top), (_W - _RIGHT, top + h), (160, 160, 160), 1)
    _text(img, 'likelihood', (8, top + h // 2), 0.45)
    _text(img, '1', (_LEFT - 14, top + 8), 0.35)
    _text(img, '0', (_LEFT - 14, top + h), 0.35)
    pts = np.array([[x(k), top + h - 1 - int(round(f.likelihood * (h - 2)))]
                    for k, f in enumerate(frames)], np.int32)
    if len(pts) > 1:
        cv2.polylines(img, [pts], False, _ORANGE, 2, cv2.LINE_AA)


def _axis(img, n: int, x, y: int) -> None:
    import cv2
    step = max(1, int(10 ** np.floor(np.log10(max(n, 10)))) // 2)
    while n / step > 16:
        step *= 2
    for k in range(0, n + 1, step):
        cv2.line(img, (x(k), y), (x(k), y + 4), (0, 0, 0), 1)
        _text(img, str(k), (x(k) - 10, y + 17), 0.35)
    _text(img, 'frame', (_W - _RIGHT - 40, y + 30), 0.4)


def _legend(img, y: int) -> None:
    import cv2
    cv2.circle(img, (_LEFT, y - 4), 4, _GREEN, 1, cv2.LINE_AA)
    _text(img, 'ground truth (legible)', (_LEFT + 10, y), 0.4)
    cx = _LEFT + 200
    cv2.line(img, (cx - 3, y - 7), (cx + 3, y - 1), _RED, 1)
    cv2.line(img, (cx - 3, y - 1), (cx + 3, y - 7), _RED, 1)
    _text(img, 'classified sign', (cx + 10, y), 0.4)
    cv2.line(img, (cx + 140, y - 4), (cx + 160, y - 4), _ORANGE, 2)
    _text(img, 'likelihood', (cx + 166, y), 0.4)
    px = cx + 260
    for phase, col in PHASE_COLORS.items():
        cv2.rectangle(img, (px, y - 10), (px + 14, y + 2), col, -1)
        cv2.rectangle(img, (px, y - 10), (px + 14, y + 2), (120, 120, 120), 1)
        _text(img, phase, (px + 18, y), 0.4)
        px += 30 + 9 * len(phase)


# --- Markdown -------------------------------------------------------------------------------

#: Histogram range (ms, log-spaced bins) of the stage processing times.
_HIST_MS = (0.01, 1000.0)
_HIST_BINS = 50


def draw_stage_histograms(stage_ms: dict) -> np.ndarray:
    """One row per stage: the histogram of its per-frame processing time (ms, log x axis),
    p50 (blue) and p99 (red) marked; a BGR image."""
    import cv2
    w, left, row = 900, 150, 90
    img = np.full((30 + row * max(1, len(stage_ms)) + 30, w, 3), 255, np.uint8)
    lo, hi = np.log10(_HIST_MS[0]), np.log10(_HIST_MS[1])
    edges = np.linspace(lo, hi, _HIST_BINS + 1)
    span = w - left - 20

    def x_of(ms: float) -> int:
        v = np.log10(min(max(ms, _HIST_MS[0]), _HIST_MS[1]))
        return int(left + (v - lo) / (hi - lo) * span)
    _text(img, 'processing time per frame (ms, in process; blue p50, red p99)', (left, 20), 0.5)
    for i, (name, ms) in enumerate(stage_ms.items()):
        top = 30 + i * row
        _text(img, name, (8, top + row // 2), 0.45)
        a = np.log10(np.clip(np.asarray(ms, float), *_HIST_MS)) if len(ms) else np.zeros(0)
        counts, _ = np.histogram(a, edges)
        peak = max(1, int(counts.max()) if counts.size else 1)
        for k, c in enumerate(counts):
            if c:
                x0 = int(left + (edges[k] - lo) / (hi - lo) * span)
                x1 = int(left + (edges[k + 1] - lo) / (hi - lo) * span) - 1
                y0 = top + row - 10 - int((row - 25) * c / peak)
                cv2.rectangle(img, (x0, y0), (x1, top + row - 10), (150, 150, 150), -1)
        if len(ms):
            for q, colour in ((50, (200, 80, 0)), (99, (30, 30, 220))):
                x = x_of(float(np.percentile(ms, q)))
                cv2.line(img, (x, top + 8), (x, top + row - 10), colour, 2)
        cv2.line(img, (left, top + row - 10), (w - 20, top + row - 10), (0, 0, 0), 1)
    y = img.shape[0] - 8
    for ms in (0.01, 0.1, 1, 10, 100, 1000):
        _text(img, f'{ms:g}', (x_of(ms) - 8, y), 0.4)
    return img


def _latency_lines(summary: dict, out: Path, stage_ms: dict) -> list[str]:
    import cv2
    rows = summary.get('stage_ms') or {}
    if not rows:
        return []
    lines = ['## Processing time per stage', '',
             'Measured in process, per frame, on this machine (the nodes report the same '
             'figures live in `/diagnostics`: `<topic> processing p50/p99 ms`).', '',
             '| stage | frames | p50 ms | p99 ms | max ms |', '|---|---|---|---|---|']
    lines += [f"| {k} | {v['frames']} | {_cell(v['p50'])} | {_cell(v['p99'])} | "
              f"{_cell(v['max'])} |" for k, v in rows.items()]
    if stage_ms:
        cv2.imwrite(str(out / 'stage_latency.png'), draw_stage_histograms(stage_ms))
        lines += ['', '![processing time per stage](stage_latency.png)']
    return lines + ['']


def _cell(v) -> str:
    return '-' if v is None else (f'{v:.3f}' if isinstance(v, float) else str(v))


def _table_iv(results: list[dict]) -> list[str]:
    from workzone_ros.tools.eval_workzone import table_iv_rows
    ok = [r for r in results if 'error' not in r]
    lines = ['| bag | event | o/images/precision/recall | timing |', '|---|---|---|---|']
    for r in ok:
        name = Path(r['bag']).name
        timing = {'Workzone begins': r['zone_begin']['error_s'],
                  'Workzone ends': r['zone_end']['error_s']}
        delays = [c['delay_s'] for c in r['changes']]
        for i, (label, cell) in enumerate(table_iv_rows(r)):
            t = timing.get(label) if i < 2 else delays[i - 2]
            what = 'error' if i < 2 else 'delay'
            lines.append(f'| {name if i == 0 else ""} | {label} | {cell} | '
                         f'{what} {_cell(t)} s |')
    return lines


def _bag_lines(r: dict) -> list[str]:
    b, e = r['zone_begin'], r['zone_end']
    ttc = ', '.join(f'{k} {_cell(v)} s' for k, v in r['time_to_correct'].items())
    return [
        f"- frames {r['frames']}, {r['weather']}; phase accuracy {r['phase_accuracy']:.3f}, "
        f"active accuracy {r['active_accuracy']:.3f}, flicker {r['flicker']} "
        f"({r['phase_changes']} phase changes, truth {r['truth_changes']})",
        f"- zone begin error {_cell(b['error_s'])} s / {_cell(b['error_m'])} m; end error "
        f"{_cell(e['error_s'])} s / {_cell(e['error_m'])} m",
        f'- time to the first correct phase after each truth onset: {ttc}',
        f"- mean likelihood inside {_cell(r['likelihood_inside'])}, outside "
        f"{_cell(r['likelihood_outside'])}",
    ]


def _confusion(results: list[dict]) -> list[str]:
    total: dict[str, dict[str, int]] = {}
    for r in results:
        for g, row in r.get('sign_confusion', {}).items():
            for p, n in row.items():
                total.setdefault(g, {})[p] = total.get(g, {}).get(p, 0) + n
    if not total:
        return []
    cols = [k for k in catalogue.WORKZONE_KEYS + catalogue.GENERAL_KEYS
            if any(k in row for row in total.values())] + ['missed']
    rows = [k for k in catalogue.WORKZONE_KEYS + catalogue.GENERAL_KEYS if k in total] \
        + (['no sign'] if 'no sign' in total else [])
    lines = ['| truth \\ predicted | ' + ' | '.join(cols) + ' |',
             '|---|' + '---|' * len(cols)]
    for g in rows:
        lines.append(f'| {g} | ' + ' | '.join(str(total[g].get(c, 0) or '')
                                             for c in cols) + ' |')
    return ['## Sign confusion (per frame, IoU >= 0.5)', ''] + lines + ['']


def write_report(folder: str, results: list[dict], summary: dict, opts,
                 argv: Optional[Sequence[str]] = None) -> str:
    """Write ``folder/README.md`` and one timeline PNG per bag; returns the Markdown path."""
    import cv2
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    s = summary
    lines = ['# Work-zone state evaluation', '',
             '`workzone-ros evaluate workzone ' + ' '.join(argv or []) + '`', '',
             f"Signs: **{opts.signs}**; odometry {'on' if opts.odom else 'off'}; channelizers "
             f"{'on' if opts.channelizers else 'off'}; tolerance {opts.tolerance_s} s.", '',
             f"- bags: {s['bags']} ({s['failed']} failed), frames {s['frames']}, phase "
             f"accuracy {s['phase_accuracy']}",
             f"- zone bounds recognised **{s['bounds_recognised']}/{s['bounds']}**, "
             f"driving-condition changes **{s['changes_recognised']}/{s['changes']}**, "
             f"flicker {s['flicker']}",
             f"- zone begin |error| mean {_cell(s['zone_begin_abs_error_s_mean'])} s, max "
             f"{_cell(s['zone_begin_abs_error_s_max'])} s; end mean "
             f"{_cell(s['zone_end_abs_error_s_mean'])} s, max "
             f"{_cell(s['zone_end_abs_error_s_max'])} s", '',
             '## Table IV', ''] + _table_iv(results) + ['']
    for r in results:
        name = Path(r['bag']).name
        if 'error' in r:
            lines += [f'## {name}', '', f"ERROR: {r['error']}", '']
            continue
        png = f'{name}_timeline.png'
        frames = r.get('_frames') or []
        if frames:
            cv2.imwrite(str(out / png), draw_timeline(
                frames, f"{name} ({r['scenario']}, {r['weather']}): signs {opts.signs}"))
        lines += [f'## {name}', ''] + _bag_lines(r) + ['', f'![timeline]({png})', '']
    if opts.signs == 'pipeline':
        lines += _confusion(results)
    from workzone_ros.tools.workzone_stages import report_lines
    lines += report_lines(results, s.get('stages'))
    from workzone_ros.tools.eval_workzone import pooled_stage_ms
    lines += _latency_lines(s, out, pooled_stage_ms([r for r in results if 'error' not in r]))
    path = out / 'README.md'
    path.write_text('\n'.join(lines) + '\n')
    return str(path)
