"""Sphinx configuration of sinslab's documentation (``make docs`` builds it into site/).

The pages are the Markdown files of this folder, read by MyST; the API reference is
generated from the docstrings by autodoc (numpy-style sections through napoleon). The
docstrings' cross-references (``:func:``, ``:class:``, ``:mod:``) are checked: a reference
to a sinslab name that does not exist is a warning, and the test suite builds with
warnings as errors. References to other packages' names (numpy's ``ndarray``, ...) are
left unlinked: the build reads no inventory over the network.
"""
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
os.environ.setdefault("MPLBACKEND", "Agg")

import sinslab  # noqa: E402

project = "sinslab"
author = "The sinslab developers"
copyright = "2026, The sinslab developers"
release = sinslab.__version__
version = release

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "INTERFACES.md"]
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False,
                           "member-order": "bysource"}
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
# numpy's ArrayLike by its name, not the union it stands for (a screenful per parameter)
autodoc_type_aliases = {"ArrayLike": "numpy.typing.ArrayLike", "NDArray": "numpy.typing.NDArray"}
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# parameter and attribute types as text: "ndarray (n, 3)" is a shape, not references to names
napoleon_use_param = False
napoleon_use_ivar = True

# every reference checked; names outside sinslab (numpy, scipy, the standard library) have
# no inventory here, so only sinslab's own are required to resolve
nitpicky = True
nitpick_ignore_regex = [(r"py:.*", r"(?!sinslab\.).*"),
                        # private names (a leading underscore) are not in the reference by design
                        (r"py:.*", r"sinslab\..*\._\w+.*"),
                        # type variables of generic functions
                        (r"py:class", r"sinslab\..*\.[A-Z]")]
# a word of a type written in a docstring ("ndarray (n, 3)") that names attributes of
# several classes is ambiguous text, not a broken reference
suppress_warnings = ["ref.python"]

html_theme = "alabaster"
html_title = f"sinslab {release}"
html_theme_options = {"description": "Strapdown inertial navigation in Python", "fixed_sidebar": False,
                      "show_relbars": True}
html_static_path: list[str] = []
html_show_sourcelink = False
