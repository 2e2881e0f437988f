"""Tests of the autopilot-in-the-loop simulator loop (hil.autopilot.fly_with_autopilot) with
an in-process backend: the loop's contract, not a protocol (the PX4 and ArduPilot protocol
tests speak real sockets to protocol peers).

The in-process backend holds the trimmed pitch, yaw and throttle and flies a wings-level roll
loop (PI on roll, damping on the roll rate) on the truth it was sent, so the aircraft really
responds to what is commanded.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence

from hil.autopilot import fly_with_autopilot
from hil.pipeline import SimSetup, SimStep


class _Backend:
    name = "test autopilot"

    def __init__(self, *, silent_after: int | None = None, bad_every: int = 0) -> None:
        self.silent_after = silent_after
        self.bad_every = bad_every
        self.sent: list[int] = []
        self.asked = 0
        self.roll_rad = self.p_rps = self.roll_integral = 0.0

    def wait_connected(self, timeout_s: float, stop: threading.Event) -> bool:
        return True

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        self.asked += 1
        if self.silent_after is not None and self.asked > self.silent_after:
            return None
        # the controls of step k are computed from what step k-1 sent: never ahead
        assert len(self.sent) == self.asked - 1
        self.roll_integral += self.roll_rad * 0.01  # 100 Hz
        aileron = -0.8 * self.roll_rad - 0.3 * self.p_rps - 0.8 * self.roll_integral
        aileron = max(-0.3, min(0.3, aileron))
        if self.bad_every and self.asked % self.bad_every == 0:
            return [aileron, math.nan]  # a NaN pitch: ignored (the trimmed pitch holds)
        return [aileron]  # the other controls hold at the trim

    def send(self, step: SimStep) -> None:
        self.sent.append(step.truth.time_us)
        w, x, y, z = (float(v) for v in step.truth.q_nb)
        self.roll_rad = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        self.p_rps = float(step.truth.omega_b_rps[0])

    def counters(self) -> dict[str, int]:
        return {"sent": len(self.sent)}


def _setup(duration_s: float = 4.0) -> SimSetup:
    return SimSetup.build(duration_s=duration_s, rate_hz=100.0, seed=3)


def test_lockstep_flies_one_step_per_command_and_feeds_every_frame() -> None:
    backend = _Backend(bad_every=50)
    frames: list[int] = []
    flown = fly_with_autopilot(_setup(), backend, on_frame=lambda t, f: frames.append(t))
    assert flown.connected and flown.stalled is None and flown.ended is None
    assert flown.steps == 400 == len(backend.sent) == backend.asked - 1
    assert flown.frames == len(frames) > flown.steps  # IMU every step, plus GNSS/truth/...
    assert flown.clipped_controls == 8  # one NaN pitch every 50 commands
    assert abs(backend.roll_rad) < math.radians(5.0)  # the roll loop held the wings level


def test_a_silent_autopilot_stalls_the_run_without_running_ahead() -> None:
    backend = _Backend(silent_after=120)
    flown = fly_with_autopilot(_setup(), backend, stall_timeout_s=0.05)
    assert flown.steps == 120 == len(backend.sent)
    assert flown.stalled is not None and "1.20 s" in flown.stalled
