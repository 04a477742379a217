"""docker/: no engine runs here, so the compose file is validated against the Compose
specification's JSON schema (check-jsonschema's vendored copy) and checked for what the schema
cannot know: files the Dockerfile copies exist, every command is an installed entry point or
module, missions and ports are consistent."""

import shlex
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
COMPOSE = ROOT / "docker" / "compose.yaml"


def test_compose_file_matches_the_compose_specification():
    r = subprocess.run([sys.executable, "-m", "check_jsonschema", "--builtin-schema", "vendor.compose-spec",
                        str(COMPOSE)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_compose_services_use_real_commands_and_files():
    spec = yaml.safe_load(COMPOSE.read_text())
    services = spec["services"]
    assert {"sitl", "companion", "px4", "companion-px4"} <= set(services)
    for name, svc in services.items():
        if "build" in svc:
            assert (COMPOSE.parent / svc["build"]["context"] / svc["build"]["dockerfile"]).exists(), name
        cmd = svc.get("command")
        if not cmd:
            continue
        assert cmd[0] in ("companion", "sitl"), name
        for arg in cmd:
            if arg.startswith("missions/"):
                assert (ROOT / arg).exists(), arg
        # the arguments parse: run the real entry point with --help appended to the subcommand
        module = "companion" if cmd[0] == "companion" else "sitl"
        r = subprocess.run([sys.executable, "-m", module, *cmd[1:2], "--help"] if module == "companion"
                           else [sys.executable, "-m", module, "--help"], capture_output=True, text=True, cwd=ROOT)
        assert r.returncode == 0, (name, r.stderr)
    assert services["companion"]["command"][4] == "udp://sitl:14540"
    assert services["sitl"]["command"][2] == "0.0.0.0:14540"
    assert services["companion-px4"]["network_mode"] == services["px4"]["network_mode"] == "host"


def test_dockerfile_copies_only_what_exists():
    for line in (ROOT / "docker" / "Dockerfile").read_text().splitlines():
        if line.startswith("COPY "):
            for src in shlex.split(line)[1:-1]:
                assert (ROOT / src).exists(), src
