"""The composition root: the ``hilnav`` command line and ``hilnav up``.

The only place that may import every layer (scenarios, hil, fusion, sim) and wire them
together; nothing imports it. Each command validates its input, builds its pieces through the
shared pipeline (:mod:`hil.pipeline`) and scorer (:mod:`scenarios.summary`), and maps failures
to the exit codes in docs/architecture.md.
"""
