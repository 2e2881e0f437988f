"""Leaving without the final garbage collection never costs a file its buffered data.

GIVEN a process about to exit, WHEN ``freeze_for_exit`` decides whether to freeze the live
objects (so the shutdown collections skip them), THEN it freezes only when no buffered file is
open for writing, and a file left open (even in a reference cycle) is still flushed.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from scenarios.cli.quick_exit import QUICK_EXIT_COMMANDS, command_of


def _python(code: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          check=False, timeout=60)


def test_nothing_open_for_writing_freezes() -> None:
    proc = _python("import sys\n"
                   "from scenarios.cli.quick_exit import freeze_for_exit\n"
                   "print('unflushed stdout line', end='')\n"
                   "sys.exit(0 if freeze_for_exit() else 3)\n")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "unflushed stdout line"  # the standard streams are still flushed


@pytest.mark.parametrize("during_set_up", [False, True])
def test_a_file_left_open_in_a_reference_cycle_blocks_the_freeze_and_is_flushed(
        tmp_path: Path, during_set_up: bool) -> None:
    """Opened at the top level, or inside the settled heap (so frozen since the set-up)."""
    path = tmp_path / "left-open.txt"
    opener = "with settled_heap():\n    " if during_set_up else ""
    proc = _python("import sys\n"
                   "from scenarios.cli.quick_exit import freeze_for_exit, settled_heap\n"
                   "class Holder:\n"
                   "    pass\n"
                   "h = Holder()\n"
                   "h.me = h  # a cycle: a plain exit flushes this file, a frozen one would not\n"
                   f"{opener}h.f = open(sys.argv[1], 'w')\n"
                   "h.f.write('x' * 1000)\n"
                   "sys.exit(4 if freeze_for_exit() else 0)\n", str(path))
    assert proc.returncode == 0, proc.stderr
    assert path.read_text() == "x" * 1000


def test_an_offline_command_exits_with_its_code_and_complete_output(tmp_path: Path) -> None:
    out = tmp_path / "schema.json"
    proc = subprocess.run([sys.executable, "-m", "scenarios.cli", "schema", "--out", str(out)],
                          capture_output=True, text=True, check=False, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "properties" in json.loads(out.read_text())
    bad = subprocess.run([sys.executable, "-m", "scenarios.cli", "schema", "--out",
                          str(tmp_path)], capture_output=True, text=True, check=False,
                         timeout=120)
    assert bad.returncode == 2
    assert "is a folder" in bad.stderr and "Traceback" not in bad.stderr


def test_only_offline_commands_are_named() -> None:
    assert command_of(["run", "x.yaml", "--out", "d"]) == "run"
    assert command_of(["--help"]) is None
    assert command_of([]) is None
    assert {"up", "fusion", "monitor", "sim", "router", "check", "campaign"}.isdisjoint(
        QUICK_EXIT_COMMANDS)


def test_the_settled_heap_freezes_without_collecting_and_leaves_the_collector_on() -> None:
    import gc
    import weakref

    from scenarios.cli.quick_exit import settled_heap

    class Node:
        me: Node | None = None

    assert gc.isenabled()
    frozen_before = gc.get_freeze_count()
    try:
        with settled_heap():
            assert not gc.isenabled()
            cycle = Node()
            cycle.me = cycle
            alive = weakref.ref(cycle)
            del cycle
        assert gc.isenabled()
        assert gc.get_freeze_count() > frozen_before
        gc.collect()
        assert alive() is not None  # frozen, not collected: no collection traversed the heap
    finally:
        gc.unfreeze()
        gc.collect()
    assert alive() is None  # unfrozen, it is ordinary garbage again
