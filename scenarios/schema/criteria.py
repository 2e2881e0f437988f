"""Pass criteria: the summary.json metrics a scenario may bound, their units, and the
criterion model."""

from __future__ import annotations

import re
from typing import Literal, Self

from pydantic import Field, field_validator, model_validator

from scenarios.event_metrics import EVENT_SENSORS
from scenarios.metrics import ERROR_AT_S
from scenarios.schema.base import Strict, key_error, unknown_name
from scenarios.schema.units import parse_quantity
from scenarios.summary import Criterion

__all__ = ["KNOWN_METRICS", "CriterionSpec", "metric_unit"]

# Unit suffix of a summary.json field name -> the unit a limit is converted to.
_UNIT_OF_TOKEN: dict[str, str] = {"m": "m", "s": "s", "deg": "deg", "mps": "m/s"}


def _metric_names() -> tuple[str, ...]:
    at = [str(s) for s in ERROR_AT_S]
    outage = [
        "start_s", "end_s", "duration_s", "horizontal_rmse_m", "horizontal_max_m",
        "vertical_rmse_m", "vertical_max_m", "cep50_m", "cep95_m", "nees_mean", "reconverge_s",
    ]
    names = [f"outages.{n}" for n in outage]
    names += [f"outages.horizontal_error_m_at.{s}" for s in at]
    names += [f"outages.vertical_error_m_at.{s}" for s in at]
    names += [f"outages.rmse.{n}" for n in
              ("lat_deg", "lon_deg", "h_m", "vn_mps", "ve_mps", "vd_mps", "horizontal_m")]
    names += [f"outages.containment_3sigma.{n}" for n in ("horizontal", "vertical")]
    names += [f"events.{n}" for n in (
        "start_s", "end_s", "detect_s", "max_horizontal_m", "max_vertical_m", "reaccept_count",
        "bad_fixes_fused", "reconverge_s")]
    names += [f"detect_s_by_sensor.{n}" for n in EVENT_SENSORS]
    names += [f"gnss_on.{n}" for n in (
        "horizontal_rmse_m", "vertical_rmse_m", "roll_rmse_deg", "pitch_rmse_deg",
        "yaw_rmse_deg")]
    names += [f"nees.{n}" for n in (
        "nees_mean", "rms_z_pos", "rms_z_vel", "rms_z_att", "within_3sigma_pos",
        "within_3sigma_vel", "within_3sigma_att")]
    names += [f"containment_3sigma.{n}" for n in ("horizontal", "vertical")]
    names += [f"rejections_outside_events.{n}" for n in (
        "gnss_rejected", "baro_rejected", "mag_rejected")]
    names += ["sim_duration_s", "realtime_factor"]
    return tuple(names)


KNOWN_METRICS: tuple[str, ...] = _metric_names()
"""Dotted summary.json paths a criterion may name (``health.*`` is also accepted). Through a
list (``outages``, ``events``) the worst value counts (largest for ``max``, smallest for
``min``)."""


def metric_unit(path: str) -> str | None:
    """Unit of a summary.json value from its field name (``_m`` m, ``_s`` s, ``_deg`` deg,
    ``_mps`` m/s; the innermost named part wins), or None for a dimensionless value."""
    for part in reversed(path.split(".")):
        for token in reversed(part.split("_")):
            if token in _UNIT_OF_TOKEN:
                return _UNIT_OF_TOKEN[token]
    return None


class CriterionSpec(Strict):
    """A pass criterion: the summary.json value at ``metric`` must be <= ``max`` (or >= ``min``).

    Through a list (all outages, all events) the worst value counts. Items without the value
    are skipped unless ``fail_if_missing`` (e.g. an event never detected has no ``detect_s``).
    """

    name: str | None = Field(default=None, description="Label; default 'METRIC <= MAX'.")
    metric: str = Field(
        description="Dotted path into summary.json (worst case over all outages / events).",
        json_schema_extra={"anyOf": [{"enum": list(KNOWN_METRICS)},
                                     {"pattern": r"^health(\.[A-Za-z0-9_]+)+$"}]},
    )
    max: float | str | None = Field(
        default=None,
        description="Upper limit: a number in the metric's unit or a string with a unit, "
        "e.g. '25 m', '1.5 km', '0.5 deg', '2 m/s', '30 s'.",
    )
    min: float | str | None = Field(
        default=None, description="Lower limit (instead of max), e.g. 0.9 for a containment."
    )
    fail_if_missing: bool = Field(
        default=False, description="An item (outage, event) without the value fails."
    )

    @field_validator("metric")
    @classmethod
    def _known_metric(cls, value: str) -> str:
        if value in KNOWN_METRICS or re.fullmatch(r"health(\.[A-Za-z0-9_]+)+", value):
            return value
        raise ValueError(unknown_name("metric", value, KNOWN_METRICS) + ", health.*")

    @model_validator(mode="after")
    def _one_limit(self) -> Self:
        if (self.max is None) == (self.min is None):
            raise key_error("give exactly one of max and min")
        key = "max" if self.max is not None else "min"
        try:
            self.limit()
        except ValueError as error:
            raise key_error(str(error), (key,)) from None
        return self

    @property
    def op(self) -> Literal["<=", ">="]:
        """``"<="`` for ``max``, ``">="`` for ``min``."""
        return "<=" if self.max is not None else ">="

    def limit(self) -> float:
        """The limit in the unit of the summary field (m, s, deg, m/s or dimensionless)."""
        raw = self.max if self.max is not None else self.min
        return parse_quantity(raw, metric_unit(self.metric))

    def criterion(self) -> Criterion:
        """The :class:`~scenarios.summary.Criterion` this spec describes."""
        raw = self.max if self.max is not None else self.min
        name = self.name or f"{self.metric} {self.op} {raw}"
        return Criterion(name=name, path=self.metric, limit=self.limit(), op=self.op,
                         none_fails=self.fail_if_missing)
