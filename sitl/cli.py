"""``sitl``: the simulated vehicle as a MAVLink endpoint — the bundled autopilot on the plant, or
a real autopilot's SITL build on the plant (``--firmware px4|ardupilot``, :mod:`sitl.firmware`).

    sitl                                   # PX4 SITL's ports: listens on 14580, sends to 14540; real time
    sitl --speedup 10 --scenario E5_suspended_weight --attitude pd_do
    sitl --listen 127.0.0.1:14540          # your own ports: answers clients at 14540, sends to no one first
    sitl --firmware px4 --speedup 4 --lockstep             # PX4 v1.16 flies the plant; companion on udpin://0.0.0.0:14540
    sitl --firmware ardupilot --speedup 4 --lockstep       # ArduCopter flies the plant; companion on tcp://127.0.0.1:5760

By default the bundled vehicle uses PX4 SITL's ports: it listens on 127.0.0.1:14580 and sends to
127.0.0.1:14540 from the start, so a script written for PX4 SITL connects unchanged with
``udpin://0.0.0.0:14540`` (MAVSDK, the companion) or ``udpin:0.0.0.0:14540`` (pymavlink, MAVProxy
``--master``); ``udpout://127.0.0.1:14580`` reaches it too. ``--listen`` or ``--peer`` choose the
ports instead (the vehicle then sends first only to each ``--peer``).

MAVLink 2 signing is on when a key is given, from ``--signing-key-file FILE`` or the environment
variable MAVLINK_SIGNING_KEY (64 hex digits or a passphrase); never on the command line itself.
Make a key with ``companion keygen FILE``.
"""

from __future__ import annotations

import argparse
import asyncio
from typing import Sequence

from companion.config import ConfigError
from companion.control.attitude import ATTITUDE_CONTROLLERS
from companion.mavlink.signing import SigningError
from companion.mavlink.signing_options import add_signing_options

from .plant.engine import ENGINES
from .autopilot.cli import (PX4_LISTEN, PX4_PEER, _fail, _finite, _int_in, _Parser, build, parse_address, parse_origin,
                            parse_param, ports, serve)
from .firmware.cli import add_firmware_options
from .firmware.cli import run as run_firmware
from .plant.geo import GeoOrigin
from .plant.scenario import Scenario, load_scenario

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    ap = _Parser(prog="sitl", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--listen", type=parse_address, default=None,
                    help=f"HOST:PORT to bind (default, with no --peer either: {PX4_LISTEN[0]}:{PX4_LISTEN[1]}, "
                         "PX4 SITL's)")
    ap.add_argument("--peer", type=parse_address, action="append", default=None,
                    help=f"HOST:PORT to send to from the start (repeatable; default, with no --listen either: "
                         f"{PX4_PEER[0]}:{PX4_PEER[1]}, where PX4 SITL sends)")
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
    ap.add_argument("--engine", choices=ENGINES, default=None,
                    help="what steps the plant between two decisions of the rules: compiled (the lab's kernel; the "
                         "default where numba is installed, or $SITL_ENGINE) or objects (plain Python)")
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
    ap.add_argument("--boot-time", type=_finite, default=0.0, metavar="SECONDS",
                    help="how long the vehicle has been up when it starts [s]: every stamp it sends starts there. "
                         "time_boot_ms wraps at 2^32 ms (4294967.296 s, 49.7 days): --boot-time 4294937 wraps it "
                         "30 simulated seconds after start (0..1e8, default 0)")
    ap.add_argument("--duration", type=_finite, default=None, help="stop after this many simulated seconds")
    add_signing_options(ap)
    add_firmware_options(ap)
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    if not 0.05 <= args.speedup <= 1000:
        ap.error("--speedup must be within 0.05..1000")
    if not (args.wait_for_setpoints == 0 or 0.005 <= args.wait_for_setpoints <= 0.5):
        ap.error("--wait-for-setpoints must be 0 (off) or within 0.005..0.5 s (below the 1 s offboard-loss timeout)")
    if not (args.lockstep == 0 or 1.0 <= args.lockstep <= 100.0):
        ap.error("--lockstep must be a period of 1..100 ms")
    if not 0.0 <= args.boot_time <= 1e8:
        ap.error("--boot-time must be within 0..1e8 s (3 years; stamps of 1e9 s and more read as UNIX time)")
    if args.duration is not None and args.duration <= 0:
        ap.error("--duration must be positive")
    if args.firmware is not None:
        return _firmware(ap, args)
    for option in ("firmware_path", "layout", "position_source"):
        if getattr(args, option) is not None:
            ap.error(f"--{option.replace('_', '-')} needs --firmware")
    args.listen, args.peer = ports(args.listen, args.peer)
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




def _firmware(ap: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``--firmware``: what the bundled autopilot's options mean does not apply."""
    for option, default in (("listen", None), ("peer", None), ("attitude", "ism_do"),
                            ("flavour", "px4"), ("sysid", 1), ("wait_for_setpoints", 0.0), ("boot_time", 0.0),
                            ("engine", None)):
        if getattr(args, option) != default:
            ap.error(f"--{option.replace('_', '-')} is the bundled autopilot's: with --firmware the firmware's own "
                     f"ports, attitude loop and rules apply")
    try:
        scenario = load_scenario(args.scenario) if args.scenario else Scenario(name="sitl")
    except (ConfigError, OSError, ValueError) as exc:
        return _fail(str(exc))
    return run_firmware(args, scenario, args.origin)
