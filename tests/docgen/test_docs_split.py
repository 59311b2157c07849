"""docgen/docs_split.py: the quickstart's picture of a split by runs and by blocks of time."""

from __future__ import annotations

from docgen.docs_split import LOG, SPLITS, main, parts_of


def test_each_run_or_each_block_of_time_is_in_one_part():
    by_runs, by_blocks = (parts_of(LOG, **kwargs) for _, kwargs in SPLITS)
    assert by_runs.groupby(["method", "run"])["part"].nunique().eq(1).all()
    blocks = (by_blocks["t"] // 10).astype(int)  # t starts at 0 in every run of this log
    assert by_blocks.groupby(blocks)["part"].nunique().eq(1).all()
    assert by_blocks.groupby(["method", "run"])["part"].nunique().gt(1).all()  # runs are cut
    assert len(by_runs) == len(by_blocks) == 5249


def test_main_draws_the_picture(tmp_path):
    main(["--figure", str(tmp_path / "split.png")])
    assert (tmp_path / "split.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
