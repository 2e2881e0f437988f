"""hilnav's pure numerical navigation core.

Conventions (they hold everywhere in hilnav; other packages refer here)
-----------------------------------------------------------------------
Frames
    ``e``  Earth-centred Earth-fixed (ECEF), WGS-84.
    ``n``  local navigation frame North-East-Down (NED) at the vehicle.
    ``b``  body frame Forward-Right-Down (FRD).
    ``i``  inertial frame (for rates: ``omega_ie`` is the Earth rate, ``omega_ib`` what a gyro
    measures).
Naming
    ``vec_a`` is a vector expressed in frame ``a`` (``v_n``, ``f_b``); ``mat_ab`` maps vectors
    from ``b`` to ``a`` (``C_nb @ f_b`` is ``f_n``). ``omega_ab_c`` is the rate of ``b`` w.r.t.
    ``a`` expressed in ``c``.
Attitude
    Hamilton quaternion, scalar first ``[w, x, y, z]``; ``q_nb`` rotates body to NED (the same
    convention as MAVLink's ATTITUDE_QUATERNION and HIL_STATE_QUATERNION). Euler angles are
    3-2-1 (yaw, pitch, roll), radians.
Units
    SI and radians everywhere inside. Human units (deg/h, mg, ug/sqrt(Hz), hPa, degE7) live
    only in YAML configuration and in ``hil.codec``; they are converted once, at load.
    Boundary field names carry units: ``lat_rad``, ``alt_msl_m``, ``v_ned_mps``, ``time_us``.
Position
    Geodetic latitude / longitude (rad) on WGS-84 and height above mean sea level (m). hilnav
    treats MSL height as the navigation height; the geoid undulation only matters to the
    barometric calibration (paper P4) and is handled there explicitly.
Randomness
    Never drawn here: ``fusion`` is deterministic. Simulators take a ``numpy.random.Generator``.

``fusion`` imports nothing of hilnav but itself (and the neutral ``physconst``) and performs
no I/O, no clock reads.

Layout
------
Foundations: :mod:`~fusion.earth`, :mod:`~fusion.rotations`, :mod:`~fusion.strapdown`
(mechanisation), :mod:`~fusion.error_model` (state layouts, F, Phi, Q), :mod:`~fusion.kalman`
(gated Joseph update), :mod:`~fusion.trajectory` (ideal IMU from a trajectory). The filter
engine: :mod:`~fusion.filter` (``NavFilter``, the orchestrator) sequencing
:mod:`~fusion.screening` (input samples), :mod:`~fusion.propagation` (covariance time update),
:mod:`~fusion.feedback` (feedback and resets), :mod:`~fusion.history` (delayed measurements),
:mod:`~fusion.alignment`, one module per aiding source under :mod:`fusion.aiding` (gnss,
baro, mag, pseudo_gnss, airspeed with its pitot monitor),
:mod:`~fusion.altitude_link` and :mod:`~fusion.outage`; its outputs are in
:mod:`~fusion.estimate` and its configuration in :mod:`~fusion.config`. Methods: the altitude
channel (:mod:`fusion.altitude`), GNSS-outage bridging (:mod:`fusion.bridging`) and its
regressors (:mod:`~fusion.gmdh`, :mod:`~fusion.regressors`, :mod:`~fusion.regressor_base`,
:mod:`~fusion.laguerre` for the MPC).
"""

__all__ = ["FilterConfig", "NavEstimate", "NavFilter"]


def __getattr__(name: str) -> object:
    # Lazy exports: ``import fusion.earth`` must not pull in pydantic and the whole filter.
    if name == "FilterConfig":
        from fusion.config import FilterConfig

        return FilterConfig
    if name == "NavEstimate":
        from fusion.estimate import NavEstimate

        return NavEstimate
    if name == "NavFilter":
        from fusion.filter import NavFilter

        return NavFilter
    raise AttributeError(f"module 'fusion' has no attribute {name!r}")
