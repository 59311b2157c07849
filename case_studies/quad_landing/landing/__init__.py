"""Landing: the paper's landing state machine and what it needs to fly one run.

It owns the random landing scenarios (:mod:`.scenario`), the perception contracts the
state machine queries, the learned IPC and the trivial baseline (:mod:`.contracts`), the
state machine with its exact accept and cut tests (:mod:`.state_machine`,
``proofs/landing_safety.md``) and the record of a run (:mod:`.runs`). Flying many runs
and judging them is :mod:`case_studies.quad_landing.reproduction`'s job.
"""
