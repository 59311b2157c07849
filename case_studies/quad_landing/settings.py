"""The case study's two settings files and how they are read (with :mod:`tomllib`).

``defaults.toml`` holds the simulator, perception and data-collection settings
(:func:`case_studies.quad_landing.sim.config.load_config`); ``reproduce.toml`` those of
the paper reproduction (:func:`case_studies.quad_landing.reproduction.config.load_reproduce_config`).
Both sit beside this module. A file is read into a tree ``{section: {key: value}}``;
override files and mappings are merged on top section by section, key by key
(:func:`merge_sections`), and every section becomes a frozen dataclass that validates
itself. Unknown sections or keys are errors, so typos do not pass silently. Nothing is
ever ``eval``-ed. The helpers here know nothing of the sections themselves.

Examples
--------
>>> read_toml(DEFAULTS_PATH)["camera"]["width"]
320
>>> toml_default(REPRODUCE_PATH, "sizes", "mc_runs")
300
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Self

from ipcverify.errors import InvalidInputError

__all__ = [
    "DEFAULTS_PATH",
    "REPRODUCE_PATH",
    "PAPER_HEAD_PATH",
    "V1_HEAD_PATH",
    "ConfigError",
    "TomlSection",
    "Range",
    "read_toml",
    "sections_by_name",
    "merge_sections",
    "build_sections",
    "toml_default",
    "check_range",
    "check_positive",
]

#: The simulator's defaults, shipped beside the code.
DEFAULTS_PATH = Path(__file__).with_name("defaults.toml")
#: The reproduction's settings, shipped beside the code.
REPRODUCE_PATH = Path(__file__).with_name("reproduce.toml")
#: The paper's IPC (``[paper]``), stated in full: ``reproduce --settings`` this file (``docs/reproduce.md``).
PAPER_HEAD_PATH = Path(__file__).with_name("paper_head.toml")
#: ipcverify's earlier ``v1`` head in the default contract's place (``docs/reproduce.md``).
V1_HEAD_PATH = Path(__file__).with_name("v1_head.toml")

#: A ``[low, high]`` pair of a settings file.
Range = tuple[float, float]


class ConfigError(InvalidInputError):
    """A configuration file or override is malformed; the message names the key."""


class TomlSection:
    """Base of the dataclasses built from one table of a shipped settings file.

    A subclass (a frozen dataclass) names its file and table in its class statement,
    ``class SimParams(TomlSection, file=DEFAULTS_PATH, section="sim")`` (they become
    :attr:`toml_file` and :attr:`toml_section`), and carries **no default values**: the
    file holds them, so a value has one source. The loaders build whole configurations;
    :meth:`defaults` builds one section from the shipped table, with some keys replaced
    (for examples and tests).

    Examples
    --------
    >>> @dataclasses.dataclass(frozen=True, kw_only=True)
    ... class Quad(TomlSection, file=DEFAULTS_PATH, section="quad"):
    ...     mass: float
    >>> Quad.toml_section, Quad.toml_file.name
    ('quad', 'defaults.toml')
    >>> class Half(TomlSection, section="quad"):
    ...     pass
    Traceback (most recent call last):
    ...
    TypeError: Half: a TomlSection names both its file and its section, or neither
    """

    #: The shipped file the section is read from.
    toml_file: ClassVar[Path]
    #: The section's table name in that file.
    toml_section: ClassVar[str]

    def __init_subclass__(
        cls, *, file: Path | None = None, section: str | None = None, **kwargs: Any
    ) -> None:
        """Set :attr:`toml_file` and :attr:`toml_section` from the class keywords.

        A subclass without them (a base for other sections, or a table that is never loaded
        from a file, as in :func:`merge_sections`'s example) inherits what its base has.
        """
        super().__init_subclass__(**kwargs)
        if (file is None) != (section is None):
            raise TypeError(f"{cls.__name__}: a TomlSection names both its file and its section, or neither")
        if file is not None and section is not None:
            cls.toml_file, cls.toml_section = file, section

    @classmethod
    def toml_keys(cls) -> frozenset[str]:
        """The keys the section's table accepts (the dataclass's fields)."""
        return frozenset(f.name for f in dataclasses.fields(cls) if f.init)  # type: ignore[arg-type]

    @classmethod
    def from_table(cls, table: Mapping[str, Any]) -> Self:
        """Build from a table (lists become tuples); a missing key is a :class:`ConfigError`."""
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in table.items()}
        try:
            return cls(**values)
        except TypeError as exc:  # missing required keys
            raise ConfigError(f"[{cls.toml_section}]: {exc}") from None

    def to_table(self) -> dict[str, Any]:
        """Plain data in the layout of the TOML table (tuples become lists)."""
        return {
            f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
            if f.init
        }

    @classmethod
    def defaults(cls, **overrides: Any) -> Self:
        """The section as shipped in :attr:`toml_file`, with the keys in ``overrides`` replaced."""
        name = cls.toml_section
        shipped = {name: read_toml(cls.toml_file)[name]}
        return cls.from_table(merge_sections(shipped, {name: overrides}, "override", {name: cls})[name])


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; a missing or malformed file is a :class:`ConfigError`."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"config file {path} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"config file {path} is not valid TOML: {exc}") from None


def toml_default(path: str | Path, section: str, key: str) -> Any:
    """The value of ``[section] key`` in a shipped settings file (e.g. for ``--help`` texts)."""
    return read_toml(path)[section][key]


def sections_by_name(*classes: type[TomlSection]) -> dict[str, type[TomlSection]]:
    """``{toml_section: class}`` of the sections of one file, in the order given.

    A class that names no section, or two that name the same one, is an error (the table
    would be read by no class, or by one of them unseen).

    Examples
    --------
    >>> @dataclasses.dataclass(frozen=True, kw_only=True)
    ... class Quad(TomlSection, file=DEFAULTS_PATH, section="quad"):
    ...     mass: float
    >>> sections_by_name(Quad)
    {'quad': <class 'case_studies.quad_landing.settings.Quad'>}
    >>> sections_by_name(Quad, Quad)
    Traceback (most recent call last):
    ...
    ValueError: Quad and Quad both read [quad]
    """
    out: dict[str, type[TomlSection]] = {}
    for cls in classes:
        name = getattr(cls, "toml_section", None)
        if name is None:
            raise ValueError(f"{cls.__name__} names no section (class keywords file=..., section=...)")
        if name in out:
            raise ValueError(f"{out[name].__name__} and {cls.__name__} both read [{name}]")
        out[name] = cls
    return out


def merge_sections(
    base: Mapping[str, Mapping[str, Any]],
    over: Mapping[str, Any],
    source: str,
    sections: Mapping[str, type[TomlSection]],
) -> dict[str, dict[str, Any]]:
    """``base`` with the ``{section: {key: value}}`` tables of ``over`` merged on top.

    Every section must be one of ``sections`` (name -> :class:`TomlSection`) and every key
    one of its :meth:`~TomlSection.toml_keys`; errors name ``source``, the section and the key.

    Examples
    --------
    >>> @dataclasses.dataclass(frozen=True, kw_only=True)
    ... class Box(TomlSection):
    ...     side: float
    >>> merge_sections({"box": {"side": 1.0}}, {"box": {"side": 2.0}}, "override", {"box": Box})
    {'box': {'side': 2.0}}
    >>> merge_sections({}, {"box": {"edge": 2.0}}, "my.toml", {"box": Box})
    Traceback (most recent call last):
    ...
    case_studies.quad_landing.settings.ConfigError: my.toml: unknown key box.edge; valid keys: side
    """
    out = {name: dict(section) for name, section in base.items()}
    for name, section in over.items():
        if name not in sections:
            raise ConfigError(f"{source}: unknown section [{name}]; valid sections: {', '.join(sections)}")
        if not isinstance(section, Mapping):
            raise ConfigError(f"{source}: [{name}] must be a table of keys, got {section!r}")
        valid = sections[name].toml_keys()
        for key, value in section.items():
            if key not in valid:
                raise ConfigError(
                    f"{source}: unknown key {name}.{key}; valid keys: {', '.join(sorted(valid))}"
                )
            out.setdefault(name, {})[key] = value
    return out


def build_sections(
    tree: Mapping[str, Mapping[str, Any]], sections: Mapping[str, type[TomlSection]]
) -> dict[str, Any]:
    """Each section's dataclass built from its table of ``tree`` (:meth:`TomlSection.from_table`)."""
    return {name: cls.from_table(tree.get(name, {})) for name, cls in sections.items()}


def check_range(where: str, value: Any, lo: float = -math.inf) -> Range:
    """``value`` as a ``(low, high)`` pair of finite numbers with ``lo <= low <= high``.

    Examples
    --------
    >>> check_range("scenario.start_height", [1.5, 2.1], 0.0)
    (1.5, 2.1)
    """
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where} must be two numbers [low, high], got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b):
        raise ConfigError(f"{where} must be finite with {lo:g} <= low <= high, got {value!r}")
    return (a, b)


def check_positive(where: str, value: Any, *, integer: bool = False, allow_zero: bool = False) -> None:
    """Raise a :class:`ConfigError` naming ``where`` unless ``value`` is a finite number > 0
    (``>= 0`` with ``allow_zero``; a whole number with ``integer``).

    Examples
    --------
    >>> check_positive("landing.climb", 0.3)
    >>> check_positive("sizes.mc_runs", 0, integer=True)
    Traceback (most recent call last):
    ...
    case_studies.quad_landing.settings.ConfigError: sizes.mc_runs must be an integer > 0, got 0
    """
    bad = isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value)
    if not bad:
        bad = value < 0 or (value == 0 and not allow_zero) or (integer and int(value) != value)
    if bad:
        kind = "an integer" if integer else "a number"
        raise ConfigError(f"{where} must be {kind} {'>= 0' if allow_zero else '> 0'}, got {value!r}")
