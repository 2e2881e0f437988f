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
* ``send``: the state line of the step (its IMU sample and the latest pitot airspeed as our
  fusion gets them, so IMU and pitot faults reach ArduPilot too); parameter changes due by its
  simulated time go out on ArduPilot's MAVLink port (``mavlink_url``;
  :mod:`hil.autopilot.sim_params`) for what ArduPilot simulates itself (GPS, barometer).

Bad input (counted in :meth:`counters`, never fatal): an unknown magic (``bad_magic``) or a
known magic with the wrong length (``bad_size``) is ignored; an undriven mapped output (PWM 0)
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

__all__ = ["DEFAULT_URL", "ArduPilotBackend", "parse_json_url"]

DEFAULT_URL = "udpin:127.0.0.1:9002"
_EXPECTED = (
    f"expected ArduPilot SITL JSON servo packets (magic {SERVO_MAGIC_16} / {SERVO_MAGIC_32}, "
    f"{PACKET_SIZES[SERVO_MAGIC_16]} / {PACKET_SIZES[SERVO_MAGIC_32]} bytes; start SITL with "
    "--model JSON:<host>)"
)


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
    ) -> None:
        host, port = parse_json_url(url)
        self.url = url
        self.servo_map = servo_map or ServoMap.default()
        self.warnings: list[str] = []
        self._warn_cb = warn
        if origin is None and setup is not None:
            start = setup.flight.start
            origin = JsonOrigin(math.radians(start.lat_deg), math.radians(start.lon_deg), 0.0)
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

    def close(self) -> None:
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
        return servo.controls

    def send(self, step: SimStep) -> None:
        imu: ImuSample | None = None
        for sample in step.sensed:
            if isinstance(sample, ImuSample):
                imu = sample
            elif isinstance(sample, AirspeedSample):
                self._airspeed_mps = calibrated_airspeed_mps(sample.diff_pressure_pa)
        line = json_state_line(step.truth, self.origin, imu=imu, airspeed_mps=self._airspeed_mps)
        self._last_line = line
        self._counts["steps_answered"] += 1
        self._send(line)
        if self._params is not None:
            self._params.advance(step.truth.time_us * 1e-6)

    def counters(self) -> dict[str, int]:
        out = dict(self._counts)
        if self._params is not None:
            out.update(self._params.counters())
        return out

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
            if self._rate_hz is not None and parsed.frame_rate_hz != round(self._rate_hz):
                self._warn(f"ArduPilot asks for {parsed.frame_rate_hz} Hz physics "
                           f"(SIM_RATE_HZ); hilnav steps at {self._rate_hz:g} Hz: set "
                           f"SIM_RATE_HZ {self._rate_hz:g}")
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
