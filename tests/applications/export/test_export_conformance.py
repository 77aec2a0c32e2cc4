"""Every file optcal writes reproduces ``optcal apply``: the conformance suite over formats × calibration types (issue 37).

Driven by the two registries: every export format of :data:`optcal.applications.export.EXPORTERS`
× every calibration of :data:`CALIBRATIONS`, one entry per calibration type of
:data:`optcal.families.calibration_files.CAL_TYPES` (and per variant: the Ferraris and Tedaldi ``imu``,
the ``extended`` type with each effect of :data:`optcal.core.extended_model.PARAMETRIC`).  A new
calibration type is one entry of :data:`CALIBRATIONS`; a type without one fails
:func:`test_every_registered_calibration_type_and_format_is_in_the_suite`.

Each cell's expected outcome is :data:`EXPECTED` (docs/exports.md prints it; :func:`test_docs_table_is_the_suites`
regenerates the table and compares), and the cell's test proves it:

``exact``
    the consumer's own equation, re-implemented here from its source (cited at each reader) and
    applied to the numbers of the written file and to a real recording's raw samples, gives what
    :meth:`Calibration.correct` / ``correct_gyro`` give (what ``optcal apply`` writes: the same
    calls) to the digits written.  A frame change the export states ("turned by X deg") is allowed
    and checked: the consumer's output is apply's turned by that angle (lengths, the angle between
    force and rate, and the rotation itself).
``loss``
    the model the format holds is simpler: the consumer's equation on the calibration's poses
    gives exactly the rms ``|a| − 1`` the export reports as "exported" (apply's is its "full"),
    the gyroscope's dropped g-sensitivity exactly the rate it reports; where the format keeps
    the axes (firmware), the directions are the sensor's.
``refused``
    :class:`~optcal.errors.InputError` in one line.
``noise``
    the file holds noise densities, not intrinsics: each figure is the Allan result's (the largest
    axis, the per-sample variance for ROS), and nothing of the calibration is claimed.

Real recordings (../shared/data; skipped cleanly without): imu_tk's Xsens MTi log (accelerometer and
gyroscope in counts) and imucal's Ferraris session (m/s², deg/s).  The extended calibrations are the
Xsens lumped fit with one planted term each, applied to the Xsens samples with a planted
temperature ramp and the log's time.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import shutil
import subprocess
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

from helpers.common import SHARED
from optcal.applications.export import EXPORTERS, export
from optcal.applications.export.base import ExportOptions, ExportResult, linear_part
from optcal.core.extended_model import PARAMETRIC
from optcal.errors import InputError
from optcal.families.calibration_files import CAL_TYPES, load
from optcal.families.caltypes.base import Calibration, FitPoses, ValidityRangeWarning
from optcal.families.caltypes.extended import ExtendedCalibration, ExtendedTerm, ValidityRange

DATA = SHARED / "data"
XSENS = DATA / "imutk-xsens" / "xsens_imutk.csv"
FERRARIS = DATA / "imucal-ferraris" / "example_ferraris_session.csv"
MAGNETIC = DATA / "ckexplorer-holds" / "acc_mag_log.csv"
pytestmark = pytest.mark.skipif(not (XSENS.is_file() and FERRARIS.is_file()), reason="../shared/data is not present")

G = 9.80665
#: The Xsens MTi driver's sensitivities (imu_tk's test app and imu_tk_matlab's datasheet values, the
#: recording's PROVENANCE.md): 415 counts per m/s², 6258 counts per rad/s, unsigned 16-bit around 32768.
XSENS_DRIVER = {"counts_per_g": 415.0 * G, "gyro_counts_per_rad_s": 6258.0, "counts_per_dps": 6258.0 * math.pi / 180}
MIDSCALE = 32768.0
#: What "to the digits written" means: the formats write 9 (firmware, noise) to 17 significant digits;
#: 1e-8 relative of a 1 g (or 1 rad/s) output covers 9 digits of every factor in a product of three.
WRITTEN_RTOL = 1e-8
#: A reported figure is printed with 4 significant digits (angles, deg/s) or 4 decimals of a mg.
PRINTED_RTOL = 1e-3


# ----------------------------------------------------------------------------------- the calibrations
@dataclass(frozen=True)
class Case:
    """One calibration and the raw samples of a real recording to apply it to."""

    cal: Calibration
    acc: np.ndarray
    gyro: np.ndarray | None
    temp: np.ndarray | None
    t: np.ndarray | None
    options: ExportOptions

    def applied(self) -> tuple[np.ndarray, np.ndarray | None]:
        """What ``optcal apply`` writes for the samples: :meth:`Calibration.correct` (g) and ``correct_gyro`` (rad/s)."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityRangeWarning)
            acc = self.cal.correct(self.acc, self.temp, self.t)
        gyro = None
        if self.gyro is not None and getattr(self.cal, "gyro", None) is not None:
            gyro = self.cal.correct_gyro(self.gyro, self.acc)  # type: ignore[attr-defined]
        return acc, gyro


def cli(*args: Any) -> None:
    from optcal.cli.main import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main([str(a) for a in args]) == 0, args


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The shared recordings' calibrations (fitted once) and a subset of their raw samples."""
    d = tmp_path_factory.mktemp("conformance")
    cli("calibrate", XSENS, "-o", d / "xsens_lumped.json")
    cli("calibrate", XSENS, "--imu", "-o", d / "xsens_imu.json")
    cli("calibrate", FERRARIS, "--rate", 102.4, "--method", "ferraris", "-o", d / "ferraris.json")
    cli("calibrate", MAGNETIC, "--sensor", "mag", "-o", d / "mag.json")
    out = io.StringIO()
    from optcal.cli.main import main

    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        assert main(["allan", str(XSENS), "--sensor", "both", "--window", ":50", "--calibration",
                     str(d / "xsens_imu.json"), "--json"]) == 0
    xs = pd.read_csv(XSENS).iloc[6000:9000:3]  # moves and rests after the initial rest
    fe = pd.read_csv(FERRARIS).iloc[::10]
    return {
        "dir": d, "allan": json.loads(out.getvalue()),
        "xsens_acc": xs[["acc_x_counts", "acc_y_counts", "acc_z_counts"]].to_numpy(float),
        "xsens_gyro": xs[["gyro_x_counts", "gyro_y_counts", "gyro_z_counts"]].to_numpy(float),
        "xsens_t": np.arange(len(xs)) * 0.03,
        "ferraris_acc": fe[["acc_x", "acc_y", "acc_z"]].to_numpy(float),
        "ferraris_gyro": fe[["gyr_x", "gyr_y", "gyr_z"]].to_numpy(float),
        "mag": pd.read_csv(MAGNETIC)[["mx", "my", "mz"]].to_numpy(float)[::4],
    }


def xsens_case(r: dict[str, Any], cal: Calibration, **extra: Any) -> Case:
    gyro = XSENS_DRIVER if getattr(cal, "gyro", None) is not None else {"counts_per_g": XSENS_DRIVER["counts_per_g"]}
    options = ExportOptions(**gyro, allan=r["allan"], random_walk_bound=True, max_loss_g=1.0)
    return Case(cal, r["xsens_acc"], r["xsens_gyro"], extra.get("temp"), extra.get("t"), options)


def ferraris_case(r: dict[str, Any], cal: Calibration) -> Case:
    """imucal's session; a calibration without its poses (a six-position one, a peer's file) measures its losses on
    the Ferraris fit's six poses."""
    poses = None if cal.fitted_on is not None else load(r["dir"] / "ferraris.json").fitted_on
    options = ExportOptions(allan=r["allan"], random_walk_bound=True, max_loss_g=1.0, poses=poses)
    return Case(cal, r["ferraris_acc"], r["ferraris_gyro"], None, None, options)


#: A planted term of each effect, of the size a MEMS accelerometer shows (and ``optcal diagnose`` finds on the
#: shared recordings): 0.5 mg/°C of bias, 300 ppm/°C of scale, 20 µg/s of drift, 3 mg/g² of nonlinearity.
PLANTED: dict[str, tuple[float, ...]] = {"temperature_bias": (0.5e-3, 1e-5), "temperature_scale": (3e-4,),
                                         "bias_drift": (2e-5,), "scale_nonlinearity": (3e-3,)}


def extended_case(r: dict[str, Any], effect: str) -> Case:
    """The Xsens lumped fit with one term of ``effect`` planted in the log itself: its poses and samples are what the
    extended model measures for the forces the lumped fit reads, at a temperature ramp of 15-35 °C over 60 s."""
    lumped = load(r["dir"] / "xsens_lumped.json").lumped()
    poses = lumped.fitted_on
    assert poses is not None
    cal = ExtendedCalibration(lumped.T, lumped.o, (ExtendedTerm(effect, "y", PLANTED[effect]),),
                              temp_ref=25.0, t_ref=30.0, units=lumped.units)
    model = cal.model

    def planted(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        temp, t = np.linspace(15.0, 35.0, len(raw)), np.linspace(0.0, 60.0, len(raw))
        return model.measure(lumped.correct(raw), temp, t), temp, t

    fitted = FitPoses(*planted(poses.acc))
    cal.fitted_on = fitted
    cal.validity = ValidityRange.of(cal.norm_errors(fitted.acc, fitted.temp, fitted.t) + 1.0, fitted.temp, fitted.t)
    acc, temp, t = planted(r["xsens_acc"])
    return replace(xsens_case(r, cal, temp=temp, t=t), acc=acc)


def peer_case(r: dict[str, Any]) -> Case:
    """imucal's file (optcal's export of the Ferraris calibration) read back as a peer's calibration."""
    text = export(load(r["dir"] / "ferraris.json"), "imucal").text
    path = r["dir"] / "peer_imucal.json"
    path.write_text(text)
    return ferraris_case(r, load(path))


#: The noise-only formats: the same outcome for every calibration.
NOISE_ONLY: dict[str, str] = {"kalibr": "noise", "ros": "noise", "vins": "noise", "orbslam3": "noise", "okvis": "noise"}
#: ArduPilot's and PX4's per-axis model: every calibration loses its cross-axis terms (and the gyro all but its bias).
FIRMWARE_LOSS: dict[str, str] = {"ardupilot": "loss", "px4": "loss", "px4-shell": "loss"}


def formats(**outcomes: str) -> dict[str, str]:
    """Outcomes of the intrinsics formats by keyword (``kalibr_imu`` for ``kalibr-imu``), with the firmware and
    noise-only formats' common ones."""
    return {**FIRMWARE_LOSS, **NOISE_ONLY, **{k.replace("_", "-"): v for k, v in outcomes.items()}}


@dataclass(frozen=True)
class Entry:
    """A calibration of the suite: how to make it from the recordings, and each format's outcome (:func:`judge`)."""

    make: Callable[[dict[str, Any]], Case]
    expected: dict[str, str]


#: Everything exact: the formats that hold a full linear accelerometer and gyroscope (a frame turn stated).
ALL_EXACT = formats(c="exact", imucal="exact", kalibr_imu="exact", openvins="exact", basalt="exact", imutk="exact")
#: A gyroscope g-sensitivity (the Ferraris fit's K_ga): Basalt and imu_tk have no place for it, its rate reported.
G_SENSITIVE = {**ALL_EXACT, "basalt": "loss", "imutk": "loss"}
#: An extended calibration: only the C header holds its terms; the others write the lumped part and report the loss.
EXTENDED = formats(c="exact", imucal="loss", kalibr_imu="loss", openvins="loss", basalt="loss", imutk="loss")

def magnetometer_case(r: dict[str, Any]) -> Case:
    """The hand-turned session's magnetometer (gauss), its raw samples as the consumers' input."""
    return Case(load(r["dir"] / "mag.json"), r["mag"], None, None, None, ExportOptions())


#: A magnetometer: the compass parameters of the two firmwares hold its symmetric T and o exactly; no other format
#: has a place for a magnetometer, and refuses it.
MAGNETOMETER = {**{fmt: "refused" for fmt in EXPORTERS}, "ardupilot": "exact", "px4": "exact", "px4-shell": "exact",
                "c": "exact"}

#: One entry per calibration: the key is ``cal_type`` or ``cal_type/variant``.  A new calibration type is one entry.
CALIBRATIONS: dict[str, Entry] = {
    "lumped": Entry(lambda r: xsens_case(r, load(r["dir"] / "xsens_lumped.json")), ALL_EXACT),
    "sixpos_full": Entry(lambda r: ferraris_case(r, load(r["dir"] / "ferraris.json").accelerometer.calibration),  # type: ignore[attr-defined]
                         ALL_EXACT),
    "imu/ferraris": Entry(lambda r: ferraris_case(r, load(r["dir"] / "ferraris.json")), G_SENSITIVE),
    "imu/tedaldi": Entry(lambda r: xsens_case(r, load(r["dir"] / "xsens_imu.json")), ALL_EXACT),
    **{f"extended/{effect}": Entry(lambda r, e=effect: extended_case(r, e), EXTENDED) for effect in PARAMETRIC},
    "peer/imucal": Entry(peer_case, G_SENSITIVE),
    "magnetometer": Entry(magnetometer_case, MAGNETOMETER),
}


@pytest.fixture(scope="module")
def cases(recordings: dict[str, Any]) -> dict[str, Case]:
    return {key: entry.make(recordings) for key, entry in CALIBRATIONS.items()}


# ----------------------------------------------------------------------------------- the consumers
@dataclass
class Consumed:
    """What a consumer computes from the written file: the specific force (g of the calibration) and the rate
    (rad/s) of raw samples; ``frame_deg`` the frame turn the export stated (None: the calibration's own frame)."""

    acc_g: Callable[[np.ndarray, np.ndarray | None, np.ndarray | None], np.ndarray]
    gyro: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    frame_deg: float | None = None


def driver(case: Case) -> tuple[float, float, float, float]:
    """``k, z, s, z_g``: the driver's m/s² per raw accelerometer unit and zero, rad/s per raw gyro unit and zero
    (what every topic-unit consumer reads: the sensor's datasheet, not optcal)."""
    units = case.cal.units
    k = {"m/s^2": 1.0, "g": G}.get(units, G / (case.options.counts_per_g or np.nan))
    z = MIDSCALE if units == "counts" else 0.0
    gunits = getattr(case.cal, "gyro_units", None)
    s = {"rad/s": 1.0, "deg/s": math.pi / 180}.get(str(gunits), 1.0 / (case.options.gyro_counts_per_rad_s or np.nan))
    zg = MIDSCALE if gunits == "counts" else 0.0
    return k, z, s, zg


def turned_by(result: ExportResult) -> float | None:
    """The frame turn an export states in its notes ("... turned by X deg"), or None."""
    for note in result.notes:
        m = re.search(r"turned by ([0-9.e+-]+) deg", note)
        if m:
            return float(m.group(1))
    return None


def mavlink_params(result: ExportResult, tmp: Path) -> Any:
    """The exported ArduPilot parameter file as pymavlink's own loader reads it (``MAVParmDict.load``)."""
    mavparm = pytest.importorskip("pymavlink.mavparm")
    path = tmp / "cal.param"
    path.write_text(result.text)
    p = mavparm.MAVParmDict()
    with contextlib.redirect_stdout(io.StringIO()):
        assert p.load(str(path))
    return p


def ardupilot(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """ArduPilot (ArduPilot/ardupilot libraries/AP_InertialSensor/AP_InertialSensor_Backend.cpp,
    ``_rotate_and_correct_accel``: ``accel -= offsets; accel *= scale`` per axis; AP_InertialSensor_tempcal.cpp,
    ``TCal::correct_sensor``: ``v -= p(T - 35) - p(CALTEMP - 35)``, ``p(x) = (c1 + (c2 + c3 x) x) x · 1e-6``, T and
    CALTEMP clamped to [TMIN, TMAX]).  The parameter file is read by pymavlink's own loader (``MAVParmDict.load``)."""
    p = mavlink_params(result, tmp)
    k, z, _, _ = driver(case)

    def acc(raw: np.ndarray, temp: np.ndarray | None, t: np.ndarray | None) -> np.ndarray:
        v = k * (raw - z)
        if p.get("INS_TCAL1_ENABLE") == 1:
            c = [np.array([p[f"INS_TCAL1_ACC{n}_{a}"] for a in "XYZ"]) for n in (1, 2, 3)]

            def poly(x: Any) -> np.ndarray:
                x = np.asarray(x, float)[..., None]
                return (c[0] + (c[1] + c[2] * x) * x) * x * 1e-6

            lo, hi = p["INS_TCAL1_TMIN"], p["INS_TCAL1_TMAX"]
            assert temp is not None
            v = v - poly(np.clip(temp, lo, hi) - 35.0) + poly(np.clip(p["INS_ACC1_CALTEMP"], lo, hi) - 35.0)
        return (v - [p[f"INS_ACCOFFS_{a}"] for a in "XYZ"]) * [p[f"INS_ACCSCAL_{a}"] for a in "XYZ"] / G

    _, _, s, zg = driver(case)
    has_gyro = "INS_GYROFFS_X" in p  # _rotate_and_correct_gyro: gyro -= offsets (rad/s)
    return Consumed(acc, (lambda w, raw: s * (w - zg) - [p[f"INS_GYROFFS_{a}"] for a in "XYZ"]) if has_gyro else None)


def px4_params(text: str) -> dict[str, float]:
    """QGroundControl's reader of PX4's parameter file (mavlink/qgroundcontrol src/FactSystem/ParameterManager.cc,
    ``readParametersFromStream``: '#' lines skipped, five tab-separated fields: vehicle, component, name, value, type)
    and PX4's shell (``param set NAME VALUE``)."""
    out: dict[str, float] = {}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        if line.startswith("param set "):
            _, _, name, value = line.split()[:4]
        else:
            fields = line.split("\t")
            assert len(fields) == 5, line
            name, value = fields[2], fields[3]
        out[name] = float(value)
    return out


def px4(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """PX4 (PX4/PX4-Autopilot src/lib/sensor_calibration/Accelerometer.hpp, ``Correct``: ``(data − thermal_offset −
    offset) ⊙ scale``; src/modules/temperature_compensation/TemperatureCompensation.cpp, ``calc_thermal_offsets_3D``:
    ``dT = clamp(T, TMIN, TMAX) − TREF``, ``X0 + X1 dT + X2 dT² + X3 dT³``)."""
    p = px4_params(result.text)
    k, z, _, _ = driver(case)

    def acc(raw: np.ndarray, temp: np.ndarray | None, t: np.ndarray | None) -> np.ndarray:
        v = k * (raw - z)
        if p.get("TC_A_ENABLE") == 1:
            assert temp is not None
            dT = np.clip(temp, p["TC_A0_TMIN"], p["TC_A0_TMAX"]) - p["TC_A0_TREF"]
            for j in range(3):
                v[:, j] = v[:, j] - sum(p[f"TC_A0_X{n}_{j}"] * dT**n for n in range(4))
        return (v - [p[f"CAL_ACC0_{a}OFF"] for a in "XYZ"]) * [p[f"CAL_ACC0_{a}SCALE"] for a in "XYZ"] / G

    _, _, s, zg = driver(case)
    has_gyro = "CAL_GYRO0_XOFF" in p  # src/lib/sensor_calibration/Gyroscope.hpp, Correct: data - offset (rad/s)
    return Consumed(acc, (lambda w, raw: s * (w - zg) - [p[f"CAL_GYRO0_{a}OFF"] for a in "XYZ"]) if has_gyro else None)


C_MAIN = r"""
#include <stdio.h>
#include "cal.h"
int main(void)
{
    double a[3], w[3], temp, t, out[3], out_w[3] = {0.0, 0.0, 0.0};
    while (scanf("%lf %lf %lf %lf %lf %lf %lf %lf", &a[0], &a[1], &a[2], &w[0], &w[1], &w[2], &temp, &t) == 8) {
        %ACC%;
        %GYRO%;
        printf("%.17g %.17g %.17g %.17g %.17g %.17g\n", out[0], out[1], out[2], out_w[0], out_w[1], out_w[2]);
    }
    return 0;
}
"""


def c_header(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """The C99 header, compiled with the system's ``cc`` and run on the samples (its own functions are the consumer)."""
    if shutil.which("cc") is None:
        pytest.skip("no C compiler (cc) on this machine")
    (tmp / "cal.h").write_text(result.text)
    acc_call = ("optcal_apply_accel_tt(a, temp, t, out)" if "optcal_apply_accel_tt" in result.text
                else "optcal_apply_accel(a, out)")
    gyro_call = ""
    if "optcal_apply_gyro(const double raw[3], const double raw_acc[3]" in result.text:
        gyro_call = "optcal_apply_gyro(w, a, out_w)"
    elif "optcal_apply_gyro(" in result.text:
        gyro_call = "optcal_apply_gyro(w, out_w)"
    (tmp / "main.c").write_text(C_MAIN.replace("%ACC%", acc_call).replace("%GYRO%", gyro_call or "(void)w"))
    subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-pedantic", "-o", str(tmp / "apply"), str(tmp / "main.c"),
                    "-lm"], check=True, cwd=tmp)

    def run(raw: np.ndarray, gyro: np.ndarray | None, temp: np.ndarray | None, t: np.ndarray | None) -> np.ndarray:
        n = len(raw)
        rows = np.column_stack([raw, np.zeros((n, 3)) if gyro is None else gyro,
                                np.zeros(n) if temp is None else temp, np.zeros(n) if t is None else t])
        stdin = "\n".join(" ".join(repr(float(v)) for v in row) for row in rows)
        out = subprocess.run([str(tmp / "apply")], input=stdin, capture_output=True, text=True, check=True).stdout
        return np.loadtxt(out.splitlines()).reshape(n, 6)

    return Consumed(lambda raw, temp, t: run(raw, None, temp, t)[:, :3],
                    (lambda w, raw: run(raw, w, None, None)[:, 3:]) if gyro_call else None)


def comment_vector(text: str, label: str) -> np.ndarray:
    line = next(ln for ln in text.splitlines() if ln.strip().startswith(f"# {label}"))
    return np.array([float(v) for v in line.split(":")[-1].split(",")])


def kalibr_imu(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """Kalibr's scale-misalignment model (ethz-asl/kalibr @1f60227 aslam_offline_calibration/kalibr/python/
    kalibr_imu_camera_calibration/IccSensors.py, ``IccScaledMisalignedImu`` line 912, its error terms lines 969 and 1015,
    ``setIntrisicsMatrices`` line 933: ``α = M_a a_i + b_a``, ``ω_m = M_g C_gyro_i
    ω_i + A C_gyro_i a_i + b_g``) solved for ``a_i``, ``ω_i``; the biases from the file's comments (Kalibr estimates
    them)."""
    imu = yaml.safe_load(result.text)["imu0"]
    M_a = np.array(imu["accelerometers"]["M"])
    M_g, A, C = (np.array(imu["gyroscopes"][key]) for key in ("M", "A", "C_gyro_i"))
    assert np.all(np.triu(M_a, 1) == 0) and np.all(np.triu(M_g, 1) == 0)
    b_a = comment_vector(result.text, "accelerometer bias b_a")
    k, z, s, zg = driver(case)
    has_gyro = "gyroscope bias b_g" in result.text
    b_g = comment_vector(result.text, "gyroscope bias b_g") if has_gyro else np.zeros(3)

    def acc(raw: np.ndarray, temp: Any = None, t: Any = None) -> np.ndarray:
        return np.linalg.solve(M_a, (k * (raw - z) - b_a).T).T / G

    def gyro(w: np.ndarray, raw: np.ndarray) -> np.ndarray:
        a_i = acc(raw) * G
        return (C.T @ np.linalg.solve(M_g, (s * (w - zg) - b_g - a_i @ (A @ C).T).T)).T

    return Consumed(acc, gyro if has_gyro else None, turned_by(result))


def openvins(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """OpenVINS (rpng/open_vins @6948812 ov_msckf/src/core/VioManagerOptions.h lines 306-321: ``Tw``, ``Ta``,
    ``R_IMUtoACC``, ``R_IMUtoGYRO``, ``Tg`` read from ``imu0``, ``Dw = Tw⁻¹``, ``Da = Ta⁻¹``, the kalibr model keeping
    their lower triangles; ov_msckf/src/state/Propagator.cpp lines 184-190: ``a_I = R_ACCtoIMU Da (a_m − b_a)``,
    ``ω_I = R_GYROtoIMU Dw (ω_m − b_g − Tg a_I)``)."""
    assert result.text.startswith("%YAML:1.0")
    imu = yaml.safe_load(result.text.split("\n", 1)[1])["imu0"]
    Dw, Da = (np.tril(np.linalg.inv(np.array(imu[key]))) for key in ("Tw", "Ta"))
    R_acc, R_gyro = np.array(imu["R_IMUtoACC"]).T, np.array(imu["R_IMUtoGYRO"]).T
    Tg = np.array(imu["Tg"])
    b_a = comment_vector(result.text, "accelerometer bias b_a")
    has_gyro = "gyroscope bias b_g" in result.text
    b_g = comment_vector(result.text, "gyroscope bias b_g") if has_gyro else np.zeros(3)
    k, z, s, zg = driver(case)

    def acc(raw: np.ndarray, temp: Any = None, t: Any = None) -> np.ndarray:
        return (k * (raw - z) - b_a) @ (R_acc @ Da).T / G

    def gyro(w: np.ndarray, raw: np.ndarray) -> np.ndarray:
        return (s * (w - zg) - b_g - (acc(raw) * G) @ Tg.T) @ (R_gyro @ Dw).T

    return Consumed(acc, gyro if has_gyro else None, turned_by(result))


def basalt(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """Basalt (VladyslavUsenko/basalt-headers @a585db3 include/basalt/calibration/calib_bias.hpp, ``getBiasAndScale``
    lines 91 and 179, ``getCalibrated`` lines 106 and 191: ``CalibAccelBias``
    ``a_c = (I + S_a) a_r − b``, ``S_a`` lower-triangular from ``s_1…s_6`` as ``getBiasAndScale`` fills it;
    ``CalibGyroBias`` ``ω_c = (I + S_g) ω_r − b``, ``S_g`` column-major from ``s_1…s_9``)."""
    value = json.loads(result.text)["value0"]
    p = np.array(value["calib_accel_bias"])
    S_a = np.zeros((3, 3))
    S_a[:, 0] = p[3:6]
    S_a[1, 1], S_a[2, 1], S_a[2, 2] = p[6], p[7], p[8]
    q = np.array(value["calib_gyro_bias"])
    S_g = np.column_stack([q[3:6], q[6:9], q[9:12]])
    k, z, s, zg = driver(case)
    has_gyro = getattr(case.cal, "gyro", None) is not None

    def acc(raw: np.ndarray, temp: Any = None, t: Any = None) -> np.ndarray:
        return ((k * (raw - z)) @ (np.eye(3) + S_a).T - p[:3]) / G

    def gyro(w: np.ndarray, raw: np.ndarray) -> np.ndarray:
        return (s * (w - zg)) @ (np.eye(3) + S_g).T - q[:3]

    return Consumed(acc, gyro if has_gyro else None, turned_by(result))


def imutk_triad(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """imu_tk's ``CalibratedTriad_::load`` (Kyle-ak/imu_tk @7780270 include/imu_tk/calibration.h line 387): 9 numbers row-major into
    the misalignment T, 9 into the scale K, 3 into the bias B."""
    v = [float(x) for x in text.split()]
    assert len(v) == 21
    return np.array(v[:9]).reshape(3, 3), np.array(v[9:18]).reshape(3, 3), np.array(v[18:])


def imutk(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """imu_tk's ``unbiasNormalize`` (calibration.h line 163: ``ms_mat_ (raw − bias_vec_)``, ``ms_mat_ = mis_mat_
    scale_mat_`` line 433): ``X' = T K (X − B)`` on raw samples (m/s² at its g_mag, rad/s)."""
    T_a, K_a, B_a = imutk_triad(result.text)
    gyro_text = result.files.get("_gyro")

    def acc(raw: np.ndarray, temp: Any = None, t: Any = None) -> np.ndarray:
        return (raw - B_a) @ (T_a @ K_a).T / case.options.gravity_m_s2

    gyro = None
    if gyro_text is not None:
        T_g, K_g, B_g = imutk_triad(gyro_text)
        gyro = lambda w, raw: (w - B_g) @ (T_g @ K_g).T  # noqa: E731
    return Consumed(acc, gyro, turned_by(result))


def imucal(case: Case, result: ExportResult, tmp: Path) -> Consumed:
    """imucal itself (mad-lab-fau/imucal, installed; @8716e4c imucal/management.py line 238 ``load_calibration_info``,
    imucal/ferraris_calibration_info.py lines 85 and 114 ``_calibrate_acc``, ``_calibrate_gyr``), m/s² and deg/s."""
    management = pytest.importorskip("imucal.management")
    path = tmp / "imucal.json"
    path.write_text(result.text)
    info = management.load_calibration_info(path)
    g = float(re.search(r"g = ([0-9.e+-]+) m/s\^2", json.loads(result.text)["comment"]).group(1))  # type: ignore[union-attr]
    d = json.loads(result.text)

    def run(raw: np.ndarray, w: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        w = np.zeros_like(raw) if w is None else w
        a, r = info.calibrate(raw, w, d["from_acc_unit"], d["from_gyr_unit"])
        return a / g, np.radians(r)

    has_gyro = getattr(case.cal, "gyro", None) is not None
    return Consumed(lambda raw, temp, t: run(raw, None)[0], (lambda w, raw: run(raw, w)[1]) if has_gyro else None)


#: The firmware formats: per-axis offsets and scales; their gyroscope keeps the bias only (its loss, the rate error
#: at a stated rate, is tested against ArduPilot's and PX4's equations in tests/applications/test_export_firmware.py).
FIRMWARE: tuple[str, ...] = ("ardupilot", "px4", "px4-shell")
#: format → the consumer's reader and equation (None: a noise-only format, :func:`noise_figures`).
CONSUMERS: dict[str, Callable[[Case, ExportResult, Path], Consumed] | None] = {
    "ardupilot": ardupilot, "px4": px4, "px4-shell": px4, "c": c_header, "imucal": imucal,
    "kalibr-imu": kalibr_imu, "openvins": openvins, "basalt": basalt, "imutk": imutk,
    "kalibr": None, "ros": None, "vins": None, "orbslam3": None, "okvis": None,
}


# ----------------------------------------------------------------------------------- noise-only formats
#: format → its four noise keys (figure of the Allan result: white noise or random walk, of which sensor).
NOISE_KEYS: dict[str, dict[str, tuple[str, str]]] = {
    # ethz-asl/kalibr aslam_offline_calibration/kalibr/python/kalibr_common/ConfigReader.py, ImuParameters
    "kalibr": {"accelerometer_noise_density": ("accelerometer", "white"), "gyroscope_noise_density": ("gyroscope", "white"),
               "accelerometer_random_walk": ("accelerometer", "walk"), "gyroscope_random_walk": ("gyroscope", "walk")},
    # HKUST-Aerial-Robotics/VINS-Fusion vins_estimator/src/estimator/parameters.cpp (fsSettings["acc_n"] ...)
    "vins": {"acc_n": ("accelerometer", "white"), "gyr_n": ("gyroscope", "white"),
             "acc_w": ("accelerometer", "walk"), "gyr_w": ("gyroscope", "walk")},
    # UZ-SLAMLab/ORB_SLAM3 src/Tracking.cc, ParseIMUParamFile
    "orbslam3": {"IMU.NoiseAcc": ("accelerometer", "white"), "IMU.NoiseGyro": ("gyroscope", "white"),
                 "IMU.AccWalk": ("accelerometer", "walk"), "IMU.GyroWalk": ("gyroscope", "walk")},
    # ethz-asl/okvis_ros src/VioParametersReader.cpp, imu_params
    "okvis": {"sigma_a_c": ("accelerometer", "white"), "sigma_g_c": ("gyroscope", "white"),
              "sigma_aw_c": ("accelerometer", "walk"), "sigma_gw_c": ("gyroscope", "walk")},
}


def allan_figure(allan: dict[str, Any], sensor: str, figure: str) -> float:
    """The largest axis's white noise or random walk of the Allan result (the bound where the log shows none)."""
    white = "velocity_random_walk" if sensor == "accelerometer" else "angle_random_walk"
    values = []
    for a in "xyz":
        axis = allan[sensor][a]
        if figure == "white":
            values.append(axis[white])
        else:
            walk = axis.get("rate_random_walk")
            values.append(walk if walk is not None else axis["rate_random_walk_bound"]["value"])
    return max(values)


def noise_figures(case: Case, fmt: str, result: ExportResult) -> None:
    """The noise figures the file states are the Allan result's (and no intrinsics are claimed)."""
    allan = case.options.allan
    assert allan is not None
    if fmt == "ros":
        # sensor_msgs/Imu linear_acceleration_covariance: the white noise per sample, N² × rate
        cov = np.array(yaml.safe_load(result.text)["linear_acceleration_covariance"]).reshape(3, 3)
        rate = float(allan["accelerometer"]["rate_hz"]) if "rate_hz" in allan["accelerometer"] else None
        density = np.array([allan["accelerometer"][a]["velocity_random_walk"] for a in "xyz"])
        if rate is None:
            rate = float(cov[0, 0] / density[0] ** 2)
        np.testing.assert_allclose(np.diag(cov), density**2 * rate, rtol=WRITTEN_RTOL)
        assert np.all(cov == np.diag(np.diag(cov)))
        return
    text = result.text
    data = yaml.safe_load(text.split("\n", 1)[1] if text.startswith("%YAML") else text)
    data = data.get("imu_params", data.get("imu0", data))
    for key, (sensor, figure) in NOISE_KEYS[fmt].items():
        assert data[key] == pytest.approx(allan_figure(allan, sensor, figure), rel=WRITTEN_RTOL), key
    assert not any("scale" in m or "misalignment" in m for m in result.mapped), result.mapped


# ----------------------------------------------------------------------------------- the cells
def close(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference relative to the samples' own magnitude (1 g, a rate)."""
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def rotation_between(ours: np.ndarray, theirs: np.ndarray) -> np.ndarray:
    """The proper rotation R with theirs ≈ ours Rᵀ (Kabsch)."""
    U, _, Vt = np.linalg.svd(theirs.T @ ours)
    D = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(U @ Vt)))])
    return U @ D @ Vt


def judge(case: Case, fmt: str, tmp: Path) -> str:
    """Export ``case`` in ``fmt``, prove what the export claims, and say which: exact, loss, refused or noise."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityRangeWarning)
            result = export(case.cal, fmt, case.options)
    except InputError as exc:
        assert "\n" not in str(exc) and str(exc), str(exc)
        return "refused"
    if case.cal.cal_type == "magnetometer":
        return judge_magnetometer(case, fmt, result, tmp)
    consumer = CONSUMERS[fmt]
    if consumer is None:
        noise_figures(case, fmt, result)
        return "noise"
    consumed = consumer(case, result, tmp)
    ours_a, ours_w = case.applied()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityRangeWarning)
        theirs_a = consumed.acc_g(case.acc, case.temp, case.t)
    theirs_w = consumed.gyro(case.gyro, case.acc) if consumed.gyro is not None and case.gyro is not None else None
    assert (theirs_w is None) == (ours_w is None), "the gyroscope is exported exactly when the calibration has one"
    # a frame change the export states: the consumer's output is apply's turned by the stated angle
    R = np.eye(3)
    if consumed.frame_deg:  # measured against the linear part, which every format holds (an extended's terms aside)
        M, o, _ = linear_part(case.cal)
        R = rotation_between((case.acc - o) @ M.T, theirs_a)
        angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))
        assert angle == pytest.approx(consumed.frame_deg, rel=PRINTED_RTOL, abs=1e-4), (fmt, angle, consumed.frame_deg)
    theirs_a = theirs_a @ R  # back into apply's frame
    exact = True
    if theirs_w is not None and ours_w is not None and fmt not in FIRMWARE:
        theirs_w = theirs_w @ R
        expected_w = ours_w
        added = [d for d in result.dropped if "the rate it adds" in d]
        if added:  # the g-sensitivity the format has no place for: T_g G_g ā left in the rate, as reported
            gyro = getattr(case.cal, "gyro")
            expected_w = ours_w + ours_a @ (gyro.T @ gyro.g_sensitivity).T
            poses = case.options.poses or case.cal.fitted_on
            f = case.cal.correct(poses.acc)
            f /= np.linalg.norm(f, axis=1, keepdims=True)
            missed = np.degrees(np.linalg.norm(f @ (gyro.T @ gyro.g_sensitivity).T, axis=1))
            reported = float(re.search(r"the rate it adds at 1 g is ([0-9.e+-]+) deg/s rms", added[0]).group(1))  # type: ignore[union-attr]
            assert reported == pytest.approx(float(np.sqrt(np.mean(missed**2))), rel=PRINTED_RTOL)
            exact = False
        assert close(theirs_w, expected_w) <= WRITTEN_RTOL, (fmt, "gyro", close(theirs_w, expected_w))
    if result.loss is None or abs(result.loss.loss_g) < 0.5e-7:  # below the 4 decimals of a mg printed
        assert close(theirs_a, ours_a) <= WRITTEN_RTOL, (fmt, close(theirs_a, ours_a))
        return "exact" if exact and fmt not in FIRMWARE else "loss"
    # a simpler model: on the calibration's poses the consumer gives exactly the rms |a| - 1 the export reports
    poses = case.options.poses or case.cal.fitted_on
    assert poses is not None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityRangeWarning)
        full = np.linalg.norm(case.cal.correct(poses.acc, poses.temp, poses.t), axis=1) - 1
        exported = np.linalg.norm(consumed.acc_g(poses.acc, poses.temp, poses.t), axis=1) - 1
    rms = lambda x: float(np.sqrt(np.mean(x**2)))  # noqa: E731
    assert rms(full) == pytest.approx(result.loss.rms_full_g, rel=1e-9, abs=1e-12)
    assert rms(exported) == pytest.approx(result.loss.rms_exported_g, rel=1e-6, abs=1e-9), (fmt, rms(exported), result.loss)
    return "loss"



#: Milligauss (ArduPilot's compass unit) and gauss (PX4's) per magnetometer data unit.
MILLIGAUSS_PER_UNIT: dict[str, float] = {"gauss": 1e3, "mgauss": 1.0, "uT": 10.0, "nT": 1e-2, "T": 1e7}


def judge_magnetometer(case: Case, fmt: str, result: ExportResult, tmp: Path) -> str:
    """The firmware's compass equation on the raw samples against ``optcal apply``'s field (data units).

    ArduPilot (ArduPilot/ardupilot libraries/AP_Compass/AP_Compass_Backend.cpp, ``correct_field``: ``field +=
    offsets; field = mat * field`` with ``mat`` the symmetric matrix of ``COMPASS_DIA`` on its diagonal and
    ``COMPASS_ODI`` off it, milligauss; the file read by pymavlink's ``MAVParmDict.load``); PX4
    (PX4/PX4-Autopilot src/lib/sensor_calibration/Magnetometer.cpp, ``Correct``: ``_rotation * (_scale * (data −
    _offset))``, gauss, ``set_offdiagonal`` filling ``_scale`` with ``XODIAG, YODIAG, ZODIAG`` as (xy, xz, yz);
    QGroundControl's file read as :func:`px4_params` reads it).
    """
    cal, m = case.cal, case.acc
    if fmt == "c":  # optcal's own header, compiled and run on the samples: optcal_apply_mag_field
        if shutil.which("cc") is None:
            pytest.skip("no C compiler (cc) on this machine")
        (tmp / "mag.h").write_text(result.text)
        (tmp / "main.c").write_text('#include <stdio.h>\n#include "mag.h"\nint main(void) {\n double m[3], out[3];\n'
                                    ' while (scanf("%lf %lf %lf", &m[0], &m[1], &m[2]) == 3) {\n'
                                    '  optcal_apply_mag_field(m, out);\n  printf("%.17g %.17g %.17g\\n", out[0], out[1], out[2]);\n'
                                    ' }\n return 0;\n}\n')
        subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-pedantic", "-o", str(tmp / "mag"), str(tmp / "main.c")],
                       check=True, cwd=tmp)
        stdin = "\n".join(" ".join(repr(float(v)) for v in row) for row in m)
        theirs = np.loadtxt(subprocess.run([str(tmp / "mag")], input=stdin, capture_output=True, text=True,
                                           check=True).stdout.splitlines())
        difference = float(np.max(np.linalg.norm(theirs - cal.field(m), axis=1)) / cal.field_strength)  # type: ignore[attr-defined]
        assert difference <= 1e-12, difference
        return "exact"
    if fmt == "ardupilot":
        p = mavlink_params(result, tmp)
        ofs = np.array([p[f"COMPASS_OFS_{a}"] for a in "XYZ"])
        d, od = [p[f"COMPASS_DIA_{a}"] for a in "XYZ"], [p[f"COMPASS_ODI_{a}"] for a in "XYZ"]
        per_unit = MILLIGAUSS_PER_UNIT[cal.units]
    else:
        p = px4_params(result.text)
        ofs = -np.array([p[f"CAL_MAG0_{a}OFF"] for a in "XYZ"])
        d, od = [p[f"CAL_MAG0_{a}SCALE"] for a in "XYZ"], [p[f"CAL_MAG0_{a}ODIAG"] for a in "XYZ"]
        per_unit = MILLIGAUSS_PER_UNIT[cal.units] * 1e-3
    mat = np.array([[d[0], od[0], od[1]], [od[0], d[1], od[2]], [od[1], od[2], d[2]]])
    theirs = (m * per_unit + ofs) @ mat.T / per_unit
    ours = cal.field(m)  # type: ignore[attr-defined]
    difference = float(np.max(np.linalg.norm(theirs - ours, axis=1)) / cal.field_strength)  # type: ignore[attr-defined]
    assert difference <= WRITTEN_RTOL, (fmt, difference)
    return "exact"


# ----------------------------------------------------------------------------------- the tests
def test_every_registered_calibration_type_and_format_is_in_the_suite() -> None:
    """A calibration type registered without an entry here, or a format without its outcome, fails the suite."""
    covered = {key.split("/")[0] for key in CALIBRATIONS}
    missing = sorted(set(CAL_TYPES) - covered)
    assert not missing, f"calibration type(s) {missing} have no entry in CALIBRATIONS: add one (a real recording's fit)"
    assert {key.split("/", 1)[1] for key in CALIBRATIONS if key.startswith("extended/")} == set(PARAMETRIC)
    for key, entry in CALIBRATIONS.items():
        assert set(entry.expected) == set(EXPORTERS), f"{key}: outcomes for {sorted(set(EXPORTERS) ^ set(entry.expected))}"
        assert set(entry.expected.values()) <= set(OUTCOMES), key
    assert set(CONSUMERS) == set(EXPORTERS)


@pytest.mark.parametrize("key", list(CALIBRATIONS))
@pytest.mark.parametrize("fmt", list(EXPORTERS))
def test_export_reproduces_apply_or_reports_its_loss(cases: dict[str, Case], fmt: str, key: str, tmp_path: Path) -> None:
    assert judge(cases[key], fmt, tmp_path) == CALIBRATIONS[key].expected[fmt]


@pytest.mark.parametrize("key", list(CALIBRATIONS))
def test_a_loss_above_the_users_limit_is_refused_in_one_line(cases: dict[str, Case], key: str) -> None:
    """Each format that reports a loss refuses the combination, in one line, when the user's max_loss_g is below it."""
    case = cases[key]
    for fmt, outcome in CALIBRATIONS[key].expected.items():
        if outcome != "loss":
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityRangeWarning)
            result = export(case.cal, fmt, case.options)
        if result.loss is None or not result.loss.loss_g > 1e-6:  # a gyroscope's loss only (or below a µg)
            continue
        strict = replace(case.options, max_loss_g=result.loss.loss_g / 2)
        with pytest.raises(InputError) as refused, warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityRangeWarning)
            export(case.cal, fmt, strict)
        assert "\n" not in str(refused.value) and "lose too much" in str(refused.value), (fmt, str(refused.value))


def test_the_issues_imucal_export_of_a_ferraris_calibration_through_the_command_line(recordings, tmp_path: Path,
                                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The issue's commands: optcal export --format imucal, read by imucal's calibrate(), against optcal apply (was a
    0.9 deg turn of the accelerometer, 0.30 m/s^2)."""
    management = pytest.importorskip("imucal.management")
    from helpers.cli_run import run_args

    cal = recordings["dir"] / "ferraris.json"
    code, _, err = run_args(capsys, "export", str(cal), "--format", "imucal", "-o", str(tmp_path / "imucal.json"))
    assert code == 0, err
    code, _, err = run_args(capsys, "apply", str(cal), str(FERRARIS), "--rate", "102.4", "--units", "m/s^2", "-o",
                            str(tmp_path / "applied.csv"))
    assert code == 0, err
    raw = pd.read_csv(FERRARIS)
    acc, gyr = management.load_calibration_info(tmp_path / "imucal.json").calibrate(
        raw[["acc_x", "acc_y", "acc_z"]].to_numpy(), raw[["gyr_x", "gyr_y", "gyr_z"]].to_numpy(), "m/s^2", "deg/s")
    applied = pd.read_csv(tmp_path / "applied.csv")
    np.testing.assert_allclose(acc, applied[["ax_m_s2", "ay_m_s2", "az_m_s2"]].to_numpy(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.radians(gyr), applied[["gx_rad_s", "gy_rad_s", "gz_rad_s"]].to_numpy(), rtol=0,
                               atol=1e-12)


def test_a_refused_combination_is_one_line_and_exit_2_on_the_command_line(recordings, capsys) -> None:
    from helpers.cli_run import run_args

    code, out, err = run_args(capsys, "export", str(recordings["dir"] / "xsens_lumped.json"), "--format", "ardupilot",
                              "--counts-per-g", str(XSENS_DRIVER["counts_per_g"]), "--max-loss", "0.001")
    assert code == 2 and out == "" and err.count("\n") == 1 and "lose too much" in err and "Traceback" not in err


# ----------------------------------------------------------------------------------- the docs table
#: Each outcome as the table in docs/exports.md prints it.
OUTCOMES: dict[str, str] = {"exact": "exact", "loss": "loss reported", "refused": "refused", "noise": "noise only"}
DOCS = Path(__file__).resolve().parents[3] / "docs" / "exports.md"
BEGIN, END = "<!-- conformance table: generated by tests/applications/export/test_export_conformance.py -->", "<!-- end -->"


def table_markdown() -> str:
    """The formats × calibrations table of :data:`CALIBRATIONS`' outcomes, as docs/exports.md holds it."""
    keys = list(CALIBRATIONS)
    lines = ["| format | " + " | ".join(f"`{k}`" for k in keys) + " |", "|---" * (len(keys) + 1) + "|"]
    lines += [f"| `{fmt}` | " + " | ".join(OUTCOMES[CALIBRATIONS[k].expected[fmt]] for k in keys) + " |" for fmt in EXPORTERS]
    return "\n".join(lines)


def test_docs_table_is_the_suites() -> None:
    text = DOCS.read_text()
    assert BEGIN in text and END in text, f"{DOCS} lacks the table's markers"
    held = text.split(BEGIN, 1)[1].split(END, 1)[0].strip()
    assert held == table_markdown(), ("docs/exports.md's table differs from the suite's outcomes: regenerate it with "
                                      "PYTHONPATH=.:tests python tests/applications/export/test_export_conformance.py")


if __name__ == "__main__":  # rewrite the table in docs/exports.md from the suite's outcomes
    text = DOCS.read_text()
    head, rest = text.split(BEGIN, 1)
    DOCS.write_text(head + BEGIN + "\n" + table_markdown() + "\n" + END + rest.split(END, 1)[1])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ql_factorisation_turns_a_full_matrix_lower_triangular_by_a_proper_rotation(seed: int) -> None:
    from optcal.applications.export.intrinsics import ql

    A = np.eye(3) + 0.05 * np.random.default_rng(seed).standard_normal((3, 3))
    R, L = ql(A)
    np.testing.assert_allclose(R @ A, L, atol=1e-14)
    assert np.all(np.triu(L, 1) == 0) and np.all(np.diag(L) > 0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0)
    R, L = ql(np.tril(A))  # already lower-triangular: kept as it is
    assert np.array_equal(R, np.eye(3)) and np.array_equal(L, np.tril(A))
