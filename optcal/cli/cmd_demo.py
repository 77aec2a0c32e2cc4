"""``optcal demo``: the Lu 2017 simulation end to end, needing no files.

(Interim: the diagnosis story replaces this once ``optcal diagnose`` lands.)
"""

from __future__ import annotations

import click


@click.command()
@click.option("--seed", type=int, default=0, show_default=True)
def demo(seed: int) -> None:
    """Simulate the Lu 2017 sensor, calibrate it with every method and compare."""
    import numpy as np

    from optcal.calibration import calibrate
    from optcal.model import lu2017_reference_model
    from optcal.simulate import simulate_poses, tilted_sweeps

    model = lu2017_reference_model()
    poses = simulate_poses(model, tilted_sweeps(40), 0.001, rng=np.random.default_rng(seed))
    raw_rms = float(np.sqrt(np.mean((np.linalg.norm(poses.acc, axis=1) - 1) ** 2)))
    click.echo(f"Simulated the Lu 2017 sensor in {poses.n} static poses with 1 mg noise.")
    click.echo(f"Before calibration the norm is off by {raw_rms * 1e3:.1f} mg rms.")
    for method in ("svd", "convex", "mle", "exact", "gd"):
        r = calibrate(poses, method=method)
        click.echo(
            f"  {method:<6s} rms |a|-1 = {r.rms_norm_residual_g * 1e3:.3f} mg, max |A - A_true| = "
            f"{np.max(np.abs(r.A - model.A)):.1e}, {r.solver.iterations} iterations, {r.solver.solve_time_s * 1e3:.1f} ms"
        )
