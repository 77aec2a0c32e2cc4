"""The order a directly entered time term is named at: the step-down of forward selection.

A drift may enter at order 2 or 3 directly (:data:`~optcal.applications.diagnosis.acceptance.DIRECT_ORDERS`). It is
stepped down to a lower order ``j`` when its coefficients above ``j`` add nothing significant (F test at the level it
entered at, the level a later step would need to raise the order again): a linear drift is named as linear, not as
the cubic that fitted a shade better.

The lower order must stand for the term on its own: it must pass the test the step gives every order of the term (its
F test against the step's model at the same level, and a lower BIC).  The likelihood-ratio statistics of the nested
fits add up (``χ²(k vs 0) = χ²(j vs 0) + χ²(k vs j)``, exactly for the Gaussian likelihood ratio and in the F form's
numerators), so order ``k`` can pass against the step's model while neither its part above ``j`` nor order ``j`` alone
passes: the departure is spread over the coefficients.  Stepping down there replaces a term the data ask for by one
they do not, and no drift is named (the 38 Xsens rests with a z drift of 0.1 mg linear and 0.03 mg in ``s²`` planted
on the log's own: order 2 at p 1.1e-4, its second coefficient at p 0.0011 and order 1 alone at p 0.0063 against
0.00056; a knock on z was named in its place, ``tests/applications/test_diagnosis_step_down.py``).  Such an order is skipped; when no lower order
passes both tests, the term keeps the order it entered at.

A term kept that way is *spread*.  When only spread terms pass in a step (before, nothing passed there), the step also
searches terms together (a drift and a knock, two drifts: :mod:`~optcal.applications.diagnosis.term_pair`), as it did
before, and the kept order competes with them by ΔBIC and the held-out check.  A cubic in time is the smooth summary
of a linear drift with a knock at the middle (mikoff's unit 0, 22 rests, an 8 mg x drift and a 4 mg x knock after
rest 11: the cubic at p 2.7e-4, order 1 alone at p 0.00086 against 0.00083; the drift and the knock together at p
8.1e-5, ΔBIC −54 against the cubic's −31).  Where another candidate passes, the sets are not searched, as before (two
knocks in mikoff's unit 0 cut into 66 poses: the pair of knocks, ΔBIC −20.5, is named; a y drift with the x knock
searched together, ΔBIC −23.1, would win the BIC tie on fewer coefficients and name a drift that is not there).
"""

from __future__ import annotations

from dataclasses import dataclass

from optcal.applications.diagnosis.fitting import Fit, Fitter

__all__ = ["StepDown", "lower_order"]


@dataclass(frozen=True)
class StepDown:
    """The step-down of one term (:func:`lower_order`).

    Attributes
    ----------
    fit : Fit or None
        The fit at the lower order; ``None``: the term keeps the order it entered at.
    order : int or None
        The lower order.
    spread : bool
        Kept because every lower order whose higher coefficients add nothing fails its own test: the evidence is
        spread over the coefficients, where a polynomial may stand for another shape (a drift and a knock: a cubic
        in time is their smooth summary), so a step where only such terms pass searches terms together too
        (:mod:`~optcal.applications.diagnosis.term_pair`, module docstring).
    """

    fit: Fit | None
    order: int | None
    spread: bool = False


def lower_order(fitter: Fitter, current: Fit, entered: Fit, key: tuple[str, int], order: int,
                level: float) -> StepDown:
    """The lowest order below ``order`` that the term ``key`` of ``entered`` (fitted from ``current``) steps down to,
    with its fit; or that it keeps ``order`` (module docstring).

    An order ``j`` is taken when the coefficients of ``order`` above ``j`` are not significant together (F test of the
    order-``j`` fit against ``entered``, at ``level``) and order ``j`` passes its own test against ``current`` (F test
    at ``level``, BIC lower than ``current``'s), as the step's candidate of order ``j`` must.
    """
    bic0 = fitter.bic(current)
    spread = False
    for j in range(1, order):
        terms = dict(entered.terms)
        terms[key] = j
        lower = fitter.fit(terms, entered.outliers, entered.x)
        if fitter.f_test(lower, entered) < level:
            continue  # the coefficients above j are needed
        if fitter.f_test(current, lower) < level and fitter.bic(lower) < bic0:
            return StepDown(lower, j)
        spread = True  # order j fails its own test: it cannot stand for the term (module docstring); a higher j may
    return StepDown(None, None, spread)
