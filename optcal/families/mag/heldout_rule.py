"""The held-out rule that chooses a magnetometer's form, written once for the 3-D forms
(:func:`optcal.families.mag.fit.choose_form`) and the planar ones (:func:`optcal.families.mag.planar.fit_planar`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from optcal.families.mag.heldout import HeldOut

__all__ = ["richest_within_se"]


def richest_within_se(heldout: "HeldOut", ranked: list[str], usable: Callable[[str], bool]
                      ) -> tuple[str | None, str | None, tuple[float, float] | None]:
    """The held-out form rule (3-D and planar): the richest usable form (``ranked`` simplest first) whose held-out mean
    square exceeds the best usable form's by at most the paired standard error, with that excess (``None``: the best
    chosen), and the best; ``(None, None, None)`` when none is usable.  A magnetometer always has some soft iron, so
    the sphere is an approximation (the peers' default is the full ellipsoid: Magneto, MATLAB magcal, MotionCal,
    ArduPilot); the rule protects from a richer form that predicts unseen directions worse (generated true spheres:
    the full form costs under 0.15 % of the field; divemove's richer forms are 2.1-3.7 SE worse)."""
    best = next((f for f in sorted(ranked, key=heldout.rms) if usable(f)), None)
    if best is None:
        return None, None, None
    for form in reversed(ranked[ranked.index(best) + 1:]):
        worse, se = heldout.gain(form, best)
        if worse <= se and usable(form):
            return form, best, (worse, se)
    return best, best, None
