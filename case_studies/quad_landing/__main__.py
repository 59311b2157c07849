"""``python -m case_studies.quad_landing``: see :mod:`case_studies.quad_landing.cli`."""

from case_studies.quad_landing.cli import main

if __name__ == "__main__":
    main()
