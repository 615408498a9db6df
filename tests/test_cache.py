"""The on-disk cache is bounded (least recently used entries go first), the compiled
model's structure records are keyed by the build settings they were built with, and every
entry is verified by its key and checksum when read (a wrong one is rebuilt with a warning)."""
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
    key = compiled.records.structure_record_key(functions)
    monkeypatch.setattr(compiled.toolchain, "CFLAGS", [*compiled.CFLAGS, "-fno-inline"])
    assert compiled.records.structure_record_key(functions) != key


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


# ---- every entry verified: checksum and key (issue 24 item 3) --------------------------------
def _written(tmp_path, kind):
    (path,) = (tmp_path / kind).glob("*.json")
    return path


def _cache_warnings(caught):
    return [str(w.message) for w in caught if issubclass(w.category, cache.CacheWarning)]


@pytest.mark.parametrize("alter", ["scaled numbers", "another key's file", "truncated",
                                   "not an object", "checksum of other numbers"])
def test_an_altered_table_entry_is_discarded_with_one_warning_naming_it(monkeypatch, tmp_path,
                                                                         alter):
    """Whatever is changed in an entry's file (its numbers, still valid JSON; the file of
    another key put in its place; half the file; another JSON value; the checksum), the
    reader gets no value, one warning naming the file, and the file is gone; the value
    stored again reads back exactly."""
    import json
    import warnings

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    value = [[1.0367, 1.0211, 0.1 + 0.2], [3.71, 6.23, 1e-300]]
    cache.store_table("kind", "line A", value)
    path = _written(tmp_path, "kind")
    assert cache.load_table("kind", "line A") == value
    entry = json.loads(path.read_text())
    if alter == "scaled numbers":
        entry["value"] = [[1.5 * v for v in row] for row in entry["value"]]
        path.write_text(json.dumps(entry))
    elif alter == "another key's file":
        cache.store_table("kind", "line B", value)
        other = next(p for p in (tmp_path / "kind").glob("*.json") if p != path)
        os.replace(other, path)
    elif alter == "truncated":
        path.write_text(path.read_text()[:40])
    elif alter == "not an object":
        path.write_text("[1, 2, 3]")
    else:
        entry["value"][0][0] = 1.5
        entry["sha256"] = cache.table_checksum("line A", value[::-1])
        path.write_text(json.dumps(entry))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert cache.load_table("kind", "line A") is None
        assert cache.load_table("kind", "line A") is None     # gone: a plain miss, no word
    said = _cache_warnings(caught)
    assert len(said) == 1 and str(path) in said[0] and "\n" not in said[0], said
    assert not path.exists()
    cache.store_table("kind", "line A", value)
    assert cache.load_table("kind", "line A") == value


def test_table_entries_read_back_exactly_and_old_ones_are_a_quiet_miss(monkeypatch, tmp_path):
    """The checksum is of the value's JSON text (hand-checked here with hashlib): rewriting an
    untouched entry with Python's json keeps it valid; an entry of the format before the
    checksums ({"key", "value"} only) is not used, without a warning."""
    import hashlib
    import json
    import warnings

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    value = {"constants": [63741423.624223284, -0.0, float("nan")], "jac_row": [0, 2], "n": 3,
             "library": "31ffefc2435a746ecd0c9269c370e39c", "name": "Zylinder \u00e4"}
    cache.store_table("kind", "model \u00e4", value)
    path = _written(tmp_path, "kind")
    entry = json.loads(path.read_text())
    assert entry["key"] == "model \u00e4"
    want = hashlib.sha256("model \u00e4".encode() + b"\0" + json.dumps(value).encode())
    assert entry["sha256"] == want.hexdigest() == cache.table_checksum("model \u00e4", value)
    path.write_text(json.dumps(entry))                       # the same text again
    got = cache.load_table("kind", "model \u00e4")
    assert json.dumps(got) == json.dumps(value)              # (NaN != NaN: compare the text)
    path.write_text(json.dumps({"key": "model \u00e4", "value": value}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert cache.load_table("kind", "model \u00e4") is None


@pytest.fixture(scope="module")
def default_rig_cache(tmp_path_factory):
    """A cache directory filled by one run of the default rig (a fresh process), and that
    run's summary. The run builds its library before it runs (not in the background, the
    command line's default, whose first run goes on with CVODES): the cache then holds the
    library whatever the build's time, and the reruns, compiled, give the same figures."""
    import json

    d = tmp_path_factory.mktemp("cache")
    out = _simulate(d, HYDROLINE_BACKGROUND_BUILD="0")
    assert out.returncode == 0 and "warning" not in out.stderr, out.stderr
    return d, json.loads(out.stdout)


def _simulate(cache_dir, **environment):
    """``hydroline simulate --json`` (the default rig) in a new process with this cache (and
    these environment variables)."""
    import subprocess
    import sys

    env = dict(os.environ, HYDROLINE_CACHE_DIR=str(cache_dir), **environment)
    return subprocess.run([sys.executable, "-m", "hydroline", "simulate", "--json"], env=env,
                          capture_output=True, text=True, timeout=300)


def _copy_of(default_rig_cache, tmp_path):
    import shutil

    d = tmp_path / "cache"
    shutil.copytree(default_rig_cache[0], d)
    return d


def _rerun_after(d, damaged: list, clean_summary):
    """Run the default rig again on the damaged cache: exit 0, one warning line per damaged
    file naming it, nothing blamed on the rig, and the paper's figures again (README:
    40.0 Hz / 1.00 MPa at the supply port, 31.0 Hz / 0.94 MPa at the return port)."""
    import json

    out = _simulate(d)
    assert out.returncode == 0, out.stderr
    lines = out.stderr.splitlines()
    assert len(lines) == len(damaged), lines
    for path in damaged:
        (line,) = [ln for ln in lines if str(path) in ln]
        assert line.startswith("hydroline simulate: warning: cache entry ")
        assert "discarded and rebuilt" in line
    said = out.stderr
    for path in damaged:
        said = said.replace(str(path), "PATH")
    for word in ("hose", "accumulator", "supply.", "return.", "error", "Traceback"):
        assert word not in said
    summary = json.loads(out.stdout)
    assert summary["supply"]["frequency_hz"] == pytest.approx(40.0, abs=0.05)
    assert summary["supply"]["amplitude_mpa"] == pytest.approx(1.00, abs=0.005)
    assert summary["return"]["frequency_hz"] == pytest.approx(31.0, abs=0.05)
    assert summary["return"]["amplitude_mpa"] == pytest.approx(0.94, abs=0.005)
    for side in ("supply", "return"):     # and those of the run that filled the cache
        assert summary[side] == clean_summary[side]
    return out


def test_tampered_line_tables_are_rebuilt_with_a_warning(default_rig_cache, tmp_path):
    """Issue 24: the cached correction factors alpha_i, beta_i scaled by 1.5 (still valid
    JSON) gave 25.8 Hz / 1.50 MPa, exit 0 and no word. The default rig's lines are now the
    exact-pole realisations (table ``residue_lines``): their matrices scaled by 1.5 likewise.
    Now: one warning naming each altered file, and 40.0 Hz / 1.00 MPa again."""
    import json

    def scaled(v):
        if isinstance(v, list):
            return [scaled(x) for x in v]
        if isinstance(v, dict):
            return {k: scaled(x) for k, x in v.items()}
        return 1.5 * v if isinstance(v, float) else v

    d = _copy_of(default_rig_cache, tmp_path)
    tables = sorted((d / "residue_lines").glob("*.json")) + sorted(
        (d / "correction_factors").glob("*.json"))
    assert tables
    for path in tables:
        entry = json.loads(path.read_text())
        entry["value"] = scaled(entry["value"])
        path.write_text(json.dumps(entry))
    _rerun_after(d, tables, default_rig_cache[1])
    again = _simulate(d)             # rebuilt: the next run has nothing to say
    assert again.returncode == 0 and again.stderr == ""


@pytest.mark.parametrize("damage", ["scaled constants", "shifted Jacobian rows", "truncated"])
def test_damaged_model_record_is_rebuilt_and_never_blames_the_rig(default_rig_cache, tmp_path,
                                                                  damage):
    """A model record with its constants scaled made the steady state fail with an error
    about the supply accumulator; shifted Jacobian rows ended in a traceback; half a file
    was a quiet miss. Each is now one warning naming the record, and the run as it should
    be."""
    import json

    d = _copy_of(default_rig_cache, tmp_path)
    (path,) = (d / "models").glob("*.json")
    entry = json.loads(path.read_text())
    if damage == "scaled constants":
        entry["value"]["constants"] = [10.0 * c for c in entry["value"]["constants"]]
        path.write_text(json.dumps(entry))
    elif damage == "shifted Jacobian rows":
        entry["value"]["jac_row"] = [r + 1 for r in entry["value"]["jac_row"]]
        path.write_text(json.dumps(entry))
    else:
        path.write_text(path.read_text()[:len(path.read_text()) // 2])
    _rerun_after(d, [path], default_rig_cache[1])


def stiffening_oscillator_network():
    """The oscillator of tests/test_compiled.py with a spring that stiffens (x^3 term): as many
    states, parameters and signals, another structure."""
    from dataclasses import dataclass

    from hydroline.engine import Network
    from test_compiled import Hold, Oscillator

    @dataclass(kw_only=True)
    class Stiffening(Oscillator):
        def derivatives(self, t, x, u, p):
            d = super().derivatives(t, x, u, p)
            return {"x": d["x"], "v": d["v"] - self.omega ** 2 * 1e6 * x["x"] ** 3}

    return Network([Hold(name="source"), Stiffening(name="osc", omega=219.0)])


@pytest.mark.parametrize("misfit", ["another library", "Jacobian rows out of range"])
def test_a_model_record_that_does_not_fit_is_rebuilt(monkeypatch, tmp_path, misfit):
    """A record with a valid checksum that still does not fit its model (written wrongly: it
    names the library of another structure with as many states, parameters and signals, or
    its Jacobian pattern has rows beyond the states) is discarded with one warning naming
    it and the model is built anew: the oscillator's exact step response (peak
    1 + exp(-pi zeta / sqrt(1 - zeta^2)) mm)."""
    import json
    import warnings

    from hydroline import compiled
    from hydroline.engine import integrate
    from test_compiled import _oscillator_peak, oscillator_network

    if not compiled.available():
        pytest.skip("no C compiler")
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled.toolchain, "_LIBS", {})
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    library = compiled.native_model(oscillator_network(omega=219.0)).library_path
    path = _written(tmp_path, "models")
    key = json.loads(path.read_text())["key"]
    record = cache.load_table("models", key)
    if misfit == "another library":    # a stiffening spring: more constants (another structure)
        other = compiled.native_model(stiffening_oscillator_network()).library_path
        assert other != library
        record["library"] = other.stem[3:]
    else:
        record["jac_row"] = [r + 2 for r in record["jac_row"]]
    cache.store_table("models", key, record)                 # with a checksum that fits it
    monkeypatch.setattr(compiled.records, "_MODELS", {})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = integrate(oscillator_network(omega=219.0), np.zeros(2), 0.05, solver="compiled")
    said = _cache_warnings(caught)
    assert len(said) == 1 and str(path) in said[0], said
    assert res.metadata["solver"] == "compiled"
    assert res["osc.x"].max() == pytest.approx(_oscillator_peak(), rel=2e-3)
    assert cache.load_table("models", key)["library"] == library.stem[3:]   # recorded anew


def test_kept_in_memory_is_per_thread_and_restored_after_overlapping_blocks():
    """Overlapping ``kept_in_memory`` blocks in two threads (a sweep on a Dask cluster of
    threads) leave the on-disk cache in use afterwards; inside, only their own thread skips it."""
    import threading

    from hydroline.lines import memo

    inside, leave = threading.Barrier(3), threading.Event()
    seen = {}

    def variant(name):
        with memo.kept_in_memory():
            inside.wait()                       # both threads inside at once
            seen[name] = memo._DISK.store
            leave.wait()

    threads = [threading.Thread(target=variant, args=(n,)) for n in ("a", "b")]
    for t in threads:
        t.start()
    inside.wait()
    seen["main"] = memo._DISK.store             # this thread is in no block
    leave.set()
    for t in threads:
        t.join()
    assert seen == {"a": False, "b": False, "main": True}
    assert memo._DISK.store is True


def test_a_shipped_table_is_read_where_the_cache_has_none(monkeypatch, tmp_path):
    """An entry shipped with the package (in the cache's format) is read where the cache has
    no file for its key and copied into the cache; one that fails its check is a quiet miss,
    and the package's file stays."""
    import shutil
    import warnings

    shipped = tmp_path / "shipped"
    monkeypatch.setattr(cache, "SHIPPED_TABLES", shipped)
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path / "made"))
    cache.store_table("kind", "key a", [1.5, 2.5])
    cache.store_table("kind", "key b", [3.0])
    shutil.copytree(tmp_path / "made", shipped)
    altered = shipped / "kind" / cache._table_path("kind", "key b", shipped).name
    altered.write_text(altered.read_text().replace("3.0", "4.5"))
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path / "empty"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert cache.load_table("kind", "key a") == [1.5, 2.5]
        assert cache.load_table("kind", "key b") is None
        assert cache.load_table("kind", "key c") is None
    assert _entries(tmp_path / "empty", "kind") == [cache._table_path("kind", "key a").name]
    assert altered.exists()


def test_the_default_rigs_line_realisations_are_shipped(monkeypatch, tmp_path):
    """The default rig's lines (open-loop step) are realised from the shipped tables in an
    empty cache, without computing one (they are out of date after a change of the line
    code: ``python tools/ship_tables.py`` writes them anew)."""
    from collections import OrderedDict

    from hydroline.lines import residue
    from hydroline.rigs import load_rig
    from hydroline.system import build_circuit

    def computed(*args):
        raise AssertionError("a default-rig line was computed: its table is not shipped; "
                             "run python tools/ship_tables.py")

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(residue._REALISATIONS, "memory", OrderedDict())
    monkeypatch.setattr(residue, "_realise", computed)
    build_circuit(load_rig(None))
    assert _entries(tmp_path, "residue_lines")


def test_the_default_fits_interpolation_nodes_are_shipped(monkeypatch, tmp_path):
    """A fit of the default rig's section-II bulk moduli interpolates their lines over Dn
    (:mod:`hydroline.lines.residue_table`) from nodes shipped with the package: in an empty
    cache, at the start values, none is computed (after a change of the line code ``python
    tools/ship_tables.py`` writes them anew)."""
    from hydroline.lines import residue_table
    from hydroline.rigs import load_rig
    from hydroline.system import build_circuit

    def computed(*args):
        raise AssertionError("an interpolation node of the default fit was computed: it is "
                             "not shipped; run python tools/ship_tables.py")

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    for kept in ("_NODES", "_STENCILS", "_SHARED"):
        monkeypatch.setattr(residue_table, kept, {})
    monkeypatch.setattr(residue_table, "_realised_node", computed)
    with residue_table.interpolated_lines():     # (as the fit's runs)
        build_circuit(load_rig(None))
    assert len(_entries(tmp_path, residue_table.NODE_TABLE)) >= residue_table.DEGREE + 1
