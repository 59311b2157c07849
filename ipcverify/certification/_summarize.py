"""Build a certificate's executive summary (:class:`~ipcverify.certification.CertificateSummary`).

:func:`summarize` reads a :class:`~ipcverify.certification.Certificate` and writes down, without
deciding anything anew, what its records already say: the claim in one sentence, ``epsilon``,
``delta`` and the unit of the claim, and one line per check -- the calibration certificate, the
held-out test, the per-flight test (when the test was counted per group), the domain of validity
and Theorem 1 -- with the verdict the certificate reached and the numbers behind it.
:func:`ipcverify.certification.certify` calls it and stores the result in the certificate.
"""

from __future__ import annotations

from collections.abc import Sequence

from ipcverify._package import VERSION
from ipcverify._wording._spelling import option, regroup_domain
from ipcverify._wording._verdicts import NOT_RUN, domain_verdict, held_out_remedy, theorem1_verdict
from ipcverify.calibration._protocol import GroupUnit
from ipcverify.certification._certificate import Certificate, CertificateStatus
from ipcverify.certification._summary import CertificateSummary, Check, CheckLevel, target_strength, utc_now
from ipcverify.certification._test_result import GroupTest, TestResult
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.guard._domain_report import DomainReport


def capitalized(text: str) -> str:
    """``text`` with its first letter upper-cased and the rest untouched (unlike ``str.capitalize``).

    Parameters
    ----------
    text : str
        A sentence to start a line with (a check's name, the reason Theorem 1 was not computed);
        empty text is returned as it is.

    Examples
    --------
    >>> capitalized("not computed: before Theorem 1 covered it")
    'Not computed: before Theorem 1 covered it'
    """
    return text[:1].upper() + text[1:]


def _status_detail(status: CertificateStatus) -> str:
    """The status text without a leading repetition of its name ("certified: ...")."""
    return status.text.removeprefix(status.name.lower().replace("_", " ") + ": ")


def _shift_note(cert: Certificate) -> str:
    """For a certified contract whose test queries lie far outside its domain: the verdict says so.

    The rule is on the certificate's facts: a CERTIFIED status whose domain report counts far more
    test queries outside than its flag rate explains (:attr:`DomainReport.well_above_flag_rate`).
    The test can then be consistent with the claim while most queries lie where the certificate
    promises nothing, and the verdict line must not say only the former.
    """
    d = cert.domain
    if cert.status is not CertificateStatus.CERTIFIED or d is None or not d.well_above_flag_rate:
        return ""
    why = "a shift" if d.row_level_column is None else "a shift, or a row-level test on correlated rows"
    if d.threshold == 0:
        why = "a domain test of radius 0, fitted on repeated rows: recalibrate"
    return (
        f"; but {100 * d.outside_fraction:.0f} % of the test queries lie outside the domain of validity "
        f"({why}: the certificate promises nothing for them)"
    )


def _claim(cert: Certificate) -> str:
    cal, test = cert.calibration, cert.test
    if cal is not None:
        return cal.guarantee
    if test is None:
        return "Nothing is claimed: the model is not calibrated and no test data was given."
    return (
        "No calibration certificate; the held-out test alone says that, with confidence "
        f"{1 - test.delta:.6g}, the violation rate is at most {test.bound_text()} "
        f"({test.violations} of {test.n} test {test.unit} outside their sets; valid if they are i.i.d. "
        "from deployment)."
    )


def _calibration_check(cert: Certificate) -> Check:
    cal = cert.calibration
    name = "calibration certificate"
    if cal is None:
        return Check(
            name=name,
            verdict="absent",
            level="fail",
            detail="the model is not calibrated: run ipcverify calibrate on held-out data",
        )
    weak = target_strength(cal.epsilon) == "weak"
    mode = (
        "PAC (holds for this calibration, except with probability delta)"
        if cal.mode == "pac"
        else ("marginal (on average over calibration draws, not for this one)")
    )
    return Check(
        name=name,
        verdict="present, weak target" if weak else "present",
        level="warn" if weak else "pass",
        detail=(
            f"{mode}; certified violation rate {cal.certified_epsilon:.4g} (target epsilon = "
            f"{cal.epsilon:g}), delta = {cal.delta:g}; {cal.grouping}; n = {cal.n:,}"
        ),
    )


def _counted(t: TestResult) -> str:
    rate = "" if t.statistic == "mean" else f" outside ({100 * t.empirical_rate:.3g} %)"
    return f"{t.counted()}{rate}; upper bound {t.bound_text()} at confidence {1 - t.delta:.6g}"


def _independence_check(cert: Certificate) -> Check:
    """A row-level claim on rows that come in runs or flights: its assumption is in doubt."""
    found, cal_col, test_col = [], None, None
    if cert.calibration_group_columns:
        cal_col, groups = next(iter(cert.calibration_group_columns.items()))
        n = f" in {cert.calibration.n:,} rows" if cert.calibration is not None else ""
        found.append(f"the calibration data had a {cal_col!r} column ({groups} groups{n})")
    if cert.test_group_columns:
        test_col, groups = next(iter(cert.test_group_columns.items()))
        rows = f" in {cert.test.n:,} test rows" if cert.test is not None else ""
        found.append(f"the test data has a {test_col!r} column ({groups} groups{rows})")
    col = cal_col or test_col
    if cert.group_test is not None:
        counted = f"the test is also counted per group of {cert.group_test.column!r} above"
    elif test_col is not None:
        counted = f"certify with {option('group_column', test_col)} to also count the test per {test_col}"
    else:
        counted = "test data with a column naming its runs could also be counted per run"
    runs = cert.runs or {}
    worth = ""
    if runs.get("unit") == "row" and runs.get("dependence"):
        worth = f"; measured at calibration: {runs['dependence']['statement']}"
    return Check(
        name="independent rows",
        verdict="assumed, in doubt",
        level="warn",
        detail=(
            f"{' and '.join(found)}: rows of one {col} are usually correlated, but the row-level claim, "
            "and the calibration behind it, count every row as an independent sample, which their "
            f"exact bounds need{worth}; {counted}, and recalibrate with {option('grouped', col)} for a claim "
            f"about whole {col}s"
        ),
    )


def _runs_check(cert: Certificate) -> Check | None:
    """What the calibration data's runs support: the floor, the smallest rate, the runs the target needs."""
    runs = cert.runs
    if not runs or not runs.get("plan"):
        return None
    plan, dep = runs["plan"], runs.get("dependence") or {}
    lines = {c["guarantee"]: c for c in plan["claims"]}
    share = lines["expected-share"]
    detail = (
        f"{runs['n_runs']} calibration runs of {runs['column']!r}: no claim about a new run goes below "
        f"{plan['floor']:.3g} at delta = {plan['delta']:g}; the smallest certifiable expected share is "
        f"{share['smallest']:g}, and epsilon = {plan['epsilon']:g} needs at least {share['runs_needed']} runs"
    )
    if dep.get("statement"):
        detail += f"; {dep['statement']}"
    return Check(
        name="what the runs support", verdict=f"claim about {runs['unit']}s", level="info", detail=detail
    )


def _test_check(cert: Certificate, rows_outside: tuple[int, int] | None) -> Check:
    t, c = cert.test, cert.consistency
    name = "held-out test"
    if t is None:
        return Check(name=name, verdict="not run", level="info", detail=f"{NOT_RUN} ({held_out_remedy()})")
    level: CheckLevel
    if not c.checked:
        verdict, level, versus = (
            "reported, not compared",
            "info",
            f"not compared with the calibration: {c.reason}",
        )
    elif c.consistent:
        verdict, level = "consistent with the calibration", "pass"
        versus = f"lower bound {c.test_lower_bound:.4g} <= allowed {c.allowed_rate:.4g}"
    else:
        verdict, level = "CONTRADICTS the calibration", "fail"
        versus = f"lower bound {c.test_lower_bound:.4g} > allowed {c.allowed_rate:.4g}"
    detail = f"{_counted(t)}; {versus}"
    if cert.test_rows is not None:
        detail += f"; {cert.test_rows.sentence()}"
    if rows_outside is not None and t.unit != "samples":
        k, n = rows_outside
        detail += (
            f"; all test rows: {k:,} of {n:,} outside ({100 * k / n:.3g} %; descriptive only, rows of a "
            "group are correlated)"
        )
    return Check(name=name, verdict=verdict, level=level, detail=detail)


def _group_checks(g: GroupTest, test: TestResult | None = None) -> list[Check]:
    """Two rows (one random row per group; any violation per group); the compared one has the verdict.

    A row whose counts are the held-out test's own (a claim about groups counts the test per
    group already) says so, so that a reader does not take it for a second, independent test.
    """
    rows = []
    c = g.consistency
    statistics: tuple[tuple[GroupUnit, str], ...] = (
        ("share", "share of each group's rows outside"),
        ("share-of-runs", "groups above the claim's share"),
        ("sample", "one random row per group"),
        ("trajectory", "any violation in a group"),
    )
    for unit, what in statistics:
        res = g.result(unit)
        if res is None or (unit == "sample" and g.compared_unit != "sample"):
            continue  # the mean share counts every row; one random row per group only for a claim on it
        if res.statistic == "mean":
            counted = f"mean share {100 * res.empirical_rate:.3g} % outside over {res.n:,} groups"
        else:
            counted = f"{int(res.violations):,} of {res.n:,} groups ({100 * res.empirical_rate:.3g} %)" + (
                " have a truth outside its set somewhere" if unit == "trajectory" else " outside"
            )
        counted += f"; upper bound {res.bound_text()} at confidence {1 - res.delta:.6g}"
        level: CheckLevel
        if g.compared_unit == unit and c.checked:
            verdict, level = (
                ("consistent with the calibration", "pass")
                if c.consistent
                else ("CONTRADICTS the calibration", "fail")
            )
            counted += f"; lower bound {c.test_lower_bound:.4g} vs. allowed rate {c.allowed_rate:.4g}"
        else:
            if g.compared_unit is None or not c.checked:
                why = c.reason or "the calibration claims no rate to compare with"
            elif unit == "trajectory" and g.compared_unit in ("share", "share-of-runs"):
                why = "the claim bounds a group's share of rows outside, not whether any row is"
            elif unit == "trajectory":
                why = "the claim bounds single rows, not whole groups"
            else:
                why = "the claim is about whole groups (the row below)"
            verdict, level = "reported only", "info"
            counted += f"; not compared: {why}"
        if (
            test is not None
            and test.unit != "samples"  # the held-out test counted the claim's groups ...
            and g.compared_unit == unit  # ... by this row's statistic
            and (test.violations, test.n, test.statistic) == (res.violations, res.n, res.statistic)
        ):
            counted += "; the same count as the held-out test above, not a second test"
        name = f"per-flight test ({g.column!r}): {what}"
        rows.append(Check(name=name, verdict=verdict, level=level, detail=counted))
    return rows


def _domain_check(d: DomainReport | None) -> Check:
    name = "domain of validity"
    verdict = (
        domain_verdict(present=False, radius_zero=False, queries=0, well_above=False, row_level=False)
        if d is None
        else d.verdict
    )
    if d is None:
        return Check(
            name=name,
            verdict=verdict,
            level="warn",
            detail="the model carries no domain-of-validity test; recalibrate with a current ipcverify",
        )
    fitted = f"fitted on {d.n_reference:,} calibration inputs, flag rate = {d.flag_rate:g}"
    if d.threshold == 0:  # only in a model file from before the test was fitted on distinct inputs
        return Check(
            name=name,
            verdict=verdict,
            level="warn",
            detail=f"{fitted}; its threshold is 0 because it was fitted on repeated calibration inputs by an "
            "older ipcverify, so the queries it flags say nothing about a shift -- recalibrate to refit it "
            "on the distinct inputs",
        )
    if d.n == 0:
        return Check(name=name, verdict=verdict, level="info", detail=f"{fitted}; {NOT_RUN}")
    counted = f"{d.outside:,} of {d.n:,} test queries ({100 * d.outside_fraction:.3g} %) outside; {fitted}"
    if d.well_above_flag_rate and d.row_level_column is not None:
        col = d.row_level_column
        return Check(
            name=name,
            verdict=verdict,
            level="warn",
            detail=counted + f"; the certificate promises nothing for them. The test was fitted row by "
            f"row on calibration data with a column {col!r}: refit it by {col} "
            f"({regroup_domain(col, d.regroup_flag_rate)}) "
            f"to tell a shift from a threshold too short for a new {col}",
        )
    if d.well_above_flag_rate:
        return Check(
            name=name,
            verdict=verdict,
            level="warn",
            detail=counted + "; the certificate promises nothing for them",
        )
    return Check(name=name, verdict=verdict, level="pass", detail=counted)


def _theorem1_check(cert: Certificate) -> Check:
    t1 = cert.theorem1
    name = "Theorem 1 (paper)"
    if t1 is None:
        return Check(
            name=name, verdict="not computed", level="info", detail=capitalized(cert.theorem1_reason)
        )
    s = t1.sound
    need = (
        "no training-set size brings it below 1"
        if s.n_needed is None
        else f"below 1 needs N >= {s.n_needed:.3g}"
    )
    terms = f"sound L_g = {s.lipschitz:.3g}, p = {t1.n_parameters:,}, N = {t1.n_train:,}"
    if s.vacuous:
        return Check(
            name=name,
            verdict=theorem1_verdict(vacuous=True),
            level="info",
            detail=f"bound {s.bound:.3g} >= 1 ({terms}; {need}); the certificate does not rest on it",
        )
    return Check(
        name=name,
        verdict=theorem1_verdict(vacuous=False),
        level="pass",
        detail=f"bound {s.bound:.4g} < 1 ({terms}), under the assumptions of proofs/theorem1.md",
    )


def output_labels(
    model: IPCModel, test_data: PerceptionDataset | None, labels: Sequence[str] | None = None
) -> tuple[str, ...]:
    """One label per coordinate of ``y``: the user's, else the data's or the model's column names.

    Parameters
    ----------
    model : IPCModel
        The model (its column names, if the data has none).
    test_data : PerceptionDataset or None
        The test data (its ``y`` column names).
    labels : sequence of str, optional
        The user's labels.

    Raises
    ------
    InvalidInputError
        If ``labels`` does not name every coordinate of ``y`` exactly once with a non-empty label.

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> m = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="cholesky")).model
    >>> output_labels(m, None), output_labels(m, None, [" forward", "left", "up"])
    (('y_0', 'y_1', 'y_2'), ('forward', 'left', 'up'))
    """
    n = model.config.y_dim
    if labels is None:
        names = tuple(test_data.y_columns) if test_data is not None else ()
        names = names or tuple(model.metadata.get("y_columns") or ())
        return names if len(names) == n else tuple(f"y_{i}" for i in range(n))
    return check_labels(labels, n)


def check_labels(labels: Sequence[str], n: int) -> tuple[str, ...]:
    """``labels`` stripped, if they name ``n`` coordinates of ``y`` with a non-empty label each.

    Examples
    --------
    >>> check_labels([" forward", "left", "up "], 3)
    ('forward', 'left', 'up')
    """
    given = tuple(str(label).strip() for label in labels)
    if len(given) != n or not all(given):
        example = (
            ",".join(("forward", "left", "up", "speed")[:n])
            if n <= 4
            else ",".join(f"y{i}" for i in range(n))
        )
        raise InvalidInputError(
            f"labels must name the {n} coordinates of y (the output columns), one non-empty label each; got "
            f"{len(given)}: {list(given)}; pass one each, e.g. {option('labels', tuple(example.split(',')))}"
        )
    return given


def _data_hashes(cert: Certificate) -> dict[str, str]:
    out: dict[str, str] = {}
    if cert.test_data is not None:
        if cert.test_data.file_sha256 is not None:
            out["test data file"] = cert.test_data.file_sha256
        out["test data content"] = cert.test_data.content_sha256
    if cert.calibration is not None:
        out["calibration data content"] = cert.calibration.data_sha256
    if cert.train_data is not None:
        if cert.train_data.file_sha256 is not None:
            out["training data file"] = cert.train_data.file_sha256
        out["training data content"] = cert.train_data.content_sha256
    return out


def summarize(
    cert: Certificate,
    *,
    created_utc: str | None = None,
    units: str | None = None,
    labels: Sequence[str] = (),
    rows_outside: tuple[int, int] | None = None,
) -> CertificateSummary:
    """The executive summary of ``cert`` (its verdicts are the certificate's; nothing is re-decided).

    Parameters
    ----------
    cert : Certificate
        What :func:`~ipcverify.certification.certify` established.
    created_utc : str, optional
        When it was made (UTC, ISO 8601); default: now.
    units : str, optional
        The units of ``y`` (e.g. ``"m"``); default: none named ("units of the data").
    labels : sequence of str, optional
        One label per coordinate of ``y``; default ``y_0, y_1, ...``.
    rows_outside : (int, int), optional
        Test rows outside their sets and test rows: shown, as a description, beside a test
        counted per group (whose bound does not count rows).

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify import IPCModel
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify import calibrate
    >>> from ipcverify import certify
    >>> m = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model
    >>> m = calibrate(m, example(2000, seed=1).data, epsilon=0.2, delta=0.01)
    >>> s = summarize(certify(m, example(2000, seed=2).data).certificate, units="m")
    >>> s.verdict_text()[:67]
    'CERTIFIED, WEAK TARGET (epsilon = 0.2: up to 20 % of the truths may'
    >>> [c.name for c in s.checks]
    ['calibration certificate', 'held-out test', 'domain of validity', 'Theorem 1 (paper)']
    """
    cal = cert.calibration
    claim_of = cert.group_claim
    checks = [_calibration_check(cert), _test_check(cert, rows_outside)]
    if cert.test_rows is not None and (rows_check := cert.test_rows.check()) is not None:
        checks.append(rows_check)  # repeated test rows, or an overlap a model file too old cannot check
    if cert.group_test is not None:
        checks += _group_checks(cert.group_test, cert.test)
    if claim_of is None and (cert.test_group_columns or cert.calibration_group_columns):
        checks.append(_independence_check(cert))
    if (runs_check := _runs_check(cert)) is not None:
        checks.append(runs_check)
    checks += [_domain_check(cert.domain), _theorem1_check(cert)]
    y_dim = int(cert.model.architecture.get("y_dim", len(labels) or 1))
    delta = cal.delta if cal is not None else (None if cert.test is None else cert.test.delta)
    return CertificateSummary(
        status=cert.status.name,
        status_detail=_status_detail(cert.status) + _shift_note(cert),
        claim=_claim(cert),
        epsilon=None if cal is None else cal.epsilon,
        certified_epsilon=None if cal is None else cal.certified_epsilon,
        delta=delta,
        unit="row" if claim_of is None else "group",
        unit_column=None if claim_of is None else claim_of.column,
        unit_statistic=None if claim_of is None else claim_of.unit,
        checks=tuple(checks),
        date_utc=utc_now() if created_utc is None else created_utc,
        ipcverify_version=VERSION,
        model_sha256=cert.model.file_sha256 or cert.model.network_sha256,
        model_sha256_of="model file" if cert.model.file_sha256 else "network",
        data_sha256=_data_hashes(cert),
        units=units,
        labels=tuple(labels) if labels else tuple(f"y_{i}" for i in range(y_dim)),
    )
