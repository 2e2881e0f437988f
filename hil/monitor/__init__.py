"""The live monitor of a vehicle on the bus: dashboard, MCAP recorder, and the process loop.

=============================  ==========================================================
:mod:`hil.monitor.dashboard`   :class:`MonitorState`: what the dashboard shows, rendered
:mod:`hil.monitor.recorder`    :class:`McapRecorder`: bus samples -> MCAP
:mod:`hil.monitor.loop`        :func:`monitor_main`: subscribe, show, record until stopped
=============================  ==========================================================
"""

from __future__ import annotations

from hil.monitor.dashboard import MonitorState
from hil.monitor.loop import monitor_main
from hil.monitor.recorder import McapRecorder

__all__ = ["McapRecorder", "MonitorState", "monitor_main"]
