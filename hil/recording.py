"""Record a lockstep flight: JSBSim -> sensor models -> MAVLink frames -> .tlog."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hil.streamer import GnssWindow, LockstepReport, SensorStreamer, run_lockstep
from hil.tlog import TlogWriter
from sim import presets
from sim.flight import Flight, FlightConfig, StartState
from sim.plans import FlightPlan, load_plan
from sim.sensors import SensorSuite, SensorSuiteConfig


def _parse_wind(text: str) -> tuple[float, float, float]:
    try:
        n, e, d = (float(p) for p in text.split(","))
    except ValueError:
        raise ValueError(f"wind {text!r} must be N,E,D in m/s, e.g. 5,-3,0") from None
    return (n, e, d)


@dataclass(frozen=True)
class SimRequest:
    """Everything a lockstep flight needs, validated."""

    flight: FlightConfig
    plan: FlightPlan
    sensors: SensorSuiteConfig
    duration_s: float
    seed: int
    gnss_off: tuple[GnssWindow, ...] = ()
    truth_rate_hz: float = 50.0

    @classmethod
    def build(
        cls,
        *,
        plan: str = "racetrack",
        aircraft: str = "c172x",
        duration_s: float = 600.0,
        seed: int = 1,
        rate_hz: float = 200.0,
        imu: str = "industrial-mems",
        gnss: str = "modern",
        baro: str = "ms5611",
        mag: str = "consumer",
        lat_deg: float = 47.0,
        lon_deg: float = 8.0,
        alt_msl_m: float = 1000.0,
        heading_deg: float = 0.0,
        airspeed_mps: float = 50.0,
        wind: str = "0,0,0",
        turbulence: float = 0.0,
        gnss_off: list[str] | tuple[str, ...] = (),
        truth_rate_hz: float = 50.0,
    ) -> SimRequest:
        """Validate human-facing options (ValueError / ValidationError name the bad one)."""
        if not duration_s > 0:
            raise ValueError(f"duration must be > 0 s (got {duration_s})")
        if seed < 0:
            raise ValueError(f"seed must be >= 0 (got {seed})")
        flight = FlightConfig(
            aircraft=aircraft,
            rate_hz=rate_hz,
            start=StartState(
                lat_deg=lat_deg, lon_deg=lon_deg, alt_msl_m=alt_msl_m,
                heading_deg=heading_deg, airspeed_mps=airspeed_mps,
            ),
            wind_ned_mps=_parse_wind(wind),
            turbulence=turbulence,
            seed=seed,
        )
        sensors = presets.suite_config(imu=imu, gnss=gnss, baro=baro, mag=mag)
        return cls(
            flight=flight,
            plan=load_plan(plan),
            sensors=sensors,
            duration_s=duration_s,
            seed=seed,
            gnss_off=tuple(GnssWindow.parse(w) for w in gnss_off),
            truth_rate_hz=truth_rate_hz,
        )


def record_flight(
    request: SimRequest,
    path: Path,
    *,
    progress: Callable[[float], None] | None = None,
) -> LockstepReport:
    """Fly ``request`` and write every frame to ``path`` (a .tlog, simulated-time stamps).

    The log is flushed and closed even when the aircraft crashes mid-run.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    suite = SensorSuite(request.sensors, request.seed, request.flight.rate_hz)
    streamer = SensorStreamer(truth_rate_hz=request.truth_rate_hz, gnss_off=request.gnss_off)
    with Flight(request.flight, request.plan) as flight, TlogWriter(path) as log:
        return run_lockstep(flight, suite, streamer, request.duration_s,
                            lambda t_us, frame: log.write(frame, t_us),
                            progress=progress)
