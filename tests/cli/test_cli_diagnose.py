"""``optcal diagnose`` and ``optcal demo`` on the command line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers.diagnosis_cases import make_case, write_table

from optcal.cli.main import main


def test_json_is_exactly_one_object_with_the_finding(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    case = make_case("temperature_bias", 21)
    path = write_table(case, tmp_path / "poses.csv")
    code = main(["diagnose", str(path), "--json", "--simulations", "20", "--plot", str(tmp_path / "fig")])
    out = capsys.readouterr()
    assert code == 0, out.err
    obj = json.loads(out.out)  # exactly one JSON object on stdout
    assert obj["n_poses"] == case.poses.n and obj["data"]["kind"] == "pose table"
    assert [f["effect"] for f in obj["findings"]] == ["temperature_bias"]
    f = obj["findings"][0]
    assert f["axes"] == [case.axis] and f["estimate"][case.axis] == pytest.approx(case.value, rel=0.3)
    assert obj["final"]["gain"] > 1 and obj["final"]["heldout_rms_g"] < obj["baseline"]["heldout_rms_g"]
    assert f["sensor"] == "accelerometer"  # issue 39's contract: one findings list for both sensors
    assert obj["gain"] == pytest.approx(obj["baseline"]["heldout_rms_g"] / obj["final"]["heldout_rms_g"])
    assert {Path(p).name for p in obj["figures"]} == {"residuals.png", "simulation_check.png"}
    assert all(Path(p).stat().st_size > 1000 for p in obj["figures"])


def test_text_report(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    case = make_case(None, 22)
    path = write_table(case, tmp_path / "poses.csv")
    assert main(["diagnose", str(path), "--simulations", "20"]) == 0
    out = capsys.readouterr().out
    assert "read as a pose table" in out and "Simulation check" in out
    assert "none: the paper's model explains these data" in out and "gain 1×" in out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--effects", "temperature_bias"], "temperature_bias: no temperature column"),
        (["--effects", "wind"], "unknown effect"),
        (["--sensor", "mag", "--heldout-se", "1"], "--heldout-se applies to the accelerometer's diagnosis"),
    ],
)
def test_bad_input_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], message: str) -> None:
    path = write_table(make_case(None, 23), tmp_path / "poses.csv", temp=False)
    assert main(["diagnose", str(path), *args]) == 2
    err = capsys.readouterr().err
    assert "error: " in err and message in err and "Traceback" not in err and err.count("\n") == 1


def test_constant_temperature_and_too_few_poses(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    case = make_case(None, 24)
    case.poses.temp = np.full(case.poses.n, 25.0)
    path = write_table(case, tmp_path / "poses.csv")
    assert main(["diagnose", str(path), "--effects", "temperature_scale"]) == 2
    assert "temperature is constant" in capsys.readouterr().err
    small = make_case(None, 25, n_range=(11, 11))
    path = write_table(small, tmp_path / "small.csv")
    assert main(["diagnose", str(path)]) == 2
    err = capsys.readouterr().err
    assert "11 poses are too few for a diagnosis" in err
    # one line: what is missing and what to do (issue 39: never "nothing found" below 12 poses)
    assert "record 1 more rest in new orientations" in err and "optcal calibrate" in err
    assert len([line for line in err.splitlines() if "too few" in line]) == 1


def test_demo_needs_no_files_and_reveals_the_truth_at_the_end(capsys: pytest.CaptureFixture) -> None:
    assert main(["demo", "--hidden", "temperature_bias", "--seed", "4", "--simulations", "20"]) == 0
    out = capsys.readouterr().out
    reveal = out.index("6. The reveal")
    hidden_axis_line = out[reveal:]
    assert "temperature_bias on axis" in hidden_axis_line
    assert "named the right effect on the right axis" in hidden_axis_line
    assert "gain of" in out[:reveal] and "Hidden in the recording" not in out[:reveal]


def test_demo_with_data(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = write_table(make_case("scale_nonlinearity", 26), tmp_path / "poses.csv")
    assert main(["demo", "--data", str(path), "--simulations", "10"]) == 0
    out = capsys.readouterr().out
    assert "scale_nonlinearity" in out and "6. The reveal" not in out


def test_baseline_method_and_saved_calibration(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """--method gd and --baseline cal.json start the diagnosis from that calibration and say so."""
    case = make_case("temperature_bias", 27)
    path = write_table(case, tmp_path / "poses.csv")
    assert main(["calibrate", str(path), "--method", "convex", "-o", str(tmp_path / "cal.json")]) == 0
    capsys.readouterr()
    runs = {}
    for args in (["--method", "gd"], ["--baseline", str(tmp_path / "cal.json")], []):
        assert main(["diagnose", str(path), "--json", "--quiet", "--simulations", "0", *args]) == 0
        out = capsys.readouterr()
        assert out.err == ""  # --quiet: no progress
        runs[tuple(args[:1])] = json.loads(out.out)
    assert runs[("--method",)]["baseline"]["calibration"] == "the gd calibration"
    assert runs[("--baseline",)]["baseline"]["calibration"] == "the given calibration"
    # the refit reaches the same maximum-likelihood baseline and the same finding from every start
    for obj in runs.values():
        assert obj["baseline"]["rms_g"] == pytest.approx(runs[()]["baseline"]["rms_g"], rel=1e-4)  # weights are taken at the start
        assert [f["effect"] for f in obj["findings"]] == ["temperature_bias"]


def test_diagnose_saves_the_extended_model_and_it_corrects_better_than_lumped(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A raw recording with a planted temperature coefficient: diagnose -o, then apply the file to the static poses.

    The extended calibration halves (at least) the rms |a| − 1 of the lumped calibration applied the
    same way, and reproduces the diagnosis's own final rms within 10 %.
    """
    import optcal.families.calibration_files as calibration_files
    from optcal.data import load
    from optcal.families.simulate.effects import recording_with_effect

    frame, truth = recording_with_effect("temperature_bias", seed=2)
    rec = tmp_path / "rec.csv"
    frame.to_csv(rec, index=False, float_format="%.6f")
    assert main(["calibrate", str(rec), "-o", str(tmp_path / "lumped.json")]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(rec), "--simulations", "0", "--json", "--quiet", "-o", str(tmp_path / "ext.json")]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert [f["effect"] for f in obj["findings"]] == ["temperature_bias"] and obj["findings"][0]["axes"] == [truth.axis]
    assert obj["saved"]["cal_type"] == "extended"
    poses = load(rec)
    extended, lumped = calibration_files.load(tmp_path / "ext.json"), calibration_files.load(tmp_path / "lumped.json")
    assert extended.cal_type == "extended" and extended.validity.to_dict()["temp"] is not None

    def rms_error(cal) -> float:
        return float(np.sqrt(np.mean((np.linalg.norm(cal.correct(poses.acc, temp=poses.temp, t=poses.t), axis=1) - 1) ** 2)))

    assert rms_error(extended) <= 0.5 * rms_error(lumped)
    assert rms_error(extended) == pytest.approx(obj["final"]["rms_g"], rel=0.1)

    # The same through `optcal apply`: the corrected recordings, averaged over the static intervals
    # that segmentation found in the raw recording (the row count is unchanged by apply).
    from optcal.data import load_with_segmentation

    intervals = load_with_segmentation(rec).segmentation.intervals
    applied_rms = {}
    for name in ("ext", "lumped"):
        out = tmp_path / f"{name}_applied.csv"
        assert main(["apply", str(tmp_path / f"{name}.json"), str(rec), "-o", str(out)]) == 0
        corrected = pd.read_csv(out)
        assert len(corrected) == len(frame)
        acc = corrected[["ax_g", "ay_g", "az_g"]].to_numpy()
        means = np.array([acc[i.start:i.stop].mean(axis=0) for i in intervals])
        applied_rms[name] = float(np.sqrt(np.mean((np.linalg.norm(means, axis=1) - 1) ** 2)))
    capsys.readouterr()
    assert applied_rms["ext"] <= 0.5 * applied_rms["lumped"]
    assert applied_rms["ext"] == pytest.approx(obj["final"]["rms_g"], rel=0.1)


def test_baseline_in_other_units_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A baseline calibration fitted on data in other units is refused, as check and apply refuse it."""
    case = make_case("temperature_bias", 27)
    path = write_table(case, tmp_path / "poses.csv")
    assert main(["calibrate", str(path), "--method", "convex", "-o", str(tmp_path / "cal.json")]) == 0
    cal = json.loads((tmp_path / "cal.json").read_text())
    assert cal["units"]["input"] == "g"
    cal["units"]["input"] = "counts"
    (tmp_path / "cal_ms2.json").write_text(json.dumps(cal))
    capsys.readouterr()
    code = main(["diagnose", str(path), "--quiet", "--simulations", "0", "--baseline", str(tmp_path / "cal_ms2.json")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "baseline calibration is for data in counts but the poses are in g" in err


def test_nothing_found_saves_the_lumped_baseline(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = write_table(make_case(None, 28), tmp_path / "poses.csv")
    assert main(["diagnose", str(path), "--simulations", "0", "-o", str(tmp_path / "cal.json")]) == 0
    assert "saved: " in capsys.readouterr().out
    import optcal.families.calibration_files as calibration_files

    assert calibration_files.load(tmp_path / "cal.json").cal_type == "lumped"
