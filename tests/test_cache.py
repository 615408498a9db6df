"""The on-disk cache is bounded (least recently used entries go first), and the compiled
model's structure records are keyed by the build settings they were built with."""
from __future__ import annotations

import os

import numpy as np
import pytest

from hydroline import cache


def _entries(tmp_path, kind):
    d = tmp_path / kind
    return sorted(p.name for p in d.iterdir() if p.suffix == ".json") if d.is_dir() else []


def test_tables_are_bounded_least_recently_used_first(monkeypatch, tmp_path):
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(cache, "MAX_ENTRIES", 20)
    monkeypatch.setattr(cache, "PRUNE_EVERY", 1)        # every write prunes
    for i in range(20):
        cache.store_table("kind", f"key {i}", [i])
    # every entry old, key 0 read (used) recently: it outlives the never-read ones
    for i, path in enumerate(sorted((tmp_path / "kind").iterdir())):
        os.utime(path, (1e9 + i, 1e9 + i))
    assert cache.load_table("kind", "key 0") == [0]
    for i in range(20, 30):
        cache.store_table("kind", f"key {i}", [i])
    kept = _entries(tmp_path, "kind")
    assert len(kept) <= 20
    assert cache.load_table("kind", "key 0") == [0]        # recently used: kept
    assert cache.load_table("kind", "key 29") == [29]      # just written: kept
    assert sum(cache.load_table("kind", f"key {i}") is not None for i in range(1, 20)) < 19


def test_prune_removes_old_temporary_files_only(monkeypatch, tmp_path):
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    d = tmp_path / "kind"
    d.mkdir()
    old, new = d / "a.tmp", d / "b.tmp"
    old.write_text("x")
    new.write_text("x")
    os.utime(old, (1e9, 1e9))
    assert cache.prune_tables("kind", 10) == 1
    assert not old.exists() and new.exists()
    assert cache.prune_tables("missing", 10) == 0


def test_structure_record_key_holds_the_compiler_flags(monkeypatch):
    from hydroline import compiled
    from hydroline.compiled.codegen import scaled_functions
    from hydroline.engine import Network
    from hydroline.components import StepCommand

    net = Network([StepCommand(name="u", quantity="pressure", initial=1.0, final=2.0,
                               time=0.1, connections={"command": "u"})],
                  warn_lost_flows=False)
    functions = scaled_functions(net.compile())
    key = compiled._structure_record_key(functions)
    monkeypatch.setattr(compiled, "CFLAGS", [*compiled.CFLAGS, "-fno-inline"])
    assert compiled._structure_record_key(functions) != key


def test_compiled_libraries_are_bounded_least_recently_used_first(monkeypatch, tmp_path):
    """hl_*.so files (with their build record and lock) beyond MAX_LIBRARIES go, oldest use
    first, down to 90 %; other files stay."""
    from hydroline import compiled

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    for i in range(12):
        for suffix in (".so", ".sha256", ".lock"):
            path = tmp_path / f"hl_{i:032x}{suffix}"
            path.write_text("x")
            os.utime(path, (1e9 + i, 1e9 + i))
    (tmp_path / "models").mkdir()
    (tmp_path / "notes.txt").write_text("mine")
    os.utime(tmp_path / f"hl_{0:032x}.so", (2e9, 2e9))      # library 0 used lately
    assert compiled.prune_libraries(12) == 0
    assert compiled.prune_libraries(10) == 3                # 12 -> 9 (90 % of 10)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert [n for n in left if n.endswith(".so")] == [f"hl_{i:032x}.so" for i in (0, 4, 5, 6, 7, 8, 9, 10, 11)]
    for i in (1, 2, 3):     # the record and lock went with their library
        assert not any(n.startswith(f"hl_{i:032x}") for n in left)
    assert "notes.txt" in left and "models" in left
    assert compiled.prune_libraries(0) == 8                 # the newest always stays
    assert sorted(p.name for p in tmp_path.glob("*.so")) == [f"hl_{0:032x}.so"]


def test_a_pruned_library_is_compiled_again(monkeypatch, tmp_path):
    from hydroline import compiled
    from hydroline.engine import Network, integrate

    if not compiled.available():
        pytest.skip("no C compiler")
    from test_engine import _vessel

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    net = Network(_vessel(outlet_read=True))
    first = integrate(net, np.array([1e6]), 0.02, dt_out=1e-3, solver="compiled")
    assert len(list(tmp_path.glob("hl_*.so"))) == 1
    (path,) = tmp_path.glob("hl_*.so")
    os.utime(path, (1e9, 1e9))
    (tmp_path / "hl_newer.so").write_text("x")      # the newest stays: ours goes
    assert compiled.prune_libraries(1) == 1 and not path.exists()
    again = integrate(Network(_vessel(outlet_read=True)), np.array([1e6]), 0.02, dt_out=1e-3,
                      solver="compiled")
    assert path.exists()                            # compiled again, same numbers
    assert np.array_equal(first["p_v"], again["p_v"])
