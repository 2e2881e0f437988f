"""Fault events as scenario files write them: the file's keys and units, converted to the
:mod:`sim.faults.events` models on load.

The event models are :mod:`sim.faults`' own (SI fields, validated there); this module only
knows how a file spells them:

* ``at`` and ``duration`` give ``start_s`` and ``duration_s``: a number of seconds or a string
  with a time unit ("90 s", "5 min", "1.5 h"); ``duration`` omitted or null: to the end of the
  flight.
* A few fields are written in human units under a key naming the unit (the table
  ``_IN_FILE_UNITS`` below), e.g. a baro glitch's ``offset_pa`` as ``offset_pa`` or
  ``offset_hpa`` (give one), an IMU bias step's ``value`` as ``value_deg_per_h`` (gyro) or
  ``value_mg`` (accelerometer). The conversions are :func:`scenarios.schema.units.to_si`.
* Every other field is written under its own name, in its own unit.

:data:`Event` is the type of one item of a scenario's ``events``: it converts a file mapping
when the validation context says ``{FILE_UNITS: True}`` (what :func:`load_scenario` passes);
otherwise it takes the SI fields (``Scenario.model_validate`` of a ``model_dump``). Its JSON
Schema is the file form. Errors found here point at the file's key; errors the event model
finds are pointed back at the file's key by :func:`file_loc`.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, get_args

from pydantic import (
    BeforeValidator,
    Field,
    GetJsonSchemaHandler,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
)
from pydantic.json_schema import JsonSchemaValue
from pydantic_core import CoreSchema

from scenarios.schema.base import key_error, unknown_name
from scenarios.schema.units import TIME_PATTERN, parse_quantity, si_unit, to_si
from sim.faults.events import (
    EVENT_TYPES,
    BaroDrift,
    BaroGlitch,
    FaultEvent,
    ImuBiasStep,
    ImuSaturation,
    ImuSensor,
    MagAnomaly,
    WeatherFront,
    field_unit,
)

__all__ = ["FILE_UNITS", "Event", "FileKey", "file_keys", "file_loc", "from_file"]

FILE_UNITS = "file_units"
"""Validation-context key: true when the events are written as in a file."""

_IMU_SENSORS: tuple[str, ...] = get_args(ImuSensor)

# Fields a file gives in other units: event class -> field -> (file key, its unit), in the
# order the keys are listed. Keys of one field are alternatives (give one; null = not given);
# for the IMU fields each unit belongs to one sensor (the one whose SI unit it converts to).
_IN_FILE_UNITS: dict[type[FaultEvent], dict[str, tuple[tuple[str, str], ...]]] = {
    BaroDrift: {"rate_pa_per_s": (("rate_pa_per_s", "Pa/s"), ("rate_hpa_per_h", "hPa/h"))},
    BaroGlitch: {"offset_pa": (("offset_pa", "Pa"), ("offset_hpa", "hPa"))},
    WeatherFront: {
        "rate_pa_per_s": (("rate_hpa_per_10min", "hPa/10min"), ("rate_hpa_per_h", "hPa/h"))
    },
    ImuBiasStep: {"value": (("value_deg_per_h", "deg/h"), ("value_mg", "mg"))},
    ImuSaturation: {"limit": (("limit_dps", "deg/s"), ("limit_g", "g"))},
    MagAnomaly: {"offset_ned_t": (("offset_ned_ut", "uT"),)},
}
# What a sensor-dependent event is called in "a gyro step takes ...".
_NOUN: dict[type[FaultEvent], str] = {ImuBiasStep: "step", ImuSaturation: "saturation"}

_WINDOW_DOC = {
    "start_s": "Start: seconds after the flight begins, or '5 min'.",
    "duration_s": "Length (s or '90 s', '2 min'); omitted: until the end of the flight.",
}


@dataclass(frozen=True, slots=True)
class FileKey:
    """One key of an event in a scenario file.

    Attributes
    ----------
    name : the key.
    field : the event model's field it gives.
    unit : the unit the file writes it in (None: a field that is not a quantity).
    quantity : a number or a string with a unit (``at``, ``duration``).
    converted : the file's unit is not the field's (the value goes through ``to_si``).
    alternative : one of several keys of ``field``; null means not given.
    sensor : the IMU sensor this key belongs to (None: any).
    """

    name: str
    field: str
    unit: str | None
    quantity: bool = False
    converted: bool = False
    alternative: bool = False
    sensor: str | None = None


@functools.cache
def file_keys(cls: type[FaultEvent]) -> dict[str, FileKey]:
    """The keys a file may give for event class ``cls``, in schema order (``type`` first).

    Raises
    ------
    ValueError
        The file-unit table and the event's declared units disagree (a programming error,
        found on import).
    """
    keys: dict[str, FileKey] = {"type": FileKey("type", "type", None)}
    keys["at"] = FileKey("at", "start_s", field_unit(cls, "start_s"), quantity=True)
    keys["duration"] = FileKey(
        "duration", "duration_s", field_unit(cls, "duration_s"), quantity=True, alternative=True
    )
    table = _IN_FILE_UNITS.get(cls, {})
    for field in cls.model_fields:
        if field in ("type", "start_s", "duration_s"):
            continue
        if field not in table:
            keys[field] = FileKey(field, field, field_unit(cls, field))
            continue
        alternatives = table[field]
        for name, unit in alternatives:
            sensors = [s for s in _IMU_SENSORS if field_unit(cls, field, s) == si_unit(unit)]
            if field_unit(cls, field) is None and len(sensors) != 1:
                raise ValueError(f"{cls.__name__}.{field}: {unit} is no one sensor's unit")
            if field_unit(cls, field) not in (None, si_unit(unit)):
                raise ValueError(f"{cls.__name__}.{field} is not in {si_unit(unit)} ({unit})")
            if any(getattr(m, bound, 0) != 0 for m in cls.model_fields[field].metadata
                   for bound in ("gt", "ge", "lt", "le")):
                raise ValueError(f"{cls.__name__}.{field}: a bound other than 0 would need "
                                 f"converting to {unit}")
            keys[name] = FileKey(
                name, field, unit, converted=unit != si_unit(unit),
                alternative=len(alternatives) > 1,
                sensor=sensors[0] if field_unit(cls, field) is None else None,
            )
    return keys


def _keys_of(keys: dict[str, FileKey], field: str) -> list[FileKey]:
    return [k for k in keys.values() if k.field == field]


def _chosen(raw: Mapping[str, Any], keys: dict[str, FileKey], field: str) -> FileKey:
    """The key that gives ``field`` in ``raw`` (the sensor's, the one given, or the first)."""
    options = _keys_of(keys, field)
    sensor = raw.get("sensor")
    for k in options:
        if k.sensor is not None and k.sensor == sensor:
            return k
    for k in options:
        if k.sensor is None and raw.get(k.name) is not None:
            return k
    return options[0]


@functools.cache
def _adapter(cls: type[FaultEvent], field: str) -> TypeAdapter[Any]:
    # The field's own type and bounds; its bounds are 0 or none (see file_keys), which hold in
    # any unit the file uses as well as in SI.
    info = cls.model_fields[field]
    annotation: Any = Annotated[info.annotation, *info.metadata] if info.metadata else (
        info.annotation)
    return TypeAdapter(annotation)


def _convert(cls: type[FaultEvent], key: FileKey, value: Any) -> Any:
    """The SI value of a converted key, or ``value`` itself when it is not a valid number
    (then the event model reports it, at this key)."""
    try:
        number = _adapter(cls, key.field).validate_python(value)
    except ValidationError:
        return value
    assert key.unit is not None
    if isinstance(number, tuple):
        return tuple(to_si(x, key.unit) for x in number)
    return to_si(number, key.unit)


def from_file(raw: Any) -> Any:
    """One event as a file writes it -> the SI fields of its ``sim.faults`` model.

    Parameters
    ----------
    raw : the event's mapping from the file. Anything else, or a mapping without a known
        ``type``, is returned unchanged for the model to report.

    Returns
    -------
    dict
        ``type`` and the SI fields the file gives (the model's defaults fill the rest).

    Raises
    ------
    pydantic_core.PydanticCustomError
        An unreadable ``at`` / ``duration``, an unknown key, two alternative keys given, or
        an IMU key of the other sensor; its context ``loc`` is ``(type, key)``.
    """
    if not isinstance(raw, Mapping) or not isinstance(raw.get("type"), str):
        return raw
    cls = EVENT_TYPES.get(raw["type"])
    if cls is None:
        return raw
    tag = cls.type_name
    keys = file_keys(cls)
    out: dict[str, Any] = {"type": tag}
    for key in keys.values():
        if key.quantity and key.name in raw and not (key.alternative and raw[key.name] is None):
            try:
                out[key.field] = parse_quantity(raw[key.name], key.unit)
            except ValueError as error:
                raise key_error(str(error), (tag, key.name)) from None
    for name in raw:
        if name not in keys:
            raise key_error(unknown_name("key", name, list(keys)), (tag, name))
    for field in dict.fromkeys(k.field for k in keys.values()):
        if field in out or field == "type":
            continue
        options = _keys_of(keys, field)
        given = [k for k in options if k.name in raw and not (k.alternative
                                                             and raw[k.name] is None)]
        if any(k.sensor is not None for k in options):
            sensor = raw.get("sensor")
            if sensor not in _IMU_SENSORS:
                continue  # the model reports the sensor
            want = _chosen(raw, keys, field)
            for k in given:
                if k is not want:
                    raise key_error(
                        f"a {sensor} {_NOUN[cls]} takes {want.name}, not {k.name}", (tag, k.name)
                    )
            if not given:
                raise key_error(f"a {sensor} {_NOUN[cls]} needs {want.name}", (tag,))
        elif len(given) > 1:
            raise key_error(
                f"give one of {options[0].name} and {options[1].name}, not both",
                (tag, options[1].name),
            )
        if given:
            key = given[0]
            value = raw[key.name]
            out[field] = _convert(cls, key, value) if key.converted else value
    return out


def file_loc(
    raw: Any, loc: tuple[str | int, ...]
) -> tuple[tuple[str | int, ...], Any, FileKey | None]:
    """Where in a file's event an error of its model is: ``(tag, field, ...)`` -> ``(tag,
    key, ...)``.

    Parameters
    ----------
    raw : the event as the file writes it.
    loc : the error's location inside the event, as pydantic gives it (tag first).

    Returns
    -------
    (loc, value, key)
        The location with the field replaced by the file's key, the file's value there (None
        when the file has none) and the key (None when ``loc`` names no field).
    """
    if not isinstance(raw, Mapping) or len(loc) < 2 or not isinstance(loc[1], str):
        return loc, None, None
    cls = EVENT_TYPES.get(str(loc[0]))
    if cls is None or loc[1] not in cls.model_fields:
        return loc, None, None
    key = _chosen(raw, file_keys(cls), loc[1])
    value: Any = raw.get(key.name)
    for part in loc[2:]:
        if isinstance(value, list | tuple) and isinstance(part, int) and 0 <= part < len(value):
            value = value[part]
        else:
            value = None
    return (loc[0], key.name, *loc[2:]), value, key


def _from_file_context(value: Any, info: ValidationInfo) -> Any:
    context = info.context if isinstance(info.context, Mapping) else {}
    return from_file(value) if context.get(FILE_UNITS) else value


# --------------------------------------------------------------------------- JSON Schema


def _number_part(prop: Mapping[str, Any]) -> dict[str, Any]:
    """The number branch of a field's JSON Schema (type and bounds)."""
    for branch in prop.get("anyOf", [prop]):
        if branch.get("type") in ("number", "array"):
            return {k: v for k, v in branch.items() if k not in ("default", "description",
                                                                  "title", "unit")}
    return {"type": "number"}


def _file_schema(cls: type[FaultEvent], si: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON Schema of ``cls`` as files write it, from its SI schema ``si``."""
    props = si["properties"]
    out: dict[str, Any] = {}
    required = ["type"]
    for key in file_keys(cls).values():
        prop = props[key.field]
        if key.name == "type":
            out["type"] = {"const": cls.type_name, "title": "Type", "type": "string"}
        elif key.quantity:
            branches = [_number_part(prop), {"type": "string", "pattern": TIME_PATTERN}]
            if key.alternative:
                branches.append({"type": "null"})
            out[key.name] = {"anyOf": branches, "description": _WINDOW_DOC[key.field],
                             "title": key.name.title(), "unit": key.unit}
            if key.alternative:
                out[key.name]["default"] = None
        elif key.converted or key.alternative:
            part = _number_part(prop)  # its bounds are 0 (file_keys): the same in any unit
            text = prop.get("description", "").rstrip(".")
            if key.sensor is not None:
                text = f"{text} ({key.sensor})"
            out[key.name] = {"anyOf": [part, {"type": "null"}], "default": None} if (
                key.alternative) else part
            out[key.name].update(description=f"{text}, {key.unit}.",
                                 title=key.name.replace("_", " ").title(), unit=key.unit)
        else:
            out[key.name] = dict(prop)
            if key.field in si.get("required", []):
                required.append(key.name)
    if "start_s" in si.get("required", []):
        required.insert(1, "at")
    schema: dict[str, Any] = {
        "additionalProperties": False,
        "properties": out,
        "required": required,
        "title": si.get("title", cls.__name__),
        "type": "object",
    }
    if "description" in si:
        schema["description"] = si["description"]
    return schema


class _FileSchema:
    """Turns the events' JSON Schema (pydantic's, of the SI models) into the file form."""

    def __get_pydantic_json_schema__(
        self, core_schema: CoreSchema, handler: GetJsonSchemaHandler
    ) -> JsonSchemaValue:
        schema = handler(core_schema)
        mapping = schema.get("discriminator", {}).get("mapping", {})
        for tag, ref in mapping.items():
            target = handler.resolve_ref_schema({"$ref": ref})
            file_form = _file_schema(EVENT_TYPES[tag], target)
            target.clear()
            target.update(file_form)
        return schema


Event = Annotated[
    FaultEvent,
    Field(discriminator="type"),
    BeforeValidator(_from_file_context),
    _FileSchema(),
]
"""One item of a scenario's ``events``: a :mod:`sim.faults` event (see the module docstring)."""

# Check the file-unit table against the events' declared units now, not at the first file.
for _cls in EVENT_TYPES.values():
    file_keys(_cls)
