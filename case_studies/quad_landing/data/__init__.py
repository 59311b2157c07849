"""Data: flying the simulator to collect measurements, and the datasets made of them.

It owns the exploration paths (:mod:`.paths`), their collection into a dataset and the
dataset files (:mod:`.collect`), recorded flights measured with any camera afterwards
(:mod:`.recording`), the columns every dataset has (:mod:`.columns`), the approach flights
that look like landing runs (:mod:`.approach`), the pilot test flights of Table I
(:mod:`.pilot`), the reproduction's mixed and cached datasets (:mod:`.datasets`), and the
documentation pictures (:mod:`.pictures`, ``python -m case_studies.quad_landing pictures``).
"""
