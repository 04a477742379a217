"""``sitl --firmware px4|ardupilot``: a real autopilot's SITL build flying the project's plant.

    sitl --firmware px4 --scenario E5_suspended_weight --speedup 4 --lockstep
    sitl --firmware ardupilot --position-source gnss --param SIM_WIND_N=3

The firmware is found as the tests find it (``--firmware-path``, else PX4_SITL_BUILD /
ARDUCOPTER_SITL, else under ~/autopilots; docs/autopilots.md) and started in a fresh working
directory with its airframe set to match the plant (sitl/firmware/airframes/). Its MAVLink ports
stay where users expect them — PX4: the companion on ``udpin://0.0.0.0:14540``, a ground station
on 14550; ArduCopter: ``tcp://127.0.0.1:5760`` — and the plant's SIM_* parameters are served by
the plant's own component (id 25) on the firmware's network. Ctrl-C stops both.
"""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from companion.control.params import VehicleParams
from companion.mavlink.params import PLANT_COMPID
from companion.mavlink.signing_options import signing_key
from sitl.plant.geo import GeoOrigin
from sitl.plant.nav_sensors import NavSensorParams
from sitl.plant.parameters import ESTIMATE_ONLY, build_plant_parameters
from sitl.plant.scenario import Scenario

from .airframe import ardupilot_parameters, px4_parameters
from .ardupilot import ArduPilotBridge, ArduPilotPorts, ArduPilotProcess
from .bridge import Bridge, Pace, PlantSocket
from .builds import arducopter_binary, px4_build
from .lockstep import CompanionGate
from .plant_component import PlantComponent, estimator_origin
from .px4 import PX4_MAX_INSTANCE, Px4Bridge, Px4Ports, Px4Process
from .relay import TcpRelay, UdpRelay
from .signed_link import SignedLink
from .world import FirmwareWorld

__all__ = ["FIRMWARES", "add_firmware_options", "run", "firmware_scenario", "Session"]

FIRMWARES = ("px4", "ardupilot")
DEFAULT_LAYOUT = "x"
TELEMETRY_INTERVAL_S = 0.01
"""the companion asks for attitude and position at 100 Hz or more"""


def add_firmware_options(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--firmware", choices=FIRMWARES,
                    help="fly a real autopilot's SITL build on this plant instead of the bundled autopilot "
                         "(docs/autopilots.md)")
    ap.add_argument("--firmware-path", help="the build: PX4's build/px4_sitl_default directory or the arducopter "
                                            "binary (default: PX4_SITL_BUILD / ARDUCOPTER_SITL, else ~/autopilots)")
    ap.add_argument("--layout", choices=("x", "plus"), default=None,
                    help="rotor layout of the vehicle (default: x with --firmware, the scenario's otherwise)")
    ap.add_argument("--position-source", choices=("mocap", "gnss"), default=None,
                    help="what the firmware's estimator positions by: motion capture as external vision (the "
                         "paper's laboratory, default) or GNSS")
    ap.add_argument("--instance", type=int, default=0, help="firmware instance N: its ports move by N (PX4) or 10 N "
                                                            "(ArduCopter)")
    ap.add_argument("--firmware-param", action="append", default=[], metavar="NAME=VALUE",
                    help="set one of the firmware's own parameters at boot, on top of the airframe "
                         "(e.g. MPC_TILTMAX_AIR=60; repeatable)")


def firmware_scenario(scenario: Scenario, layout: str | None, position_source: str | None) -> Scenario:
    """The scenario with the firmware's defaults: an "x" layout unless asked otherwise."""
    v = scenario.vehicle
    vehicle = VehicleParams(**{**v.__dict__, "layout": layout or DEFAULT_LAYOUT})
    nav = scenario.nav_sensors
    if position_source is not None:
        nav = NavSensorParams(**{**nav.__dict__, "position_source": position_source})
    return scenario.with_changes(vehicle=vehicle, nav_sensors=nav)


class Session:
    """A firmware process and the bridge that flies it; :meth:`close` stops and removes both."""

    def __init__(self, firmware: str, build: Path, scenario: Scenario, seed: int, origin: GeoOrigin,
                 speedup: float, lockstep_period_s: float, instance: int = 0,
                 params: list[tuple[str, float]] | None = None, keep_workdir: bool = False,
                 firmware_params: dict[str, float] | None = None, signing_key: bytes | None = None) -> None:
        self.firmware = firmware
        self.keep_workdir = keep_workdir
        self.workdir = Path(tempfile.mkdtemp(prefix=f"ismdo-{firmware}-"))
        self.world = world = FirmwareWorld(scenario, seed, origin)
        table = build_plant_parameters(world.vehicle, lambda text: None, ESTIMATE_ONLY)
        for name, value in params or []:
            reason = table.set(name, value)
            if reason is not None:
                raise ValueError(f"--param {name}: {reason}")
        component = PlantComponent(world.vehicle, estimator_origin(origin, firmware),
                                   set_origin=scenario.nav_sensors.position_source == "mocap")
        lead = lockstep_period_s + TELEMETRY_INTERVAL_S + 0.005 if lockstep_period_s > 0 else 0.0
        gate = CompanionGate(lead)
        pace = Pace(speedup)
        vision = scenario.nav_sensors.position_source == "mocap"
        local = (PLANT_COMPID, component.receive)
        """the companion's link reaches the plant's component directly (a ground station through
        the firmware's forwarding)"""
        self.bridge: Bridge
        self.process: Px4Process | ArduPilotProcess
        if firmware == "px4":
            ports = Px4Ports(instance)
            relay: UdpRelay | TcpRelay = UdpRelay(("127.0.0.1", ports.relay), ("127.0.0.1", ports.companion),
                                                  gate.setpoint, gate.telemetry, local, gate.heartbeat)
            plant = PlantSocket(ports.plant, ("127.0.0.1", ports.plant_firmware))
            self.bridge = Px4Bridge(world, component, plant, relay, gate, pace, ports=ports, vision=vision)
            self.process = Px4Process(build, ports, px4_parameters(scenario) | (firmware_params or {}), self.workdir)
            self.ports: dict[str, str] = {
                "companion": f"udpin://0.0.0.0:{ports.companion}", "ground station": f"udp 14550 (from {ports.gcs})",
                "simulator": f"tcp 127.0.0.1:{ports.simulator}"}
        else:
            aports = ArduPilotPorts(instance)
            relay = TcpRelay(("127.0.0.1", aports.companion), ("127.0.0.1", aports.serial0), gate.setpoint,
                             gate.telemetry, local, gate.heartbeat)
            plant = PlantSocket(aports.plant)
            self.bridge = ArduPilotBridge(world, component, plant, relay, gate, pace, ports=aports, vision=vision)
            home = f"{origin.lat_deg},{origin.lon_deg},{origin.alt_m},0"
            self.process = ArduPilotProcess(build, aports, ardupilot_parameters(scenario) | (firmware_params or {}),
                                            self.workdir, home)
            self.ports = {"companion": f"tcp://127.0.0.1:{aports.companion}",
                          "simulator": f"udp 127.0.0.1:{aports.json} (JSON)"}
        relay.on_command = gate.command
        if signing_key is not None:
            relay.signing = SignedLink(signing_key)
        self.process.start()

    def run(self, stop: Any, duration_s: float | None = None) -> None:
        last_check = [0.0]

        def stopped() -> bool:
            now = time.monotonic()
            if now - last_check[0] > 0.5:
                last_check[0] = now
                if not self.process.alive():
                    return True
            return bool(stop())
        self.bridge.run(stopped, duration_s)

    def close(self) -> None:
        self.process.stop()
        self.bridge.close()
        if not self.keep_workdir:
            shutil.rmtree(self.workdir, ignore_errors=True)


def run(args: argparse.Namespace, scenario: Scenario, origin: GeoOrigin) -> int:
    """``sitl --firmware``: start, serve until Ctrl-C (or ``--duration``), stop both."""
    if args.firmware == "px4" and not 0 <= args.instance <= PX4_MAX_INSTANCE:
        print(f"sitl: error: --instance {args.instance}: PX4's instances are 0-{PX4_MAX_INSTANCE} (its MAVLink "
              f"links move with the instance only that far)", file=sys.stderr)
        return 2
    find = px4_build if args.firmware == "px4" else arducopter_binary
    build, why = find(args.firmware_path)
    if build is None:
        print(f"sitl: error: {why}", file=sys.stderr)
        return 2
    scenario = firmware_scenario(scenario, args.layout, args.position_source)
    stop = {"now": False}

    def on_signal(signum: int, frame: object) -> None:
        stop["now"] = True
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    try:
        firmware_params = dict(parse_firmware_param(text) for text in args.firmware_param)
        session = Session(args.firmware, build, scenario, args.seed, origin, args.speedup,
                          args.lockstep * 1e-3, args.instance, args.param, firmware_params=firmware_params,
                          signing_key=signing_key(args, "sitl"))
    except (OSError, ValueError) as exc:
        print(f"sitl: error: {exc}", file=sys.stderr)
        return 2
    try:
        if not args.quiet:
            where = ", ".join(f"{k} {v}" for k, v in session.ports.items())
            print(f"sitl: {args.firmware} ({build}) flying the plant ({scenario.name}, {scenario.vehicle.layout}, "
                  f"{scenario.nav_sensors.position_source}), speed-up {args.speedup:g}x"
                  f"{', lockstep' if args.lockstep else ''}: {where}; plant parameters: component 25", flush=True)
        session.run(lambda: stop["now"], args.duration)
        alive = session.process.alive()
    finally:
        session.close()
    report = session.bridge.report()
    report["firmware_exited"] = not alive
    print(f"sitl: stopped {json.dumps(report)}", flush=True)
    if not alive and not stop["now"] and (args.duration is None or session.world.t < args.duration):
        print(f"sitl: error: {args.firmware} exited (its log: {session.process.log})", file=sys.stderr)
        return 1
    return 0


def parse_firmware_param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep or not name or len(name) > 16 or not name.replace("_", "").isalnum():
        raise ValueError(f"--firmware-param {text!r}: expected NAME=NUMBER")
    try:
        number = float(value)
    except ValueError:
        raise ValueError(f"--firmware-param {text!r}: {value!r} is not a number") from None
    if number != number or number in (float("inf"), float("-inf")):
        raise ValueError(f"--firmware-param {text!r}: not a finite number")
    return name, number
