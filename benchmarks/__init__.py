"""Benchmark scripts and the one-command benchmark suite (``python -m benchmarks.run``).

Not installed with ipcverify; run from the repository root. Nothing here is a test:
the scripts measure and write their numbers to JSON beside them.
"""
