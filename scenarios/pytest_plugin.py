"""pytest plugin: every scenario YAML becomes a test, so teams gate CI on their own folders.

Installed with hilnav (entry point ``pytest11``) but inert until asked for::

    pytest --hilnav scenarios/library            # every *.yaml / *.yml scenario is a test
    pytest --hilnav my_scenarios --hilnav-out out/ci --hilnav-bridge gmdh

A scenario test passes when ``hilnav run`` would exit 0: the flight finished and every pass
criterion holds. A failure lists the failed criteria with value and limit; each run folder
(summary.json, junit.xml, report.html, run.tlog) is kept under ``--hilnav-out`` (default: a
``hilnav`` folder in pytest's temporary directory). A file that is not a valid scenario fails
with the loader's one-line message (file, line, key).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hilnav", "hilnav scenario files as tests")
    group.addoption("--hilnav", action="store_true", default=False,
                    help="collect hilnav scenario YAML files as tests")
    group.addoption("--hilnav-out", default=None,
                    help="folder for the run folders (default: pytest's tmp dir)")
    group.addoption("--hilnav-bridge", default=None, help="override the bridging method")
    group.addoption("--hilnav-altitude", default=None, help="override the altitude method")
    group.addoption("--hilnav-seed", default=None, type=int, help="override the seed")


def pytest_collect_file(parent: pytest.Collector, file_path: Path) -> pytest.Collector | None:
    if not parent.config.getoption("hilnav"):
        return None
    if file_path.suffix not in (".yaml", ".yml"):
        return None
    return ScenarioFile.from_parent(parent, path=file_path)


class ScenarioFile(pytest.File):
    def collect(self) -> Iterator[pytest.Item]:
        yield ScenarioItem.from_parent(self, name=self.path.stem)


class ScenarioFailed(Exception):
    """The scenario ran and at least one criterion failed (or the flight ended early)."""


class ScenarioItem(pytest.Item):
    def runtest(self) -> None:
        from scenarios.runner import run_scenario
        from scenarios.schema import load_scenario

        cfg = self.config
        scn = load_scenario(self.path)
        overrides: dict[str, Any] = {
            "seed": cfg.getoption("hilnav_seed"),
            "bridge": cfg.getoption("hilnav_bridge"),
            "altitude": cfg.getoption("hilnav_altitude"),
        }
        given = {k: v for k, v in overrides.items() if v is not None}
        if given:
            scn = scn.with_overrides(**given)
        base = cfg.getoption("hilnav_out")
        root = Path(base) if base else cfg._tmp_path_factory.getbasetemp() / "hilnav"  # type: ignore[attr-defined]
        if scn.autopilot.unaided_baseline:  # both flights, one card
            from scenarios.unaided_baseline import run_with_unaided_baseline

            result = run_with_unaided_baseline(scn, root / self.path.stem)
        else:
            result = run_scenario(scn, root / self.path.stem)
        s = result.summary
        self.user_properties.append(("run_folder", str(result.out_dir)))
        problems = [
            f"{c['name']}: {c['value']} (limit {c.get('op', '<=')} {c['limit']})"
            for c in s.get("criteria", []) if not c["ok"]
        ]
        ended = s.get("health", {}).get("flight_ended")
        if ended:
            problems.insert(0, f"the flight ended early: {ended}")
        if problems or not result.passed:
            raise ScenarioFailed("; ".join(problems) or "not passed")

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException],
                     style: Any = None) -> str:
        if isinstance(excinfo.value, ScenarioFailed | ValueError):
            return f"{self.path.name}: {excinfo.value}"
        return str(super().repr_failure(excinfo, style))

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.path, 0, f"hilnav scenario {self.path.name}"
