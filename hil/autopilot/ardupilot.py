"""ArduPilot SITL flies our aircraft: the JSON physics backend (:class:`ArduPilotBackend`).

ArduPilot SITL started with ``--model JSON:<our host>`` sends a binary servo packet
(:mod:`hil.autopilot.sitl_json`) to UDP port 9002 for every physics frame it wants and waits
for one JSON state line back, sent to the address the packet came from. This backend is the
UDP server of that exchange; :func:`hil.autopilot.fly_with_autopilot` runs it in lockstep:

* ``wait_connected``: until the first valid servo packet (its PWM are the first controls).
* ``controls``: the next packet with a NEW frame count -> PWM -> :class:`ServoMap` -> controls
  in PX4's order. A packet repeating the last frame count (ArduPilot resends after 1 s
  without an answer, e.g. when our line was lost) does not step: it gets the last state line
  again (``repeated_frames``). A frame count going backwards means ArduPilot restarted: it is
  reported once per restart (``restarts``, :attr:`ArduPilotBackend.warnings`) and flown on
  (the aircraft cannot be put back; ArduPilot's clock simply resumes at our timestamp).
* trim hold: a booting or disarmed ArduPlane sits in MANUAL with neutral surfaces and its
  throttle at the minimum, which a trimmed aircraft in the air does not survive; its outputs are
  flown only once it reports itself armed (:class:`hil.autopilot.arming.TrimHold`, as for
  PX4). The armed flag is read from the HEARTBEATs on its MAVLink port (``mavlink_url``) and
  from its telemetry when the run records it (:meth:`ArduPilotBackend.watch_armed`); with
  neither the backend cannot see it and flies the outputs from the first packet
  (``trim_released_s`` None, ``disarmed_controls`` 0).
  :attr:`ArduPilotBackend.trim_released_s` is the simulated time the hold ended.
* ``send``: the state line of the step (its IMU sample and the latest pitot airspeed as our
  fusion gets them, so IMU and pitot faults reach ArduPilot too); parameter changes due by its
  simulated time go out on ArduPilot's MAVLink port (``mavlink_url``;
  :mod:`hil.autopilot.sim_params`) for what ArduPilot simulates itself (GPS, barometer).

Bad input (counted in :meth:`counters`, never fatal): an unknown magic (``bad_magic``) or a
known magic with the wrong length (``bad_size``) is ignored; a physics rate (SIM_RATE_HZ)
unlike ours is one warning, once ArduPilot has asked for the same rate for
``RATE_SETTLED_PACKETS`` packets (its rate changes while it boots) or, failing that, at the end
with the last rate asked for; an undriven mapped output (PWM 0)
holds its control, PWM outside the servo's range is clipped (``pwm_undriven``,
``pwm_clipped``); MAVLink bytes on the JSON port (``wrong_protocol``) put one line naming what
was expected into :attr:`ArduPilotBackend.warnings` (and ``warn``).

Addresses: the default ``udpin:127.0.0.1:9002`` serves an ArduPilot on the same machine; use
``udpin:0.0.0.0:9002`` when SITL runs elsewhere (``--model JSON:<this machine's address>``).
"""

from __future__ import annotations

import math
import selectors
import socket
import threading
import time
from collections.abc import Callable, Sequence
from typing import Final

from hil.autopilot.arming import TrimHold
from hil.autopilot.backend import DenialStep
from hil.autopilot.servos import ServoMap
from hil.autopilot.sim_params import SimParamSender
from hil.autopilot.sitl_json import (
    PACKET_SIZES,
    SERVO_MAGIC_16,
    SERVO_MAGIC_32,
    JsonOrigin,
    ServoPacket,
    json_state_line,
    parse_servo_packet,
)
from hil.pipeline import SimSetup, SimStep
from physconst.airdata import calibrated_airspeed_mps
from sim.faults.ardupilot import ardupilot_param_schedule, ardupilot_unmapped
from sim.samples import AirspeedSample, ImuSample

__all__ = ["DEFAULT_URL", "RATE_SETTLED_PACKETS", "ArduPilotBackend", "json_origin",
           "parse_json_url"]

DEFAULT_URL = "udpin:127.0.0.1:9002"
RATE_SETTLED_PACKETS: Final = 200
"""Packets asking for the same physics rate after which ArduPilot's rate counts as settled."""
_EXPECTED = (
    f"expected ArduPilot SITL JSON servo packets (magic {SERVO_MAGIC_16} / {SERVO_MAGIC_32}, "
    f"{PACKET_SIZES[SERVO_MAGIC_16]} / {PACKET_SIZES[SERVO_MAGIC_32]} bytes; start SITL with "
    "--model JSON:<host>)"
)


def json_origin(setup: SimSetup) -> JsonOrigin:
    """The origin of the JSON position for ``setup`` (ArduPilot's home): the start of the
    flight at 0 m MSL, JSBSim's ground."""
    start = setup.flight.start
    return JsonOrigin(math.radians(start.lat_deg), math.radians(start.lon_deg), 0.0)


def parse_json_url(text: str) -> tuple[str, int]:
    """``udpin:HOST:PORT`` (or ``udp:HOST:PORT``) -> (host, port); ValueError otherwise."""
    scheme, _, rest = text.partition(":")
    host, sep, port = rest.rpartition(":")
    if scheme not in ("udpin", "udp") or not sep or not host or not port.isdigit() \
            or not 0 <= int(port) <= 0xFFFF:
        raise ValueError(f"ArduPilot JSON URL {text!r}: expected udpin:HOST:PORT, e.g. "
                         f"{DEFAULT_URL} (0.0.0.0 to accept a SITL on another machine)")
    return host.strip("[]"), int(port)


class ArduPilotBackend:
    """ArduPilot SITL's JSON physics interface, simulator side (see the module docstring).

    Parameters
    ----------
    url : str
        Where to listen: ``udpin:HOST:PORT`` (port 0: a free port, see :attr:`local_address`).
    servo_map : ServoMap, optional
        PWM -> controls (default :meth:`ServoMap.default`, ArduPlane's outputs).
    setup : SimSetup, optional
        Its GNSS windows and fault events become SIM_* parameter changes
        (:mod:`sim.faults.ardupilot`), sent over ``mavlink_url``; its start is the JSON origin
        (ArduPilot's home; altitude 0 m MSL, JSBSim's ground) unless ``origin`` is given.
    mavlink_url : str, optional
        ArduPilot's MAVLink port for the parameters, e.g. ``tcp:127.0.0.1:5760``. Without it
        nothing is denied in ArduPilot's own sensors (:attr:`warnings` says so when the setup
        has events).
    origin : JsonOrigin, optional
        The origin of the JSON position (ArduPilot's ``--home``).
    warn : callable, optional
        Called with each warning line as it happens.
    hold_trim_disarmed : bool
        Fly the trim until ArduPilot reports itself armed (see the module docstring).
    """

    name = "ArduPilot"

    def __init__(
        self,
        url: str = DEFAULT_URL,
        *,
        servo_map: ServoMap | None = None,
        setup: SimSetup | None = None,
        mavlink_url: str | None = None,
        origin: JsonOrigin | None = None,
        warn: Callable[[str], None] | None = None,
        hold_trim_disarmed: bool = True,
    ) -> None:
        host, port = parse_json_url(url)
        self.url = url
        self.servo_map = servo_map or ServoMap.default()
        self.warnings: list[str] = []
        self._warn_cb = warn
        if origin is None and setup is not None:
            origin = json_origin(setup)
        self.origin = origin or JsonOrigin(0.0, 0.0, 0.0)
        self._params: SimParamSender | None = None
        if setup is not None:
            self._params = self._param_sender(setup, mavlink_url)
        try:
            self._sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET,
                                       socket.SOCK_DGRAM)
            self._sock.bind((host, port))
        except OSError as exc:
            if self._params is not None:
                self._params.close()
            raise ValueError(f"ArduPilot JSON URL {url}: cannot listen ({exc.strerror})") from None
        self._sock.setblocking(False)
        self._sel = selectors.DefaultSelector()
        self._sel.register(self._sock, selectors.EVENT_READ)
        self._peer: tuple[str, int] | None = None
        self._frame_count: int | None = None
        self._pending: ServoPacket | None = None
        self._last_line: bytes | None = None
        self._counts = dict.fromkeys(
            ("packets", "packets_16", "packets_32", "steps_answered", "repeated_frames",
             "skipped_frames", "restarts", "bad_magic", "bad_size", "wrong_protocol",
             "pwm_clipped", "pwm_undriven", "send_errors"), 0)
        self.frame_rate_hz: int | None = None
        self._airspeed_mps: float | None = None  # of the latest pitot sample (held between)
        self._rate_hz = None if setup is None else setup.flight.rate_hz
        self._rate_run = 0  # packets in a row asking for frame_rate_hz
        self._rate_warned = False
        self.trim_hold = TrimHold(enabled=hold_trim_disarmed)
        self._armed_sources: list[Callable[[], bool | None]] = []
        if self._params is not None:
            params = self._params
            self._armed_sources.append(lambda: params.armed)
        self._time_us = 0  # of the latest step sent
        self._params_finished = False

    # -- setup --
    def _param_sender(self, setup: SimSetup, mavlink_url: str | None) -> SimParamSender | None:
        events = tuple(setup.faults or ())
        for ev in events:
            reason = ardupilot_unmapped(ev)
            if reason is not None:
                self._warn(f"{ev.type_name} at {ev.start_s:g} s does not reach ArduPilot: {reason}")
        schedule = ardupilot_param_schedule(
            events, [(w.start_s, w.duration_s) for w in setup.gnss_off],
            origin_lat_rad=math.radians(setup.flight.start.lat_deg),
            origin_alt_msl_m=setup.flight.start.alt_msl_m, duration_s=setup.duration_s,
        )
        denial = [p for p in schedule if p.time_s > 0]
        if mavlink_url is None:
            if denial:
                self._warn("the scenario's GNSS / sensor events do not reach ArduPilot's own "
                           "simulated sensors without --ardupilot-mavlink (its MAVLink port)")
            return None
        return SimParamSender(mavlink_url, schedule)

    def _warn(self, line: str) -> None:
        self.warnings.append(line)
        if self._warn_cb is not None:
            self._warn_cb(line)

    @property
    def local_address(self) -> tuple[str, int]:
        """Where we listen (the bound port when the URL asked for port 0)."""
        host, port = self._sock.getsockname()[:2]
        return host, port

    @property
    def param_sender(self) -> SimParamSender | None:
        """The MAVLink parameter sender (None without a setup)."""
        return self._params

    def watch_armed(self, source: Callable[[], bool | None]) -> None:
        """Also read ArduPilot's armed flag from ``source`` (e.g. its telemetry's HEARTBEAT:
        :attr:`hil.autopilot.telemetry.AutopilotTelemetry.armed`; None: not heard yet)."""
        self._armed_sources.append(source)

    def armed(self) -> bool | None:
        """Whether ArduPilot reports itself armed (False while booting: not yet heard);
        None when nothing shows its armed state."""
        if not self._armed_sources:
            return None
        return any(source() for source in self._armed_sources)

    @property
    def trim_released_s(self) -> float | None:
        """Simulated time (s) ArduPilot first reported itself armed (the trim hold ended)."""
        return self.trim_hold.released_s

    def problems(self) -> list[str]:
        """What did not reach ArduPilot (its denial parameters; :mod:`hil.autopilot.sim_params`),
        asked once the flight is over (it waits briefly for the acknowledgements owed)."""
        if self._params is None:
            return []
        self._finish_params()
        return self._params.problems()

    def denial(self) -> list[DenialStep]:
        """Each SIM_* change of the scenario's denial and its outcome (none without a MAVLink
        port: then ArduPilot's own sensors were never denied)."""
        if self._params is None:
            return []
        self._finish_params()
        return self._params.steps()

    def _finish_params(self) -> None:
        if self._params is not None and not self._params_finished:
            self._params_finished = True
            self._params.finish()

    def close(self) -> None:
        self._warn_rate()
        self._sel.close()
        self._sock.close()
        if self._params is not None:
            self._params.close()

    def __enter__(self) -> ArduPilotBackend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- AutopilotBackend --
    def wait_connected(self, timeout_s: float, stop: threading.Event) -> bool:
        deadline = time.monotonic() + timeout_s
        while not stop.is_set():
            if self._params is not None:
                self._params.poll()
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            packet = self._receive(min(remaining, 0.1))
            if packet is not None:
                self._pending = packet
                return True
        return False

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        packet, self._pending = self._pending, None
        deadline = time.monotonic() + timeout_s
        while packet is None:
            remaining = deadline - time.monotonic()
            if remaining < 0:
                return None
            packet = self._receive(remaining)
        servo = self.servo_map.controls(packet.pwm_us)
        self._counts["pwm_clipped"] += servo.clipped
        self._counts["pwm_undriven"] += servo.undriven
        return self.trim_hold.apply(servo.controls, self.armed(), self._time_us)

    def send(self, step: SimStep) -> None:
        imu: ImuSample | None = None
        for sample in step.sensed:
            if isinstance(sample, ImuSample):
                imu = sample
            elif isinstance(sample, AirspeedSample):
                self._airspeed_mps = calibrated_airspeed_mps(sample.diff_pressure_pa)
        line = json_state_line(step.truth, self.origin, imu=imu, airspeed_mps=self._airspeed_mps)
        self._last_line = line
        self._time_us = step.truth.time_us
        self._counts["steps_answered"] += 1
        self._send(line)
        if self._params is not None:
            self._params.advance(step.truth.time_us * 1e-6)

    def counters(self) -> dict[str, int]:
        out = dict(self._counts)
        out["disarmed_controls"] = self.trim_hold.held
        if self._params is not None:
            out.update(self._params.counters())
        return out

    def _warn_rate(self) -> None:
        """One warning when ArduPilot's physics rate is not ours (see the module docstring)."""
        rate = self.frame_rate_hz
        if self._rate_warned or rate is None or self._rate_hz is None \
                or rate == round(self._rate_hz):
            return
        self._rate_warned = True
        self._warn(f"ArduPilot asks for {rate} Hz physics (SIM_RATE_HZ); hilnav steps at "
                   f"{self._rate_hz:g} Hz: set SIM_RATE_HZ {self._rate_hz:g}")

    # -- the socket --
    def _send(self, line: bytes) -> None:
        if self._peer is None:
            return
        try:
            self._sock.sendto(line, self._peer)
        except OSError:
            self._counts["send_errors"] += 1

    def _receive(self, timeout_s: float) -> ServoPacket | None:
        """The next servo packet with a new frame count, within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                data, address = self._sock.recvfrom(2048)
            except BlockingIOError:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._sel.select(remaining)
                continue
            except OSError:
                continue  # ICMP port unreachable of an earlier send: nothing to read
            packet = self._accept(data, address)
            if packet is not None:
                return packet

    def _accept(self, data: bytes, address: tuple[str, int]) -> ServoPacket | None:
        parsed = parse_servo_packet(data)
        if isinstance(parsed, str):
            self._counts[parsed] += 1
            if parsed == "wrong_protocol" and self._counts[parsed] == 1:
                self._warn(f"{self.url}: {address[0]}:{address[1]} sent MAVLink bytes; "
                           f"{_EXPECTED}")
            return None
        c = self._counts
        c["packets"] += 1
        c["packets_32" if len(parsed.pwm_us) == 32 else "packets_16"] += 1
        self._peer = address
        if self.frame_rate_hz != parsed.frame_rate_hz:
            self.frame_rate_hz = parsed.frame_rate_hz
            self._rate_run = 0
        self._rate_run += 1
        if self._rate_run >= RATE_SETTLED_PACKETS:
            self._warn_rate()
        last = self._frame_count
        if last is not None and parsed.frame_count == last:
            c["repeated_frames"] += 1
            if self._last_line is not None:
                self._send(self._last_line)  # it did not get our answer: answer again
            return None
        if last is not None and parsed.frame_count < last:
            c["restarts"] += 1
            self._warn(f"ArduPilot restarted (frame count {last} -> {parsed.frame_count}); "
                       "flying on from the current state")
        elif last is not None and parsed.frame_count > last + 1:
            c["skipped_frames"] += parsed.frame_count - last - 1
        self._frame_count = parsed.frame_count
        return parsed
