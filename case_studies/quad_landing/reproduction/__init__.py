"""The paper reproduction: ``python -m case_studies.quad_landing reproduce`` end to end.

It owns the reproduction's settings read from ``reproduce.toml`` (:mod:`.config`),
learning and calibrating the IPCs (:mod:`.learn`), Table I (:mod:`.table1`), the Monte
Carlo landing campaigns (:mod:`.campaign`), the certified bound on unsafe landings and
the closed-loop checks (:mod:`.certified`), the figures (:mod:`.figures`), the report
page (:mod:`.report_page`) and the driver that runs them in order and writes
``summary.json`` and ``report.html`` (:mod:`.pipeline`). It is named ``reproduction``
so that it does not shadow the function ``case_studies.quad_landing.reproduce``.
"""
