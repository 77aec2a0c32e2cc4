"""``optcal simulate``: write a simulated pose table from the lumped model."""

from __future__ import annotations

import click
import numpy as np

from optcal.families.simulate.poses import SCHEDULES


@click.command()
@click.option("--schedule", type=click.Choice(SCHEDULES), default="tilted", show_default=True,
              help="lu2017: the paper's three sweeps as written; tilted: the same sweeps about tilted axes; "
                   "uniform: random orientations; sixpos: six cube faces.")
@click.option("--orientations", type=click.Path(exists=True, dir_okay=False),
              help="CSV of user-given orientations (columns dx,dy,dz or qw,qx,qy,qz or roll_deg,pitch_deg); overrides --schedule.")
@click.option("-n", "--poses", "n", type=click.IntRange(1, 10_000_000), default=120, show_default=True, help="Number of poses.")
@click.option("--sigma", type=click.FloatRange(0), default=0.01, show_default=True, help="White noise, g (per pose, or per sample with --samples).")
@click.option("--samples", type=click.IntRange(1), default=None, help="Noise per sample, averaged over this many samples per pose.")
@click.option("--sensor", type=click.Choice(["lu2017"]), default="lu2017", show_default=True, help="Simulated sensor (Lu 2017, section 3.1).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="Output CSV.")
def simulate(schedule: str, orientations: str | None, n: int, sigma: float, samples: int | None,
             sensor: str, seed: int, output: str) -> None:
    """Simulate static poses a = C ā + o + noise and write them as a pose table (CSV).

    With --schedule sixpos the table also holds each pose's known orientation (roll_deg,
    pitch_deg), which `optcal calibrate --method sixpos` needs.
    """
    import pandas as pd

    from optcal.data.tables import read_csv_frame
    from optcal.errors import InputError
    from optcal.core.model import lu2017_reference_model
    from optcal.families.simulate.poses import schedule as make_schedule
    from optcal.families.simulate.poses import angles_from_directions, simulate_poses, user_directions

    model = lu2017_reference_model()
    rng_dirs, rng_noise = np.random.default_rng([seed, 1]), np.random.default_rng([seed, 2])
    if orientations:
        frame = read_csv_frame(orientations)
        for kind, cols in (("directions", ["dx", "dy", "dz"]), ("quaternions", ["qw", "qx", "qy", "qz"]),
                           ("euler_deg", ["roll_deg", "pitch_deg"])):
            if all(c in frame.columns for c in cols):
                directions = user_directions(frame[cols].to_numpy(float), kind)
                break
        else:
            raise InputError(f"{orientations}: needs columns dx,dy,dz or qw,qx,qy,qz or roll_deg,pitch_deg")
    else:
        directions = make_schedule(schedule, n, rng_dirs)
    if samples:
        poses = simulate_poses(model, directions, sigma, noise="sample", samples_per_pose=samples, rng=rng_noise)
    else:
        poses = simulate_poses(model, directions, sigma, rng=rng_noise)
    frame = pd.DataFrame(poses.acc, columns=["ax", "ay", "az"])
    if poses.sigma is not None:
        frame["sigma"] = poses.sigma
    if schedule == "sixpos" and not orientations:  # the known orientations of the six-position method
        frame["roll_deg"], frame["pitch_deg"] = angles_from_directions(directions)
    from optcal.cli.outputs import writing

    with writing(output) as tmp:  # whole or not at all
        frame.to_csv(tmp, index=False, float_format="%.10g")
    click.echo(f"wrote {poses.n} poses ({'schedule ' + schedule if not orientations else orientations}, "
               f"sigma {sigma:g} g) to {output}", err=True)
