"""The names the commands offer for the fusion's choices, defined once and importable without
the numerical modules behind them (no numpy, scipy or pydantic), so that ``hilnav --help`` can
list them without loading the filter.

:mod:`fusion.config` and :mod:`fusion.bridging.registry` validate against these names and
re-export them.
"""

from __future__ import annotations

BRIDGE_METHODS: tuple[str, ...] = (
    "none", "gmdh", "gmdh-pseudo", "mlp", "rbf", "bp-parallel", "gmdh-airspeed", "gmdh-wind",
    "gmdh-pitot", "gmdh-thermal",
)
"""Names accepted by :func:`fusion.bridging.registry.make_bridge`."""

ALTITUDE_METHODS: tuple[str, ...] = ("ekf", "loop", "loop-mpc", "loop-kf")
"""Altitude methods of :class:`fusion.config.AltitudeConfig` (and ``--altitude`` on the command
line)."""

AIRSPEED_MODES: tuple[str, ...] = ("on", "off", "synthetic")
"""Air-data choices of the commands (``--airspeed``): ``on`` fuses the pitot when the stream
carries one; ``off`` fuses no air data (samples counted, not fused); ``synthetic`` is ``on``
plus synthetic airspeed on a fixed-wing without a pitot (:class:`fusion.config.AirspeedTuning`)."""
DEFAULT_AIRSPEED_MODE = "on"
"""The commands' air-data default: the pitot is fused whenever the stream carries one, as PX4
and ArduPilot do: with the gust states the pitot helps on held-out JSBSim flights in calm,
steady and turbulent air (``bench/air_data.py``; docs/results.md, "Air data"); without them
(a gust taken for white noise) it made a 300 s outage worse than free inertial."""

ALIGN_MODES: tuple[str, ...] = ("auto", "static", "in-flight")
"""Alignment choices of the commands (``--align``): :attr:`fusion.config.InitConfig.mode` with a
hyphen."""
DEFAULT_ALIGN_MODE = "auto"
"""The commands' alignment default: the path follows from the data
(:class:`fusion.config.InitConfig`)."""

THERMAL_MODES: tuple[str, ...] = ("off", "blind", "states", "cal")
"""Thermal strategies of the commands (``--thermal``; ``cal`` takes a calibration file):
:attr:`fusion.thermal.tuning.ThermalTuning.mode`."""
DEFAULT_THERMAL_MODE = "off"
"""The commands' thermal default: no temperature model and the datasheet's bias noise."""
