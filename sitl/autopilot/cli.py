"""The bundled vehicle behind the ``sitl`` command (:mod:`sitl.cli`): options checked, vehicle
built, server run.

    sitl                                   # PX4 SITL's ports: listens on 14580, sends to 14540; real time
    sitl --speedup 10 --scenario E5_suspended_weight --attitude pd_do
    sitl --listen 127.0.0.1:14540          # your own ports: answers clients at 14540, sends to no one first

With neither ``--listen`` nor ``--peer`` the vehicle takes PX4 SITL's ports (:func:`ports`): clients
written for PX4 SITL connect unchanged with ``udpin://0.0.0.0:14540`` (MAVSDK, the companion) or
``udpin:0.0.0.0:14540`` (pymavlink, MAVProxy ``--master``); ``udpout://127.0.0.1:14580`` works too.

MAVLink 2 signing is on when a key is given, from ``--signing-key-file FILE`` or the environment
variable MAVLINK_SIGNING_KEY (64 hex digits or a passphrase); never on the command line itself.
Make a key with ``companion keygen FILE``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import signal
import socket
import sys
from typing import NoReturn

from companion.config import ConfigError
from companion.mavlink.signing_options import signing_key

from ..plant.engine import default_engine
from ..plant.scenario import Scenario, load_scenario
from ..plant.vehicle import SimVehicle
from .logic import Autopilot, AutopilotParams
from .parameters import out_of_range
from .server import PX4_LISTEN, PX4_PEER, MavlinkServer, ServerConfig
from .telemetry import GeoOrigin

__all__ = ["build", "serve", "parse_address", "parse_param", "parse_origin", "ports", "PX4_LISTEN", "PX4_PEER"]



def ports(listen: tuple[str, int] | None, peers: list[tuple[str, int]] | None,
          ) -> tuple[tuple[str, int], list[tuple[str, int]]]:
    """The address to bind and the peers to send to from the start: PX4 SITL's pair when neither is
    given; otherwise what was given (a ``--listen`` alone sends first to no one, a ``--peer`` alone
    listens on PX4's port)."""
    if listen is None and peers is None:
        return PX4_LISTEN, [PX4_PEER]
    return listen or PX4_LISTEN, list(peers or [])


class _Parser(argparse.ArgumentParser):
    """Errors are one line on stderr and exit status 2 (argparse's own prints the usage too)."""

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: error: {' '.join(message.split())}", file=sys.stderr)
        raise SystemExit(2)


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (or ``udp://HOST:PORT``) to a tuple, with a clear error; the host must be an
    IPv4 address or a name that resolves to one."""
    raw = text.split("://", 1)[-1]
    host, sep, port = raw.rpartition(":")
    if not sep or not port.isdigit() or not 0 <= int(port) < 65536:  # 0: any free port (the banner says which)
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, got {text!r}")
    host = host or "127.0.0.1"
    try:
        socket.getaddrinfo(host, int(port), socket.AF_INET, socket.SOCK_DGRAM)
    except (OSError, UnicodeError):
        raise argparse.ArgumentTypeError(f"{host!r} is not an IPv4 address or a name that resolves to one") from None
    return host, int(port)


def parse_param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=NUMBER, got {text!r}") from None
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=NUMBER, got {text!r}")
    return name.strip(), number


def parse_origin(text: str) -> GeoOrigin:
    try:
        lat, lon, alt = (float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LAT,LON,ALT, got {text!r}") from None
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and -500.0 <= alt <= 10_000.0):
        raise argparse.ArgumentTypeError(f"expected LAT in [-90, 90], LON in [-180, 180] and ALT in "
                                         f"[-500, 10000] m, got {text!r}")
    return GeoOrigin(lat, lon, alt)


def _int_in(low: int, high: int) -> type:
    def parse(text: str) -> int:
        try:
            value = int(text, 0)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected {low}..{high}, got {value}")
        return value
    parse.__name__ = "integer"
    return parse  # type: ignore[return-value]


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def unflyable(scenario: Scenario) -> list[str]:
    """What makes a scenario's vehicle impossible to fly live (the parameter ranges check the rest)."""
    v, a = scenario.plant_vehicle, scenario.airframe
    numbers = {"vehicle.mass_kg": v.mass_kg, "vehicle.arm_length_m": v.arm_length_m,
               "vehicle.k_thrust_n_s2": v.k_thrust_n_s2, "vehicle.k_torque_nm_s2": v.k_torque_nm_s2,
               "vehicle.rotor_speed_max_rad_s": v.rotor_speed_max_rad_s, "vehicle.gravity_m_s2": v.gravity_m_s2,
               "airframe.rotor_time_constant_s": a.rotor_time_constant_s,
               **{f"vehicle.inertia_kg_m2[{i}]": j for i, j in enumerate(v.inertia_kg_m2)}}
    problems = [f"{k} = {x!r} must be a positive number" for k, x in numbers.items()
                if not (isinstance(x, (int, float)) and math.isfinite(x) and x > 0)]
    if problems:
        return problems
    if not 0 <= v.rotor_speed_min_rad_s < v.rotor_speed_max_rad_s:
        problems.append("vehicle.rotor_speed_min_rad_s must be within [0, rotor_speed_max_rad_s)")
    if v.thrust_max_n < 1.5 * v.weight_n:
        problems.append(f"the vehicle cannot fly: full thrust {v.thrust_max_n:.3g} N is less than 1.5 x its weight "
                        f"{v.weight_n:.3g} N")
    if not 100.0 <= scenario.plant_rate_hz <= 10_000.0:
        problems.append(f"plant_rate_hz = {scenario.plant_rate_hz:g} must be within 100..10000")
    return problems


def build(args: argparse.Namespace) -> MavlinkServer:
    scenario = load_scenario(args.scenario) if args.scenario else Scenario(name="sitl")
    problems = unflyable(scenario)
    if problems:
        raise ConfigError(args.scenario or "scenario", None, "", "; ".join(problems))
    # a live vehicle starts on the ground at the origin, whatever the scenario's setpoint says
    vehicle = SimVehicle(scenario, args.attitude, args.seed, (0.0, 0.0, scenario.airframe.ground_z_m), 0.0,
                         hovering=False)
    if (getattr(args, "engine", None) or default_engine()) == "compiled":
        vehicle.compile_chunks()
    ap = Autopilot(vehicle, AutopilotParams(paper_inner_loop=args.flavour == "paper",
                                            flavour="ardupilot" if args.flavour == "ardupilot" else "px4"))
    cfg = ServerConfig(listen=args.listen, peers=tuple(args.peer), speedup=args.speedup, sysid=args.sysid,
                       origin=args.origin, signing_key=signing_key(args, "sitl"),
                       wait_for_setpoints_s=args.wait_for_setpoints, lockstep_period_s=args.lockstep * 1e-3,
                       max_wait_wall_s=3.0 if args.lockstep else 1.0, boot_time_s=args.boot_time)
    server = MavlinkServer(ap, cfg)
    bad = out_of_range(server.params)
    if bad:  # the scenario set what no PARAM_SET may
        raise ConfigError(args.scenario or "scenario", None, "", "; ".join(bad))
    for name, value in args.param:
        reason = server.params.set(name, value)
        if reason is not None:
            raise ConfigError("--param", None, "", reason)
    return server


async def serve(server: MavlinkServer, duration_s: float | None, quiet: bool) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    await server.start()
    host, port = server.address
    if not quiet:
        pushing = "".join(f", sending to udp://{h}:{p} (MAVSDK: udpin://0.0.0.0:{p})" for h, p in server.config.peers)
        print(f"sitl: vehicle sysid {server.config.sysid} compid {server.config.compid} listening on "
              f"udp://{host}:{port} (MAVSDK: udpout://{host}:{port}){pushing}, speed-up {server.config.speedup:g}x",
              flush=True)
    await server.run(stop, duration_s)
    report = {"t": round(server.ap.t, 3), "stats": dict(server.stats), "rejections": dict(server.rejections),
              "signing_rejections": dict(server.signing_rejections),
              "mode": server.ap.mode.name, "armed": server.ap.armed, "events": list(server.ap.events),
              "terminated": server.ap.terminated, "halted": server.guard.halted,
              "loop_lateness_ms": server.lateness_ms(), "setpoint_age_ms": server.setpoint_age_ms(),
              "longest_wait_ms": round(server.longest_wait_s * 1e3, 1), "pace": server.pace(),
              "run_cpu": server.run_cpu, "steps": dict(server.ap.vehicle.chunk_counts),
              "peers": server.peers.summary(),
              "peer_table": {"added": server.peers.added, "evicted": server.peers.evicted,
                             "refused": server.peers.refused, "expired": server.peers.expired}}
    print(f"sitl: stopped {json.dumps(report)}", flush=True)


def _fail(message: str) -> int:
    print(f"sitl: error: {' '.join(message.split())}", file=sys.stderr)
    return 2
