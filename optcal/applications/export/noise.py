"""Noise blocks for estimators from ``optcal allan`` results: VINS, ORB-SLAM3, OKVIS (and the VIO intrinsics' keys).

Every estimator here takes the four continuous-time figures of Kalibr's IMU noise model (the
IMU-Noise-Model wiki page of ethz-asl/kalibr), one per sensor, the same on every axis:

===============================  ===========  =============  ==============  ===============
figure (Allan, Yin 2014)         unit         VINS           ORB-SLAM3       OKVIS
===============================  ===========  =============  ==============  ===============
accelerometer white noise N_a    m/s²/√Hz     ``acc_n``      ``IMU.NoiseAcc``   ``sigma_a_c``
gyroscope white noise N_g        rad/s/√Hz    ``gyr_n``      ``IMU.NoiseGyro``  ``sigma_g_c``
accelerometer bias walk K_a      m/s³/√Hz     ``acc_w``      ``IMU.AccWalk``    ``sigma_aw_c``
gyroscope bias walk K_g          rad/s²/√Hz   ``gyr_w``      ``IMU.GyroWalk``   ``sigma_gw_c``
===============================  ===========  =============  ==============  ===============

Upstream readers: VINS-Fusion ``vins_estimator/src/estimator/parameters.cpp`` (``ACC_N =
fsSettings["acc_n"]`` …, used as densities in ``factor/integration_base.h``); ORB-SLAM3
``src/Tracking.cc`` (``ParseIMUParamFile``: ``IMU.Frequency`` an integer, the four noise keys
reals, ``IMU::Calib(Tbc, Ng·√f, Na·√f, Ngw/√f, Naw/√f)``: continuous-time densities turned
discrete) and ``src/Settings.cc`` (``readIMU``); OKVIS ``okvis_ros``' ``VioParametersReader.cpp``
(``imu_params``: ``sigma_g_c``, ``sigma_a_c``, ``sigma_gw_c``, ``sigma_aw_c``, "_c" for
continuous, beside ``a_max``, ``g_max``, ``sigma_bg``, ``sigma_ba``, ``tau``, ``g``, ``a0``,
``imu_rate`` that the user fills in; ``config/config_fpga_p2_euroc.yaml``).

Each figure is the largest over the axes of the Allan result (the per-axis values in a comment);
a rate random walk the log does not show is refused unless ``random_walk_bound`` (then its
one-sided confidence bound, labelled).  ``inflate = (WHITE, WALK)`` multiplies the white-noise
densities and the walks (the customary margin for unmodelled vibration and temperature); the
factors and the values before them are written into the file.
"""

from __future__ import annotations

from dataclasses import dataclass

from optcal.errors import InputError
from optcal.families.caltypes.base import Calibration
from optcal.applications.export.base import ExportOptions, ExportResult
from optcal.applications.export.kalibr import axis_values, bound_note, random_walk_per_axis, split_allan, update_rate


@dataclass(frozen=True)
class Figure:
    """One noise figure: per axis, the largest axis, its unit and whether some axes hold a bound."""

    name: str
    per_axis: dict[str, float]
    unit: str
    factor: float
    bounded: tuple[str, ...] = ()

    @property
    def measured(self) -> float:
        """The largest axis's value before inflation."""
        return max(self.per_axis.values())

    @property
    def value(self) -> float:
        """The largest axis's value times the inflation factor."""
        return self.measured * self.factor

    def comment(self) -> str:
        axes = ", ".join(f"{a} {v:.4g}" for a, v in self.per_axis.items())
        bound = f"; UPPER BOUND on {', '.join(self.bounded)} (no +1/2 slope in the log)" if self.bounded else ""
        inflated = f"; x{self.factor:g} inflation -> {self.value:.6g}" if self.factor != 1.0 else ""
        return f"# {self.name}, {self.unit}: per axis {axes}; largest {self.measured:.6g}{inflated}{bound}"


@dataclass(frozen=True)
class NoiseModel:
    """The four figures of both sensors (module docstring), the IMU rate, and what to say about them."""

    acc_white: Figure
    acc_walk: Figure
    gyro_white: Figure
    gyro_walk: Figure
    rate_hz: float
    inflate: tuple[float, float]
    notes: tuple[str, ...]

    def comments(self) -> list[str]:
        white, walk = self.inflate
        lines = ["# continuous-time noise from optcal allan (Allan deviation, Yin 2014): white-noise densities and "
                 "bias random walks, the largest axis of each"]
        lines.append(f"# inflation applied: white noise x{white:g}, random walk x{walk:g}"
                     + ("" if self.inflate != (1.0, 1.0) else " (none; --inflate WHITE,WALK sets it)"))
        lines += [f.comment() for f in (self.acc_white, self.gyro_white, self.acc_walk, self.gyro_walk)]
        return lines

    mapped: tuple[str, ...] = ("Allan velocity random walk (accelerometer white noise)",
                               "Allan angle random walk (gyroscope white noise)",
                               "Allan rate random walks of both sensors (bias random walks)")
    dropped: tuple[str, ...] = ("bias instability of both sensors (the estimators' noise models have no such term)",
                                "per-axis differences (one figure per sensor: the largest axis)")


def check_inflation(inflate: tuple[float, float]) -> None:
    if len(inflate) != 2 or not all(f > 0 for f in inflate):
        raise InputError(f"inflate must be two positive factors WHITE,WALK (e.g. 1,1 for none), got {inflate}")


def noise_model(options: ExportOptions, required_by: str) -> NoiseModel | None:
    """The noise figures of ``options``' Allan results, or None without one.

    Raises
    ------
    InputError
        One sensor's result is missing, or a rate random walk is absent and ``random_walk_bound`` not set.
    """
    check_inflation(options.inflate)
    acc, gyro = split_allan(options)
    if acc is None and gyro is None:
        return None
    if acc is None or gyro is None:
        missing = "accelerometer" if acc is None else "gyroscope"
        raise InputError(f"{required_by} needs the noise of both sensors, and the {missing}'s Allan result is missing: "
                         "save one result of both with optcal allan LOG --sensor both --json and pass it as allan=")
    white, walk = options.inflate
    acc_white = axis_values(acc, "velocity_random_walk")
    gyro_white = axis_values(gyro, "angle_random_walk")
    if len(acc_white) < 3 or len(gyro_white) < 3:
        raise InputError("the Allan results lack the white noise of an axis; run optcal allan again")
    acc_walk, acc_bounded = random_walk_per_axis(acc, options.random_walk_bound, "the accelerometer random walk",
                                                 "the accelerometer's Allan result")
    gyro_walk, gyro_bounded = random_walk_per_axis(gyro, options.random_walk_bound, "the gyroscope random walk",
                                                   "the gyroscope's Allan result")
    notes = []
    if acc_bounded:
        notes.append(bound_note(acc, "the accelerometer random walk", acc_bounded))
    if gyro_bounded:
        notes.append(bound_note(gyro, "the gyroscope random walk", gyro_bounded))
    if options.inflate != (1.0, 1.0):
        notes.append(f"inflated: white noise x{white:g}, random walk x{walk:g} (written into the file's comments)")
    return NoiseModel(
        Figure("accelerometer white noise", acc_white, "m/s^2/sqrt(Hz)", white),
        Figure("accelerometer bias random walk", acc_walk, "m/s^3/sqrt(Hz)", walk, tuple(acc_bounded)),
        Figure("gyroscope white noise", gyro_white, "rad/s/sqrt(Hz)", white),
        Figure("gyroscope bias random walk", gyro_walk, "rad/s^2/sqrt(Hz)", walk, tuple(gyro_bounded)),
        update_rate(acc, options), options.inflate, tuple(notes))


def required_noise(options: ExportOptions, fmt: str) -> NoiseModel:
    model = noise_model(options, f"the {fmt} format")
    if model is None:
        raise InputError(f"the {fmt} format is the noise model: pass allan= (optcal allan LOG --sensor both --json)")
    return model


def real(value: float) -> str:
    """A float that OpenCV's FileStorage reads as real (an exponent, never a bare integer)."""
    return f"{value:.9e}"


def block(cal: Calibration, options: ExportOptions, fmt: str, reader: str, keys: list[str],
          header: list[str] | None = None) -> ExportResult:
    """The file: ``%YAML:1.0``, where it comes from, the noise comments, then ``keys``."""
    model = required_noise(options, fmt)
    lines = ["%YAML:1.0",
             f"# {fmt} IMU noise exported by optcal from {options.source} ({cal.describe()}); read by {reader}",
             "# units: continuous time (densities); the estimator turns them into per-sample values itself",
             *model.comments(), *(header or []), *keys]
    dropped = [*model.dropped, f"the calibration itself ({cal.describe()}): this block holds only the noise model"]
    return ExportResult(fmt, "\n".join(lines) + "\n", None, list(model.mapped), dropped, list(model.notes))


def export_vins(cal: Calibration, options: ExportOptions) -> ExportResult:
    """VINS-Mono / VINS-Fusion: ``acc_n``, ``gyr_n``, ``acc_w``, ``gyr_w`` (module docstring)."""
    m = required_noise(options, "vins")
    keys = [f"acc_n: {real(m.acc_white.value)}  # accelerometer white noise [ m/s^2/sqrt(Hz) ]",
            f"gyr_n: {real(m.gyro_white.value)}  # gyroscope white noise [ rad/s/sqrt(Hz) ]",
            f"acc_w: {real(m.acc_walk.value)}  # accelerometer bias random walk [ m/s^3/sqrt(Hz) ]",
            f"gyr_w: {real(m.gyro_walk.value)}  # gyroscope bias random walk [ rad/s^2/sqrt(Hz) ]",
            f"g_norm: {options.gravity_m_s2:.9g}  # gravity magnitude [ m/s^2 ] (the calibration's 1 g)"]
    return block(cal, options, "vins", "VINS-Fusion vins_estimator/src/estimator/parameters.cpp", keys)


def export_orbslam3(cal: Calibration, options: ExportOptions) -> ExportResult:
    """ORB-SLAM3: ``IMU.NoiseGyro``, ``IMU.NoiseAcc``, ``IMU.GyroWalk``, ``IMU.AccWalk``, ``IMU.Frequency``."""
    m = required_noise(options, "orbslam3")
    frequency = int(round(m.rate_hz))
    keys = [f"IMU.NoiseGyro: {real(m.gyro_white.value)}  # [ rad/s/sqrt(Hz) ]",
            f"IMU.NoiseAcc: {real(m.acc_white.value)}  # [ m/s^2/sqrt(Hz) ]",
            f"IMU.GyroWalk: {real(m.gyro_walk.value)}  # [ rad/s^2/sqrt(Hz) ]",
            f"IMU.AccWalk: {real(m.acc_walk.value)}  # [ m/s^3/sqrt(Hz) ]",
            f"IMU.Frequency: {frequency}  # [ Hz ] (an integer: Tracking.cc reads it with isInt)"]
    result = block(cal, options, "orbslam3", "ORB-SLAM3 src/Tracking.cc (ParseIMUParamFile) and src/Settings.cc (readIMU)",
                   keys)
    if abs(frequency - m.rate_hz) > 1e-6 * m.rate_hz:
        result.notes.append(f"IMU.Frequency is read as an integer: the log's {m.rate_hz:.6g} Hz is written as {frequency}")
    result.notes.append("ORB-SLAM3 also needs IMU.T_b_c1 (the camera-IMU transform), which optcal does not know")
    return result


def export_okvis(cal: Calibration, options: ExportOptions) -> ExportResult:
    """OKVIS: ``imu_params: sigma_g_c, sigma_a_c, sigma_gw_c, sigma_aw_c`` (the rest left to fill in)."""
    m = required_noise(options, "okvis")
    keys = ["imu_params:",
            f"    sigma_g_c: {real(m.gyro_white.value)}  # gyro noise density [ rad/s/sqrt(Hz) ]",
            f"    sigma_a_c: {real(m.acc_white.value)}  # accelerometer noise density [ m/s^2/sqrt(Hz) ]",
            f"    sigma_gw_c: {real(m.gyro_walk.value)}  # gyro drift noise density [ rad/s^2/sqrt(Hz) ]",
            f"    sigma_aw_c: {real(m.acc_walk.value)}  # accelerometer drift noise density [ m/s^3/sqrt(Hz) ]",
            f"    g: {options.gravity_m_s2:.9g}  # gravity [ m/s^2 ] (the calibration's 1 g)",
            f"    imu_rate: {int(round(m.rate_hz))}  # [ Hz ]",
            "    # a_max, g_max, sigma_bg, sigma_ba, tau, a0 and T_BS are not optcal's to give: fill them in"]
    result = block(cal, options, "okvis", "OKVIS VioParametersReader.cpp (imu_params)", keys)
    result.notes.append("OKVIS's reader also requires imu_params a_max, g_max, sigma_bg, sigma_ba, tau, a0 and T_BS: "
                        "merge this block into your config, which has them")
    return result
