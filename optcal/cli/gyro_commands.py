"""The ``--imu`` path of ``optcal calibrate`` and the IMU block of ``optcal check`` (kept out of the command modules)."""

from __future__ import annotations

from typing import Any

import click
import numpy as np


def calibrate_imu_command(
    data: str, method: str, as_json: bool, output: str | None, allow_degenerate: bool,
    gyro_units: str | None, joint: bool, g_sensitivity: bool, data_opts: dict[str, Any],
) -> None:
    """``optcal calibrate DATA --imu``: both sensors from one raw recording."""
    from optcal.cli.cmd_calibrate import echo_json
    from optcal.cli.data_options import data_line, data_summary, load_data_detailed
    from optcal.families.gyro.estimator import GyroSettings, calibrate_imu_loaded

    loaded = load_data_detailed(data, **data_opts)
    settings = GyroSettings(accelerometer="joint" if joint else "fixed", g_sensitivity=g_sensitivity,
                            allow_degenerate=allow_degenerate)
    cal = calibrate_imu_loaded(loaded, gyro_units=gyro_units, method=method, settings=settings,
                               acc_settings={"allow_degenerate": allow_degenerate})
    if output:
        from optcal.cli.outputs import output_file

        cal.save(output_file(output))
    if as_json:
        out = cal.to_dict()
        out.pop("fitted_on", None)
        out["data"] = data_summary(data, loaded.poses)
        echo_json(out)
        return
    click.echo(data_line(data, loaded.poses))
    click.echo(cal.report())
    if output:
        click.echo(f"saved to {output}")


def gravity_check_lines(cal: Any, data: str, data_opts: dict[str, Any]) -> tuple[list[str], dict[str, Any]]:
    """``optcal check`` on an IMU calibration: the gravity-prediction residual of DATA's moves, before and after."""
    from optcal.cli.data_options import load_data_detailed
    from optcal.families.gyro.check import gravity_prediction_check

    loaded = load_data_detailed(data, **data_opts)
    if loaded.segmentation is None or loaded.segmentation.recording.gyro is None:
        return ["gyro: DATA has no raw gyro samples; the gravity-prediction check needs a raw recording with gx, gy, gz"], {}
    result = gravity_prediction_check(cal, loaded.segmentation)
    lines = [f"gyro: gravity predicted across {result.angles_after_deg.size} moves, rms angle to the next pose: "
             f"before {result.rms_before_deg:.3f}° ({result.before}), after {result.rms_after_deg:.3f}°"]
    return lines, {"gravity_prediction": {"n_moves": int(result.angles_after_deg.size),
                                          "rms_deg_before": result.rms_before_deg, "rms_deg_after": result.rms_after_deg,
                                          "before": result.before, "exclusions": result.exclusions,
                                          "angles_deg_before": np.round(result.angles_before_deg, 6).tolist(),
                                          "angles_deg_after": np.round(result.angles_after_deg, 6).tolist()}}


def allan_gyro_command(data: str, as_json: bool, gyro_units: str | None, counts_per_rad_s: float | None,
                       max_tau: float | None, reading: dict[str, Any]) -> None:
    """``optcal allan DATA --sensor gyro``: the gyro's noise parameters (and Kalibr's two numbers)."""
    import json

    from optcal.cli.cmd_allan import read_still_log
    from optcal.families.noise.gyro_allan import analyse_gyro_log
    from optcal.core.units import decide_gyro_units
    from optcal.core.fit_result import jsonable

    log = read_still_log(data, sensor="gyro", **reading)
    decision = decide_gyro_units(log.samples, log.samples.mean(axis=0), gyro_units, log.units or None)
    analysis = analyse_gyro_log(log.samples, log.rate_hz, decision.units, counts_per_rad_s, max_tau)
    if as_json:
        out = analysis.summary()
        out["log"].update({"path": data, "units_reason": decision.reason, "exclusions": log.exclusions})
        click.echo(json.dumps(jsonable(out), allow_nan=False))
        return
    click.echo(f"DATA: {data}, a still log of {log.samples.shape[0]} samples at {log.rate_hz:.6g} Hz, "
               f"gyro units {decision.units} ({decision.reason})")
    if log.exclusions:
        click.echo("excluded: " + "; ".join(f"{k}: {v}" for k, v in log.exclusions.items()))
    click.echo(analysis.report())
