"""Input screening for :class:`fusion.filter.NavFilter`: which samples may be used, and how.

IMU samples (:meth:`SampleScreen.imu`): a sample with an unreadable or out-of-range timestamp
(negative, or beyond :data:`MAX_TIME_US`) is dropped, a duplicated one too; one with
non-finite or out-of-range fields is replaced by the last good sample (zero-order hold over its
interval). The filter's clock is never moved by one sample: a stamp more than
``ImuTuning.time_jump_s`` ahead of it, or behind it, is *quarantined* (counted, dropped). Only
``time_base_confirm_samples`` consecutive quarantined samples at plausible intervals
(``<= max_dt_s`` apart) are a new time base: a forward gap up to ``max_coast_s`` is then a gap
the INS coasts over instead of integrating it, anything else (a step back, as after a
simulator restart, or a longer gap) sets :attr:`SampleScreen.rebase_pending` for the filter to
re-initialise. A real sample in between ends the run, so one bogus frame, or a stream of them
interleaved with the real one, never takes the clock. The first sample is integrated over its
own ``dt_s`` only if that is plausible (``<= max_dt_s``).

Aiding samples (:meth:`SampleScreen.order`): per-sensor time order, and a stamp more than
``max_sensor_lead_s`` ahead of the IMU is dropped (it would otherwise block its stream until
the IMU caught up). Everything rejected is counted in the shared
:class:`~fusion.estimate.HealthCounters`, never raised.
"""

from __future__ import annotations

from typing import Any

from fusion.config import ImuTuning
from fusion.estimate import HealthCounters
from fusion.samples import ImuSample, as_vec3

Vec6 = tuple[float, float, float, float, float, float]
ImuStep = tuple[int, float, Vec6, bool, bool]
"""``(time_us, dt_s, (f_x, f_y, f_z, w_x, w_y, w_z), good, gap)`` of a usable IMU sample."""

MAX_TIME_US = 2**62
"""Largest timestamp taken, us (146,000 years; MAVLink's uint64 ``time_usec`` can say 2^64-1,
which no clock means and whose differences overflow the covariance)."""


class SampleScreen:
    """Time order and validity of the input samples (see the module docstring).

    Parameters
    ----------
    imu : ImuTuning
        Ranges, plausible interval, time-jump threshold, sensor lead.
    counters : HealthCounters
        Where rejections are counted.
    """

    def __init__(self, imu: ImuTuning, counters: HealthCounters) -> None:
        self._c = counters
        self._accel_range = imu.accel_range_mps2
        self._gyro_range = imu.gyro_range_rps
        self._max_dt = imu.max_dt_s
        self._max_dt_us = round(imu.max_dt_s * 1e6)
        self._jump_us = round(imu.time_jump_s * 1e6)
        self._max_coast_us = round(imu.max_coast_s * 1e6)
        self._confirm = imu.time_base_confirm_samples
        self._max_lead_us = round(imu.max_sensor_lead_s * 1e6)
        self.last_imu_us: int | None = None
        """Time of the last IMU sample taken (integrated, held or coasted over)."""
        self._run_n = 0  # consecutive quarantined samples at plausible intervals
        self._run_last_us = 0
        self.rebase_pending = False
        """A confirmed new time base the INS cannot coast into: the filter must
        re-initialise (with a fresh screen)."""
        self._good_fw: Vec6 | None = None
        self._last_us: dict[str, int] = {}

    def imu(self, s: ImuSample) -> ImuStep | None:
        """Screen one IMU sample.

        Parameters
        ----------
        s : ImuSample

        Returns
        -------
        tuple or None
            ``None``: nothing to integrate (dropped, or no good sample yet, or an implausible
            first interval). Else ``(time_us, dt_s, fw, good, gap)``: the interval since the
            previous sample (the first sample's own ``dt_s``), the specific force and rate to
            use (this sample's, or the last good one's when ``good`` is false), and ``gap``:
            a confirmed forward gap (see the module docstring) that must not be integrated.
        """
        c = self._c
        t = s.time_us
        if type(t) is not int:  # the common case needs no conversion
            try:
                t = int(t)
            except (TypeError, ValueError, OverflowError):
                c.imu_nan += 1
                return None
        if not 0 <= t <= MAX_TIME_US:
            c.time_quarantined += 1
            self._run_n = 0
            return None
        last = self.last_imu_us
        gap = False
        if last is not None:
            step = t - last
            if step == 0:
                c.duplicates += 1
                return None
            if step < 0 or step > self._jump_us:
                if not self._confirmed(t, step < 0):
                    return None
                if step < 0 or step > self._max_coast_us:
                    self.rebase_pending = True
                    return None
                gap = True  # a confirmed forward gap: coast over it
            elif self._run_n:
                self._run_n = 0  # a sample on the clock ends a quarantined run
        try:
            try:  # fast path: numpy arrays
                fx, fy, fz = s.specific_force_b_mps2.tolist()
                wx, wy, wz = s.angular_rate_b_rps.tolist()
            except AttributeError:
                fx, fy, fz = as_vec3(s.specific_force_b_mps2)
                wx, wy, wz = as_vec3(s.angular_rate_b_rps)
            dt_s = s.dt_s
            if type(dt_s) is not float:
                dt_s = float(dt_s)
            # x * 0 is 0 for finite x, NaN for NaN/Inf: one test for all seven fields
            finite = (fx + fy + fz + wx + wy + wz + dt_s) * 0.0 == 0.0
        except (TypeError, ValueError, AttributeError):
            finite = False
        good = False
        fw = self._good_fw
        if not finite:
            c.imu_nan += 1
        else:
            ar = self._accel_range
            gr = self._gyro_range
            # |x| <= range as chained comparisons (finite x: the same test as abs, no calls)
            if (
                -ar <= fx <= ar and -ar <= fy <= ar and -ar <= fz <= ar
                and -gr <= wx <= gr and -gr <= wy <= gr and -gr <= wz <= gr
            ):  # fmt: skip
                c.imu_ok += 1
                good = True
                self._good_fw = fw = (fx, fy, fz, wx, wy, wz)
            else:
                c.imu_out_of_range += 1
        if fw is None:  # nothing good to hold yet
            self.last_imu_us = t
            return None
        self.last_imu_us = t
        if last is None:
            if not (good and 0.0 < dt_s <= self._max_dt):
                return None
            return (t, dt_s, fw, good, False)
        dt = (t - last) * 1e-6
        if gap:
            c.time_jump += 1
            return (t, dt, fw, good, True)
        return (t, dt, fw, good, False)

    def _confirmed(self, t: int, backwards: bool) -> bool:
        """Quarantine an IMU stamp off the clock (count it); True once it completes a run of
        ``time_base_confirm_samples`` consecutive such stamps at plausible intervals."""
        c = self._c
        if backwards:
            c.time_backwards += 1
        else:
            c.time_quarantined += 1
        if self._run_n and 0 < t - self._run_last_us <= self._max_dt_us:
            self._run_n += 1
        else:
            self._run_n = 1
        self._run_last_us = t
        if self._run_n < self._confirm:
            return False
        self._run_n = 0
        return True

    def order(self, kind: str, time_us: Any) -> int | None:
        """Per-sensor time order of an aiding sample.

        Parameters
        ----------
        kind : str
            ``"gnss"``, ``"baro"`` or ``"mag"`` (also the prefix of its ``*_invalid`` counter).
        time_us : int-like
            The sample's timestamp.

        Returns
        -------
        int or None
            The time, or ``None`` (counted) when the timestamp is unreadable or out of range
            (``<kind>_invalid``), repeats (``duplicates``), goes backwards
            (``time_backwards``) or lies more than ``max_sensor_lead_s`` ahead of the IMU
            (``time_jump``).
        """
        c = self._c
        try:
            t = int(time_us)
        except (TypeError, ValueError, OverflowError):
            t = -1
        if not 0 <= t <= MAX_TIME_US:
            setattr(c, f"{kind}_invalid", getattr(c, f"{kind}_invalid") + 1)
            return None
        last = self._last_us.get(kind)
        if last is not None and t <= last:
            if t == last:
                c.duplicates += 1
            else:
                c.time_backwards += 1
            return None
        imu = self.last_imu_us
        if imu is not None and t - imu > self._max_lead_us:
            c.time_jump += 1
            return None
        self._last_us[kind] = t
        return t
