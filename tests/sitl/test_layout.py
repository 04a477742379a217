"""sitl/ laid out by role (docs/architecture.md): which package may import which, read from the
code's own import statements (every one, at any depth: lazy imports inside functions count)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

ALLOWED = {
    "plant": {"plant"},
    "autopilot": {"autopilot", "plant", "percentiles"},
    "lab": {"lab", "plant"},
    "netem": {"netem", "percentiles"},
    "firmware": {"firmware", "plant"},
    "percentiles": set(),
    "cli": {"autopilot", "firmware", "plant"},
    "__main__": {"cli"},
    "__init__": set(),
}
"""sitl's parts (a package, or a file at its top) and the parts each may import: autopilot/, lab/
and firmware/ (a real autopilot flying the plant) all build on plant/ and never on each other; the
relay knows no vehicle; the ``sitl`` command (cli) runs the bundled autopilot or a firmware"""


def _part(module: str) -> str:
    """sitl.lab.sweep -> lab; sitl.percentiles -> percentiles"""
    return module.split(".")[1] if "." in module else "__init__"


def _imports(path: Path) -> list[tuple[str, int]]:
    """every module that ``path`` imports, as an absolute dotted name, with its line"""
    here = path.relative_to(ROOT).with_suffix("").parts
    package = here[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                out.append((node.module or "", node.lineno))
                continue
            base = package[: len(package) - (node.level - 1)]
            if node.module:
                out.append((".".join((*base, node.module)), node.lineno))
            else:  # from . import x
                out += [(".".join((*base, a.name)), node.lineno) for a in node.names]
    return out


def test_each_part_of_sitl_imports_only_what_it_may() -> None:
    wrong = []
    for path in sorted((ROOT / "sitl").rglob("*.py")):
        part = _part(".".join(path.relative_to(ROOT).with_suffix("").parts))
        for module, line in _imports(path):
            if module == "sitl" or module.startswith("sitl."):
                target = _part(module)
                if target not in ALLOWED[part]:
                    wrong.append(f"{path.relative_to(ROOT)}:{line} ({part}) imports {module} ({target})")
    assert not wrong, "\n".join(wrong)


def test_every_file_of_sitl_belongs_to_a_part() -> None:
    for path in (ROOT / "sitl").rglob("*.py"):
        assert _part(".".join(path.relative_to(ROOT).with_suffix("").parts)) in ALLOWED, path


def test_the_companion_never_imports_the_simulated_vehicle() -> None:
    """the vehicle is another program on the wire (companion/vehicle_process.py starts it)"""
    wrong = [f"{p.relative_to(ROOT)}:{line} imports {m}" for p in sorted((ROOT / "companion").rglob("*.py"))
             for m, line in _imports(p) if m == "sitl" or m.startswith("sitl.")]
    assert not wrong, "\n".join(wrong)
