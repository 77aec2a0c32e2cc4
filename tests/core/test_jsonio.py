"""The one JSON writer and reader (optcal.core.jsonio): strict JSON, the file layout, the errors, the format version."""

import json

import numpy as np
import pytest

from optcal.core.jsonio import FORMAT_VERSION, check_version, json_text, jsonable, parse_version, read_json, write_json
from optcal.errors import InputError

SAMPLE = {
    "T": np.eye(3) * 0.5,
    "o": (np.float32(1.5), np.int64(2), np.bool_(True)),
    "chisqr": float("nan"),
    "aic": np.float64("-inf"),
    3: "key made a string",
    "nested": [{"a": np.arange(2)}],
}


def test_jsonable_makes_numpy_plain_and_non_finite_null():
    d = jsonable(SAMPLE)
    assert d == {"T": [[0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]], "o": [1.5, 2, True], "chisqr": None,
                 "aic": None, "3": "key made a string", "nested": [{"a": [0, 1]}]}
    assert type(d["o"][1]) is int and type(d["o"][2]) is bool
    assert jsonable(d) == d  # idempotent: a converted object passes through unchanged


def test_write_json_layout_is_the_files_of_before(tmp_path):
    """Indented by 2, one trailing newline, keys in the given order: what optcal wrote before the writer was shared."""
    path = tmp_path / "out.json"
    write_json(path, SAMPLE)
    text = path.read_text()
    assert text == json.dumps(jsonable(SAMPLE), indent=2) + "\n"
    assert text.endswith("}\n") and not text.endswith("\n\n") and "NaN" not in text and "Infinity" not in text
    assert list(json.loads(text)) == ["T", "o", "chisqr", "aic", "3", "nested"]


def test_json_text_is_one_strict_line():
    text = json_text(SAMPLE)
    assert "\n" not in text and text == json.dumps(jsonable(SAMPLE), allow_nan=False)
    assert json.loads(text)["chisqr"] is None


def test_read_json_errors_name_the_file_and_what_it_should_be(tmp_path):
    with pytest.raises(InputError, match=r"missing.json: no such calibration file$"):
        read_json(tmp_path / "missing.json")
    with pytest.raises(InputError, match=r"no such calibration file"):
        read_json(tmp_path)  # a folder is not a file
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(InputError, match=r"broken.json: not a JSON calibration file \(Expecting"):
        read_json(broken)
    with pytest.raises(InputError, match=r"not a JSON Allan result file \(.*\); save one with optcal allan"):
        read_json(broken, "Allan result file", hint="save one with optcal allan LOG --json > broken.json")
    broken.write_text("[1, 2]")
    with pytest.raises(InputError, match=r"not an optcal calibration file \(not a JSON object\)"):
        read_json(broken)
    good = tmp_path / "good.json"
    write_json(good, SAMPLE)
    assert read_json(good) == jsonable(SAMPLE)


def test_format_version():
    assert FORMAT_VERSION == "2.0"
    assert parse_version("2.7") == (2, 7) and parse_version(1) == (1, 0)
    assert check_version("2.9") == (2, 9)  # a newer minor version only adds optional fields
    with pytest.raises(InputError, match=r"format version 3.0, newer than this optcal reads \(2.x"):
        check_version("3.0")
    with pytest.raises(InputError, match="optcal files start at version 1"):
        check_version(0)
    for bad in (True, "two"):
        with pytest.raises(InputError, match="is not a version number"):
            parse_version(bad)
