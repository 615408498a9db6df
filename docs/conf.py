"""Sphinx configuration of the hydroline documentation.

Build locally (after ``pip install -e '.[docs]'``)::

    sphinx-build -W -b html docs docs/_build/html

Tutorials (``docs/tutorials/*.py``) are rendered by sphinx-gallery without executing them
(the test suite runs them: ``tests/test_tutorials.py``); set ``HYDROLINE_DOCS_EXECUTE=1`` to
execute them during the build and embed their figures and output.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
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
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
myst_dmath_double_inline = True

# API reference
autosummary_generate = True
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_typehints = "none"           # types are in the numpydoc Parameters sections
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
numpydoc_attributes_as_param_list = True


sphinx_gallery_conf = {
    "examples_dirs": ["tutorials"],
    "gallery_dirs": ["auto_tutorials"],
    "filename_pattern": r"/tutorial_",
    "plot_gallery": os.environ.get("HYDROLINE_DOCS_EXECUTE", "0") == "1",
    "download_all_examples": False,
    "within_subsection_order": "FileNameSortKey",
    "remove_config_comments": True,
}

html_theme = "alabaster"
html_title = "hydroline"
html_static_path: list[str] = []
