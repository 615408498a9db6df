"""What limits the performance envelope (issue 29): the limited_by rules on traces with a known
answer, the force-limited band of a heavy mass against (p_s - p_t) A/m, where and by how much
the lines may lift the envelope above the constant supply's, and a multi-axis rig one axis at a
time and all together."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from hydroline.rigs import load_rig
from hydroline.studies.envelope import (FLOW_LOSS, STALL_SHARE, PeriodicResponse, SineRig,
                                        analytic_envelope, diagnose, envelope_points,
                                        vendor_parameters)

#: The default rig's rest pressures at the valve's ports (tests/test_envelope.py), [Pa].
PORTS = {"actuator": (20.6846e6, 1.5134e6)}


# ------------------------------------------------------------------ the rules, known answers

P_S, P_T, AREA, N = 21e6, 1e6, 5e-4, 256
DROP = P_S - P_T


def fake(supply=None, ret=None, bottom=None, top=None, spool=0.1, released=()):
    """A driven axis's last period: spool at ``spool`` of its 0.4 mm opening over the first
    half period and at its full opening over the second, ports and chambers as given."""
    def trace(v, default):
        return np.full(N, default) if v is None else np.asarray(v, dtype=float)

    half = np.r_[np.zeros(N // 2), np.ones(N // 2)].astype(bool)
    rig = SimpleNamespace(
        driven=["a"], nominal={"a": (P_S, P_T)},
        axes={"a": SimpleNamespace(supply_pressure="ps", return_pressure="pr", bottom_pressure="pb",
                                   top_pressure="pt", valve="v", current="i", position="x")},
        limits={"a": dict(current=0.05, opening=4e-4, bottom_area=AREA, top_area=AREA)})
    traces = {"ps": trace(supply, P_S), "pr": trace(ret, P_T), "pb": trace(bottom, 11e6),
              "pt": trace(top, 11e6), "i": np.full(N, 0.01),
              "v.spool_position": np.where(half, 4e-4, spool * 4e-4)}
    r = PeriodicResponse(10.0, {}, {}, {"a": 0.06}, {}, {}, traces, 1, 0.0, None,
                         [f"{s} below" for s in released], list(released))
    return r, rig, half


def test_limit_rules_on_known_traces():
    """The documented rules, each at its threshold: the port losses count from
    1 - (1 - 5 %)^2 = 9.75 % of the drop (the loss that costs 5 % of the valve's flow at
    its opening, flow ~ sqrt(drop)); force from 95 % of the stall force (P_S - P_T) A; gas
    release at a port is that line's pulsation, in a chamber short of stall is gas release."""
    loss = 1 - (1 - FLOW_LOSS) ** 2
    assert loss == pytest.approx(0.0975)
    r, rig, half = fake()
    assert diagnose(r, rig, True, 0.05) == "valve"             # at its opening, no losses
    r, rig, _ = fake(spool=0.5)
    r.traces["v.spool_position"][:] = 0.5 * 4e-4
    assert diagnose(r, rig, True, 0.05) == "distortion"        # nothing at a limit
    for k, name in ((0.95, "valve"), (1.05, "supply_dip")):    # dip over the saturated half
        r, rig, _ = fake(supply=np.where(half, P_S - k * loss * DROP, P_S + 5e6))
        assert diagnose(r, rig, True, 0.05) == name
    for k, name in ((0.95, "valve"), (1.05, "return_rise")):
        r, rig, _ = fake(ret=np.where(half, P_T + k * loss * DROP, 0.5e6))
        assert diagnose(r, rig, True, 0.05) == name
    # the return port's troughs at the gas-release pressure, the valve not at its limit
    r, rig, _ = fake(spool=0.5, ret=P_T + 0.9e6 * np.sin(np.arange(N)), released=["pr"])
    assert diagnose(r, rig, True, 0.05) == "return_rise"
    r, rig, _ = fake(released=["ps"])
    assert diagnose(r, rig, True, 0.05) == "supply_dip"
    # chambers: bottom at supply, top at tank less the stall margin's 4 % or 6 % of the drop
    for k, name in ((0.96, "force"), (0.94, "gas_release")):
        r, rig, _ = fake(bottom=np.full(N, P_T + k * DROP), top=np.full(N, P_T),
                         released=["pt"])
        assert diagnose(r, rig, True, 0.05) == name
    assert STALL_SHARE == 0.95


# ------------------------------------------------------------------ the force band

def heavy_mass_rig():
    """The default axis horizontal (no weight), carrying 300 kg on a 10x larger valve
    (190 L/min) with a tenth of the P gain (the same loop gain K_v). The force limit
    a = (p_s - p_t) A / m = 19.17 MPa * 4.83 cm^2 / 300 kg = 30.9 m/s^2 then acts alone
    between ~10 and ~13 Hz: the flow limit v = Q/A (6.9 m/s at 5 % distortion) is 14x the
    force limit's a/w there, so the valve's flow is not needed where the load pressure peaks
    (it would be above a/w > v/sqrt(2): 0.7 Hz); the oil column's resonance is
    172 Hz sqrt(16.15 kg/300 kg) = 40 Hz, so the chambers follow the load quasi-statically
    to (f/40 Hz)^2 = 6-11 %. Below ~9 Hz braking the mass through the P loop's throttling
    valve cavitates the filling chamber before the load pressure reaches the drop (0.95 of
    the force limit at 9 Hz); above ~13 Hz the oil column lifts the load pressure's peak
    over the drop (1.06 at 15 Hz)."""
    rig = load_rig().copy()
    rig.set("actuator.moving_mass", "300 kg")
    rig.set("actuator.gravity", "0 m/s^2")
    rig.set("servovalve.rated_flow", "190 L/min")
    rig.set("controller.proportional_gain", "0.15 A/m")
    return rig


def test_force_limited_band_of_a_heavy_mass():
    """Constant supply: the envelope within 5 % of the force limit (p_s - p_t) A / m / w^2
    where it acts alone, limited by force."""
    srig = SineRig(heavy_mass_rig(), "constant", pressures=PORTS)
    v = vendor_parameters(srig)
    assert v["mass"] == pytest.approx(300.0)
    frequencies = [10.0, 12.0]
    an = analytic_envelope(frequencies, **v, distortion=0.05)
    assert an["limited_by"] == ["force", "force"]
    a = (PORTS["actuator"][0] - PORTS["actuator"][1]) * v["area"] / 300.0
    assert a == pytest.approx(30.9, rel=0.01)
    for point, f in zip(envelope_points(srig, frequencies, an["displacement_amplitude_m"]),
                        frequencies):
        assert point["displacement_amplitude_m"] == pytest.approx(a / (2 * math.pi * f) ** 2,
                                                                  rel=0.05)
        assert point["limited_by"] == "force"


# ------------------------------------------------------------------ lines above the ideal supply

def test_lines_lift_the_envelope_only_by_their_port_pulsation():
    """At 146 Hz (2f = 292 Hz: near the return line's ninth mode, 9 x 31 Hz, were it an ideal
    quarter-wave line) the lines' envelope lies a grid step above the constant supply's.
    That is the valve's flow, not the search: the ports' pressure pulsation at 2f, locked to
    the spool's motion,
    raises the valve's fundamental load flow at the same spool motion by a few percent
    (port_ripple_gain: a drop pulsating by e of it at 2f changes a sqrt-law flow's
    fundamental by up to e/4), while the ports' lower mean pressures (the mean flow's drop
    in the lines) only take from it. So the lines' curve may lie above the constant
    supply's by at most that gain and the bisection's one grid step (both searches try the
    same amplitudes 1.02**k)."""
    rig = load_rig()
    hoses = SineRig(rig, "hoses")
    const = SineRig(rig, "constant", pressures=hoses.nominal)
    f = [145.90812273]
    guess = analytic_envelope(f, **vendor_parameters(const),
                              distortion=0.05)["displacement_amplitude_m"]
    h = envelope_points(hoses, f, guess)[0]
    c = envelope_points(const, f, guess)[0]
    assert c["port_ripple_gain"] == pytest.approx(1.0, abs=1e-9)     # constant ports
    gain = h["port_ripple_gain"]
    assert 1.01 < gain < 1.1
    ratio = h["displacement_amplitude_m"] / c["displacement_amplitude_m"]
    assert ratio <= gain * 1.02 * (1 + 1e-9)


# ------------------------------------------------------------------ multi-axis

def test_two_axes_one_at_a_time_and_together():
    """two_axis, 20 Hz (the supply line's 40 Hz quarter wave at 2f): axis 1 alone with axis 2
    holding, then both in phase. The shared supply's pulsation doubles with both valves'
    flow, so together they reach less than one alone by more than a grid step, limited by the
    supply's dip. The held axis stays. (One compiled model serves both: the held axis's
    reference has zero amplitude.)"""
    rig = load_rig("two_axis")
    one = SineRig(rig, "hoses", "axis1")
    guess = analytic_envelope([20.0], **vendor_parameters(one),
                              distortion=0.05)["displacement_amplitude_m"]
    alone = envelope_points(one, [20.0], guess)[0]
    both = envelope_points(SineRig(rig, "hoses", "all"), [20.0], guess)[0]
    assert both["displacement_amplitude_m"] < alone["displacement_amplitude_m"] / 1.02
    assert both["limited_by"] == "supply_dip"
    # the held axis stays: its valve at null feeds the supply's pulsation to both chambers
    # alike through its symmetric underlap (13 nm of motion against 8.8 mm)
    assert 0 <= alone["held_motion_m"] < 0.01 * alone["displacement_amplitude_m"]
    assert both["held_motion_m"] == 0.0                        # none held
