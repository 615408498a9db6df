"""The documentation's pages point at things that exist.

* every test named on the verification page (``tests/test_x.py::test_name``, or
  ``::test_name`` after a file named earlier in the same cell) is defined in that file;
* every equation number cited in the package, the tests and the rig files, (M1)...(M38), is
  defined in the model reference (``\\tag{M#}``), so a citation never dangles;
* the values the model reference quotes for the default rig (§7, the table of §9) are the
  rig's.
"""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def test_verification_page_names_existing_tests():
    text = (DOCS / "verification.md").read_text()
    named = 0
    for cell in re.split(r"\|", text):
        current = None
        for m in re.finditer(r"(tests/test_\w+\.py)?(?:::(test_\w+))?", cell):
            if m.group(1):
                current = m.group(1)
                assert (ROOT / current).is_file(), current
            if not m.group(2):
                continue
            assert current, f"'::{m.group(2)}' without a file before it"
            source = (ROOT / current).read_text()
            assert re.search(rf"^def {m.group(2)}\(", source, re.M), f"{current}::{m.group(2)}"
            named += 1
    assert named > 40


def test_every_cited_equation_is_in_the_model_reference():
    defined = set(re.findall(r"\\tag\{(M\d+)\}", (DOCS / "model.md").read_text()))
    assert defined == {f"M{i}" for i in [*range(1, 39), *range(40, 46)]}
    cited = set()
    for path in [*ROOT.glob("hydroline/**/*.py"), *ROOT.glob("hydroline/**/*.toml"),
                 *ROOT.glob("tests/*.py"), ROOT / "README.md"]:
        cited |= set(re.findall(r"\b(M\d{1,2})\b", path.read_text()))
    assert cited - defined == set(), f"cited but not in docs/model.md: {sorted(cited - defined)}"


def _section(text: str, heading: str) -> str:
    """The text of one ``## heading`` section of a Markdown page."""
    start = text.index(f"\n## {heading}")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


def _si(text: str) -> float:
    """A quantity as the page writes it (``1e9 N/m``, ``50 mA``, ``0.02``) in SI base units."""
    from hydroline.units import ureg

    return float(ureg.Quantity(text.replace("*", " ")).to_base_units().magnitude)


def _default_rig_value(path: str) -> float:
    """What the default rig builds with at ``path``: its file's value, else the built
    component's attribute (a manifold's node volume: with its section II removed), else, for
    ``Class.parameter``, the component class's default."""
    import dataclasses

    import hydroline
    from hydroline import components
    from hydroline.system import build_circuit

    head, _, attr = path.rpartition(".")
    if head[:1].isupper():
        field = {f.name: f for f in dataclasses.fields(getattr(components, head))}[attr]
        return field.default
    rig = hydroline.load_rig()
    if rig.get(path) is not None:
        return rig[path]
    if head.endswith(".manifold") and attr == "volume":
        side = head.split(".")[0]
        rig = rig.copy().set(f"{side}.section2.length", "0 m")
        return getattr(build_circuit(rig).component(f"{side}.node"), attr)
    return getattr(build_circuit(rig).component(head), attr)


def test_model_reference_values_are_the_default_rigs():
    """The table of default-rig values in docs/model.md §9 states what the rig builds."""
    table = _section((DOCS / "model.md").read_text(), "9. ")
    rows = re.findall(r"^\| [^|]+ \| [^|]+ \| ([^|]+) \| `([\w.]+)` \|$", table, re.M)
    assert len(rows) >= 20
    for value, path in rows:
        expected = float(_default_rig_value(path))
        assert _si(value) == pytest.approx(expected, rel=5e-4, abs=1e-30), f"{path}: {value}"


def test_model_reference_section_7_quotes_the_rig_file():
    """The paper's data and the calibrated values quoted in §7 are the default rig file's."""
    import hydroline

    text = _section((DOCS / "model.md").read_text(), "7. ")
    rig = hydroline.load_rig()
    quoted = {"supply.section2.bulk_modulus": "203.8 MPa", "supply.section2.diameter": "13.43 mm",
              "return.section2.bulk_modulus": "140.8 MPa", "return.section2.diameter": "13.61 mm",
              "actuator.bulk_modulus": "689.5 MPa", "actuator.moving_mass": "7.953 kg",
              "actuator.stroke": "102 mm", "supply.section2.length": "3.048 m",
              "return.section2.length": "3.048 m", "servovalve.natural_frequency": "140 Hz",
              "servovalve.rated_current": "50 mA"}
    for path, shown in quoted.items():
        assert shown in text, f"§7 no longer quotes {shown} ({path})"
        assert _si(shown) == pytest.approx(rig[path], rel=5e-4), f"{path}: §7 says {shown}"
