"""Hostile mission files: each is refused by `companion check` with exit 2 and file:line, quickly,
and by load_mission (which `companion fly` uses) with the same ConfigError."""

import json
import os
import time

import pytest

from companion.cli import main
from companion.config import MAX_FILE_BYTES, ConfigError, read_text
from companion.mission import is_safe_component, load_mission, safe_component
from helpers.missions import goto_mission

GOOD = goto_mission()


def check(capsys, path):
    """`companion check path`: exit code and the one error line."""
    t0 = time.process_time()  # CPU time: what the file costs, whatever else runs on the machine
    code = main(["check", str(path)])
    assert time.process_time() - t0 < 5.0, "a hostile file must be refused quickly"
    return code, capsys.readouterr().err.strip()


def refused(capsys, path, line, *words):
    code, err = check(capsys, path)
    assert code == 2, err
    assert err.startswith(f"companion: error: {path}:{line}:"), err
    for w in words:
        assert w in err, err
    with pytest.raises(ConfigError) as e:  # fly loads with the same function: the same refusal
        load_mission(path)
    assert e.value.line == line
    return err


def test_the_good_file_is_accepted(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD)
    code, _ = check(capsys, p)
    assert code == 0


def test_deep_nesting(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD + "x = " + "[" * 100_000 + "]" * 100_000 + "\n")
    refused(capsys, p, 16, "nested more than 16 deep")


def test_deep_nesting_of_inline_tables(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text("a = 1\nx = " + "{b = " * 3000 + "1" + "}" * 3000 + "\n" + GOOD)
    refused(capsys, p, 2, "nested")


def test_brackets_inside_strings_and_comments_do_not_count(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace('name = "m"', 'name = "m"  # ' + "[" * 20 + '\ndescription = "' + "[" * 20 + '"'))
    assert load_mission(p).description.startswith("[[[")


def test_nul_byte(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_bytes(GOOD.replace('name = "m"', 'name = "m\0"').encode())
    refused(capsys, p, 1, "NUL")


def test_non_utf8(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_bytes(GOOD.encode().replace(b"altitude_m = 1.5", b"altitude_m = 1.5 # \xff\xfe"))
    refused(capsys, p, 5, "not UTF-8")


def test_huge_file_is_refused_unread(tmp_path, capsys):
    p = tmp_path / "m.toml"
    with open(p, "w") as f:
        f.write(GOOD)
        f.write(("# " + "x" * 98 + "\n") * 10_500)  # 1.05 MB of comments: valid TOML, too big
    line = GOOD.count("\n") + (MAX_FILE_BYTES - len(GOOD)) // 101 + 1
    refused(capsys, p, line, "larger than 1000000 bytes")


def test_a_sparse_file_of_a_terabyte_costs_nothing(tmp_path):
    p = tmp_path / "m.toml"
    with open(p, "wb") as f:
        f.truncate(1 << 40)
    t0 = time.process_time()
    with pytest.raises(ConfigError, match="larger than"):
        load_mission(p)
    assert time.process_time() - t0 < 1.0


def test_not_a_regular_file(tmp_path, capsys):
    d = tmp_path / "dir.toml"
    d.mkdir()
    code, err = check(capsys, d)
    assert code == 2 and "not a regular file" in err and str(d) in err
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    code, err = check(capsys, fifo)  # would block for ever if it were opened
    assert code == 2 and "not a regular file" in err


def test_missing_file(tmp_path, capsys):
    code, err = check(capsys, tmp_path / "nope.toml")
    assert code == 2 and "cannot read file" in err


def test_huge_string(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace('name = "m"', 'name = "m"\ndescription = "' + "x" * 100_000 + '"'))
    err = refused(capsys, p, 2, "description", "at most 1000 characters")
    assert len(err) < 1000, "the message does not quote the megabyte"


def test_huge_key(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace('name = "m"', 'name = "m"\n' + "k" * 500_000 + " = 1"))
    err = refused(capsys, p, 2, "unknown key")
    assert len(err) < 2000


def test_huge_integer(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace("altitude_m = 1.5", "altitude_m = " + "9" * 5000))
    refused(capsys, p, 5, "not valid TOML")


def test_enormous_waypoint_array(tmp_path, capsys):
    """20k waypoints: refused by their count (10^6 do not even fit in the 1 MB a file may have)."""
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace("[[1, 0, -1.5], [1, 1, -1.5]]", "[" + "[1,0,-1]," * 20_000 + "]"))
    refused(capsys, p, 12, "steps[2].waypoints", "at most 2000 waypoints")
    p.write_text(GOOD.replace("[[1, 0, -1.5], [1, 1, -1.5]]", "[" + "[1,0,-1]," * 1_000_000 + "]"))
    refused(capsys, p, 12, "larger than")  # the waypoints line, where the 1 MB bound falls


def test_too_many_steps(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD + '\n[[steps]]\naction = "wait"\nduration_s = 1\n' * 1000)
    refused(capsys, p, 17 + 4 * 996, "steps[1000]", "at most 1000 steps")


@pytest.mark.parametrize("name", ["../../etc/cron.d/x", "a/b", "a\\b", "..", ".hidden", "a..b", "", "x" * 65,
                                  "sp ace", "tab\tname", "nul\u0000", "ünïcode", "semi;colon", "-" * 0])
def test_unsafe_names_are_refused(tmp_path, capsys, name):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace('name = "m"', f"name = {json.dumps(name)}"))
    refused(capsys, p, 1, "name:", "letters, digits")


@pytest.mark.parametrize("name", ["hover45", "E4_square-2.v1", "_x", "a.b.c", "9"])
def test_safe_names_are_accepted(tmp_path, name):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace('name = "m"', f'name = "{name}"'))
    assert load_mission(p).name == name


def test_a_name_from_an_unsafe_file_name_is_made_safe(tmp_path):
    p = tmp_path / "my mission (copy).toml"
    p.write_text(GOOD.replace('name = "m"\n', ""))
    assert load_mission(p).name == "my_mission__copy_"


@pytest.mark.parametrize("text", ["../../x", "..", ".", "", "/", "a/../b", "\u0000", "x" * 500, "..a", "a..", "é/€"])
def test_safe_component(text):
    s = safe_component(text)
    assert is_safe_component(s) and "/" not in s and not s.startswith(".") and ".." not in s and len(s) <= 64


def test_control_characters_in_step_names_and_descriptions(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace('action = "offboard"', 'action = "offboard"\nname = "a\\u001b[2Jb"'))
    refused(capsys, p, 9, "steps[1].name", "control character")
    p.write_text(GOOD.replace('action = "offboard"', 'action = "offboard"\nname = "a | b"'))
    refused(capsys, p, 9, "steps[1].name", "'|'")


def test_parameter_names_are_restricted(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace('[[steps]]\naction = "land"', '[[steps]]\naction = "set_param"\nparam = "../X"\n'
                              'value = 1\n\n[[steps]]\naction = "land"'))
    refused(capsys, p, 16, "steps[3].param", "1..16 letters")


def test_read_text_skips_json_strings_when_counting_nesting(tmp_path):
    p = tmp_path / "x.plan"
    p.write_text(json.dumps({"a": "[" * 100, "b": [[1]]}))
    assert read_text(p, syntax="json")
    p.write_text(json.dumps({"a": "x\\\"" + "[" * 100, "b": [[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]}))
    with pytest.raises(ConfigError, match="nested"):
        read_text(p, syntax="json")


@pytest.mark.parametrize("change", [
    lambda t: t.replace('name = "m"', 'name = "../../x"'),
    lambda t: t.replace("[1, 1, -1.5]]", "[1, 1e9, -1.5]]"),
    lambda t: t + "x = " + "[" * 50 + "]" * 50 + "\n",
    lambda t: t.replace('[[steps]]\naction = "land"\n', ""),
    lambda t: t + '\n[safety]\ntelemetry_timeout_s = 0\n',
])
def test_fly_refuses_what_check_refuses_with_the_same_message(tmp_path, capsys, change):
    """One loader: `fly` exits 2 with check's message, before it opens any link."""
    p = tmp_path / "m.toml"
    p.write_text(change(GOOD))
    code, err = check(capsys, p)
    assert code == 2 and err.startswith(f"companion: error: {p}:")
    assert main(["fly", str(p), "--connect", "udp://127.0.0.1:9", "--no-plots"]) == 2
    assert capsys.readouterr().err.strip() == err
