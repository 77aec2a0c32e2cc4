"""A bias that wanders in time as a random walk, fitted jointly with ``T`` and ``o`` by maximum likelihood.

Issue 13, item 2: a bias that rises and falls over a recording (warm-up, bias instability at
the scale of minutes) has almost no linear component.  Instead of a polynomial in time, the bias
is a state: each axis of ``b(t)`` is a Wiener process (a random walk), and the pose means are

``ā_k = T (a_k − o − b(t_k))``,   ``b(t_j) − b(t_k) ~ N(0, q |t_j − t_k| I₃)``,

``q = K²`` with ``K`` the rate-random-walk coefficient of the accelerometer's bias in raw units
per √s, the quantity ``optcal allan`` reports as ``K`` (its Allan deviation ``K √(τ/3)``;
IEEE Std 952-1997, annex C).  The walk starts at 0 at the first pose of each session (its start
is the offset ``o``), so ``cov(b(t_k), b(t_j)) = q (min(t_k, t_j) − t_0)`` within a session and 0
between sessions.

**Likelihood.**  Linearised about the current ``(T, o)``, the norm residual (Lu 2017, eq. 13)
moves with the bias as with the offset, ``∂r_k/∂b = −Tᵀ ā_k = h_k`` (eq. 16), so integrating the
walk out gives Gaussian residuals with covariance

``C = s² (W⁻¹ + λ (H Hᵀ ∘ B))``,   ``B_kj = min(t_k, t_j) − t_0``,  ``q = λ s²``,

where ``W⁻¹`` holds each pose's white-noise variance in g² (``(σ_k ‖h_k‖)²`` when the table has
``σ``, else 1) and ``s²`` is a free noise scale (profiled out: ``ŝ² = rᵀ V⁻¹ r / n``), so the
white noise is not assumed to be what ``σ/√n`` says.  For fixed ``λ`` the calibration is a
generalised least-squares problem, solved by Gauss–Newton from the baseline fit; ``λ`` is found
by maximising the profile likelihood ``−½ (n log ŝ² + log det V)`` over ``log λ``: a grid over
``log λ`` finds the lowest basin and a bounded minimisation refines it; a fit of most of the same
poses (a held-out fold) walks the grid downhill from the whole fit's lowest point instead
(``near``), the same grid point when the profile has one basin.  The walk is a Markov chain in
time, so ``V⁻¹``, ``log det V`` and the smoothed walk take one banded factorisation
(:mod:`optcal.core.chain_covariance`: the Kalman filter's likelihood and the Rauch–Tung–Striebel
smoother, exact): linear in the number of poses, 10⁴ poses included.

**Test of ``q = 0``.**  ``λ = 0`` is on the boundary of the parameter space, so the
likelihood-ratio statistic is distributed as ``½χ²₀ + ½χ²₁`` under the null (Self & Liang 1987,
case 5): ``p = ½ P(χ²₁ > LR)``.

**Smoothed bias.**  ``E[b(t_k) | r] = −q Σ_j B_kj h_j (C⁻¹ r)_j`` (a bias ``b`` moves the residual by ``−h_kᵀ b``: the
measurement contains it, the model subtracts it) and its variance, the bias track
the model hands back (the Rauch–Tung–Striebel smoother's result, computed densely).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize, stats

from optcal.core.chain_covariance import ChainCovariance, MarkovChain
from optcal.errors import InputError
from optcal.core.norm_residual import NormResidualKernel
from optcal.core.poses import PoseTable

#: Search range of ``log10 λ`` relative to the white-noise scale over the recording's duration.
LOG_LAMBDA_RANGE: tuple[float, float] = (-8.0, 8.0)
#: Gauss–Newton steps of the generalised least-squares fit at one ``λ``.
GN_STEPS: int = 8
#: Points of the ``log10 λ`` grid over :data:`LOG_LAMBDA_RANGE` (2/3 of a decade apart) that locates the
#: profile's lowest basin before the bounded minimisation refines it within one spacing either side.
GRID_POINTS: int = 25


@dataclass(frozen=True)
class RandomWalkBiasFit:
    """The calibration with a random-walk bias, its intensity and the bias track.

    Attributes
    ----------
    theta : ndarray, shape (9,)
        θ (lower-triangular ``T``, then ``o``) at the maximum likelihood.
    q : float
        Random-walk intensity ``K²`` in raw units² per second (0 when the walk is not supported).
    K : float
        ``√q``: raw units per √s (``optcal allan``'s rate random walk of the bias).
    K_interval : tuple of float
        95 % profile-likelihood interval of ``K`` (0 as the lower end when ``q = 0`` is inside).
    noise_scale : float
        ``ŝ``: the white pose noise relative to what the table's ``σ`` says (1 = as stated).
    log_likelihood, log_likelihood_white : float
        Profile log-likelihood at ``q̂`` and at ``q = 0``.
    lr_statistic, p_value : float
        Likelihood-ratio test of ``q = 0`` (boundary: ``½χ²₀ + ½χ²₁``, Self & Liang 1987).
    bias_track, bias_track_sd : ndarray, shape (n, 3)
        Smoothed ``b(t_k)`` and its standard deviation, raw units, in the table's pose order.  The
        deviation is conditional on ``theta`` (the calibration's own uncertainty is not in it):
        on simulated sessions 59–87 % of the planted walk lies within 3 of them, not 99.7 %.
    residuals : ndarray, shape (n,)
        Norm residuals at ``theta`` minus the smoothed bias's share (g).
    theta_white : ndarray, shape (9,)
        θ at ``q = 0`` (:meth:`RandomWalkBias.white_fit` of the same poses, bit for bit).
    lam_lowest : float
        ``λ = q / s²`` (raw units² per s over the white scale) where the profile was lowest, also when
        that is no better than ``q = 0`` (then ``q`` is 0): where a fit of a subset of these poses
        starts its search (``near`` of :meth:`RandomWalkBias.fit`).
    """

    theta: NDArray[np.float64]
    q: float
    K: float
    K_interval: tuple[float, float]
    noise_scale: float
    log_likelihood: float
    log_likelihood_white: float
    lr_statistic: float
    p_value: float
    bias_track: NDArray[np.float64]
    bias_track_sd: NDArray[np.float64]
    residuals: NDArray[np.float64]
    theta_white: NDArray[np.float64]
    lam_lowest: float

    @property
    def wander_rms(self) -> float:
        """RMS over the poses of the smoothed bias's departure from its mean, raw units (all axes)."""
        centred = self.bias_track - self.bias_track.mean(axis=0)
        return float(np.sqrt(np.mean(np.sum(centred**2, axis=1))))


def brownian_states(t: NDArray, session: NDArray) -> tuple[NDArray[np.intp], MarkovChain]:
    """The walk's states and their chain at unit intensity (``q = 1``).

    Each distinct time of a session after its first pose's time ``t_0`` is a state (poses recorded
    at the same time share it); poses at ``t_0`` see none (the walk is 0 there: its start is the
    offset).  Within a session ``x_{i+1} = x_i + √(t_{i+1} − t_i) ε``, the first state restarting
    with variance ``t_1 − t_0``: ``cov = min(t_k, t_j) − t_0`` (module docstring).

    Returns
    -------
    state : ndarray of int, shape (n,)
        The state of each pose (``−1`` at its session's start).
    chain : MarkovChain
    """
    t = np.asarray(t, dtype=float)
    session = np.asarray(session)
    order = np.lexsort((t, session))
    ts, ss = t[order], session[order]
    new_session = np.r_[True, ss[1:] != ss[:-1]]
    start = ts[new_session][np.cumsum(new_session) - 1]
    new_time = np.r_[True, new_session[1:] | (ts[1:] != ts[:-1])]
    group = np.cumsum(new_time) - 1  # distinct (session, time) of each pose in order
    g_time = ts[new_time]
    g_start = start[new_time]
    is_state = g_time != g_start
    state_of_group = np.where(is_state, np.cumsum(is_state) - 1, -1)
    # a state's predecessor is the previous time of its session (its start's group included: a restart)
    q = np.diff(g_time, prepend=np.nan)[is_state]
    restart = ~np.r_[False, is_state[:-1]]
    phi = np.where(restart[is_state][1:], 0.0, 1.0)
    state = np.empty(t.size, dtype=np.intp)
    state[order] = state_of_group[group]
    return state, MarkovChain(phi, q)


def _session_start(t: NDArray, session: NDArray) -> NDArray[np.float64]:
    """The first pose's time of each pose's session."""
    start = np.empty_like(t)
    for s in np.unique(session):
        start[session == s] = t[session == s].min()
    return start


def _brownian_covariance(t: NDArray, session: NDArray) -> NDArray[np.float64]:
    """``B_kj = min(t_k, t_j) − t_0`` within a session (its first pose's time ``t_0``), 0 between sessions (dense)."""
    state, chain = brownian_states(t, session)
    P = chain.covariance() if chain.size else np.zeros((0, 0))
    B = np.zeros((t.size, t.size))
    seen = state >= 0
    B[np.ix_(seen, seen)] = P[np.ix_(state[seen], state[seen])]
    return B


class RandomWalkBias:
    """Maximum-likelihood calibration with a bias that wanders as a random walk in time.

    Parameters
    ----------
    noise_scale : float or None
        The white pose noise relative to the table's ``σ``: ``None`` estimates it with the walk
        (profiled out); a number fixes it (1 when ``σ`` is trusted, or the factor measured on
        the recording's still parts).  With few poses the two are hard to tell apart: a walk
        whose steps are as large as the white noise explains white noise too, and the
        profiled likelihood then drifts toward a walk without white noise.  Fix it when it is known.
    """

    def __init__(self, noise_scale: float | None = None) -> None:
        if noise_scale is not None and not noise_scale > 0:
            raise InputError(f"noise_scale must be positive or None, not {noise_scale}")
        self.noise_scale = noise_scale

    # -- the pieces ---------------------------------------------------------------------------
    def _setup(self, poses: PoseTable, session: ArrayLike | None) -> tuple[NDArray, NDArray, NDArray]:
        if poses.t is None:
            raise InputError("a random-walk bias needs the poses' times: the pose table has no t column")
        n = poses.acc.shape[0]
        sess = np.zeros(n, dtype=int) if session is None else np.asarray(session, dtype=int)
        t = np.asarray(poses.t, dtype=float)
        sigma = np.ones(n) if poses.sigma is None else np.asarray(poses.sigma, dtype=float)
        return t, sess, sigma

    @staticmethod
    def _white_variance(point, sigma: NDArray, known: bool) -> NDArray[np.float64]:
        """Each pose's white-noise variance of the norm residual, g² (1 when ``σ`` is not known)."""
        return (sigma * point.normal_gain()) ** 2 if known else np.ones_like(sigma)

    def _gls(self, kernel: NormResidualKernel, theta: NDArray, lam: float, walk: tuple[NDArray, MarkovChain],
             sigma: NDArray, known: bool) -> tuple[NDArray, float, ChainCovariance, NDArray]:
        """Gauss–Newton GLS at fixed ``λ``: θ, the profile −2 log-likelihood, ``V`` and the residuals."""
        n = sigma.size
        for _ in range(GN_STEPS):
            point = kernel.at_theta(theta)
            V = self._covariance(point, lam, walk, sigma, known)
            J = point.jacobian().T  # (n, 9)
            r = point.residuals
            VX = V.solve(np.column_stack([J, r]))  # V⁻¹J and V⁻¹r from one solve
            step = np.linalg.solve(J.T @ VX[:, :9], -(J.T @ VX[:, 9]))
            if np.max(np.abs(step)) < 1e-12 * max(1.0, np.max(np.abs(theta + step))):
                # converged: θ is the fixed point to 1e-12 of itself, and V, r at θ are the ones just built
                # (the step would move it by < 1e-12 of itself: one factorisation and solve saved per λ)
                quad = float(r @ VX[:, 9])
                break
            theta = theta + step
        else:
            point = kernel.at_theta(theta)
            V = self._covariance(point, lam, walk, sigma, known)
            r = point.residuals
            quad = float(r @ V.solve(r))
        if self.noise_scale is not None:  # −2 log L with s² fixed (constant 2π terms dropped)
            s2 = self.noise_scale**2
            return theta, quad / s2 + n * np.log(s2) + V.logdet, V, r
        return theta, n * np.log(max(quad / n, 1e-300)) + V.logdet, V, r  # s² profiled: ŝ² = rᵀV⁻¹r / n

    def _covariance(self, point, lam: float, walk: tuple[NDArray, MarkovChain], sigma: NDArray,
                    known: bool) -> ChainCovariance:
        """``V = W⁻¹ + λ (H Hᵀ ∘ B)`` (module docstring), in linear time (:mod:`optcal.core.chain_covariance`).

        The walk is the chain's state; pose ``k`` sees it along ``−h_k`` (a bias ``b`` moves the
        residual by ``−h_kᵀ b``; Lu 2017, eq. 16), so the smoothed states are the bias itself.
        """
        state, chain = walk
        H = point.bias_jacobian()  # (3, n): ∂r_k/∂b (Lu 2017, eq. 16)
        return ChainCovariance(self._white_variance(point, sigma, known), -H.T, state,
                               chain.scaled(lam) if lam > 0 else None)

    def white_fit(self, poses: PoseTable, theta0: ArrayLike) -> NDArray[np.float64]:
        """θ of the calibration without a walk (``q = 0``: weighted least squares with the table's σ)."""
        t, sess, sigma = self._setup(poses, None)
        theta, _, _, _ = self._gls(NormResidualKernel(poses.acc), np.asarray(theta0, dtype=float).ravel()[:9], 0.0,
                                   brownian_states(t, sess), sigma, poses.sigma is not None)
        return theta

    # -- the fit --------------------------------------------------------------------------------
    def fit(self, poses: PoseTable, theta0: ArrayLike, session: ArrayLike | None = None,
            interval: bool = True, near: float | None = None) -> RandomWalkBiasFit:
        """Fit ``(T, o, q)`` by maximum likelihood with the walk integrated out.

        Parameters
        ----------
        poses : PoseTable
            Pose means with their times ``t`` (seconds) and, optionally, ``σ``.
        theta0 : array_like, shape (9,)
            The white-noise fit's θ (e.g. :class:`~optcal.families.accel.mle.MaximumLikelihood`;
            :func:`optcal.core.model.theta_from`), the start.
        session : array_like of int, optional
            Session of each pose (the walk restarts in each).
        interval : bool
            Compute ``K``'s profile-likelihood interval (``False``: ``(nan, nan)``; a held-out fold
            needs only the estimate).
        near : float, optional
            ``λ`` near which the profile's lowest point is expected (the :attr:`~RandomWalkBiasFit.lam_lowest` of
            a fit of a superset of these poses, e.g. the whole session for a held-out fold): the grid is
            walked downhill from the grid point nearest to it instead of evaluated everywhere.  It finds
            the same grid point as the whole grid when the profile has one basin along the grid (so
            the same estimate, to the bounded minimisation's tolerance); ``None`` evaluates the whole grid.
        """
        t, sess, sigma = self._setup(poses, session)
        known = poses.sigma is not None
        kernel = NormResidualKernel(poses.acc)
        walk = brownian_states(t, sess)
        span = float(np.max(t - _session_start(t, sess)))
        theta0 = np.asarray(theta0, dtype=float).ravel()[:9]
        # λ's natural unit: the white variance over the bias variance one raw unit² s⁻¹ gives in a session
        point0 = kernel.at_theta(theta0)
        white = float(np.median(self._white_variance(point0, sigma, known)))
        gain2 = float(np.median(np.sum(point0.bias_jacobian() ** 2, axis=0)))
        unit = white / (gain2 * max(span, 1e-12))
        theta_white, m2ll_white, _, _ = self._gls(kernel, theta0, 0.0, walk, sigma, known)

        cache: dict[float, tuple[NDArray, float]] = {}

        def profile(log_lam: float) -> float:
            if log_lam in cache:  # a grid point asked again (the interval's ends, K at its bounds)
                return cache[log_lam][1]
            # warm start from the nearest λ already solved (the profile is evaluated along log λ)
            start = cache[min(cache, key=lambda g: abs(g - log_lam))][0] if cache else theta_white
            th, m2ll, V, r = self._gls(kernel, start, unit * 10.0**log_lam, walk, sigma, known)
            cache[log_lam] = (th, m2ll)
            # K at this λ, with the noise scale profiled at it: q = λ ŝ²(λ)
            K_at[log_lam] = float(np.sqrt(unit * 10.0**log_lam * self._scale2(V, r)))
            return m2ll

        K_at: dict[float, float] = {}

        lo, hi = LOG_LAMBDA_RANGE
        grid = np.linspace(lo, hi, GRID_POINTS)
        values = np.full(grid.size, np.inf)  # +inf: not evaluated
        if near is None or not near > 0:
            values[:] = [profile(g) for g in grid]
            best = int(np.argmin(values))
        else:
            best = int(np.clip(np.rint((np.log10(near / unit) - lo) / (grid[1] - grid[0])), 0, grid.size - 1))
            values[best] = profile(grid[best])
            while True:  # downhill along the grid to its nearest local minimum
                for j in (best - 1, best + 1):
                    if 0 <= j < grid.size and values[j] == np.inf:
                        values[j] = profile(grid[j])
                lower = best - 1 if best > 0 and values[best - 1] < values[best] else best
                lower = best + 1 if best + 1 < grid.size and values[best + 1] < values[lower] else lower
                if lower == best:
                    break
                best = lower
        lam_lowest = unit * 10.0 ** float(grid[best])
        if values[best] < m2ll_white:
            a, b = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
            res = optimize.minimize_scalar(profile, bounds=(a, b), method="bounded", options={"xatol": 1e-4})
            log_lam = float(res.x) if res.fun <= values[best] else float(grid[best])
            theta, m2ll = cache[log_lam]
            lam = lam_lowest = unit * 10.0**log_lam
        else:
            theta, m2ll, lam, log_lam = theta_white, m2ll_white, 0.0, None
        lr = max(m2ll_white - m2ll, 0.0)
        p = 0.5 * float(stats.chi2.sf(lr, 1)) if lr > 0 else 1.0  # Self & Liang 1987: ½χ²₀ + ½χ²₁

        # the smoothed walk and the noise scale at the optimum (the chain's states are the bias / s)
        point = kernel.at_theta(theta)
        V = self._covariance(point, lam, walk, sigma, known)
        r = point.residuals
        n = r.size
        s2 = self._scale2(V, r)
        q = lam * s2
        H = point.bias_jacobian()  # (3, n)
        track = np.zeros((n, 3))
        sd = np.zeros((n, 3))
        if q > 0:
            state = walk[0]
            seen = state >= 0
            track[seen] = V.state_mean(r)[state[seen]]  # E[b_k | r] (s² cancels)
            sd[seen] = np.sqrt(np.clip(s2 * V.state_variance()[state[seen]], 0.0, None))
        residuals = r + np.einsum("ik,ki->k", H, track)  # the walk's share −h_kᵀ b_k taken out
        bounds = self._interval(profile, K_at, m2ll, log_lam, m2ll_white) if interval else (float("nan"), float("nan"))
        return RandomWalkBiasFit(
            theta=theta, q=q, K=float(np.sqrt(q)), K_interval=bounds, noise_scale=float(np.sqrt(s2)),
            log_likelihood=-0.5 * m2ll, log_likelihood_white=-0.5 * m2ll_white, lr_statistic=lr, p_value=p,
            bias_track=track, bias_track_sd=sd, residuals=residuals, theta_white=theta_white, lam_lowest=lam_lowest,
        )

    def _scale2(self, V: ChainCovariance, r: NDArray) -> float:
        """``s²``: fixed, or profiled (``rᵀ V⁻¹ r / n``)."""
        if self.noise_scale is not None:
            return self.noise_scale**2
        return float(r @ V.solve(r)) / r.size

    @staticmethod
    def _interval(profile, K_at: dict[float, float], m2ll: float, log_lam: float | None,
                  m2ll_white: float) -> tuple[float, float]:
        """95 % profile-likelihood interval of ``K`` (−2 log-likelihood within χ²₁(0.95) of the optimum)."""
        level = m2ll + float(stats.chi2.ppf(0.95, 1))
        lo, hi = LOG_LAMBDA_RANGE

        def to_K(g: float) -> float:
            profile(g)
            return K_at[g]

        centre = lo if log_lam is None else log_lam
        upper = hi
        if profile(hi) > level:
            upper = optimize.brentq(lambda g: profile(g) - level, centre, hi, xtol=1e-3)
        if m2ll_white <= level:
            return 0.0, to_K(upper)
        lower = optimize.brentq(lambda g: profile(g) - level, lo, centre, xtol=1e-3) if profile(lo) > level else lo
        return to_K(lower), to_K(upper)

    def predict_heldout(self, train: PoseTable, test: PoseTable, fit: RandomWalkBiasFit,
                        session_train: ArrayLike | None = None,
                        session_test: ArrayLike | None = None) -> NDArray[np.float64]:
        """Norm residuals of held-out poses after the bias the training poses predict for them (g).

        The walk at a held-out time is predicted from the training residuals (the conditional
        mean of a Gaussian process: ``E[h_hᵀ b(t_h) | r_train]``), then subtracted.
        """
        t_tr, s_tr, sig_tr = self._setup(train, session_train)
        t_te, s_te, _ = self._setup(test, session_test)
        known = train.sigma is not None
        n = t_tr.size
        p_tr = NormResidualKernel(train.acc).at_theta(fit.theta)
        p_te = NormResidualKernel(test.acc).at_theta(fit.theta)
        if fit.q <= 0:
            return p_te.residuals
        # one chain over the training and the held-out times; the held-out poses' states are seen by no
        # residual and are predicted from their neighbours (E[b(t_h) | r_train], a Brownian bridge)
        state, chain = brownian_states(np.concatenate([t_tr, t_te]), np.concatenate([s_tr, s_te]))
        V = self._covariance(p_tr, fit.q / fit.noise_scale**2, (state[:n], chain), sig_tr, known)
        mean = V.state_mean(p_tr.residuals)
        held = state[n:]
        if mean.shape[0] == 0:  # no state after the sessions' starts: the walk is 0 at every held-out pose
            return p_te.residuals
        bias = np.where((held >= 0)[:, None], mean[np.maximum(held, 0)], 0.0)
        return p_te.residuals + np.einsum("ik,ki->k", p_te.bias_jacobian(), bias)  # the walk's share −h·b out


__all__ = ["RandomWalkBias", "RandomWalkBiasFit", "brownian_states"]
