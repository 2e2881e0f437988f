"""Thermal strategies of the IMU: what the filter does about biases that move with die
temperature.

``FilterConfig.thermal.mode`` (``--thermal`` on the commands):

========  ======================================================================================
``off``   nothing (the default: the IMU's datasheet process noise only)
``blind`` no temperature model; the bias random walk is widened so that it admits the thermal
          drift the part can show (:func:`fusion.thermal.tuning.blind_imu_tuning` says how)
``states`` six more error states, a linear temperature coefficient per gyro and accelerometer
          axis, ``b = b0 + k (T - T_ref)`` (:mod:`fusion.state_layout`, the ``+therm``
          block); the bias estimate moves with ``k dT`` as the temperature changes
``cal``   a calibration file (PX4 ``TC_G0_*`` / ``TC_A0_*`` cubic, or ArduPilot
          ``INS_TCAL1_*``) applied to the IMU before the filter, as an autopilot applies it
========  ======================================================================================

``--bridge gmdh-thermal`` (:mod:`fusion.thermal.bias_model`) learns the bias against
(temperature, its rate) online and feeds the predicted change forward during an outage.

Every strategy reads the temperature through :class:`fusion.thermal.screen.TemperatureScreen`:
a NaN, stuck, out-of-range or physically impossible temperature is rejected and counted, and
the thermal corrections then fall back to the blind filter (they hold).

Pure: no I/O, no clocks.
"""
