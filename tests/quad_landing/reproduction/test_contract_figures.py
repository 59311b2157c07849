"""The three-contract figure: a rate of zero reads 0 on the log axis, not the floor's value."""

from __future__ import annotations

from case_studies.quad_landing.reproduction.contract_figures import plot_contracts


def test_the_bottom_tick_of_table_one_reads_zero():
    fig = plot_contracts({}, floor=1e-3)
    ax = fig.axes[0]
    labels = [ax.yaxis.get_major_formatter()(v, i) for i, v in enumerate(ax.get_yticks())]
    assert labels == ["0", "1 %", "10 %", "100 %"]
    assert ax.get_ylim()[0] < 1e-3 < 1 / 300  # the floor lies below the smallest non-zero rate
