"""The one pipeline: a flight setup -> MAVLink frames, and frames -> fused, collected tracks.

Every command and bench goes through these two halves, so lockstep runs, replays, comparisons,
campaigns, the live service and the benchmarks share every component:

* **simulate**: :class:`SimSetup` (aircraft, plan, sensor models, fault timeline, GNSS-off
  windows, vehicle-state reports) -> :class:`SimChain` (JSBSim flight + sensor suite +
  vehicle-state reporter + fault injector + sensor streamer) -> ``(time_us, frame)`` MAVLink 2
  frames. :func:`fly` runs the chain in lockstep
  (simulated time only) into a frame sink; the live simulator paces the same chain against
  the wall clock.
* **fuse**: :class:`FusionRun` decodes frames (or already decoded samples) and steps one
  :class:`fusion.filter.NavFilter`, built by :func:`build_filter` exactly the same way for
  every command, and collects estimate / truth / fix tracks (:class:`hil.tracks.Collector`)
  for the scorer.
"""

from __future__ import annotations

import operator
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Literal

from fusion.bridging.registry import BRIDGE_METHODS, make_bridge
from fusion.config import (
    ALTITUDE_METHODS,
    DEFAULT_AIRSPEED_MODE,
    DEFAULT_ALIGN_MODE,
    FilterConfig,
    airspeed_tuning,
    init_for_align,
)
from fusion.estimate import NavEstimate
from fusion.filter import NavFilter
from fusion.thermal.tuning import ThermalTuning
from hil.codec import Decoder
from hil.streamer import GnssWindow, SensorStreamer
from hil.tlog import TlogWriter
from hil.tracks import Collector
from hil.tuning import filter_config_for_imu, filter_gnss_config, gnss_state_layout
from sim import presets
from sim.faults import FaultEvent, FaultInjector, FaultLogEntry
from sim.flight import Flight, FlightConfig, FlightEnded, StartState
from sim.gnss import GnssConfig
from sim.plans import FlightPlan, load_plan
from sim.samples import Sample, Truth
from sim.sensors import SensorSuite, SensorSuiteConfig
from sim.vehicle_state import VehicleStateConfig, VehicleStateReporter

Frame = tuple[int, bytes]
FrameSink = Callable[[int, bytes], None]
ProgressFn = Callable[[float], None]


# ------------------------------------------------------------------------------ simulate
@dataclass(frozen=True)
class SimSetup:
    """Everything a simulated flight needs, validated (SI units).

    ``faults`` is the scenario's fault timeline; ``None`` flies without a fault injector (a
    plain recording), an empty tuple with one that has nothing to do (a scenario without
    events). ``gnss_off`` windows suppress HIL_GPS by time of validity. ``vehicle_state``: rate
    and content of the HIL_ACTUATOR_CONTROLS / RAW_RPM reports (:mod:`sim.vehicle_state`).
    """

    flight: FlightConfig
    plan: FlightPlan
    sensors: SensorSuiteConfig
    duration_s: float
    seed: int
    faults: tuple[FaultEvent, ...] | None = None
    gnss_off: tuple[GnssWindow, ...] = ()
    truth_rate_hz: float = 50.0
    vehicle_state: VehicleStateConfig = field(default_factory=VehicleStateConfig)

    def __post_init__(self) -> None:
        if not self.duration_s > 0:
            raise ValueError(f"duration must be > 0 s (got {self.duration_s})")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0 (got {self.seed})")

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
        pitot: str = presets.DEFAULT_PITOT_PRESET,
        imu_thermal: str = presets.IMU_THERMAL_OFF,
        lat_deg: float = 47.0,
        lon_deg: float = 8.0,
        alt_msl_m: float = 1000.0,
        heading_deg: float = 0.0,
        airspeed_mps: float = 50.0,
        start_kind: Literal["air", "ground"] = "air",
        wind: str = "0,0,0",
        turbulence: float = 0.0,
        wind_shear_exponent: float = 0.0,
        wind_ref_agl_m: float | None = None,
        gnss_off: Sequence[str] = (),
        truth_rate_hz: float = 50.0,
        vehicle_state_rate_hz: float = 50.0,
    ) -> SimSetup:
        """A setup from human-facing options (preset names, ``N,E,D`` wind, ``START:DUR``
        outages); ValueError / ValidationError name the bad one. ``pitot="none"``: an
        aircraft without an airspeed sensor (no ``diff_pressure`` in the stream);
        ``imu_thermal``: a thermal IMU part powered on at the start, or ``off``."""
        if not duration_s > 0:
            raise ValueError(f"duration must be > 0 s (got {duration_s})")
        if seed < 0:
            raise ValueError(f"seed must be >= 0 (got {seed})")
        flight = FlightConfig(
            aircraft=aircraft,
            rate_hz=rate_hz,
            start=StartState(
                kind=start_kind, lat_deg=lat_deg, lon_deg=lon_deg, alt_msl_m=alt_msl_m,
                heading_deg=heading_deg, airspeed_mps=airspeed_mps,
            ),
            wind_ned_mps=_parse_wind(wind),
            wind_shear_exponent=wind_shear_exponent,
            wind_ref_agl_m=wind_ref_agl_m,
            turbulence=turbulence,
            seed=seed,
        )
        return cls(
            flight=flight,
            plan=load_plan(plan),
            sensors=presets.suite_config(imu=imu, gnss=gnss, baro=baro, mag=mag, pitot=pitot,
                                         imu_thermal=imu_thermal),
            duration_s=duration_s,
            seed=seed,
            gnss_off=tuple(GnssWindow.parse(w) for w in gnss_off),
            truth_rate_hz=truth_rate_hz,
            vehicle_state=VehicleStateConfig(rate_hz=vehicle_state_rate_hz),
        )


def _parse_wind(text: str) -> tuple[float, float, float]:
    try:
        n, e, d = (float(p) for p in text.split(","))
    except ValueError:
        raise ValueError(f"wind {text!r} must be N,E,D in m/s, e.g. 5,-3,0") from None
    return (n, e, d)


@dataclass(frozen=True)
class SimStep:
    """One simulator step: the truth, the sensor samples and the frames they became;
    ``sensed``: the samples as sent, after the fault timeline (what an autopilot's sensors
    read: :mod:`hil.autopilot.ardupilot` sends ArduPilot its IMU and airspeed from them)."""

    truth: Truth
    samples: Sequence[Sample]
    frames: list[Frame]
    sensed: Sequence[Sample] = ()


class SimChain:
    """JSBSim flight + sensor suite + vehicle-state reporter + fault injector + sensor streamer,
    opened as a context.

    :meth:`steps` advances the flight one step at a time until ``duration_s`` of simulated time
    have passed or the flight ends (stall, ground contact: kept in :attr:`ended`, never
    raised, so whatever was produced so far stays valid).
    """

    def __init__(self, setup: SimSetup) -> None:
        self.setup = setup
        self.suite = SensorSuite(setup.sensors, setup.seed, setup.flight.rate_hz)
        self.vehicle = VehicleStateReporter(setup.vehicle_state)
        self.flight: Flight | None = None
        self.faults: FaultInjector | None = None
        self.streamer: SensorStreamer | None = None
        self.ended: FlightEnded | None = None
        self.start_us = 0
        self.time_us = 0

    def __enter__(self) -> SimChain:
        s = self.setup
        self.flight = Flight(s.flight, s.plan).__enter__()
        try:
            if s.faults is not None:
                self.faults = FaultInjector(s.faults, seed=s.seed, t0_us=self.flight.time_us)
            self.streamer = SensorStreamer(truth_rate_hz=s.truth_rate_hz, gnss_off=s.gnss_off,
                                           faults=self.faults,
                                           imu_temperature=s.sensors.imu_thermal is not None)
        except BaseException:
            self.flight.__exit__(None, None, None)
            raise
        self.start_us = self.time_us = self.flight.time_us
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self.flight is not None:
            self.flight.__exit__(exc_type, exc, tb)

    @property
    def sim_duration_s(self) -> float:
        """Simulated seconds flown so far."""
        return (self.time_us - self.start_us) * 1e-6

    @property
    def fault_log(self) -> list[FaultLogEntry]:
        """The injector's event starts and ends so far (empty without an injector)."""
        return [] if self.streamer is None else self.streamer.fault_log

    @property
    def fault_counters(self) -> dict[str, int]:
        """A copy of the injector's counters (empty without an injector)."""
        return {} if self.streamer is None else self.streamer.fault_counters

    def steps(self, *, batch: int = 1) -> Iterator[SimStep]:
        """Fly until the setup's duration is reached or the flight ends.

        ``batch`` > 1 (lockstep only): JSBSim and the guidance law advance up to ``batch`` steps in
        a row (each step's vehicle state read right after it, as JSBSim has it then), and only then
        are those steps' sensor samples made, encoded and yielded, one by one. The steps, samples
        and frames are the same, in the same order; what changes is that JSBSim's ``run()`` calls
        follow one another while its code and data are still in the CPU caches instead of after the
        sensor models, the encoder and whatever the consumer does with each step (JSBSim's ``run()``
        is slower with them in between: ``jsbsim_run_inside_chain`` of bench/sim_throughput.py;
        docs/results.md, "Speed"). A consumer that acts on the flight between steps (an autopilot's
        commands, live pacing) needs ``batch=1``: the flight is then up to ``batch - 1`` steps ahead
        of the step yielded.
        """
        flight, streamer = self.flight, self.streamer
        if flight is None or streamer is None:
            raise RuntimeError("SimChain.steps() outside its `with` block")
        if batch < 1:
            raise ValueError(f"batch must be >= 1 (got {batch})")
        end_us = self.start_us + round(self.setup.duration_s * 1e6)
        suite, vehicle = self.suite, self.vehicle
        step, read_vehicle = flight.step, flight.vehicle_state
        time_us = flight.truth().time_us
        flown: list[tuple[Truth, Sequence[Sample]]] = []
        while time_us < end_us:
            try:
                while time_us < end_us and len(flown) < batch:
                    truth = step()
                    time_us = truth.time_us
                    flown.append((truth, vehicle.step(time_us, read_vehicle)))
            except FlightEnded as exc:
                self.ended = exc
            for truth, reports in flown:
                self.time_us = truth.time_us
                samples: Sequence[Sample] = suite.step(truth)
                if reports:
                    samples = [*samples, *reports]
                frames = streamer.frames(truth, samples)
                yield SimStep(truth, samples, frames, streamer.last_samples)
            flown.clear()
            if self.ended is not None:
                return


#: Steps per batch of a lockstep flight (:func:`fly`): 1 s of simulated time at 200 Hz. Each stage
#: (JSBSim, samples, encode, decode + filter) runs a whole batch in a row with its code and data
#: warm, which costs less CPU than alternating the stages every step (bench/sim_throughput.py,
#: ``sim_chain_batched`` against ``sim_chain``; docs/results.md, "Speed"). The size comes from an
#: ad-hoc sweep (50 gained less, 1000 no more; not a committed result).
LOCKSTEP_BATCH = 200

@dataclass(frozen=True)
class Flown:
    """What a lockstep flight produced besides its frames."""

    sim_duration_s: float
    wall_s: float
    frames: int
    ended: FlightEnded | None
    fault_log: list[FaultLogEntry]
    fault_counters: dict[str, int]

    @property
    def realtime_factor(self) -> float:
        return self.sim_duration_s / self.wall_s if self.wall_s > 0 else float("inf")


def fly(setup: SimSetup, sink: FrameSink, *, progress: ProgressFn | None = None,
        batch: int = LOCKSTEP_BATCH) -> Flown:
    """Fly ``setup`` in lockstep (as fast as the machine allows) into ``sink(time_us, frame)``.

    Simulated time is the only clock; ``progress(simulated_s)`` is called once per simulated
    second. Work goes in batches of ``batch`` steps (:data:`LOCKSTEP_BATCH`): JSBSim flies
    them, their samples are made and encoded, then the sink gets their frames, in order. The
    sink receives the same frames in the same order whatever ``batch``; each stage just runs
    ``batch`` times in a row with its code and data warm in the CPU caches. A sink with a
    ``frames(batch)`` method (:class:`FusionRun`, :func:`tee`) gets each batch in one call.
    """
    n_frames = 0
    wall0 = time.perf_counter()
    to_sink = _batch_sink(sink)
    with SimChain(setup) as chain:
        next_progress_us = chain.start_us
        pending: list[Frame] = []
        for k, step in enumerate(chain.steps(batch=batch), 1):
            pending.extend(step.frames)
            if k % batch == 0:
                to_sink(pending)
                n_frames += len(pending)
                pending.clear()
            if progress is not None and step.truth.time_us >= next_progress_us:
                progress((step.truth.time_us - chain.start_us) * 1e-6)
                next_progress_us += 1_000_000
        to_sink(pending)
        n_frames += len(pending)
    wall = time.perf_counter() - wall0
    return Flown(chain.sim_duration_s, wall, n_frames, chain.ended, list(chain.fault_log),
                 chain.fault_counters)


def _batch_sink(sink: FrameSink) -> Callable[[Sequence[Frame]], None]:
    """``sink.frames`` when the sink takes whole batches, else a loop calling it per frame."""
    frames: Callable[[Sequence[Frame]], None] | None = getattr(sink, "frames", None)
    if frames is not None:
        return frames

    def each(batch: Sequence[Frame]) -> None:
        for time_us, frame in batch:
            sink(time_us, frame)

    return each


def record_flight(setup: SimSetup, path: Path, *, progress: ProgressFn | None = None) -> Flown:
    """Fly ``setup`` in lockstep and write every frame to the ``.tlog`` at ``path``
    (simulated-time stamps); the log is flushed and closed even when the aircraft crashes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with TlogWriter(path) as log:
        return fly(setup, lambda t_us, frame: log.write(frame, t_us), progress=progress)


# ---------------------------------------------------------------------------------- fuse
def filter_config(
    imu: str, receiver: GnssConfig, altitude: str = "ekf",
    airspeed: str = DEFAULT_AIRSPEED_MODE, align: str = DEFAULT_ALIGN_MODE,
    thermal: ThermalTuning | None = None,
) -> FilterConfig:
    """The filter every command builds: tuned from the IMU datasheet preset ``imu``, modelling
    the GNSS ``receiver`` (its time-correlated error as bias states when it has one), with the
    altitude method ``altitude``, the air-data choice ``airspeed``
    (:data:`fusion.config.AIRSPEED_MODES`) and the alignment ``align``
    (:data:`fusion.config.ALIGN_MODES`). ValueError names a bad preset or method."""
    if altitude not in ALTITUDE_METHODS:
        raise ValueError(
            f"unknown altitude method {altitude!r}; valid methods: {', '.join(ALTITUDE_METHODS)}"
        )
    config = filter_config_for_imu(imu)
    return config.model_copy(update={
        "altitude": config.altitude.model_copy(update={"method": altitude}),
        "gnss": filter_gnss_config(receiver, config.gnss),
        "state_layout": gnss_state_layout(receiver, config.state_layout),
        "airspeed": airspeed_tuning(airspeed, config.airspeed),
        "init": init_for_align(align, config.init),
        "thermal": thermal if thermal is not None else config.thermal,
    })


def build_filter(config: FilterConfig, bridge: str = "none") -> NavFilter:
    """A :class:`NavFilter` with the bridging method ``bridge`` (ValueError lists the valid
    ones)."""
    if bridge not in BRIDGE_METHODS:
        raise ValueError(
            f"unknown bridging method {bridge!r}; valid methods: {', '.join(BRIDGE_METHODS)}")
    return NavFilter(config, bridge=make_bridge(bridge, config.bridge))


_sample_of = operator.attrgetter("sample")  # Decoded -> its sample
_frame_of = operator.itemgetter(1)  # (time_us, frame) -> frame


class FusionRun:
    """Frames -> decoded samples -> one filter -> collected tracks.

    Parameters
    ----------
    config : FilterConfig
    bridge : str
        Bridging method (:data:`fusion.bridging.BRIDGE_METHODS`).
    collect : bool
        Keep the estimate, truth and fix tracks for scoring (:attr:`collector`).
    nav : NavFilter, optional
        A filter already built from ``config`` and ``bridge`` (for callers that own it).
    keep_objects : bool
        The collector also keeps every estimate, truth and fix object (tests, tools); by
        default it keeps their compact columns only (:class:`hil.tracks.Collector`).
    spill_dir : Path, optional
        The collector writes its compact columns to an anonymous file in this folder as they
        fill, so memory stays flat however long the run (the live service's ``--out``).

    A FusionRun is also a frame sink (``run(time_us, frame)``), so a lockstep flight can be
    fused while it flies; :attr:`fuse_s` accumulates the wall time spent decoding and fusing.
    """

    def __init__(self, config: FilterConfig, bridge: str = "none", *, collect: bool = True,
                 nav: NavFilter | None = None, keep_objects: bool = False,
                 spill_dir: Path | None = None) -> None:
        self.config = config
        self.bridge = bridge
        self.nav = nav if nav is not None else build_filter(config, bridge)
        self.decoder = Decoder()
        self.collector: Collector | None = (
            Collector(keep_objects=keep_objects, spill_dir=spill_dir) if collect else None)
        self.samples = 0
        self.fuse_s = 0.0
        self.on_estimate: Callable[[NavEstimate], None] | None = None
        """Called with the newest estimate of each frame fused as a sink (``run(time_us,
        frame)``), e.g. to send it on while the flight goes on."""

    def feed(self, items: Iterable[Sample | Truth]) -> list[NavEstimate]:
        """Step the filter with decoded samples (truth is only collected); new estimates."""
        col = self.collector
        if col is not None:
            return col.feed(self.nav, items)
        out: list[NavEstimate] = []
        for item in items:
            if not isinstance(item, Truth):
                out.extend(self.nav.step(item))
        return out

    def feed_frame(self, frame: bytes) -> list[NavEstimate]:
        """Decode one frame (or a chunk of a byte stream) and fuse what it held."""
        decoded = self.decoder.feed(frame)
        self.samples += len(decoded)
        col = self.collector
        if col is not None:
            return col.feed(self.nav, map(_sample_of, decoded))
        out: list[NavEstimate] = []
        step = self.nav.step
        for d in decoded:  # as feed(), without a generator per frame
            if not isinstance(d.sample, Truth):
                out.extend(step(d.sample))
        return out

    def __call__(self, time_us: int, frame: bytes) -> None:
        t0 = time.perf_counter()
        estimates = self.feed_frame(frame)
        self.fuse_s += time.perf_counter() - t0
        if estimates and self.on_estimate is not None:
            self.on_estimate(estimates[-1])

    def frames(self, batch: Sequence[Frame]) -> None:
        """Sink of a batch of frames (:func:`fly` hands over each lockstep batch): all of them
        decoded first, then their samples fused. The decoder never looks at the filter, so the
        filter gets the same samples in the same order as frame by frame; each stage just
        runs over the whole batch with its code and data warm in the CPU caches
        (interleaving them frame by frame costs more CPU).
        """
        t0 = time.perf_counter()
        decoded = self.decoder.feed_all(map(_frame_of, batch))
        self.samples += len(decoded)
        self.feed(map(_sample_of, decoded))
        self.fuse_s += time.perf_counter() - t0

    @property
    def fusion_us_per_sample(self) -> float:
        """Mean wall time per decoded sample of the frames fused through ``__call__``, us."""
        return 1e6 * self.fuse_s / max(self.samples, 1)


def fuse_frames(frames: Iterable[Frame], config: FilterConfig, bridge: str = "none", *,
                keep_objects: bool = False) -> FusionRun:
    """Decode and fuse a whole frame stream (e.g. a recording kept in memory)."""
    run = FusionRun(config, bridge, keep_objects=keep_objects)
    t0 = time.perf_counter()
    for _t, frame in frames:
        run.feed_frame(frame)
    run.fuse_s = time.perf_counter() - t0
    return run


class _Tee:
    """The sink of :func:`tee`: a frame to each sink in turn, or a batch to each sink in turn
    (whole, to those that take batches)."""

    def __init__(self, sinks: list[FrameSink]) -> None:
        self._sinks = sinks
        self._batch_sinks = [_batch_sink(s) for s in sinks]

    def __call__(self, time_us: int, frame: bytes) -> None:
        for s in self._sinks:
            s(time_us, frame)

    def frames(self, batch: Sequence[Frame]) -> None:
        for s in self._batch_sinks:
            s(batch)


def tee(*sinks: FrameSink | None) -> FrameSink:
    """One frame sink that hands every frame to each of ``sinks`` (``None`` entries skipped);
    given a batch (:func:`fly`), each sink gets the whole batch before the next one does."""
    return _Tee([s for s in sinks if s is not None])

