"""Actuator map: PX4's HIL_ACTUATOR_CONTROLS channels -> the aircraft's controls.

PX4's simulator interface sends ``controls[16]``, one value per output channel: channel ``i``
is the output configured by ``PWM_MAIN_FUNC{i+1}`` (SITL) or ``HIL_ACT_FUNC{i+1}`` (HITL).
PX4's ``pwm_out_sim`` scales a motor output to 0..1 and every other output (servos) to -1..1,
and ``simulator_mavlink`` sends zeros while the vehicle is disarmed. What a channel means is
the airframe's choice (control allocation, ``CA_SV_CS*`` parameters), so an actuator map says
how each channel drives the aircraft: the control vector :meth:`sim.flight.Flight.command`
takes (PX4's legacy HIL order and signs: roll, + = right wing down; pitch, + = nose up; yaw,
+ = nose right; throttle 0..1; flaps 0..1).

File format (YAML)::

    # PX4 standard plane (1030_gazebo-classic_plane): see docs/autopilot/px4-standard-plane.yaml
    channels:
      - {channel: 5, control: roll, scale: -0.5}   # PWM_MAIN_FUNC6 = 201 left aileron
      - {channel: 6, control: roll, scale: 0.5}    # PWM_MAIN_FUNC7 = 202 right aileron
      - {channel: 7, control: pitch}               # PWM_MAIN_FUNC8 = 203 elevator
      - {channel: 2, control: yaw}                 # PWM_MAIN_FUNC3 = 204 rudder
      - {channel: 4, control: throttle}            # PWM_MAIN_FUNC5 = 101 motor 1

``channel`` is the 0-based index into ``controls[16]``; ``control`` one of roll (alias
aileron), pitch (elevator), yaw (rudder), throttle, flaps; ``scale`` (default 1) and
``offset`` (default 0) give ``scale * controls[channel] + offset``. Several entries of one
control add up (two ailerons, two flaps), and one channel may feed several controls (elevons).
roll, pitch, yaw and throttle must each be fed (``scale: 0`` with an ``offset`` pins one);
flaps may be left out (they then hold). A non-finite channel value makes its control
non-finite, which the flight ignores and counts; values outside a control's range are
clipped and counted there too.

The default (:meth:`ActuatorMap.default`) is the legacy HIL order: channels 0 roll, 1 pitch,
2 yaw, 3 throttle, each with scale 1.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Final, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from sim.vehicle_state import CONTROL_INDEX

__all__ = ["CONTROLS", "ActuatorMap", "ChannelMapping"]

Control = Literal["roll", "pitch", "yaw", "throttle", "flaps"]
CONTROLS: Final[tuple[Control, ...]] = ("roll", "pitch", "yaw", "throttle", "flaps")
"""The aircraft controls a channel can drive, in the control vector's order."""
_ALIASES: Final = {"aileron": "roll", "elevator": "pitch", "rudder": "yaw"}
_REQUIRED: Final[tuple[Control, ...]] = ("roll", "pitch", "yaw", "throttle")
_N_CHANNELS: Final = 16  # HIL_ACTUATOR_CONTROLS.controls


class ChannelMapping(BaseModel):
    """One channel feeding one control: ``scale * controls[channel] + offset``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    channel: int = Field(ge=0, lt=_N_CHANNELS)
    control: Control
    scale: float = Field(default=1.0, allow_inf_nan=False)
    offset: float = Field(default=0.0, allow_inf_nan=False)

    @field_validator("control", mode="before")
    @classmethod
    def _alias(cls, value: object) -> object:
        return _ALIASES.get(value, value) if isinstance(value, str) else value


class ActuatorMap(BaseModel):
    """How HIL_ACTUATOR_CONTROLS channels drive the aircraft (see the module docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    channels: tuple[ChannelMapping, ...] = Field(min_length=1)

    @model_validator(mode="after")
    def _check(self) -> ActuatorMap:
        fed = {m.control for m in self.channels}
        missing = [c for c in _REQUIRED if c not in fed]
        if missing:
            raise ValueError(
                f"no channel feeds {', '.join(missing)} (roll, pitch, yaw and throttle are "
                "required; scale: 0 with an offset pins a control)"
            )
        return self

    @classmethod
    def default(cls) -> ActuatorMap:
        """The legacy HIL order: 0 roll, 1 pitch, 2 yaw, 3 throttle."""
        return cls(channels=tuple(
            ChannelMapping(channel=i, control=c) for i, c in enumerate(_REQUIRED)))

    @classmethod
    def load(cls, path: Path | str) -> ActuatorMap:
        """Read an actuator map YAML file.

        Raises
        ------
        ValueError
            Missing file, bad YAML, or bad content (one line naming the file and the entry).
        """
        p = Path(path)
        if not p.is_file():
            raise ValueError(f"actuator map {p}: no such file")
        try:
            data = yaml.safe_load(p.read_text(encoding="utf-8"))
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            where = f" (line {mark.line + 1})" if mark is not None else ""
            raise ValueError(f"actuator map {p}: not valid YAML{where}") from None
        if not isinstance(data, dict):
            raise ValueError(f"actuator map {p}: expected a mapping with a 'channels' list")
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            e = exc.errors()[0]
            loc = ".".join(str(x) for x in e["loc"]) or "file"
            raise ValueError(f"actuator map {p}: {loc}: {e['msg']}") from None

    @property
    def n_controls(self) -> int:
        """Length of the control vectors :meth:`apply` returns (up to the last fed control)."""
        return 1 + max(CONTROL_INDEX[m.control] for m in self.channels)

    def apply(self, channels: Sequence[float]) -> list[float]:
        """The control vector (PX4 legacy order and signs) for one HIL_ACTUATOR_CONTROLS.

        Parameters
        ----------
        channels : sequence of float
            ``controls[16]`` as received (a shorter sequence reads as zeros beyond its end).

        Returns
        -------
        list of float
            ``n_controls`` values (flaps, last in the order, only when fed); a control fed by
            a non-finite channel is non-finite (the flight ignores and counts it).
        """
        out = [0.0] * self.n_controls
        n = len(channels)
        for m in self.channels:
            raw = float(channels[m.channel]) if m.channel < n and m.scale != 0.0 else 0.0
            out[CONTROL_INDEX[m.control]] += m.scale * raw + m.offset
        return out
