"""Versioned model files: compressed ``.npz`` of arrays plus JSON metadata, never pickles.

Every trained model of the project (sign classifiers, the shape cascades) is written and
read the same way, so a missing, truncated, tampered, foreign or other-version file is one
clear line naming the problem, and nothing in a file is ever executed:

* :func:`write_npz` stores the arrays and the metadata with ``schema``, ``version`` and a
  SHA-256 over both (:func:`digest`), through a temporary file (a crash never leaves half a
  model);
* :func:`read_npz` loads with ``allow_pickle=False``;
* :func:`check_header` checks the schema, the version and the hash.

No rclpy import.
"""
from __future__ import annotations

import hashlib
import json
import os
import zipfile
from typing import Mapping

import numpy as np

__all__ = ['digest', 'one_line', 'write_npz', 'read_npz', 'check_header']


def digest(arrays: Mapping[str, np.ndarray], metadata: Mapping) -> str:
    """SHA-256 over every array (name, dtype, shape, bytes) and the metadata but its hash."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f'{name}|{a.dtype.str}|{a.shape}|'.encode())
        h.update(a.tobytes())
    md = {k: v for k, v in metadata.items() if k != 'sha256'}
    h.update(json.dumps(md, sort_keys=True).encode())
    return h.hexdigest()


def one_line(exc: BaseException) -> str:
    """An exception's text on one line (its type when it has none)."""
    return ' '.join(str(exc).split()) or type(exc).__name__


def write_npz(path: str | os.PathLike, arrays: Mapping[str, np.ndarray],
              metadata: Mapping) -> None:
    """Write ``arrays`` and ``metadata`` (plus its ``sha256``) to ``path`` atomically."""
    path = os.fspath(path)
    os.makedirs(os.path.dirname(path) or '.', exist_ok=True)
    md = dict(metadata)
    md['sha256'] = digest(arrays, md)
    tmp = path + '.tmp.npz'
    np.savez_compressed(tmp, metadata=np.array(json.dumps(md, sort_keys=True)), **arrays)
    os.replace(tmp, path)


def read_npz(path: str, what: str, error: type[Exception]
             ) -> tuple[dict[str, np.ndarray], dict]:
    """``(arrays, metadata)`` of an existing file; ``error`` (one line) when it cannot be
    read or is not a model file at all (``what`` names the kind in the message)."""
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise error(f'{path!r} is not a {what} (not an .npz)')
        with z:
            if 'metadata' not in z.files:
                raise error(f'{path!r} is not a {what} (no metadata)')
            md = json.loads(str(z['metadata']))
            arrays = {k: z[k] for k in z.files if k != 'metadata'}
    except error:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError, AttributeError,
            json.JSONDecodeError) as exc:
        raise error(f'cannot read {what} {path!r} (truncated or corrupt?): '
                    f'{one_line(exc)}') from None
    return arrays, md


def check_header(path: str, arrays: Mapping[str, np.ndarray], md: object, *, what: str,
                 schema: str, version: int, retrain: str, error: type[Exception]) -> None:
    """Raise ``error`` (one line) unless ``md`` is ``schema`` at ``version`` and the hash
    matches; ``retrain`` is the command that makes a current file."""
    if not isinstance(md, dict) or md.get('schema') != schema:
        raise error(f'{path!r} is not a {what} (schema '
                    f'{md.get("schema") if isinstance(md, dict) else None!r})')
    if md.get('version') != version:
        raise error(f'{path!r} is {what} version {md.get("version")!r}; this build reads '
                    f'version {version} (retrain with {retrain})')
    if md.get('sha256') != digest(arrays, md):
        raise error(f'{path!r} fails its integrity check (arrays or metadata changed '
                    'after training)')
