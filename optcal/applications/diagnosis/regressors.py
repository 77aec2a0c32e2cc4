"""Temperature, time and session of each pose as the regressors of the candidate effects."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from optcal.applications.diagnosis.effects import NEEDS
from optcal.core.poses import PoseTable

#: A temperature range below this (°C) is treated as constant: no temperature effect can be estimated.
MIN_TEMP_SPAN_C: float = 0.5


@dataclass(frozen=True)
class Regressors:
    """Temperature and time of each pose, centred and scaled to [−1, 1].

    Attributes
    ----------
    tau, s : ndarray, shape (n,)
        ``(temp − T_ref)/temp_half`` and ``(t − t_ref)/t_half`` (zeros when absent).
    temp_ref, temp_half : float
        Mid-point and half-span of the temperature, °C (``nan``/0 when absent or constant).
    t_ref, t_half : float
        Mid-point and half-span of the pose times, s.
    has_temp, has_time : bool
        Whether a temperature (non-constant) and a time column are usable.
    notes : list of str
        Why a column is unusable (for the report).
    session : ndarray of int, shape (n,)
        Session of each pose (all 0 for one recording).
    n_sessions : int
    """

    tau: NDArray[np.float64]
    s: NDArray[np.float64]
    temp_ref: float
    temp_half: float
    t_ref: float
    t_half: float
    has_temp: bool
    has_time: bool
    notes: tuple[str, ...] = ()
    session: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    n_sessions: int = 1

    @classmethod
    def of(cls, poses: PoseTable, session: NDArray[np.intp] | None = None) -> "Regressors":
        """The regressors of ``poses``; ``session`` (optional) is the session of each pose (0, 1, ...).

        With several sessions the pose times must already count from each session's own start
        (:func:`optcal.applications.diagnosis.sessions.stack_sessions` does that): a drift is within a session.
        """
        n = poses.n
        notes: list[str] = []
        tau, s = np.zeros(n), np.zeros(n)
        temp_ref, temp_half, t_ref, t_half = float("nan"), 0.0, float("nan"), 0.0
        has_temp = has_time = False
        if poses.temp is None:
            notes.append("no temperature column: temperature effects cannot be tested")
        else:
            lo, hi = float(np.min(poses.temp)), float(np.max(poses.temp))
            temp_ref = 0.5 * (lo + hi)
            if hi - lo < MIN_TEMP_SPAN_C:
                notes.append(
                    f"the temperature is constant (range {hi - lo:.2g} °C < {MIN_TEMP_SPAN_C:g} °C): "
                    "temperature effects cannot be estimated"
                )
            else:
                has_temp, temp_half = True, 0.5 * (hi - lo)
                tau = (poses.temp - temp_ref) / temp_half
        if poses.t is None:
            notes.append("no time column: bias_drift cannot be tested")
        else:
            lo, hi = float(np.min(poses.t)), float(np.max(poses.t))
            t_ref = 0.5 * (lo + hi)
            if hi <= lo:
                notes.append("all poses have the same time: bias_drift cannot be tested")
            else:
                has_time, t_half = True, 0.5 * (hi - lo)
                s = (poses.t - t_ref) / t_half
        index = np.zeros(n, dtype=np.intp) if session is None else np.asarray(session, dtype=np.intp)
        n_sessions = int(index.max()) + 1 if n else 1
        if n_sessions < 2:
            notes.append("one session: session_bias needs several sessions of the sensor")
        return cls(tau, s, temp_ref, temp_half, t_ref, t_half, has_temp, has_time, tuple(notes), index, n_sessions)

    def supports(self, effect: str) -> bool:
        """Whether the columns ``effect`` needs are usable."""
        need = NEEDS[effect]
        return (need is None or (need == "temp" and self.has_temp) or (need == "t" and self.has_time)
                or (need == "session" and self.n_sessions > 1))

    def reason_unsupported(self, effect: str) -> str:
        need = NEEDS[effect]
        word = {"temp": "temperature", "t": "time", "session": "session"}.get(str(need), "time")
        hits = [note for note in self.notes if word in note]
        return hits[0] if hits else f"{effect} needs a {word} column"

    def half_span(self, effect: str) -> float:
        """The scale turning a normalised coefficient into physical units (1 for the nonlinearity)."""
        need = NEEDS[effect]
        return self.temp_half if need == "temp" else self.t_half if need == "t" else 1.0

    def correlation(self) -> float | None:
        """Pearson correlation of temperature and time (``None`` unless both are usable)."""
        if not (self.has_temp and self.has_time):
            return None
        return float(np.corrcoef(self.tau, self.s)[0, 1])

