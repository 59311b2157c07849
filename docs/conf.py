"""Sphinx configuration of the documentation site (issue 39).

Build it from the repository's root (the tests do: ``tests/test_site.py``)::

    python -m sphinx -W -b html -c docs . docs/_build/html

The source directory is the repository's root so that the pages in ``docs/`` and ``proofs/``
link each other, and the code and tests they cite, by the same relative paths that GitHub and
``tests/test_docs.py`` resolve; ``include_patterns`` keeps every other file out of the site. The
gallery's scripts are in ``examples/``; sphinx-gallery runs them and writes their pages to
``docs/auto_examples/`` (not committed).
"""

from __future__ import annotations

import os

import ipcverify

project = "ipcverify"
author = "the ipcverify authors"
copyright = "the ipcverify authors, MIT licence"  # noqa: A001 (Sphinx's name)
release = version = ipcverify.__version__

root_doc = "docs/index"
include_patterns = [
    "docs/**",
    "proofs/**",
    "CHANGELOG.md",
    "data/README.md",  # the bundled real log
    "benchmarks/results.md",  # every table of the committed benchmark run
    "tests/ipcverify/io/ingest/data/euroc_mh04/README.md",  # the ingestion example's excerpt
]
exclude_patterns = [
    "docs/_build",
    "docs/auto_examples/*.ipynb",
    "docs/auto_examples/*.py",
    "**/.ipynb_checkpoints",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}

extensions = [
    "myst_parser",  # the Markdown pages
    "sphinx.ext.autodoc",  # the API reference, from the docstrings
    "numpydoc",  # ... which are numpydoc
    "sphinx_gallery.gen_gallery",  # examples/, run at every build
]

# MyST: headings get anchors (the pages link "page.md#a-heading"), $...$ is not math.
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence"]

# autodoc + numpydoc: the signature as written (the PEP 604 types), members not listed on
# their own (a class's attributes are in its docstring's Attributes section).
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

sphinx_gallery_conf = {
    "examples_dirs": "examples",  # relative to the source directory (the root)
    "gallery_dirs": "docs/auto_examples",
    "filename_pattern": r"/plot_",  # every script runs
    "download_all_examples": False,
    "remove_config_comments": True,
    "write_computation_times": False,  # no sg_execution_times page in the source tree
    "matplotlib_animations": False,
    "abort_on_example_error": True,
    "plot_gallery": "True",
    "show_memory": False,
    "run_stale_examples": True,  # every build runs every example, so each is checked as written
}

html_theme = "pydata_sphinx_theme"
html_title = f"ipcverify {release}"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_show_sourcelink = False

# the examples render their figures off-screen
os.environ.setdefault("MPLBACKEND", "Agg")


def _copy_page_images(app, exception):  # noqa: ANN001, ANN202 (Sphinx's event signature)
    """Copy ``docs/img/`` beside the built pages, and lead the output's ``index.html`` to the site.

    The pages show figures in raw HTML (``<p align="center"><img src="img/...">``, as GitHub
    renders them), which Sphinx passes through without collecting the files; copying the
    folder makes those paths resolve in the site as they do in the repository.
    """
    import shutil
    from pathlib import Path

    if exception is None and app.builder.format == "html":
        img = Path("docs") / "img"
        shutil.copytree(Path(app.srcdir) / img, Path(app.outdir) / img, dirs_exist_ok=True)
        # the root document is docs/index; the output folder's own index.html leads there
        (Path(app.outdir) / "index.html").write_text(REDIRECT, encoding="utf-8")


REDIRECT = (
    '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>ipcverify</title>'
    '<meta http-equiv="refresh" content="0; url=docs/index.html"></head>'
    '<body><a href="docs/index.html">ipcverify documentation</a></body></html>\n'
)


def setup(app):  # noqa: ANN001, ANN201
    app.connect("build-finished", _copy_page_images)
    return {"parallel_read_safe": True}
