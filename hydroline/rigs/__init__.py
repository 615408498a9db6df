"""Rig descriptions: TOML files whose quantities carry units, parsed into SI (a parameter set).

``load_rig()`` gives the embedded default, the 2005 paper's rig (``ayalew2005.toml``);
``load_rig(path)`` reads a user's file, which may give only what differs (``base`` key, see
below) or a complete description. Parameters are addressed by their dotted path in the file,
e.g. ``supply.section2.length``; :meth:`Rig.set` changes one with units.

Optional ``[supply.pressure_profile]`` / ``[return.pressure_profile]`` tables make the pump or
tank pressure vary in time (step, sine, ramp about ``<side>.pressure``, or a CSV table of the
absolute pressure); see :func:`hydroline.system.pressure_profile`.

An optional ``[connections]`` table rewires component ports to other signals, e.g.
``"servovalve.supply_pressure" = "pump_pressure"`` connects the valve straight to the pump
(an ideal supply). The network checks the result: a port wired to a signal nobody outputs is
reported as unconnected.
"""
from __future__ import annotations

import copy
import tomllib
from importlib import resources
from pathlib import Path

from ..units import UnitError, parse_quantity

__all__ = ["Rig", "RigError", "load_rig", "SCHEMA", "DEFAULT_RIG"]

DEFAULT_RIG = "ayalew2005.toml"
#: Longest list a rig parameter may hold (the laps have four), [items].
MAX_LIST_LENGTH = 64
#: Largest rig file read, [bytes]: a rig is a page of parameters, not a data set.
MAX_RIG_BYTES = 1 << 20


class RigError(ValueError):
    """A rig file or parameter that cannot be used; the message is one line naming it."""


#: A time-varying source pressure (``[supply.pressure_profile]``, ``[return.pressure_profile]``):
#: ``type`` step (``time``, ``final``), sine (``amplitude``, ``frequency``, ``start``), ramp
#: (``slope``, ``start``, ``end``) about ``<side>.pressure``, or table (``file``: CSV with
#: ``time [unit]``, ``pressure [unit]`` columns, absolute, path relative to the rig file).
_PROFILE = {"type": "str", "time": "s", "final": "Pa", "amplitude": "Pa", "frequency": "Hz",
            "start": "s", "end": "s", "slope": "Pa/s", "file": "str"}
_LINE = {"length": "m", "diameter": "m", "bulk_modulus": "Pa", "modes": "-"}
_ACC = {"capacity": "m^3", "precharge_pressure": "Pa", "polytropic_exponent": "-",
        "connection_length": "m", "connection_diameter": "m", "model": "str", "modes": "-"}

#: Every parameter a rig file may hold: section -> key -> SI unit ("-" dimensionless,
#: "str" text, "list:<unit>" list of quantities).
SCHEMA = {
    "rig": {"name": "str", "modes_per_section": "-", "base": "str", "line_method": "str",
            "allow_implausible": "list:str"},
    "fluid": {"density": "kg/m^3", "kinematic_viscosity": "m^2/s", "bulk_modulus": "Pa",
              "gas_release_pressure": "Pa"},
    "supply": {"pressure": "Pa"},
    "supply.pressure_profile": _PROFILE,
    "supply.section1": _LINE, "supply.section2": _LINE,
    "supply.manifold": {"resistance": "Pa*s/m^3", "volume": "m^3"},
    "supply.accumulator": _ACC,
    "return": {"pressure": "Pa"},
    "return.pressure_profile": _PROFILE,
    "return.section1": _LINE, "return.section2": _LINE,
    "return.manifold": {"resistance": "Pa*s/m^3", "volume": "m^3"},
    "return.check_valve": {"reverse_resistance": "Pa*s/m^3", "forward_resistance": "Pa*s/m^3"},
    "return.accumulator": _ACC,
    "servovalve": {"rated_current": "A", "rated_flow": "m^3/s", "rated_pressure_drop": "Pa",
                   "max_opening": "m", "natural_frequency": "Hz", "damping_ratio": "-",
                   "laps": "list:m", "laminar_pressure": "Pa"},
    "actuator": {"area": "m^2", "bottom_area": "m^2", "top_area": "m^2", "stroke": "m",
                 "dead_volume": "m^3", "bulk_modulus": "Pa", "moving_mass": "kg",
                 "initial_position": "m", "gravity": "m/s^2", "internal_leakage": "m^3/s/Pa",
                 "external_leakage": "m^3/s/Pa"},
    "friction": {"viscous_up": "N*s/m", "viscous_down": "N*s/m", "coulomb_up": "N",
                 "coulomb_down": "N", "static_up": "N", "static_down": "N",
                 "stribeck_velocity": "m/s", "stribeck_exponent": "-",
                 "regularization_velocity": "m/s", "model": "str",
                 "bristle_stiffness": "N/m", "bristle_damping": "N*s/m"},
    "load": {"mass": "kg", "stiffness": "N/m", "damping": "N*s/m", "applied_force": "N",
             "free_position": "m"},
    "controller": {"proportional_gain": "A/m", "integral_gain": "A/m/s",
                   "derivative_gain": "A*s/m", "current_limit": "A", "sample_time": "s"},
    "scenario.open-loop-step": {"current": "A", "time": "s", "t_end": "s", "initial_current": "A"},
    "scenario.closed-loop-sine": {"amplitude": "m", "frequency": "Hz", "offset": "m",
                                  "t_end": "s", "initial_position": "m"},
}


def _flatten(tree, prefix="", depth=0):
    out = {}
    for k, v in tree.items():
        path = f"{prefix}{k}"
        if isinstance(v, dict):
            if depth >= 4:
                raise RigError(f"{path[:60]}...: tables nested too deeply; a rig parameter is "
                               f"section.key or section.subsection.key")
            out.update(_flatten(v, path + ".", depth + 1))
        else:
            out[path] = v
    return out


def _parse(path: str, raw):
    if path.startswith("connections."):
        # [connections] "component.port" = "signal": rewire one port (see build_network)
        if not isinstance(raw, str) or not raw:
            raise RigError(f"{path}: a connection names a signal, e.g. \"pump_pressure\"; got {raw!r}")
        return raw
    section, _, key = path.rpartition(".")
    if section not in SCHEMA:
        known = ", ".join(sorted(SCHEMA))
        raise RigError(f"{path}: unknown component/section '{section or key}' (known: {known})")
    unit = SCHEMA[section].get(key)
    if unit is None:
        raise RigError(f"{path}: unknown parameter '{key}' of '{section}' "
                       f"(known: {', '.join(sorted(SCHEMA[section]))})")
    if unit == "str":
        if not isinstance(raw, str):
            raise RigError(f"{path}: expected text, got {raw!r}")
        return raw
    if unit.startswith("list:") and not (isinstance(raw, list) and len(raw) <= MAX_LIST_LENGTH):
        what = "text" if unit == "list:str" else f"quantities in [{unit[5:]}]"
        size = f" of {len(raw)} items" if isinstance(raw, list) else ""
        raise RigError(f"{path}: expected a list of at most {MAX_LIST_LENGTH} {what}, got a "
                       f"{type(raw).__name__}{size}")
    if unit == "list:str":
        if not all(isinstance(v, str) for v in raw):
            raise RigError(f"{path}: expected a list of text, e.g. [\"actuator.moving_mass\"]")
        return list(raw)
    try:
        if unit.startswith("list:"):
            return [parse_quantity(v, unit[5:], f"{path}[{i}]") for i, v in enumerate(raw)]
        return parse_quantity(raw, "dimensionless" if unit == "-" else unit, path)
    except UnitError as e:
        raise RigError(str(e)) from None


class Rig:
    """A parsed rig: parameters in SI, addressed by dotted paths.

    Attributes
    ----------
    values : dict   path -> SI value (float), text or list
    raw : dict      path -> the value as written (with its unit)
    source : str    Where it came from
    """

    def __init__(self, values: dict, raw: dict, source: str):
        self.values, self.raw, self.source = values, raw, source

    def __getitem__(self, path: str):
        try:
            return self.values[path]
        except KeyError:
            raise RigError(f"{path}: not set in rig {self.source}") from None

    def get(self, path: str, default=None):
        return self.values.get(path, default)

    def __contains__(self, path):
        return path in self.values

    def set(self, path: str, value) -> "Rig":
        """Set one parameter from a quantity with units (``"1.5 m"``) or, for text and
        dimensionless ones, a plain value. Returns self."""
        self.values[path] = _parse(path, value)
        self.raw[path] = value
        return self

    def copy(self) -> "Rig":
        return Rig(copy.deepcopy(self.values), copy.deepcopy(self.raw), self.source)

    def to_toml(self) -> str:
        """The rig as TOML text with its units (the raw values)."""
        sections = {}
        for path, v in self.raw.items():
            sec, _, key = path.rpartition(".")
            sections.setdefault(sec, {})[key] = v
        lines = []
        for sec in sections:
            lines.append(f"[{sec}]")
            for k, v in sections[sec].items():
                lines.append(f"{k} = {_toml_value(v)}")
            lines.append("")
        return "\n".join(lines)


def _toml_value(v):
    if isinstance(v, str):
        return '"' + v.replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def _read_toml(path) -> tuple[dict, str]:
    if path is None:
        text = resources.files(__name__).joinpath(DEFAULT_RIG).read_text()
        return tomllib.loads(text), f"embedded:{DEFAULT_RIG}"
    p = Path(path)
    if not p.is_file():
        raise RigError(f"rig file not found: {path}")
    try:
        if p.stat().st_size > MAX_RIG_BYTES:
            raise RigError(f"{path}: {p.stat().st_size} bytes is too large for a rig file "
                           f"(at most {MAX_RIG_BYTES} bytes)")
        return tomllib.loads(p.read_text(encoding="utf-8")), str(p)
    except tomllib.TOMLDecodeError as e:
        raise RigError(f"{path}: not valid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise RigError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    except RecursionError:
        raise RigError(f"{path}: nested too deeply to be a rig file (arrays or tables "
                       f"inside each other hundreds of levels deep)") from None
    except OSError as e:
        raise RigError(f"{path}: cannot read the rig file ({e.strerror or e})") from None


def load_rig(path=None) -> Rig:
    """Load a rig file (the embedded default when ``path`` is None).

    A file with ``[rig] base = "default"`` starts from the embedded rig and overrides only
    what it lists.
    """
    tree, source = _read_toml(path)
    raw = _flatten(tree)
    if raw.get("rig.base") in ("default", DEFAULT_RIG):
        base = load_rig(None)
        for k, v in raw.items():
            if k != "rig.base":
                base.set(k, v)
        base.source = source
        return base
    values = {k: _parse(k, v) for k, v in raw.items()}
    return Rig(values, raw, source)
