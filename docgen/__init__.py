"""Generators of the documentation's pages, figures and data: ``python -m docgen.NAME``.

Not installed with ipcverify; run from the repository root. A generator writes what the docs
show (a figure under ``docs/img/``, the numbers pasted between ``generated`` markers, the JSON a
page quotes, beside the script) or test data (``landing_sets``); the benchmarks, which measure,
are in ``benchmarks/``. Nothing here is a test: ``tests/docgen/`` checks the pages against what
these scripts write.
"""
