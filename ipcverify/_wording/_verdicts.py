"""The verdicts of a certificate, each worded once, from plain facts.

A certificate's status, Theorem 1's verdict and the domain of validity's verdict are shown in
three places: the summary (``certificate.json`` and its checks), the CLI's table and the HTML
page. Each is worded here, by one function of the facts (names, counts, flags), and every
rendering calls it, so the three say the same words. The remedies these sentences name (pass the
test data, calibrate) are rendered for the audience of the running code
(:mod:`~ipcverify._wording._spelling`).

Examples
--------
>>> theorem1_verdict(vacuous=True)
'vacuous (proves nothing)'
>>> domain_verdict(present=True, radius_zero=False, queries=100, well_above=False, row_level=False)
'as expected in distribution'
>>> status_verdict("UNTESTED").split(" -- ")[1]
'pass test_data with fresh held-out samples to add the test'
"""

from __future__ import annotations

from ipcverify._wording._audience import Audience, audience
from ipcverify._wording._spelling import option

__all__ = [
    "NOT_RUN",
    "calibrate_call",
    "certify_call",
    "domain_verdict",
    "held_out_remedy",
    "status_verdict",
    "theorem1_verdict",
]

#: Why a check on test data did not run.
NOT_RUN = "no test data given: the held-out test was not run"


def held_out_remedy() -> str:
    """What adds the held-out test: pass the test data (``--data`` on the command line).

    Examples
    --------
    >>> held_out_remedy()
    'pass test_data with fresh held-out samples'
    """
    return f"pass {option('test_data')} with fresh held-out samples"


def calibrate_call() -> str:
    """The call that calibrates a model on held-out data, as the current audience writes it.

    Examples
    --------
    >>> calibrate_call()
    'calibrate(model, calibration_data, epsilon=E, delta=D)'
    """
    if audience() is Audience.CLI:
        return (
            f"ipcverify calibrate MODEL CALIBRATION_DATA {option('epsilon', 'E')} {option('delta', 'D')} "
            f"{option('out', 'calibrated.pt')}"
        )
    return f"calibrate(model, calibration_data, {option('epsilon', 'E')}, {option('delta', 'D')})"


def certify_call() -> str:
    """The call that certifies a model on test data, as the current audience writes it.

    Examples
    --------
    >>> certify_call()
    'certify(model, test_data)'
    """
    if audience() is Audience.CLI:
        return f"ipcverify certify MODEL {option('test_data', 'TEST')}"
    return "certify(model, test_data)"


def status_verdict(status: str) -> str:
    """The sentence of a certificate status (a :class:`~ipcverify.certification.CertificateStatus` name).

    Examples
    --------
    >>> status_verdict("CERTIFIED")
    'certified: calibrated contract, test data consistent with the calibration'
    """
    calibrate = "ipcverify calibrate" if audience() is Audience.CLI else "calibrate(...)"
    texts = {
        "CERTIFIED": "certified: calibrated contract, test data consistent with the calibration",
        "CONTRADICTED": (
            "contradicted: the test data violates the calibration's claim -- check that calibration and "
            "test data come from the deployment distribution; recalibrate on representative data"
        ),
        "NOT_CALIBRATED": (
            f"no calibration certificate: only the test-set bound holds -- run `{calibrate}` on "
            "held-out data to obtain one"
        ),
        "UNCHECKED": "certified by calibration; consistency with the test data not checkable in this mode",
        "ROWS_ASSUMED": (
            "row-level claim on rows that come in runs: it holds only if those rows are independent "
            "samples, which rows of one run usually are not -- calibrate by runs for a claim that does not "
            "assume it"
        ),
        "UNTESTED": (
            "certified by calibration; no test data was given, so nothing checked it independently -- "
            f"{held_out_remedy()} to add the test"
        ),
    }
    return texts[status]


def theorem1_verdict(vacuous: bool) -> str:
    """Theorem 1's verdict: its sound bound is ``>= 1`` (vacuous) or not.

    Examples
    --------
    >>> theorem1_verdict(vacuous=False)
    'not vacuous'
    """
    return "vacuous (proves nothing)" if vacuous else "not vacuous"


def domain_verdict(
    *, present: bool, radius_zero: bool, queries: int, well_above: bool, row_level: bool
) -> str:
    """The domain of validity's verdict from its facts.

    Parameters
    ----------
    present : bool
        The model carries a domain test.
    radius_zero : bool
        Its threshold is 0 (fitted on repeated inputs by an older ipcverify).
    queries : int
        The number of test queries it checked (0: the test was not run).
    well_above : bool
        Far more queries lie outside than false alarms explain.
    row_level : bool
        The test was fitted row by row on data whose rows come in runs.

    Examples
    --------
    >>> domain_verdict(present=True, radius_zero=False, queries=100, well_above=True, row_level=False)
    'SHIFT: far more queries outside than false alarms explain'
    """
    if not present:
        return "absent"
    if radius_zero:
        return "radius 0: flags every query not equal to a calibration input"
    if queries == 0:
        return "not run"
    if well_above and row_level:
        return (
            "SHIFT, or a row-level test on correlated rows: far more queries outside than false alarms "
            "explain"
        )
    if well_above:
        return "SHIFT: far more queries outside than false alarms explain"
    return "as expected in distribution"
