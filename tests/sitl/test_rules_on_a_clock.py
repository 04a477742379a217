"""The autopilot's timing rules on a clock: readings built by hand, no plant flown.

The rules (:class:`~sitl.autopilot.logic.Autopilot`) read the vehicle only as a
:class:`~sitl.autopilot.sensed.Sensed` record, so a vehicle "hovering at 2 m" or "resting on the
ground" is a reading, and every timeout can be checked to the plant step at which it fires.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control import quaternion as quat
from companion.control.vector import ZERO3
from sitl.autopilot.logic import Autopilot, AutopilotParams, Failsafe, MavResult, Mode
from sitl.autopilot.sensed import Sensed
from sitl.plant.scenario import Scenario
from sitl.plant.sensors import ImuSample, MocapSample
from sitl.plant.vehicle import SimVehicle

G = 9.81
THRUST = 0.5
"""a normalised thrust: what the stream sends (its value is no rule's business)"""


class Clock:
    """Runs the rules step by step on readings of a vehicle at ``height_m``, still and level,
    its tracking ``tracked_age_s`` old (the plant step count is kept as an integer: exact times)."""

    def __init__(self, start_s: float = 1.2, **params: object) -> None:
        self.ap = Autopilot(SimVehicle(Scenario(name="unit"), "ism_do", 1, ZERO3, 0.0, hovering=False),
                            AutopilotParams(**params))  # type: ignore[arg-type]
        self.dt = self.ap.dt
        self.k = round(start_s / self.dt)
        self.height_m = 0.0
        self.lost_at_s: float | None = None
        self.ap.observe(self.reading(self.k * self.dt))

    def reading(self, t: float) -> Sensed:
        age = 0.0 if self.lost_at_s is None else t - self.lost_at_s
        pos = (0.0, 0.0, -self.height_m)
        tracked = MocapSample(t - age, pos, ZERO3, ZERO3, quat.IDENTITY)
        return Sensed(t, tracked, quat.IDENTITY, ImuSample(ZERO3, (0.0, 0.0, -G)), age, None)

    def step(self) -> None:
        self.ap.decide(self.reading(self.k * self.dt))
        self.k += 1
        self.ap.observe(self.reading(self.k * self.dt))

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / self.dt)):
            self.step()

    def until(self, changed, within_s: float) -> float:
        """Step until ``changed()``; the time the rules decided it (the start of that step)."""
        for _ in range(round(within_s / self.dt)):
            decided_at = self.ap.t
            self.step()
            if changed():
                return decided_at
        raise AssertionError(f"nothing changed within {within_s} s")

    def fired_on_time(self, elapsed_s: float, delay_s: float) -> bool:
        """A rule "after ``delay_s``" fires at the first step past it: never a step early, at most one
        late (the clock's float sums make "past" and "at" one step)."""
        return delay_s - 1e-9 < elapsed_s <= delay_s + self.dt + 1e-9

    def stream(self, seconds: float, sender: int = 255) -> float:
        """Attitude targets every 20 ms for ``seconds``; the time of the last one."""
        for _ in range(round(seconds / 0.02)):
            assert self.ap.attitude_target(sender, 0, quat.IDENTITY, ZERO3, THRUST) is None
            last = self.ap.t
            self.run(0.02)
        return last

    def hovering(self) -> None:
        """Armed, in the air at 2 m (the reading says so; nothing flew there)."""
        assert self.ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)).result == MavResult.ACCEPTED
        self.height_m = 2.0
        self.run(0.1)
        assert not self.ap.landed and self.ap.lifted_off


def test_arming_waits_for_the_estimator_to_settle_one_second_after_boot():
    c = Clock(start_s=0.0)
    arm = (mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,))
    assert c.ap.command(*arm).result == MavResult.TEMPORARILY_REJECTED
    c.run(0.999)
    assert c.ap.command(*arm).result == MavResult.TEMPORARILY_REJECTED
    c.run(0.002)
    assert c.ap.command(*arm).result == MavResult.ACCEPTED


def test_px4_descends_one_loss_timeout_after_the_last_offboard_setpoint():
    c = Clock()
    c.hovering()
    c.stream(0.04)
    assert c.ap.set_mode(Mode.OFFBOARD).result == MavResult.ACCEPTED
    last = c.stream(1.0)
    at = c.until(lambda: c.ap.mode != Mode.OFFBOARD, within_s=2.0)
    assert c.fired_on_time(at - last, c.ap.params.offboard_loss_timeout_s)
    assert c.ap.mode == Mode.LAND and c.ap.failsafe == Failsafe.OFFBOARD_LOST_DESCENDING


def test_with_hold_on_loss_it_holds_then_lands_after_the_hold_time():
    c = Clock(offboard_loss_hold=True)
    c.hovering()
    c.stream(0.04)
    c.ap.set_mode(Mode.OFFBOARD)
    last = c.stream(0.5)
    at = c.until(lambda: c.ap.mode == Mode.HOLD, within_s=2.0)
    assert c.fired_on_time(at - last, 1.0) and c.ap.failsafe == Failsafe.OFFBOARD_LOST
    landing = c.until(lambda: c.ap.mode == Mode.LAND, within_s=6.0)
    assert c.fired_on_time(landing - c.ap.failsafe_time, c.ap.params.failsafe_hold_s)
    assert c.ap.failsafe == Failsafe.OFFBOARD_LOST_LANDING



def test_a_mode_change_by_the_operator_ends_the_failsafe():
    c = Clock()
    c.hovering()
    c.stream(0.04)
    c.ap.set_mode(Mode.OFFBOARD)
    c.stream(0.5)
    c.until(lambda: c.ap.mode == Mode.LAND, within_s=2.0)
    assert c.ap.failsafe == Failsafe.OFFBOARD_LOST_DESCENDING  # PX4 v1.16 without RC: descends at once
    assert c.ap.set_mode(Mode.HOLD).result == MavResult.ACCEPTED and c.ap.failsafe is None
    c.run(8.0)
    assert c.ap.mode == Mode.HOLD and c.ap.armed  # no landing: the operator took over


def test_position_lost_in_the_air_descends_blind_after_half_a_second_and_lands_on_it_once_back():
    c = Clock()
    c.hovering()
    c.lost_at_s = c.ap.t
    at = c.until(lambda: c.ap.failsafe is not None, within_s=1.0)
    assert c.fired_on_time(at - c.lost_at_s, Autopilot.POSITION_TIMEOUT_S)
    assert c.ap.mode == Mode.LAND and c.ap.failsafe == Failsafe.POSITION_LOST
    assert c.ap.set_mode(Mode.HOLD).result == MavResult.DENIED  # only landing, while blind
    c.run(0.2)
    c.lost_at_s = None
    c.step()
    assert c.ap.failsafe == Failsafe.POSITION_LOST_LANDING and c.ap.mode == Mode.LAND


def test_disarms_the_land_delay_after_touch_down_and_the_preflight_delay_after_arming_without_take_off():
    c = Clock()
    c.hovering()
    c.height_m = 0.0
    c.until(lambda: c.ap.landed, within_s=0.1)
    off = c.until(lambda: not c.ap.armed, within_s=3.0)
    assert c.fired_on_time(off - c.ap.touchdown_time, c.ap.params.disarm_land_s)
    assert "Landed, disarmed" in c.ap.messages[-1][1]

    c = Clock(disarm_preflight_s=3.0)
    c.ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,))
    armed = c.ap.t
    off = c.until(lambda: not c.ap.armed, within_s=4.0)
    assert c.fired_on_time(off - armed, 3.0) and "no take-off" in c.ap.messages[-1][1]
