"""Sphinx configuration of the hydroline documentation.

Build locally (after ``pip install -e '.[docs]'``)::

    sphinx-build -W -b html docs docs/_build/html

Tutorials (``docs/tutorials/*.py``) are executed by sphinx-gallery during the build (the
same work as running the six scripts, about a minute of two idle cores with an empty
hydroline cache; unchanged tutorials are not run again), and their printed output and
figures are embedded; a tutorial that fails fails the build, and so does one that runs past
``HYDROLINE_DOCS_TUTORIAL_TIMEOUT`` seconds (default 600; ``docs/gallery_timeout.py``).
``HYDROLINE_DOCS_EXECUTE=0``
renders them without running them. ``tests/test_tutorials.py`` checks a built site
(``HYDROLINE_DOCS_BUILT=docs/_build/html``): every tutorial ran, printed, and shows its
figures.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "docs"))    # gallery_scraper
os.environ.setdefault("MPLBACKEND", "Agg")

import hydroline  # noqa: E402

project = "hydroline"
author = "the hydroline developers"
copyright = "2026, the hydroline developers"
release = version = hydroline.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",            # MathJax 3 from the package, not a CDN: maths offline
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "tutorials/*.rst",
                    "auto_tutorials/*.ipynb", "auto_tutorials/*.py", "auto_tutorials/*.zip",
                    "auto_tutorials/*.json", "auto_tutorials/*.md5"]

# Markdown pages (model reference, notes): $...$ and $$...$$ maths, equation labels.
# a further-pages glob in the index may match nothing in a checkout without topic notes
suppress_warnings = ["toc.empty_glob"]

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
myst_dmath_double_inline = True

# API reference
autosummary_generate = True
autodoc_default_options = {"members": True, "ignore-module-all": True}
autodoc_typehints = "none"           # types are in the numpydoc Parameters sections
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
numpydoc_attributes_as_param_list = True


sphinx_gallery_conf = {
    "examples_dirs": ["tutorials"],
    "gallery_dirs": ["auto_tutorials"],
    "filename_pattern": r"/tutorial_",
    "plot_gallery": os.environ.get("HYDROLINE_DOCS_EXECUTE", "1") != "0",
    # hydroline saves its figures to files; show those as well as open pyplot figures
    "image_scrapers": ("gallery_scraper.written_figures", "matplotlib"),
    "download_all_examples": False,
    "within_subsection_order": "FileNameSortKey",
    "remove_config_comments": True,
    # a time limit per tutorial (docs/gallery_timeout.py): one that hangs fails the build,
    # naming itself, instead of holding CI until the job's own limit
    "reset_modules": ("matplotlib", "gallery_timeout.limit_time"),
    "reset_modules_order": "both",
}

#: Modules whose docstrings are numpydoc (checked by tests/test_docstrings_numpydoc.py).
NUMPYDOC_MODULES = [line.strip() for line in (ROOT / "docs" / "numpydoc_modules.txt").read_text().splitlines()
                    if line.strip() and not line.startswith("#")]


def _owner_module(what, name, obj):
    """The module that wrote a documented object's docstring (its own name for a module).

    A method without a docstring of its own shows its base class's (autodoc inherits it): that
    docstring is the base's module's, converted or not (a component's ``outputs_of`` shows the
    engine's ``Component.outputs_of``)."""
    if what == "module":
        return name
    mod = getattr(obj, "__module__", None)
    if mod is None:                        # properties, attributes: take the dotted name
        mod = name.rsplit(".", 2)[0]
    func = obj.fget if isinstance(obj, property) else getattr(obj, "__func__", obj)
    if what in ("method", "property") and getattr(func, "__doc__", None) is None:
        import importlib

        cls_path, _, attr = name.rpartition(".")
        modname, _, clsname = cls_path.rpartition(".")
        try:
            cls = getattr(importlib.import_module(modname), clsname)
        except (ImportError, AttributeError, ValueError):
            return mod
        for base in getattr(cls, "__mro__", ())[1:]:
            if attr in base.__dict__:
                return base.__module__
    return mod


def show_unconverted_verbatim(app, what, name, obj, options, lines):
    """Docstrings of modules not yet in numpydoc_modules.txt are shown as they are written.

    The compact one-line style (``name : float   Meaning, [unit]``) reads wrongly when parsed
    as numpydoc and its ``|x|`` notation breaks reStructuredText, so until a module is
    converted its docstrings appear verbatim, in a literal block.
    """
    if _owner_module(what, name, obj) in NUMPYDOC_MODULES or not lines:
        return
    import inspect

    raw = inspect.getdoc(obj) or ""
    if not raw.strip():
        return
    lines[:] = ["::", ""] + ["    " + line for line in raw.splitlines()] + [""]


def setup(app):
    # after numpydoc (priority 500): replace its rendering for unconverted modules
    app.connect("autodoc-process-docstring", show_unconverted_verbatim, priority=900)


html_theme = "alabaster"
html_title = "hydroline"
html_static_path: list[str] = []
