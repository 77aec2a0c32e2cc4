"""Kalibr: an ``imu.yaml`` noise model from an ``optcal allan --json`` result.

Upstream definition (ethz-asl/kalibr, ``aslam_offline_calibration/kalibr/python/kalibr_common/
ConfigReader.py``, ``ImuParameters``; the IMU-Noise-Model wiki page): keys ``rostopic``,
``update_rate`` (Hz), ``accelerometer_noise_density`` (m/s²/√Hz, continuous-time white noise;
Kalibr uses ``density · √update_rate`` per sample) and ``accelerometer_random_walk`` (m/s³/√Hz,
bias diffusion); both must be positive.  optcal's Allan result gives the velocity random walk
``N`` in m/s/√s (= m/s²/√Hz) and the rate random walk ``K`` in m/s²/√s (= m/s³/√Hz) per axis
(Yin 2014; :mod:`optcal.families.noise.allan`): the largest over the axes is written, each axis in a comment.
A log too short to show the rate random walk's +1/2 slope has no ``K``; with
``ExportOptions.random_walk_bound`` the Allan result's one-sided 95 % confidence bound is written
instead (``K ≤ σ_up(τ_L)·√(3/τ_L)``, σ_up the χ² upper confidence limit of the Allan deviation at
the longest τ with Greenhall's equivalent degrees of freedom,
:func:`optcal.families.noise.allan.rate_random_walk_confidence_bound`), labelled as a bound in the
file and the notes.
The gyroscope keys ``gyroscope_noise_density`` (rad/s/√Hz) and ``gyroscope_random_walk``
(rad/s²/√Hz) come from the gyroscope's Allan result: the ``gyroscope`` half of an
``optcal allan --sensor both --json`` result, or an ``optcal allan --sensor gyro --json`` result
(``gyro_allan``); the angle random walk and the rate random walk of the largest axis (its bound
with ``random_walk_bound``, as for the accelerometer).  Without one they are left as comments.
"""

from __future__ import annotations

from optcal.families.caltypes.base import Calibration
from optcal.errors import InputError
from optcal.applications.export.base import ExportOptions, ExportResult

AXIS_NAMES: tuple[str, str, str] = ("x", "y", "z")


def axis_values(allan: dict, key: str) -> dict[str, float]:
    """The per-axis value of ``key`` in an Allan result, axes without it left out."""
    return {a: float(allan[a][key]) for a in AXIS_NAMES if allan[a].get(key) is not None}


def update_rate(allan: dict, options: ExportOptions) -> float:
    """The IMU rate: ``options.rate_hz``, else the Allan log's."""
    rate = options.rate_hz if options.rate_hz is not None else allan.get("log", {}).get("rate_hz")
    if rate is None or not rate > 0:
        raise InputError("no update rate: give rate_hz (the IMU topic's rate, Hz)")
    return float(rate)


def split_allan(options: ExportOptions) -> tuple[dict | None, dict | None]:
    """The accelerometer's and the gyroscope's Allan results of ``options`` (either may be None).

    ``options.allan`` is an accelerometer result, or an ``optcal allan --sensor both`` result
    holding both; ``options.gyro_allan`` a gyroscope result.

    Raises
    ------
    InputError
        A gyroscope result given as ``allan``, or the gyroscope given twice.
    """
    acc, gyro = options.allan, options.gyro_allan
    if acc is not None and acc.get("sensor") == "both":
        if gyro is not None:
            raise InputError("allan already holds the gyroscope (optcal allan --sensor both): drop gyro_allan")
        acc, gyro = acc["accelerometer"], acc["gyroscope"]
    if acc is not None and acc.get("sensor") == "gyro":
        raise InputError("allan is a gyro Allan result: pass it as gyro_allan, and the accelerometer's as allan "
                         "(or one optcal allan LOG --sensor both --json result as allan)")
    if gyro is not None and gyro.get("sensor") != "gyro":
        raise InputError("gyro_allan is not a gyro Allan result: save one with optcal allan LOG --sensor gyro --json "
                         "(or --sensor both, passed as allan)")
    return acc, gyro


def random_walk_per_axis(allan: dict, random_walk_bound: bool, key: str,
                         result: str = "the Allan result") -> tuple[dict[str, float], list[str]]:
    """The rate random walk per axis of an Allan result, and the axes where it is only the confidence bound.

    Parameters
    ----------
    allan : dict
        An ``optcal allan --json`` result, either sensor.
    random_walk_bound : bool
        Write the result's ``rate_random_walk_bound`` (the one-sided confidence bound from the
        longest τ) on axes whose log shows no +1/2 slope, instead of leaving them out.
    key : str
        The key the value goes to (named in the refusal).
    result : str
        How the refusal names the result.

    Raises
    ------
    InputError
        When no axis has a rate random walk and the bound is not asked for (or not in the result).
    """
    walk = axis_values(allan, "rate_random_walk")
    bounded = [a for a in AXIS_NAMES if a not in walk]
    if bounded and random_walk_bound:
        if any(not isinstance(allan[a].get("rate_random_walk_bound"), dict) for a in bounded):
            raise InputError(f"{result} has no rate_random_walk_bound (an older optcal wrote it); "
                             "run optcal allan again to get one")
        walk.update({a: float(allan[a]["rate_random_walk_bound"]["value"]) for a in bounded})
    elif not walk:
        raise InputError(
            f"{result} has no rate random walk on any axis (the log is too short to show the +1/2 slope); "
            f"the estimator needs {key} > 0: record a longer static log, or pass random_walk_bound=True "
            "to write the upper bound the log allows"
        )
    else:
        bounded = []
    return walk, bounded


def bound_note(allan: dict, key: str, bounded: list[str]) -> str:
    """The note saying that ``key`` is an upper confidence bound on the axes ``bounded``, with the τ of each."""
    first = allan[bounded[0]]["rate_random_walk_bound"]
    taus = ", ".join(f"{a} at tau {allan[a]['rate_random_walk_bound']['tau_s']:.4g} s" for a in bounded)
    return (f"{key} is an upper bound, not a measurement, on axes {', '.join(bounded)}: the log "
            f"shows no +1/2 slope, so K <= sigma_up(tau)*sqrt(3/tau), sigma_up the {first['confidence']:.0%} "
            f"one-sided confidence limit of the Allan deviation at the longest tau ({taus}); "
            "a longer static log measures it")


def gyroscope_lines(gyro_allan: dict, random_walk_bound: bool = False) -> tuple[list[str], list[str]]:
    """The Kalibr gyroscope keys from an ``optcal allan --sensor gyro --json`` result, each axis in a comment, and notes."""
    if gyro_allan.get("sensor") != "gyro":
        raise InputError("gyro_allan is not a gyro Allan result: save one with optcal allan LOG --sensor gyro --json")
    arw = axis_values(gyro_allan, "angle_random_walk")
    if not arw or not max(arw.values()) > 0:
        raise InputError("the gyro Allan result has no angle random walk; Kalibr needs gyroscope_noise_density > 0")
    rrw, bounded = random_walk_per_axis(gyro_allan, random_walk_bound, "gyroscope_random_walk", "the gyro Allan result")
    lines = [
        "# gyro angle random walk per axis, rad/s/sqrt(Hz): " + ", ".join(f"{a} {v:.4g}" for a, v in arw.items()),
        "# gyro rate random walk per axis, rad/s^2/sqrt(Hz): " + ", ".join(f"{a} {v:.4g}" for a, v in rrw.items())
        + (f" (UPPER BOUND on {', '.join(bounded)}: no +1/2 slope in the log)" if bounded else ""),
        f"gyroscope_noise_density: {max(arw.values()):.9g}  # [ rad / s / sqrt(Hz) ]",
        f"gyroscope_random_walk: {max(rrw.values()):.9g}  # [ rad / s^2 / sqrt(Hz) ]"
        + (" UPPER BOUND" if max(rrw, key=rrw.__getitem__) in bounded else ""),
    ]
    return lines, [bound_note(gyro_allan, "gyroscope_random_walk", bounded)] if bounded else []


def export(cal: Calibration, options: ExportOptions) -> ExportResult:
    """The Kalibr ``imu.yaml`` of the Allan result in ``options.allan`` (the measured noise, never inflated)."""
    if options.inflate != (1.0, 1.0):
        raise InputError("inflate (--inflate) applies to vins, orbslam3, okvis, kalibr-imu, openvins and basalt; the "
                         "kalibr format writes the measured noise (use kalibr-imu for an inflated Kalibr file)")
    acc_allan, gyro_allan = split_allan(options)
    if acc_allan is None:
        raise InputError("the kalibr format needs the noise model: pass allan= (an optcal allan --json result); "
                         "optcal allan LOG --sensor both --json gives both sensors")
    density = axis_values(acc_allan, "velocity_random_walk")
    if not density:
        raise InputError("the Allan result has no velocity random walk on any axis; Kalibr needs accelerometer_noise_density > 0")
    walk, bounded = random_walk_per_axis(acc_allan, options.random_walk_bound, "accelerometer_random_walk")
    rate = update_rate(acc_allan, options)

    def per_axis(values: dict[str, float]) -> str:
        return ", ".join(f"{a} {v:.4g}" for a, v in values.items())

    lines = [
        f"# Kalibr IMU noise model exported by optcal (calibration: {options.source}, {cal.describe()})",
        "# keys as read by kalibr_common/ConfigReader.py (ImuParameters); the largest axis is written",
        f"# velocity random walk per axis, m/s^2/sqrt(Hz): {per_axis(density)}",
        f"# rate random walk per axis, m/s^3/sqrt(Hz): {per_axis(walk)}"
        + (f" (UPPER BOUND on {', '.join(bounded)}: no +1/2 slope in the log)" if bounded else ""),
        f"rostopic: {options.rostopic}",
        f"update_rate: {rate:.9g}",
        f"accelerometer_noise_density: {max(density.values()):.9g}  # [ m / s^2 / sqrt(Hz) ]",
        f"accelerometer_random_walk: {max(walk.values()):.9g}  # [ m / s^3 / sqrt(Hz) ]"
        + (" UPPER BOUND" if max(walk, key=walk.__getitem__) in bounded else ""),
    ]
    mapped = ["Allan velocity random walk (noise density)", "Allan rate random walk (random walk)"]
    notes: list[str] = []
    if bounded:
        notes.append(bound_note(acc_allan, "accelerometer_random_walk", bounded))
    if gyro_allan is not None:
        gyro_lines, gyro_notes = gyroscope_lines(gyro_allan, options.random_walk_bound)
        lines += gyro_lines
        notes += gyro_notes
        mapped += ["gyro Allan angle random walk (gyroscope noise density)",
                   "gyro Allan rate random walk (gyroscope random walk)"]
    else:
        lines += ["# gyroscope_noise_density: not given (optcal allan LOG --sensor gyro --json); fill in (rad/s/sqrt(Hz))",
                  "# gyroscope_random_walk: not given (optcal allan LOG --sensor gyro --json); fill in (rad/s^2/sqrt(Hz))"]
        notes.append("Kalibr also needs gyroscope_noise_density and gyroscope_random_walk: give an "
                     "optcal allan --sensor both --json result (allan), or a --sensor gyro one (gyro_allan), "
                     "or fill them in")
    dropped = [f"the calibration itself ({cal.describe()}: biases, scales, misalignment): Kalibr's imu.yaml holds "
               "only the noise model (--format kalibr-imu writes the intrinsics)",
               "bias instability (Kalibr's noise model has no such term)"]
    return ExportResult("kalibr", "\n".join(lines) + "\n", None, mapped, dropped, notes)
