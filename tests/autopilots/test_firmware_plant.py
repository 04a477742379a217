"""The real firmware flying the project's plant (``sitl --firmware``), with the paper's disturbances:
PX4 v1.16 through its simulator MAVLink API and ArduCopter through its JSON interface, in lockstep
with the plant and with the companion, so a busy host changes how long these take, not what they
measure.

Bounds come from the physics and from the autopilot's own position control flown in the same
boot (``--controller autopilot``: the same mission and reference as position targets):

- the 6 N weight (hover45, the paper's Fig. 10) needs a tilt of atan(6 / (0.63 * 9.81)) = 44.2 deg
  to be held; the companion's ISM+DO must hold it there, estimate the force, and keep its peak and
  RMS error at most half of the autopilot's own (the figure this project publishes);
- after the release (E5) it must be back within 5 cm;
- a motor losing 20 % of its thrust in a hover costs 5 % of the weight and an unbalanced moment:
  held within 0.15 m (what a loop without disturbance rejection settles at, F / (m w_c^2) =
  0.31 / (0.63 * 1.5^2) = 0.22 m, less a margin) and 10 deg.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.plots import load_timeseries
from companion.vehicle_process import FirmwareVehicle
from helpers.firmware import worker_instance
from sitl.firmware.builds import arducopter_binary, px4_build

from .conftest import segments

pytestmark = [pytest.mark.autopilot, pytest.mark.integration, pytest.mark.xdist_group("firmware_plant")]
"""one worker takes all of this module's tests (``--dist loadgroup``), so its flights are flown once"""

SPEEDUP = 20.0
"""the upper bound; lockstep with the companion sets the pace (7-11x measured on two cores)"""
WEIGHT_N, MASS_KG, G = 6.0, 0.63, 9.81
TILT_LIMIT = {"px4": "MPC_TILTMAX_AIR", "ardupilot": "ATC_ANGLE_MAX"}
"""the autopilot's own tilt limit, raised to the mission's 60 deg: at their defaults (45 and 30 deg)
neither can hold the weight at all, ArduCopter is carried out of the safety volume"""
TILT_45_DEG = math.degrees(math.atan(WEIGHT_N / (MASS_KG * G)))


def _found(firmware: str) -> None:
    build, why = (px4_build if firmware == "px4" else arducopter_binary)()
    if build is None:
        pytest.skip(why)


def fly(companion, vehicle: FirmwareVehicle, mission: str, *args: str) -> dict:  # type: ignore[no-untyped-def]
    c = companion(mission, vehicle.url, "--connect-timeout", "120", *args)
    code, out = c.finish(timeout=600)
    assert code == 0, out
    seg = segments(c.flight_dir())
    seg["_folder"] = c.flight_dir()
    return seg


def tilt_deg(folder, t0: float, t1: float) -> np.ndarray:  # type: ignore[no-untyped-def]
    d = load_timeseries(folder)
    keep = (d["t"] >= t0) & (d["t"] <= t1)
    s = np.sqrt(d["qx"][keep] ** 2 + d["qy"][keep] ** 2)
    c = np.sqrt(d["qw"][keep] ** 2 + d["qz"][keep] ** 2)
    return np.degrees(2 * np.arctan2(s, c))


def error_m(folder, t0: float, t1: float) -> np.ndarray:  # type: ignore[no-untyped-def]
    d = load_timeseries(folder)
    keep = (d["t"] >= t0) & (d["t"] <= t1) & np.isfinite(d["error_m"])
    return d["error_m"][keep]


@pytest.fixture(scope="module", params=["px4", "ardupilot"])
def hover45(request, tmp_path_factory):  # type: ignore[no-untyped-def]
    """One boot per firmware, its tilt limit at the mission's 60 deg: the autopilot's own position
    control flies hover45, then the companion's ISM+DO."""
    firmware = request.param
    _found(firmware)
    from helpers.processes import CompanionProcess

    out = tmp_path_factory.mktemp(f"hover45-{firmware}")
    flights = {}

    def companion(mission: str, url: str, *args: str) -> CompanionProcess:
        return CompanionProcess(mission, url, out, *args)

    vehicle = FirmwareVehicle(firmware, "--firmware-param", f"{TILT_LIMIT[firmware]}=60", speedup=SPEEDUP,
                              instance=worker_instance(2))
    try:
        flights["autopilot"] = fly(companion, vehicle, "missions/hover45.toml", "--controller", "autopilot")
        flights["ism_do"] = fly(companion, vehicle, "missions/hover45.toml")
    finally:
        report = vehicle.stop(timeout_s=30)
    flights["report"] = report
    flights["firmware"] = firmware
    return flights


def test_hover45_holds_45_degrees_against_the_weight(hover45):  # type: ignore[no-untyped-def]
    """With the weight attached the companion's ISM+DO estimates it (6 N within 0.4 N), holds the
    tilt it needs (44.2 deg, within 2.5 deg, over the last 10 s of the 20 s) and the point (RMS
    below 5 cm over those 10 s)."""
    seg = hover45["ism_do"]
    held = seg["45 deg hover"]
    assert held["force_estimate_n"][0] == pytest.approx(WEIGHT_N, abs=0.4), held
    late = (held["t_end"] - 10.0, held["t_end"])
    tilt = tilt_deg(seg["_folder"], *late)
    assert tilt.mean() == pytest.approx(TILT_45_DEG, abs=2.5), (tilt.min(), tilt.mean(), tilt.max())
    e = error_m(seg["_folder"], *late)
    assert math.sqrt(np.mean(e ** 2)) < 0.05, e.max()


def test_ism_do_holds_the_weight_with_at_most_half_the_autopilots_own_error(hover45, record_property):  # type: ignore[no-untyped-def]
    """The same mission, plant, seed and weight, flown by the autopilot's own position control in
    the same boot: ISM+DO's peak and RMS error are at most half of it."""
    own, ours = hover45["autopilot"]["45 deg hover"], hover45["ism_do"]["45 deg hover"]
    figures = {k: (round(ours[k], 3), round(own[k], 3)) for k in ("peak_error_m", "rms_error_m")}
    record_property("hover45_ism_do_vs_autopilot", figures)
    assert ours["peak_error_m"] <= 0.5 * own["peak_error_m"], figures
    assert ours["rms_error_m"] <= 0.5 * own["rms_error_m"], figures


def test_the_release_of_the_weight_is_recovered(hover45):  # type: ignore[no-untyped-def]
    """E5: released, the vehicle swings back and is within 5 cm over the last 5 s of the 15 s."""
    seg = hover45["ism_do"]
    after = seg["after release"]
    e = error_m(seg["_folder"], after["t_end"] - 5.0, after["t_end"])
    assert e.max() < 0.05, (after, e.max())
    assert hover45["report"]["firmware_exited"] is False


@pytest.mark.parametrize("firmware", ["px4", "ardupilot"])
def test_a_motor_losing_20_percent_in_a_hover(firmware, companion):  # type: ignore[no-untyped-def]
    _found(firmware)
    vehicle = FirmwareVehicle(firmware, speedup=SPEEDUP, instance=worker_instance(2))
    try:
        seg = fly(companion, vehicle, "missions/motor_fault.toml")
    finally:
        vehicle.stop(timeout_s=30)
    weak = seg["motor 1 at 80 %"]
    assert weak["peak_error_m"] < 0.15 and weak["peak_tilt_deg"] < 10.0, weak
    assert seg["restored"]["peak_error_m"] < 0.15, seg["restored"]
