"""Solver comparison: Cramér–Rao efficiency, speed against the baseline and scipy, scaling.

Every estimator of optcal, and scipy's ``least_squares``, on the same simulated data:

* **Efficiency** — per parameter θ_i, ``MSE_i / CRLB_i`` with the Cramér–Rao bound of
  :func:`optcal.core.identifiability.cramer_rao_bound` (gravity directions as nuisance
  parameters); ``efficiency`` = ``Σ_i MSE_i / Σ_i CRLB_i`` ("summed over parameters"), also
  the bias of each parameter in units of its bound, iterations, time and failures.
* **Designs** — the Table 1 setup of Lu 2017 (the tilted sweeps, 120 poses, 5 mg, see
  :mod:`optcal.applications.papers.lu2017`), random designs (directions uniform on the sphere, fixed
  per design point), and sweeps of the number of poses, the noise, the coverage (spherical
  caps) and the distortion of the sensor (Lu's scale and non-orthogonality errors times a
  factor).
* **Speed to the same cost** — from the same start (the SVD fit), with the same weights,
  on the same normalised cost ``f(θ) = Σ w_k r_k(θ)²``: IPOPT's solve in the ``mle``
  problem (built once) against the paper's gradient descent run until
  ``f ≤ f*·(1 + ε)`` (ε = 1e-9, and 1e-12) and against scipy's ``least_squares`` (LM and
  TRF, analytic Jacobian from the same numpy evaluator).  Solvers are interleaved run by
  run and each is timed three times in a row on each run's data (best kept), so a busy
  machine slows every solver alike; the figure is the median over runs of the per-run ratio.
* **Throughput** — complete ``mle`` fits per second (validation, convex start, reweighting,
  covariance and identifiability included) with the problems built once: batched, many units
  per IPOPT problem (:mod:`optcal.families.accel.batched`, the headline ``throughput_fits_per_s``),
  and one at a time (``throughput_single_fits_per_s``).
* **Large** — one ``calibrate(poses, method="mle")`` on 10⁶ poses.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import click
import numpy as np
from numpy.typing import NDArray

from optcal.errors import ConvergenceWarning, OptcalError
from optcal.families.accel.base import Normaliser
from optcal.families.accel.ellipsoid import ConvexEllipsoidFit, SVDEllipsoidFit
from optcal.families.accel.exact import ExactMaximumLikelihood
from optcal.families.accel.gradient_descent import GradientDescent, descend
from optcal.families.accel.mle import MaximumLikelihood, MLProblem, NormResidualCost
from optcal.families.accel.result import CalibrationResult
from optcal.families.accel.scipy_ls import ScipyLeastSquares, solve_least_squares
from optcal.core.identifiability import analyse_design, cramer_rao_bound
from optcal.core.model import PARAM_NAMES, LumpedModel, lu2017_reference_model, unpack_theta
from optcal.core.poses import PoseTable
from optcal.applications.papers.command_output import show_progress
from optcal.applications.papers.solver_profiles import distorted_model, format_profile
from optcal.applications.papers.solver_profiles import run as run_profiles
from optcal.core.jsonio import json_text, jsonable
from optcal.families.simulate.poses import cap_directions, simulate_poses, tilted_sweeps, uniform_directions

#: Gradient-descent iteration limit in the studies (a run that reaches it counts as a failure).
GD_MAX_ITER = 20_000

#: method name -> estimator factory (keyword settings go to the constructor).  Every estimator
#: at its defaults, except gd's iteration limit.
ESTIMATORS: dict[str, Callable[..., Any]] = {
    "svd": lambda **s: SVDEllipsoidFit(**s),
    "convex-clarabel": lambda **s: ConvexEllipsoidFit(solver="CLARABEL", **s),
    "convex-scs": lambda **s: ConvexEllipsoidFit(solver="SCS", **s),
    "mle": lambda **s: MaximumLikelihood(**s),
    "exact": lambda **s: ExactMaximumLikelihood(**s),
    "gd": lambda **s: GradientDescent(max_iter=GD_MAX_ITER, **s),
    "scipy-lm": lambda **s: ScipyLeastSquares("lm", **s),
    "scipy-trf": lambda **s: ScipyLeastSquares("trf", **s),
}
ALL_METHODS = tuple(ESTIMATORS)
#: gd's relative cost targets for the speed comparison (f ≤ f*·(1 + ε)).
GD_TARGETS = (1e-9, 1e-12)


def _progress(iterable: Any, desc: str, progress: bool, total: int | None = None) -> Any:
    from tqdm import tqdm

    return tqdm(iterable, desc=desc, disable=not progress, total=total, leave=False)


def mle_standard_errors(result: CalibrationResult) -> NDArray[np.float64]:
    """Standard errors ``sqrt(diag Σ)`` of the parameters of an ``mle`` fit."""
    # An mle result always carries the inverse Fisher information as its covariance
    # (families.accel.base.finish): None here would be a bug, not a data problem.
    if result.covariance is None:
        raise RuntimeError("an mle calibration result without a covariance")
    return np.sqrt(np.diag(result.covariance))


@dataclass
class Design:
    """A simulation setting: sensor, true directions, noise per pose (g)."""

    label: str
    model: LumpedModel
    directions: NDArray[np.float64]
    sigma: float

    def poses(self, seed: int, run: int) -> PoseTable:
        return simulate_poses(self.model, self.directions, self.sigma, rng=np.random.default_rng([seed, 7, run]))

    def crlb(self) -> NDArray[np.float64]:
        return cramer_rao_bound(self.model, self.directions, self.sigma)


def monte_carlo(design: Design, methods: tuple[str, ...], runs: int, seed: int, progress: bool = True,
                settings: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """Every method on the same ``runs`` noisy pose tables of one design.

    A failure is an exception of optcal (no ellipsoid, unidentifiable answer, solver error)
    or a solver that does not report convergence; failed runs are left out of the MSE.
    ``mle`` at its defaults fits all runs together (:class:`~optcal.families.accel.batched.BatchedMaximumLikelihood`,
    equal to one-at-a-time fits to the solver tolerance): its time per run is the batch's time
    divided by the runs, its iterations those of the shared IPOPT problems.
    """
    truth = design.model.theta
    crlb = np.diag(design.crlb())
    errors: dict[str, list[NDArray]] = {m: [] for m in methods}
    times: dict[str, list[float]] = {m: [] for m in methods}
    iters: dict[str, list[int]] = {m: [] for m in methods}
    failures: dict[str, dict[str, int]] = {m: {} for m in methods}
    estimators = {m: ESTIMATORS[m](**(settings or {}).get(m, {})) for m in methods}
    one_at_a_time = list(methods)
    if "mle" in methods and not (settings or {}).get("mle") and _batched_monte_carlo(design, runs, seed, truth,
                                                                                       errors, times, iters, failures):
        one_at_a_time.remove("mle")
    for run in _progress(range(runs), design.label, progress):
        poses = design.poses(seed, run)
        for m in one_at_a_time:
            t0 = time.perf_counter()
            try:
                with warnings.catch_warnings():  # a run that does not converge is counted below
                    warnings.simplefilter("ignore", ConvergenceWarning)
                    res = estimators[m].fit(poses)
            except OptcalError as exc:
                key = type(exc).__name__
                failures[m][key] = failures[m].get(key, 0) + 1
                continue
            elapsed = time.perf_counter() - t0
            if not res.solver.success:
                key = f"not converged ({res.solver.status})"
                failures[m][key] = failures[m].get(key, 0) + 1
                continue
            errors[m].append(res.params[:9] - truth)
            times[m].append(elapsed)
            iters[m].append(res.solver.iterations)
    out: dict[str, Any] = {}
    for m in methods:
        e = np.array(errors[m])
        n_fail = sum(failures[m].values())
        entry: dict[str, Any] = {"runs": len(e), "failures": n_fail, "failure_reasons": failures[m]}
        if len(e):
            mse = np.mean(e**2, axis=0)
            bias = np.mean(e, axis=0)
            entry.update(
                {
                    "efficiency": float(np.sum(mse) / np.sum(crlb)),
                    "mse_over_crlb": dict(zip(PARAM_NAMES, mse / crlb)),
                    "mean_mse_over_crlb": float(np.mean(mse / crlb)),
                    "bias_over_crlb_sd": dict(zip(PARAM_NAMES, bias / np.sqrt(crlb))),
                    "max_abs_bias_over_crlb_sd": float(np.max(np.abs(bias / np.sqrt(crlb)))),
                    "median_time_s": float(np.median(times[m])),
                    "median_iterations": float(np.median(iters[m])),
                }
            )
        out[m] = entry
    return {
        "design": design.label,
        "n_poses": int(len(design.directions)),
        "sigma_g": design.sigma,
        "runs": runs,
        "fisher_condition_number": analyse_design(design.model, design.directions).condition_number,
        "crlb_sd": dict(zip(PARAM_NAMES, np.sqrt(crlb))),
        "mc_relative_se_of_mse": float(np.sqrt(2.0 / max(runs, 1))),
        "methods": out,
    }


def _batched_monte_carlo(design: Design, runs: int, seed: int, truth: NDArray, errors: dict[str, list[NDArray]],
                         times: dict[str, list[float]], iters: dict[str, list[int]],
                         failures: dict[str, dict[str, int]]) -> bool:
    """The default ``mle`` of every run of :func:`monte_carlo` in batched IPOPT problems (its bookkeeping).

    A run whose poses do not identify θ counts as an ``IdentifiabilityError`` (``mle`` refuses
    it), a problem that does not report success as not converged.  Returns False (nothing
    recorded) when the batch refuses the tables, so that the runs are fitted one at a time.
    """
    from optcal.families.accel.batched import BatchedMaximumLikelihood

    tables = [design.poses(seed, run) for run in range(runs)]
    t0 = time.perf_counter()
    try:
        fit = BatchedMaximumLikelihood().fit_many(tables)
    except OptcalError:
        return False
    per_run = (time.perf_counter() - t0) / max(runs, 1)
    for k in range(runs):
        reason = ("IdentifiabilityError" if not fit.identifiable[k]
                  else None if fit.success[k] else "not converged (batched IPOPT)")
        if reason:
            failures["mle"][reason] = failures["mle"].get(reason, 0) + 1
            continue
        errors["mle"].append(fit.theta[k] - truth)
        times["mle"].append(per_run)
        iters["mle"].append(int(fit.iterations[k]))
    return True


def table1_design(sigma: float = 0.005) -> Design:
    """Lu 2017 Table 1: the paper's sensor, three tilted sweeps of 40 poses (see lu2017)."""
    return Design("Table 1 (tilted sweeps, 120 poses)", lu2017_reference_model(), tilted_sweeps(40), sigma)


def uniform_design(n: int, sigma: float, seed: int, model: LumpedModel | None = None, label: str | None = None) -> Design:
    """``n`` directions uniform on the sphere (one fixed draw per design point)."""
    d = uniform_directions(n, np.random.default_rng([seed, 3, n]))
    return Design(label or f"uniform, {n} poses, {sigma * 1e3:g} mg", model or lu2017_reference_model(), d, sigma)


# --------------------------------------------------------------------------- speed


def _median_ratio(num: list[float], den: list[float]) -> float:
    return float(np.median(np.asarray(num) / np.asarray(den)))


def _best_of(repeats: int, fn: Callable[[], Any]) -> tuple[float, Any]:
    """Smallest wall time of ``repeats`` calls (as :mod:`timeit` advises) and the last result."""
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def comparison_start(poses: PoseTable) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The common ground of the speed comparison: normalised data ``u``, the propagated weights
    at the SVD start (scaled to mean 1) and that start θ₀, so that every solver minimises the
    same cost from the same point."""
    ml = MaximumLikelihood(init="svd")
    norm = Normaliser.of(poses.acc)
    u = norm.forward(poses.acc)
    theta0, _ = ml.initial_normalised(poses, norm, u)
    w = ml.weights(poses, norm, u, theta0)
    return u, w / np.mean(w), theta0


def speed_to_same_cost(design: Design, runs: int, seed: int, progress: bool = True, repeats: int = 3) -> dict[str, Any]:
    """IPOPT (the ``mle`` problem) against gradient descent and scipy, same start, weights, cost.

    Each solver is timed ``repeats`` times in a row on each run's data and its best time kept,
    so that a passing disturbance (other jobs, BLAS threads of the previous solver) does not
    land on one solver only.
    """
    times: dict[str, list[float]] = {"mle": [], "scipy-lm": [], "scipy-trf": []}
    times.update({f"gd_{eps:g}": [] for eps in GD_TARGETS})
    iters: dict[str, list[int]] = {k: [] for k in times}
    gaps: dict[str, list[float]] = {k: [] for k in times}
    gd_failures = 0
    problem = MLProblem.get(len(design.directions))
    for run in _progress(range(runs), f"speed: {design.label}", progress):
        poses = design.poses(seed, 1000 + run)
        u, w, theta0 = comparison_start(poses)
        cost = NormResidualCost(u, w)
        elapsed, (x_ml, stats) = _best_of(repeats, lambda: problem.solve(theta0, u, w))
        times["mle"].append(elapsed)
        iters["mle"].append(int(stats["iter_count"]))
        f_star = cost.value(x_ml)
        gaps["mle"].append(0.0)
        T_n, o_n = unpack_theta(theta0)
        x_gd0 = np.concatenate([T_n.ravel(), o_n])
        mu = GradientDescent.auto_step(x_gd0, u, w)
        for eps in GD_TARGETS:
            key = f"gd_{eps:g}"
            elapsed, (_, f, it, status) = _best_of(
                repeats, lambda: descend(x_gd0, u, w, mu, 0.0, 200_000, f_star * (1 + eps))  # noqa: B023
            )
            times[key].append(elapsed)
            iters[key].append(it)
            gaps[key].append(f / f_star - 1)
            gd_failures += status != "converged"
        for method in ("lm", "trf"):
            key = f"scipy-{method}"
            elapsed, (x, res) = _best_of(repeats, lambda: solve_least_squares(theta0, u, w, method))  # noqa: B023
            times[key].append(elapsed)
            iters[key].append(int(res.nfev))
            gaps[key].append(cost.value(x) / f_star - 1)
    scipy_best = min(("scipy-lm", "scipy-trf"), key=lambda k: np.median(times[k]))
    return {
        "design": design.label,
        "n_poses": int(len(design.directions)),
        "runs": runs,
        "repeats": repeats,
        "median_time_s": {k: float(np.median(v)) for k, v in times.items()},
        "median_iterations": {k: float(np.median(v)) for k, v in iters.items()},
        "max_relative_cost_gap": {k: float(np.max(v)) for k, v in gaps.items()},
        "gd_failures": int(gd_failures),
        "speedup_vs_gd": {f"{eps:g}": _median_ratio(times[f"gd_{eps:g}"], times["mle"]) for eps in GD_TARGETS},
        "speedup_vs_scipy": {k: _median_ratio(times[k], times["mle"]) for k in ("scipy-lm", "scipy-trf")},
        "fastest_scipy": scipy_best,
    }


def throughput(design: Design, fits: int, seed: int, progress: bool = True, batched_fits: int | None = None) -> dict[str, Any]:
    """Complete default ``mle`` fits per second on pre-simulated tables, one at a time and batched.

    One at a time: ``MaximumLikelihood().fit`` per table, problem built once.  Batched:
    :class:`~optcal.families.accel.batched.BatchedMaximumLikelihood` on ``batched_fits`` tables
    (10 × ``fits`` by default; its problems built by a first call on the same tables), the
    figure ``throughput_fits_per_s`` of the study.  Both are complete fits (validation, convex
    start, weights re-propagated until they settle, covariance, identifiability); the largest
    difference between the two on the common tables is reported in standard errors.  Rates per
    second of wall time and per second of the process's CPU time (``fits_per_cpu_s``: what one
    core gives when the machine is shared).
    """
    from optcal.families.accel.batched import BatchedMaximumLikelihood
    from optcal.core.identifiability import parameter_full_scale

    n_batched = batched_fits or 10 * fits
    tables = [design.poses(seed, 5000 + k) for k in range(max(fits, n_batched))]
    estimator = MaximumLikelihood()
    estimator.fit(tables[0])  # builds (or fetches) the problem
    singles = []
    t0, c0 = time.perf_counter(), time.process_time()
    for poses in _progress(tables[:fits], "throughput", progress):
        singles.append(estimator.fit(poses))
    elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0
    batched = BatchedMaximumLikelihood()
    batched.fit_many(tables[:n_batched])  # builds the problems of every batch size it meets
    t0, c0 = time.perf_counter(), time.process_time()
    fit = batched.fit_many(tables[:n_batched])
    elapsed_b, cpu_b = time.perf_counter() - t0, time.process_time() - c0
    deviation = max(float(np.max(np.abs(fit.theta[k] - r.params[:9]) / mle_standard_errors(r)))
                    for k, r in enumerate(singles))
    full_scale = max(float(np.max(np.abs(fit.theta[k] - r.params[:9]) / parameter_full_scale(r.params[:9])))
                     for k, r in enumerate(singles))
    stderr_rel = max(float(np.max(np.abs(fit.stderr[k] / mle_standard_errors(r) - 1.0)))
                     for k, r in enumerate(singles))
    return {"design": design.label, "fits": fits, "seconds": elapsed, "fits_per_s": fits / elapsed,
            "fits_per_cpu_s": fits / cpu,
            "batched": {"fits": n_batched, "seconds": elapsed_b, "fits_per_s": n_batched / elapsed_b,
                        "fits_per_cpu_s": n_batched / cpu_b,
                        "batch": batched.batch, "max_deviation_from_single_in_stderr": deviation,
                        "max_deviation_from_single_full_scale": full_scale,
                        "max_stderr_relative_difference": stderr_rel}}



def large(n: int, seed: int) -> dict[str, Any]:
    """One ``mle`` calibration of ``n`` poses (uniform directions, 5 mg), after a warm-up fit."""
    from optcal.families.accel.calibration import calibrate

    model = lu2017_reference_model()
    calibrate(uniform_design(20_000, 0.005, seed).poses(seed, 0), method="mle")  # imports, problem
    design = uniform_design(n, 0.005, seed)
    poses = design.poses(seed, 1)
    t0 = time.perf_counter()
    res = calibrate(poses, method="mle")
    elapsed = time.perf_counter() - t0
    sd = mle_standard_errors(res)
    return {
        "n_poses": n,
        "mle_s": elapsed,
        "ipopt_s": res.solver.solve_time_s,
        "iterations": res.solver.iterations,
        "status": res.solver.status,
        "max_abs_error_over_stderr": float(np.max(np.abs(res.params[:9] - model.theta) / sd)),
    }


# --------------------------------------------------------------------------- the study


@dataclass(frozen=True)
class Plan:
    """Sizes of the study (full or quick)."""

    runs: int
    efficiency_runs: int
    speed_runs: int
    throughput_fits: int
    large_n: int
    speed_large_n: tuple[int, ...]
    n_poses: tuple[int, ...]
    noise_mg: tuple[float, ...]
    caps_deg: tuple[float, ...]
    distortion: tuple[float, ...]
    coverage_noise_mg: tuple[float, ...]
    coverage_runs: int

    @classmethod
    def make(cls, quick: bool, runs: int | None) -> "Plan":
        if quick:
            r = runs or 20
            return cls(r, max(r, 50), r, 100, 100_000, (100_000,), (10, 100, 1000), (1.0, 10.0, 50.0), (180.0, 60.0, 30.0),
                       (0.0, 1.0, 2.0), (1.0, 20.0), r)
        r = runs or 200
        return cls(r, max(r, 500), r, 500, 1_000_000, (100_000, 1_000_000), (10, 30, 100, 300, 1000, 3000, 10000),
                   (0.1, 1.0, 5.0, 10.0, 20.0, 50.0), (180.0, 120.0, 90.0, 60.0, 45.0, 30.0),
                   (0.0, 0.5, 1.0, 2.0, 3.0), (1.0, 5.0, 20.0, 50.0), max(r // 6, 10))


#: Methods of the sweeps (SCS and TRF only in the Table 1 comparison).  ``exact`` runs at every
#: size of the sweep: its NLP has 9 + 3n variables, built in ~5 s for 10⁴ poses.
SWEEP_METHODS = ("svd", "convex-clarabel", "mle", "exact", "gd", "scipy-lm")
EXACT_MAX_POSES = 10_000


def run(quick: bool = False, runs: int | None = None, seed: int = 0, progress: bool = True,
        profile_solvers: list[str] | None = None) -> dict[str, Any]:
    """The whole study; returns a JSON-safe dict (see the module docstring).

    ``performance_profile`` is every installed NLP solver on the instance library of
    :mod:`optcal.applications.papers.solver_profiles` (``profile_solvers`` to name them; the
    quick mode's :data:`~optcal.applications.papers.solver_profiles.QUICK_SOLVERS` otherwise).
    """
    plan = Plan.make(quick, runs)
    t_start = time.perf_counter()
    profiles = run_profiles(quick=quick, seed=seed, solvers=profile_solvers, progress=progress)
    experiments: dict[str, Any] = {}
    experiments["table1"] = monte_carlo(table1_design(), ALL_METHODS, plan.runs, seed, progress)
    eff_design = uniform_design(140, 0.010, seed, label="uniform, 140 poses, 10 mg")
    experiments["efficiency_140_10mg"] = monte_carlo(
        eff_design, ("svd", "convex-clarabel", "mle", "exact", "scipy-lm"), plan.efficiency_runs, seed, progress
    )
    experiments["poses"] = [
        monte_carlo(uniform_design(n, 0.005, seed), tuple(m for m in SWEEP_METHODS if m != "exact" or n <= EXACT_MAX_POSES),
                    plan.runs if n <= 1000 else max(plan.runs // 5, 5), seed, progress)
        for n in plan.n_poses
    ]
    experiments["noise"] = [monte_carlo(uniform_design(120, s / 1e3, seed), SWEEP_METHODS, plan.runs, seed, progress)
                            for s in plan.noise_mg]
    experiments["distortion"] = [
        monte_carlo(uniform_design(120, 0.005, seed, distorted_model(k), f"distortion ×{k:g}, uniform, 120 poses, 5 mg"),
                    SWEEP_METHODS, plan.runs, seed, progress)
        for k in plan.distortion
    ]
    # coverage: caps about z; every fit may return a degenerate answer (allow_degenerate) so that
    # "failure" means no calibration at all (svd: not an ellipsoid) or a solver that did not converge
    degenerate_ok = {m: {"allow_degenerate": True} for m in ("svd", "convex-clarabel", "mle")}
    experiments["coverage"] = [
        monte_carlo(
            Design(f"cap {cap:g}°, 120 poses, {s:g} mg", lu2017_reference_model(),
                   cap_directions(120, cap, np.random.default_rng([seed, 4, int(cap)])), s / 1e3),
            ("svd", "convex-clarabel", "mle"), plan.coverage_runs, seed, progress, degenerate_ok,
        )
        for cap in plan.caps_deg
        for s in plan.coverage_noise_mg
    ]
    speed = [speed_to_same_cost(table1_design(), plan.speed_runs, seed, progress)]
    hemisphere = Design("hemisphere (90° cap), 120 poses, 1 mg", lu2017_reference_model(),
                        cap_directions(120, 90.0, np.random.default_rng([seed, 4, 90])), 0.001)
    # the larger designs: a quarter of the runs, at least 5 -- never more than --runs asked for
    speed += [speed_to_same_cost(d, max(plan.speed_runs // 4, min(5, plan.speed_runs)), seed, progress)
              for d in (uniform_design(1000, 0.005, seed), uniform_design(10000, 0.005, seed), hemisphere)]
    # large n: the data term dominates IPOPT's fixed cost (a few runs, each solver timed once)
    speed += [speed_to_same_cost(uniform_design(n, 0.005, seed), min(3, plan.speed_runs), seed, progress, repeats=1)
              for n in plan.speed_large_n]
    largest = max((s for s in speed if s["design"].startswith("uniform")), key=lambda s: s["n_poses"])
    thr = throughput(table1_design(), plan.throughput_fits, seed, progress)
    big = large(plan.large_n, seed)
    headline = speed[0]
    return jsonable(
        {
            "issue": "solver comparison: Cramér–Rao efficiency, speed, scaling",
            "quick": quick,
            "seed": seed,
            "efficiency": {m: r.get("efficiency") for m, r in experiments["efficiency_140_10mg"]["methods"].items()},
            "efficiency_table1": {m: r.get("efficiency") for m, r in experiments["table1"]["methods"].items()},
            "speedup": {
                "mle_vs_gd": headline["speedup_vs_gd"]["1e-09"],
                "mle_vs_scipy": headline["speedup_vs_scipy"][headline["fastest_scipy"]],
                "design": headline["design"],
                "gd_target": "f ≤ f*·(1 + 1e-9)",
                "scipy_method": headline["fastest_scipy"],
            },
            "speedup_large": {
                "n_poses": largest["n_poses"],
                "mle_vs_gd": largest["speedup_vs_gd"]["1e-09"],
                "mle_vs_scipy": largest["speedup_vs_scipy"][largest["fastest_scipy"]],
                "scipy_method": largest["fastest_scipy"],
            },
            "throughput_fits_per_s": thr["batched"]["fits_per_s"],
            "throughput_single_fits_per_s": thr["fits_per_s"],
            "throughput_fits_per_cpu_s": thr["batched"]["fits_per_cpu_s"],
            "throughput_max_deviation_full_scale": thr["batched"]["max_deviation_from_single_full_scale"],
            "large": {"n_poses": big["n_poses"], "mle_s": big["mle_s"]},
            "performance_profile": profiles,
            "details": {"experiments": experiments, "speed": speed, "throughput": thr, "large": big},
            "runtime_s": time.perf_counter() - t_start,
        }
    )


def format_report(res: dict[str, Any]) -> str:
    """The headline figures as readable text."""
    d = res["details"]
    lines = ["Solver comparison" + (" — quick run" if res["quick"] else ""), ""]
    eff = d["experiments"]["efficiency_140_10mg"]
    lines.append(f"Efficiency Σ MSE / Σ CRLB, {eff['design']}, {eff['runs']} runs:")
    lines += [f"  {m:<16s} {v:8.3f}" if v is not None else f"  {m:<16s}   failed" for m, v in res["efficiency"].items()]
    t1 = d["experiments"]["table1"]
    lines += ["", f"Table 1 design, {t1['runs']} runs:",
              f"  {'method':<16s} {'ΣMSE/ΣCRLB':>10s} {'max|bias|/sd':>12s} {'median t':>10s} {'iters':>7s} {'fail':>5s}"]
    for m, r in t1["methods"].items():
        if "efficiency" not in r:
            lines.append(f"  {m:<16s} all runs failed: {r['failure_reasons']}")
            continue
        lines.append(f"  {m:<16s} {r['efficiency']:10.3f} {r['max_abs_bias_over_crlb_sd']:12.3f} "
                     f"{r['median_time_s'] * 1e3:8.2f}ms {r['median_iterations']:7.0f} {r['failures']:5d}")
    lines += ["", "Speed to the same cost (median of per-run ratios):"]
    for s in d["speed"]:
        lines.append(f"  {s['design']}: mle {s['median_time_s']['mle'] * 1e3:.2f} ms; "
                     f"gd ×{s['speedup_vs_gd']['1e-09']:.1f} (ε=1e-9), ×{s['speedup_vs_gd']['1e-12']:.1f} (ε=1e-12); "
                     f"scipy LM ×{s['speedup_vs_scipy']['scipy-lm']:.2f}, TRF ×{s['speedup_vs_scipy']['scipy-trf']:.2f}")
    big = res["speedup_large"]
    lines += [f"  largest design, {big['n_poses']} poses: mle vs gd ×{big['mle_vs_gd']:.1f} (ε=1e-9), "
              f"vs {big['scipy_method']} ×{big['mle_vs_scipy']:.2f}"]
    lines += ["", f"Throughput: {res['throughput_fits_per_s']:.0f} complete mle fits per second batched "
              f"({res['throughput_single_fits_per_s']:.0f} one at a time; equal to within "
              f"{res['throughput_max_deviation_full_scale']:.1e} of full scale)",
              f"Large: {res['large']['n_poses']} poses through mle in {res['large']['mle_s']:.2f} s",
              "", format_profile(res["performance_profile"]),
              f"runtime {res['runtime_s']:.0f} s"]
    return "\n".join(lines)


@click.command("solvers")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--quick", is_flag=True, help="A smaller run (fewer runs, shorter sweeps, 10⁵ poses for 'large').")
@click.option("--runs", type=click.IntRange(1), default=None, help="Monte Carlo runs per design point [200; quick 20].")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--profile-solvers", default=None, metavar="LIST",
              help="NLP solvers of the performance profiles, comma-separated [every installed one; quick: "
                   "ipopt, sqpmethod, sqpmethod+osqp, fatrop, uno].")
def command(as_json: bool, quick: bool, runs: int | None, seed: int, profile_solvers: str | None) -> None:
    """Solver comparison: Cramér–Rao efficiency, speed against gd and scipy, scaling to 10⁶ poses; every
    installed NLP solver on an instance library (performance profiles)."""
    from optcal.solvers.registry import choose_nlp_solver

    names = None
    if profile_solvers:
        names = [n.strip().lower() for n in profile_solvers.split(",") if n.strip()]
        for name in names:
            choose_nlp_solver(name)  # refused in one line, naming those that run
    res = run(quick=quick, runs=runs, seed=seed, progress=show_progress(), profile_solvers=names)
    if as_json:
        click.echo(json_text(res))
    else:
        click.echo(format_report(res))
