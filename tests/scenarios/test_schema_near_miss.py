"""A misspelt required key is named as the misspelling, not only as a missing key."""

from __future__ import annotations

from pathlib import Path

import pytest

from scenarios.schema import ScenarioError, load_scenario


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def test_misspelt_required_key_names_the_misspelling(tmp_path: Path) -> None:
    """GIVEN a scenario whose only duration key is misspelt ``duraton_s``
    WHEN it is loaded
    THEN the error is at that key's line and names the misspelling and the key it stands for."""
    path = _write(tmp_path, "name: x\nduraton_s: 120\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert err.key == "duraton_s" and err.line == 2
    assert "unknown key 'duraton_s' (did you mean 'duration_s'?)" in str(err)


def test_missing_required_key_without_near_miss_stays_missing(tmp_path: Path) -> None:
    """GIVEN a scenario without a duration and an unrelated unknown key
    WHEN it is loaded THEN the missing key is reported as missing."""
    path = _write(tmp_path, "name: x\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert info.value.key == "duration_s" and "required key is missing" in str(info.value)
