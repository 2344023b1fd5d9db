"""Work-zone sign classifier: a small convolutional network run by OpenCV's ``dnn`` module.

The alternative to the log-polar + PCA + SVM of :mod:`workzone_ros.core.classifier`: a
few-10k-parameter CNN trained offline on the same crops
(``workzone-ros train cnn``, PyTorch in the ``cnn`` extra), exported to ONNX and run here by
``cv2.dnn`` -- no training framework at run time (no torch, no onnx import).

Same public interface as :class:`~workzone_ros.core.classifier.SignClassifier`:
``classes``, ``metadata``, ``predict_proba(crops)``, ``classify(crops)`` (a list of
:class:`~workzone_ros.core.classifier.Prediction`) and ``classify_boxes(frame, boxes,
margin)`` with the same cropping rules (:func:`features.crop_sign`, squared, the model's
margin), one forward pass for every box of a frame.

Pre-processing (recorded in the model's metadata and checked on load): each BGR crop is
resized to ``input_size`` x ``input_size`` (area filter when shrinking, as the SVM's
features do; a crop larger than twice that is first subsampled to twice that, which keeps
a batch of large crops cheap), then standardised over all its pixels and channels (zero
mean, unit deviation: exposure and contrast are not the network's problem), channel order
BGR, NCHW.  The class probabilities are the softmax of the network's outputs, with the
model's ``background_bias`` added to the ``background`` output first.

The model file is data, not code, like the SVM's: a compressed ``.npz`` of arrays only
(``allow_pickle=False``) holding the ONNX bytes as a ``uint8`` array, the class list and JSON
metadata (schema ``workzone_ros/SignClassifierCNN`` version 1, input size, normalisation,
architecture, training sources and settings) with a SHA-256 over every array and the rest of
the metadata.  :func:`workzone_ros.core.classifier.load_model` reads either kind and
dispatches here by the schema, so every consumer of a model path (the ``classifier`` node's
``model_path``, ``evaluate classifier --model``, ``evaluate real_signs --model``, ``bench
classifier --model``) takes either model.
"""
from __future__ import annotations

import os
from typing import Mapping, Sequence

import cv2
import numpy as np

from workzone_ros.core import classifier as _svm
from workzone_ros.core.classifier import ModelError, Prediction
from workzone_ros.core.features import _square
from workzone_ros.core.model_files import check_header, one_line, write_npz

__all__ = ['SCHEMA', 'VERSION', 'DEFAULT_MODEL', 'CnnSignClassifier', 'ModelError',
           'Prediction', 'preprocess', 'save_model', 'load_model', 'from_contents']

SCHEMA = 'workzone_ros/SignClassifierCNN'
VERSION = 1
#: Where the trainer writes a CNN by default, relative to ``config/``.
DEFAULT_MODEL = 'models/sign_classifier_cnn.npz'
#: Normalisations this build can apply (metadata ``normalise``).
NORMALISATIONS = ('per_crop',)
_EPS = 1e-6


def preprocess(crops: Sequence[np.ndarray], size: int) -> np.ndarray:
    """BGR ``uint8`` crops (any size, colour or grey) as the network's input blob.

    Returns:
        ``(n, 3, size, size)`` float32, each crop standardised over all its pixels and
        channels.
    """
    n, big = len(crops), 2 * size
    stack = np.empty((n, size, size, 3), np.uint8)
    for k, crop in enumerate(crops):
        if crop.ndim == 2:
            crop = cv2.cvtColor(np.ascontiguousarray(crop), cv2.COLOR_GRAY2BGR)
        if crop.shape[0] > big and crop.shape[1] > big:
            # subsample to twice the input first: the area filter's cost grows with the
            # crop, a 170 px crop costs 5x a 64 px one
            crop = cv2.resize(crop, (big, big), interpolation=cv2.INTER_NEAREST)
        stack[k] = _square(crop, size)
    x = stack.reshape(n, -1).astype(np.float32)
    mean = x.mean(axis=1, keepdims=True)
    std = x.std(axis=1, keepdims=True)
    x -= mean
    x /= std + _EPS
    return np.ascontiguousarray(x.reshape(n, size, size, 3).transpose(0, 3, 1, 2))


def _softmax(z: np.ndarray) -> np.ndarray:
    z = z - z.max(axis=1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


class CnnSignClassifier:
    """A trained CNN rebuilt from its ONNX bytes; see :func:`load_model`.

    Args:
        onnx: the network (ONNX bytes, input ``(n, 3, S, S)``, output logits ``(n, k)``).
        classes: class keys, in the order of the network's outputs.
        metadata: at least ``input_size``; ``normalise`` (``per_crop``), ``margin``,
            ``square_crops``, ``temperature`` (logits are divided by it) and
            ``background_bias`` (added to the ``background`` logit: the reject class's
            prior at run time, where most boxes are not signs) are optional.

    Raises:
        ValueError: the bytes are not a network OpenCV can run, or its output does not
            have one value per class.

    Attributes:
        classes: class keys, in the order of the probability columns.
        metadata: schema, input size, architecture, training sources, ...
        arrays: the model's arrays by name (``onnx``).
        method, features: ``'cnn'`` (for reports that print them for the SVM).
    """

    method = 'cnn'
    features = 'cnn'

    def __init__(self, onnx: bytes | np.ndarray, classes: Sequence[str], metadata: Mapping):
        self.classes: tuple[str, ...] = tuple(str(c) for c in classes)
        self.metadata: dict = dict(metadata)
        buf = np.frombuffer(bytes(onnx), np.uint8) if isinstance(onnx, (bytes, bytearray)) \
            else np.ascontiguousarray(onnx, np.uint8).ravel()
        self.arrays: dict[str, np.ndarray] = {'onnx': buf}
        self.input_size = int(self.metadata['input_size'])
        self.margin = float(self.metadata.get('margin', 0.1))
        self.temperature = float(self.metadata.get('temperature', 1.0))
        self.background_bias = float(self.metadata.get('background_bias', 0.0))
        if self.background_bias and 'background' not in classes:
            raise ValueError('a background bias without a background class')
        norm = self.metadata.get('normalise', 'per_crop')
        if norm not in NORMALISATIONS:
            raise ValueError(f'unknown normalisation {norm!r}')
        if not 8 <= self.input_size <= 256 or not self.temperature > 0:
            raise ValueError(f'input size {self.input_size} / temperature '
                             f'{self.temperature} out of range')
        if len(self.classes) < 2:
            raise ValueError('fewer than two classes')
        try:
            self._net = cv2.dnn.readNetFromONNX(buf)
        except cv2.error as exc:
            raise ValueError('the ONNX network cannot be read: '
                             + ' '.join(str(exc).split())[-160:]) from None
        out = self._forward(np.zeros((1, 3, self.input_size, self.input_size), np.float32))
        if out.shape != (1, len(self.classes)):
            raise ValueError(f'the network outputs {out.shape[1:]} values, the model has '
                             f'{len(self.classes)} classes')

    # --- prediction -----------------------------------------------------------------------
    def _forward(self, blob: np.ndarray) -> np.ndarray:
        try:
            self._net.setInput(blob)
            out = self._net.forward()
        except cv2.error as exc:
            raise ValueError('the ONNX network does not run: '
                             + ' '.join(str(exc).split())[-160:]) from None
        return np.asarray(out, np.float32).reshape(blob.shape[0], -1)

    def logits(self, crops: Sequence[np.ndarray]) -> np.ndarray:
        """The network's raw outputs ``(n, len(classes))`` for BGR crops (one pass)."""
        if len(crops) == 0:
            return np.zeros((0, len(self.classes)), np.float32)
        return self._forward(preprocess(crops, self.input_size))

    def predict_proba(self, crops: Sequence[np.ndarray]) -> np.ndarray:
        """Class probabilities ``(n, len(classes))`` of BGR crops, in one forward pass."""
        if len(crops) == 0:
            return np.zeros((0, len(self.classes)))
        return self.proba_of_logits(self.logits(crops))

    def proba_of_logits(self, z: np.ndarray) -> np.ndarray:
        """Probabilities of raw network outputs (background bias, then temperature)."""
        z = np.array(z, np.float64)
        if self.background_bias:
            z[:, self.classes.index('background')] += self.background_bias
        return _softmax(z / self.temperature)

    # the SVM's code, unchanged: argmax -> Prediction, and the cropping rules of the node
    _predictions = _svm.SignClassifier._predictions
    classify = _svm.SignClassifier.classify
    classify_boxes = _svm.SignClassifier.classify_boxes


# --- files ---------------------------------------------------------------------------------

def save_model(clf: CnnSignClassifier, path: str | os.PathLike) -> None:
    """Write ``clf`` as a compressed ``.npz`` of arrays and JSON metadata (no pickles)."""
    arrays = {'onnx': np.ascontiguousarray(clf.arrays['onnx'], np.uint8),
              'classes': np.array(clf.classes)}
    write_npz(path, arrays, {**clf.metadata, 'schema': SCHEMA, 'version': VERSION,
                             'classes': list(clf.classes)})


def from_contents(path: str, arrays: Mapping[str, np.ndarray], md: Mapping
                  ) -> CnnSignClassifier:
    """The classifier of a file's arrays and metadata (read by ``classifier.load_model``).

    Raises:
        ModelError: another version, a hash mismatch, or a network that does not load.
    """
    check_header(path, arrays, md, what='workzone_ros CNN sign classifier', schema=SCHEMA,
                 version=VERSION, retrain='workzone-ros train cnn', error=ModelError)
    try:
        return CnnSignClassifier(arrays['onnx'], [str(c) for c in arrays['classes']], md)
    except (KeyError, ValueError, TypeError, IndexError) as exc:
        raise ModelError(f'CNN sign classifier {path!r} is malformed: '
                         f'{one_line(exc)}') from None


def load_model(path: str | os.PathLike) -> CnnSignClassifier:
    """Read a CNN model file (as :func:`workzone_ros.core.classifier.load_model` does).

    Raises:
        ModelError: missing, truncated, corrupt, tampered, another version, or a sign
            classifier that is not a CNN.
    """
    model = _svm.load_model(path)
    if not isinstance(model, CnnSignClassifier):
        raise ModelError(f'{os.fspath(path)!r} is a sign classifier but not a CNN '
                         f'({model.method})')
    return model

