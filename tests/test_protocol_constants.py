"""Every MAVLink protocol number has one home: pymavlink's generated constants, or
companion/mavlink/ where pymavlink has none (PX4 and ArduCopter mode numbers, the force-arm code).

Read from the code itself (an AST scan of companion/, sitl/, tests/ and benchmarks/, companion/mavlink/
excluded): a bare integer where the protocol expects one of its enums or bitmasks is a second copy of
that fact. What counts as protocol-typed is read from pymavlink's message definitions (the fields
that carry an enum or a bitmask), so a new message is covered without editing this file.
"""

from __future__ import annotations

import ast
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("companion", "sitl", "tests", "benchmarks")
HOME = ROOT / "companion" / "mavlink"

_MESSAGES = {cls.__name__[len("MAVLink_"):-len("_message")]: cls for cls in vars(mavlink).values()
             if isinstance(cls, type) and cls.__name__.startswith("MAVLink_") and cls.__name__.endswith("_message")
             and hasattr(cls, "fieldenums_by_name")}
"""lower-case message name (as in ``<name>_send``) -> its pymavlink class"""

PROTOCOL_FIELDS = {f for cls in _MESSAGES.values() for f in cls.fieldenums_by_name} | {"custom_mode"}
"""field names that carry a MAVLink enum or bitmask in some message (command, result, type_mask,
landed_state, base_mode, severity, coordinate_frame, ...), plus HEARTBEAT's custom_mode (the
autopilots' mode words, whose numbers live in companion.mavlink.modes)"""
MASK_FIELDS = {f for cls in _MESSAGES.values() for f, d in cls.fielddisplays_by_name.items() if d == "bitmask"}
"""of those, the bitmasks: 0 (no bit set) needs no name"""
IGNORED_FIELDS = {"type", "autopilot", "mode", "state", "status", "frame", "flags"} - {"type_mask"}
"""names too common to read as MAVLink fields when compared on an arbitrary object (``x.type``,
``x.mode``); they are still checked as arguments of a message's ``_send``/``_encode``"""
KEYWORD_FIELDS = {"type_mask", "command", "result", "landed_state", "base_mode", "custom_mode", "severity",
                  "coordinate_frame", "system_status", "param_type"}
"""keyword arguments of any function (a test helper's ``stream(..., type_mask=7)``) read as the field of
that name; a message's own ``_send``/``_encode`` is checked against all of its fields"""
COMMAND_CALLS = {"command_long", "_command_long", "command", "command_int"}
"""helpers whose first argument is a MAV_CMD (the links' ``command_long``, the simulated autopilot's
``command``)"""
NAMED_PARAMS = {"MAV_CMD_SET_MESSAGE_INTERVAL": (1,), "MAV_CMD_REQUEST_MESSAGE": (1,), "MAV_CMD_DO_SET_MODE": (1, 2, 3),
                "MAV_CMD_COMPONENT_ARM_DISARM": (2,)}
"""params that carry protocol numbers: a message id (param1 of SET_MESSAGE_INTERVAL, REQUEST_MESSAGE), the
custom-mode flag and the mode numbers (DO_SET_MODE; companion.mavlink.modes), the force code (ARM_DISARM
param2; companion.mavlink.commands)"""
CONSTANT_NAMES = {n for n in vars(mavlink) if n.startswith(("MAV_", "MAVLINK_MSG_ID_", "ATTITUDE_TARGET_",
                                                                  "POSITION_TARGET_"))}


def _bare(node: ast.AST | None) -> bool:
    """an integer written as digits: ``176``, ``-1``, ``6 << 16``, ``(4 << 16) | (3 << 24)``"""
    if isinstance(node, ast.Constant):
        return isinstance(node.value, int) and not isinstance(node.value, bool)
    if isinstance(node, ast.UnaryOp):
        return _bare(node.operand)
    if isinstance(node, ast.BinOp):
        return _bare(node.left) and _bare(node.right)
    return False


def _value(node: ast.AST) -> int:
    """the integer a :func:`_bare` expression writes"""
    return eval(compile(ast.Expression(node), "<bare>", "eval"), {})


def _zero(node: ast.AST | None) -> bool:
    return isinstance(node, ast.Constant) and node.value == 0


def _named(node: ast.AST | None) -> str:
    """``mavlink.MAV_CMD_X`` or ``MAV_CMD_X`` -> ``MAV_CMD_X``"""
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.Name):
        return node.id
    return ""


def _field(node: ast.AST) -> str:
    """the MAVLink field a compared expression reads: ``msg.result``, ``h.base_mode``, ``get_msgid()``,
    or a variable named after one (``type_mask``)"""
    name = _named(node) if isinstance(node, (ast.Attribute, ast.Name)) else ""
    if name in PROTOCOL_FIELDS - IGNORED_FIELDS:
        return name
    if isinstance(node, ast.Call) and _named(node.func) == "get_msgid":
        return "msgid"
    return ""


def _bad_value(field: str, node: ast.AST | None) -> bool:
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return any(_bad_value(field, e) for e in node.elts)
    return _bare(node) and not (field in MASK_FIELDS and _zero(node))


def _target(call: ast.Call) -> tuple[str, list[ast.expr]]:
    """the function a call reaches and its arguments: ``f(a, b)`` -> ("f", [a, b]); a helper handed the
    encoder's name, ``packed("command_long_encode", 1, 1, 400, ...)``, -> ("command_long_encode", [1, 1, 400, ...])"""
    for i, a in enumerate(call.args):
        if isinstance(a, ast.Constant) and isinstance(a.value, str) and a.value.endswith(("_send", "_encode")):
            return a.value, call.args[i + 1:]
    return _named(call.func), list(call.args)


def _message_call(call: ast.Call) -> list[tuple[str, ast.AST]]:
    """(field, argument) for each argument of ``<message>_send/_encode(...)`` or
    ``MAVLink_<message>_message(...)``"""
    name, args = _target(call)
    for suffix in ("_send", "_encode"):
        if name.endswith(suffix) and name[: -len(suffix)] in _MESSAGES:
            cls = _MESSAGES[name[: -len(suffix)]]
            break
    else:
        if not (name.startswith("MAVLink_") and name.endswith("_message")):
            return []
        cls = getattr(mavlink, name, None)
        if cls is None or not hasattr(cls, "fieldnames"):
            return []
    pairs = [(f, a) for f, a in zip(cls.fieldnames, args)]
    pairs += [(k.arg, k.value) for k in call.keywords if k.arg]
    return pairs


def _command_params(command: ast.AST | None, params: list[ast.AST]) -> list[str]:
    """a nonzero number written as digits in one of the command's NAMED_PARAMS"""
    name = _named(command)
    return [f"{name} param{i} {ast.unparse(params[i - 1])}" for i in NAMED_PARAMS.get(name, ())
            if i <= len(params) and _digits(params[i - 1])]


def _digits(node: ast.AST | None) -> bool:
    """a nonzero number written as digits (COMMAND_LONG's params are floats: ``6.0`` too)"""
    if isinstance(node, ast.Constant) and isinstance(node.value, float):
        return node.value != 0.0
    return _bare(node) and not _zero(node)


def bare_numbers(source: str, filename: str = "<string>") -> list[tuple[int, str]]:
    """(line, what) for each protocol number written as digits in ``source``"""
    tree = ast.parse(source, filename)
    found = _renamed_entries(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            fields = _message_call(node)
            found += [(node.lineno, f"{f}={ast.unparse(a)}") for f, a in fields
                      if f in PROTOCOL_FIELDS and _bad_value(f, a)]
            found += [(node.lineno, f"{k.arg}={ast.unparse(k.value)}") for k in node.keywords
                      if k.arg in KEYWORD_FIELDS and _bad_value(k.arg, k.value)]
            name, args = _target(node)
            if name in ("command_long_send", "command_long_encode"):
                found += [(node.lineno, w) for w in _command_params(args[2] if len(args) > 2 else None, args[4:])]
            if _named(node.func) in COMMAND_CALLS and node.args:
                if _bare(node.args[0]):
                    found.append((node.lineno, f"{_named(node.func)}({ast.unparse(node.args[0])}, ...)"))
                rest = node.args[1].elts if len(node.args) == 2 and isinstance(node.args[1], ast.Tuple) \
                    else node.args[1:]
                found += [(node.lineno, w) for w in _command_params(node.args[0], list(rest))]
        elif isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            for a, b in zip(sides, sides[1:]):
                for x, y in ((a, b), (b, a)):
                    if (f := _field(x)) and _bad_value(f, y):
                        found.append((node.lineno, f"{ast.unparse(x)} vs {ast.unparse(y)}"))
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitAnd):
            for x, y in ((node.left, node.right), (node.right, node.left)):
                if (f := _field(x)) and _bare(y):
                    found.append((node.lineno, f"{ast.unparse(x)} & {ast.unparse(y)}"))
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            args = node.args
            positional = [*args.posonlyargs, *args.args]
            pairs = [*zip(positional[len(positional) - len(args.defaults):], args.defaults),
                     *((a, d) for a, d in zip(args.kwonlyargs, args.kw_defaults) if d is not None)]
            found += [(node.lineno, f"default {a.arg}={ast.unparse(d)}") for a, d in pairs
                      if a.arg in PROTOCOL_FIELDS - IGNORED_FIELDS and _bad_value(a.arg, d)]
        elif isinstance(node, ast.Dict):
            items = {k.value: v for k, v in zip(node.keys, node.values) if isinstance(k, ast.Constant)}
            found += [(node.lineno, f"{k!r}: {ast.unparse(v)}") for k, v in items.items()
                      if k in PROTOCOL_FIELDS - IGNORED_FIELDS and _bad_value(k, v)]
            params = [items.get(f"param{i}") for i in (1, 2, 3)]
            found += [(node.lineno, w) for w in _command_params(items.get("command"), params)]
        elif isinstance(node, ast.Assign):
            found += [(node.lineno, f"{t.id} = {ast.unparse(node.value)} (pymavlink has it)") for t in node.targets
                      if isinstance(t, ast.Name) and t.id in CONSTANT_NAMES and _bare(node.value)]
        elif isinstance(node, ast.ClassDef):
            found += [(node.lineno, w) for w in _mirrored_enum(node)]
    return sorted(set(found))


def _mirrored_enum(cls: ast.ClassDef) -> list[str]:
    """members of an IntEnum that retype a MAVLink enum (``ACCEPTED = 0`` beside MAV_RESULT_ACCEPTED)"""
    if not any(_named(b) == "IntEnum" for b in cls.bases):
        return []
    members = {t.id: s.value for s in cls.body if isinstance(s, ast.Assign) and _bare(s.value)
               for t in s.targets if isinstance(t, ast.Name)}
    if not members:
        return []
    found = []
    for enum, entries in mavlink.enums.items():
        values = {e.name: v for v, e in entries.items()}
        same = [f"{cls.name}.{m} = {ast.unparse(v)} (pymavlink: {enum}_{m})" for m, v in members.items()
                if values.get(f"{enum}_{m}") == _value(v)]
        found += same if len(same) >= 2 else []
    return found


_ENTRIES = {e.name: v for entries in mavlink.enums.values() for v, e in entries.items()}


def _renamed_entries(tree: ast.Module) -> list[tuple[int, str]]:
    """module constants that repeat an enum entry under its last words (``TAKEOFF = 22`` beside
    MAV_CMD_NAV_TAKEOFF), including ``A, B = 22, 16``"""
    found = []
    for node in tree.body:
        if not isinstance(node, ast.Assign):
            continue
        for target in node.targets:
            pairs = [(target, node.value)] if isinstance(target, ast.Name) else \
                list(zip(target.elts, node.value.elts)) if isinstance(target, ast.Tuple) and \
                isinstance(node.value, ast.Tuple) else []
            for t, v in pairs:
                if not (isinstance(t, ast.Name) and t.id.isupper() and _bare(v)):
                    continue
                value = _value(v)
                same = [e for e, ev in _ENTRIES.items() if ev == value and e.startswith("MAV_")
                        and e.endswith("_" + t.id) and t.id not in CONSTANT_NAMES]
                found += [(node.lineno, f"{t.id} = {value} (pymavlink: {same[0]})")] if same else []
    return found


def _scanned() -> list[Path]:
    return sorted(p for top in SCANNED for p in (ROOT / top).rglob("*.py") if HOME not in p.parents)


def test_no_bare_protocol_number_outside_companion_mavlink() -> None:
    found = [f"{p.relative_to(ROOT)}:{line}: {what}" for p in _scanned()
             for line, what in bare_numbers(p.read_text(), str(p))]
    assert not found, f"{len(found)} bare MAVLink numbers (use pymavlink's constants or companion.mavlink):\n" + \
        "\n".join(found)


def test_the_scan_sees_each_kind_of_bare_number() -> None:
    """each form the scan looks for, written bare, is found; written with its name, is not"""
    bare = """
m.mav.command_long_send(1, 1, 176, 0, 1, 6, 0, 0, 0, 0, 0)
await link.command_long(400, 1)
ap.command(mavlink.MAV_CMD_REQUEST_MESSAGE, (148,))
m.mav.set_attitude_target_send(0, 1, 1, 7, q, 0, 0, 0, 0.5); stream(m, type_mask=128)
x = msg.type_mask & 64
ok = ack.result == 0 and s.landed_state in (1, 2) and h.custom_mode == 6 << 16 and h.base_mode & 128
def stream(m, type_mask: int = 3): pass
fields = {"type_mask": 2048}
fields = {"command": mavlink.MAV_CMD_DO_SET_MODE, "param1": 1.0, "param2": 6.0}
MAV_CMD_DO_SET_MODE = 176
class Result(enum.IntEnum):
    ACCEPTED = 0
    DENIED = 2
TAKEOFF, WAYPOINT = 22, 16
"""
    named = """
m.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub,
                        0, 0, 0, 0)
await link.command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
m.mav.set_attitude_target_send(0, 1, 1, 0, q, 0, 0, 0, 0.5)
ok = ack.result == mavlink.MAV_RESULT_ACCEPTED and len(x) == 3 and h.base_mode & ARMED
def stream(m, type_mask: int = 0): pass
class Result(enum.IntEnum):
    ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
TAKEOFF, TIMEOUT_S = mavlink.MAV_CMD_NAV_TAKEOFF, 22
"""
    lines = {line for line, _ in bare_numbers(bare)}
    assert lines == {*range(2, 13), 15}, bare_numbers(bare)
    assert bare_numbers(named) == []
