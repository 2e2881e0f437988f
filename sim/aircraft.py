"""The JSBSim aircraft hilnav offers, the start at which each trims, and how one is loaded.

Aircraft files may declare CSV outputs into the working directory, output sockets and
listening input sockets; the adapter loads a private copy of the aircraft without those
directives, so a flight writes no files and opens no sockets. What JSBSim logs while it loads
or trims (warnings of some wheel aircraft, trim reports) is dropped
(:func:`jsbsim_log_discarded`).
"""

from __future__ import annotations

import contextlib
import re
import shutil
import tempfile
from collections.abc import Iterator
from functools import lru_cache
from pathlib import Path
from typing import Any

import jsbsim

from sim.flight_config import StartState

# The wheel aircraft this adapter offers: each was checked (jsbsim 1.3.3, 50 Hz, cruise plan)
# to load, trim and hold straight and level flight for 60 s (altitude within 20 m, airspeed
# within 3 m/s, bank within 5 deg) when started at the (altitude m, true airspeed m/s) given
# here, which ``suggested_start`` returns. c172x and c310 also fly every packaged plan.
# Not offered: non-aeroplanes (ball, ballx, blank, mk82, weather-balloon, Submarine_Scout,
# ZLT-NT, F450, ah1s, paraglider, pogo-jsbsim, Pterosaur), gliders and rocket planes that
# cannot hold level flight (SGS, sgs126, sgs233, minisgs, Shuttle, X15, x24b), aircraft that
# reference FlightGear-only properties and fail to initialise stand-alone (dr1, f104,
# fokker50, fokker100, L17), and aircraft that did not trim or did not hold level flight in
# that check (listed with the measured outcome in the hilnav report).
_VERIFIED: dict[str, tuple[float, float]] = {
    "737": (3000.0, 140.0),
    "787-8": (3000.0, 140.0),
    "A320": (3000.0, 140.0),
    "A4": (3000.0, 100.0),
    "B747": (3000.0, 100.0),
    "Boeing314": (1000.0, 50.0),
    "c172p": (1000.0, 50.0),
    "c172r": (1000.0, 50.0),
    "c172x": (1000.0, 50.0),
    "c182": (1000.0, 50.0),
    "c310": (1000.0, 50.0),
    "DHC6": (1000.0, 50.0),
    "f15": (3000.0, 100.0),
    "f16": (3000.0, 100.0),
    "F4N": (3000.0, 100.0),
    "F80C": (3000.0, 100.0),
    "global5000": (3000.0, 100.0),
    "J3Cub": (1000.0, 25.0),
    "OV10": (1000.0, 70.0),
    "pa28": (1000.0, 50.0),
    "Short_S23": (1000.0, 50.0),
    "T37": (1000.0, 50.0),
    "T38": (3000.0, 140.0),
    "t6texan2": (1000.0, 50.0),
}

# Aircraft files may declare data outputs (CSV files written into the working directory,
# sockets to localhost) and network inputs (listening sockets). A simulator library must do
# neither, so these top-level elements -- the ones with attributes; FCS components use bare
# <input>/<output> tags -- are dropped from a private copy of the aircraft before loading.
_IO_ELEMENT = re.compile(
    r"<(input|output)\s+[^>]*?(?:/>|>.*?</\1\s*>)", flags=re.DOTALL | re.IGNORECASE
)

# JSBSim's generic Autopilot system (systems/Autopilot.xml; the c172x and global5000 load it)
# writes its ground-steering switch to fcs/steer-cmd-norm at every frame -- 0 unless its own
# autopilot steers -- which takes the nose wheel from every other pilot. The private copy
# carries that system without this one output, in the aircraft's own Systems/ folder (JSBSim
# looks there before the shared folder), so the rudder can steer the nose wheel on a ground
# start. Nothing else reads the property, so a flight in the air is unchanged.
_GENERIC_AUTOPILOT = "Autopilot"
_STEERING_OUTPUT = "<output>fcs/steer-cmd-norm</output>"


@lru_cache(maxsize=1)
def _aircraft_dir() -> Path:
    return Path(jsbsim.get_default_root_dir()) / "aircraft"


def available_aircraft() -> list[str]:
    """Aircraft of the installed jsbsim wheel this adapter offers, sorted (case-insensitive).

    These are the wheel's aircraft checked to load, trim and fly straight and level (see
    ``suggested_start``); c172x (the default) and c310 are tuned to fly every plan.
    """
    root = _aircraft_dir()
    return sorted(
        (name for name in _VERIFIED if (root / name / f"{name}.xml").is_file()), key=str.lower
    )


def suggested_start(aircraft: str, **overrides: Any) -> StartState:
    """A start state at which ``aircraft`` trims (altitude and airspeed), plus ``overrides``
    (any :class:`~sim.flight_config.StartState` field; a ground start takes the altitude as its
    runway's elevation).

    Raises
    ------
    ValueError
        Unknown aircraft; the message lists the valid ones.
    """
    if aircraft not in _VERIFIED:
        raise ValueError(
            f"unknown aircraft {aircraft!r}: valid aircraft are {', '.join(available_aircraft())}"
        )
    alt_m, airspeed_mps = _VERIFIED[aircraft]
    return StartState(**{"alt_msl_m": alt_m, "airspeed_mps": airspeed_mps, **overrides})


def load_without_io(fdm: Any, aircraft: str) -> None:
    """Load ``aircraft`` from the wheel's data, minus its data-output and network-input
    directives (see ``_IO_ELEMENT``). The private copy is deleted once JSBSim has read it."""
    root = Path(jsbsim.get_default_root_dir())
    with tempfile.TemporaryDirectory(prefix="hilnav-jsbsim-") as tmp:
        folder = Path(tmp) / aircraft
        shutil.copytree(root / "aircraft" / aircraft, folder)
        for xml in folder.glob("*.xml"):
            text = xml.read_text(encoding="utf-8", errors="surrogateescape")
            cleaned = _IO_ELEMENT.sub("", text)
            if cleaned != text:
                xml.write_text(cleaned, encoding="utf-8", errors="surrogateescape")
        _free_nose_wheel(folder, root / "systems")
        try:
            with jsbsim_log_discarded():  # load-time warnings of some wheel aircraft
                loaded = fdm.load_model_with_paths(
                    aircraft, tmp, str(root / "engine"), str(root / "systems"), True
                )
        except jsbsim.BaseError as error:
            raise ValueError(f"JSBSim could not load aircraft {aircraft!r}: {error}") from None
    if not loaded:
        raise ValueError(f"JSBSim could not load aircraft {aircraft!r}")
    fdm.disable_output()


def _free_nose_wheel(folder: Path, systems: Path) -> None:
    """Give the aircraft copy in ``folder`` the generic Autopilot system without its
    ground-steering output (see ``_STEERING_OUTPUT``), when it loads that system."""
    uses = f'<system file="{_GENERIC_AUTOPILOT}"'
    if not any(uses in xml.read_text(encoding="utf-8", errors="surrogateescape")
               for xml in folder.glob("*.xml")):
        return
    own = folder / "Systems" / f"{_GENERIC_AUTOPILOT}.xml"
    source = own if own.is_file() else systems / f"{_GENERIC_AUTOPILOT}.xml"
    if not source.is_file():
        return
    text = source.read_text(encoding="utf-8", errors="surrogateescape")
    if _STEERING_OUTPUT in text:
        own.parent.mkdir(exist_ok=True)
        own.write_text(text.replace(_STEERING_OUTPUT, ""), encoding="utf-8",
                       errors="surrogateescape")


class _DiscardLog(jsbsim.FGLogger):
    """A JSBSim log backend that drops every record."""

    def set_level(self, level: jsbsim.LogLevel) -> None:
        pass

    def file_location(self, filename: str, line: int) -> None:
        pass

    def message(self, message: str) -> None:
        pass

    def format(self, format: jsbsim.LogFormat) -> None:
        pass

    def flush(self) -> None:
        pass


@contextlib.contextmanager
def jsbsim_log_discarded() -> Iterator[None]:
    """Drop what JSBSim logs from this thread meanwhile (trim reports, load-time warnings).

    JSBSim reports a failed trim axis and the XML warnings of some wheel aircraft whatever its
    debug level; on the console they would corrupt a CLI's or a test's output. JSBSim sends
    every such record to the calling thread's ``FGLogger``, so swapping that logger silences
    them without touching a file descriptor or another thread. The previous logger is
    restored on exit.
    """
    previous = jsbsim.get_logger()
    jsbsim.set_logger(_DiscardLog())
    try:
        yield
    finally:
        jsbsim.set_logger(previous)
