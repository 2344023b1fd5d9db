"""``workzone-ros evaluate <stage> ...``: accuracy reports against a bag's ground truth, and
the robustness campaign (``faults``).

Each evaluation is a module ``workzone_ros.tools.eval_<stage>`` with ``main(argv) -> int``.
"""
from __future__ import annotations

import sys

from workzone_ros.cli import dispatch

__all__ = ['EVALUATIONS', 'main']

EVALUATIONS: dict[str, str] = {
    'lidar': 'LiDAR candidates (FP/FN by range band) and projection error (Cahail et al.)',
    'color': 'color detection, Seo et al. Table I metrics per weather; real clips',
    'tracker': 'tracking, Lee et al. Table II quantities; CamShift peer',
    'classifier': 'sign classifier, Seo et al. Table III; mirror pairs, background, real clips',
    'workzone': 'work-zone state, Seo et al. Table IV: bounds, condition changes, timing, flicker',
    'digits': 'the work-zone speed limit reader on rendered signs (correct / wrong / unread)',
    'real_signs': 'detector + tracker + classifier on the real dashcam clips, per frame',
    'ablation': 'each default-on switch of the colour stage turned off: Table I, real clips',
    'shapes': 'sign-shape cascades (Tables 3 and 4 of Balali and Golparvar-Fard); drum / cone '
              'veto on real crops',
    'general': 'general signs (stop, yield, warning, speed limit, guide, mile): the table of '
               'Cahail et al.',
    'faults': 'malformed messages on every subscription of every node: crashes, recovery',
    'reliability': 'the live graph under a looping bag, killed nodes, lost sensors, load',
}


def main(argv: list[str] | None = None) -> int:
    """Dispatch to the named module's ``main``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return dispatch('workzone-ros evaluate', 'stage', EVALUATIONS, 'workzone_ros.tools.eval_',
                    argv)
