"""Rig-file fuzz (issue 14): every mutated rig either runs or is refused with one line naming
the parameter -- never a traceback, a silent misread, a hang or a silent default.

A seeded generator mutates the default rig (values scaled by powers of ten, negated, zeroed,
given the wrong unit, no unit, a decimal comma, two numbers, an exponent tower, a 100,000-digit
number, lists nested thousands deep, keys deleted or unknown, text parameters garbled) and
writes each as a TOML file. In-process, through the loading and validation layer that every
command shares (``load_rig`` -> scenario -> ``build_network``), each must either build, with
every deleted key that changes the result listed by ``defaults_used``, or raise a ValueError
(RigError, UnitError) whose message is one line starting with a rig path. A handful of them
then go through the real command line (``hydroline simulate FILE --json``): exit 0 with
finite JSON, or exit 2 with one line on stderr.
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import time
import tomllib
from importlib import resources

import numpy as np
import pytest

from hydroline.cli import main
from hydroline.rigs import SCHEMA, load_rig
from hydroline.rigs.parameters import PARAMETERS, defaults_used
from hydroline.scenarios import build_scenario
from hydroline.system import build_network

N_RIGS = 240
SEED = 20261123

BASE = tomllib.loads(resources.files("hydroline.rigs").joinpath("ayalew2005.toml").read_text())

#: Text values that must never be read as a number (each one a reproducer of issue 14).
BAD_TEXT = ["20,7 MPa", "MPa", "cm^2", "2 3 m", "20.7 MPa 3", "9**9**9 m", "1" * 100_000 + " m",
            "nan Pa", "inf m", "", "   ", "3 m +", "1e400 m", "abc", "1 foo", "N m", "3 N m",
            "-", "1 000 m", "0x10 m"]


def _toml_value(v, depth=0):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)          # a JSON string is a valid TOML basic string
    if isinstance(v, (int, float)):
        return repr(v) if math.isfinite(v) else ("nan" if v != v else ("inf" if v > 0 else "-inf"))
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x, depth + 1) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(x, depth + 1)}"
                               for k, x in v.items()) + "}"
    raise TypeError(type(v))


def _to_toml(tree) -> str:
    lines = []

    def table(prefix, node):
        scalars = {k: v for k, v in node.items() if not isinstance(v, dict)}
        if prefix:
            lines.append(f"[{prefix}]")
        for k, v in scalars.items():
            lines.append(f"{json.dumps(k)} = {_toml_value(v)}")
        for k, v in node.items():
            if isinstance(v, dict):
                table(f"{prefix}.{json.dumps(k)}" if prefix else json.dumps(k), v)

    table("", tree)
    return "\n".join(lines) + "\n"


def _leaves(tree, prefix=""):
    for k, v in tree.items():
        path = f"{prefix}{k}"
        if isinstance(v, dict):
            yield from _leaves(v, path + ".")
        else:
            yield path


def _set(tree, path, value):
    *heads, last = _split(path)
    node = tree
    for h in heads:
        node = node.setdefault(h, {})
    node[last] = value


def _split(path):
    if path.startswith("scenario."):          # scenario names hold dashes, no dots
        _, name, key = path.split(".", 2)
        return ["scenario", name, *key.split(".")]
    return path.split(".")


def _delete(tree, path):
    *heads, last = _split(path)
    node = tree
    for h in heads:
        node = node[h]
    del node[last]


def _quantity_text(value):
    return value if isinstance(value, str) else None


def mutate(rng, tree):
    """One to three mutations of a copy of ``tree``; returns (tree, [(kind, path)])."""
    tree = json.loads(json.dumps(tree))
    paths = [p for p in _leaves(tree)]
    done = []
    for _ in range(int(rng.integers(1, 4))):
        path = paths[int(rng.integers(len(paths)))]
        kind = str(rng.choice(["scale", "scale", "negate", "zero", "bad_text", "bad_text",
                               "bare", "wrong_unit", "delete", "delete", "unknown", "type",
                               "nested", "garble"]))
        *heads, last = _split(path)
        node = tree
        try:
            for h in heads:
                node = node[h]
            old = node[last]
        except (KeyError, TypeError):
            continue
        text = _quantity_text(old)
        if kind == "scale" and text:
            m = re.match(r"^\s*([-+0-9.eE]+)\s*(.*)$", text)
            if m:
                node[last] = f"{float(m[1]) * 10.0 ** int(rng.integers(-30, 31)):.6g} {m[2]}".strip()
        elif kind == "negate" and text:
            node[last] = "-" + text.lstrip("+")
        elif kind == "zero" and text:
            m = re.match(r"^\s*[-+0-9.eE]+\s*(.*)$", text)
            if m:
                node[last] = f"0 {m[1]}".strip()
        elif kind == "bad_text":
            node[last] = str(rng.choice(BAD_TEXT))
        elif kind == "bare":
            node[last] = float(rng.choice([0.0, 1.0, 3.048, -2.5, 1e30]))
        elif kind == "wrong_unit" and text:
            node[last] = str(rng.choice(["3000 psi", "3.048 m", "50 mA", "2 Hz", "16 kg", "100 rad/s"]))
        elif kind == "delete":
            del node[last]
        elif kind == "unknown":
            node[last + "_x"] = "1 m"
        elif kind == "type":
            node[last] = [True, {"a": 1}, [1, 2], 7, 1.5][int(rng.integers(5))]
        elif kind == "nested":
            depth = int(rng.choice([10, 3000]))
            node[last] = "[" * depth + '"1 m"' + "]" * depth   # written raw below
            kind = f"nested{depth}"
        elif kind == "garble" and isinstance(old, str):
            node[last] = old[::-1]
        else:
            continue
        done.append((kind, path))
    return tree, done


def _write(tmp_path, i, tree):
    text = _to_toml(tree)
    # a raw nested array: the string value marked above is written without quotes
    text = re.sub(r'"(\[+\\"1 m\\"\]+)"', lambda m: m[1].replace('\\"', '"'), text)
    f = tmp_path / f"rig{i:03d}.toml"
    f.write_text(text)
    return f


LEADING_PATH = re.compile(r"^(?P<path>[A-Za-z_][\w.\-]*)(\[\d+\])?(\.\.\.)?:")


def _known_path(path):
    if path in PARAMETERS or path.startswith(("connections.", "rig.")):
        return True
    section, _, key = path.rpartition(".")
    return section in SCHEMA or path in SCHEMA or path.split(".")[0] in (
        "supply", "return", "fluid", "servovalve", "actuator", "friction", "load",
        "controller", "scenario", "initial piston position")


def _outcome(f):
    """"ok", or the one-line message of the ValueError the loading layer raises."""
    rig = load_rig(f)
    for scenario in ("open-loop-step", "closed-loop-sine"):
        sc = build_scenario(rig, scenario)
        build_network(rig, sc.commands, sc.position_guess)
    return rig


@pytest.fixture(scope="module")
def fuzzed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fuzz")
    rng = np.random.default_rng(SEED)
    cases = []
    for i in range(N_RIGS):
        tree, done = mutate(rng, BASE)
        cases.append((_write(tmp, i, tree), done))
    return cases


def test_fuzzed_rigs_load_or_fail_with_one_line_naming_the_key(fuzzed):
    tic = time.perf_counter()
    ok = refused = 0
    for f, done in fuzzed:
        try:
            rig = _outcome(f)
        except ValueError as e:      # RigError, UnitError, NetworkError
            msg = str(e)
            assert msg and "\n" not in msg and len(msg) < 600, (f, done, msg[:300])
            m = LEADING_PATH.match(msg)
            file_error = msg.startswith(str(f))
            assert file_error or (m and _known_path(m["path"])), (done, msg)
            # ... and the parameter named is one that was changed
            assert file_error or any(path in msg for _, path in done), (done, msg)
            refused += 1
            continue
        except Exception as e:       # anything else is a bug
            pytest.fail(f"{f.name} {done}: {type(e).__name__}: {str(e)[:300]}")
        ok += 1
        # a deleted key that changes the result is reported as defaulted
        reported = {p for sc in ("open-loop-step", "closed-loop-sine")
                    for p, _ in defaults_used(rig, sc)}
        for kind, path in done:
            if kind == "delete" and path in PARAMETERS and path not in rig:
                p = PARAMETERS[path]
                if p.default not in (None, "required") and not p.inherited \
                        and p.scope in ("always", "open-loop-step", "closed-loop-sine"):
                    assert path in reported, (f.name, done)
    assert ok + refused == N_RIGS and ok >= 10 and refused >= N_RIGS // 2
    assert time.perf_counter() - tic < 60          # generous: no hang, no minutes-long parse


@pytest.mark.parametrize("text", BAD_TEXT[:7])
def test_issue_reproducers_refused_naming_the_key(tmp_path, text):
    f = tmp_path / "r.toml"
    f.write_text(f'[rig]\nbase = "default"\n[supply.section2]\nlength = {json.dumps(text)}\n')
    tic = time.perf_counter()
    with pytest.raises(ValueError) as err:
        load_rig(f)
    assert time.perf_counter() - tic < 1.0
    msg = str(err.value)
    assert msg.startswith("supply.section2.length: ") and "\n" not in msg
    assert len(msg) < 300


def _cli_cases(fuzzed, n):
    """The first n fuzzed rigs that load, and the first n refused, in generator order."""
    ok, bad = [], []
    for f, done in fuzzed:
        try:
            _outcome(f)
            (ok if len(ok) < n else []).append(f)
        except ValueError:
            (bad if len(bad) < n else []).append(f)
        if len(ok) >= n and len(bad) >= n:
            break
    return ok + bad


def test_fuzzed_rigs_through_the_command_line(fuzzed, tmp_path, capsys):
    """Real CLI runs (in-process main, short runs): exit 0 with finite JSON or exit 2 with
    one line on stderr."""
    for k, f in enumerate(_cli_cases(fuzzed, 3)):
        rc = main(["simulate", str(f), "--json", "--t-end", "0.02 s", "--out", str(tmp_path / str(k))])
        cap = capsys.readouterr()
        errors = [ln for ln in cap.err.splitlines() if ": error: " in ln]
        if rc == 0:
            summary = json.loads(cap.out)
            for v in (summary["supply"]["amplitude_mpa"], summary["return"]["amplitude_mpa"],
                      summary["actuator_natural_frequency_hz"]):
                assert math.isfinite(v)
            assert not errors
        else:
            assert rc == 2, (f, rc, cap.err)
            assert len(cap.err.strip().splitlines()) == 1 and len(errors) == 1, cap.err
            assert cap.out == ""


def test_one_fuzzed_rig_in_a_real_process(fuzzed, tmp_path):
    f = _cli_cases(fuzzed, 1)[-1]           # a refused one: exit 2, one line, no traceback
    done = subprocess.run([sys.executable, "-m", "hydroline", "simulate", str(f), "--json",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert done.stdout == ""


# ---- circuit fuzz (issue 24): miswired circuits --------------------------------------------
# A seeded generator rewires the shipped circuits through [connections] (the template rig,
# close-coupled or not, the two-axis rig, the paper's rig written as a circuit) in the ways a
# circuit goes physically wrong: a port fed its own component's output, two ports of one
# component on one node, a servovalve port moved to the other side, P and T swapped, a line
# crossed between supply and return, a port re-pointed to another node (a cut), flows
# crossed, a port on a signal of another kind or of no component, and pairs of these. Each
# is only built (the checks run before any run): every one must be refused in one line
# naming a component's port, or be warned of in one line; none is accepted silently.
# Which side a signal is on comes from its name in the shipped rigs, not from the checks.

N_CIRCUITS = 240
CIRCUIT_SEED = 20260524
#: The shipped rigs' prescribed pressures (pressure sources): reading one of them in place of
#: a node of its own side is the documented ideal-source idealization, not a miswiring.
PRESCRIBED = {"pump_pressure": "supply", "tank_pressure": "return"}
HYDRAULIC = ("pressure", "flow")


def _side(signal):
    """supply / return / a chamber, from a shipped rig's signal name."""
    if "_chamber_" in signal:
        return signal.split("_chamber_")[0]
    if "return" in signal or "tank" in signal:
        return "return"
    if "supply" in signal or "pump" in signal:
        return "supply"
    return None


def _circuit_bases():
    from pathlib import Path
    close = load_rig()
    close.set("supply.section2.length", "0 m")
    close.set("return.section2.length", "0 m")
    rigs = {"default": load_rig(), "close-coupled": close, "two_axis": load_rig("two_axis"),
            "paper-circuit": load_rig(Path(__file__).parent / "data" / "ayalew2005_circuit.toml")}
    from hydroline.system import build_circuit
    return {k: (rig, build_circuit(rig).components) for k, rig in rigs.items()}


class _Miswire:
    """The generator's view of one base circuit: its ports and signals by quantity."""

    def __init__(self, parts):
        self.parts = parts
        self.signals = {}
        for c in parts:
            for p, spec in {**c.inputs, **c.outputs}.items():
                self.signals.setdefault(spec.quantity, set()).add(c.signal(p))
        self.signals = {q: sorted(s) for q, s in self.signals.items()}
        self.inputs = [(c, p, s.quantity) for c in parts for p, s in c.inputs.items()
                       if s.quantity in HYDRAULIC]
        self.valves = [c for c in parts if "supply_pressure" in c.inputs and "return_pressure" in c.inputs]

    def pick(self, rng, seq):
        return seq[int(rng.integers(len(seq)))] if seq else None

    def self_loop(self, rng):
        c, p, o = self.pick(rng, [(c, p, o) for c in self.parts for p, s in c.inputs.items()
                                  for o, t in c.outputs.items()
                                  if s.quantity in HYDRAULIC and s.quantity == t.quantity])
        return {f"{c.name}.{p}": c.signal(o)}

    def short(self, rng):
        c, p, q = self.pick(rng, [(c, p, q) for c in self.parts for p, s in c.inputs.items()
                                  for q, t in c.inputs.items() if p != q
                                  and s.quantity in HYDRAULIC and s.quantity == t.quantity])
        return {f"{c.name}.{p}": c.signal(q)}

    def other_side(self, rng):
        v = self.pick(rng, self.valves)
        port = self.pick(rng, ["supply_pressure", "return_pressure"])
        here = _side(v.signal(port))
        return {f"{v.name}.{port}": self.pick(rng, [s for s in self.signals["pressure"]
                                                    if _side(s) in ("supply", "return")
                                                    and _side(s) != here])}

    def swap(self, rng):
        v = self.pick(rng, self.valves)
        return {f"{v.name}.{a}_{q}": v.signal(f"{b}_{q}") for a, b in
                (("supply", "return"), ("return", "supply")) for q in HYDRAULIC}

    def cross(self, rng):
        c, p, _ = self.pick(rng, [(c, p, q) for c, p, q in self.inputs if q == "pressure"
                                  and c not in self.valves
                                  and _side(c.signal(p)) in ("supply", "return")])
        here = _side(c.signal(p))
        return {f"{c.name}.{p}": self.pick(rng, [s for s in self.signals["pressure"]
                                                 if _side(s) in ("supply", "return")
                                                 and _side(s) != here])}

    def cut(self, rng):
        c, p, _ = self.pick(rng, [x for x in self.inputs if x[2] == "pressure"])
        old = c.signal(p)
        return {f"{c.name}.{p}": self.pick(rng, [s for s in self.signals["pressure"] if s != old
                                                 and PRESCRIBED.get(s, "-") != _side(old)])}

    def flow_cross(self, rng):
        c, p, _ = self.pick(rng, [x for x in self.inputs if x[2] == "flow"])
        old = c.signal(p)
        return {f"{c.name}.{p}": self.pick(rng, [s for s in self.signals["flow"] if s != old])}

    def absurd(self, rng):
        c, p, q = self.pick(rng, self.inputs)
        other = [s for k, v in self.signals.items() if k not in HYDRAULIC for s in v]
        return {f"{c.name}.{p}": self.pick(rng, other + ["nowhere", "valve current", ""])}

    KINDS = ("self_loop", "short", "other_side", "swap", "cross", "cut", "flow_cross", "absurd")

    def make(self, rng):
        kind = str(self.pick(rng, self.KINDS + ("pair",)))
        if kind != "pair":
            return kind, getattr(self, kind)(rng)
        a, b = (str(self.pick(rng, self.KINDS)) for _ in range(2))
        return f"{a}+{b}", {**getattr(self, a)(rng), **getattr(self, b)(rng)}


@pytest.fixture(scope="module")
def miswired():
    rng = np.random.default_rng(CIRCUIT_SEED)
    bases = _circuit_bases()
    cases = []
    while len(cases) < N_CIRCUITS:
        name = str(rng.choice(sorted(bases)))
        rig, parts = bases[name]
        kind, overrides = _Miswire(parts).make(rng)
        cases.append((name, kind, overrides))
    return bases, cases


def test_miswired_circuits_refused_in_one_line_or_warned(miswired):
    """>= 200 generated bad circuits: each refused (RigError, one line, naming a component's
    port) or warned of in one line; 0 accepted silently, no other exception."""
    import warnings

    from hydroline.circuit.wiring import WiringWarning
    from hydroline.engine.network import UnusedSignalWarning
    from hydroline.rigs import RigError
    from hydroline.system import build_circuit

    bases, cases = miswired
    tic = time.perf_counter()
    outcome, kinds = {"refused": 0, "warned": 0}, set()
    for name, kind, overrides in cases:
        rig, parts = bases[name]
        rig = rig.copy()
        ports = {f"{c.name}.{p}" for c in parts for p in (*c.inputs, *c.outputs)}
        ports |= {f"{c.name}.ports.{p}" for c in parts for p in (*c.inputs, *c.outputs)}
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            try:
                for port, signal in overrides.items():
                    rig.set(f"connections.{port}", signal)
                build_circuit(rig)
            except RigError as e:
                msg = str(e)
                assert msg and "\n" not in msg and len(msg) < 600, (name, kind, overrides, msg)
                assert re.match(r"^(connections|circuit)[.:]|^[\w.]+: ", msg), (name, overrides, msg)
                assert any(p in msg for p in ports), (name, kind, overrides, msg)
                outcome["refused"] += 1
                kinds.add(kind.split("+")[0])
                continue
            except Exception as e:         # anything else is a bug
                pytest.fail(f"{name} {kind} {overrides}: {type(e).__name__}: {str(e)[:300]}")
        lines = [str(w.message) for w in said
                 if issubclass(w.category, (WiringWarning, UnusedSignalWarning))]
        assert lines, f"accepted silently: {name} {kind} {overrides}"
        assert all("\n" not in s for s in lines)
        outcome["warned"] += 1
    assert sum(outcome.values()) == len(cases) >= 200
    assert outcome["refused"] >= 0.9 * len(cases), outcome
    assert kinds == set(_Miswire.KINDS), kinds        # every class was generated and refused
    assert time.perf_counter() - tic < 60             # generous: build only, no integration


# ---- no negative absolute pressure (issue 30) ----------------------------------------------
# The fuzz campaigns' plausible rigs that drove pressures below zero absolute (a return hose of
# 0.3x bore with a valve of 3x flow: -20.6 MPa; a valve of 10x flow, /work/shared/repro/p3_11:
# -6.8 MPa), as a user writes them (the cavity model on by default at 5 kPa, M42, M45): every
# watched pressure stays at or above zero absolute, and the valve ports, hose ends holding a
# cavity (M45), at or above p_cav.
CAVITATING = {"narrow return, big valve": {"return.section2.diameter": "4.08 mm",
                                           "servovalve.rated_flow": "57 L/min"},
              "valve 10x": {"servovalve.rated_flow": "190 L/min"}}


@pytest.mark.parametrize("changes", CAVITATING.values(), ids=list(CAVITATING))
def test_plausible_cavitating_rigs_keep_pressures_above_zero(changes):
    from hydroline import simulate
    from hydroline.scenarios.running import watched_pressures

    rig = load_rig(None)
    del rig.values["fluid.cavity_pressure"], rig.raw["fluid.cavity_pressure"]   # the default
    for key, value in changes.items():
        rig = rig.set(key, value)
    res = simulate(rig, t_end=0.2, solver="cvodes")
    lows = {k: float(res[k].min()) for k in watched_pressures(res)}
    assert min(lows.values()) >= 0.0, lows
    # p_end = p~ + |k| w >= p_cav (M45) to its rounding; |k| w < 1e11 Pa on these rigs
    for port in ("supply_port_pressure", "return_port_pressure"):
        assert lows[port] >= 5e3 - 1e-3, lows
    assert any("cavity opened" in w for w in res.warnings)
