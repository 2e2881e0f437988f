"""A digest of one navigation-filter pass, for bit-identity checks in tests and benches.

:func:`filter_digest` hashes every estimate of one :class:`NavFilter` pass over a sample stream
(array fields by their bytes, every other field by its ``repr``: exact for floats), the
innovations of every step and the final covariance. Two runs agree on it only if their
estimates are bit for bit the same. :func:`tuned_config` is the commands' tuning for an IMU
preset with the few overrides the speed bench and the kernel tests vary.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Iterable
from typing import Any

import numpy as np

from fusion.config import FilterConfig
from fusion.filter import NavFilter
from hil.tuning import filter_config_for_imu, filter_config_for_presets


def tuned_config(
    imu: str,
    *,
    cov_rate_hz: float | None,
    layout: str | None = None,
    gnss_bias: bool = False,
) -> FilterConfig:
    """The commands' filter configuration for ``imu`` (``modern`` GNSS with ``gnss_bias``).

    Parameters
    ----------
    imu : str
        IMU preset name.
    cov_rate_hz : float or None
        Covariance propagation rate (Hz); None propagates at every IMU sample.
    layout : str or None
        Error-state layout overriding the tuning's choice.
    gnss_bias : bool
        Carry the GNSS position-bias states (the tuning for the ``modern`` receiver).
    """
    cfg = filter_config_for_presets(imu, "modern") if gnss_bias else filter_config_for_imu(imu)
    update: dict[str, Any] = {
        "rates": cfg.rates.model_copy(update={"covariance_rate_hz": cov_rate_hz})}
    if layout is not None:
        update["state_layout"] = layout
    return cfg.model_copy(update=update)


def filter_digest(config: FilterConfig, samples: Iterable[Any]) -> str:
    """SHA-256 of one pass of a fresh :class:`NavFilter` over ``samples``.

    Parameters
    ----------
    config : FilterConfig
        The filter's configuration.
    samples : iterable
        Sensor samples in emission order.

    Returns
    -------
    str
        Hex digest over every estimate, every step's innovations and the final covariance.
    """
    nav = NavFilter(config)
    h = hashlib.sha256()

    def feed(value: Any) -> None:
        if isinstance(value, np.ndarray):
            h.update(value.tobytes())
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            for f in dataclasses.fields(value):
                feed(getattr(value, f.name))
        elif isinstance(value, tuple | list):
            for v in value:
                feed(v)
        else:
            h.update(repr(value).encode())
        h.update(b"|")

    for s in samples:
        feed(nav.step(s))
        feed(nav.innovations)
    feed(nav.covariance)
    return h.hexdigest()
