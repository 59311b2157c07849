"""Data: flying the simulator to collect lagged measurements, and the datasets made of them.

It owns the exploration paths (:mod:`.paths`), their collection into a dataset and the
dataset files (:mod:`.collect`), the columns every dataset has (:mod:`.columns`), the
approach flights that look like landing runs (:mod:`.approach`), the reproduction's mixed
and cached datasets (:mod:`.datasets`), and the documentation pictures
(:mod:`.pictures`, ``python -m case_studies.quad_landing pictures``).
"""
