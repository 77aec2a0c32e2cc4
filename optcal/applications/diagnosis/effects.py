"""The vocabulary of the diagnosis: the candidate effects, what each needs, its units and its cause.

The parametric effects are the terms of :class:`optcal.core.extended_model.ExtendedModel` (the
forward model and its units are documented there); ``outliers`` are poses that are not static
or are corrupt (no parameters: found by a robust fit and given zero weight).
"""

from __future__ import annotations

from collections.abc import Iterable

from optcal.errors import InputError
from optcal.core.extended_model import MAX_ORDER as MODEL_MAX_ORDER
from optcal.core.extended_model import PARAMETRIC
from optcal.core.extended_model import NEEDS as MODEL_NEEDS
from optcal.core.extended_model import UNITS as MODEL_UNITS
from optcal.core.model import AXES

__all__ = ["EFFECTS", "VOCABULARY", "PARAMETRIC", "FITTED", "SESSION_BIAS", "BIAS_STEP", "STEP_MIN_SIDE", "MAX_STEPS", "MAX_SESSIONS", "CAUSE_STEPS", "MAX_ORDER", "NEEDS", "UNITS", "REGRESSOR_TEXT", "REGRESSOR_WORDS", "PLAIN_NAMES", "CAUSES",
           "parse_effects", "describe_term", "plain_term"]

#: "The bias changed between sessions" (turn-on bias repeatability): one offset per session after
#: the first and per axis, relative to the first session (several sessions of one sensor only).
SESSION_BIAS: str = "session_bias"
#: "The bias stepped once and stayed" (a knock, a shock or a connector re-seated between two rests): one offset
#: per axis of the poses after an unknown pose, relative to those before it; a session bias with two segments
#: whose split is searched (:meth:`~optcal.applications.diagnosis.selection.ForwardSelection.step_candidates`).
BIAS_STEP: str = "bias_step"
#: Fewest poses on each side of a bias step: a step leaving one or two poses on one side is those poses' own
#: departure, the outlier test's question (a knocked rest that did not persist), and with two it is confounded with
#: their two mean shifts; three keep one degree of freedom beyond a pair of outliers.
STEP_MIN_SIDE: int = 3
#: Most bias steps one recording is searched for (a knock, then another): "order" k of ``bias_step`` is the offset of
#: the poses after the k-th step placed (its regressor that step's indicator), as ``session_bias``'s orders are its
#: sessions.  Each step is placed by its own search at the family-wise level (its position paid for in its p value).
MAX_STEPS: int = 2
#: Most sessions one diagnosis fits together (each adds three offsets to the fit's layout).
MAX_SESSIONS: int = 10
#: The coefficient terms the diagnosis fits: the extended model's, then the per-session offsets.
FITTED: tuple[str, ...] = (*PARAMETRIC, SESSION_BIAS, BIAS_STEP)
#: Number of coefficients per axis of each fitted term (its polynomial orders; for the session
#: offsets, one per session after the first).
MAX_ORDER: dict[str, int] = {**MODEL_MAX_ORDER, SESSION_BIAS: MAX_SESSIONS - 1, BIAS_STEP: MAX_STEPS}
#: The effects one recording can show, in the order they are reported.
EFFECTS: tuple[str, ...] = (*PARAMETRIC, "outliers")
#: The whole vocabulary of model extensions: one recording's effects and, for several sessions,
#: the bias changing between them.
VOCABULARY: tuple[str, ...] = (*FITTED, "outliers")
#: Column each effect needs (``None``: none; ``session``: several sessions).
NEEDS: dict[str, str | None] = {**MODEL_NEEDS, SESSION_BIAS: "session", BIAS_STEP: None, "outliers": None}
#: Units of the first-order coefficient (JSON ``estimate``; ``rows`` for outliers; the session
#: offsets' estimate is their spread, the turn-on repeatability).
UNITS: dict[str, str] = {**MODEL_UNITS, SESSION_BIAS: "g", BIAS_STEP: "g", "outliers": "rows"}
#: The regressor each effect adds to output axis i (for reports).
REGRESSOR_TEXT: dict[str, str] = {
    "temperature_bias": "ΔT",
    "temperature_scale": "ΔT·f_{axis}",
    "bias_drift": "Δt",
    "scale_nonlinearity": "f_{axis}²",
    SESSION_BIAS: "session",
    BIAS_STEP: "step",
}
#: The physical cause each effect names, in plain words.
CAUSES: dict[str, str] = {
    "temperature_bias": "the zero offset moves with temperature (thermal stress in the package and MEMS structure)",
    "temperature_scale": "the sensitivity changes with temperature (thermal change of the spring stiffness and readout gain)",
    "bias_drift": "the zero offset wanders with time (bias instability, self-heating or mechanical settling after power-on)",
    "scale_nonlinearity": "the output is not proportional to the force (a second-order response of the sensing element)",
    SESSION_BIAS: "the bias changed between sessions (turn-on bias repeatability: the zero offset settles at "
                  "a different value each time the sensor is powered)",
    BIAS_STEP: "the bias stepped once and stayed (a knock or shock between two rests, a re-seated connector or "
               "mount: the zero offset moved and did not come back)",
    "outliers": "some poses were not static or are corrupt (the sensor moved, was bumped, or the interval was mis-detected)",
}
#: The cause of a ``bias_step`` finding with a second step placed (:data:`MAX_STEPS`).
CAUSE_STEPS: str = ("the bias stepped at each of these places and stayed (knocks or shocks between rests, a re-seated "
                    "connector or mount: the zero offset moved each time and did not come back)")
#: The regressor of each effect in plain words (figures and the simulation check).
REGRESSOR_WORDS: dict[str, str] = {
    "temperature_bias": "temperature",
    "temperature_scale": "temperature × force",
    "bias_drift": "time",
    "scale_nonlinearity": "force²",
    SESSION_BIAS: "the session",
    BIAS_STEP: "before or after the step",
}


#: Each effect in plain words (figures: no internal names).
PLAIN_NAMES: dict[str, str] = {
    "temperature_bias": "bias changing with temperature",
    "temperature_scale": "sensitivity changing with temperature",
    "bias_drift": "bias drifting in time",
    "scale_nonlinearity": "nonlinear response",
    SESSION_BIAS: "bias differing between sessions",
    BIAS_STEP: "bias step",
    "outliers": "outlier poses",
}


def plain_term(effect: str, axis: int, order: int) -> str:
    """A term in plain words, e.g. ``bias changing with temperature on z (order 2)``."""
    return f"{PLAIN_NAMES[effect]} on {AXES[axis]}" + (f" (order {order})" if order > 1 and effect != SESSION_BIAS else "")


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
    unknown = [s for s in names if s not in VOCABULARY]
    if unknown:
        raise InputError(f"unknown effect(s) {', '.join(unknown)}; choose from {', '.join(VOCABULARY)}")
    return tuple(e for e in VOCABULARY if e in names)


def describe_term(effect: str, axis: int, order: int) -> str:
    """Readable name of a term, e.g. ``temperature_bias(z, order 2)`` (``session_bias(z)``: every session's offset)."""
    if effect == BIAS_STEP and order > 1:
        return f"{effect}({AXES[axis]}, {order} steps)"
    if effect in (SESSION_BIAS, BIAS_STEP):
        return f"{effect}({AXES[axis]})"
    return f"{effect}({AXES[axis]}" + (f", order {order})" if order > 1 else ")")
