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
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ipcverify.errors import InvalidInputError

__all__ = [
    "DEFAULTS_PATH",
    "REPRODUCE_PATH",
    "ConfigError",
    "Range",
    "read_toml",
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

#: A ``[low, high]`` pair of a settings file.
Range = tuple[float, float]


class ConfigError(InvalidInputError):
    """A configuration file or override is malformed; the message names the key."""


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


def _keys(cls: type) -> frozenset[str]:
    """The keys a section's dataclass accepts (its ``toml_keys()``, else its init fields)."""
    own = getattr(cls, "toml_keys", None)
    if callable(own):
        return frozenset(own())
    return frozenset(f.name for f in dataclasses.fields(cls) if f.init)


def merge_sections(
    base: Mapping[str, Mapping[str, Any]],
    over: Mapping[str, Any],
    source: str,
    sections: Mapping[str, type],
) -> dict[str, dict[str, Any]]:
    """``base`` with the ``{section: {key: value}}`` tables of ``over`` merged on top.

    Every section must be one of ``sections`` (name -> dataclass) and every key one the
    dataclass accepts; errors name ``source``, the section and the key.

    Examples
    --------
    >>> @dataclasses.dataclass
    ... class Box:
    ...     side: float
    >>> merge_sections({"box": {"side": 1.0}}, {"box": {"side": 2.0}}, "override", {"box": Box})
    {'box': {'side': 2.0}}
    """
    out = {name: dict(section) for name, section in base.items()}
    for name, section in over.items():
        if name not in sections:
            raise ConfigError(f"{source}: unknown section [{name}]; valid sections: {', '.join(sections)}")
        if not isinstance(section, Mapping):
            raise ConfigError(f"{source}: [{name}] must be a table of keys, got {section!r}")
        valid = _keys(sections[name])
        for key, value in section.items():
            if key not in valid:
                raise ConfigError(
                    f"{source}: unknown key {name}.{key}; valid keys: {', '.join(sorted(valid))}"
                )
            out.setdefault(name, {})[key] = value
    return out


def build_sections(tree: Mapping[str, Mapping[str, Any]], sections: Mapping[str, type]) -> dict[str, Any]:
    """Each section's dataclass built from its table of ``tree`` (lists become tuples).

    A dataclass with a ``from_toml(table)`` classmethod builds itself; a missing key is a
    :class:`ConfigError` naming the section.
    """
    parts: dict[str, Any] = {}
    for name, cls in sections.items():
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in tree.get(name, {}).items()}
        build = getattr(cls, "from_toml", cls)
        try:
            parts[name] = build(values) if build is not cls else cls(**values)
        except TypeError as exc:  # missing required keys
            raise ConfigError(f"[{name}]: {exc}") from None
    return parts


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
    bad = isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value)
    if not bad:
        bad = value < 0 or (value == 0 and not allow_zero) or (integer and int(value) != value)
    if bad:
        kind = "an integer" if integer else "a number"
        raise ConfigError(f"{where} must be {kind} {'>= 0' if allow_zero else '> 0'}, got {value!r}")
