"""Several sessions of one sensor diagnosed together, and their turn-on bias repeatability.

Each session (a recording or pose table, read with its own data decisions) keeps its own time
origin: its pose times are counted from its own first pose, so a drift term describes the
bias *within* a session, the same shape after every power-on.  Temperature is pooled (a
temperature coefficient is a property of the sensor).  The pose tables are stacked with a
session index; one calibration ``T``, ``o`` is fitted to all of them.

"The bias changed between sessions" (``session_bias``) is a candidate of the forward selection
like every effect: per axis, the offsets of sessions 2..S from session 1 (``S − 1`` coefficients,
all counted in the test's degrees of freedom and in the BIC), fitted jointly with ``T`` and
``o``.  Its finding reports every session's offset from their mean, with standard errors, and
their spread (the sample standard deviation over the sessions, the turn-on repeatability).

A future session's offset is unknown, so the calibration a user can apply
(:meth:`SessionOffsets.applied_bias_shift`) uses the *mean* of the sessions' biases and records
the repeatability as the uncertainty of its bias.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.effects import MAX_SESSIONS, SESSION_BIAS
from optcal.applications.diagnosis.fitting import Fit, Fitter
from optcal.applications.diagnosis.problem import BETA_INDEX, active_mask, session_offsets_g
from optcal.errors import InputError
from optcal.core.model import AXES
from optcal.core.poses import PoseTable

#: What the saved calibration does with the sessions' offsets (printed and stored).
APPLIED_TEXT = (
    "per-session offsets cannot be applied to a future session: the saved calibration applies the mean "
    "of the sessions' biases and records their spread (the turn-on bias repeatability) as the "
    "uncertainty of its bias"
)


@dataclass(frozen=True)
class SessionStack:
    """Pose tables of several sessions stacked into one, with the session of each pose.

    Attributes
    ----------
    poses : PoseTable
        Every session's poses, session after session; times count from each session's own first
        pose (s).
    session : ndarray of int, shape (n,)
        Session of each pose (0, 1, ...).
    names : tuple of str
        A name per session (e.g. its file).
    time_origins : tuple of float or None
        The time each session's clock was shifted by (its first pose's time, s; ``None``: no time).
    """

    poses: PoseTable
    session: NDArray[np.intp]
    names: tuple[str, ...]
    time_origins: tuple[float | None, ...]

    @property
    def n_sessions(self) -> int:
        return len(self.names)

    def counts(self) -> list[int]:
        """Poses per session."""
        return [int(np.sum(self.session == k)) for k in range(self.n_sessions)]


def _column(tables: Sequence[PoseTable], name: str, shifts: Sequence[float] | None = None) -> NDArray | None:
    values = [getattr(p, name) for p in tables]
    if all(v is None for v in values):
        return None
    if any(v is None for v in values):
        missing = [k + 1 for k, v in enumerate(values) if v is None]
        raise InputError(f"sessions {missing} have no {name} column while the others have one; give every session "
                         f"a {name} column, or none")
    if shifts is not None:
        values = [v - shift for v, shift in zip(values, shifts)]
    return np.concatenate(values)


def stack_sessions(tables: Sequence[PoseTable], names: Sequence[str] | None = None) -> SessionStack:
    """Stack the pose tables of ``tables`` (one per session of the same sensor) into one.

    Parameters
    ----------
    tables : sequence of PoseTable
        At least two, at most :data:`~optcal.applications.diagnosis.effects.MAX_SESSIONS`, in the same units.
    names : sequence of str, optional
        A name per session (default ``session 1``, ``session 2``, ...).

    Raises
    ------
    InputError
        Fewer than two or too many sessions, different units, a column some sessions lack.
    """
    tables = list(tables)
    names = [f"session {k + 1}" for k in range(len(tables))] if names is None else [str(x) for x in names]
    if len(names) != len(tables):
        raise InputError(f"names has {len(names)} entries for {len(tables)} sessions; give one name per session")
    if not 2 <= len(tables) <= MAX_SESSIONS:
        raise InputError(f"{len(tables)} sessions given: diagnosing sessions together needs 2 to {MAX_SESSIONS}; "
                         "diagnose a single recording on its own")
    units = {p.units for p in tables}
    if len(units) > 1:
        listing = ", ".join(f"{n}: {p.units}" for n, p in zip(names, tables))
        raise InputError(f"the sessions are in different units ({listing}); give them in the same units "
                         "(the units decision of each can be overridden)")
    origins = [None if p.t is None or p.n == 0 else float(np.min(p.t)) for p in tables]
    t = _column(tables, "t", [0.0 if o is None else o for o in origins])
    rows = [p.rows for p in tables]
    exclusions: dict[str, int] = {}
    for p in tables:
        for key, count in p.exclusions.items():
            exclusions[key] = exclusions.get(key, 0) + count
    first = tables[0]
    stacked = replace(
        first,
        acc=np.concatenate([p.acc for p in tables]),
        sigma=_column(tables, "sigma"), n_samples=_column(tables, "n_samples"), t=t,
        temp=_column(tables, "temp"), gyro=None if any(p.gyro is None for p in tables) else _column(tables, "gyro"),
        rows=np.concatenate(rows), source=f"{len(tables)} sessions", exclusions=exclusions, extra={},
    )
    session = np.concatenate([np.full(p.n, k, dtype=np.intp) for k, p in enumerate(tables)])
    return SessionStack(stacked, session, tuple(names), tuple(origins))


@dataclass
class SessionOffsets:
    """Every session's bias offset from the sessions' mean, per axis, and their spread.

    Attributes
    ----------
    names : list of str
    axes : list of str
        Axes carrying a session offset in the final model.
    offsets_g, stderr_g : dict of str to list of float
        Per axis, each session's bias minus the mean of the sessions' biases (g), and its
        standard error.
    repeatability_g : dict of str to float
        Per axis, the sample standard deviation of the sessions' biases (g): the turn-on bias
        repeatability.
    mean_from_first_g : dict of str to float
        Per axis, the mean of the sessions' biases minus the first session's (g): the shift the
        saved calibration applies to the fitted bias.
    applied : str
    """

    names: list[str]
    axes: list[str]
    offsets_g: dict[str, list[float]]
    stderr_g: dict[str, list[float]]
    repeatability_g: dict[str, float]
    mean_from_first_g: dict[str, float]
    applied: str = APPLIED_TEXT

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def repeatability_vector(self) -> NDArray[np.float64]:
        """Repeatability of the three axes (g; 0 where the sessions' biases agree)."""
        return np.array([self.repeatability_g.get(a, 0.0) for a in AXES])


def session_offsets(fitter: Fitter, fit: Fit, names: Sequence[str]) -> SessionOffsets | None:
    """The sessions' offsets of ``fit`` with standard errors (``None`` when it has no session term)."""
    S = fitter.reg.n_sessions
    axes = [a for a in range(3) if (SESSION_BIAS, a) in fit.terms]
    if S < 2 or not axes:
        return None
    cov = fitter.covariance(fit)
    free_beta = [int(b) for b in np.flatnonzero(active_mask(fit.terms))]
    relative = session_offsets_g(fit.x, S)  # (3, S), first session 0
    # centred = M δ with δ the offsets of sessions 2..S from the first (its own is 0)
    M = np.vstack([np.zeros((1, S - 1)), np.eye(S - 1)]) - np.full((S, S - 1), 1.0 / S)
    out = SessionOffsets(list(names), [AXES[a] for a in axes], {}, {}, {}, {})
    for a in axes:
        position = [9 + free_beta.index(BETA_INDEX[(SESSION_BIAS, a, k)]) for k in range(1, S)]
        centred = relative[a] - relative[a].mean()
        var = np.diag(M @ cov[np.ix_(position, position)] @ M.T)
        out.offsets_g[AXES[a]] = [float(v) for v in centred]
        out.stderr_g[AXES[a]] = [float(np.sqrt(max(v, 0.0))) for v in var]
        out.repeatability_g[AXES[a]] = float(np.std(relative[a], ddof=1))
        out.mean_from_first_g[AXES[a]] = float(relative[a].mean())
    return out
