"""``companion``: fly a mission offboard, re-draw a flight's plots, or check a mission file.

    companion fly missions/hover45.toml --controller ism_do      # sitl or PX4 SITL: udpin://0.0.0.0:14540
    companion fly missions/square_gps.toml                       # PX4 SITL (5 m up: GPS)
    companion plot flights/20261122-120000_hover45_ism_do
    companion check missions/*.toml
    companion demo                     # start the bundled vehicle, fly hover45 and waypoints
    companion keygen ~/.config/mavlink.key   # a new signing key (file mode 600)
    companion estimate flight.ulg --mass 1.0     # the external force over a logged flight
    companion fly missions/hover45.toml --signing-key-file ~/.config/mavlink.key

MAVLink 2 signing is on when a key is given, from ``--signing-key-file FILE`` or the environment
variable MAVLINK_SIGNING_KEY (64 hex digits or a passphrase); never on the command line itself.

Exit codes: 0 completed, 1 aborted (refused command, offboard left, timeout), 2 bad mission file
or arguments, 3 vehicle link lost, 130 interrupted (after holding, landing and disarming).
"""

from __future__ import annotations

import argparse
import math
import asyncio
import sys
from pathlib import Path
from typing import Sequence

from companion.config import ConfigError
from companion.control.position import POSITION_CONTROLLERS
from companion.link.url import parse_endpoint
from companion.mavlink.identity import VehicleTarget
from companion.mavlink.signing import SigningError, fingerprint, write_key_file
from companion.mavlink.signing_options import add_signing_options, signing_key

__all__ = ["main"]


def _fly(args: argparse.Namespace) -> int:
    from .flight import Flight, FlightOptions, run_flight
    from .mission import load_mission

    try:
        mission = load_mission(args.mission)
    except ConfigError as exc:
        _config_error(exc)
        return 2
    if args.thrust_max is not None and not 1.0 <= args.thrust_max <= 500.0:
        print(f"companion: error: --thrust-max {args.thrust_max:g}: expected 1..500 N", file=sys.stderr)
        return 2
    try:
        parse_endpoint(args.connect)
    except ValueError as exc:
        print(f"companion: error: {exc}", file=sys.stderr)
        return 2
    try:
        key = signing_key(args, "companion")
    except SigningError as exc:
        print(f"companion: error: {exc}", file=sys.stderr)
        return 2
    if key is not None and args.backend == "mavsdk":
        print("companion: error: MAVLink signing needs --backend pymavlink (MAVSDK 4.1's Python API takes no "
              "signing key)", file=sys.stderr)
        return 2
    if args.target_component is not None and args.target_system is None:
        print("companion: error: --target-component needs --target-system too", file=sys.stderr)
        return 2
    target = (None if args.target_system is None else
              VehicleTarget(args.target_system, args.target_component or 0))
    opts = FlightOptions(mission_file=Path(args.mission),
                         connect=args.connect, backend=args.backend, controller=args.controller, rate_hz=args.rate,
                         out_dir=Path(args.out), thrust_max_n=args.thrust_max, quiet=args.quiet, signing_key=key,
                         connect_timeout_s=args.connect_timeout, position_wait_s=args.position_wait,
                         output=args.output, take_over=args.take_over,
                         ardupilot_shaping=args.ardupilot_shaping, target=target)
    try:
        flight = Flight(mission, opts)
    except OSError as exc:
        print(f"companion: error: cannot write the flight record under {args.out}: {exc.strerror or exc}",
              file=sys.stderr)
        return 2
    return asyncio.run(run_flight(flight, plots=not args.no_plots))


def _plot(args: argparse.Namespace) -> int:
    from .plots import draw_flight

    folder = Path(args.flight)
    if not (folder / "timeseries.csv").exists():
        print(f"companion: error: {folder} is not a flight folder (no timeseries.csv)", file=sys.stderr)
        return 2
    for p in draw_flight(folder):
        print(p)
    return 0


def _config_error(exc: ConfigError) -> None:
    """The refusal on one line, then what to do about it (if the loader said)."""
    print(f"companion: error: {exc}", file=sys.stderr)
    for line in exc.hint.splitlines():
        print(f"companion: {line}", file=sys.stderr)


def _check(args: argparse.Namespace) -> int:
    """Load each mission exactly as ``fly`` does (one loader): ok and what it flies, or the
    refusal with file:line and key, exit 2. ``--show``: the steps as they will be flown, in NED."""
    from .mission import extent, load_mission
    from .mission.show import gps_height_warning, steps_in_ned

    status = 0
    for name in args.missions:
        try:
            m = load_mission(name)
        except ConfigError as exc:
            _config_error(exc)
            status = 2
            continue
        far_m, high_m = extent(m)
        print(f"{name}: ok ({len(m.steps)} steps, {m.controller.position} at {m.controller.rate_hz:g} Hz; "
              f"flies within {far_m:.1f} m of home and {high_m:.1f} m above it; "
              f"volume {m.safety.volume.describe()})")
        if "not flown" in m.description or "not used" in m.description:
            print(f"{name}: note: {m.description}")
        warning = gps_height_warning(m)
        if warning:
            print(f"{name}: warning: {warning}")
        if args.show:
            for line in steps_in_ned(m):
                print(line)
    return status


def _demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    return run_demo(out_dir=Path(args.out), speedup=args.speedup, controller=args.controller)


def _keygen(args: argparse.Namespace) -> int:
    try:
        key = write_key_file(args.file)
    except FileExistsError:
        print(f"companion: error: {args.file} exists; a key is never overwritten", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"companion: error: cannot write {args.file}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"{args.file}: new MAVLink 2 signing key (mode 600), fingerprint {fingerprint(key)}")
    return 0


def _positive(text: str) -> float:
    """A finite number above zero (argparse: exit 2 with the option named)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"expected a finite number above 0, got {text!r}")
    return value


def _mavlink_id(text: str) -> int:
    """A MAVLink system or component id, 1..255 (argparse: exit 2 with the option named)."""
    if not text.strip().isdigit() or not 1 <= int(text) <= 255:
        raise argparse.ArgumentTypeError(f"expected an id of 1..255, got {text!r}")
    return int(text)


def _non_negative(text: str) -> float:
    value = _positive(text) if text.strip() not in ("0", "0.0") else 0.0
    return value


def _estimate(args: argparse.Namespace) -> int:
    from .estimate import ThrustScale, estimate_force, plot, rms, write_csv
    from .logs import read_log

    scale = None
    if args.thrust_scale_total is not None:
        scale = ThrustScale(args.thrust_scale_total, per_motor=False)
    elif args.thrust_scale_per_motor is not None:
        scale = ThrustScale(args.thrust_scale_per_motor, per_motor=True)
    try:
        series = read_log(args.log, args.columns, thrust_is_newtons=args.thrust_newtons, world_frame=args.world,
                          body_frame=args.body)
        est = estimate_force(series, args.mass, args.gamma, scale, args.method, args.motor_tau)
    except (OSError, ValueError, RuntimeError, ZeroDivisionError) as exc:
        print(f"companion: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = Path(args.log).name.split(".")[0]
    write_csv(est, out / f"{stem}_force.csv")
    plot(est, out / f"{stem}_force.png", series.source)
    print(f"{series.source}: {len(est.t_s)} samples over {est.t_s[-1]:.1f} s, {est.method}")
    if est.airborne is not None:
        print(f"airborne {est.airborne_s:.1f} s of {est.t_s[-1]:.1f} s by {est.airborne_source} (the output's "
              "airborne column; on the ground the force is the ground's)")
    if est.thrust_scale_n is not None:
        print(est.describe_scale())
    if est.truth_force_ned_n is not None:
        print(f"RMS error against the logged truth: {rms(est.force_ned_n - est.truth_force_ned_n):.3f} N")
    print(f"-> {out / f'{stem}_force.csv'}, {out / f'{stem}_force.png'}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="companion", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    fly = sub.add_parser("fly", help="fly a mission file")
    fly.add_argument("mission", help="mission file (.toml, or a QGroundControl .plan)")
    fly.add_argument("--connect", default="udpin://0.0.0.0:14540",
                     help="udpin://HOST:PORT (the vehicle sends first: PX4 SITL and the bundled sitl, 14540; the "
                          "default), udp://HOST:PORT (a vehicle that listens), tcp://HOST:PORT (ArduPilot SITL: 5760), "
                          "serial:///dev/DEVICE:BAUD (a flight controller's TELEM port)")
    fly.add_argument("--controller", choices=(*POSITION_CONTROLLERS, "autopilot"),
                     help="position controller; autopilot: the autopilot's own position control flies the same "
                          "reference (SET_POSITION_TARGET_LOCAL_NED), for comparison")
    fly.add_argument("--rate", type=float, help="control rate in vehicle Hz (10..250)")
    fly.add_argument("--backend", choices=("pymavlink", "mavsdk"), default="pymavlink")
    fly.add_argument("--thrust-max", type=float, help="thrust at full throttle [N] (default: ask the vehicle)")
    fly.add_argument("--out", default="flights", help="folder for flight records")
    fly.add_argument("--connect-timeout", type=_positive, default=20.0, metavar="S",
                     help="give up if no autopilot heartbeat and telemetry (attitude and position) within S seconds "
                          "of wall time, whatever else the peer sends (default 20)")
    fly.add_argument("--position-wait", type=_non_negative, default=0.0, metavar="S",
                     help="a vehicle that sends attitude but no position yet (its estimator has no origin: "
                          "ArduCopter SITL about 40 s after boot) is waited for S seconds more than "
                          "--connect-timeout, with a progress line every 5 s (default 0: not waited for)")
    fly.add_argument("--output", choices=("auto", "attitude", "rates", "attitude_rates"), default="auto",
                     help="what SET_ATTITUDE_TARGET carries: attitude (q, thrust, yaw-rate feed-forward; the "
                          "default), rates (body rates and thrust: the attitude loop closed here), attitude_rates "
                          "(everything, as the paper's inner loop takes it)")
    fly.add_argument("--take-over", action="store_true",
                     help="fly a vehicle that is already armed or flying, from where it is (no take-off); "
                          "without it the companion refuses such a vehicle: another operator may be flying it")
    fly.add_argument("--ardupilot-shaping", action=argparse.BooleanOptionalAction, default=None,
                     help="ArduCopter: keep (--ardupilot-shaping) or turn off for the flight "
                          "(--no-ardupilot-shaping, the default) its attitude input shaping, ATC_RATE_FF_ENAB; turned "
                          "off, it is put back when the flight ends, on every path (default: the mission's "
                          "[controller] ardupilot_shaping)")
    fly.add_argument("--target-system", type=_mavlink_id, metavar="N",
                     help="the MAVLink system id of the vehicle to fly when a link carries several (a router, a "
                          "swarm radio); overrides the mission's [target] system_id. Without one, the companion flies "
                          "the only autopilot on the link and refuses when it hears more than one")
    fly.add_argument("--target-component", type=_mavlink_id, metavar="C",
                     help="its autopilot's component id (default: whichever autopilot component of that system)")
    fly.add_argument("--no-plots", action="store_true")
    fly.add_argument("--quiet", action="store_true")
    add_signing_options(fly)
    fly.set_defaults(func=_fly)
    plot = sub.add_parser("plot", help="re-draw a flight's plots")
    plot.add_argument("flight")
    plot.set_defaults(func=_plot)
    check = sub.add_parser("check", help="validate mission files")
    check.add_argument("missions", nargs="+")
    check.add_argument("--show", action="store_true", help="print the steps as they will be flown (a .plan's "
                       "converted), positions in metres north, east, down of home, and the fences")
    check.set_defaults(func=_check)
    demo = sub.add_parser("demo", help="fly hover45 and waypoints against the bundled simulated vehicle")
    demo.add_argument("--out", default="flights")
    demo.add_argument("--speedup", type=float, default=8.0, help="upper bound on the simulated vehicle's speed-up "
                      "(in lockstep it flies as fast as the companion answers, up to this)")
    demo.add_argument("--controller", choices=POSITION_CONTROLLERS, default="ism_do")
    demo.set_defaults(func=_demo)
    est = sub.add_parser("estimate", help="the external force over a logged flight (ULog, tlog, DataFlash or CSV)")
    est.add_argument("log", help=".ulg (PX4), .tlog (MAVLink: PX4 or ArduPilot), .bin (ArduCopter DataFlash) or "
                                 ".csv/.csv.gz (with --columns)")
    est.add_argument("--mass", type=_positive, required=True, help="vehicle mass [kg]")
    scale = est.add_mutually_exclusive_group()
    scale.add_argument("--thrust-scale-total", type=_positive, metavar="N",
                       help="thrust of all rotors at full thrust [N] (default: estimated from the log)")
    scale.add_argument("--thrust-scale-per-motor", type=_positive, metavar="N",
                       help="thrust of one rotor at full thrust [N]; converted with the log's motor count")
    est.add_argument("--gamma", type=_positive, default=5.0, help="observer bandwidth [rad/s] (default 5)")
    est.add_argument("--method", choices=("auto", "accelerometer", "velocity"), default="auto")
    est.add_argument("--motor-tau", type=_non_negative, default=0.0,
                     help="rotor time constant [s] for logged commands")
    est.add_argument("--columns", help="CSV: FIELD=COLUMN,... (t,qw,qx,qy,qz,ax,ay,az,vx,vy,vz,z,thrust,landed) or "
                                       "'sitl'")
    est.add_argument("--thrust-newtons", action="store_true", help="CSV: the thrust column is in newtons")
    est.add_argument("--world", choices=("ned", "enu"), default="ned", help="CSV: world frame")
    est.add_argument("--body", choices=("frd", "flu"), default="frd", help="CSV: body frame")
    est.add_argument("--out", default="estimates", help="output folder")
    est.set_defaults(func=_estimate)
    keygen = sub.add_parser("keygen", help="write a new random MAVLink 2 signing key to a file (mode 600)")
    keygen.add_argument("file")
    keygen.set_defaults(func=_keygen)
    args = ap.parse_args(argv)
    if getattr(args, "rate", None) is not None and not 10.0 <= args.rate <= 250.0:
        ap.error("--rate must be within 10..250 Hz")
    return int(args.func(args))
