"""Every installed solver on one formulation: an instance library and Dolan–Moré performance profiles.

The estimator study (:mod:`optcal.applications.papers.solver_study`) compares estimators; this
one compares *solvers* on the same problem.  Each instance is the norm-residual
maximum-likelihood NLP of :func:`optcal.problems.norm_residual_ml` (Lu 2017, eq. 13-14; its
first pass, from the convex start, with the loss the instance asks for) and every NLP solver
of the catalogue that runs here (:func:`optcal.solvers.registry.available_nlp_solvers`) solves
it from the same start; the convex fit of the same poses is solved by every suited cvxpy solver.

* **Instances** — synthetic designs varying one factor at a time about a base (Lu 2017's sensor,
  120 poses uniform on the sphere, 5 mg): the number of poses, the noise, the distortion of the
  sensor (Lu's scale and non-orthogonality errors times a factor), the coverage (spherical caps)
  and outliers (a share of poses moved by 50 σ, with the squared, Huber and Cauchy losses); and
  the real recordings in ``../shared/data`` (each read with the options its PROVENANCE.md gives).
* **Success** — the solver reports success and its objective lies within :data:`GAP_TOLERANCE`
  (relative) of the best any solver found on that instance (≈ 0.01 standard errors, see below).
* **Performance profiles** (Dolan & Moré 2002) — for a metric t (solve time, iterations),
  ``r_ps = t_ps / min_s t_ps`` on the instances a solver succeeds on (∞ otherwise) and
  ``ρ_s(τ) = |{p : r_ps ≤ τ}| / n_p``: the share of instances solved within a factor τ of the best.
  Iterations are compared only between solvers that count iterations (alpaqa reports gradient
  evaluations, bonmin branch-and-bound nodes).

The relative gap: near the optimum ``f − f* ≈ ½ δᵀ∇²f δ`` and, with the cost scale of
:func:`optcal.solvers.nlp.cost_scale`, ``f* ≈ c χ²`` with ``χ² ≈ n``; a relative gap ε is a
step of about ``√(2εn)`` standard errors: 1e-6 is 0.015 standard errors at 120 poses.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optcal.core.jsonio import jsonable
from optcal.core.model import LumpedModel, lu2017_reference_model
from optcal.core.poses import PoseTable
from optcal.errors import OptcalError
from optcal.families.simulate.poses import cap_directions, simulate_poses, uniform_directions

#: Relative objective gap to the best solver within which an answer counts as the optimum
#: (≈ 0.015 standard errors at 120 poses, module docstring).
GAP_TOLERANCE: float = 1e-6
#: The solvers of the quick mode (what CI runs): IPOPT and four others that take a second in all.
QUICK_SOLVERS: tuple[str, ...] = ("ipopt", "sqpmethod", "sqpmethod+osqp", "fatrop", "uno")
#: Solvers whose iteration count is something else (excluded from the iterations profile).
NOT_ITERATIONS: dict[str, str] = {"alpaqa": "gradient evaluations", "bonmin": "branch-and-bound nodes"}
#: τ grid of the profiles: 1 to 100, log-spaced.
TAUS: NDArray[np.float64] = np.unique(np.round(np.logspace(0, 2, 41), 6))
#: Outliers of the outlier instances: moved by this many noise standard deviations.
OUTLIER_SIGMAS: float = 50.0


def distorted_model(factor: float) -> LumpedModel:
    """Lu 2017's sensor with its scale and non-orthogonality errors multiplied by ``factor``."""
    scale = 1.0 + factor * (np.array([1.2, 0.8, 1.3]) - 1.0)
    rho, phi, lam = factor * np.deg2rad([2.0, 1.0, 1.5])
    mounting = np.eye(3) + np.array([[0, -0.02, -0.05], [0.02, 0, -0.05], [0.05, 0.05, 0]])
    return LumpedModel.from_physical(scale, rho, phi, lam, bias=[0.20, 0.15, 0.10], mounting=mounting)


@dataclass(frozen=True)
class Instance:
    """One problem of the library: its poses, the loss of its NLP, what it varies."""

    name: str
    kind: str  # "synthetic" or "real"
    factor: str
    poses: PoseTable
    loss: str = "squared"


def synthetic_instances(quick: bool, seed: int = 0) -> list[Instance]:
    """One factor at a time about the base design (module docstring); quick: fewer levels."""
    base_n, base_sigma = 120, 0.005
    sizes = (12, 30, 60) if quick else (12, 30, 300, 1000, 3000)
    noises = (0.5, 20.0) if quick else (0.1, 0.5, 20.0, 50.0)
    distortions = (0.0, 3.0) if quick else (0.0, 2.0, 3.0, 4.0)  # ×5 would make S_y = 1 − 5·0.2 = 0
    caps = (90.0, 45.0) if quick else (120.0, 90.0, 60.0, 45.0)
    shares = (0.05,) if quick else (0.05, 0.15)
    rng = np.random.default_rng([seed, 29])

    def draw(model: LumpedModel, directions: NDArray, sigma: float) -> PoseTable:
        return simulate_poses(model, directions, sigma, rng=np.random.default_rng(rng.integers(1 << 31)))

    ref = lu2017_reference_model()
    uniform = uniform_directions(base_n, np.random.default_rng([seed, 3, base_n]))
    out = [Instance("base: 120 poses, 5 mg", "synthetic", "base", draw(ref, uniform, base_sigma))]
    out += [Instance(f"size: {n} poses", "synthetic", "size",
                     draw(ref, uniform_directions(n, np.random.default_rng([seed, 3, n])), base_sigma)) for n in sizes]
    out += [Instance(f"noise: {s:g} mg", "synthetic", "noise", draw(ref, uniform, s / 1e3)) for s in noises]
    out += [Instance(f"distortion: x{k:g}", "synthetic", "distortion", draw(distorted_model(k), uniform, base_sigma))
            for k in distortions]
    out += [Instance(f"coverage: {c:g} deg cap", "synthetic", "coverage",
                     draw(ref, cap_directions(base_n, c, np.random.default_rng([seed, 4, int(c)])), base_sigma)) for c in caps]
    for share in shares:
        poses = draw(ref, uniform, base_sigma)
        k = max(1, int(round(share * poses.n)))
        rows = rng.choice(poses.n, k, replace=False)
        push = rng.standard_normal((k, 3))
        acc = poses.acc.copy()
        acc[rows] += OUTLIER_SIGMAS * base_sigma * push / np.linalg.norm(push, axis=1, keepdims=True)
        corrupted = PoseTable(acc=acc, sigma=poses.sigma)
        for loss in ("squared", "huber", "cauchy"):
            out.append(Instance(f"outliers: {share:.0%}, {loss} loss", "synthetic", "outliers", corrupted, loss))
    return out


#: The real recordings: folder/file under ``../shared/data`` and the reading options their
#: PROVENANCE.md gives (a rate where the file has no time).
REAL_RECORDINGS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("imutk-xsens/xsens_imutk.csv", {}),
    *((f"mikoff-mpu9150/imu{k}.log", {"rate": 100.0}) for k in range(5)),
    ("mpu6050-imucalibration/example_data_calibration.csv", {}),
    ("imucal-ferraris/example_ferraris_session.csv", {"rate": 102.4}),
    ("hassan-innalabs-m3/CalibrationOfLowCostTriaxialInertialSensors.mat", {}),
    ("hassan-innalabs-m3/CalibrationOfLowCostTriaxialInertialSensors30.mat", {}),
    ("hassan-innalabs-m3/CalibrationOfLowCostTriaxialInertialSensors50.mat", {}),
    ("hassan-lis3dh-phone/MobileAccData30orientationRawSample01.mat", {"rate": 50.0}),
)


def default_data_dir() -> Path:
    """``../shared/data`` beside the repository (where the package is installed editable)."""
    return Path(__file__).resolve().parents[4] / "shared" / "data"


def real_instances(data_dir: Path | None = None) -> tuple[list[Instance], dict[str, str]]:
    """The real recordings that are present and read, and why the others are not."""
    from optcal.data import load

    folder = default_data_dir() if data_dir is None else Path(data_dir)
    out: list[Instance] = []
    skipped: dict[str, str] = {}
    for name, options in REAL_RECORDINGS:
        path = folder / name
        if not path.exists():
            skipped[name] = "not present"
            continue
        try:
            out.append(Instance(f"real: {name}", "real", "real", load(path, **options)))
        except OptcalError as exc:
            skipped[name] = f"not read: {exc}"
    return out, skipped


def solve_instance(instance: Instance, solvers: list[str], repeats: int) -> dict[str, Any]:
    """Every solver on the instance's formulation, from the same start: the best of ``repeats`` solve times."""
    from optcal.problems import norm_residual_ml

    formulation = norm_residual_ml(instance.poses, loss=instance.loss, allow_degenerate=True)
    rows: dict[str, Any] = {}
    for name in solvers:
        try:
            best = None
            t0 = time.perf_counter()
            for _ in range(repeats):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    sol = formulation.solve(name)
                best = sol if best is None or sol.seconds < best.seconds else best
            assert best is not None
            rows[name] = {"status": best.status, "reported_success": best.success, "iterations": best.iterations,
                          "time_s": best.seconds, "objective": best.objective,
                          "wall_s_with_build": (time.perf_counter() - t0) / repeats}
        except OptcalError as exc:
            rows[name] = {"status": f"error: {exc}", "reported_success": False, "iterations": None, "time_s": None,
                          "objective": None}
    finite = [r["objective"] for r in rows.values() if r["objective"] is not None and np.isfinite(r["objective"])]
    f_best = min(finite) if finite else float("nan")
    for r in rows.values():
        if r["objective"] is None or not np.isfinite(f_best):
            r["gap"], r["success"] = None, False
            continue
        r["gap"] = float((r["objective"] - f_best) / max(abs(f_best), 1e-300))
        r["success"] = bool(r["reported_success"] and r["gap"] <= GAP_TOLERANCE)
    return {"name": instance.name, "kind": instance.kind, "factor": instance.factor, "n_poses": instance.poses.n,
            "loss": instance.loss, "best_objective": f_best, "solvers": rows}


def conic_instance(instance: Instance, solvers: list[str]) -> dict[str, Any]:
    """Every suited cvxpy solver on the convex fit (unpolished): time, iterations, status, distance to the first."""
    from optcal.families.accel.base import Normaliser
    from optcal.families.accel.ellipsoid import ConvexEllipsoidFit

    norm = Normaliser.of(instance.poses.acc)
    rows: dict[str, Any] = {}
    reference = None
    for name in solvers:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = ConvexEllipsoidFit(solver=name, polish=False, allow_degenerate=True).fit(instance.poses)
        except OptcalError as exc:
            rows[name] = {"status": f"error: {exc}", "success": False}
            continue
        theta_n = norm.theta_to_normalised(res.params)
        reference = theta_n if reference is None else reference
        rows[name] = {"status": res.solver.status, "success": res.solver.success, "iterations": res.solver.iterations,
                      "time_s": res.solver.solve_time_s, "max_abs_difference_normalised": float(np.max(np.abs(theta_n - reference)))}
    return {"name": instance.name, "solvers": rows}


def profile(results: list[dict[str, Any]], solvers: list[str], metric: str) -> dict[str, Any]:
    """Dolan–Moré profile of ``metric`` (``time_s`` or ``iterations``) over the instances: τ and ρ_s(τ)."""
    if metric == "iterations":
        solvers = [s for s in solvers if s not in NOT_ITERATIONS]
    ratios: dict[str, list[float]] = {s: [] for s in solvers}
    for inst in results:
        values = {s: inst["solvers"][s][metric] for s in solvers
                  if inst["solvers"][s]["success"] and inst["solvers"][s][metric] is not None}
        # an iteration count of 0 (the start already optimal) counts as one
        values = {s: max(float(v), 1.0) if metric == "iterations" else float(v) for s, v in values.items()}
        best = min(values.values()) if values else None
        for s in solvers:
            ratios[s].append(values[s] / best if best and s in values else float("inf"))
    n = len(results)
    rho = {s: [float(np.sum(np.asarray(r) <= tau) / n) if n else 0.0 for tau in TAUS] for s, r in ratios.items()}
    return {"tau": TAUS.tolist(), "rho": rho, "solvers": solvers}


def run(quick: bool = False, seed: int = 0, solvers: list[str] | None = None, data_dir: Path | None = None,
        repeats: int | None = None, progress: bool = False) -> dict[str, Any]:
    """The solver study; returns the JSON-safe ``performance_profile`` object (see the module docstring).

    Non-finite numbers (an infinite gap of a solver that diverged) are ``None`` in it.
    """
    from tqdm import tqdm

    from optcal.solvers.registry import NLP_SOLVERS, available_conic_solvers, available_nlp_solvers, probe_nlp_solver

    t_start = time.perf_counter()
    installed = available_nlp_solvers()
    if solvers is None:
        solvers = [s for s in installed if s in QUICK_SOLVERS] if quick else installed
    repeats = repeats or (1 if quick else 3)
    synthetic = synthetic_instances(quick, seed)
    real, skipped = real_instances(data_dir)
    instances = synthetic + real
    results = [solve_instance(inst, solvers, repeats) for inst in tqdm(instances, desc="solver profiles", disable=not progress,
                                                                          leave=False)]
    conic_solvers = available_conic_solvers()
    conic = [conic_instance(inst, conic_solvers) for inst in instances]
    success_rate = {s: float(np.mean([r["solvers"][s]["success"] for r in results])) for s in solvers}
    gaps = {s: [r["solvers"][s]["gap"] for r in results if r["solvers"][s]["gap"] is not None] for s in solvers}
    return jsonable({
        "solvers": solvers,
        "not_run": {name: probe_nlp_solver(name).reason for name in NLP_SOLVERS if name not in installed},
        "not_in_this_run": [s for s in installed if s not in solvers],
        "n_instances": len(results),
        "n_real_instances": sum(r["kind"] == "real" for r in results),
        "real_skipped": skipped,
        "formulation": "norm-residual ML (optcal.problems.norm_residual_ml), first pass from the convex start",
        "gap_tolerance": GAP_TOLERANCE,
        "repeats": repeats,
        "time": profile(results, solvers, "time_s"),
        "iterations": profile(results, solvers, "iterations"),
        "iterations_not_counted": {s: NOT_ITERATIONS[s] for s in solvers if s in NOT_ITERATIONS},
        "success_rate": success_rate,
        "objective_gap": {s: {"median": float(np.median(g)) if g else None, "max": float(np.max(g)) if g else None}
                          for s, g in gaps.items()},
        "median_time_s": {s: _median([r["solvers"][s]["time_s"] for r in results if r["solvers"][s]["success"]])
                          for s in solvers},
        "conic": {"solvers": conic_solvers, "instances": conic,
                  "max_abs_difference_normalised": {s: max((c["solvers"][s].get("max_abs_difference_normalised", float("inf"))
                                                            for c in conic if s in c["solvers"]), default=None)
                                                    for s in conic_solvers}},
        "instances": results,
        "runtime_s": time.perf_counter() - t_start,
    })


def _median(values: list[Any]) -> float | None:
    return float(np.median(values)) if values else None


def format_profile(res: dict[str, Any]) -> str:
    """The profile's headline figures as text."""
    lines = [f"Solver performance profiles: {res['n_instances']} instances ({res['n_real_instances']} real recordings), "
             f"success = reported success and objective within {res['gap_tolerance']:g} (relative) of the best",
             f"  {'solver':<20s} {'success':>8s} {'median t':>10s} {'ρ(1) time':>10s} {'ρ(10) time':>11s} {'max gap':>9s}"]
    taus = res["time"]["tau"]
    k10 = int(np.argmin(np.abs(np.asarray(taus) - 10.0)))
    for s in res["solvers"]:
        t = res["median_time_s"][s]
        gap = res["objective_gap"][s]["max"]  # None: a solver diverged somewhere (an infinite gap)
        lines.append(f"  {s:<20s} {res['success_rate'][s]:8.0%} {t * 1e3 if t is not None else float('nan'):8.2f}ms "
                     f"{res['time']['rho'][s][0]:10.2f} {res['time']['rho'][s][k10]:11.2f} "
                     f"{gap if gap is not None else float('nan'):9.1e}")
    if res["not_run"]:
        lines.append("  not run here: " + "; ".join(f"{k} ({v})" for k, v in res["not_run"].items()))
    conic = res["conic"]["max_abs_difference_normalised"]
    lines.append("  convex fit, largest difference from " + (res["conic"]["solvers"][0] if res["conic"]["solvers"] else "-")
                 + " (normalised θ): " + ", ".join(f"{k} {v:.1e}" for k, v in conic.items() if v is not None))
    return "\n".join(lines)


def profile_figure(res: dict[str, Any]) -> Any:
    """Two panels: the time and the iterations profiles (ρ_s(τ) against τ, log scale)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.6))
    axes = fig.subplots(1, 2, sharey=True)
    style = {s: (f"C{k % 10}", "-" if k < 10 else "--") for k, s in enumerate(res["solvers"])}  # one look per solver
    for ax, key, title in ((axes[0], "time", "solve time"), (axes[1], "iterations", "iterations")):
        prof = res[key]
        for s in prof["solvers"]:
            ax.step(prof["tau"], prof["rho"][s], where="post", label=s, color=style[s][0], linestyle=style[s][1])
        ax.set_xscale("log")
        ax.set_xlabel("τ (within a factor τ of the best)")
        ax.set_title(f"{title}: {res['n_instances']} instances ({res['n_real_instances']} real)")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("share of instances ρ_s(τ)")
    axes[0].legend(fontsize=7, loc="lower right", ncol=2)
    if res["iterations_not_counted"]:
        axes[1].text(0.98, 0.02, "not counted: " + ", ".join(f"{k} ({v})" for k, v in res["iterations_not_counted"].items()),
                     transform=axes[1].transAxes, ha="right", va="bottom", fontsize=7)
    fig.tight_layout()
    return fig


__all__ = ["GAP_TOLERANCE", "Instance", "QUICK_SOLVERS", "REAL_RECORDINGS", "conic_instance", "distorted_model",
           "format_profile", "profile", "profile_figure", "real_instances", "run", "solve_instance", "synthetic_instances"]
