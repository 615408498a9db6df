"""
(g) Writing your own component
==============================

A contributor's path on one example: an inline pressure filter, whose drop is a laminar part
through the element's pores and a turbulent part in the housing's passages::

    dp = R_l q + K_t q |q|.

The steps: write the component (a dataclass declaring its parameters once, with a causality
chosen by ``compute``, :doc:`../engine`), check it against the hand formula, register it as a
circuit type so rig files can name it, put it before the valve of the paper's rig with a short
file that extends the shipped circuit (``base = "ayalew2005_circuit"``), and check its drop at
the steady flow of a run. Run time: about 30 s (the new circuit is compiled to C once).
"""

# %%
# The component
# -------------
# A filter passes the oil from an inlet to an outlet like the manifold's resistance, so it
# derives from :class:`~hydroline.components.resistance.OrientedResistance`: that class gives
# the ports of the three causalities (``compute = "outlet"``: inlet pressure and flow in,
# outlet pressure out; ``"inlet"``: the mirror; ``"flow"``: both pressures in, the flow out)
# and the hydraulic ends the wiring checks read. The filter writes its law both ways:
# ``pressure_drop(q)`` and its inverse ``flow(dp)``, with :mod:`hydroline.engine.ops` so the
# same code runs on numbers and compiles to C.
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import hydroline
from hydroline.components.resistance import OrientedResistance
from hydroline.engine import ops
from hydroline.engine.component import parameter

OUT = Path("tutorial-out")
OUT.mkdir(exist_ok=True)


@dataclass(kw_only=True)
class InlineFilter(OrientedResistance):
    """Inline pressure filter, flow from inlet to outlet: dp = R_l q + K_t q |q|.

    Parameters
    ----------
    laminar_resistance : float     R_l, laminar drop through the element, [Pa s/m^3]
    turbulent_coefficient : float  K_t, turbulent drop in the housing, [Pa s^2/m^6]
    """

    laminar_resistance: float = parameter(1e8, "Pa*s/m^3", "R_l: laminar drop of the element",
                                          positive=True, plausible=(1e5, 1e12))
    turbulent_coefficient: float = parameter(0.0, "Pa*s^2/m^6", "K_t: turbulent drop of the "
                                             "housing", minimum=0.0, plausible=(0.0, 1e15))

    def __post_init__(self):
        super().__post_init__()        # the ports of the chosen causality
        self.check_parameters()        # bounds: one line naming the parameter and its unit

    def pressure_drop(self, q):
        return self.laminar_resistance * q + self.turbulent_coefficient * q * ops.fabs(q)

    def flow(self, dp):
        # the root of K_t q^2 + R_l q - |dp| = 0, written without cancellation (R_l > 0)
        r = self.laminar_resistance
        return 2.0 * dp / (r + ops.sqrt(r * r + 4.0 * self.turbulent_coefficient * ops.fabs(dp)))


for compute in ("outlet", "inlet", "flow"):
    f = InlineFilter(name="filter", compute=compute)
    print(f"compute = {compute!r:9s} reads {', '.join(f.inputs):30s} gives {', '.join(f.outputs)}")

# %%
# Checked against the hand formula
# --------------------------------
# A clean 20 L/min pressure filter drops about 0.3 bar through its element and 0.2 bar in its
# housing at the valve's rated 19 L/min: R_l = 1e8 Pa s/m^3, K_t = 2e11 Pa s^2/m^6.
R_L, K_T = 1e8, 2e11
filt = InlineFilter(name="filter", laminar_resistance=R_L, turbulent_coefficient=K_T)
q = 19e-3 / 60                                     # 19 L/min, m^3/s
dp_hand = R_L * q + K_T * q * abs(q)               # 31.7 kPa + 20.1 kPa
print(f"at 19 L/min: dp = {filt.pressure_drop(q) / 1e5:.4f} bar (hand {dp_hand / 1e5:.4f} bar)")
assert abs(filt.pressure_drop(q) - dp_hand) <= 1e-12 * dp_hand
assert abs(filt.flow(dp_hand) - q) <= 1e-12 * q    # the inverse law gives the flow back
assert filt.flow(-dp_hand) == -filt.flow(dp_hand)  # and is odd: reverse flow, reverse drop

# %%
# Registered as a circuit type
# ----------------------------
# Rig files name component types (``type = "hose"``, ...) from
# :data:`hydroline.circuit.types.COMPONENT_TYPES`, where each is one ``ComponentType(name,
# class, description)``. Added there, the new type is read in its declared units, its values
# checked against its bounds and plausible ranges, and listed by ``hydroline circuit --types``.
# (To ship it with hydroline: the class in ``hydroline/components/``, the line in the tuple of
# ``hydroline/circuit/types.py``; ``tests/test_rig_checks.py`` then checks its declarations.)
from hydroline.circuit.types import COMPONENT_TYPES, ComponentType, parameter_reference

COMPONENT_TYPES["inline_filter"] = ComponentType(
    "inline_filter", InlineFilter, "inline pressure filter, dp = R_l q + K_t q|q|")
print(parameter_reference().split("### `inline_filter`")[1].strip())

# %%
# The paper's rig with the filter before the valve
# ------------------------------------------------
# The shipped circuit of the paper's rig is the base; the file adds the filter and the oil in
# its bowl, and re-points two ports. Why the bowl: the hose's end gives a pressure and takes
# a flow, the valve's P port takes a pressure and gives a flow, so a filter between them
# alone, giving its outlet pressure from the valve's flow, would need the valve's flow to
# give the valve's pressure: an algebraic loop, refused in one line (tried below). The bowl's
# volume holds the pressure as a state; the filter then takes both pressures and gives the
# flow (``compute = "flow"``).
RIG = """
[rig]
base = "ayalew2005_circuit"       # the paper's rig, as a circuit (hydroline/rigs/)
name = "the paper's rig, inline filter before the valve"

[circuit.filter]                  # the element: from section 2's end into the bowl
type = "inline_filter"
laminar_resistance = "1e8 Pa*s/m^3"       # [datasheet] clean element, 0.3 bar at 19 L/min
turbulent_coefficient = "2e11 Pa*s^2/m^6" # [datasheet] housing passages, 0.2 bar at 19 L/min
compute = "flow"
ports = { inlet_pressure = "supply_port_pressure", outlet_pressure = "filter_pressure", flow = "filter_flow" }

[circuit.filter_housing]          # the oil in the bowl, which the valve draws from
type = "volume"
volume = "0.2 L"                  # [datasheet] bowl of a 20 L/min pressure filter
nominal_pressure = "20 MPa"
terms = { element = 1, valve = -1 }
ports = { element = "filter_flow", valve = "supply_port_flow", pressure = "filter_pressure" }

[circuit."supply.section2"]       # the hose delivers what the element passes
ports = { downstream_flow = "filter_flow" }

[circuit.servovalve]              # the valve's P port on the bowl
ports = { supply_pressure = "filter_pressure" }
"""
path = OUT / "paper_rig_with_filter.toml"
path.write_text(RIG)
rig = hydroline.load_rig(path)
print(f"{len(RIG.strip().splitlines())} lines; the valve's P port now reads "
      f"{rig['circuit.servovalve.ports.supply_pressure']!r}")

# the filter alone between hose and valve: refused before any run
loop = OUT / "filter_without_bowl.toml"
loop.write_text('[rig]\nbase = "ayalew2005_circuit"\n'
                '[circuit.filter]\ntype = "inline_filter"\ncompute = "outlet"\n'
                'ports = { inlet_pressure = "supply_port_pressure", flow = "supply_port_flow", '
                'outlet_pressure = "filter_pressure" }\n'
                '[circuit.servovalve]\nports = { supply_pressure = "filter_pressure" }\n')
try:
    hydroline.simulate(hydroline.load_rig(loop))
except ValueError as err:
    print(f"without the bowl: {err}")

# %%
# Its drop at the steady flow
# ---------------------------
# The 50 mA open-loop step: at rest before it the valve passes its null leakage; during the
# stroke the piston rises at about constant speed. At both steady flows the drop across the
# filter in the run is the hand formula's at the flow through it, and the flow is what the
# bottom chamber takes, A_b v (continuity; the bowl and the chamber store a little as their
# pressures ring, below 1 %).
res = hydroline.simulate(rig, "open-loop-step")
t, q = res.t, res["filter_flow"]
dp = res["supply_port_pressure"] - res["filter_pressure"]


def hand(q):
    return R_L * q + K_T * q * np.abs(q)


rest = np.searchsorted(t, 0.009)
stroke = (t >= 0.02) & (t <= 0.07)
q_stroke = q[stroke].mean()
q_piston = 4.83e-4 * res["piston_velocity"][stroke].mean()      # A_b [paper] times v
print(f"at rest:       q = {q[rest] * 6e4:6.3f} L/min, dp = {dp[rest]:9.1f} Pa "
      f"(hand {hand(q[rest]):9.1f} Pa)")
print(f"during stroke: q = {q_stroke * 6e4:6.2f} L/min (A_b v = {q_piston * 6e4:.2f} L/min), "
      f"dp = {dp[stroke].mean() / 1e5:.3f} bar (hand at the mean flow "
      f"{hand(q_stroke) / 1e5:.3f} bar)")
assert abs(dp[rest] - hand(q[rest])) <= 1e-9 * hand(q[rest])
assert np.max(np.abs(dp - hand(q))) <= 1e-9 * np.max(np.abs(dp))   # every sample
assert abs(q_stroke / q_piston - 1) < 0.02

# %%
# What the filter changes
# -----------------------
# Against the paper's rig without it: the bowl's oil sits at the end of supply section 2, so
# the hose no longer ends on the valve's closed port alone.
base = hydroline.summarize(hydroline.simulate(None, "open-loop-step"))
ours = hydroline.summarize(res)
for label, s in (("paper's rig", base), ("with filter", ours)):
    print(f"{label:12s} valve P port: {s['supply']['frequency_hz']:5.1f} Hz, "
          f"{s['supply']['amplitude_mpa']:.2f} MPa; settles in "
          f"{s['supply']['settling_time_s'] * 1e3:.0f} ms")
res.plot(["supply_port_pressure", "filter_pressure"], path=OUT / "filter_pressures.png",
         title="supply section 2's end and the filter bowl")
