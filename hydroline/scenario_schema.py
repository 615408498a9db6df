"""Rig-file schema of a user's own experiment: ``[scenario.<name>] type = "axis-commands"``.

A rig may define experiments of its own besides the built-in ones
(:data:`hydroline.scenarios.EXPERIMENTS`): a command per servo axis, each a waveform with
units or a CSV table with units in its header::

    [scenario.my-test]
    type = "axis-commands"
    t_end = "0.3 s"                   # simulated time (required)
    disturbance_time = "10 ms"        # optional: where the metrics start (default: the
                                      # first time a command changes)

    [scenario.my-test.axis2]          # an axis by name (``hydroline circuit RIG`` lists them)
    quantity = "position"             # "position": the axis's position reference [m] (into
                                      # its controller); "current": its valve current [A]
    waveform = "sine"                 # step | ramp | sine | csv
    offset = "0 mm"
    amplitude = "5 mm"
    frequency = "4 Hz"
    start = "10 ms"

    [scenario.my-test.axis1]
    quantity = "current"
    waveform = "csv"
    file = "axis1_current.csv"        # header "time [s], current [mA]" (units required),
                                      # path relative to the rig file

Axes not listed hold (their position reference stays where the piston starts, or zero valve
current without a controller). The keys of each waveform and their units:
:data:`WAVEFORM_KEYS` (``[q]``: the unit of the axis's ``quantity``). Every value is a
quantity with its unit; a bare number, an unknown key or a key of another waveform is
refused in one line naming the key and its unit.

This module imports nothing else of hydroline: the rig reader calls
:func:`parse_scenario_value` with its own quantity parser.
"""
from __future__ import annotations

__all__ = ["EXPERIMENT_TYPES", "QUANTITY_UNITS", "WAVEFORM_KEYS", "SCENARIO_KEYS",
           "is_own_scenario", "parse_scenario_value"]

#: ``type`` values a rig's own experiment may have.
EXPERIMENT_TYPES = ("axis-commands",)

#: What an axis command may drive -> its SI unit.
QUANTITY_UNITS = {"current": "A", "position": "m"}

#: Waveform -> key -> (unit, required); ``"q"`` is the unit of the axis's quantity,
#: ``"q/s"`` that per second.
WAVEFORM_KEYS = {
    "step": {"initial": ("q", False), "final": ("q", True), "time": ("s", True)},
    "ramp": {"initial": ("q", False), "slope": ("q/s", True), "start": ("s", True),
             "end": ("s", True)},
    "sine": {"offset": ("q", False), "amplitude": ("q", True), "frequency": ("Hz", True),
             "start": ("s", False)},
    "csv": {"file": ("str", True)},
}

#: Keys of the experiment's own table -> SI unit.
SCENARIO_KEYS = {"type": "str", "t_end": "s", "disturbance_time": "s"}

#: Keys every axis table has besides its waveform's.
AXIS_KEYS = {"quantity": "str", "waveform": "str"}


def is_own_scenario(path: str, raw: dict) -> bool:
    """True when ``path`` (``scenario.<name>...``) belongs to an experiment the rig defines
    itself (its table has a ``type``).

    Parameters
    ----------
    path : str
        A rig path
    raw : dict
        All raw values of the rig, path -> value as written

    Returns
    -------
    bool
        Whether the path lies in a ``[scenario.NAME]`` table that gives a ``type``
    """
    parts = path.split(".")
    return len(parts) >= 3 and parts[0] == "scenario" and f"scenario.{parts[1]}.type" in raw


def _unit(unit: str, quantity_unit: str) -> str:
    return unit.replace("q", quantity_unit) if unit.startswith("q") else unit


def parse_scenario_value(path: str, raw_value, raw: dict, parse_quantity_as):
    """One value of a rig's own experiment, in SI.

    Parameters
    ----------
    path : str
        ``scenario.<name>.<key>`` or ``scenario.<name>.<axis>.<key>``
    raw_value : object
        The value as written (a quantity with its unit, or text)
    raw : dict
        All raw values of the rig (for the type, quantity, waveform)
    parse_quantity_as : callable
        ``(path, raw_value, unit) -> value`` (the rig's reader;
        unit "str" for text)

    Returns
    -------
    object
        float [SI unit of the key] or text

    Raises
    ------
    ValueError
        One line naming the key and its unit
    """
    parts = path.split(".")
    base = f"scenario.{parts[1]}"
    if len(parts) == 3:
        key = parts[2]
        if key not in SCENARIO_KEYS:
            raise ValueError(f"{path}: unknown key '{key}' of a rig's own experiment (keys: "
                             f"{', '.join(f'{k} [{u}]' for k, u in SCENARIO_KEYS.items())}; one "
                             f"[{base}.<axis>] table per driven axis)")
        if key == "type" and raw_value not in EXPERIMENT_TYPES:
            raise ValueError(f"{path}: must be one of {', '.join(EXPERIMENT_TYPES)}, got "
                             f"{raw_value!r}")
        return parse_quantity_as(path, raw_value, SCENARIO_KEYS[key])
    if len(parts) != 4:
        raise ValueError(f"{path}: a rig's own experiment has keys {base}.<key> and "
                         f"{base}.<axis>.<key> only")
    axis, key = parts[2], parts[3]
    if key in AXIS_KEYS:
        value = parse_quantity_as(path, raw_value, "str")
        allowed = QUANTITY_UNITS if key == "quantity" else WAVEFORM_KEYS
        if value not in allowed:
            what = (", ".join(f"{q} [{u}]" for q, u in QUANTITY_UNITS.items())
                    if key == "quantity" else ", ".join(WAVEFORM_KEYS))
            raise ValueError(f"{path}: must be one of {what}, got {value!r}")
        return value
    quantity = raw.get(f"{base}.{axis}.quantity")
    if quantity not in QUANTITY_UNITS:
        raise ValueError(f"{base}.{axis}.quantity: required before '{key}' has a unit: "
                         f"{' or '.join(f'{q!r} [{u}]' for q, u in QUANTITY_UNITS.items())}")
    waveform = raw.get(f"{base}.{axis}.waveform")
    if waveform not in WAVEFORM_KEYS:
        raise ValueError(f"{base}.{axis}.waveform: required, one of {', '.join(WAVEFORM_KEYS)}; "
                         f"got {waveform!r}")
    keys = WAVEFORM_KEYS[waveform]
    if key not in keys:
        qu = QUANTITY_UNITS[quantity]
        raise ValueError(f"{path}: not a key of waveform = {waveform!r} (keys: "
                         f"{', '.join(f'{k} [{_unit(u, qu)}]' for k, (u, _) in keys.items())})")
    return parse_quantity_as(path, raw_value, _unit(keys[key][0], QUANTITY_UNITS[quantity]))
