"""A peer's calibration (imucal, imu_tk) next to optcal's own on the same data: what each misses.

:func:`compare_with_peer` evaluates both on the poses of DATA: the norm error ``‖ā_k‖ − 1`` of
every pose (Lu 2017, eq. 13) under the peer's calibration as it was given, and under optcal's
calibration fitted on DATA (in sample, and held out by k-fold: the peer was fitted elsewhere, so
every pose is held out for it, and optcal's held-out figure is the fair one to set next to it).

What the peer misses is then said in the sensor's terms: its bias, scales and axis angles against
optcal's (the physical decomposition of :meth:`optcal.core.model.LumpedModel.physical`, the same
for any frame convention), and how much of its error each group explains — the peer's rms with
that group replaced by optcal's.  What optcal's own misses is its held-out error against its
in-sample error and against the pose noise alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.jsonio import jsonable
from optcal.core.model import LumpedModel, PhysicalParameters
from optcal.core.norm_residual import norm_residuals
from optcal.core.poses import PoseTable
from optcal.core.stats import rms
from optcal.errors import InputError

#: The parameter groups whose replacement is tried, in the order reported.
GROUPS: tuple[str, ...] = ("bias", "scale", "axis angles")
#: Folds of optcal's held-out error (each pose is tested once, by a fit on the others).
FOLDS: int = 5


@dataclass
class PeerComparison:
    """The peer's calibration and optcal's own on DATA's poses (module docstring).

    Attributes
    ----------
    peer : str
        The peer named by its tool and its method (``imucal Ferraris``).
    source : str
        The peer's file(s).
    rows : ndarray of int
        The poses' rows.
    peer_after : ndarray
        ``‖ā_k‖ − 1`` under the peer's calibration, g.
    noise : ndarray or None
        The spread expected from the pose noise alone, g.
    own : str
        optcal's calibration (method, what it was fitted on), or why there is none.
    own_after, own_heldout : ndarray or None
        Under optcal's calibration fitted on DATA, in sample and k-fold held out, g.
    differences : dict
        Peer minus optcal: ``bias_mg``, ``scale_ppm`` (per axis), ``angles_deg`` (ρ, φ, λ of Lu 2017, eq. 1).
    explained : dict of str to float
        The peer's rms (g) with each group of :data:`GROUPS` replaced by optcal's.
    folds : int
        Folds of :attr:`own_heldout`.
    """

    peer: str
    source: str
    rows: NDArray[np.int64]
    peer_after: NDArray[np.float64]
    noise: NDArray[np.float64] | None
    own: str
    own_after: NDArray[np.float64] | None = None
    own_heldout: NDArray[np.float64] | None = None
    differences: dict[str, Any] = field(default_factory=dict)
    explained: dict[str, float] = field(default_factory=dict)
    folds: int = FOLDS

    def lines(self) -> list[str]:
        """The text report's lines."""
        mg = 1e3
        out = [f"{self.peer} next to optcal's own calibration on DATA's {self.rows.size} poses (|a|-1):"]
        width = max(len(self.peer), len("optcal (held out)")) + 2
        out.append(f"  {'':<{width}} {'rms (mg)':>9} {'max (mg)':>9}")
        out.append(f"  {self.peer:<{width}} {rms(self.peer_after) * mg:9.4f} {np.max(np.abs(self.peer_after)) * mg:9.4f}"
                   "   (fitted elsewhere: every pose is new to it)")
        if self.own_after is not None:
            out.append(f"  {'optcal (in sample)':<{width}} {rms(self.own_after) * mg:9.4f} "
                       f"{np.max(np.abs(self.own_after)) * mg:9.4f}   ({self.own})")
            if self.own_heldout is not None:
                out.append(f"  {'optcal (held out)':<{width}} {rms(self.own_heldout) * mg:9.4f} "
                           f"{np.max(np.abs(self.own_heldout)) * mg:9.4f}   ({self.folds}-fold: each pose predicted by a fit "
                           "on the others)")
        else:
            out.append(f"  optcal's own: {self.own}")
        if self.noise is not None:
            out.append(f"  {'pose noise alone':<{width}} {rms(self.noise) * mg:9.4f}")
        if self.differences:
            d = self.differences
            out.append(f"what {self.peer} misses, against optcal's fit of DATA (peer - optcal): "
                       f"bias {', '.join(f'{v:+.3f}' for v in d['bias_mg'])} mg; "
                       f"scale {', '.join(f'{v:+.0f}' for v in d['scale_ppm'])} ppm; "
                       f"axis angles {', '.join(f'{k} {v:+.4f}' for k, v in d['angles_deg'].items())} deg")
            out.append(f"  {self.peer}'s rms {rms(self.peer_after) * mg:.4f} mg becomes, with optcal's "
                       + "; ".join(f"{g}: {v * mg:.4f} mg" for g, v in self.explained.items()))
        if self.own_after is not None and self.own_heldout is not None:
            out.append(f"what optcal's own misses: held out {rms(self.own_heldout) * mg:.4f} mg against in sample "
                       f"{rms(self.own_after) * mg:.4f} mg"
                       + (f" and the pose noise alone {rms(self.noise) * mg:.4f} mg" if self.noise is not None else ""))
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe, figures in g (mg, ppm and degrees where the name says so)."""
        def stats(r: NDArray[np.float64] | None) -> dict[str, Any] | None:
            return None if r is None else {"rms_g": rms(r), "max_abs_g": float(np.max(np.abs(r)))}

        return jsonable({
            "peer": self.peer, "source": self.source, "n_poses": int(self.rows.size),
            "peer_after": stats(self.peer_after),
            "own": self.own, "own_in_sample": stats(self.own_after), "own_heldout": stats(self.own_heldout),
            "own_heldout_folds": self.folds if self.own_heldout is not None else None,
            "rms_noise_g": None if self.noise is None else rms(self.noise),
            "differences_peer_minus_own": self.differences or None,
            "peer_rms_g_with_own": self.explained or None,
            "poses": [{"row": int(self.rows[k]), "peer_g": self.peer_after[k],
                       "own_g": None if self.own_after is None else self.own_after[k],
                       "own_heldout_g": None if self.own_heldout is None else self.own_heldout[k]}
                      for k in range(self.rows.size)],
        })


def _model(params: PhysicalParameters) -> LumpedModel:
    return LumpedModel.from_physical(params.scale, params.rho, params.phi, params.lam, params.bias)


def _swap(peer: PhysicalParameters, own: PhysicalParameters, group: str) -> PhysicalParameters:
    """The peer's parameters with ``group`` taken from optcal's."""
    if group == "bias":
        return replace(peer, bias=own.bias)
    if group == "scale":
        return replace(peer, scale=own.scale)
    return replace(peer, rho=own.rho, phi=own.phi, lam=own.lam)


def differences(peer: LumpedModel, own: LumpedModel, acc: NDArray[np.float64]) -> tuple[dict[str, Any], dict[str, float]]:
    """Peer minus optcal in the sensor's terms, and the peer's rms (g) with each group replaced by optcal's."""
    p, q = peer.physical(), own.physical()
    diff = {
        "bias_mg": ((p.bias - q.bias) / q.scale * 1e3).tolist(),  # raw units over raw units per g
        "scale_ppm": ((p.scale / q.scale - 1.0) * 1e6).tolist(),
        "angles_deg": {name: float(np.degrees(a - b)) for name, a, b in
                       (("rho", p.rho, q.rho), ("phi", p.phi, q.phi), ("lambda", p.lam, q.lam))},
    }
    explained = {}
    for group in GROUPS:
        m = _model(_swap(p, q, group))
        explained[group] = rms(norm_residuals(m.T_canonical, m.o, acc))
    return diff, explained


def compare_with_peer(cal: Any, poses: PoseTable, noise: NDArray[np.float64] | None, own: Any | None = None,
                      own_label: str = "", own_heldout: NDArray[np.float64] | None = None,
                      method: str = "default", folds: int = FOLDS) -> PeerComparison:
    """The peer's calibration ``cal`` next to optcal's on ``poses`` (in ``cal``'s units).

    Parameters
    ----------
    cal : PeerCalibration
    poses : PoseTable
        DATA's poses, in the calibration's units.
    noise : ndarray, optional
        The spread of each pose's norm error from its noise alone, g.
    own : LumpedModel, optional
        optcal's calibration of ``poses`` when the caller has one (the diagnosis's baseline);
        otherwise fitted here by ``method`` and held out by :data:`FOLDS`-fold.
    own_label : str
        What ``own`` is.
    own_heldout : ndarray, optional
        ``own``'s held-out residuals, g.
    method : str
        optcal's estimator when ``own`` is not given.
    folds : int
        Folds of the held-out error (the one computed here, or ``own_heldout``'s).
    """
    from optcal.applications.quality.validation import held_out_validation, norm_noise
    from optcal.families.accel.calibration import calibrate

    if noise is None and poses.sigma is not None:
        lumped = cal.lumped()
        noise = norm_noise(lumped.T, lumped.o, poses.acc, poses.sigma)
    peer_after = cal.norm_errors(poses.acc)
    result = PeerComparison(cal.label, cal.source, poses.rows.copy(), peer_after, noise, own_label, folds=folds)
    if own is None:
        try:
            fit = calibrate(poses, method)
            own = LumpedModel.from_T(fit.T, fit.o)
            result.own = f"{fit.method}, fitted on these {poses.n} poses"
            try:
                own_heldout = held_out_validation(poses, folds=min(folds, poses.n), method=method, full=fit).residuals
            except InputError as exc:
                result.own += f"; no held-out error: {exc}"
        except InputError as exc:
            result.own = f"cannot be fitted on DATA ({exc})"
            return result
    result.own_after = norm_residuals(own.T_canonical, own.o, poses.acc)
    result.own_heldout = own_heldout
    result.differences, result.explained = differences(cal.lumped().model, own, poses.acc)
    return result
