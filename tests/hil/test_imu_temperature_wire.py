"""The IMU's temperature on the wire: HIL_SENSOR ``temperature`` with the IMU fields when a
thermal IMU model runs, the barometer's in its own frame, the decoder giving each sample its
own sensor's temperature; a recorded log keeps it."""

from __future__ import annotations

import numpy as np
import pytest

from hil.codec import Decoder, Encoder
from hil.codec.wire import KELVIN_AT_0_CELSIUS, HilSensorField
from hil.streamer import SensorStreamer
from hil.tlog import TlogWriter, iter_decoded
from sim import presets
from sim.imu_thermal import ImuThermalConfig
from sim.samples import BaroSample, ImuSample
from sim.sensors import SensorSuite
from tests.hil.codec_helpers import one, parse_raw
from tests.sim.test_sensors import stationary_truth


def _imu(t_us: int, temperature_k: float) -> ImuSample:
    return ImuSample(t_us, 0.005, np.array([0.0, 0.0, -9.8]), np.zeros(3), temperature_k)


def test_imu_temperature_round_trips_exactly_at_the_parts_resolution() -> None:
    enc = Encoder()
    for n in (-504, -1, 0, 3, 496):  # BMI088: n·0.125 + 23 °C
        t_k = 23.0 + 0.125 * n + KELVIN_AT_0_CELSIUS
        frame = enc.sensors(_imu(5000, t_k), imu_temperature=True)
        msg = parse_raw(frame)
        assert msg.fields_updated & HilSensorField.TEMPERATURE
        assert msg.temperature == 23.0 + 0.125 * n  # exact in float32
        (imu,) = one(Decoder(imu_dt_s=0.005), frame)
        assert imu.temperature_k == pytest.approx(t_k, abs=1e-9)


def test_imu_temperature_is_off_by_default_and_never_shares_a_frame_with_the_baro() -> None:
    enc = Encoder()
    msg = parse_raw(enc.sensors(_imu(5000, 250.0)))
    assert not msg.fields_updated & HilSensorField.TEMPERATURE and msg.temperature == 0.0
    with pytest.raises(ValueError, match="one temperature field"):
        enc.sensors(_imu(5000, 250.0), BaroSample(5000, 9e4, 280.0), imu_temperature=True)
    with pytest.raises(ValueError, match=r"imu\.temperature_k"):
        enc.sensors(_imu(5000, float("nan")), imu_temperature=True)


def test_streamed_thermal_imu_decodes_with_its_own_temperature_and_the_baro_with_its(
        tmp_path) -> None:
    part = presets.imu_thermal_preset("bmi088")
    assert part is not None
    thermal = ImuThermalConfig(part=part, preset="bmi088", start_temperature_c=-10.0)
    cfg = presets.suite_config("consumer-mems").model_copy(update={"imu_thermal": thermal})
    suite = SensorSuite(cfg, seed=1, sim_rate_hz=200.0)
    streamer = SensorStreamer(imu_temperature=True)
    log = tmp_path / "thermal.tlog"
    sent_imu: list[float] = []
    sent_baro: list[float] = []
    with TlogWriter(log) as writer:
        for k in range(200 * 4):
            truth = stationary_truth(k)
            samples = suite.step(truth)
            sent_imu += [s.temperature_k for s in samples if isinstance(s, ImuSample)]
            sent_baro += [s.temperature_k for s in samples if isinstance(s, BaroSample)]
            for t_us, frame in streamer.frames(truth, samples):
                writer.write(frame, t_us)
    got_imu: list[float] = []
    got_baro: list[float] = []
    for _, d in iter_decoded(log):
        if isinstance(d.sample, ImuSample):
            got_imu.append(d.sample.temperature_k)
        elif isinstance(d.sample, BaroSample):
            got_baro.append(d.sample.temperature_k)
    assert len(got_imu) == len(sent_imu) and len(got_baro) == len(sent_baro)
    np.testing.assert_allclose(got_imu, sent_imu, atol=1e-9)
    np.testing.assert_allclose(got_baro, sent_baro, atol=1e-4)  # float32 degC of the baro
    # the part's quantisation and update period survive the trip: 0.125 K steps, 1.28 s holds
    n = (np.array(got_imu) - KELVIN_AT_0_CELSIUS - 23.0) / 0.125
    np.testing.assert_allclose(n, np.round(n), atol=1e-9)
    assert len(set(got_imu)) <= 1 + 4 // 1.28 + 1
    assert abs(np.mean(got_imu) - np.mean(got_baro)) > 5.0  # a cold-soaked IMU, warm baro
