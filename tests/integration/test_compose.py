"""docker-compose.yml and Dockerfile, checked offline (no Docker engine here or in CI).

The compose file is validated against the Compose Specification's JSON Schema as vendored by
``check-jsonschema``; every hilnav service must call a real ``hilnav`` subcommand with options
that subcommand accepts (parsed by the CLI itself, nothing is run); health checks must parse;
endpoints must agree between services.
"""

from __future__ import annotations

import importlib.metadata
import json
import re
import shlex
from importlib import resources
from pathlib import Path
from typing import Any

import jsonschema
import pytest
import typer
import yaml

from scenarios.cli.app import app

ROOT = Path(__file__).resolve().parents[2]
COMPOSE = ROOT / "docker-compose.yml"
DOCKERFILE = ROOT / "Dockerfile"
ROUTER = "zenohd"


def compose() -> dict[str, Any]:
    doc = yaml.safe_load(COMPOSE.read_text())
    assert isinstance(doc, dict)
    return doc


def compose_spec() -> dict[str, Any]:
    path = resources.files("check_jsonschema") / "builtin_schemas/vendor/compose-spec.json"
    return json.loads(path.read_text())


def argv(value: str | list[str]) -> list[str]:
    return shlex.split(value) if isinstance(value, str) else [str(v) for v in value]


def hilnav_services() -> dict[str, dict[str, Any]]:
    """Services running our image (built from the Dockerfile, entrypoint ``hilnav``)."""
    return {name: s for name, s in compose()["services"].items() if "build" in s}


def hilnav_params(args: list[str]) -> dict[str, Any]:
    """``hilnav ARGS`` parsed by the command's own parser (down to a subcommand such as
    ``sim live``); nothing runs. Its parameters, as the command would get them."""
    command = typer.main.get_command(app)
    rest = list(args)
    name = "hilnav"
    while hasattr(command, "commands"):  # a group: descend to the subcommand
        commands = command.commands
        assert rest and rest[0] in commands, (
            f"`hilnav {' '.join(args)}`: {rest[:1]} is not one of {sorted(commands)}")
        name = rest.pop(0)
        command = commands[name]
    with command.make_context(name, rest) as ctx:
        return dict(ctx.params)


def option(args: list[str], name: str) -> str:
    assert name in args, f"{name} missing from {args}"
    return args[args.index(name) + 1]


def test_compose_file_follows_the_compose_specification() -> None:
    schema = compose_spec()
    validator = jsonschema.validators.validator_for(schema)(schema)
    errors = sorted(validator.iter_errors(compose()), key=lambda e: list(e.path))
    assert not errors, "\n".join(f"{list(e.path)}: {e.message}" for e in errors)


def test_the_spec_validation_catches_mistakes() -> None:
    # guard against a schema that accepts anything
    bad = compose()
    bad["services"]["sim"]["commnd"] = ["sim"]
    bad["services"]["monitor"]["depends_on"]["zenohd"]["condition"] = "service_happy"
    schema = compose_spec()
    validator = jsonschema.validators.validator_for(schema)(schema)
    errors = {tuple(e.path): e.message for e in validator.iter_errors(bad)}
    assert "commnd" in errors[("services", "sim")]
    assert "service_happy" in errors[("services", "monitor", "depends_on")]


def test_services_and_router_image() -> None:
    services = compose()["services"]
    assert set(services) == {ROUTER, "sim", "fusion", "monitor"}
    router = services[ROUTER]
    m = re.fullmatch(r"eclipse/zenoh:(\d+)\.(\d+)\.(\d+)", router["image"])
    assert m, f"zenohd image must be pinned to a release, got {router['image']}"
    wheel = importlib.metadata.version("eclipse-zenoh").split(".")
    assert m.groups()[:2] == tuple(wheel[:2]), "zenohd and the eclipse-zenoh wheel must match"
    args = argv(router["command"])
    assert "--no-multicast-scouting" in args
    assert option(args, "--listen") == "tcp/0.0.0.0:7447"


def test_every_service_has_a_health_check() -> None:
    for name, service in compose()["services"].items():
        check = service.get("healthcheck")
        assert check and check["test"][0] in ("CMD", "CMD-SHELL"), name


@pytest.mark.parametrize("name", ["sim", "fusion", "monitor"])
def test_service_command_is_a_registered_hilnav_subcommand(name: str) -> None:
    service = hilnav_services()[name]
    args = argv(service["command"])
    # the (sub)command exists and its own parser accepts the options (nothing runs)
    assert hilnav_params(args), name


def test_hilnav_services_use_the_image_entrypoint() -> None:
    text = DOCKERFILE.read_text()
    assert re.search(r'^ENTRYPOINT \["hilnav"\]$', text, re.M)
    for name, service in hilnav_services().items():
        assert service["build"]["dockerfile"] == "Dockerfile", name
        assert "entrypoint" not in service, name


def test_health_checks_of_our_services_parse() -> None:
    # the bus has no CLI of its own: health checks run `hilnav check` (hil.bus.check_bus)
    commands = typer.main.get_command(app).commands  # type: ignore[attr-defined]
    for name, service in hilnav_services().items():
        test = service["healthcheck"]["test"]
        assert test[:3] == ["CMD", "hilnav", "check"], name
        with commands["check"].make_context("check", test[3:]) as ctx:
            assert ctx.params["connect"] == f"tcp/{ROUTER}:7447", name


def test_endpoints_agree_between_services() -> None:
    s = {name: argv(x["command"]) for name, x in hilnav_services().items()}
    zenoh = f"tcp/{ROUTER}:7447"
    assert option(s["fusion"], "--zenoh") == zenoh
    assert option(s["sim"], "--zenoh") == zenoh
    assert option(s["monitor"], "--connect") == zenoh
    listen = option(s["fusion"], "--mavlink")
    assert s["sim"][:2] == ["sim", "live"]
    target = s["sim"][2]
    assert listen == "udpin:0.0.0.0:14560" and target == "udpout:fusion:14560"
    vehicles = {option(a, "--vehicle") for a in s.values()}
    assert vehicles == {"sim1"}
    # the sim's health check listens to the truth key of that vehicle
    sim_check = hilnav_services()["sim"]["healthcheck"]["test"]
    assert "hilnav/sim1/sim/truth" in sim_check


def test_dockerfile_installs_the_package_pinned_python() -> None:
    text = DOCKERFILE.read_text()
    m = re.search(r"^FROM python:(\d+\.\d+)-slim-\w+$", text, re.M)
    assert m, "base image must pin the Python minor version"
    for package in ("sim", "hil", "fusion", "scenarios"):
        assert re.search(rf"^COPY {package} \./{package}$", text, re.M), package
    assert "RUN pip install ." in text
    assert re.search(r"^USER hilnav$", text, re.M)
