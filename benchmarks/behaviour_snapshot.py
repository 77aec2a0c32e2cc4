"""Behaviour snapshot of the ``optcal`` command line: proof that a restructuring changes no output.

Before a restructuring (modules moved between subpackages, behaviour meant to stay the same),
``capture`` runs a fixed list of ``optcal`` command lines (:data:`CASES`) on the real recordings
in ``../shared/data`` and writes what each one did: its exit code, its standard output (the
``--json`` object, or the text lines of commands that print text, such as ``export``), its
standard error lines and the files it wrote.  After the restructuring the same capture is taken
again and ``compare`` reports, path by path, whatever differs.  Exit codes and ``error: ...``
lines are behaviour too: cases that end with exit code 2 are part of the list.

Notes
-----
Only the command line is used.  Every case runs
``sys.executable -c "import sys; from optcal.cli.main import main; sys.exit(main())" ARGS...``:
``optcal.cli.main:main`` is the console-script entry point and keeps its path, and it *returns*
the exit code, so the ``sys.exit`` is what makes it the process's exit code (as the installed
``optcal`` script does).  No other optcal module is imported, so this script runs unchanged on both
sides of the restructuring.  Which ``optcal`` runs is decided by the interpreter's ``sys.path``:
put an untouched checkout first on ``PYTHONPATH`` to capture the old code (``_meta.json`` records
the package folder that was found).

Every case (and its setup commands, e.g. saving a calibration that ``check`` or ``export`` then
reads) runs in a fresh temporary directory holding a symbolic link ``data`` to the shared
recordings, so data paths appear in the output as the same relative names (``data/...``) in every
run, and files the case writes (``cal.json``, ``results.parquet``) under the same relative names.
Absolute paths that still appear (the case directory, the shared folder, the optcal package
folder, each also in its resolved form) are replaced by ``<CASE_DIR>``, ``<SHARED>`` and
``<OPTCAL>``.  Files the case wrote are recorded too: JSON parsed, text as lines, binary files
(Parquet) by name only.  The children run with ``PYTHONHASHSEED=0`` and one BLAS/OpenMP thread
(:data:`CHILD_ENV`), so that no number depends on hash randomisation or on how a reduction was
split over threads, and with ``PYTHONDONTWRITEBYTECODE=1``, so that no ``__pycache__`` is written
into the checkouts; the commands' own seeds (``diagnose``, ``plan``, ``simulate``) stay at their
fixed default, 0.

``capture OUTDIR [--shared PATH] [--only NAME ...] [--timeout S]`` writes ``OUTDIR/<case>.json``
per case and ``OUTDIR/_meta.json`` (interpreter, optcal folder, wall time per case; never
compared).  ``--shared`` defaults to the ``shared/data`` folder beside the repository
(``<repo>/../shared/data``).  The 36 cases take 40-70 s on the 2-core machine (45 s idle).  ``list`` prints
the command lines.

``compare DIR_A DIR_B [--rtol 1e-12] [--atol 1e-12]`` compares two captures recursively: the same
cases, keys, list lengths, strings, booleans, nulls and exit codes; numbers ``a`` (DIR_A) and
``b`` (DIR_B) equal when ``|a - b| <= atol + rtol * |b|``; numbers inside strings and text lines
(``export`` files, error lines) are compared the same way and the rest of the string exactly.
Keys named in :data:`IGNORED_KEYS` (wall-clock times) are skipped wherever they occur.  It prints
one line per differing path (``case:path: before=... after=...``) and a summary line, and exits 0
when the captures are identical, 1 otherwise (2 on a usage error).

Needs the standard library only (the children need optcal and its dependencies).

Examples
--------
Capture the old code, then the new one, and compare::

    PYTHONPATH=/tmp/work/before .venv/bin/python benchmarks/behaviour_snapshot.py capture /tmp/work/snap_before
    .venv/bin/python benchmarks/behaviour_snapshot.py capture /tmp/work/snap_after
    .venv/bin/python benchmarks/behaviour_snapshot.py compare /tmp/work/snap_before /tmp/work/snap_after
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Keys whose values are not behaviour, skipped by ``compare`` wherever they occur (found by
#: reading the captured JSON and by two captures of the same code).  Keep this list short.
IGNORED_KEYS: dict[str, str] = {
    # wall-clock time of one solver call (calibrate --json, the saved calibration, --imu gyro_fit.solver)
    "solve_time_s": "wall-clock time of the solver",
    # wall-clock time of the whole fleet run (fleet --json summary)
    "seconds": "wall-clock time of the fleet run",
}

#: Name of the link to the shared recordings inside every case directory.
DATA_LINK = "data"

#: Recordings used by the cases (relative to the case directory, through :data:`DATA_LINK`).
XSENS = f"{DATA_LINK}/imutk-xsens/xsens_imutk.csv"
MIKOFF = f"{DATA_LINK}/mikoff-mpu9150/imu{{}}.log"
MIKOFF0, MIKOFF1 = MIKOFF.format(0), MIKOFF.format(1)
MPU6050 = f"{DATA_LINK}/mpu6050-imucalibration/example_data_calibration.csv"
MPU6050_STILL = f"{DATA_LINK}/mpu6050-imucalibration/example_data_tinit_calc.csv"
INNALABS_MAT = f"{DATA_LINK}/hassan-innalabs-m3/CalibrationOfLowCostTriaxialInertialSensors50.mat"
CK_HOLDS = f"{DATA_LINK}/ckexplorer-holds/acc_log.csv"
SUNSIDED_STILL = f"{DATA_LINK}/sunsided-mpu6050/set-2/unmoved-with-x-pointing-forward-10min/mpu6050.csv"

#: Placeholders of the absolute paths that are replaced in every output.
CASE_DIR, SHARED, OPTCAL = "<CASE_DIR>", "<SHARED>", "<OPTCAL>"

#: Environment of every child: no hash randomisation, one BLAS/OpenMP thread, no display, and no
#: ``__pycache__`` written into the checkouts being compared.
CHILD_ENV: dict[str, str] = {
    "PYTHONHASHSEED": "0",
    "PYTHONDONTWRITEBYTECODE": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "MPLBACKEND": "Agg",
    "TZ": "UTC",
}

#: How the command line is entered (the console script ``optcal = optcal.cli.main:main``).
ENTRY = "import sys; from optcal.cli.main import main; sys.exit(main())"

#: Default time limit of one command, seconds.
DEFAULT_TIMEOUT_S = 300.0

#: A number inside a string (compared with the tolerance by ``compare``).
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|(?<![A-Za-z_])[-+]?(?:nan|inf)(?![A-Za-z_])")


@dataclass(frozen=True)
class Step:
    """One optcal command run before a case, in its directory (e.g. saving a calibration).

    Attributes
    ----------
    args : tuple of str
        The optcal arguments.
    stdout_to : str, optional
        File (relative to the case directory) that receives the step's standard output.
    """

    args: tuple[str, ...]
    stdout_to: str | None = None


@dataclass(frozen=True)
class Case:
    """One optcal command line of the snapshot.

    Attributes
    ----------
    name : str
        File stem of the case's record (``<name>.json``).
    args : tuple of str
        The optcal arguments (data paths relative to the case directory).
    setup : tuple of Step
        Commands run first in the same directory; their results are recorded too.
    note : str
        What the case covers (and the exit code expected when it is not 0).
    """

    name: str
    args: tuple[str, ...]
    setup: tuple[Step, ...] = ()
    note: str = ""


# the setup calibrations print JSON too: the text report states the solver's wall-clock time in its
# text, where no key can be ignored, while the JSON keeps it under solve_time_s (IGNORED_KEYS)
_SAVE_MIKOFF_CAL = Step(("calibrate", MIKOFF0, "--rate", "100", "--json", "-o", "cal.json"))
_SAVE_MIKOFF_IMU = Step(("calibrate", MIKOFF0, "--rate", "100", "--imu", "--json", "-o", "imu.json"))
_SAVE_XSENS_CAL = Step(("calibrate", XSENS, "--json", "-o", "cal.json"))

#: The command lines of the snapshot, in the order they run.
CASES: tuple[Case, ...] = (
    # calibrate: the four kinds of recording, three methods, the refusals
    Case("calibrate_xsens", ("calibrate", XSENS, "--json", "-o", "cal.json"),
         note="imu_tk's Xsens log (raw counts, time column); the calibration file is recorded too"),
    Case("calibrate_xsens_gd", ("calibrate", XSENS, "--method", "gd", "--json"), note="the gradient-descent baseline"),
    Case("calibrate_xsens_convex", ("calibrate", XSENS, "--method", "convex", "--json"), note="the cvxpy fit alone"),
    Case("calibrate_mikoff_imu0", ("calibrate", MIKOFF0, "--rate", "100", "--json"),
         note="one MPU-9150 unit: headerless, no time column"),
    Case("calibrate_mikoff_imu0_no_rate", ("calibrate", MIKOFF0, "--json"),
         note="exit 2: no time column and no --rate"),
    Case("calibrate_mpu6050", ("calibrate", MPU6050, "--json"),
         note="exit 2: the MPU-6050 log's 10 poses determine one combination only weakly"),
    Case("calibrate_mpu6050_allow_degenerate", ("calibrate", MPU6050, "--allow-degenerate", "--json"),
         note="the same log, fitted anyway"),
    Case("calibrate_pose_table_mat", ("calibrate", INNALABS_MAT, "--json"),
         note="exit 2: the only pose tables in shared/data are MATLAB files, which optcal does not read"),
    Case("calibrate_ckexplorer_holds", ("calibrate", CK_HOLDS, "--rate", "100", "--json"),
         note="exit 2: 160 holds with no motion between them, refused as a recording that never rests"),
    Case("calibrate_pose_table_simulated",
         ("calibrate", "poses.csv", "--json"),
         setup=(Step(("simulate", "--schedule", "uniform", "-n", "120", "--sigma", "0.001", "-o", "poses.csv")),),
         note="a text pose table (written by optcal simulate, seed 0)"),
    Case("calibrate_sixpos_simulated",
         ("calibrate", "six.csv", "--method", "sixpos", "--json"),
         setup=(Step(("simulate", "--schedule", "sixpos", "--sigma", "0.001", "-o", "six.csv")),),
         note="six-position least squares on a simulated six-face pose table"),
    Case("calibrate_bad_method", ("calibrate", XSENS, "--method", "bogus", "--json"),
         note="exit 2: a usage error (invalid choice)"),
    # calibrate --imu: accelerometer and gyroscope
    Case("calibrate_imu_xsens", ("calibrate", XSENS, "--imu", "--json", "-o", "imu.json"),
         note="the Xsens log's gyro columns (merged into the CSV: the separate gyro file is not in shared/data)"),
    Case("calibrate_imu_mikoff_imu0", ("calibrate", MIKOFF0, "--rate", "100", "--imu", "--json"),
         note="gyro in rad/s, no time column"),
    # diagnose
    Case("diagnose_xsens", ("diagnose", XSENS, "--json", "-o", "ext.json"),
         note="200 simulations, seed 0; the saved final model is recorded too"),
    Case("diagnose_mikoff_imu0", ("diagnose", MIKOFF0, "--rate", "100", "--json")),
    # check: a saved calibration on another unit's recording
    Case("check_mikoff_cal_on_imu1", ("check", "cal.json", MIKOFF1, "--rate", "100", "--json"),
         setup=(_SAVE_MIKOFF_CAL,)),
    Case("check_mikoff_imu_cal_on_imu1", ("check", "imu.json", MIKOFF1, "--rate", "100", "--json"),
         setup=(_SAVE_MIKOFF_IMU,), note="cal_type imu: adds the gravity-prediction check of the moves"),
    # plan
    Case("plan_poses_12", ("plan", "--poses", "12", "--json")),
    Case("plan_next_mpu6050", ("plan", "--next", MPU6050, "--target-stderr", "1e-3", "--json")),
    Case("plan_next_mikoff_imu0", ("plan", "--next", MIKOFF0, "--rate", "100", "--json")),
    Case("plan_no_request", ("plan", "--json"), note="exit 2: neither --poses nor --next"),
    # export of a saved calibration (m/s^2) in every format; output is text, the report on stderr
    *(Case(f"export_{fmt}", ("export", "cal.json", "--format", fmt), setup=(_SAVE_MIKOFF_CAL,))
      for fmt in ("ardupilot", "px4", "ros", "c")),
    Case("export_kalibr_no_allan", ("export", "cal.json", "--format", "kalibr"), setup=(_SAVE_MIKOFF_CAL,),
         note="exit 2: kalibr needs --allan"),
    Case("export_kalibr_with_allan",
         ("export", "cal.json", "--format", "kalibr", "--allan", "allan.json", "--random-walk-bound"),
         setup=(_SAVE_MIKOFF_CAL, Step(("allan", SUNSIDED_STILL, "--json"), stdout_to="allan.json")),
         note="kalibr with an Allan result of a 10-minute still log (no +1/2 slope: the labelled bound)"),
    Case("export_ardupilot_counts_no_scale", ("export", "cal.json", "--format", "ardupilot"),
         setup=(_SAVE_XSENS_CAL,), note="exit 2: a calibration in counts needs --counts-per-g"),
    # fleet over the five MPU-9150 units (Dask, one worker)
    Case("fleet_mikoff",
         ("fleet", f"{DATA_LINK}/mikoff-mpu9150/imu*.log", "--rate", "100", "--workers", "1", "--no-progress",
          "-o", "results.parquet", "--json"),
         note="the glob is expanded by optcal (no shell); the Parquet table is recorded by name only"),
    # segment
    Case("segment_xsens", ("segment", XSENS, "--json")),
    Case("segment_mpu6050", ("segment", MPU6050, "--json"), note="rate from the file's 'Fs,100' header"),
    # allan on still logs
    Case("allan_sunsided_10min", ("allan", SUNSIDED_STILL, "--json"), note="g, bursty host time stamps"),
    Case("allan_sunsided_10min_gyro", ("allan", SUNSIDED_STILL, "--sensor", "gyro", "--json")),
    Case("allan_mpu6050_still", ("allan", MPU6050_STILL, "--counts-per-g", "16384", "--json")),
    Case("allan_mpu6050_still_no_scale", ("allan", MPU6050_STILL, "--json"),
         note="exit 2: counts need --counts-per-g"),
)


# ----------------------------------------------------------------------------------------------- capture


def repo_root() -> Path:
    """The repository holding this script (the parent of ``benchmarks/``)."""
    return Path(__file__).resolve().parent.parent


def default_shared() -> Path:
    """The shared recordings beside the repository, ``<repo>/../shared/data``."""
    return repo_root().parent / "shared" / "data"


def optcal_location() -> str | None:
    """Folder of the ``optcal`` package this interpreter finds (located, not imported).

    Returns
    -------
    str or None
        The package folder, or ``None`` when no ``optcal`` is on the path.
    """
    spec = importlib.util.find_spec("optcal")
    if spec is None or not spec.submodule_search_locations:
        return None
    return str(list(spec.submodule_search_locations)[0])


class Normaliser:
    """Replaces the absolute paths that differ from run to run by placeholders.

    Parameters
    ----------
    replacements : sequence of (str, str)
        ``(path, placeholder)`` pairs; each path is also replaced in its resolved form, the
        longest path first (so a folder inside another gets its own placeholder).
    """

    def __init__(self, replacements: Sequence[tuple[str, str]]) -> None:
        pairs: dict[str, str] = {}
        for path, placeholder in replacements:
            for form in {path, os.path.realpath(path)}:
                if form and form != os.sep:
                    pairs[form.rstrip(os.sep)] = placeholder
        self.pairs: list[tuple[str, str]] = sorted(pairs.items(), key=lambda kv: -len(kv[0]))

    def text(self, s: str) -> str:
        """Return ``s`` with every known path replaced by its placeholder."""
        for path, placeholder in self.pairs:
            s = s.replace(path, placeholder)
        return s

    def value(self, obj: Any) -> Any:
        """Return a parsed JSON value with every string (keys too) passed through :meth:`text`."""
        if isinstance(obj, str):
            return self.text(obj)
        if isinstance(obj, list):
            return [self.value(v) for v in obj]
        if isinstance(obj, dict):
            return {self.text(k): self.value(v) for k, v in obj.items()}
        return obj


def child_env() -> dict[str, str]:
    """The environment of every optcal child process.

    Returns
    -------
    dict of str to str
        The current environment with :data:`CHILD_ENV` over it and ``PYTHONPATH`` made absolute
        (the children run in their own directories, where a relative entry would point elsewhere).
    """
    env = dict(os.environ)
    env.update(CHILD_ENV)
    if env.get("PYTHONPATH"):
        env["PYTHONPATH"] = os.pathsep.join(os.path.abspath(p) for p in env["PYTHONPATH"].split(os.pathsep) if p)
    return env


def child_optcal_location(cwd: Path) -> str | None:
    """Folder of the ``optcal`` package a child process finds in ``cwd`` (located, not imported).

    Parameters
    ----------
    cwd : Path
        Directory the child runs in.

    Returns
    -------
    str or None
        The package folder, or ``None`` when the child finds no ``optcal``.
    """
    code = ("import importlib.util; s = importlib.util.find_spec('optcal'); "
            "print(list(s.submodule_search_locations)[0] if s and s.submodule_search_locations else '')")
    out = subprocess.run([sys.executable, "-c", code], cwd=cwd, env=child_env(), capture_output=True, text=True,
                         check=True).stdout.strip()
    return out or None


def run_optcal(args: Sequence[str], cwd: Path, timeout_s: float) -> tuple[int | None, str, str]:
    """Run ``optcal ARGS`` through its entry point (:data:`ENTRY`) in a child process.

    Parameters
    ----------
    args : sequence of str
        The optcal arguments.
    cwd : Path
        Directory the command runs in.
    timeout_s : float
        Time limit, seconds.

    Returns
    -------
    exit_code : int or None
        The process's exit code, ``None`` when it was stopped at the time limit.
    stdout, stderr : str
        What it printed.
    """
    cmd = [sys.executable, "-c", ENTRY, *args]
    try:
        proc = subprocess.run(cmd, cwd=cwd, env=child_env(), capture_output=True, text=True, timeout=timeout_s,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
        return None, out, err + f"\n<timed out after {timeout_s:g} s>"
    return proc.returncode, proc.stdout, proc.stderr


def parse_stdout(stdout: str, norm: Normaliser) -> tuple[str, Any]:
    """Standard output as ``("json", object)``, ``("text", lines)`` or ``("empty", None)``.

    Parameters
    ----------
    stdout : str
        What the command printed on standard output.
    norm : Normaliser
        Replaces the run's absolute paths.

    Returns
    -------
    kind : str
        ``"json"``, ``"text"`` or ``"empty"``.
    content : object
        The parsed JSON value, the list of lines, or ``None``.
    """
    if not stdout.strip():
        return "empty", None
    try:
        return "json", norm.value(json.loads(stdout))
    except json.JSONDecodeError:
        return "text", norm.text(stdout).splitlines()


def read_files(case_dir: Path, norm: Normaliser) -> dict[str, Any]:
    """The files a case wrote in its directory (the ``data`` link excluded).

    Parameters
    ----------
    case_dir : Path
        The case's directory.
    norm : Normaliser
        Replaces the run's absolute paths.

    Returns
    -------
    dict of str to dict
        Relative name -> ``{"kind": "json", "content": value}``, ``{"kind": "text", "content":
        lines}`` or ``{"kind": "binary"}`` (binary files, e.g. Parquet, by name only).
    """
    out: dict[str, Any] = {}
    for path in sorted(case_dir.rglob("*")):
        rel = path.relative_to(case_dir)
        if rel.parts[0] == DATA_LINK or not path.is_file():
            continue
        try:
            text = path.read_bytes().decode("utf-8")
        except UnicodeDecodeError:
            out[rel.as_posix()] = {"kind": "binary"}
            continue
        try:
            out[rel.as_posix()] = {"kind": "json", "content": norm.value(json.loads(text))}
        except json.JSONDecodeError:
            out[rel.as_posix()] = {"kind": "text", "content": norm.text(text).splitlines()}
    return out


def record_run(args: Sequence[str], case_dir: Path, norm: Normaliser, timeout_s: float,
               stdout_to: str | None = None) -> dict[str, Any]:
    """Run one optcal command in ``case_dir`` and describe what it did.

    Parameters
    ----------
    args : sequence of str
        The optcal arguments.
    case_dir : Path
        Directory the command runs in.
    norm : Normaliser
        Replaces the run's absolute paths.
    timeout_s : float
        Time limit, seconds.
    stdout_to : str, optional
        File (relative to ``case_dir``) that receives the standard output as printed.

    Returns
    -------
    dict
        ``argv``, ``exit_code``, ``stdout_kind``, ``stdout`` and ``stderr`` (lines), normalised.
    """
    code, stdout, stderr = run_optcal(args, case_dir, timeout_s)
    if stdout_to is not None:
        (case_dir / stdout_to).write_text(stdout)
    kind, parsed = parse_stdout(stdout, norm)
    return {
        "argv": ["optcal", *args],
        "exit_code": code,
        "stdout_kind": kind,
        "stdout": parsed,
        "stderr": norm.text(stderr).splitlines(),
    }


def capture_case(case: Case, shared: Path, work: Path, optcal_dir: str | None, timeout_s: float) -> dict[str, Any]:
    """Run one case (setup steps first) in a fresh directory and return its record.

    Parameters
    ----------
    case : Case
        The case.
    shared : Path
        The shared recordings (resolved), linked into the case directory as ``data``.
    work : Path
        Folder the case directory is made in (removed afterwards).
    optcal_dir : str or None
        The optcal package folder, replaced by ``<OPTCAL>`` in the output.
    timeout_s : float
        Time limit of each command, seconds.

    Returns
    -------
    dict
        ``case``, ``note``, ``setup`` (when there are setup steps), the fields of
        :func:`record_run` and ``files`` (:func:`read_files`).
    """
    case_dir = Path(tempfile.mkdtemp(prefix=f"{case.name}-", dir=work))
    try:
        (case_dir / DATA_LINK).symlink_to(shared, target_is_directory=True)
        replacements = [(str(case_dir), CASE_DIR), (str(shared), SHARED)]
        if optcal_dir:
            replacements.append((optcal_dir, OPTCAL))
        norm = Normaliser(replacements)
        setup = [record_run(step.args, case_dir, norm, timeout_s, step.stdout_to) for step in case.setup]
        record: dict[str, Any] = {"case": case.name, "note": case.note}
        if setup:
            record["setup"] = setup
        record.update(record_run(case.args, case_dir, norm, timeout_s))
        record["files"] = read_files(case_dir, norm)
        return record
    finally:
        shutil.rmtree(case_dir, ignore_errors=True)


def capture(outdir: Path, shared: Path, only: Sequence[str] | None, timeout_s: float) -> int:
    """Run the cases and write ``outdir/<case>.json`` and ``outdir/_meta.json``.

    Parameters
    ----------
    outdir : Path
        Capture folder (created when missing).
    shared : Path
        The shared recordings.
    only : sequence of str, optional
        Run only the cases of these names.
    timeout_s : float
        Time limit of each command, seconds.

    Returns
    -------
    int
        0, or 2 when the shared folder or a case name is wrong or no optcal is found.
    """
    if not shared.is_dir():
        print(f"error: the shared recordings are not at {shared} (give --shared PATH)", file=sys.stderr)
        return 2
    unknown = set(only or ()) - {c.name for c in CASES}
    if unknown:
        print(f"error: unknown case(s): {', '.join(sorted(unknown))}", file=sys.stderr)
        return 2
    cases = [c for c in CASES if not only or c.name in only]
    outdir.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="optcal-snapshot-") as work:
        optcal_dir = child_optcal_location(Path(work))
        if optcal_dir is None:
            print("error: the interpreter finds no optcal package (install it or set PYTHONPATH)", file=sys.stderr)
            return 2
        print(f"optcal from {optcal_dir} (python {sys.executable}); shared data {shared}", file=sys.stderr)
        for case in cases:
            t0 = time.perf_counter()
            record = capture_case(case, shared.resolve(), Path(work), optcal_dir, timeout_s)
            timings[case.name] = round(time.perf_counter() - t0, 2)
            (outdir / f"{case.name}.json").write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n")
            print(f"{case.name}: exit {record['exit_code']} ({timings[case.name]:.1f} s)", file=sys.stderr)
    total = time.perf_counter() - start
    meta = {
        "python": sys.executable,
        "python_version": sys.version,
        "optcal_location": optcal_dir,
        "pythonpath": os.environ.get("PYTHONPATH"),
        "shared": str(shared),
        "child_env": CHILD_ENV,
        "cases": [c.name for c in cases],
        "wall_s_per_case": timings,
        "wall_s_total": round(total, 2),
        "captured_at_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    (outdir / "_meta.json").write_text(json.dumps(meta, indent=1) + "\n")
    print(f"{len(cases)} cases captured in {total:.1f} s into {outdir}", file=sys.stderr)
    return 0


# ----------------------------------------------------------------------------------------------- compare


@dataclass(frozen=True)
class Tolerance:
    """When two numbers count as equal: ``|a - b| <= atol + rtol * |b|`` (``a`` before, ``b`` after).

    Attributes
    ----------
    rtol, atol : float
        Relative and absolute tolerance.
    """

    rtol: float
    atol: float

    def equal(self, a: float, b: float) -> bool:
        """Whether ``a`` and ``b`` agree (NaN equals NaN; an infinity only the same infinity)."""
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        if math.isinf(a) or math.isinf(b):
            return a == b
        return abs(a - b) <= self.atol + self.rtol * abs(b)


def is_number(x: Any) -> bool:
    """Whether ``x`` is a JSON number (``bool`` is not, although Python counts it as ``int``)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def strings_equal(a: str, b: str, tol: Tolerance) -> bool:
    """Whether two strings are equal, or the same text around numbers that agree within ``tol``.

    Parameters
    ----------
    a, b : str
        The strings, before and after.
    tol : Tolerance
        Tolerance of the numbers inside them.

    Returns
    -------
    bool
        True when equal in that sense.
    """
    if a == b:
        return True
    if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
        return False
    na, nb = _NUMBER.findall(a), _NUMBER.findall(b)
    return len(na) == len(nb) and all(tol.equal(float(x), float(y)) for x, y in zip(na, nb))


def shown(x: Any, limit: int = 160) -> str:
    """``x`` as JSON, cut to about ``limit`` characters, for a difference line."""
    s = json.dumps(x, ensure_ascii=False)
    return s if len(s) <= limit + 10 else s[:limit] + "..."


def differences(a: Any, b: Any, tol: Tolerance, path: str = "") -> Iterator[tuple[str, Any, Any]]:
    """Every difference between two parsed JSON values, keys of :data:`IGNORED_KEYS` skipped.

    Parameters
    ----------
    a, b : object
        The values, before and after.
    tol : Tolerance
        Tolerance of the numbers (and of the numbers inside strings).
    path : str
        Where ``a`` and ``b`` are (``stdout.params.o_x``, ``stderr[0]``).

    Yields
    ------
    path : str
        Where they differ (``<length>`` for lists of different lengths).
    before, after : object
        The two values there (``"<missing>"`` for a key or element only one side has).
    """
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b), key=str):
            if key in IGNORED_KEYS:
                continue
            sub = f"{path}.{key}" if path else str(key)
            if key not in b:
                yield sub, a[key], "<missing>"
            elif key not in a:
                yield sub, "<missing>", b[key]
            else:
                yield from differences(a[key], b[key], tol, sub)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{path}.<length>", len(a), len(b)
        for i, (x, y) in enumerate(zip(a, b)):
            yield from differences(x, y, tol, f"{path}[{i}]")
        for i in range(min(len(a), len(b)), max(len(a), len(b))):  # the elements only one side has
            yield f"{path}[{i}]", a[i] if i < len(a) else "<missing>", b[i] if i < len(b) else "<missing>"
    elif is_number(a) and is_number(b):
        if not tol.equal(float(a), float(b)):
            yield path, a, b
    elif isinstance(a, str) and isinstance(b, str):
        if not strings_equal(a, b, tol):
            yield path, a, b
    elif a != b or type(a) is not type(b):  # booleans, nulls, or values of different types
        yield path, a, b


def compare(dir_a: Path, dir_b: Path, tol: Tolerance) -> int:
    """Print every difference between two captures and a summary line.

    Parameters
    ----------
    dir_a, dir_b : Path
        The captures, before and after (``_meta.json`` and other ``_*`` files are not compared).
    tol : Tolerance
        Tolerance of the numbers.

    Returns
    -------
    int
        0 when the captures are identical, 1 when they differ, 2 when a folder is missing.
    """
    for d in (dir_a, dir_b):
        if not d.is_dir():
            print(f"error: {d} is not a capture folder", file=sys.stderr)
            return 2
    names_a = {p.stem for p in dir_a.glob("*.json") if not p.name.startswith("_")}
    names_b = {p.stem for p in dir_b.glob("*.json") if not p.name.startswith("_")}
    n_diff, cases_differing = 0, 0
    for name in sorted(names_a | names_b):
        if name not in names_a or name not in names_b:
            print(f"{name}: case only in {dir_a if name in names_a else dir_b}")
            n_diff += 1
            cases_differing += 1
            continue
        found = list(differences(json.loads((dir_a / f"{name}.json").read_text()),
                                 json.loads((dir_b / f"{name}.json").read_text()), tol))
        for path, before, after in found:
            print(f"{name}:{path}: before={shown(before)} after={shown(after)}")
        n_diff += len(found)
        cases_differing += bool(found)
    n_cases = len(names_a | names_b)
    settings = f"rtol {tol.rtol:g}, atol {tol.atol:g}; ignored keys: {', '.join(IGNORED_KEYS)}"
    if n_diff == 0:
        print(f"identical: {n_cases} cases ({settings})")
        return 0
    print(f"DIFFERENT: {n_diff} difference(s) in {cases_differing} of {n_cases} cases ({settings})")
    return 1


# ----------------------------------------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    """The parser of the ``capture``, ``compare`` and ``list`` sub-commands."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    cap = sub.add_parser("capture", help="run the cases and write OUTDIR/<case>.json")
    cap.add_argument("outdir", type=Path)
    cap.add_argument("--shared", type=Path, default=default_shared(),
                     help="folder of the shared recordings [<repo>/../shared/data]")
    cap.add_argument("--only", nargs="+", default=None, metavar="NAME", help="run only these cases")
    cap.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, help="time limit of one command, s")
    cmp_ = sub.add_parser("compare", help="compare two captures (exit 0 when identical, 1 otherwise)")
    cmp_.add_argument("dir_a", type=Path, help="the capture before")
    cmp_.add_argument("dir_b", type=Path, help="the capture after")
    cmp_.add_argument("--rtol", type=float, default=1e-12)
    cmp_.add_argument("--atol", type=float, default=1e-12)
    sub.add_parser("list", help="print the case names and their command lines")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run this script's command line.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status.
    """
    ns = build_parser().parse_args(argv)
    if ns.command == "capture":
        return int(capture(ns.outdir, ns.shared, ns.only, ns.timeout))
    if ns.command == "compare":
        return int(compare(ns.dir_a, ns.dir_b, Tolerance(ns.rtol, ns.atol)))
    for case in CASES:
        steps = "".join(f"optcal {' '.join(s.args)}{' > ' + s.stdout_to if s.stdout_to else ''}; " for s in case.setup)
        print(f"{case.name}: {steps}optcal {' '.join(case.args)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
