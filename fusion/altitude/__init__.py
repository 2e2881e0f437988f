"""The vertical channel: paper P4's barometric-inertial altitude (damping loop, vertical error
model, MPC and Kalman compensators) and the barometric altimeter it runs on.

Pure, deterministic, steppable objects (no I/O, no clock, no randomness). Heights are geometric
heights above mean sea level in metres, **up positive**; vertical speed ``vz`` is up positive
(``vz = −v_D``).

Vertical acceleration input ``az``
    ``az_up = f_up − g(φ, 0)``: the specific force along the local vertical (up positive; in NED
    ``f_up = −f_D``), minus the *sea-level* normal gravity at the latitude. Gravity falls with
    height by ``2ωs²·h`` (free-air gradient, ``ωs² = g/R``, the squared Schuler frequency), so
    the true vertical acceleration is ``az_up + 2ωs²·h``; the loop adds that term itself, as in
    P4 eq. 5. This term is what makes the free inertial vertical channel unstable (error growth
    ``cosh(√2·ωs·t)``, time constant 570 s). A caller that already used height-dependent
    gravity must pass ``omega_s2=0`` to :class:`~fusion.altitude.loop.ThirdOrderLoop`.

One job per module:

- :mod:`~fusion.altitude.atmosphere` — standard atmosphere, QNH, P4's non-standard atmosphere;
- :mod:`~fusion.altitude.calibration` — online calibration of P4's ``(s, b)`` from GNSS height;
- :mod:`~fusion.altitude.altimeter` — height from pressure (standard, QNH or calibrated);
- :mod:`~fusion.altitude.baro_monitor` — baro range, frozen-sensor and jump checks;
- :mod:`~fusion.altitude.loop` — the third-order damping loop (P4 eq. 5);
- :mod:`~fusion.altitude.vertical_model` — P4's vertical error model (eq. 6-9);
- :mod:`~fusion.altitude.mpc` — the Laguerre-MPC compensator on that model;
- :mod:`~fusion.altitude.vertical_kf` — P4's Kalman comparator on that model;
- :mod:`~fusion.altitude.channel` — the channel that steps all of them together;
- :mod:`~fusion.altitude.common` — constants, checks and the config base they share.
"""
