"""Parameter files (hil.autopilot.param_file): ArduPilot's NAME VALUE lines and PX4's
QGroundControl lines, and one FILE:LINE sentence for every bad file."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.autopilot.param_file import (
    PARAM_TYPE_INT32,
    PARAM_TYPE_REAL32,
    ParamFileError,
    ParamValue,
    read_param_file,
)


def test_ardupilot_lines_blank_or_comma_separated_with_comments(tmp_path: Path) -> None:
    path = tmp_path / "a.parm"
    path.write_text("# C172\nARSPD_SKIP_CAL 1\n\nTRIM_ARSPD_CM,4500  # cruise\n"
                    "ARSPD_OFFSET\t-1.5\n")
    assert read_param_file(path) == [
        ParamValue("ARSPD_SKIP_CAL", 1.0, PARAM_TYPE_REAL32, 2),
        ParamValue("TRIM_ARSPD_CM", 4500.0, PARAM_TYPE_REAL32, 4),
        ParamValue("ARSPD_OFFSET", -1.5, PARAM_TYPE_REAL32, 5),
    ]


def test_qgroundcontrol_lines_keep_their_type(tmp_path: Path) -> None:
    path = tmp_path / "p.params"
    path.write_text("# Onboard parameters for Vehicle 1\n#\n# Vehicle-Id Component-Id Name "
                    "Value Type\n1\t1\tFW_AIRSPD_TRIM\t45.000000000000000000\t9\n"
                    "1\t1\tNAV_DLL_ACT\t0\t6\n")
    assert read_param_file(path) == [
        ParamValue("FW_AIRSPD_TRIM", 45.0, PARAM_TYPE_REAL32, 4),
        ParamValue("NAV_DLL_ACT", 0.0, PARAM_TYPE_INT32, 5),
    ]


@pytest.mark.parametrize(("text", "line", "words"), [
    ("A 1\nB\n", 2, "expected NAME VALUE"),
    ("A 1\nB x\n", 2, "the value of B is not a number: 'x'"),
    ("A nan\n", 1, "must be finite"),
    ("A 1\nA 2\n", 2, "A is set twice (also on line 1)"),
    ("1 1 A 2 77\n", 1, "is not a MAV_PARAM_TYPE"),
    ("x y A 2 9\n", 1, "numbers first"),
    ("THIS_NAME_IS_TOO_LONG 1\n", 1, "at most 16 characters"),
    ("# nothing\n", 1, "no parameter in the file"),
])
def test_a_bad_file_is_one_line_with_file_and_line(tmp_path: Path, text: str, line: int,
                                                    words: str) -> None:
    path = tmp_path / "bad.parm"
    path.write_text(text)
    with pytest.raises(ParamFileError) as err:
        read_param_file(path)
    message = str(err.value)
    assert message.startswith(f"{path}:{line}: ")
    assert words in message and "\n" not in message


def test_a_missing_file_says_so(tmp_path: Path) -> None:
    with pytest.raises(ParamFileError, match="cannot read the parameter file"):
        read_param_file(tmp_path / "none.parm")
