"""ArduPilot's servo outputs -> the control vector :meth:`sim.flight.Flight.command` takes.

ArduPilot SITL sends PWM (us) of its servo outputs 1-16 (or 1-32) in every JSON-backend servo
packet (:mod:`hil.autopilot.sitl_json`). A :class:`ServoMap` says which output drives which
control and how its PWM scales; it is the :class:`hil.codec.ServoChannelMap` that also decodes
SERVO_OUTPUT_RAW (one definition of an output's PWM scaling and signs), plus a YAML file
format and the surface names of ArduPilot's ``SERVOn_FUNCTION`` (aileron, elevator, rudder).

Signs (ArduPlane)
    ArduPlane writes each surface as a scaled output (``SRV_Channels::set_output_scaled``,
    +-4500) and turns it into PWM as ``trim + scaled / 4500 * (max - trim)`` (below the trim
    with ``trim - min``), negated when ``SERVOn_REVERSED`` is set. PWM above the trim is roll
    right, nose up, nose right: that is what ArduPilot's own SITL plane, which ArduPlane's
    default parameters fly with unreversed servos, does with it (``libraries/SITL/
    SIM_Plane.cpp``: surface angle ``(pwm - 1500) / 500`` times ``c_l_deltaa = 0.25``,
    ``c_m_deltae = 1.0``, ``c_n_deltar = 0.1``, all positive, in FRD moments). So PWM above
    the trim maps to PX4's positive roll / pitch / yaw (``reversed: true`` undoes a reversed
    servo). The throttle is ``(pwm - min) / (max - min)``. Read from ArduPilot's sources; not
    checked against a running ArduPlane (none can run on this machine).

YAML (``--servo-map FILE``)::

    # ArduPlane's default outputs (SERVO1..4_FUNCTION = 4, 19, 70, 21)
    channels:
      - {servo: 1, control: aileron}                       # PWM 1000 / 1500 / 2000 us
      - {servo: 2, control: elevator, reversed: false}
      - {servo: 3, control: throttle, pwm_min_us: 1100, pwm_max_us: 1900}
      - {servo: 4, control: rudder}
      - {servo: 5, control: flaps}

    ``servo`` is the 1-based output number (``SERVOn``; 1-16), ``control`` one of aileron
    (= roll), elevator (= pitch), rudder (= yaw), throttle, flaps (or the other
    :class:`hil.codec.ServoChannel` control names); ``pwm_min_us`` / ``pwm_trim_us`` /
    ``pwm_max_us`` default to 1000 / 1500 / 2000 (``SERVOn_MIN`` / ``_TRIM`` / ``_MAX``);
    ``reversed`` to false. Unmapped controls are 0 (the aircraft's own neutral).

Bad PWM
    A mapped output at 0 or 65535 (ArduPilot sends 0 for an output it does not drive) holds
    that control (NaN, which ``Flight.command`` ignores and counts) and is counted
    (``undriven``); PWM outside [min, max] is clipped and counted (``clipped``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from hil.codec import ServoChannel, ServoChannelMap
from hil.codec.wire import UINT16_MAX
from sim.vehicle_state import CONTROL_INDEX, N_CONTROLS

__all__ = ["SURFACE_NAMES", "ServoControls", "ServoMap"]

SURFACE_NAMES = {"aileron": "roll", "elevator": "pitch", "rudder": "yaw"}
"""ArduPilot's surface names -> the control names of :class:`hil.codec.ServoChannel`."""


@dataclass(frozen=True, slots=True)
class ServoControls:
    """One packet's PWM as controls: PX4 order and signs (NaN = hold), and what was bad."""

    controls: tuple[float, ...]
    clipped: int
    undriven: int


class ServoMap:
    """Which ArduPilot servo output drives which control (see the module docstring).

    Parameters
    ----------
    channels : ServoChannelMap
        The outputs (``ServoChannel.output`` = the 1-based servo number).
    """

    def __init__(self, channels: ServoChannelMap) -> None:
        self.channels = channels
        self._slots = [(c.output - 1, CONTROL_INDEX[c.control], c) for c in channels.channels]

    @classmethod
    def default(cls) -> ServoMap:
        """ArduPlane's default outputs: 1 aileron, 2 elevator, 3 throttle, 4 rudder,
        PWM 1000 / 1500 / 2000 us, none reversed."""
        return cls(ServoChannelMap())

    @classmethod
    def load(cls, path: Path | str) -> ServoMap:
        """Read a servo map YAML file; ValueError names the file and what is wrong."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) else type(exc).__name__
            raise ValueError(f"servo map {path}: cannot read it ({reason})") from None
        return cls.from_mapping(data, source=str(path))

    @classmethod
    def from_mapping(cls, data: Any, *, source: str = "servo map") -> ServoMap:
        """A servo map from parsed YAML (``{"channels": [...]}``); ValueError names the
        bad entry."""
        if not isinstance(data, dict) or set(data) != {"channels"}:
            raise ValueError(f"{source}: expected one key 'channels' with a list of outputs")
        entries = data["channels"]
        if not isinstance(entries, list) or not entries:
            raise ValueError(f"{source}: 'channels' must be a non-empty list")
        channels = []
        for i, entry in enumerate(entries, 1):
            if not isinstance(entry, dict):
                raise ValueError(f"{source}: channel {i} must be a mapping")
            fields = dict(entry)
            if "servo" in fields:
                fields["output"] = fields.pop("servo")
            control = fields.get("control")
            if isinstance(control, str):
                fields["control"] = SURFACE_NAMES.get(control, control)
            try:
                channels.append(ServoChannel.model_validate(fields))
            except ValidationError as exc:
                err = exc.errors()[0]
                where = ".".join(str(p) for p in err["loc"]) or "entry"
                where = "servo" if where == "output" else where
                raise ValueError(f"{source}: channel {i}: {where}: {err['msg']}") from None
        try:
            return cls(ServoChannelMap(channels=tuple(channels)))
        except ValidationError as exc:
            raise ValueError(f"{source}: {exc.errors()[0]['msg']}") from None

    def controls(self, pwm_us: Sequence[int]) -> ServoControls:
        """PWM of outputs 1..len(pwm_us) -> a control vector in PX4 order (length
        :data:`sim.vehicle_state.N_CONTROLS`; unmapped 0, undriven NaN)."""
        out = [0.0] * N_CONTROLS
        clipped = undriven = 0
        for index, slot, channel in self._slots:
            pwm = pwm_us[index] if index < len(pwm_us) else 0
            if pwm <= 0 or pwm >= UINT16_MAX:
                out[slot] = math.nan
                undriven += 1
                continue
            value, was_clipped = channel.normalised(pwm)
            out[slot] = value
            clipped += was_clipped
        return ServoControls(tuple(out), clipped, undriven)

    def pwm(self, controls: Sequence[float]) -> list[int]:
        """The inverse: controls in PX4 order -> PWM of outputs 1-16 (unmapped outputs 0),
        what an ArduPilot with this map would output (used by protocol peers and tests)."""
        out = [0] * 16
        for index, slot, c in self._slots:
            x = min(max(float(controls[slot]), -1.0), 1.0) if slot < len(controls) else 0.0
            if c.control == "throttle":
                x = min(max(x, 0.0), 1.0)
                x = 1.0 - x if c.reversed else x
                pwm = c.pwm_min_us + x * (c.pwm_max_us - c.pwm_min_us)
            else:
                x = -x if c.reversed else x
                span = (c.pwm_max_us - c.pwm_trim_us) if x >= 0 else (c.pwm_trim_us - c.pwm_min_us)
                pwm = c.pwm_trim_us + x * span
            out[index] = round(pwm)
        return out
