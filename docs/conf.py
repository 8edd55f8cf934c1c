"""Sphinx configuration of the flexid documentation.

Build (from the repository root, with the ``docs`` extra installed)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

The gallery executes the ``examples/gallery/plot_*.py`` scripts at build time.
"""

from __future__ import annotations

import importlib
import inspect
import os
import pkgutil
import pydoc
import types
import warnings

from sphinx.util import logging

import flexid

# matplotlib without a display, before sphinx-gallery or flexid.report.plots import pyplot
os.environ.setdefault("MPLBACKEND", "Agg")

project = "flexid"
author = "flexid developers"
copyright = "flexid developers"
release = flexid.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "myst_parser",  # docs/architecture.md stays Markdown: it is read on GitHub too
]

templates_path = ["_templates"]
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
root_doc = "index"
default_role = "code"  # `x` in the pages is inline code, as in the README

# ---------------------------------------------------------------------------- API reference
autosummary_generate = True
autosummary_ignore_module_all = False  # a module's __all__ is its documented contract
autodoc_typehints = "none"  # numpydoc's Parameters sections state the types and shapes
autodoc_default_options = {"member-order": "bysource"}
numpydoc_show_class_members = False  # members come from the class template instead
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

intersphinx_mapping = {
    "python": ("https://docs.python.org/3", None),
    "numpy": ("https://numpy.org/doc/stable", None),
    "scipy": ("https://docs.scipy.org/doc/scipy", None),
    "gymnasium": ("https://gymnasium.farama.org", None),
}
# The build must not need the network (CI, offline machines): intersphinx inventories are
# fetched only when FLEXID_DOCS_INTERSPHINX=1.
if os.environ.get("FLEXID_DOCS_INTERSPHINX") != "1":
    intersphinx_mapping = {}

# A name that several public modules export is documented once, in the module with the
# shortest dotted name (``flexid.optimisers.Param``, not ``flexid.optimisers.registry.Param``);
# the other modules link to it. Two pages for one object would be two descriptions of its
# canonical (private-module) name, which Sphinx refuses.


def _public_modules() -> list[str]:
    names = []
    for info in pkgutil.walk_packages(flexid.__path__, "flexid."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            names.append(info.name)
    return sorted(names)


def _reexports() -> dict[str, dict[str, str]]:
    homes: dict[int, tuple[str, str]] = {}
    exported: list[tuple[str, str, object]] = []
    for modname in _public_modules():
        module = importlib.import_module(modname)
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if not (inspect.isclass(obj) or inspect.isfunction(obj)):
                continue
            exported.append((modname, name, obj))
            home = homes.get(id(obj))
            if home is None or (len(modname), modname) < (len(home[0]), home[0]):
                homes[id(obj)] = (modname, name)
    out: dict[str, dict[str, str]] = {}
    for modname, name, obj in exported:
        home_module, home_name = homes[id(obj)]
        if home_module != modname:
            out.setdefault(modname, {})[name] = f"{home_module}.{home_name}"
    return out


autosummary_context = {"reexported": _reexports()}

# ---------------------------------------------------------------------------- gallery
sphinx_gallery_conf = {
    "examples_dirs": "../examples/gallery",
    "gallery_dirs": "auto_examples",
    # The gallery holds the figure scripts, run at build time. The scripts one folder up
    # write files or read recorded data outside the repository; the getting-started pages
    # show them.
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"^(?!plot_).*\.py$",  # matched against the file name
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "write_computation_times": False,  # no execution-time page in the source tree
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "doc_module": ("flexid",),
    "reference_url": {"flexid": None},
    # A block ending in a call that returns a matplotlib object (a Figure, a Line2D, a
    # Legend) would show that object's repr, "<Figure size 640x400 with 1 Axes>", under the
    # figure; the figure itself is what the reader wants.
    "ignore_repr_types": r"matplotlib[.]",
    # FLEXID_DOCS_RERUN_GALLERY=1 runs every example again even when its script has not
    # changed (sphinx-gallery skips it by its MD5 otherwise), so that a change in flexid's
    # plotting code shows in the figures; docs/check_site.py sets it.
    "run_stale_examples": os.environ.get("FLEXID_DOCS_RERUN_GALLERY") == "1",
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "plot_gallery": "True",
}

# ---------------------------------------------------------------------------- HTML
html_theme = "pydata_sphinx_theme"
html_title = f"flexid {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_show_sourcelink = False
# no left sidebar (the top bar holds the navigation): the page's width goes to the text and
# the code, so examples are not cut off on the right
html_sidebars = {"**": []}
html_static_path = ["_static"]
# gallery output (printed summaries and tables) shown whole: wrapped, not cut at 30em
html_css_files = ["flexid.css"]


# ---------------------------------------------------------------------------- numpydoc warnings
# numpydoc reports a docstring section it does not know (and drops its text from the page)
# through Python's warnings module, which Sphinx's -W does not see; forwarding it to Sphinx's
# logger makes a dropped section fail the build instead of vanishing silently.
_logger = logging.getLogger("flexid.docs")
_show_warning = warnings.showwarning


def _forward_numpydoc_warnings(message, category, filename, lineno, file=None, line=None):
    if "numpydoc" in str(filename).replace(os.sep, "/"):
        _logger.warning("numpydoc: %s", message, type="numpydoc")
    else:
        _show_warning(message, category, filename, lineno, file, line)


warnings.showwarning = _forward_numpydoc_warnings


# ---------------------------------------------------------------------------- type aliases
def _alias_signature(app, what, name, obj, options, signature, return_annotation):
    """Keep numpydoc from giving a type alias (``StateSpace = tuple[...]``) a call signature.

    An alias is callable, so numpydoc answers with the aliased builtin's signature, which
    autodoc cannot attach to a data entry. An empty (not None) answer is the first result,
    so numpydoc's is not used, and it is falsy, so autodoc keeps no signature.
    """
    if isinstance(obj, types.GenericAlias) or type(obj).__module__ == "typing":
        return ()
    return None


# ---------------------------------------------------------------------------- inherited docstrings
def _drop_foreign_docstring(app, what, name, obj, options, lines):
    """Drop a docstring that a flexid method without one inherits from another library.

    The environments' ``step`` and ``reset`` would otherwise show Gymnasium's docstrings,
    which are not numpydoc and do not describe flexid's plants.
    """
    if what not in ("method", "property", "attribute") or getattr(obj, "__doc__", None):
        return
    owner_name, _, attr = name.rpartition(".")
    owner = pydoc.locate(owner_name)
    if not inspect.isclass(owner):
        return
    for klass in owner.__mro__[1:]:
        member = vars(klass).get(attr)
        if member is not None and getattr(member, "__doc__", None):
            if not klass.__module__.split(".")[0] == "flexid":
                lines.clear()
            return


# ---------------------------------------------------------------------------- gallery figures
def _drop_unbuilt_gallery_figures(app, docname, source):
    """Leave out a page's figure of a gallery image that was not drawn (``-D plot_gallery=0``).

    The index shows a figure the gallery draws at build time; a quick build that skips the
    gallery has no such file, and a missing image would fail the build under ``-W``.
    """
    lines = source[0].splitlines(keepends=True)
    out, i = [], 0
    while i < len(lines):
        line = lines[i]
        target = line.partition(".. figure:: ")[2].strip()
        if line.startswith(".. figure:: auto_examples/images/") and not os.path.exists(
            os.path.join(app.srcdir, target)
        ):
            i += 1
            while i < len(lines) and (not lines[i].strip() or lines[i].startswith(" ")):
                i += 1
            continue
        out.append(line)
        i += 1
    source[0] = "".join(out)


# ---------------------------------------------------------------------------- coverage
def _check_api_index(app):
    """Warn (an error under -W) when a public module is missing from the API reference."""
    index = os.path.join(app.srcdir, "api", "index.rst")
    with open(index, encoding="utf-8") as f:
        listed = {line.strip() for line in f}
    for modname in _public_modules():
        if modname not in listed:
            _logger.warning(
                "public module %s is not listed in docs/api/index.rst", modname, type="flexid"
            )


def setup(app):
    # before numpydoc's handler (priority 500): the first answer that is not None wins
    app.connect("autodoc-process-signature", _alias_signature, priority=100)
    app.connect("builder-inited", _check_api_index)
    app.connect("source-read", _drop_unbuilt_gallery_figures)
    # before numpydoc parses the docstring
    app.connect("autodoc-process-docstring", _drop_foreign_docstring, priority=100)
