"""
(b) Describing your own rig
===========================

A rig file is TOML. Every value is a string with its unit (any unit of the right dimension:
``"10 ft"``, ``"3000 psi"``, ``"32 cSt"``), and every value should say where it comes from in
a comment: ``[paper]``, ``[datasheet]``, ``[assumed]`` (and why) or ``[calibrated]`` (to
what). The embedded rig, ``hydroline/rigs/ayalew2005.toml``, is the full example.

A file that starts with ``[rig] base = "default"`` changes only what it lists. Here: a rig
with shorter, larger-bore supply hoses and a stiffer return hose. Run time: about 2 s.
"""

# %%
# Write the rig file
# ------------------
from pathlib import Path

import hydroline

OUT = Path("tutorial-out")
OUT.mkdir(exist_ok=True)

RIG = """
[rig]
base = "default"                 # start from the embedded Ayalew & Kulakowski (2005) rig
name = "our bench, short supply hoses"   # [assumed] label only

[supply.section2]                # manifold -> servovalve P port
length = "5 ft"                  # [measured] tape measure, fitting to fitting
diameter = "19.05 mm"            # [datasheet] SAE J517 100R2 size -12 bore

[return.section2]                # servovalve T port -> manifold
bulk_modulus = "160 MPa"         # [assumed] new hose, less entrained air than the paper's
"""
path = OUT / "our_bench.toml"
path.write_text(RIG)

# %%
# Load it and check what it changed
# ---------------------------------
# Values are held in SI: 5 ft is 1.524 m, 19.05 mm is 0.01905 m.
ours = hydroline.load_rig(path)
default = hydroline.load_rig()
for key in ("supply.section2.length", "supply.section2.diameter",
            "return.section2.bulk_modulus", "supply.section1.length"):
    print(f"{key:32s} default {default[key]:<12.6g} ours {ours[key]:<12.6g} [SI]")

# %%
# Units are checked at the edge
# -----------------------------
# A bare number where a unit matters, or a unit of the wrong dimension, is refused with one
# line naming the parameter.
for bad in ("3", "3 MPa"):
    try:
        ours.set("supply.section2.length", bad)
    except ValueError as err:
        print(f"{bad!r}: {err}")

# %%
# Run it and compare
# ------------------
for label, rig in (("default", default), ("ours", ours)):
    s = hydroline.summarize(hydroline.simulate(rig, "open-loop-step"))
    print(f"{label:8s} supply {s['supply']['frequency_hz']:5.1f} Hz "
          f"{s['supply']['amplitude_mpa']:.2f} MPa | return {s['return']['frequency_hz']:5.1f} Hz "
          f"{s['return']['amplitude_mpa']:.2f} MPa")

# %%
# A changed rig can be written back, with units, for the next person:
(OUT / "our_bench_full.toml").write_text(ours.to_toml())
