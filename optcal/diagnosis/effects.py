"""The vocabulary of the diagnosis: the candidate effects, what each needs, its units and its cause.

The parametric effects are the terms of :class:`optcal.extended_model.ExtendedModel` (the
forward model and its units are documented there); ``outliers`` are poses that are not static
or are corrupt (no parameters: found by a robust fit and given zero weight).
"""

from __future__ import annotations

from collections.abc import Iterable

from optcal.errors import InputError
from optcal.extended_model import MAX_ORDER, PARAMETRIC
from optcal.extended_model import NEEDS as MODEL_NEEDS
from optcal.extended_model import UNITS as MODEL_UNITS
from optcal.model import AXES

__all__ = ["EFFECTS", "PARAMETRIC", "MAX_ORDER", "NEEDS", "UNITS", "REGRESSOR_TEXT", "REGRESSOR_WORDS", "CAUSES",
           "parse_effects", "describe_term"]

#: The vocabulary of model extensions, in the order they are reported.
EFFECTS: tuple[str, ...] = (*PARAMETRIC, "outliers")
#: Column each effect needs (``None``: none).
NEEDS: dict[str, str | None] = {**MODEL_NEEDS, "outliers": None}
#: Units of the first-order coefficient (JSON ``estimate``; ``rows`` for outliers).
UNITS: dict[str, str] = {**MODEL_UNITS, "outliers": "rows"}
#: The regressor each effect adds to output axis i (for reports).
REGRESSOR_TEXT: dict[str, str] = {
    "temperature_bias": "ΔT",
    "temperature_scale": "ΔT·f_{axis}",
    "bias_drift": "Δt",
    "scale_nonlinearity": "f_{axis}²",
}
#: The physical cause each effect names, in plain words.
CAUSES: dict[str, str] = {
    "temperature_bias": "the zero offset moves with temperature (thermal stress in the package and MEMS structure)",
    "temperature_scale": "the sensitivity changes with temperature (thermal change of the spring stiffness and readout gain)",
    "bias_drift": "the zero offset wanders with time (bias instability, self-heating or mechanical settling after power-on)",
    "scale_nonlinearity": "the output is not proportional to the force (a second-order response of the sensing element)",
    "outliers": "some poses were not static or are corrupt (the sensor moved, was bumped, or the interval was mis-detected)",
}
#: The regressor of each effect in plain words (figures and the simulation check).
REGRESSOR_WORDS: dict[str, str] = {
    "temperature_bias": "temperature",
    "temperature_scale": "temperature × force",
    "bias_drift": "time",
    "scale_nonlinearity": "force²",
}


def parse_effects(text: str | Iterable[str] | None) -> tuple[str, ...] | None:
    """Parse ``"temperature_bias,outliers"`` (or a list) into effect names.

    ``None``, ``""`` or ``"all"`` mean every effect (``None`` is returned); ``"none"`` means no
    candidate at all (an empty tuple: baseline and simulation check only).
    """
    if text is None:
        return None
    names = [s.strip() for s in (text.split(",") if isinstance(text, str) else text) if s.strip()]
    if names == ["none"]:
        return ()
    if not names or names == ["all"]:
        return None
    unknown = [s for s in names if s not in EFFECTS]
    if unknown:
        raise InputError(f"unknown effect(s) {', '.join(unknown)}; choose from {', '.join(EFFECTS)}")
    return tuple(e for e in EFFECTS if e in names)


def describe_term(effect: str, axis: int, order: int) -> str:
    """Readable name of a term, e.g. ``temperature_bias(z, order 2)``."""
    return f"{effect}({AXES[axis]}" + (f", order {order})" if order > 1 else ")")
