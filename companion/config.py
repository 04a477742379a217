"""Reading parameter files (TOML) into the frozen dataclasses, with errors that point at a line.

``tomllib`` reports syntax errors with their line; for a key that parses but does not fit
(unknown name, wrong type) :func:`locate` finds the line of the key from the table headers,
so the message reads ``missions/x.toml:12: position.omega_c: unknown key; expected one of ...``.

Files are read by :func:`read_text`, which bounds what a hostile file can cost before any parser
sees it: a regular file only, at most ``max_bytes``, UTF-8 without NUL bytes, brackets nested at
most ``max_nesting`` deep (the parsers recurse per level); each refusal names the line.
"""

from __future__ import annotations

import re
import stat
import tomllib
from pathlib import Path
from typing import Any, Mapping, TypeVar

from companion.control.params import ParamError, from_mapping

__all__ = ["ConfigError", "read_text", "load_toml", "load_dataclass", "locate", "MAX_FILE_BYTES", "MAX_NESTING"]

MAX_FILE_BYTES = 1_000_000
"""parameter and mission files are a few kB"""
MAX_NESTING = 16

T = TypeVar("T")


class ConfigError(ValueError):
    """A parameter file that cannot be used: ``path``, ``line`` (or None), ``key`` and reason."""

    def __init__(self, path: str | Path, line: int | None, key: str, reason: str, hint: str = "") -> None:
        where = f"{path}:{line}" if line else f"{path}"
        # a hostile file's key or value (quoted in the reason) may be a megabyte long
        shown = key if len(key) <= 100 else key[:100] + "..."
        told = reason if len(reason) <= 400 else reason[:400] + "..."
        super().__init__(f"{where}: {shown + ': ' if shown else ''}{told}")
        self.path = str(path)
        self.line = line
        self.key = key
        self.reason = reason
        self.hint = hint
        """what to do about it, lines to print after the one-line message (may be empty)"""


_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\"']+)\s*=")
_SEGMENT = re.compile(r"([^.\[\]]+)(?:\[(\d+)\])?")


def locate(text: str, key_path: str) -> int | None:
    """1-based line of ``key_path`` (``a.b[2].c``) in TOML ``text``; the nearest table if the
    key itself is absent (e.g. a missing item), or None."""
    parts = [(m.group(1), int(m.group(2)) if m.group(2) is not None else None)
             for m in _SEGMENT.finditer(key_path)]
    if not parts:
        return None
    target_table: list[str] = []
    index: dict[str, int] = {}
    for name, idx in parts[:-1]:
        target_table.append(name)
        if idx is not None:
            index[".".join(target_table)] = idx
    last_name, last_idx = parts[-1]

    table: list[str] = []
    counts: dict[str, int] = {}
    current_ok = not target_table
    best: int | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        m = _HEADER.match(raw)
        if m:
            table = [p.strip().strip('"') for p in m.group(2).split(".")]
            name = ".".join(table)
            if m.group(1) == "[[":
                counts[name] = counts.get(name, -1) + 1
            current_ok = table == target_table and all(
                counts.get(".".join(target_table[: i + 1]), 0) == idx
                for i, (_, idx) in enumerate(parts[: len(target_table)])
                if idx is not None
            )
            if current_ok and best is None:
                best = lineno
            if table == target_table + [last_name] and (
                last_idx is None or counts.get(".".join(table), 0) == last_idx
            ):
                return lineno  # the key names a whole table: point at its header
            continue
        k = _KEY.match(raw)
        if k and current_ok and k.group(1).strip("\"'") == last_name.strip("\"'"):
            return lineno
    return best


def read_text(path: str | Path, max_bytes: int = MAX_FILE_BYTES, max_nesting: int = MAX_NESTING,
              syntax: str = "toml") -> str:
    """The text of a parameter file, refused (:class:`ConfigError` with the line) if it is not a
    regular file, is larger than ``max_bytes``, is not UTF-8, holds a NUL byte, or nests brackets
    deeper than ``max_nesting`` (``syntax`` "toml" or "json" tells strings and comments apart)."""
    p = Path(path)
    try:
        if not stat.S_ISREG(p.stat().st_mode):
            raise ConfigError(p, None, "", "not a regular file")
        with open(p, "rb") as f:
            raw = f.read(max_bytes + 1)
    except OSError as exc:
        raise ConfigError(p, None, "", f"cannot read file: {exc.strerror or exc}") from None
    if len(raw) > max_bytes:
        raise ConfigError(p, raw.count(b"\n", 0, max_bytes) + 1, "",
                          f"file larger than {max_bytes} bytes (it goes on past this line); refused unread")
    nul = raw.find(b"\0")
    if nul >= 0:
        raise ConfigError(p, raw.count(b"\n", 0, nul) + 1, "", "NUL byte in the file; expected text")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise ConfigError(p, line, "", f"not UTF-8 text (byte 0x{raw[exc.start]:02x})") from None
    deep = _too_deep(text, max_nesting, syntax)
    if deep is not None:
        raise ConfigError(p, text.count("\n", 0, deep) + 1, "",
                          f"brackets nested more than {max_nesting} deep; a parameter file needs a few")
    return text


_STRING_BODY = {'"': re.compile(r'(?:[^"\\\n]|\\.)*'), "'": re.compile(r"[^'\n]*")}
_INTERESTING = {"toml": re.compile(r"[\[\]{}\"'#]"), "json": re.compile(r'[\[\]{}"]')}


def _too_deep(text: str, limit: int, syntax: str) -> int | None:
    """Offset of the first bracket nested deeper than ``limit``, skipping strings and comments
    (linear time: each string or comment is skipped with one search)."""
    find = _INTERESTING[syntax].search
    depth, i, n = 0, 0, len(text)
    while True:
        m = find(text, i)
        if m is None:
            return None
        c, i = m.group(), m.start()
        if c in "[{":
            depth += 1
            if depth > limit:
                return i
            i += 1
        elif c in "]}":
            depth = max(0, depth - 1)
            i += 1
        elif c == "#":
            j = text.find("\n", i)
            i = n if j < 0 else j + 1
        elif syntax == "toml" and text.startswith(c * 3, i):
            j = text.find(c * 3, i + 3)
            i = n if j < 0 else j + 3
        else:  # a one-line string; basic strings ("...") have escapes, literal ones ('...') none
            end = _STRING_BODY[c].match(text, i + 1)
            i = end.end() + 1 if end else n


def load_toml(path: str | Path, max_bytes: int = MAX_FILE_BYTES) -> tuple[dict[str, Any], str]:
    """Parsed TOML and its text (read by :func:`read_text`); a syntax error becomes a
    :class:`ConfigError` with the line."""
    p = Path(path)
    text = read_text(p, max_bytes)
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"line (\d+)", str(exc))
        line = int(m.group(1)) if m else max(1, len(text.splitlines())) if "end of document" in str(exc) else None
        raise ConfigError(p, line, "", f"not valid TOML: {exc}") from None
    except RecursionError:  # read_text bounds the nesting; this is the backstop
        raise ConfigError(p, None, "", "not valid TOML: nested too deeply") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits (int() refuses it)
        m = re.search(r"[0-9_]{4000,}", text)
        line = text.count("\n", 0, m.start()) + 1 if m else None
        raise ConfigError(p, line, "", f"not valid TOML: {exc}") from None


def load_dataclass(cls: type[T], data: Mapping[str, Any], path: str | Path, text: str, key_path: str = "") -> T:
    """``from_mapping`` with any :class:`ParamError` turned into a :class:`ConfigError` with line.

    Constructors that reject a value (``__post_init__`` raising ``ValueError``) are reported
    against the table that was being built.
    """
    try:
        return from_mapping(cls, data, key_path)
    except ParamError as exc:
        key = exc.key_path
        if not key or key.endswith("."):
            key += '""'  # the key's name is empty (`"" = 1`): say so rather than print nothing
        raise ConfigError(path, locate(text, key), key, exc.detail) from None
