"""Online monitoring of a deployed contract: an anytime-valid test that its violation rate is at most epsilon.

As ground truth arrives, every query gives one observation: whether the truth fell
outside its calibrated set (``violated``) and whether the query was in the contract's
domain of validity (``in_domain``, computed elsewhere). :class:`ViolationMonitor` keeps a
betting e-process (a test supermartingale) for

    H0: conditionally on the past, each new (in-domain) observation violates with
        probability at most epsilon,

and raises an alarm the first time it reaches ``1 / delta``. By Ville's inequality the
probability that a monitor *ever* raises a false alarm under H0 is at most ``delta``, however
long it runs and however often it is looked at; the observations need not be i.i.d.
Optionally a second e-process tests "the out-of-domain rate is at most ``domain_rate``".
Proof and the choice of bets: ``proofs/monitor.md``.

The bets live in :mod:`ipcverify.guard._eprocess` (:class:`BettingEProcess`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.errors import InvalidInputError
from ipcverify.guard._eprocess import BettingEProcess, check_rate

if TYPE_CHECKING:  # matplotlib is imported by plot_monitor only: predict needs none of it
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: The alarm needs log K >= log(1 / delta) + ALARM_MARGIN (guards against rounding in long sums).
ALARM_MARGIN = 1e-6


@dataclass(frozen=True, kw_only=True)
class MonitorConfig:
    """What a :class:`ViolationMonitor` tests.

    Attributes
    ----------
    epsilon : float
        H0: the (in-domain) violation rate is at most ``epsilon`` given the past.
    delta : float
        False-alarm bound of the violation test (over the whole stream).
    domain_rate : float, optional
        If given, a second test of H0': the out-of-domain rate is at most ``domain_rate``.
    domain_delta : float, optional
        Its false-alarm bound (default ``delta``).
    in_domain_only : bool
        Feed only in-domain observations to the violation test (the contract claims nothing
        outside its domain); False feeds all.

    Examples
    --------
    >>> round(MonitorConfig(epsilon=0.01, delta=0.001).alarm_level, 4)
    6.9078
    """

    epsilon: float
    delta: float
    domain_rate: float | None = None
    domain_delta: float | None = None
    in_domain_only: bool = True

    def __post_init__(self) -> None:
        check_rate("epsilon", self.epsilon)
        check_rate("delta", self.delta)
        if self.domain_rate is None:
            if self.domain_delta is not None:
                raise InvalidInputError("domain_delta needs domain_rate (the out-of-domain rate to test)")
        else:
            check_rate("domain_rate", self.domain_rate)
            object.__setattr__(
                self, "domain_delta", check_rate("domain_delta", self.domain_delta or self.delta)
            )

    @property
    def alarm_level(self) -> float:
        """``log(1 / delta)``: the alarm fires when ``log K_t`` reaches it (plus ``ALARM_MARGIN``)."""
        return -math.log(self.delta)

    @property
    def domain_alarm_level(self) -> float | None:
        """``log(1 / domain_delta)``, if there is a domain test."""
        return None if self.domain_delta is None else -math.log(self.domain_delta)

    def to_dict(self) -> dict[str, Any]:
        """Plain data."""
        return {
            "epsilon": self.epsilon,
            "delta": self.delta,
            "domain_rate": self.domain_rate,
            "domain_delta": self.domain_delta,
            "in_domain_only": self.in_domain_only,
        }


@dataclass(frozen=True, kw_only=True)
class MonitorState:
    """The monitor after its latest observation.

    Attributes
    ----------
    index : int
        0-based position of the latest observation in the stream (-1 before any).
    log_e_value : float
        ``log K_t`` of the violation test (0 at the start).
    alarm, alarm_index : bool, int or None
        Whether ``K`` has reached ``1 / delta``, and the position of the observation at which it
        first did (the alarm stays raised).
    violations : float
        Sum of the observations fed to the violation test (their count for 0/1 observations).
    n_tested, n_in_domain : int
        Observations fed to the violation test; observations in the domain of validity.
    in_domain_fraction : float or None
        ``n_in_domain / (index + 1)`` (None before any observation).
    domain_log_e_value : float or None
        ``log K_t`` of the out-of-domain test (None without one).
    domain_alarm, domain_alarm_index : bool, int or None
        Its alarm.
    """

    index: int
    log_e_value: float
    alarm: bool
    alarm_index: int | None
    violations: float
    n_tested: int
    n_in_domain: int
    in_domain_fraction: float | None
    domain_log_e_value: float | None = None
    domain_alarm: bool = False
    domain_alarm_index: int | None = None

    def __post_init__(self) -> None:
        if self.alarm != (self.alarm_index is not None) or self.domain_alarm != (
            self.domain_alarm_index is not None
        ):
            raise InvalidInputError("an alarm needs its index and an index needs its alarm")
        if not (0 <= self.n_tested <= self.index + 1 and 0 <= self.n_in_domain <= self.index + 1):
            raise InvalidInputError(f"counts exceed the {self.index + 1} observations: {self}")

    @property
    def e_value(self) -> float:
        """``K_t`` (``inf`` if it overflows a float)."""
        return math.exp(self.log_e_value) if self.log_e_value < 709.0 else math.inf

    @property
    def violation_rate(self) -> float | None:
        """Running violation rate of the tested observations (None before any)."""
        return None if self.n_tested == 0 else self.violations / self.n_tested

    def to_dict(self) -> dict[str, Any]:
        """Plain data (the e-values as logs)."""
        return {
            "index": self.index,
            "log_e_value": self.log_e_value,
            "alarm": self.alarm,
            "alarm_index": self.alarm_index,
            "violations": self.violations,
            "n_tested": self.n_tested,
            "violation_rate": self.violation_rate,
            "n_in_domain": self.n_in_domain,
            "in_domain_fraction": self.in_domain_fraction,
            "domain_log_e_value": self.domain_log_e_value,
            "domain_alarm": self.domain_alarm,
            "domain_alarm_index": self.domain_alarm_index,
        }


@dataclass(frozen=True, kw_only=True, eq=False)
class MonitorResult:
    """The trajectory of one batch fed to :meth:`ViolationMonitor.run` (arrays are read-only).

    Attributes
    ----------
    config : MonitorConfig
    start_index : int
        Stream position of the batch's first observation.
    violated, in_domain : ndarray (m,)
        The batch.
    log_e_value : ndarray (m,)
        ``log K_t`` of the violation test after each observation (unchanged at skipped ones).
    domain_log_e_value : ndarray (m,) or None
        ``log K_t`` of the out-of-domain test.
    in_domain_fraction : ndarray (m,)
        Running fraction of in-domain observations since the stream began.
    final : MonitorState
        The state after the batch (alarm positions are stream positions).
    """

    config: MonitorConfig
    start_index: int
    violated: FloatArray
    in_domain: BoolArray
    log_e_value: FloatArray
    domain_log_e_value: FloatArray | None
    in_domain_fraction: FloatArray
    final: MonitorState

    @property
    def index(self) -> NDArray[np.intp]:
        """Stream positions of the batch's observations."""
        return self.start_index + np.arange(len(self.violated), dtype=np.intp)

    @property
    def alarm_index(self) -> int | None:
        """Stream position of the violation alarm (possibly before this batch), or None."""
        return self.final.alarm_index

    def to_dict(self) -> dict[str, Any]:
        """Configuration, batch position and length, and the final state (not the arrays)."""
        return {
            "config": self.config.to_dict(),
            "start_index": self.start_index,
            "n": len(self.violated),
            "final": self.final.to_dict(),
        }


def _observations(violated: ArrayLike, in_domain: ArrayLike | None) -> tuple[FloatArray, BoolArray]:
    v = np.asarray(violated)
    if v.ndim > 1:
        raise InvalidInputError(f"violated must be one value per observation (1-D); got shape {v.shape}")
    v = np.atleast_1d(v)
    if v.dtype != np.bool_ and not np.issubdtype(v.dtype, np.number):
        raise InvalidInputError(f"violated must be booleans or numbers in [0, 1]; got dtype {v.dtype}")
    x = v.astype(np.float64)
    if not (np.isfinite(x).all() and (x >= 0).all() and (x <= 1).all()):
        bad = int(np.flatnonzero(~(np.isfinite(x) & (x >= 0) & (x <= 1)))[0])
        raise InvalidInputError(
            f"observation {bad} (0-based): violated={v[bad].item()!r} is not in [0, 1]; pass True/False "
            "(truth outside its set) or, for one observation per group, the fraction of its samples outside"
        )
    if in_domain is None:
        return x, np.ones(len(x), dtype=bool)
    d = np.array(in_domain, ndmin=1)  # a copy: the result's arrays are made read-only
    if d.shape != x.shape:
        raise InvalidInputError(
            f"in_domain has shape {d.shape} but violated has {x.shape}; give one flag each"
        )
    if d.dtype != np.bool_:
        if not np.issubdtype(d.dtype, np.number) or not np.isin(d, (0, 1)).all():
            raise InvalidInputError(
                "in_domain must be booleans (or 0/1): was the query in the domain of validity?"
            )
        d = d.astype(bool)
    return x, d


def _first_at_least(path: FloatArray, level: float) -> int | None:
    hit = np.flatnonzero(path >= level + ALARM_MARGIN)
    return int(hit[0]) if hit.size else None


class ViolationMonitor:
    """Anytime-valid monitor of a deployed contract's violation rate (see the module docstring).

    Parameters
    ----------
    epsilon, delta : float
        H0 "violation rate at most ``epsilon`` given the past" and the false-alarm bound.
        For a calibrated contract use the rate it allows,
        ``calibration.allowed_violation_rate().rate``; for a grouped calibration feed one
        observation per flight (:func:`~ipcverify.calibration.group_violation_counts` explains
        the unit), since samples of one flight are not conditionally independent.
    domain_rate, domain_delta : float, optional
        A second test: the out-of-domain rate is at most ``domain_rate`` (false-alarm bound
        ``domain_delta``, default ``delta``).
    in_domain_only : bool
        Feed only in-domain observations to the violation test (default).

    Examples
    --------
    >>> mon = ViolationMonitor(epsilon=0.05, delta=0.01)
    >>> mon.update(False).alarm
    False
    >>> res = mon.run([True] * 30)           # the contract fails badly
    >>> res.final.alarm, res.final.alarm_index
    (True, 4)
    """

    def __init__(
        self,
        epsilon: float,
        delta: float,
        *,
        domain_rate: float | None = None,
        domain_delta: float | None = None,
        in_domain_only: bool = True,
    ) -> None:
        self.config = MonitorConfig(
            epsilon=epsilon,
            delta=delta,
            domain_rate=domain_rate,
            domain_delta=domain_delta,
            in_domain_only=in_domain_only,
        )
        self._violation = BettingEProcess(self.config.epsilon)
        self._domain = None if domain_rate is None else BettingEProcess(domain_rate)
        self._state = MonitorState(
            index=-1,
            log_e_value=0.0,
            alarm=False,
            alarm_index=None,
            violations=0.0,
            n_tested=0,
            n_in_domain=0,
            in_domain_fraction=None,
            domain_log_e_value=None if self._domain is None else 0.0,
        )

    @property
    def state(self) -> MonitorState:
        """The state after the latest observation."""
        return self._state

    def update(self, violated: bool | float, in_domain: bool = True) -> MonitorState:
        """Consume one observation; returns the new state."""
        return self.run([violated], [in_domain]).final

    def run(
        self, violated: ArrayLike, in_domain: ArrayLike | None = None, outside: ArrayLike | None = None
    ) -> MonitorResult:
        """Consume a batch of observations (vectorised); returns its trajectory.

        The monitor continues from its current state, so a stream may be fed in batches of any
        size (also one at a time through :meth:`update`) with the same result.

        Parameters
        ----------
        violated : array_like
            Per observation: 1 (or True) if the truth fell outside its set, or for one observation
            per run the run's share of rows outside, in ``[0, 1]``.
        in_domain : array_like of bool, optional
            Per observation: inside the domain of validity (default: every one).
        outside : array_like, optional
            What the out-of-domain test observes, in ``[0, 1]`` (for one observation per run: its
            share of queries outside the domain); default ``1 - in_domain``.

        Raises
        ------
        InvalidInputError
            If an observation is not a bool or a number in ``[0, 1]``, or the shapes differ.
        """
        x, d = _observations(violated, in_domain)
        away = 1.0 - d if outside is None else _observations(outside, None)[0]
        if away.shape != x.shape:
            raise InvalidInputError(
                f"outside has shape {away.shape} but violated has {x.shape}; give one each"
            )
        s, cfg, m = self._state, self.config, len(x)
        tested = d if cfg.in_domain_only else np.ones(m, dtype=bool)
        steps = self._violation.advance(x[tested])
        pos = np.cumsum(tested) - 1
        log_e = np.where(pos >= 0, steps[np.maximum(pos, 0)] if steps.size else 0.0, s.log_e_value)
        alarm_index = s.alarm_index
        if alarm_index is None and (hit := _first_at_least(log_e, cfg.alarm_level)) is not None:
            alarm_index = s.index + 1 + hit
        dom_path, dom_alarm = None, s.domain_alarm_index
        if self._domain is not None:
            dom_path = self._domain.advance(away)
            level = cfg.domain_alarm_level
            if (
                dom_alarm is None
                and level is not None
                and (hit := _first_at_least(dom_path, level)) is not None
            ):
                dom_alarm = s.index + 1 + hit
        n_in = s.n_in_domain + np.cumsum(d)
        fraction = n_in / (s.index + 2 + np.arange(m))
        self._state = MonitorState(
            index=s.index + m,
            log_e_value=float(log_e[-1]) if m else s.log_e_value,
            alarm=alarm_index is not None,
            alarm_index=alarm_index,
            violations=s.violations + float(x[tested].sum()),
            n_tested=s.n_tested + int(tested.sum()),
            n_in_domain=int(n_in[-1]) if m else s.n_in_domain,
            in_domain_fraction=float(fraction[-1]) if m else s.in_domain_fraction,
            domain_log_e_value=None
            if dom_path is None
            else (float(dom_path[-1]) if m else s.domain_log_e_value),
            domain_alarm=dom_alarm is not None,
            domain_alarm_index=dom_alarm,
        )
        for a in (x, d, log_e, fraction, *(() if dom_path is None else (dom_path,))):
            a.setflags(write=False)
        return MonitorResult(
            config=cfg,
            start_index=s.index + 1,
            violated=x,
            in_domain=d,
            log_e_value=log_e,
            domain_log_e_value=dom_path,
            in_domain_fraction=fraction,
            final=self._state,
        )


def plot_monitor(
    result: MonitorResult, *, change_index: int | None = None, title: str | None = None
) -> Figure:
    """``log K_t`` over the stream with the alarm level ``log(1/delta)`` and the alarm marked.

    Parameters
    ----------
    result : MonitorResult
        A trajectory from :meth:`ViolationMonitor.run`.
    change_index : int, optional
        Mark a known change point (e.g. a planted shift in a simulation).
    title : str, optional
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        A private figure (no pyplot state); render it with
        :func:`ipcverify.certification._report.figure_to_png`.

    Examples
    --------
    >>> res = ViolationMonitor(0.05, 0.01).run(np.arange(200) % 4 == 0)
    >>> fig = plot_monitor(res, change_index=0)
    >>> [ax.get_ylabel() for ax in fig.axes]
    ['log e-value', 'running rate']
    """
    cfg, t = result.config, result.index
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.2))
    ax, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (2, 1)})
    ax.step(
        t,
        result.log_e_value,
        where="post",
        color="#4c72b0",
        label=f'e-value against "violation rate <= {cfg.epsilon:.3g}"',
    )
    ax.axhline(
        cfg.alarm_level, color="#b42318", lw=1.5, label=f"alarm level log(1/delta), delta={cfg.delta:g}"
    )
    if result.domain_log_e_value is not None:
        ax.step(t, result.domain_log_e_value, where="post", color="#9a6700", label="out of domain?")
    for idx, color, name in ((result.alarm_index, "#b42318", "alarm"), (change_index, "#555555", "change")):
        if idx is not None and t.size and t[0] <= idx <= t[-1]:
            ax.axvline(idx, color=color, ls="--" if name == "change" else "-", lw=1, label=f"{name} at {idx}")
    ax.set_ylabel("log e-value")
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title(title or "Anytime-valid violation monitor", fontsize=10)
    tested = result.in_domain if cfg.in_domain_only else np.ones(len(t), dtype=bool)
    rate = np.cumsum(result.violated * tested) / np.maximum(np.cumsum(tested), 1)
    ax2.plot(t, rate, color="#4c72b0", lw=1, label="violation rate (this batch)")
    ax2.plot(t, result.in_domain_fraction, color="#9a6700", lw=1, label="in-domain fraction")
    ax2.axhline(cfg.epsilon, color="#4c72b0", ls=":", lw=1)
    ax2.set_ylabel("running rate")
    ax2.set_xlabel("observation")
    ax2.legend(loc="center right", fontsize=7)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.11, top=0.93, hspace=0.08)
    return fig
