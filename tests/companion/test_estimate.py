"""``companion estimate``: the external force over a logged flight, against forces that are known.

1. The project's own vehicle (the offline simulation of E5: a 6 N force on for 20 s), written as
   a flight record CSV: true attitude and velocity, the commanded thrust in newtons, and the true
   external force. Also written again in ROS conventions (ENU, FLU, scalar-last) to check the
   converters: the same force must come out.
2. A real PX4 v1.16 SIH flight (tests/data/px4_sih_drag.ulg, made with a throwaway pymavlink
   script: take-off, 12 m north and back, land; SIH_KDV = 1 N/(m/s), so the only external force
   in the air is the drag -KDV v, up to 3.5 N). Mass, thrust scale and rotor lag are read from
   the log's own parameters (SIH_MASS, SIH_T_MAX, SIH_T_TAU).

The estimate is the observer's first-order low-pass (Gamma) of the true force, so it is compared
with the truth through that same low-pass.
"""

import csv
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest

from companion.cli import main
from companion.estimate import ThrustScale, estimate_force
from companion.logs import read_csv, read_ulog

ULOG = Path(__file__).resolve().parents[1] / "data" / "px4_sih_drag.ulg"
GAMMA = 5.0


def lowpass(t, x, gamma=GAMMA):
    """What the observer does to the true force: h_hat' = Gamma (h - h_hat), h held per sample."""
    out = np.zeros_like(x)
    for k in range(1, len(t)):
        a = 1.0 - math.exp(-gamma * (t[k] - t[k - 1]))
        out[k] = out[k - 1] + a * (x[k - 1] - out[k - 1])
    return out


@pytest.fixture(scope="module")
def e5_record(tmp_path_factory):
    from sitl.plant.scenario import load_scenario
    from sitl.lab.simulation import simulate

    sc = load_scenario("E5_suspended_weight").with_changes(duration_s=30.0, log_rate_hz=100.0)
    path = tmp_path_factory.mktemp("e5") / "e5_flight.csv"
    simulate(sc, "ism_do", "ism_do", 3).to_csv(str(path))
    return path


def read_estimate(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    est = np.array([[float(r[f"force_{a}_n"]) for a in ("north", "east", "down")] for r in rows])
    truth = np.array([[float(r[f"truth_{a}_n"]) for a in ("north", "east", "down")] for r in rows])
    return np.array([float(r["t_s"]) for r in rows]), est, truth


def test_the_known_force_of_a_simulated_flight_is_recovered(e5_record, tmp_path):
    """Against the truth through the observer's own low-pass, RMS below 0.1 N on each axis: what
    is left is the thrust the log cannot know exactly (the record holds the requested thrust; the
    rotors apply it 8-bit quantised, ~0.02 N per rotor step, and 20 ms late) and the velocity's
    rounding. While the 6 N acts, its mean is within 2 %."""
    assert main(["estimate", str(e5_record), "--columns", "sitl", "--mass", "0.63", "--gamma", str(GAMMA),
                 "--out", str(tmp_path)]) == 0
    t, est, truth = read_estimate(tmp_path / "e5_flight_force.csv")
    assert (tmp_path / "e5_flight_force.png").stat().st_size > 10_000
    err = est - lowpass(t, truth)
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) < 0.1), np.sqrt(np.mean(err**2, axis=0))
    held = (t > 8.0) & (t < 22.0)
    assert est[held, 0].mean() == pytest.approx(6.0, rel=0.02)


def test_scalar_last_quaternions_are_reordered():
    from companion.estimate import quat_from_scalar_last

    np.testing.assert_array_equal(quat_from_scalar_last(np.array([[0.1, 0.2, 0.3, 0.9]])), [[0.9, 0.1, 0.2, 0.3]])


def test_ros_conventions_give_the_same_force(e5_record, tmp_path):
    """The same flight as a ROS user would log it: ENU world, FLU body, quaternion scalar-last.
    Converted back (enu_to_ned, flu_to_frd, quat_enu_flu_to_ned_frd), the estimate is the same."""
    with open(e5_record) as f:
        rows = list(csv.DictReader(f))
    ros = tmp_path / "ros.csv"
    with open(ros, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time", "qx", "qy", "qz", "qw", "vel_e", "vel_n", "vel_u", "thrust_n"])
        for r in rows:
            q_ned = np.array([float(r[c]) for c in ("qw", "qx", "qy", "qz")])
            # q_enu_flu = q_enu_ned * q_ned_frd * q_frd_flu: (w, x, y, z) -> (w, y, x, -z) then x
            # stays, y, z flip: the closed form of the two frame changes
            w_, x, y, z = q_ned
            s2 = math.sqrt(0.5)
            q_enu_ned = (0.0, s2, s2, 0.0)
            q_frd_flu = (0.0, 1.0, 0.0, 0.0)
            from companion.control import quaternion as quat

            q_ros = quat.mul(quat.mul(q_enu_ned, (w_, x, y, z)), q_frd_flu)
            w.writerow([r["t"], q_ros[1], q_ros[2], q_ros[3], q_ros[0], r["vy"], r["vx"], -float(r["vz"]),
                        r["thrust_sp"]])
    cols = {"t": "time", "qw": "qw", "qx": "qx", "qy": "qy", "qz": "qz", "vx": "vel_e", "vy": "vel_n",
            "vz": "vel_u", "thrust": "thrust_n"}
    series = read_csv(ros, cols, thrust_is_newtons=True, world_frame="enu", body_frame="flu")
    same = read_csv(e5_record, {"t": "t", "qw": "qw", "qx": "qx", "qy": "qy", "qz": "qz", "vx": "vx", "vy": "vy",
                                "vz": "vz", "thrust": "thrust_sp"}, thrust_is_newtons=True)
    a = estimate_force(series, 0.63, GAMMA).force_ned_n
    b = estimate_force(same, 0.63, GAMMA).force_ned_n
    np.testing.assert_allclose(a, b, atol=1e-3)


@pytest.mark.skipif(not ULOG.exists(), reason="no PX4 SITL ULog in tests/data")
def test_the_drag_of_a_real_px4_sitl_flight_is_recovered_from_its_ulog(tmp_path):
    """The only external force on the SIH quad in the air is its drag -SIH_KDV v (SIH's model).
    With the log's own mass, thrust scale (SIH_T_MAX per motor, motor commands summed) and rotor
    lag (SIH_T_TAU), the estimate from the accelerometer matches the drag through the observer's
    low-pass: RMS below 0.3 N north (the flight direction, where the drag reaches 3.5 N) and
    0.5 N east and down. What is left is the EKF's attitude error (1 deg of tilt is 0.17 N of
    the 9.8 N of thrust sideways) and PX4's own thrust handling."""
    from pyulog import ULog

    params = ULog(str(ULOG), ["vehicle_attitude"]).initial_parameters
    series = read_ulog(ULOG)
    est = estimate_force(series, params["SIH_MASS"], GAMMA, ThrustScale(params["SIH_T_MAX"], per_motor=True),
                         "accelerometer", params["SIH_T_TAU"])
    drag = -params["SIH_KDV"] * series.vel_ned_m_s
    expected = lowpass(series.t_s, drag)
    ulog = ULog(str(ULOG), ["vehicle_local_position", "sensor_combined"])
    data = {d.name: d.data for d in ulog.data_list}
    t0 = float(data["sensor_combined"]["timestamp"][0])
    z = np.interp(series.t_s, (data["vehicle_local_position"]["timestamp"].astype(float) - t0) * 1e-6,
                  data["vehicle_local_position"]["z"].astype(float))
    air = (z < -1.0) & (series.thrust > 0.5)
    assert air.sum() > 1000 and np.abs(drag[air, 0]).max() > 2.0  # it did fly, and fast enough
    rms = np.sqrt(np.mean((est.force_ned_n[air] - expected[air]) ** 2, axis=0))
    assert rms[0] < 0.3 and rms[1] < 0.5 and rms[2] < 0.5, rms
    assert np.corrcoef(est.force_ned_n[air, 0], expected[air, 0])[0, 1] > 0.95


def test_the_cli_reads_the_px4_ulog_and_estimates_the_thrust_scale(tmp_path, capsys):
    """Without a thrust scale the CLI finds one that makes the mean vertical force zero, fitted
    only where the vehicle flies (0.5 m above where the log starts): within 1 % of SIH_T_MAX per
    motor (4.99 N for 5 N; fitted over every sample with thrust, the ground run-up before take-off
    made it 5.19 N, 3.9 % off). It is printed per motor and in total: the log's thrust is the sum
    of 4 motors' commands."""
    if not ULOG.exists():
        pytest.skip("no PX4 SITL ULog in tests/data")
    assert main(["estimate", str(ULOG), "--mass", "1.0", "--out", str(tmp_path)]) == 0
    from companion.estimate import estimate_thrust_scale

    per_motor = estimate_thrust_scale(read_ulog(ULOG), 1.0)
    assert per_motor == pytest.approx(5.0, rel=0.01)
    out = capsys.readouterr().out
    assert f"{4 * per_motor:.3f} N total = {per_motor:.3f} N per motor x 4" in out, out


HEADER = "t,qw,qx,qy,qz,ax,ay,az,thrust\n"
COLUMNS = "t=t,qw=qw,qx=qx,qy=qy,qz=qz,ax=ax,ay=ay,az=az,thrust=thrust"


def _hover_rows(n: int, dt: float = 0.01) -> list[str]:
    return [f"{k * dt:.3f},1,0,0,0,0,0,-9.81,0.333" for k in range(n)]


@pytest.mark.parametrize("name, content, says", [
    ("empty.ulg", b"", "the file is empty"),
    ("random.ulg", bytes(range(256)) * 12, "cannot be read"),
    ("random.bin", bytes(range(256)) * 12, "no ATT (attitude) messages"),
    ("random.tlog", bytes(range(256)) * 12, "no messages from an autopilot"),
    ("short.csv", (HEADER + "\n".join(_hover_rows(5)) + "\n0.05,1,0,0,0,0,0,-9.81\n").encode(),
     "row 7, column 'thrust': missing (the row is cut short)"),
    ("nan.csv", (HEADER + "\n".join(_hover_rows(5)) + "\n0.05,1,0,0,0,nan,0,-9.81,0.3\n").encode(),
     "row 7, column 'ax': 'nan' is not a finite number"),
    ("inf.csv", (HEADER + "\n".join(_hover_rows(5)) + "\n0.05,1,0,0,0,0,0,-9.81,inf\n").encode(),
     "row 7, column 'thrust': 'inf' is not a finite number"),
    ("back.csv", (HEADER + "\n".join(_hover_rows(5)) + "\n0.01,1,0,0,0,0,0,-9.81,0.3\n").encode(),
     "row 7, column 't': time goes backwards (0.01 after 0.04)"),
])
def test_a_log_that_lies_is_refused_in_one_line_naming_where(tmp_path, capsys, name, content, says):
    """Damaged or hostile input: one line naming the file (and the row and column of a CSV), exit
    2 — never a traceback, never an estimate made of NaNs."""
    path = tmp_path / name
    path.write_bytes(content)
    code = main(["estimate", str(path), "--mass", "0.63", "--columns", COLUMNS, "--thrust-scale-total", "18.56",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and says in err[0] and str(path) in err[0], err


def test_a_directory_named_like_a_log_is_refused(tmp_path, capsys):
    (tmp_path / "x.tlog").mkdir()
    assert main(["estimate", str(tmp_path / "x.tlog"), "--mass", "0.63"]) == 2
    assert "is a directory" in capsys.readouterr().err


@pytest.mark.parametrize("option, value", [("--mass", "nan"), ("--mass", "-1"), ("--mass", "0"), ("--gamma", "0"),
                                           ("--thrust-scale-total", "0"), ("--thrust-scale-per-motor", "-1"),
                                           ("--motor-tau", "-0.1")])
def test_impossible_numbers_are_refused(tmp_path, capsys, option, value):
    args = ["estimate", str(tmp_path / "x.csv"), "--mass", "0.63", option, value]
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2 and option in capsys.readouterr().err


def test_repeated_stamps_are_no_new_information_not_a_division_by_zero(tmp_path):
    """A vehicle that waits repeats its stamps (the bundled vehicle's .tlog does): the observer
    holds its estimate over a zero step (it divided by zero before)."""
    rows = _hover_rows(200)
    rows = rows[:100] + [rows[99]] * 3 + rows[100:]
    path = tmp_path / "repeat.csv"
    path.write_text(HEADER + "\n".join(rows) + "\n")
    est = estimate_force(read_csv(path, dict(p.split("=") for p in COLUMNS.split(","))), 0.63, 5.0,
                         ThrustScale(18.56, per_motor=False))
    assert np.all(np.isfinite(est.force_ned_n))


# --- the logs people have: ArduPilot, PX4 before 1.13, logs that never flew -------------------------

DATA = Path(__file__).resolve().parents[1] / "data"
_TLOGS = Path(tempfile.mkdtemp(prefix="tlogs-"))


def data_file(name: str) -> Path:
    """A file of tests/data; the ground-station .tlogs are kept there as hex text (``NAME.hex``,
    recorded by tests/data/make_logs.py) and written out as the bytes a ground station saved."""
    path = DATA / name
    if path.exists():
        return path
    out = _TLOGS / name
    if not out.exists():
        out.write_bytes(bytes.fromhex("".join((DATA / f"{name}.hex").read_text().split())))
    return out
STEP_N = 2.0
"""the plant's SIM_FORCE_X in arducopter_force_step.*: north, the only external force in calm air
while the vehicle holds its point (drag needs speed)"""


def force_step_times(tlog):
    """(on, off) on the vehicle's clock: the plant's PARAM_VALUE answers to the ground station's
    SIM_FORCE_X, dated by the newest stamp of the autopilot before them."""
    from pymavlink import mavutil

    m, stamp, times = mavutil.mavlink_connection(str(tlog)), None, {}
    while (msg := m.recv_match()) is not None:
        if msg.get_srcComponent() == 1 and hasattr(msg, "time_boot_ms"):
            stamp = msg.time_boot_ms * 1e-3
        if msg.get_type() == "PARAM_VALUE" and msg.param_id == "SIM_FORCE_X":
            times[msg.param_value] = stamp
    return times[STEP_N], times[0.0]


def first_stamp(path):
    """The log's own clock at its first sample (t_s = 0)."""
    from pymavlink import DFReader, mavutil

    if path.suffix == ".bin":
        return DFReader.DFReader_binary(str(path)).recv_match(type="IMU").TimeUS * 1e-6
    m = mavutil.mavlink_connection(str(path))
    return m.recv_match(type="LOCAL_POSITION_NED").time_boot_ms * 1e-3


@pytest.mark.parametrize("name", ["arducopter_force_step.bin", "arducopter_force_step.tlog"])
def test_arducopter_logs_recover_the_known_step_force(tmp_path, capsys, name):
    """ArduCopter 4.8 SITL flying the plant, hovering in GUIDED while the plant pushes 2 N north for
    8.3 s: from its DataFlash log (ATT in degrees, IMU, XKF1, CTUN.ThO at 10-25 Hz) and from a ground
    station's .tlog (ATTITUDE Euler, RAW_IMU in milli-g, VFR_HUD throttle in per cent, at 10 Hz), with
    the thrust scale estimated. While the force acts (from 1 s = 5 observer time constants after it
    starts) the mean north estimate is 2 N within 0.15 N (1.4 deg of tilt of the 6.2 N weight: the
    EKF's attitude and the per-cent throttle are finer than that, while a frame, sign or unit error
    is a force east, -2 N or a factor 100); before and after it, while flying, within 0.15 N of
    zero; east within 0.1 N throughout. The airborne column is ArduPilot's own land detector."""
    log = data_file(name)
    on, off = force_step_times(data_file("arducopter_force_step.tlog"))
    assert main(["estimate", str(log), "--mass", "0.63", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "estimated" in out and "4 motors" not in out and "N per motor x 4" in out, out
    with open(tmp_path / f"{log.stem}_force.csv") as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["t_s"]) for r in rows]) + first_stamp(log)
    north = np.array([float(r["force_north_n"]) for r in rows])
    east = np.array([float(r["force_east_n"]) for r in rows])
    air = np.array([r["airborne"] == "1" for r in rows])
    acting = (t > on + 1.0) & (t < off)
    before = air & (t > on - 5.0) & (t < on)
    after = air & (t > off + 1.0) & (t < off + 5.0)
    assert acting.sum() > 60 and before.sum() > 30 and after.sum() > 30
    assert north[acting].mean() == pytest.approx(STEP_N, abs=0.15)
    assert abs(north[before].mean()) < 0.15 and abs(north[after].mean()) < 0.15
    assert np.abs(east[air & (t > on - 5.0) & (t < off + 5.0)]).max() < 0.1
    assert air[(t > on - 5.0) & (t < off + 5.0)].all() and not air[0] and not air[-1]


@pytest.mark.parametrize("name, why", [
    ("arducopter_ground.bin", "ArduCopter's land detector (EV events) says landed throughout"),
    ("arducopter_ground.tlog", "HEARTBEAT.system_status says landed throughout"),
    ("arducopter_ground_throttle.bin", "never climbs 0.5 m"),
    ("arducopter_ground_throttle.tlog", "never climbs 0.5 m"),
    ("pyulog_sample_log_small.ulg", "never climbs 0.5 m"),
])
def test_a_log_that_never_leaves_the_ground_is_refused(tmp_path, capsys, name, why):
    """Armed on the ground (ArduCopter), a quarter of the throttle on the ground (ArduCopter's land
    detector says flying: 0.09 of full thrust holds the ground's reaction), PX4 1.11 spooling up at
    boot (its land detector says flying for 1.1 s, its height sinks 1 m): one line, exit 2, never a
    thrust scale of the weight over an idle thrust."""
    code = main(["estimate", str(data_file(name)), "--mass", "0.63", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "never airborne" in err[0] and why in err[0], err


def test_a_csv_whose_landed_column_says_landed_throughout_is_refused(tmp_path, capsys):
    """A CSV maps its land detector as ``landed``: landed throughout is refused, where the thrust
    alone (a third of full, steady, the accelerometer at -g) would fit a confident 18.6 N scale."""
    rows = [r + ",1" for r in _hover_rows(300)]
    path = tmp_path / "ground.csv"
    path.write_text(HEADER.strip() + ",landed\n" + "\n".join(rows) + "\n")
    code = main(["estimate", str(path), "--mass", "0.63", "--columns", COLUMNS + ",landed=landed",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "never airborne: column 'landed' says landed throughout" in err, err


def test_pre_1_13_px4_ulogs_take_the_thrust_from_actuator_controls_0():
    """PX4 before 1.13 logs the collective thrust as actuator_controls_0.control[3] (no
    actuator_motors, no vehicle_thrust_setpoint): read onto the accelerometer's stamps, a
    collective (not a sum of motors), the land detector held between its messages."""
    from pyulog import ULog

    series = read_ulog(DATA / "pyulog_sample_log_small.ulg")
    ulog = ULog(str(DATA / "pyulog_sample_log_small.ulg"), ["actuator_controls_0", "sensor_combined",
                                                             "vehicle_land_detected"])
    d = {x.name: x.data for x in ulog.data_list}
    t_imu = d["sensor_combined"]["timestamp"].astype(float)
    want = np.interp(t_imu, d["actuator_controls_0"]["timestamp"].astype(float),
                     d["actuator_controls_0"]["control[3]"].astype(float))
    np.testing.assert_allclose(series.thrust, want)
    assert 0.35 < series.thrust.max() <= d["actuator_controls_0"]["control[3]"].max() == pytest.approx(0.407, abs=1e-3)
    assert not series.thrust_per_motor
    assert "actuator_controls_0" in series.source
    ld = d["vehicle_land_detected"]
    lifted = ld["timestamp"][np.flatnonzero(~ld["landed"].astype(bool))[0]]
    assert not series.airborne[t_imu < lifted].any() and series.airborne[t_imu >= lifted][0]


def test_the_thrust_scale_is_given_total_or_per_motor_and_the_bare_option_is_refused(tmp_path, capsys):
    """A ULog's thrust is the sum of 4 motor commands, an ArduCopter log's the collective: 5 N per
    motor and 20 N total are the same scale for both, and give the same force; the old
    ``--thrust-scale`` (which did not say which) is refused naming both."""
    for log, stem in ((ULOG, "px4_sih_drag"), (DATA / "arducopter_force_step.bin", "arducopter_force_step")):
        forces = []
        for option, value in (("--thrust-scale-per-motor", "5"), ("--thrust-scale-total", "20")):
            out = tmp_path / option
            assert main(["estimate", str(log), "--mass", "0.63", option, value, "--out", str(out)]) == 0
            printed = capsys.readouterr().out
            assert "20.000 N total = 5.000 N per motor x 4" in printed and "estimated" not in printed, printed
            forces.append(np.loadtxt(out / f"{stem}_force.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3)))
        np.testing.assert_allclose(forces[0], forces[1], atol=1e-3)
    with pytest.raises(SystemExit) as exc:
        main(["estimate", str(ULOG), "--mass", "0.63", "--thrust-scale", "5"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "--thrust-scale-total" in err and "--thrust-scale-per-motor" in err, err


def test_a_per_motor_scale_needs_the_logs_motor_count():
    """PX4 1.11's VTOL (MAV_TYPE 22) does not say how many rotors lift it: a per-motor scale is
    refused with the fix, a total one taken as it is."""
    from companion.estimate import series_thrust_scale

    series = read_ulog(DATA / "pyulog_sample_log_small.ulg")
    assert series.motor_count is None
    assert series_thrust_scale(series, ThrustScale(20.0, per_motor=False)) == 20.0
    with pytest.raises(ValueError, match="does not say how many motors.*give it total"):
        series_thrust_scale(series, ThrustScale(5.0, per_motor=True))


def test_a_wide_csv_costs_memory_for_the_mapped_columns_only(tmp_path):
    """The lab's records have 53 columns; the sitl map reads 13. Reading keeps 8 bytes per mapped
    cell (and the arrays made of them): the peak of Python's allocations while reading 10 000 rows
    stays under 8 times the mapped cells' bytes (0.96 MB; 2.8 MB measured). Read as a list of
    dicts, every cell of every row was a string in a dict: 50 MB here, 811 MB of resident memory
    for a 25-minute record (benchmarks/bench_estimate_memory.py)."""
    import tracemalloc

    from sitl.plant.kernel import LOG_COLUMNS

    from companion.logs import SITL_COLUMNS, read_log

    rng = np.random.default_rng(1)
    data = rng.normal(0.0, 0.01, size=(10_000, len(LOG_COLUMNS)))
    data[:, LOG_COLUMNS.index("t")] = np.arange(10_000) * 0.01
    data[:, LOG_COLUMNS.index("qw")] += 1.0
    path = tmp_path / "record.csv"
    np.savetxt(path, data, delimiter=",", header=",".join(LOG_COLUMNS), comments="", fmt="%.7g")
    tracemalloc.start()
    try:
        series = read_log(path, "sitl")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(series.t_s) == 10_000
    mapped_bytes = 10_000 * len(SITL_COLUMNS) * 8
    assert peak < 8 * mapped_bytes, (peak, mapped_bytes)


def test_a_fixed_wing_log_is_refused_not_misread(tmp_path, capsys):
    """A fixed wing's thrust is along its nose, not its z axis: its telemetry log (HEARTBEAT type
    FIXED_WING, the rest as a multicopter's) is refused by name instead of estimated."""
    import struct

    from pymavlink.dialects.v20 import common as mavlink

    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    frames = [mav.heartbeat_encode(mavlink.MAV_TYPE_FIXED_WING, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                   mavlink.MAV_STATE_STANDBY)]
    for k in range(50):
        frames += [mav.attitude_quaternion_encode(10 * k, 1, 0, 0, 0, 0, 0, 0),
                   mav.local_position_ned_encode(10 * k, 0, 0, -k * 0.1, 0, 0, -1.0),
                   mav.attitude_target_encode(10 * k, 0, [1, 0, 0, 0], 0, 0, 0, 0.5)]
    path = tmp_path / "plane.tlog"
    with open(path, "wb") as f:
        for k, msg in enumerate(frames):
            f.write(struct.pack(">Q", 1_700_000_000_000_000 + 10_000 * k) + msg.pack(mav))
    assert main(["estimate", str(path), "--mass", "1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "type 1 is not a multicopter" in err[0], err
