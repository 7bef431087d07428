"""The AK motor catalogue: what each model's wire ranges and mechanics are.

The catalogue is data (``akarm/data/motors.yaml``), not code paths per model. Look a model up
with :func:`get` (case-insensitive)::

    >>> from akarm import motors
    >>> m = motors.get("ak80-9")
    >>> m.t_max, m.gear_ratio
    (18.0, 9.0)

New firmware changes ranges, and units differ between batches, so every entry can be overridden
or new ones added without touching code: in a robot YAML's ``motors:`` section (for that robot
only), with :func:`load` (for the process), or with a file named by the ``AKARM_MOTORS``
environment variable (read on first use). An entry may name a ``base`` model and change only some
fields; naming an existing model without ``base`` changes only the fields given.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Literal

from akarm.errors import ConfigError, ConfigProblem, UnknownMotorError, did_you_mean
from akarm.files import FileProblem, YamlLimits, load_yaml

__all__ = ["MAX_MOTOR_FILE_BYTES", "MAX_MOTOR_FILE_NODES", "MOTOR_FILE_LIMITS", "Catalogue", "MotorModel",
           "default_catalogue", "get", "load", "names"]

_DATA_FILE = Path(__file__).parent.parent / "data" / "motors.yaml"

#: Bytes of a motor file (``AKARM_MOTORS``, :func:`load`; the bundled one has 6 500).
MAX_MOTOR_FILE_BYTES = 1 << 20
#: Values in a motor file, aliases counted at their full size (the bundled one has 400).
MAX_MOTOR_FILE_NODES = 100_000
#: How a motor file is read.
MOTOR_FILE_LIMITS = YamlLimits("motor file", MAX_MOTOR_FILE_BYTES, "MAX_MOTOR_FILE_BYTES", MAX_MOTOR_FILE_NODES,
                               "MAX_MOTOR_FILE_NODES")


@dataclass(frozen=True, slots=True)
class MotorModel:
    """One AK actuator model. SI units throughout; see ``akarm/data/motors.yaml`` for each field.

    The MIT ranges are symmetric: position in [-p_max, p_max] rad, velocity in [-v_max, v_max]
    rad/s, torque in [-t_max, t_max] N·m, kp in [0, kp_max], kd in [0, kd_max].
    """

    name: str
    p_max: float
    v_max: float
    t_max: float
    gear_ratio: float
    pole_pairs: int
    kp_max: float = 500.0
    kd_max: float = 5.0
    kt: float | None = None
    rated_torque: float | None = None
    peak_torque: float | None = None
    rated_current: float | None = None
    peak_current: float | None = None
    rotor_inertia: float | None = None
    mass: float | None = None
    friction_coulomb: float | None = None
    friction_viscous: float | None = None
    servo_position: Literal["output", "rotor"] = "output"
    mit_temp_offset: float = 0.0
    firmware: Literal["v2", "v3"] = "v2"
    source: str = ""

    @property
    def output_kt(self) -> float | None:
        """Torque per amp of Iq at the output shaft, N·m/A (``kt · gear_ratio``), if kt is known."""
        return None if self.kt is None else self.kt * self.gear_ratio

    @property
    def reflected_inertia(self) -> float:
        """Rotor inertia seen at the output, kg·m² (``rotor_inertia · gear_ratio²``; 0 if unknown)."""
        return 0.0 if self.rotor_inertia is None else self.rotor_inertia * self.gear_ratio**2


_REQUIRED = ("p_max", "v_max", "t_max", "gear_ratio", "pole_pairs")
_FIELD_NAMES = tuple(f.name for f in fields(MotorModel) if f.name != "name")
_ENTRY_KEYS = (*_FIELD_NAMES, "base")
_POSITIVE = ("p_max", "v_max", "t_max", "gear_ratio", "pole_pairs", "kp_max", "kd_max", "kt",
             "rated_torque", "peak_torque", "rated_current", "peak_current", "rotor_inertia", "mass",
             "friction_coulomb", "friction_viscous")
_CHOICES = {"servo_position": ("output", "rotor"), "firmware": ("v2", "v3")}

def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


#: One problem with one catalogue entry: (field or None, message, fix).
EntryProblem = tuple[str | None, str, str]


def _key(name: str) -> str:
    return name.strip().upper()


class Catalogue(Mapping[str, MotorModel]):
    """An immutable set of motor models, looked up case-insensitively by name."""

    def __init__(self, models: Mapping[str, MotorModel] | None = None) -> None:
        self._models: dict[str, MotorModel] = {_key(m.name): m for m in (models or {}).values()}

    def __getitem__(self, name: str) -> MotorModel:
        return self.get(name)

    def __iter__(self) -> Iterator[str]:
        return (m.name for m in self._models.values())

    def __len__(self) -> int:
        return len(self._models)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and _key(name) in self._models

    def get(self, name: str | MotorModel) -> MotorModel:  # type: ignore[override]
        """The model called ``name`` (any case); a :class:`MotorModel` is returned as it is.

        Raises:
            UnknownMotorError: no such model; the error lists the known ones.
        """
        if isinstance(name, MotorModel):
            return name
        try:
            return self._models[_key(name)]
        except (KeyError, AttributeError):
            raise UnknownMotorError(str(name), self.names()) from None

    def names(self) -> list[str]:
        """The model names, sorted."""
        return sorted(m.name for m in self._models.values())

    # C901 15 > 12, left as it was: one check per kind of catalogue field, every problem at once
    def check_entry(self, name: str, entry: Any) -> list[EntryProblem]:  # noqa: C901
        """Every problem with one override/new-model entry, without building it."""
        if not isinstance(entry, Mapping):
            return [(None, f"motor {name!r} must be a mapping of fields", "write `field: value` lines under it")]
        problems: list[EntryProblem] = []
        for k in entry:
            if k not in _ENTRY_KEYS:
                problems.append((str(k), f"unknown motor field {k!r}{did_you_mean(str(k), _ENTRY_KEYS)}",
                                 "known fields: " + ", ".join(_ENTRY_KEYS)))
        base_name = entry.get("base")
        base: MotorModel | None = None
        if base_name is not None:
            try:
                base = self.get(str(base_name))
            except UnknownMotorError as e:
                problems.append(("base", e.what, e.fix))
        elif name in self:
            base = self.get(name)
        for k in _REQUIRED:
            if base is None and base_name is None and k not in entry:
                problems.append((None, f"new motor {name!r} lacks {k!r}",
                                 f"give {k}, or `base: MODEL` to start from a known model"))
        for k in _POSITIVE:
            if k in entry:
                v = entry[k]
                # (finite: an infinite range scales every command to NaN or 0, an infinite torque limit
                # reads every reply's torque as NaN)
                if not _is_number(v) or not 0 < v < math.inf:
                    problems.append((k, f"motor {name!r}: {k} must be a positive finite number, got {v!r}",
                                     f"set {k} to a number above 0"))
                elif k == "pole_pairs" and v != int(v):
                    problems.append((k, f"motor {name!r}: pole_pairs must be a whole number, got {v!r}",
                                     "count the rotor's magnet pairs (the datasheet's pole pairs)"))
        if "mit_temp_offset" in entry and not (_is_number(entry["mit_temp_offset"])
                                               and math.isfinite(entry["mit_temp_offset"])):
            # (a NaN offset reads every temperature as NaN, which no limit is above: no over-temperature stop)
            problems.append(("mit_temp_offset", f"motor {name!r}: mit_temp_offset must be a finite number, got "
                             f"{entry['mit_temp_offset']!r}",
                             "0 for raw temperature bytes, 40 for firmware that adds 40"))
        if "source" in entry and not isinstance(entry["source"], str):
            problems.append(("source", f"motor {name!r}: source must be text, got {entry['source']!r}",
                             "name where the values come from, e.g. a datasheet"))
        for k, allowed in _CHOICES.items():
            if k in entry and entry[k] not in allowed:
                problems.append((k, f"motor {name!r}: {k} must be one of {', '.join(allowed)}, got {entry[k]!r}",
                                 f"use {' or '.join(allowed)}"))
        return problems

    def build_entry(self, name: str, entry: Mapping[str, Any]) -> MotorModel:
        """The model an entry describes (after :meth:`check_entry` found nothing)."""
        base_name = entry.get("base")
        base = self.get(str(base_name)) if base_name is not None else (self.get(name) if name in self else None)
        values = {k: v for k, v in entry.items() if k != "base"}
        for k in ("p_max", "v_max", "t_max", "gear_ratio", "kp_max", "kd_max"):
            if k in values:
                values[k] = float(values[k])
        if "pole_pairs" in values:
            values["pole_pairs"] = int(values["pole_pairs"])
        if base is not None:
            return replace(base, name=name, **values)
        return MotorModel(name=name, **values)

    def extended(self, entries: Mapping[str, Any], source: str = "<motors>") -> Catalogue:
        """A new catalogue with ``entries`` (name → fields) added or overriding existing models.

        Raises:
            ConfigError: listing every problem in every entry.
        """
        problems: list[ConfigProblem] = []
        built = dict(self._models)
        cat = self
        for name, entry in entries.items():
            found = cat.check_entry(str(name), entry)
            if found:
                problems += [ConfigProblem(source, None, msg, fix) for _, msg, fix in found]
                continue
            model = cat.build_entry(str(name), entry)
            built[_key(model.name)] = model
            cat = Catalogue({m.name: m for m in built.values()})  # later entries may use earlier as base
        if problems:
            raise ConfigError(problems)
        return cat


def _read_yaml(path: Path) -> Mapping[str, Any]:
    try:
        data = load_yaml(path, MOTOR_FILE_LIMITS) or {}
    except FileProblem as e:
        raise ConfigError([ConfigProblem(str(path), e.line, e.what, e.fix)]) from None
    if not isinstance(data, Mapping):
        raise ConfigError([ConfigProblem(str(path), None, "a motor file must map model names to fields",
                                          "write `AK80-9: {t_max: 18.0, ...}` entries")])
    return data


_default: Catalogue | None = None


def default_catalogue() -> Catalogue:
    """The bundled catalogue, plus the file named by ``AKARM_MOTORS`` and anything :func:`load`-ed."""
    global _default
    if _default is None:
        cat = Catalogue().extended(_read_yaml(_DATA_FILE), str(_DATA_FILE))
        extra = os.environ.get("AKARM_MOTORS")
        if extra:
            cat = cat.extended(_read_yaml(Path(extra)), extra)
        _default = cat
    return _default


def load(path: str | os.PathLike[str]) -> Catalogue:
    """Add or override models from a YAML file, for the rest of this process.

    Returns the new default catalogue. Raises :class:`~akarm.ConfigError` on a bad file.
    """
    global _default
    p = Path(path)
    _default = default_catalogue().extended(_read_yaml(p), str(p))
    return _default


def get(name: str | MotorModel) -> MotorModel:
    """The catalogue model called ``name``, case-insensitive (a :class:`MotorModel` passes through).

    Raises:
        UnknownMotorError: listing the known names.
    """
    return default_catalogue().get(name)


def names() -> list[str]:
    """Every model name in the default catalogue, sorted."""
    return default_catalogue().names()
