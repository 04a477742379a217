"""Reading parameter files (TOML) into the frozen dataclasses, with errors that point at a line.

``tomllib`` reports syntax errors with their line; for a key that parses but does not fit
(unknown name, wrong type) :func:`locate` finds the line of the key from the table headers,
so the message reads ``missions/x.toml:12: position.omega_c: unknown key; expected one of ...``.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any, Mapping, TypeVar

from companion.control.params import ParamError, from_mapping

__all__ = ["ConfigError", "load_toml", "load_dataclass", "locate"]

T = TypeVar("T")


class ConfigError(ValueError):
    """A parameter file that cannot be used: ``path``, ``line`` (or None), ``key`` and reason."""

    def __init__(self, path: str | Path, line: int | None, key: str, reason: str) -> None:
        where = f"{path}:{line}" if line else f"{path}"
        super().__init__(f"{where}: {key + ': ' if key else ''}{reason}")
        self.path = str(path)
        self.line = line
        self.key = key
        self.reason = reason


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


def load_toml(path: str | Path) -> tuple[dict[str, Any], str]:
    """Parsed TOML and its text; a syntax error becomes a :class:`ConfigError` with the line."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ConfigError(p, None, "", f"cannot read file: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise ConfigError(p, line, "", f"not UTF-8 text (byte 0x{raw[exc.start]:02x})") from None
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"line (\d+)", str(exc))
        line = int(m.group(1)) if m else max(1, len(text.splitlines())) if "end of document" in str(exc) else None
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
