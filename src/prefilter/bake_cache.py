"""Content-addressed cache for bakes: the same inputs give the same bytes, computed once.

A bake is identified by its kind, a version and a hash of its inputs (parameters and arrays); results
are .npy files under $PREFILTER_CACHE (default ~/.cache/prefilter), written atomically. A miss is baked
under an exclusive lock on the entry (POSIX flock): processes that miss the same entry at once (the test
suite's two workers reaching the same preset) wait for the first one's bake instead of repeating it. On a
clean machine the diffraction presets' tables were baked twice at once, 78 s of multi-threaded FFTs each,
and took 216 s of the suite's 703.
"""

from __future__ import annotations

import hashlib
import json
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
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
    return _cached_entry(path, np.load, compute, np.save)


def cached_arrays(
    kind: str,
    params: dict,
    arrays: tuple[np.ndarray, ...],
    compute: Callable[[], dict[str, np.ndarray]],
) -> dict[str, np.ndarray]:
    """`cached` for a bake made of several named arrays (stored as one .npz)."""
    path = cache_dir() / f"{kind}-{input_hash(kind, params, arrays)}.npz"
    return _cached_entry(path, _load_npz, compute, lambda f, result: np.savez(f, **result))


def _cached_entry(path: Path, load: Callable, compute: Callable, save: Callable):
    """The entry at path; on a miss baked (once across processes) and saved with save(file, result)."""
    result = _load(path, load)
    if result is not None:
        return result
    with _bake_lock(path):
        result = _load(path, load)  # baked by another process while this one waited
        if result is None:
            result = compute()
            _store(path, lambda f: save(f, result))
    return result


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as data:
        return {name: data[name] for name in data.files}


def _load(path: Path, load: Callable):
    """The entry at path, or None if there is none; a damaged entry is removed (and recomputed)."""
    if not path.is_file():
        return None
    try:
        return load(path)
    except (OSError, ValueError, KeyError):
        path.unlink(missing_ok=True)
        return None


@contextmanager
def _bake_lock(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on the entry at path while it is baked (none where locks cannot be taken: a
    read-only cache, or a system without flock; then concurrent misses bake twice, as before). The lock
    file is removed before it is released: the entry is stored by then, so a process that opens a new lock
    file afterwards finds the entry once it holds that lock."""
    lock_path = path.with_name(f".{path.name}.lock")
    try:
        import fcntl

        path.parent.mkdir(parents=True, exist_ok=True)
        lock = open(lock_path, "a")  # noqa: SIM115 (closed below)
    except (ImportError, OSError):
        yield
        return
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield
    finally:
        lock_path.unlink(missing_ok=True)
        lock.close()  # releases the lock


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
