"""``workzone-ros train <model> ...``: train a model and write it to config/models/.

Each trainer is a module ``workzone_ros.tools.train_<model>`` with ``main(argv) -> int``.
"""
from __future__ import annotations

import sys

from workzone_ros.cli import dispatch

__all__ = ['TRAINERS', 'main']

TRAINERS: dict[str, str] = {
    'color': 'boosted hue/saturation color model (Seo et al.) from `synth pixels` or images+masks',
    'classifier': 'sign classifier: log-polar + PCA + RBF SVM (Seo et al.) from renders / folders',
    'proposals': 'the candidate ranker of the recall-first colour proposals, into a colour model',
    'shapes': 'sign-shape cascades: boosted Haar-like stages (Balali and Golparvar-Fard), '
              'from renders',
    'cnn': 'sign classifier: small CNN for cv2.dnn (ONNX) from renders / folders; needs .[cnn]',
}


def main(argv: list[str] | None = None) -> int:
    """Dispatch to the named module's ``main``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return dispatch('workzone-ros train', 'model', TRAINERS, 'workzone_ros.tools.train_', argv)
