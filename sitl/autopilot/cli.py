"""``sitl``: run the simulated vehicle as a MAVLink endpoint.

    sitl                                   # udp 127.0.0.1:14540, real time, ISM+DO attitude loop
    sitl --speedup 10 --scenario E5_suspended_weight --attitude pd_do
    sitl --listen 0.0.0.0:14580 --peer 127.0.0.1:14540   # PX4 style: also push to a listening client

Clients connect with ``udpout://127.0.0.1:14540`` (MAVSDK), ``udpout:127.0.0.1:14540``
(pymavlink / MAVProxy ``--master``); with ``--peer`` the vehicle sends first, as PX4 does, to a
client listening with ``udpin://0.0.0.0:PORT``.

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
from typing import NoReturn, Sequence

from companion.config import ConfigError
from companion.control.attitude import ATTITUDE_CONTROLLERS
from companion.mavlink.signing import SigningError
from companion.mavlink.signing_options import add_signing_options, signing_key

from ..plant.scenario import Scenario, load_scenario
from ..plant.vehicle import SimVehicle
from .logic import Autopilot, AutopilotParams
from .parameters import out_of_range
from .server import MavlinkServer, ServerConfig
from .telemetry import GeoOrigin

__all__ = ["main", "build", "parse_address"]


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
    ap = Autopilot(vehicle, AutopilotParams(paper_inner_loop=args.flavour == "paper",
                                            flavour="ardupilot" if args.flavour == "ardupilot" else "px4"))
    cfg = ServerConfig(listen=args.listen, peers=tuple(args.peer), speedup=args.speedup, sysid=args.sysid,
                       origin=args.origin, signing_key=signing_key(args, "sitl"),
                       wait_for_setpoints_s=args.wait_for_setpoints, lockstep_period_s=args.lockstep * 1e-3,
                       max_wait_wall_s=3.0 if args.lockstep else 1.0)
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
        print(f"sitl: vehicle sysid {server.config.sysid} compid {server.config.compid} listening on "
              f"udp://{host}:{port} (MAVSDK: udpout://{host}:{port}), speed-up {server.config.speedup:g}x",
              flush=True)
    await server.run(stop, duration_s)
    report = {"t": round(server.ap.t, 3), "stats": dict(server.stats), "rejections": dict(server.rejections),
              "signing_rejections": dict(server.signing_rejections),
              "mode": server.ap.mode.name, "armed": server.ap.armed, "events": list(server.ap.events),
              "terminated": server.ap.terminated, "halted": server.guard.halted,
              "loop_lateness_ms": server.lateness_ms(), "setpoint_age_ms": server.setpoint_age_ms(),
              "longest_wait_ms": round(server.longest_wait_s * 1e3, 1), "pace": server.pace(),
              "peers": server.peers.summary(),
              "peer_table": {"added": server.peers.added, "evicted": server.peers.evicted,
                             "refused": server.peers.refused, "expired": server.peers.expired}}
    print(f"sitl: stopped {json.dumps(report)}", flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    ap = _Parser(prog="sitl", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--listen", type=parse_address, default=("127.0.0.1", 14540), help="HOST:PORT to bind")
    ap.add_argument("--peer", type=parse_address, action="append", default=[],
                    help="HOST:PORT to send to from the start (repeatable)")
    ap.add_argument("--speedup", type=_finite, default=1.0, help="simulated seconds per wall second")
    ap.add_argument("--scenario", help="scenario file or bundled name: vehicle, wind, forces, gains")
    ap.add_argument("--attitude", choices=ATTITUDE_CONTROLLERS, default="ism_do",
                    help="onboard attitude controller")
    ap.add_argument("--flavour", choices=("px4", "paper", "ardupilot"), default="px4",
                    help="px4: PX4 v1.16's rules (with an attitude only the yaw rate of SET_ATTITUDE_TARGET is a "
                         "feed-forward; offboard loss descends; ...); paper: a PX4-like vehicle whose inner loop "
                         "flies the attitude and its body rates together, as the paper's does "
                         "(fly it with companion --output attitude_rates); "
                         "ardupilot: behave like ArduCopter (GUIDED, GUID_OPTIONS, ANGLE_MAX, ...)")
    ap.add_argument("--param", type=parse_param, action="append", default=[], metavar="NAME=VALUE",
                    help="set a parameter at start, e.g. SIM_WIND_N=3 SIM_TURB_SIGMA=0.6 SIM_FORCE_X=6 "
                         "SIM_MASS_FAC=1.3 (repeatable; the full list: PARAM_REQUEST_LIST or docs/sitl.md)")
    ap.add_argument("--seed", type=_int_in(0, 2**32 - 1), default=1)
    ap.add_argument("--sysid", type=_int_in(1, 255), default=1)
    ap.add_argument("--origin", type=parse_origin, default=GeoOrigin(), help="LAT,LON,ALT of the local origin")
    ap.add_argument("--wait-for-setpoints", type=_finite, default=0.0, metavar="SECONDS",
                    help="while flying a companion's stream, stop the simulated clock (up to 1 s of wall time) "
                         "when the newest setpoint is older than SECONDS of simulated time: a stalled host "
                         "then does not fly the vehicle without its companion (tests, soaks; 0: off)")
    ap.add_argument("--lockstep", type=_finite, default=0.0, metavar="PERIOD_MS", nargs="?", const=10.0,
                    help="while flying a companion's stream, advance the simulated world only as setpoints arrive, "
                         "PERIOD_MS (default 10: a 100 Hz companion) per setpoint; --speedup stays the upper "
                         "bound. Host load then changes how long a flight takes, not what it measures")
    ap.add_argument("--duration", type=_finite, default=None, help="stop after this many simulated seconds")
    add_signing_options(ap)
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    if not 0.05 <= args.speedup <= 1000:
        ap.error("--speedup must be within 0.05..1000")
    if not (args.wait_for_setpoints == 0 or 0.005 <= args.wait_for_setpoints <= 0.5):
        ap.error("--wait-for-setpoints must be 0 (off) or within 0.005..0.5 s (below the 1 s offboard-loss timeout)")
    if not (args.lockstep == 0 or 1.0 <= args.lockstep <= 100.0):
        ap.error("--lockstep must be a period of 1..100 ms")
    if args.duration is not None and args.duration <= 0:
        ap.error("--duration must be positive")
    try:
        server = build(args)
    except (ConfigError, SigningError) as exc:
        return _fail(str(exc))
    except Exception as exc:  # anything else a scenario's values can provoke: one line, never a traceback
        return _fail(f"cannot build the vehicle: {type(exc).__name__}: {exc}")
    try:
        asyncio.run(serve(server, args.duration, args.quiet))
    except OSError as exc:
        return _fail(f"cannot listen on {args.listen[0]}:{args.listen[1]}: {exc.strerror or exc}")
    return 0


def _fail(message: str) -> int:
    print(f"sitl: error: {' '.join(message.split())}", file=sys.stderr)
    return 2
