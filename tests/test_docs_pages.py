"""The documentation's pages point at things that exist.

* every test named on the verification page (``tests/test_x.py::test_name``, or
  ``::test_name`` after a file named earlier in the same cell) is defined in that file;
* every equation number cited in the package, the tests and the rig files, (M1)...(M24), is
  defined in the model reference (``\\tag{M#}``), so a citation never dangles.
"""
import re
from pathlib import Path

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
    assert defined == {f"M{i}" for i in [*range(1, 27), *range(40, 45)]}
    cited = set()
    for path in [*ROOT.glob("hydroline/**/*.py"), *ROOT.glob("hydroline/**/*.toml"),
                 *ROOT.glob("tests/*.py"), ROOT / "README.md"]:
        cited |= set(re.findall(r"\b(M\d{1,2})\b", path.read_text()))
    assert cited - defined == set(), f"cited but not in docs/model.md: {sorted(cited - defined)}"
