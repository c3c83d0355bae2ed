"""bake_cache: one bake for processes that miss the same entry at once; damaged entries are baked again."""

import multiprocessing
import time

import numpy as np

from prefilter.bake_cache import cache_dir, cached, cached_arrays


def _bake_and_save(log: str, out: str, arrays: bool) -> None:
    """In a child process: bake a slow entry through the cache, noting each bake in `log`."""

    def compute():
        with open(log, "a") as f:
            f.write("baked\n")
        time.sleep(1.0)  # long enough for the other process to miss the entry too
        return np.arange(6.0)

    if arrays:
        result = cached_arrays("test-lock", {"n": 6}, (), lambda: {"values": compute()})["values"]
    else:
        result = cached("test-lock", {"n": 6}, (), compute)
    np.save(out, result)


def test_processes_missing_the_same_entry_at_once_bake_it_once(tmp_path, monkeypatch):
    monkeypatch.setenv("PREFILTER_CACHE", str(tmp_path / "cache"))
    fork = multiprocessing.get_context("fork")
    for arrays in (False, True):
        log = tmp_path / f"log-{arrays}"
        children = [
            fork.Process(
                target=_bake_and_save, args=(str(log), str(tmp_path / f"out-{arrays}-{k}.npy"), arrays)
            )
            for k in range(2)
        ]
        for child in children:
            child.start()
        for child in children:
            child.join(30)
            assert child.exitcode == 0
        assert log.read_text().splitlines() == ["baked"]
        entries = [p.name for p in cache_dir().iterdir()]
        assert len(entries) == 1 and entries[0].startswith("test-lock-"), entries  # no lock file left
        for entry in cache_dir().iterdir():
            entry.unlink()
        for k in range(2):
            np.testing.assert_array_equal(np.load(tmp_path / f"out-{arrays}-{k}.npy"), np.arange(6.0))


def test_a_damaged_entry_is_baked_again(tmp_path, monkeypatch):
    monkeypatch.setenv("PREFILTER_CACHE", str(tmp_path))
    calls = []

    def compute():
        calls.append(1)
        return np.ones(3)

    cached("test-damaged", {}, (), compute)
    (entry,) = cache_dir().glob("test-damaged-*.npy")
    entry.write_bytes(b"not an array")
    np.testing.assert_array_equal(cached("test-damaged", {}, (), compute), np.ones(3))
    assert len(calls) == 2
    np.testing.assert_array_equal(np.load(entry), np.ones(3))
