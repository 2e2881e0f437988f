"""The flag spellings of ``hilnav sim``'s modes, still understood: ``sim --record FILE``,
``sim --live URL``, ``sim --px4 URL`` and ``sim --ardupilot URL`` are rewritten to the
subcommands (``sim record FILE``, ``sim live URL``, ...) before the command line is parsed,
with one deprecation line naming the new spelling.

Only the standard library here: :func:`rewrite` runs before every ``hilnav`` command.
"""

from __future__ import annotations

__all__ = ["MODE_FLAGS", "NO_MODE", "rewrite"]

MODE_FLAGS = {"--px4": "px4", "--ardupilot": "ardupilot", "--live": "live", "--record": "record"}
"""Each flag of the old spelling and the subcommand it became, the first found wins."""

NO_MODE = ("hilnav sim needs a mode: record FILE, live URL, px4 URL or ardupilot URL "
           "(see hilnav sim --help)")

#: Options of one mode: given with the flag spelling of another mode (or none), the old
#: message says which flag they need.
_OWNED = {
    "--lockstep": ("live", "--lockstep paces against a fusion service: it needs --live URL"),
    "--actuator-map": ("px4", "--actuator-map maps PX4's controls: it needs --px4 URL"),
    "--servo-map": ("ardupilot", "--servo-map and --ardupilot-mavlink need --ardupilot URL"),
    "--ardupilot-mavlink": (
        "ardupilot", "--servo-map and --ardupilot-mavlink need --ardupilot URL"),
}

_ZENOH_SECURITY = {"--zenoh-user", "--zenoh-password-file", "--tls-ca", "--tls-cert", "--tls-key",
                   "--zenoh-key-file"}
#: The options each subcommand takes besides the flight and sensor options. With the flag
#: spelling every one of them was accepted in every mode, and ignored where it did not apply:
#: those are dropped, so a command line that worked still does.
_MODE_OPTIONS = {
    "record": set(),
    "live": {"--speed", "--zenoh", "--vehicle", "--wait-peer", "--lockstep", "--no-lockstep",
             "--lockstep-window", "--signing-key-file", *_ZENOH_SECURITY},
    "px4": {"--actuator-map", "--speed", "--stall-timeout", "--connect-timeout"},
    "ardupilot": {"--servo-map", "--ardupilot-mavlink", "--stall-timeout", "--connect-timeout"},
}
_FLAGS = {"--lockstep", "--no-lockstep"}  # the ones without a value


def _without_ignored(args: list[str], mode: str) -> list[str]:
    """``args`` without the options of other modes that the flag spelling ignored."""
    other = set().union(*_MODE_OPTIONS.values()) - _MODE_OPTIONS[mode]
    kept: list[str] = []
    i = 0
    while i < len(args):
        name, eq, _ = args[i].partition("=")
        if name in other:
            i += 1 if eq or name in _FLAGS else 2
            continue
        kept.append(args[i])
        i += 1
    return kept


def rewrite(args: list[str]) -> tuple[list[str], str | None]:
    """``args`` (without the program name) in the subcommand spelling, and the deprecation
    line to print (None: ``args`` were not in the flag spelling).

    Raises
    ------
    ValueError
        Conflicting mode flags, a mode flag without its value, options of another mode, or
        ``sim`` with options but no mode.
    """
    if len(args) < 2 or args[0] != "sim" or not args[1].startswith("-") \
            or args[1] in ("--help", "-h"):
        return args, None
    values: dict[str, str] = {}
    rest: list[str] = []
    i = 1
    while i < len(args):
        name, eq, value = args[i].partition("=")
        if name not in MODE_FLAGS:
            rest.append(args[i])
            i += 1
            continue
        if not eq:
            if i + 1 >= len(args):
                raise ValueError(f"{name} needs a value")
            value = args[i + 1]
        values[name] = value
        i += 1 if eq else 2
    if "--px4" in values and "--ardupilot" in values:
        raise ValueError("--px4 and --ardupilot are two autopilots: give one")
    for autopilot in ("--px4", "--ardupilot"):
        if autopilot in values and "--live" in values:
            raise ValueError(f"{autopilot} and --live are two ways to fly: give one")
    flag = next((f for f in MODE_FLAGS if f in values), None)
    if flag is None:
        raise ValueError(NO_MODE)
    mode = MODE_FLAGS[flag]
    for option, (owner, message) in _OWNED.items():
        if owner != mode and any(a.partition("=")[0] == option for a in rest):
            raise ValueError(message)
    target = values.pop(flag)
    record = ["--record", values.pop("--record")] if "--record" in values else []
    metavar = "FILE" if mode == "record" else "URL"
    note = (f"warning: `hilnav sim {flag} {metavar}` is deprecated; use "
            f"`hilnav sim {mode} {metavar}`")
    return ["sim", mode, target, *record, *_without_ignored(rest, mode)], note
