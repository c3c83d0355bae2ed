"""Content-addressed cache for bakes: the same inputs give the same bytes, computed once.

A bake is identified by its kind, a version and a hash of its inputs (parameters and arrays); results
are .npy files under $PREFILTER_CACHE (default ~/.cache/prefilter), written atomically.
"""

from __future__ import annotations

import hashlib
import json
import os
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np


def cache_dir() -> Path:
    return Path(os.environ.get("PREFILTER_CACHE", Path.home() / ".cache" / "prefilter"))


def input_hash(kind: str, params: dict, arrays: tuple[np.ndarray, ...] = ()) -> str:
    digest = hashlib.sha256(kind.encode())
    digest.update(json.dumps(params, sort_keys=True, default=float).encode())
    for array in arrays:
        a = np.ascontiguousarray(array)
        digest.update(f"{a.dtype.str}{a.shape}".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()[:32]


def cached(
    kind: str, params: dict, arrays: tuple[np.ndarray, ...], compute: Callable[[], np.ndarray]
) -> np.ndarray:
    """Return the bake for these inputs from the cache, computing and storing it on a miss."""
    path = cache_dir() / f"{kind}-{input_hash(kind, params, arrays)}.npy"
    if path.is_file():
        try:
            return np.load(path)
        except (OSError, ValueError):
            path.unlink(missing_ok=True)  # a damaged entry is recomputed
    result = compute()
    _store(path, lambda f: np.save(f, result))
    return result


def cached_arrays(
    kind: str,
    params: dict,
    arrays: tuple[np.ndarray, ...],
    compute: Callable[[], dict[str, np.ndarray]],
) -> dict[str, np.ndarray]:
    """`cached` for a bake made of several named arrays (stored as one .npz)."""
    path = cache_dir() / f"{kind}-{input_hash(kind, params, arrays)}.npz"
    if path.is_file():
        try:
            with np.load(path) as data:
                return {name: data[name] for name in data.files}
        except (OSError, ValueError, KeyError):
            path.unlink(missing_ok=True)
    result = compute()
    _store(path, lambda f: np.savez(f, **result))
    return result


def _store(path: Path, write: Callable) -> None:
    """Write atomically (temp file, then rename), so an interrupted bake leaves no damaged entry."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
        with open(tmp, "wb") as f:
            write(f)
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only cache only costs time
