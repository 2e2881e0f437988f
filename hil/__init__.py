"""I/O shell of hilnav: MAVLink codec and links, service processes, Zenoh bus, monitor, CLI.

``hil.codec`` is the only module that knows MAVLink's wire units (degE7, cm/s, mm, cdeg, hPa,
mG, gauss). No numerics live here: estimation is in ``fusion``, simulation in ``sim``.
"""
