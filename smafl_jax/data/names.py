"""What a column's name (or the sidecar's unit) says it holds: a drive voltage.  Plain Python: `smafl check` uses it
without JAX, and identification (`smafl_jax.identify`), the baselines and the loader's column choice share this one rule."""

from __future__ import annotations

import re

__all__ = ["VOLTAGE_UNITS", "is_voltage"]

#: Units (sidecar ``units``, or in brackets after the column name) that make an input a drive voltage.
VOLTAGE_UNITS = ("v", "volt", "volts")
#: Whole column names that mean a drive voltage: the symbols of the paper (U) and of control engineers (u, v, V), with
#: the usual suffixes (U_in, Vset, v_drive, ...).  A new-user trial named the column ``U``: the record then got a static
#: model and held out at 175x the noise instead of 5x.
_VOLTAGE_NAME = re.compile(r"^[uv][ _-]?(in|set|drive|d|s|app|applied|cmd|command|supply|sup)?$")
#: Words in a column name that mean a drive voltage (English, German).
_VOLTAGE_WORDS = ("volt", "spannung")  # not "tension": a force in a muscle rig


def is_voltage(input_name: str | None, units: dict | None = None) -> bool:
    """A drive voltage, by its column name or unit (``voltage_V``, ``Spannung [V]``, ``U``, ``v_in``, sidecar unit V).

    Why it matters: `auto_structure` puts a drive voltage behind the Joule thermal lag, and the lag baseline filters
    ``u^2``; any other input drives the hysteresis directly."""
    name = (input_name or "").strip().lower()
    unit = str((units or {}).get(input_name, "")).strip().lower()
    if unit in VOLTAGE_UNITS or any(w in name for w in _VOLTAGE_WORDS):
        return True
    bracket = re.search(r"[\[(]\s*([a-z]+)\s*[\])]\s*$", name)  # "drive [V]", "u (V)"
    if bracket and bracket.group(1) in VOLTAGE_UNITS:
        return True
    return name.endswith(("_v", "/v", " v")) or bool(_VOLTAGE_NAME.match(name))
