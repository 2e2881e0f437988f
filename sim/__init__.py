"""Flight and sensor simulation: JSBSim truth and synthetic IMU / GNSS / baro / mag samples.

Everything leaving this package is SI (metres, seconds, radians, pascals, kelvin, tesla);
JSBSim's feet, slugs and psf stop at ``sim.flight``. Frames and quaternion conventions are
those written in ``fusion/__init__.py``. ``sim`` never imports ``fusion`` and does no I/O
beyond reading its own packaged plan files.
"""
