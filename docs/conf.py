"""Sphinx configuration of the pmsm2dof documentation site.

Built by ``bash scripts/build-docs.sh`` with the repository root as the source folder, so that the
Markdown pages that live beside the code (README.md, RELIABILITY.md, benchmarks/results.md, docs/)
are the pages of the site as they are, and their relative links work both on the site and in the
repository. ``include_patterns`` says which files are pages.
"""

import importlib
import sys
import types
from importlib.metadata import version as package_version
from pathlib import Path

from sphinx.pycode import ModuleAnalyzer

import pmsm2dof

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "pmsm2dof"
author = "the pmsm2dof developers"
copyright = "2026 the pmsm2dof developers, MIT license"
release = version = package_version("pmsm2dof")

root_doc = "docs/index"
include_patterns = ["docs/**", "RELIABILITY.md", "benchmarks/results.md"]
exclude_patterns = ["docs/_ext/**", "docs/_templates/**", "docs/gallery/*.ipynb", "docs/gallery/*.py"]
# relative to the source folder (the repository root), where autosummary looks for its templates
templates_path = ["docs/_templates"]

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "sphinx_click",
    "matplotlib.sphinxext.plot_directive",
    "c_headers",
]

# Markdown pages: $...$ maths as in the repository's pages, anchors for the headings that the pages link to
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 4

# API reference: one page per module of pmsm2dof, found by walking the package (a new module appears by itself)
# and each object on the page of the module that defines it (a package's __all__ re-exports are linked, not
# repeated); the package's page links the names of pmsm2dof/__init__.py to their modules.
autosummary_generate = True
autosummary_ignore_module_all = True


def defined_in(name, module):
    """The module that defines the public name ``name`` of ``module``: a class's or function's own, else (data
    carry no ``__module__``) the module below ``module`` whose source documents it with a ``#:`` comment, else
    ``module``."""
    obj = getattr(importlib.import_module(module), name)
    if isinstance(obj, type | types.FunctionType):
        return obj.__module__
    for holder in sorted(m for m in sys.modules if m == module or m.startswith(module + ".")):
        if ("", name) in ModuleAnalyzer.for_module(holder).find_attr_docs():
            return holder
    return module


# relative to the package: autosummary refuses the current module's own name in its items
autosummary_context = {
    "facade": {
        name: f"{defined_in(name, module)}.{name}".removeprefix("pmsm2dof.")
        for name, module in pmsm2dof._EXPORTS.items()
    }
}
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_xref_param_type = False

# The gallery: examples/plot_*.py run during the build; an example that raises fails it
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": str(DOCS / "gallery"),
    "filename_pattern": r"/plot_",
    "abort_on_example_error": True,
    # every build runs every example: one unchanged may still break on a change of the package
    "run_stale_examples": True,
    "download_all_examples": False,
    "show_memory": False,
    "write_computation_times": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    # pyplot's figures and the package's own (pmsm2dof.ui.plots returns Figure objects outside pyplot)
    "image_scrapers": ("matplotlib", "gallery_figures.scrape"),
}

# Figures of the tuning guide (docs/figures/*.py), drawn by the package at build time
plot_basedir = str(DOCS)
plot_include_source = False
plot_html_show_source_link = True
plot_html_show_formats = False
plot_formats = [("png", 110)]

# "--feedforward" is an option, not a dash: no typographic quotes and dashes
smartquotes = False

html_theme = "furo"
html_title = "pmsm2dof"


def terminal_text(app, ctx, lines):
    """The command line's help texts are written for a terminal: a ``*`` in them is no reST emphasis (the
    ``**Required**`` that sphinx-click adds is)."""
    lines[:] = [line.replace("*", r"\*").replace(r"\*\*Required\*\*", "**Required**") for line in lines]


def setup(app):
    for part in ("description", "options", "arguments", "epilog"):
        app.connect(f"sphinx-click-process-{part}", terminal_text)
