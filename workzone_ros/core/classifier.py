"""Work-zone sign classifier: log-polar features, PCA, RBF SVM with probabilities (no ROS).

Seo et al., section III.B (and Lee et al., III.C): a crop is intensity-normalised, resampled to a
32 x 32 log-polar image (``workzone_ros.core.features``), projected on the 10 leading
principal components of the training set (the seed reports they hold 95 % of the variance,
Lee et al. 93 %; ours is measured and stored in the metadata) and classified by a one-vs-one
RBF support vector machine whose C and gamma are chosen by cross-validation.  LDA and kNN
(k = 10) on the same features are the seed's baselines.  Optional extra features (colour
layout, left-right asymmetry) are standardised and appended after the PCA.

Probabilities are libsvm's: each pair (i, j) gets Platt's sigmoid ``r_ij = 1 / (1 + exp(A f
+ B))`` of its decision value ``f``, fitted on out-of-fold decision values, and the pairwise
``r_ij`` are coupled into class probabilities by Wu, Lin and Weng's method 2 (the
minimiser of ``p^T Q p`` on the simplex, solved here exactly as one small linear system
instead of libsvm's fixed-point iteration).

A model is data, not code: arrays (PCA mean and components, support vectors, dual
coefficients, intercepts, gamma, the sigmoids; or LDA / kNN arrays) plus JSON metadata in a
compressed ``.npz`` loaded with ``allow_pickle=False``, and the predictor is rebuilt from the
arrays here.  The metadata carries the schema version and a SHA-256 over every array and the
rest of the metadata, so a tampered file is refused like a truncated or foreign one.
"""
from __future__ import annotations

import datetime as _dt
import os
from dataclasses import dataclass
from typing import Callable, Mapping, Optional, Sequence

import numpy as np

from workzone_ros.core import features as ft
from workzone_ros.core.model_files import check_header, one_line, read_npz, write_npz

__all__ = [
    'SCHEMA', 'VERSION', 'DEFAULT_MODEL', 'METHODS', 'ModelError', 'Prediction',
    'SignClassifier', 'fit', 'fit_arrays', 'load_model', 'save_model', 'couple_pairwise',
]

SCHEMA = 'workzone_ros/SignClassifier'
VERSION = 1
#: The shipped model, relative to ``config/`` (resolve with ``resources.config_path``).
DEFAULT_MODEL = 'models/sign_classifier_cnn.npz'
METHODS = ('svm', 'lda', 'knn')
#: Multiples of 1 / (n_features * var(X)) (scikit-learn's ``gamma='scale'``) searched by CV.
GAMMA_FACTORS = (0.25, 0.5, 1.0, 2.0, 4.0)
C_VALUES = (1.0, 10.0, 100.0, 1000.0)
_MIN_PROB = 1e-7                      # libsvm's clip of the pairwise probabilities


class ModelError(ValueError):
    """A sign classifier file that is missing, unreadable, tampered or of another version."""


@dataclass(frozen=True)
class Prediction:
    """The classifier's answer for one crop.

    Attributes:
        class_key: the most probable class (a key of ``signs.CLASSIFIER_KEYS``, or a
            general sign key when the model has those classes).
        score: probability of ``class_key`` (0..1).
        probabilities: probability of every class of the model.
    """

    class_key: str
    score: float
    probabilities: dict[str, float]


def _pairs(k: int) -> list[tuple[int, int]]:
    """libsvm's one-vs-one pair order: (0,1), (0,2), ..., (k-2, k-1)."""
    return [(i, j) for i in range(k) for j in range(i + 1, k)]


def couple_pairwise(r: np.ndarray, k: int) -> np.ndarray:
    """Class probabilities from pairwise ones (Wu, Lin and Weng 2004, method 2).

    Args:
        r: ``(n, k (k - 1) / 2)`` probabilities that the sample is class ``i`` rather than
            ``j``, in :func:`_pairs` order.
        k: number of classes.

    Returns:
        ``(n, k)`` probabilities (rows sum to 1).
    """
    n = r.shape[0]
    if k == 2:
        return np.column_stack([r[:, 0], 1.0 - r[:, 0]])
    r = np.clip(r, _MIN_PROB, 1.0 - _MIN_PROB)
    i, j = np.array(_pairs(k)).T
    R = np.zeros((n, k, k))
    R[:, i, j] = r
    R[:, j, i] = 1.0 - r
    Q = -R.transpose(0, 2, 1) * R                     # Q[t, j] = -r_jt r_tj
    diag = np.arange(k)
    Q[:, diag, diag] = np.einsum('njt,njt->nt', R, R)  # sum_j r_jt^2
    M = np.zeros((n, k + 1, k + 1))
    M[:, :k, :k] = Q
    M[:, :k, k] = 1.0
    M[:, k, :k] = 1.0
    rhs = np.zeros((n, k + 1, 1))
    rhs[:, k] = 1.0
    p = np.clip(np.linalg.solve(M, rhs)[:, :k, 0], 0.0, None)
    return p / p.sum(axis=1, keepdims=True)


def _softmax(z: np.ndarray) -> np.ndarray:
    e = np.exp(z - z.max(axis=1, keepdims=True))
    return e / e.sum(axis=1, keepdims=True)


class SignClassifier:
    """A trained classifier rebuilt from arrays; see :func:`fit` and :func:`load_model`.

    Attributes:
        classes: class keys, in the order of the probability columns.
        metadata: schema version, feature kind, method, training sources, PCA variance
            held, hyper-parameters, date, ...
        arrays: the model's parameters by name (what :func:`save_model` writes).
    """

    def __init__(self, classes: Sequence[str], arrays: Mapping[str, np.ndarray],
                 metadata: Mapping):
        self.classes: tuple[str, ...] = tuple(str(c) for c in classes)
        self.arrays: dict[str, np.ndarray] = {k: np.asarray(v) for k, v in arrays.items()}
        self.metadata: dict = dict(metadata)
        self.method: str = str(self.metadata['method'])
        self.features: str = str(self.metadata['features'])
        self.margin: float = float(self.metadata.get('margin', 0.1))
        if self.method not in METHODS:
            raise ValueError(f'unknown method {self.method!r}')
        ft._parts(self.features)
        self._check_shapes()
        if self.method == 'svm':
            self._prepare_svm()

    # --- construction ---------------------------------------------------------------------
    def _check_shapes(self) -> None:
        a, k = self.arrays, len(self.classes)
        comps = a['pca_components']
        if comps.ndim != 2 or a['pca_mean'].shape != (comps.shape[1],):
            raise ValueError('PCA mean and components do not match')
        m = comps.shape[0] + a['extra_mean'].size
        need = {'svm': ('support_vectors', 'dual_coef', 'n_support', 'intercept', 'prob_a',
                        'prob_b', 'gamma'),
                'lda': ('coef', 'intercept'), 'knn': ('train_x', 'train_y', 'k')}[self.method]
        missing = [n for n in need if n not in a]
        if missing:
            raise ValueError(f'{self.method} model lacks {", ".join(missing)}')
        width = {'svm': 'support_vectors', 'lda': 'coef', 'knn': 'train_x'}[self.method]
        if a[width].ndim != 2 or a[width].shape[1] != m:
            raise ValueError(f'{width} has shape {a[width].shape}, expected (*, {m})')
        if self.method == 'svm' and (a['n_support'].shape != (k,)
                                     or a['dual_coef'].shape[0] != k - 1
                                     or a['prob_a'].shape != (k * (k - 1) // 2,)):
            raise ValueError('SVM arrays do not match the class count')

    def _prepare_svm(self) -> None:
        """Per-class slices of the dual coefficients and the pair index arrays.

        libsvm's decision for the pair (i, j) sums the kernel values of class i's support
        vectors times their coefficients in row j - 1 and of class j's times row i; summing
        each class's block once for every row turns all pairs into k small products.
        """
        a, k = self.arrays, len(self.classes)
        start = np.r_[0, np.cumsum(a['n_support'])].astype(int)
        self._blocks = [(slice(start[c], start[c + 1]),
                         np.ascontiguousarray(a['dual_coef'][:, start[c]:start[c + 1]].T))
                        for c in range(k)]
        i, j = np.array(_pairs(k)).T
        self._pair_index = (i, j - 1, j, i)
        # the kernel in float32: |z - sv|^2 ~ 1e3..1e4 and gamma ~ 1e-4, so its rounding
        # (~1e-7 of the exponent) is far below the probabilities' precision
        self._sv32 = a['support_vectors'].astype(np.float32)
        self._sv_sq = (self._sv32 ** 2).sum(1)
        self._neg_gamma = np.float32(-float(a['gamma']))

    # --- prediction -----------------------------------------------------------------------
    def transform(self, crops: Sequence[np.ndarray]) -> np.ndarray:
        """The reduced feature vectors (PCA scores, then scaled extras) of BGR crops."""
        md = self.metadata
        base, extra = ft.features(self.features, crops, md.get('rho', 32), md.get('theta', 32),
                                  md.get('raw_size', 100))
        return self.reduce(base, extra)

    def reduce(self, base: np.ndarray, extra: Optional[np.ndarray]) -> np.ndarray:
        """PCA projection of ``base`` features with the standardised ``extra`` appended."""
        a = self.arrays
        z = (base - a['pca_mean']) @ a['pca_components'].T
        if a['extra_mean'].size:
            z = np.hstack([z, (extra - a['extra_mean']) * a['extra_scale']])
        return z.astype(np.float64)

    def predict_proba_reduced(self, z: np.ndarray) -> np.ndarray:
        """Class probabilities ``(n, len(classes))`` of reduced feature vectors."""
        a, k = self.arrays, len(self.classes)
        if self.method == 'svm':
            z32 = z.astype(np.float32)
            d2 = (z32 * z32).sum(1)[:, None] + self._sv_sq[None] - 2.0 * z32 @ self._sv32.T
            K = np.exp(self._neg_gamma * np.maximum(d2, 0.0)).astype(np.float64)
            S = np.stack([K[:, sl] @ coef for sl, coef in self._blocks], axis=1)  # n, k, k-1
            i, j1, j, i2 = self._pair_index
            dec = S[:, i, j1] + S[:, j, i2] + a['intercept']
            r = 1.0 / (1.0 + np.exp(np.clip(dec * a['prob_a'] + a['prob_b'], -500, 500)))
            return couple_pairwise(r, k)
        if self.method == 'lda':
            dec = z @ a['coef'].T + a['intercept']
            if k == 2:
                p1 = 1.0 / (1.0 + np.exp(-dec[:, 0]))
                return np.column_stack([1.0 - p1, p1])
            return _softmax(dec)
        X, y, nn = a['train_x'], a['train_y'], int(a['k'])
        d2 = (z * z).sum(1)[:, None] + (X * X).sum(1)[None] - 2.0 * z @ X.T
        near = np.argpartition(d2, min(nn, X.shape[0]) - 1, axis=1)[:, :nn]
        votes = np.zeros((z.shape[0], k))
        np.add.at(votes, (np.repeat(np.arange(z.shape[0]), near.shape[1]), y[near].ravel()), 1)
        return votes / votes.sum(axis=1, keepdims=True)

    def predict_proba(self, crops: Sequence[np.ndarray]) -> np.ndarray:
        """Class probabilities ``(n, len(classes))`` of BGR crops."""
        if len(crops) == 0:
            return np.zeros((0, len(self.classes)))
        return self.predict_proba_reduced(self.transform(crops))

    def _predictions(self, proba: np.ndarray) -> list[Prediction]:
        out = []
        for best, row in zip(proba.argmax(axis=1).tolist(), proba.tolist()):
            out.append(Prediction(self.classes[best], row[best], dict(zip(self.classes, row))))
        return out

    def classify(self, crops: Sequence[np.ndarray]) -> list[Prediction]:
        """Classify BGR ``uint8`` crops in one batch."""
        return self._predictions(self.predict_proba(crops))

    def classify_boxes(self, frame_bgr: np.ndarray,
                       boxes: Sequence[tuple[float, float, float, float]],
                       margin: Optional[float] = None) -> list[Optional[Prediction]]:
        """Crop every box of a frame (:func:`features.crop_sign`) and classify in one batch.

        Args:
            frame_bgr: the camera frame.
            boxes: ``(x, y, w, h)`` pixel boxes.
            margin: crop margin; ``None`` uses the model's (metadata ``margin``).

        Returns:
            One prediction per box, ``None`` where the box has no pixel in the image.
        """
        m = self.margin if margin is None else float(margin)
        square = bool(self.metadata.get('square_crops', True))
        crops = [ft.crop_sign(frame_bgr, b, m, square)[0] for b in boxes]
        idx = [i for i, c in enumerate(crops) if c is not None]
        preds = self.classify([crops[i] for i in idx])
        out: list[Optional[Prediction]] = [None] * len(boxes)
        for i, p in zip(idx, preds):
            out[i] = p
        return out


# --- training ------------------------------------------------------------------------------

def _platt(f: np.ndarray, positive: np.ndarray) -> tuple[float, float]:
    """Platt's sigmoid ``P(positive | f) = 1 / (1 + exp(A f + B))`` with his target smoothing.

    Newton's method with backtracking (Lin, Lin and Weng 2007, as in libsvm).
    """
    n1, n0 = int(positive.sum()), int((~positive).sum())
    t = np.where(positive, (n1 + 1.0) / (n1 + 2.0), 1.0 / (n0 + 2.0))
    A, B = 0.0, float(np.log((n0 + 1.0) / (n1 + 1.0)))

    def loss(a, b):
        z = a * f + b
        return float(np.sum(np.where(z >= 0, t * z + np.log1p(np.exp(-z)),
                                     (t - 1) * z + np.log1p(np.exp(z)))))
    value = loss(A, B)
    for _ in range(100):
        z = A * f + B
        p = np.where(z >= 0, np.exp(-z) / (1 + np.exp(-z)), 1 / (1 + np.exp(z)))
        d2 = p * (1 - p)
        h11, h22, h21 = 1e-12 + (f * f * d2).sum(), 1e-12 + d2.sum(), (f * d2).sum()
        d1 = t - p
        g1, g2 = (f * d1).sum(), d1.sum()
        if abs(g1) < 1e-5 and abs(g2) < 1e-5:
            break
        det = h11 * h22 - h21 * h21
        dA, dB = -(h22 * g1 - h21 * g2) / det, -(-h21 * g1 + h11 * g2) / det
        gd, step = g1 * dA + g2 * dB, 1.0
        while step >= 1e-10:
            new = loss(A + step * dA, B + step * dB)
            if new < value + 1e-4 * step * gd:
                A, B, value = A + step * dA, B + step * dB, new
                break
            step /= 2
        else:
            break
    return float(A), float(B)


def _fit_svm(z: np.ndarray, y: np.ndarray, k: int, seed: int, cv: int,
             progress: Optional[Callable[[str], None]]) -> tuple[dict, dict]:
    """RBF SVM (C, gamma by grid-searched CV), then per-pair Platt sigmoids on CV decisions."""
    from sklearn.model_selection import GridSearchCV, StratifiedKFold, cross_val_predict
    from sklearn.svm import SVC
    scale = 1.0 / (z.shape[1] * z.var())
    folds = max(2, min(cv, int(np.bincount(y, minlength=k).min())))
    skf = StratifiedKFold(folds, shuffle=True, random_state=seed)
    grid = {'C': list(C_VALUES), 'gamma': [g * scale for g in GAMMA_FACTORS]}
    search = GridSearchCV(SVC(kernel='rbf', decision_function_shape='ovo'), grid,
                          scoring='f1_macro', cv=skf, n_jobs=1).fit(z, y)
    best = search.best_params_
    if progress:
        progress(f'svm: C={best["C"]:g} gamma={best["gamma"]:.4g} (cv macro F1 '
                 f'{search.best_score_:.4f} over {len(C_VALUES) * len(GAMMA_FACTORS)} settings)')
    svc = SVC(kernel='rbf', decision_function_shape='ovo', **best).fit(z, y)
    oof = cross_val_predict(SVC(kernel='rbf', decision_function_shape='ovo', **best), z, y,
                            cv=skf, method='decision_function')
    if k == 2:
        oof = -oof[:, None]                              # libsvm sign: positive = class 0
    prob_a, prob_b = [], []
    for p, (i, j) in enumerate(_pairs(k)):
        sel = (y == i) | (y == j)
        A, B = _platt(oof[sel, p], y[sel] == i)
        prob_a.append(A)
        prob_b.append(B)
    arrays = {'support_vectors': svc.support_vectors_, 'dual_coef': svc._dual_coef_,
              'n_support': svc._n_support.astype(np.int64), 'intercept': svc._intercept_,
              'prob_a': np.array(prob_a), 'prob_b': np.array(prob_b),
              'gamma': np.array(float(best['gamma']))}
    hyper = {'C': float(best['C']), 'gamma': float(best['gamma']),
             'gamma_factor_of_scale': float(best['gamma'] / scale),
             'cv_macro_f1': round(float(search.best_score_), 4), 'cv_folds': folds}
    return arrays, hyper


def _fit_head(method: str, z: np.ndarray, y: np.ndarray, k: int, seed: int, cv: int,
              knn_k: int, progress) -> tuple[dict, dict]:
    if method == 'svm':
        return _fit_svm(z, y, k, seed, cv, progress)
    if method == 'lda':
        from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
        lda = LinearDiscriminantAnalysis().fit(z, y)
        return {'coef': np.atleast_2d(lda.coef_), 'intercept': np.atleast_1d(lda.intercept_)}, {}
    return ({'train_x': z.copy(), 'train_y': y.astype(np.int64), 'k': np.array(knn_k)},
            {'k': knn_k})


def fit_arrays(base: np.ndarray, extra: Optional[np.ndarray], labels: Sequence[str],
               classes: Sequence[str], *, features: str = 'logpolar', method: str = 'svm',
               n_components: int = 10, seed: int = 0, cv: int = 3, knn_k: int = 10,
               margin: float = 0.1, metadata: Optional[Mapping] = None,
               progress: Optional[Callable[[str], None]] = None) -> SignClassifier:
    """Fit PCA and the classifier on precomputed features (see :func:`fit`)."""
    from sklearn.decomposition import PCA
    if method not in METHODS:
        raise ValueError(f'unknown method {method!r}; known: {", ".join(METHODS)}')
    classes = tuple(classes)
    index = {c: i for i, c in enumerate(classes)}
    y = np.array([index[c] for c in labels], np.int64)
    present = np.bincount(y, minlength=len(classes))
    if (present < 2).any():
        few = [f'{c} ({n})' for c, n in zip(classes, present) if n < 2]
        raise ValueError(f'too few training crops (need 2 per class) for class(es) '
                         f'{", ".join(few)}')
    pca = PCA(n_components=n_components, svd_solver='randomized', random_state=seed).fit(base)
    z = pca.transform(base)
    arrays = {'pca_mean': pca.mean_.astype(np.float32),
              'pca_components': pca.components_.astype(np.float32),
              'extra_mean': np.zeros(0, np.float32), 'extra_scale': np.zeros(0, np.float32)}
    if extra is not None:
        # standardise, then give each extra the spread of an average principal component
        spread = float(np.sqrt(pca.explained_variance_.mean()))
        arrays['extra_mean'] = extra.mean(0).astype(np.float32)
        arrays['extra_scale'] = (spread / (extra.std(0) + 1e-6)).astype(np.float32)
        z = np.hstack([z, (extra - arrays['extra_mean']) * arrays['extra_scale']])
    head, hyper = _fit_head(method, z.astype(np.float64), y, len(classes), seed, cv, knn_k,
                            progress)
    held = float(pca.explained_variance_ratio_.sum())
    md = {'schema': SCHEMA, 'version': VERSION, 'method': method, 'features': features,
          'rho': 32, 'theta': 32, 'raw_size': 100, 'margin': margin, 'square_crops': True,
          'n_components': n_components, 'pca_variance_held': round(held, 4),
          'hyper': hyper, 'train_counts': {c: int(n) for c, n in zip(classes, present)},
          'date': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds')}
    md.update(metadata or {})
    return SignClassifier(classes, {**arrays, **head}, md)


def fit(crops: Sequence[np.ndarray], labels: Sequence[str], classes: Sequence[str], *,
        features: str = 'logpolar', method: str = 'svm', n_components: int = 10,
        seed: int = 0, cv: int = 3, knn_k: int = 10, margin: float = 0.1,
        metadata: Optional[Mapping] = None,
        progress: Optional[Callable[[str], None]] = None) -> SignClassifier:
    """Train a classifier on BGR crops.

    Args:
        crops: BGR ``uint8`` crops.
        labels: class key of every crop.
        classes: the model's classes (each must have crops).
        features: a kind of ``features.FEATURE_KINDS`` (``logpolar`` is the seed's).
        method: ``svm`` (the seed's), ``lda`` or ``knn``.
        n_components: principal components kept (seed: 10).
        seed: randomness of the PCA solver and the CV folds.
        cv: cross-validation folds of the SVM's C / gamma search and its sigmoids.
        knn_k: neighbours of the kNN baseline (seed: 10).
        margin: crop margin stored for ``classify_boxes``.
        metadata: extra metadata (training sources, ...).
        progress: status callback.

    Raises:
        ValueError: unknown method or feature kind, or a class without crops.
    """
    base, extra = ft.features(features, crops)
    return fit_arrays(base, extra, labels, classes,
                      features=features, method=method, n_components=n_components, seed=seed,
                      cv=cv, knn_k=knn_k, margin=margin, metadata=metadata, progress=progress)


# --- files ---------------------------------------------------------------------------------

def save_model(clf: SignClassifier, path: str | os.PathLike) -> None:
    """Write ``clf`` as a compressed ``.npz`` of arrays and JSON metadata (no pickles)."""
    arrays = {f'p_{k}': v for k, v in clf.arrays.items()}
    arrays['classes'] = np.array(clf.classes)
    write_npz(path, arrays, {**clf.metadata, 'schema': SCHEMA, 'version': VERSION,
                             'classes': list(clf.classes)})


def load_model(path: str | os.PathLike) -> SignClassifier:
    """Read a model written by :func:`save_model`, without executing anything from it.

    A CNN model file (``workzone_ros.core.cnn_classifier``, schema
    ``workzone_ros/SignClassifierCNN``) gives a ``CnnSignClassifier`` instead: the same
    interface, so a model path can name either kind.

    Raises:
        ModelError: the file is missing, truncated or corrupt, not a sign classifier, of
            another schema version, or its arrays / metadata do not match its hash.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ModelError(f'sign classifier {path!r} does not exist; train one with '
                         "'workzone-ros train classifier' or set the model path")
    arrays, md = read_npz(path, 'workzone_ros sign classifier', ModelError)
    if isinstance(md, dict) and md.get('schema') == SCHEMA + 'CNN':   # cnn_classifier.SCHEMA
        from workzone_ros.core import cnn_classifier  # the CNN run by cv2.dnn
        return cnn_classifier.from_contents(path, arrays, md)
    check_header(path, arrays, md, what='workzone_ros sign classifier', schema=SCHEMA,
                 version=VERSION, retrain='workzone-ros train classifier', error=ModelError)
    try:
        params = {k[2:]: v for k, v in arrays.items() if k.startswith('p_')}
        return SignClassifier([str(c) for c in arrays['classes']], params, md)
    except (KeyError, ValueError, TypeError, IndexError) as exc:
        raise ModelError(f'sign classifier {path!r} is malformed: {one_line(exc)}') from None
