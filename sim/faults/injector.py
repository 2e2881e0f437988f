"""The fault injector: applies a timeline of fault events to each step's sensor samples, between
:class:`sim.sensors.SensorSuite` and the encoder.

Times
    Flight time 0 is ``t0_us`` given to :class:`FaultInjector` (the first ``Truth.time_us`` of
    the run). A sample belongs to an event when *its own* time is inside the event's window: a
    GNSS fix by its time of validity (``GnssFix.time_us``, so a fix measured before an outage
    but emitted after its start still goes out, as with ``hil.streamer.GnssWindow``), every
    other sample by its ``time_us``.

Composition
    Several events on one sensor compose in a fixed order: GNSS rate → outage / jamming /
    degradation / spoofing → delay; IMU bias step → saturation → stuck axis; barometer
    offsets add, a freeze overrides them; one pitot event at a time.
    :func:`sim.faults.timeline.check_events` rejects the combinations that contradict each
    other.

Determinism
    Only jamming draws random numbers. ``numpy.random.SeedSequence(seed).spawn(n_events)`` gives
    event ``i`` its own generator, so adding an event never changes another's noise; the same
    events, seed and input give a bit-identical output.

Cost
    The events' boundaries are precomputed as one sorted list; a step in which no event is
    armed costs one integer comparison, an attribute test and a list copy. Freeze and stuck
    events (and a stuck pitot blockage) are armed :data:`PREARM_S` early (to remember the
    last good value); GNSS events stay armed :data:`GNSS_TAIL_S` after their end so that
    fixes valid inside the window but emitted later (receiver latency, delay queue) are still
    handled.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from sim._sensor_common import meridian_prime_radii_m
from sim.faults.events import (
    BARO_EVENTS,
    GNSS_EVENTS,
    IMU_EVENTS,
    PITOT_EVENTS,
    AirspeedFailure,
    BaroDrift,
    BaroFreeze,
    BaroGlitch,
    FaultEvent,
    GnssDegradation,
    GnssDelay,
    GnssJamming,
    GnssOutage,
    GnssRate,
    GnssSpoofDrift,
    GnssSpoofHijack,
    ImuBiasStep,
    ImuSaturation,
    ImuStuck,
    MagAnomaly,
    PitotBlockage,
    PitotDrift,
    WeatherFront,
    event_type_name,
)
from sim.samples import (
    AirspeedSample,
    BaroSample,
    GnssFix,
    ImuSample,
    MagSample,
    Sample,
    Truth,
)

GNSS_TAIL_S = 10.0
"""GNSS events keep handling fixes valid inside their window for this long after their end, s
(covers the receiver's latency and a delay queue; a longer latency would let late fixes leak
through unmodified)."""
PREARM_S = 5.0
"""Freeze / stuck events start watching the sensor this long before their start, s, to know
its last value (with no sample in that time, the first sample of the window is held)."""
RATE_TOLERANCE_US = 500
"""A fix up to this early on the decimation schedule still counts as due (µs jitter)."""

__all__ = ["GNSS_TAIL_S", "PREARM_S", "RATE_TOLERANCE_US", "FaultInjector", "FaultLogEntry"]


@dataclass(frozen=True, slots=True)
class FaultLogEntry:
    """An event boundary for the ``scenario/events`` topic.

    Attributes
    ----------
    time_us : int
        Simulated time of the boundary (``t0_us`` + event time), µs.
    type_name : str
        The event's type name (a key of :data:`sim.faults.events.EVENT_TYPES`).
    phase : "start" or "end"
    index : int
        The event's position in the sequence given to :class:`FaultInjector`.
    """

    time_us: int
    type_name: str
    phase: Literal["start", "end"]
    index: int = 0


_INF_US = 2**62
_END, _DISARM, _ARM, _START = 0, 1, 2, 3  # order of boundaries at the same time

# Processing stages within one sensor (see the module docstring).
_STAGE = {
    GnssRate: 0,
    GnssOutage: 1,
    GnssJamming: 1,
    GnssDegradation: 1,
    GnssSpoofDrift: 1,
    GnssSpoofHijack: 1,
    GnssDelay: 2,
    ImuBiasStep: 0,
    ImuSaturation: 1,
    ImuStuck: 2,
}

_COUNTERS = (
    "gnss_dropped",
    "gnss_delayed",
    "gnss_spoofed",
    "gnss_degraded",
    "gnss_garbage",
    "baro_modified",
    "imu_modified",
    "mag_modified",
    "airspeed_modified",
    "airspeed_dropped",
)


class _Runtime:
    """One event's window in µs and its mutable state."""

    __slots__ = (
        "axes",
        "due_us",
        "end_us",
        "event",
        "first_us",
        "held",
        "index",
        "k",
        "rng",
        "stage",
        "start_us",
        "vec",
    )

    def __init__(
        self, index: int, event: FaultEvent, t0_us: int, rng: np.random.Generator
    ) -> None:
        self.index = index
        self.event = event
        self.start_us = t0_us + round(event.start_s * 1e6)
        self.end_us = (
            _INF_US
            if event.duration_s is None
            else t0_us + round((event.start_s + event.duration_s) * 1e6)
        )
        self.rng = rng
        self.stage = _STAGE.get(type(event), 0)
        # IMU events: which vector (0 specific force, 1 angular rate) and axes they touch.
        self.vec = 1 if getattr(event, "sensor", None) == "gyro" else 0
        axis = getattr(event, "axis", None)
        self.axes: tuple[int, ...] = (0, 1, 2) if axis is None else (axis,)
        # Held values of a freeze / stuck axis, per sensor id.
        self.held: dict[int, Any] = {}
        # Decimation schedule of GnssRate.
        self.first_us: int | None = None
        self.k = 0
        self.due_us = 0

    def arm_disarm_us(self) -> tuple[int, int]:
        ev = self.event
        prearm = isinstance(ev, BaroFreeze | ImuStuck) or (
            isinstance(ev, PitotBlockage) and ev.mode == "stuck"
        )
        arm = self.start_us - (round(PREARM_S * 1e6) if prearm else 0)
        if isinstance(ev, WeatherFront) or self.end_us >= _INF_US:
            return arm, _INF_US
        if isinstance(ev, GNSS_EVENTS):
            return arm, self.end_us + round(GNSS_TAIL_S * 1e6)
        return arm, self.end_us

    def covers(self, time_us: int) -> bool:
        return self.start_us <= time_us < self.end_us




def _offset_geodetic(
    lat_rad: float, lon_rad: float, alt_m: float, dn_m: float, de_m: float, dd_m: float
) -> tuple[float, float, float]:
    """Move a geodetic point by a NED offset (m) at constant height for N and E.

    WGS-84 radii at the point; the east step uses the new latitude's parallel, which keeps the
    east component in the point's own NED tangent plane exact to second order (the north one
    is then off by ``de²·tan(lat)/(2R)``: 3 mm for 200 m east at 47°).
    """
    r_m, r_n = meridian_prime_radii_m(lat_rad)
    lat = lat_rad + dn_m / (r_m + alt_m)
    return lat, lon_rad + de_m / ((r_n + alt_m) * math.cos(lat)), alt_m - dd_m


def _ned_to_body(q_nb: list[float], n: tuple[float, float, float]) -> tuple[float, float, float]:
    """``C_nbᵀ · n`` for the Hamilton quaternion ``q_nb`` [w, x, y, z] (normalised here)."""
    w, x, y, z = q_nb
    s = 2.0 / (w * w + x * x + y * y + z * z)
    a, b, c = n
    return (
        (1 - s * (y * y + z * z)) * a + s * (x * y + w * z) * b + s * (x * z - w * y) * c,
        s * (x * y - w * z) * a + (1 - s * (x * x + z * z)) * b + s * (y * z + w * x) * c,
        s * (x * z + w * y) * a + s * (y * z - w * x) * b + (1 - s * (x * x + y * y)) * c,
    )


class FaultInjector:
    """Applies a timeline of fault events to each step's sensor samples.

    Parameters
    ----------
    events : sequence of FaultEvent
        The timeline (not checked for contradictions here: see
        :func:`sim.faults.timeline.check_events`;
        overlapping events compose as the module docstring says).
    seed : int
        Non-negative; event ``i`` draws from ``SeedSequence(seed).spawn(len(events))[i]``.
    t0_us : int
        Simulated time of flight time 0, µs.

    Attributes
    ----------
    events : tuple of FaultEvent
    log : list of FaultLogEntry
        Event starts and ends, in time order, appended when the truth time reaches them.
    counters : dict of str to int
        ``gnss_dropped`` (outage, jamming, decimation), ``gnss_delayed``, ``gnss_spoofed``,
        ``gnss_degraded``, ``gnss_garbage`` (jamming fixes let through), ``baro_modified``,
        ``imu_modified``, ``mag_modified``, ``airspeed_modified`` (blockage, drift),
        ``airspeed_dropped`` (airspeed failure).

    Raises
    ------
    ValueError
        Negative seed, non-integer ``t0_us``, or an object that is not a fault event.
    """

    def __init__(self, events: Sequence[FaultEvent], *, seed: int, t0_us: int = 0) -> None:
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer (got {seed!r})")
        if isinstance(t0_us, bool) or not isinstance(t0_us, int | np.integer):
            raise ValueError(f"t0_us must be an integer (got {t0_us!r})")
        self.events: tuple[FaultEvent, ...] = tuple(events)
        names = [event_type_name(ev) for ev in self.events]
        self._names = names
        self.log: list[FaultLogEntry] = []
        self.counters: dict[str, int] = dict.fromkeys(_COUNTERS, 0)
        children = np.random.SeedSequence(int(seed)).spawn(len(self.events))
        self._rts = [
            _Runtime(i, ev, int(t0_us), np.random.default_rng(children[i]))
            for i, ev in enumerate(self.events)
        ]
        bounds: list[tuple[int, int, int]] = []
        for rt in self._rts:
            arm, disarm = rt.arm_disarm_us()
            bounds.append((arm, _ARM, rt.index))
            bounds.append((rt.start_us, _START, rt.index))
            if rt.end_us < _INF_US:
                bounds.append((rt.end_us, _END, rt.index))
            if disarm < _INF_US:
                bounds.append((disarm, _DISARM, rt.index))
        bounds.sort()
        self._bounds = bounds
        self._bi = 0
        self._next_us = bounds[0][0] if bounds else _INF_US
        self._armed: set[int] = set()
        self._gnss_rt: tuple[_Runtime, ...] = ()
        self._baro_rt: tuple[_Runtime, ...] = ()
        self._imu_rt: tuple[_Runtime, ...] = ()
        self._mag_rt: tuple[_Runtime, ...] = ()
        self._pitot_rt: tuple[_Runtime, ...] = ()
        self._track_pitot = False
        self._last_pitot: dict[int, AirspeedSample] = {}
        self._hist_on = False
        self._track_baro = False
        self._track_imu = False
        # Truth (time, lat, lon, alt, v_ned) of recent steps while a degradation is armed.
        self._hist: deque[tuple[int, float, float, float, list[float]]] = deque(maxlen=1 << 14)
        self._last_baro: dict[int, BaroSample] = {}
        self._last_imu: dict[int, tuple[list[float], list[float]]] = {}
        # Delayed fixes (release time µs, fix), FIFO so fixes never overtake.
        self._queue: deque[tuple[int, GnssFix]] = deque()
        self._idle = True

    def pending_gnss(self) -> int:
        """Fixes held back by a delay, not yet emitted."""
        return len(self._queue)

    def apply(self, truth: Truth, samples: Sequence[Sample]) -> list[Sample]:
        """Apply the events active at this step to its samples.

        Parameters
        ----------
        truth : Truth
            The step's true state (its time drives the timeline; the attitude rotates magnetic
            anomalies; its position is the reference of GNSS degradation).
        samples : sequence of ImuSample | GnssFix | BaroSample | MagSample
            What :meth:`sim.sensors.SensorSuite.step` returned for this step.

        Returns
        -------
        list of ImuSample | GnssFix | BaroSample | MagSample
            New objects where a sample was changed (inputs are never mutated), in time order:
            delayed GNSS fixes released now first, then this step's GNSS fixes, then the other
            samples in their input order.
        """
        t = truth.time_us
        if t >= self._next_us:
            self._advance(t)
        if self._idle:
            return list(samples)
        return self._apply_active(truth, samples)

    # -- timeline --
    def _advance(self, t: int) -> None:
        bounds, n = self._bounds, len(self._bounds)
        changed = False
        while self._bi < n and bounds[self._bi][0] <= t:
            time_us, what, index = bounds[self._bi]
            self._bi += 1
            if what == _START:
                self.log.append(FaultLogEntry(time_us, self._names[index], "start", index))
            elif what == _END:
                self.log.append(FaultLogEntry(time_us, self._names[index], "end", index))
            elif what == _ARM:
                self._armed.add(index)
                changed = True
            else:
                self._armed.discard(index)
                changed = True
        self._next_us = bounds[self._bi][0] if self._bi < n else _INF_US
        if changed:
            armed = sorted((self._rts[i] for i in self._armed), key=lambda r: (r.stage, r.index))
            self._gnss_rt = tuple(r for r in armed if isinstance(r.event, GNSS_EVENTS))
            self._baro_rt = tuple(r for r in armed if isinstance(r.event, BARO_EVENTS))
            self._imu_rt = tuple(r for r in armed if isinstance(r.event, IMU_EVENTS))
            self._mag_rt = tuple(r for r in armed if isinstance(r.event, MagAnomaly))
            self._pitot_rt = tuple(r for r in armed if isinstance(r.event, PITOT_EVENTS))
            self._track_pitot = any(
                isinstance(r.event, PitotBlockage) and r.event.mode == "stuck" for r in armed
            )
            self._hist_on = any(isinstance(r.event, GnssDegradation) for r in armed)
            self._track_baro = any(isinstance(r.event, BaroFreeze) for r in armed)
            self._track_imu = any(isinstance(r.event, ImuStuck) for r in armed)
            if not self._hist_on:
                self._hist.clear()
        self._idle = not self._armed and not self._queue

    def _apply_active(self, truth: Truth, samples: Sequence[Sample]) -> list[Sample]:
        t = truth.time_us
        if self._hist_on:
            self._hist.append(
                (t, truth.lat_rad, truth.lon_rad, truth.alt_msl_m, truth.v_ned_mps.tolist())
            )
        queue = self._queue
        released: list[Sample] = []
        while queue and queue[0][0] <= t:
            released.append(queue.popleft()[1])
        direct: list[Sample] = []
        rest: list[Sample] = []
        for s in samples:
            if isinstance(s, GnssFix):
                fix: GnssFix | None = s
                release_us = t
                if self._gnss_rt:
                    fix, release_us = self._gnss(s, t)
                if fix is None:
                    continue
                if queue or release_us > t:
                    queue.append((release_us, fix))
                else:
                    direct.append(fix)
            elif isinstance(s, ImuSample):
                rest.append(self._imu(s) if self._imu_rt else s)
            elif isinstance(s, BaroSample):
                rest.append(self._baro(s) if self._baro_rt else s)
            elif isinstance(s, MagSample):
                rest.append(self._mag(s, truth) if self._mag_rt else s)
            elif isinstance(s, AirspeedSample):
                if self._pitot_rt:
                    a = self._pitot(s)
                    if a is not None:
                        rest.append(a)
                else:
                    rest.append(s)
            else:
                rest.append(s)
        self._idle = not self._armed and not queue
        return released + direct + rest

    # -- GNSS --
    def _gnss(self, fix: GnssFix, t: int) -> tuple[GnssFix | None, int]:
        tv = fix.time_us
        release_us = t
        out = fix
        c = self.counters
        for rt in self._gnss_rt:
            if not rt.covers(tv):
                continue
            ev = rt.event
            if isinstance(ev, GnssRate):
                if not self._rate_due(rt, ev, tv):
                    c["gnss_dropped"] += 1
                    return None, t
            elif isinstance(ev, GnssOutage):
                c["gnss_dropped"] += 1
                return None, t
            elif isinstance(ev, GnssJamming):
                since_us = tv - rt.start_us - round(ev.blackout_s * 1e6)
                if since_us < 0:
                    c["gnss_dropped"] += 1
                    return None, t
                phase = (since_us * 1e-6 / ev.flap_period_s) % 1.0
                if phase >= ev.flap_duty:
                    c["gnss_dropped"] += 1
                    return None, t
                out = self._garbage(out, ev, rt.rng)
                c["gnss_garbage"] += 1
            elif isinstance(ev, GnssDegradation):
                out = self._degrade(out, ev, rt)
                c["gnss_degraded"] += 1
            elif isinstance(ev, GnssSpoofDrift):
                dt = (tv - rt.start_us) * 1e-6
                b = math.radians(ev.bearing_deg)
                vn, ve = ev.rate_mps * math.cos(b), ev.rate_mps * math.sin(b)
                vd = -ev.vertical_rate_mps  # vertical_rate_mps is positive upwards
                drift = (vn * dt, ve * dt, vd * dt)
                out = self._shift(out, drift, vn, ve, vd, ev.consistent_velocity)
                c["gnss_spoofed"] += 1
            elif isinstance(ev, GnssSpoofHijack):
                out = self._shift(out, ev.offset_ned_m, 0.0, 0.0, 0.0, False)
                c["gnss_spoofed"] += 1
            elif isinstance(ev, GnssDelay):
                release_us = t + round(ev.extra_latency_s * 1e6)
                c["gnss_delayed"] += 1
        return out, release_us

    @staticmethod
    def _rate_due(rt: _Runtime, ev: GnssRate, tv: int) -> bool:
        period_us = 1e6 / ev.rate_hz
        if rt.first_us is None:
            rt.first_us = tv
        elif tv < rt.due_us - RATE_TOLERANCE_US:
            return False
        # Drift-free schedule from the first fix kept: skip every due time up to this fix.
        while rt.due_us - RATE_TOLERANCE_US <= tv:
            rt.k += 1
            rt.due_us = rt.first_us + round(rt.k * period_us)
        return True

    @staticmethod
    def _shift(
        fix: GnssFix,
        d_ned: tuple[float, float, float],
        vn: float,
        ve: float,
        vd: float,
        with_velocity: bool,
    ) -> GnssFix:
        lat, lon, alt = _offset_geodetic(fix.lat_rad, fix.lon_rad, fix.alt_msl_m, *d_ned)
        v = fix.v_ned_mps + np.array([vn, ve, vd]) if with_velocity else fix.v_ned_mps
        # Accuracy, fix type and satellites untouched: a spoofer looks healthy.
        return GnssFix(
            fix.time_us,
            lat,
            lon,
            alt,
            v,
            fix.eph_m,
            fix.epv_m,
            fix.speed_accuracy_mps,
            fix.fix_type,
            fix.satellites_visible,
            fix.sensor_id,
        )

    @staticmethod
    def _garbage(fix: GnssFix, ev: GnssJamming, rng: np.random.Generator) -> GnssFix:
        z = rng.standard_normal(6)
        u = float(rng.random())
        sats = int(rng.integers(3, 6))
        sp, sv = ev.garbage_sigma_m, ev.garbage_velocity_sigma_mps
        lat, lon, alt = _offset_geodetic(
            fix.lat_rad, fix.lon_rad, fix.alt_msl_m, sp * z[0], sp * z[1], sp * z[2]
        )
        return GnssFix(
            time_us=fix.time_us,
            lat_rad=lat,
            lon_rad=lon,
            alt_msl_m=alt,
            v_ned_mps=fix.v_ned_mps + sv * z[3:],
            eph_m=max(fix.eph_m, sp),
            epv_m=max(fix.epv_m, sp),
            speed_accuracy_mps=max(fix.speed_accuracy_mps, sv),
            fix_type=min(fix.fix_type, 2) if u < 0.5 else fix.fix_type,
            satellites_visible=min(fix.satellites_visible, sats),
            sensor_id=fix.sensor_id,
        )

    def _degrade(self, fix: GnssFix, ev: GnssDegradation, rt: _Runtime) -> GnssFix:
        tv = fix.time_us
        hist = self._hist
        # Fixes come in order of validity: older truths are never needed again.
        while len(hist) > 1 and hist[0][0] < tv:
            hist.popleft()
        # Exact when the fix's validity step went through apply() (always with SensorSuite);
        # otherwise the nearest later truth kept.
        _, lat0, lon0, alt0, v0 = hist[0]
        ramp = 1.0 if ev.ramp_s <= 0.0 else min(1.0, (tv - rt.start_us) * 1e-6 / ev.ramp_s)
        f = 1.0 + (ev.factor - 1.0) * ramp
        return GnssFix(
            time_us=tv,
            lat_rad=lat0 + f * (fix.lat_rad - lat0),
            lon_rad=lon0 + f * (fix.lon_rad - lon0),
            alt_msl_m=alt0 + f * (fix.alt_msl_m - alt0),
            v_ned_mps=np.array(v0) + f * (fix.v_ned_mps - np.array(v0)),
            eph_m=f * fix.eph_m,
            epv_m=f * fix.epv_m,
            speed_accuracy_mps=f * fix.speed_accuracy_mps,
            fix_type=fix.fix_type,
            satellites_visible=fix.satellites_visible,
            sensor_id=fix.sensor_id,
        )

    # -- barometer --
    def _baro(self, s: BaroSample) -> BaroSample:
        ts, sid = s.time_us, s.sensor_id
        offset = 0.0
        changed = False
        frozen: tuple[float, float] | None = None
        for rt in self._baro_rt:
            ev = rt.event
            if isinstance(ev, WeatherFront):
                if ts >= rt.start_us:
                    offset += ev.rate_pa_per_s * (min(ts, rt.end_us) - rt.start_us) * 1e-6
                    changed = True
            elif not rt.covers(ts):
                continue
            elif isinstance(ev, BaroDrift):
                offset += ev.rate_pa_per_s * (ts - rt.start_us) * 1e-6
                changed = True
            elif isinstance(ev, BaroGlitch):
                offset += ev.offset_pa
                changed = True
            elif isinstance(ev, BaroFreeze):
                held = rt.held.get(sid)
                if held is None:
                    last = self._last_baro.get(sid, s)
                    held = rt.held[sid] = (last.pressure_pa, last.temperature_k)
                frozen = held
        out = s
        if frozen is not None:
            out = BaroSample(ts, frozen[0], frozen[1], sid)
        elif changed:
            out = BaroSample(ts, s.pressure_pa + offset, s.temperature_k, sid)
        if out is not s:
            self.counters["baro_modified"] += 1
        if self._track_baro:
            self._last_baro[sid] = out
        return out

    # -- pitot --
    def _pitot(self, s: AirspeedSample) -> AirspeedSample | None:
        ts, sid = s.time_us, s.sensor_id
        out: AirspeedSample | None = s
        for rt in self._pitot_rt:
            if not rt.covers(ts):
                continue
            ev = rt.event
            if isinstance(ev, AirspeedFailure):
                self.counters["airspeed_dropped"] += 1
                return None
            if isinstance(ev, PitotDrift):
                dp = s.diff_pressure_pa + ev.rate_pa_per_s * (ts - rt.start_us) * 1e-6
            else:
                assert isinstance(ev, PitotBlockage)
                if ev.mode == "zero":
                    dp = 0.0
                else:
                    held = rt.held.get(sid)
                    if held is None:
                        last = self._last_pitot.get(sid, s)
                        held = rt.held[sid] = last.diff_pressure_pa
                    dp = held
            out = AirspeedSample(ts, dp, s.temperature_k, sid)
            self.counters["airspeed_modified"] += 1
            break  # one pitot event at a time (sim.faults.timeline)
        if self._track_pitot and out is not None:
            self._last_pitot[sid] = out
        return out

    # -- IMU --
    def _imu(self, s: ImuSample) -> ImuSample:
        ts, sid = s.time_us, s.sensor_id
        # Only the vectors an active event touches are converted (cost: this runs at IMU rate).
        vecs: list[list[float] | None] = [None, None]
        for rt in self._imu_rt:
            if not (rt.start_us <= ts < rt.end_us):
                continue
            v = vecs[rt.vec]
            if v is None:
                v = vecs[rt.vec] = (
                    s.angular_rate_b_rps if rt.vec else s.specific_force_b_mps2
                ).tolist()
            ev = rt.event
            if isinstance(ev, ImuBiasStep):
                v[ev.axis] += ev.value
            elif isinstance(ev, ImuSaturation):
                lim = ev.limit
                for i in rt.axes:
                    v[i] = min(lim, max(-lim, v[i]))
            else:  # ImuStuck
                (i,) = rt.axes
                held = rt.held.get(sid)
                if held is None:
                    last = self._last_imu.get(sid)
                    # Nothing seen before the start: hold the first value of the window.
                    held = rt.held[sid] = v[i] if last is None else last[rt.vec][i]
                v[i] = held
        acc, gyr = vecs
        if acc is None and gyr is None:
            out = s
        else:
            out = ImuSample(
                ts,
                s.dt_s,
                s.specific_force_b_mps2 if acc is None else np.array(acc),
                s.angular_rate_b_rps if gyr is None else np.array(gyr),
                s.temperature_k,
                sid,
            )
            self.counters["imu_modified"] += 1
        if self._track_imu:
            self._last_imu[sid] = (
                out.specific_force_b_mps2.tolist(),
                out.angular_rate_b_rps.tolist(),
            )
        return out

    # -- magnetometer --
    def _mag(self, s: MagSample, truth: Truth) -> MagSample:
        n = [0.0, 0.0, 0.0]
        active = False
        for rt in self._mag_rt:
            if rt.covers(s.time_us):
                ev = rt.event
                assert isinstance(ev, MagAnomaly)
                for i in range(3):
                    n[i] += ev.offset_ned_t[i]
                active = True
        if not active:
            return s
        b = _ned_to_body(truth.q_nb.tolist(), (n[0], n[1], n[2]))
        self.counters["mag_modified"] += 1
        return MagSample(s.time_us, s.field_b_tesla + np.array(b), s.sensor_id)
