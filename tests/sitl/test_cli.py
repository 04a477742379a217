"""Start-up arguments are checked: anything wrong ends with exit status 2 and one line on stderr
naming it, never a traceback; anything right starts the vehicle (here for 1 ms of simulated time)."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sitl.cli import main


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(capsys, *args: str) -> tuple[int, list[str]]:  # type: ignore[no-untyped-def]
    """sitl's exit status and its stderr lines, run for 1 ms of simulated time on a free port."""
    argv = ["--listen", f"127.0.0.1:{free_port()}", "--duration", "0.001", "--quiet", "--no-signing", *args]
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    return code, capsys.readouterr().err.splitlines()


@pytest.mark.parametrize("args, says", [
    (("--origin", "91,0,0"), "--origin: expected LAT in [-90, 90]"),
    (("--origin", "nan,8,400"), "--origin"),
    (("--origin", "47,8"), "expected LAT,LON,ALT"),
    (("--sysid", "0"), "--sysid: expected 1..255"),
    (("--sysid", "256"), "--sysid: expected 1..255"),
    (("--seed", "-1"), "--seed: expected 0..4294967295"),
    (("--seed", "1.5"), "--seed: expected an integer"),
    (("--speedup", "inf"), "--speedup: expected a finite number"),
    (("--speedup", "5000"), "--speedup must be within 0.05..1000"),
    (("--listen", "999.1.1.1:14540"), "is not an IPv4 address"),
    (("--listen", "127.0.0.1:70000"), "expected HOST:PORT"),
    (("--param", "SIM_MASS_FAC"), "expected NAME=NUMBER"),
    (("--param", "SIM_MASS_FAC=nan"), "SIM_MASS_FAC: value is not finite"),
    (("--param", "SIM_TORQUE_Z=1"), "SIM_TORQUE_Z: 1 outside [-0.04, 0.04]"),
    (("--param", "NO_SUCH=1"), "unknown parameter 'NO_SUCH'"),
    (("--scenario", "no_such_scenario"), "no_such_scenario: cannot read file"),
    (("--duration", "-1"), "--duration must be positive"),
    (("--wait-for-setpoints", "nan"), "--wait-for-setpoints"),
    (("--boot-time", "-1"), "--boot-time must be within 0..1e8 s"),
    (("--boot-time", "2e9"), "--boot-time must be within 0..1e8 s"),
    (("--boot-time", "nan"), "--boot-time: expected a finite number"),
])
def test_each_bad_argument_is_one_line_and_exit_status_2(capsys, args, says) -> None:  # type: ignore[no-untyped-def]
    code, err = run(capsys, *args)
    assert code == 2 and len(err) == 1 and err[0].startswith("sitl: error: ") and says in err[0], err


@pytest.mark.parametrize("text, says", [
    ("[wind]\nmean_ned_m_s = [30.0, 0.0, 0.0]\n", "SIM_WIND_N = 30 outside [-6, 6]"),
    ("[model_error]\nmass_factor = 0.3\n", "SIM_MASS_FAC = 0.3 outside"),
    ("[attitude]\nomega_c_rad_s = 60.0\n", "ATT_W_C = 60 outside"),
    ("plant_rate_hz = 0.0\n", "sitl: error:"),
    ("[vehicle]\nmass_kg = -1.0\n", "sitl: error:"),
    ("duration_s = 'long'\n", "sitl: error:"),
    ("[[[ not toml\n", "sitl: error:"),
])
def test_a_scenario_that_sets_what_no_parameter_may_is_refused_in_one_line(capsys, tmp_path: Path, text: str,
                                                                         says: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code, err = run(capsys, "--scenario", str(path))
    assert code == 2 and len(err) == 1 and says in err[0], err


def test_good_arguments_start_the_vehicle(capsys) -> None:  # type: ignore[no-untyped-def]
    code, err = run(capsys, "--origin=-33.9,151.2,40", "--sysid", "42", "--seed", "4294967295",
                    "--param", "SIM_TORQUE_X=0.15", "--scenario", "E5_suspended_weight", "--speedup", "0.05")
    assert code == 0 and err == [], err


OPTIONS = ("--origin", "--sysid", "--seed", "--speedup", "--listen", "--param", "--scenario",
           "--wait-for-setpoints", "--lockstep", "--attitude", "--flavour", "--peer", "--boot-time")
"""(not --duration: a valid long one would run; its checks are above)"""
VALUES = st.one_of(
    st.text(max_size=30),
    st.sampled_from(("nan", "inf", "-inf", "-1", "0", "1e309", "0x10", "1,2,3", "1,2", "a=b", "SIM_WIND_N=1e9",
                     "ATT_CTRL=1.5", "127.0.0.1:0", "localhost:14540", ":1", "E3_calm", "/dev/null", "")),
    st.floats().map(repr), st.integers(-2**40, 2**40).map(str),
    st.lists(st.floats(-200, 200).map(repr), min_size=3, max_size=3).map(",".join))


@settings(max_examples=80, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(OPTIONS), VALUES)
def test_no_value_of_any_option_gives_a_traceback(option: str, value: str) -> None:
    """Whatever follows an option: the vehicle starts (0), or one line and exit status 2."""
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        argv = ["--listen", f"127.0.0.1:{free_port()}", "--duration", "0.001", "--quiet", "--no-signing"]
        try:
            code = main(argv + [option, value])
        except SystemExit as exc:
            code = int(exc.code or 0)
    lines = err.getvalue().splitlines()
    assert (code == 0 and not lines) or (code == 2 and len(lines) == 1 and lines[0].startswith("sitl: error: ")), \
        (option, value, code, lines)


def run_firmware(capsys, *args: str) -> tuple[int, list[str]]:  # type: ignore[no-untyped-def]
    try:
        code = main(["--quiet", "--no-signing", *args])
    except SystemExit as exc:
        code = int(exc.code or 0)
    return code, capsys.readouterr().err.splitlines()


@pytest.mark.parametrize("args, says", [
    (("--firmware", "px4", "--firmware-path", "/nonexistent"), "no PX4 SITL build"),
    (("--firmware", "ardupilot", "--firmware-path", "/tmp"), "no ArduCopter SITL"),
    (("--firmware", "px4", "--attitude", "pd"), "--attitude is the bundled autopilot's"),
    (("--firmware", "px4", "--listen", "127.0.0.1:15000"), "--listen is the bundled autopilot's"),
    (("--firmware", "gazebo"), "invalid choice"),
    (("--firmware", "px4", "--boot-time", "100"), "--boot-time is the bundled autopilot's"),
    (("--layout", "x"), "--layout needs --firmware"),
    (("--position-source", "gnss"), "--position-source needs --firmware"),
    (("--firmware", "px4", "--instance", "10"), "PX4's instances are 0-9"),
])
def test_firmware_options_are_checked(capsys, args, says) -> None:  # type: ignore[no-untyped-def]
    code, err = run_firmware(capsys, *args)
    assert code == 2 and len(err) == 1 and says in err[0], err


def test_with_neither_listen_nor_peer_the_vehicle_takes_px4_sitls_ports() -> None:
    """Plain ``sitl`` listens where PX4 SITL's API link does (14580) and sends to where PX4 SITL sends it
    (14540), so a script written for PX4 SITL (MAVSDK ``udpin://0.0.0.0:14540``) connects unchanged;
    either option given, the ports are the user's (a --listen alone sends first to no one)."""
    from sitl.autopilot.cli import ports

    assert ports(None, None) == (("127.0.0.1", 14580), [("127.0.0.1", 14540)])
    assert ports(("127.0.0.1", 14540), None) == (("127.0.0.1", 14540), [])
    assert ports(None, [("10.0.0.2", 14550)]) == (("127.0.0.1", 14580), [("10.0.0.2", 14550)])
    assert ports(("0.0.0.0", 9000), [("127.0.0.1", 9001)]) == (("0.0.0.0", 9000), [("127.0.0.1", 9001)])


def test_the_banner_says_where_the_vehicle_sends_and_how_mavsdk_listens_there(capsys) -> None:  # type: ignore[no-untyped-def]
    peer = free_port()
    assert main(["--listen", f"127.0.0.1:{free_port()}", "--peer", f"127.0.0.1:{peer}", "--duration", "0.001",
                 "--no-signing"]) == 0
    banner = capsys.readouterr().out.splitlines()[0]
    assert f"sending to udp://127.0.0.1:{peer} (MAVSDK: udpin://0.0.0.0:{peer})" in banner, banner
