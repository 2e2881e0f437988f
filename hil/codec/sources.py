"""What the decoder remembers per message source: IMU timestamps (-> ``dt_s``), temperatures.

``ImuSample.dt_s`` is not on the wire: the decoder infers it from consecutive timestamps of
the same source (system, component, message id, sensor id). The first sample of a source
gets ``imu_dt_s`` if given, else :data:`DEFAULT_FIRST_IMU_DT_S` = 0.0 (no interval
information: integrating it adds nothing). A repeated timestamp is a duplicate and is
dropped; a timestamp that goes backwards (simulator restart) restarts the source; both are
counted.

RAW_RPM has no timestamp: it is stamped with the latest time of its *system*
(:attr:`SourceState.last_time_us`: the newest sample time decoded from any component of that
system id, GNSS fixes excepted, as their time of validity lags; all components of one vehicle
share its clock). SERVO_OUTPUT_RAW's ``time_usec`` is a uint32 that wraps after 71.6 min;
:meth:`SourceState.unwrap_u32_us` unwraps it per source.
"""

from __future__ import annotations

from typing import Final

from hil.codec.counters import DecoderCounters

__all__ = ["DEFAULT_FIRST_IMU_DT_S", "SourceKey", "SourceState"]

DEFAULT_FIRST_IMU_DT_S: Final = 0.0
_U32_RANGE: Final = 1 << 32

SourceKey = tuple[int, int, int, int]  # system, component, msg id, sensor id


class SourceState:
    """Per-source memory of one decoder.

    Parameters
    ----------
    first_dt_s : float
        ``dt_s`` of the first IMU sample of a source (and of the first after a restart), s.

    Attributes
    ----------
    last_temperature_k : dict of SourceKey -> float
        Last temperature received from each HIL_SENSOR / HIGHRES_IMU source, K.
    """

    def __init__(self, first_dt_s: float) -> None:
        self.first_dt_s = first_dt_s
        self.last_imu_time_us: dict[SourceKey, int] = {}
        self.last_temperature_k: dict[SourceKey, float] = {}
        self.last_time_us: dict[int, int] = {}
        self._u32: dict[tuple[int, int], tuple[int, int]] = {}  # source -> (last raw, offset)

    def imu_dt_s(self, key: SourceKey, time_us: int, counters: DecoderCounters) -> float | None:
        """Interval since the source's previous sample, s; None for a duplicate (drop it)."""
        last = self.last_imu_time_us.get(key)
        if last is not None and time_us == last:
            counters.imu_duplicates += 1
            return None
        self.last_imu_time_us[key] = time_us
        if last is None:
            return self.first_dt_s
        if time_us < last:
            counters.imu_time_resets += 1
            return self.first_dt_s
        return (time_us - last) * 1e-6

    def unwrap_u32_us(self, source: tuple[int, int], raw_us: int) -> int:
        """A uint32 microsecond time of ``source`` (system, component) unwrapped to a
        monotonic int: a jump back by more than half the range is a wrap (+2**32); a smaller
        one a restart of the sender (the unwrapping starts again)."""
        last, offset = self._u32.get(source, (raw_us, 0))
        if raw_us < last:
            offset = offset + _U32_RANGE if last - raw_us > _U32_RANGE // 2 else 0
        self._u32[source] = (raw_us, offset)
        return raw_us + offset

    def restart(self, key: SourceKey) -> None:
        """Forget the source's IMU timestamp (the simulation was reset)."""
        self.last_imu_time_us.pop(key, None)
