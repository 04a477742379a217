"""A named list of source mutations of the control core, and the runner that checks the tests
catch each one (a small mutation test of our own, no extra dependency).

Each :class:`Mutation` is a deliberate bug of the kind a reviewer fears: a sign, a missing term,
a wrong input, an off-by-one in a filter. The runner copies ``companion/``, ``sitl/`` and
``tests/`` to a temporary folder, applies one mutation there (every ``old`` text must occur
exactly once, so a stale entry fails loudly instead of silently testing nothing), and runs the
mutation's fast tests in that folder. The mutation is *caught* when those tests fail, *survived*
when they pass. ``tests/test_mutations.py`` runs the whole list in CI and fails on any survivor;

    PYTHONPATH=tests .venv/bin/python -m helpers.mutations --report docs/mutations.md

writes the score (``make mutations`` does this).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Mutation", "Outcome", "MUTATIONS", "REPO", "run_one", "run_all", "report", "main"]

REPO = Path(__file__).resolve().parents[2]
COPIED = ("companion", "sitl", "tests")


@dataclass(frozen=True)
class Mutation:
    name: str
    path: str
    """file, relative to the repository"""
    edits: tuple[tuple[str, str], ...]
    """(old, new) text pairs; each old occurs exactly once in the file"""
    why: str
    tests: tuple[str, ...]
    """pytest node ids (fast tests) that must catch it"""


@dataclass(frozen=True)
class Outcome:
    mutation: Mutation
    caught: bool
    seconds: float
    output: str


ATT = "tests/control/test_attitude.py"
OBS = "tests/control/test_observers.py"
POS = "tests/control/test_position.py"
REF = "tests/control/test_reference.py"
SRC = "tests/control/test_force_source.py"
ALLOC = "tests/control/test_allocation.py"
ONB = "tests/sitl/test_onboard.py"
INDI = "tests/control/test_indi.py"

MUTATIONS: tuple[Mutation, ...] = (
    Mutation(
        "observer fed the requested torque", "sitl/plant/onboard.py",
        (("sp.omega_d_rad_s, self.torque_applied_nm, dt_s,", "sp.omega_d_rad_s, self._requested, dt_s,"),
         ("        cmd = self.quantise_all(rotor_speeds_sq_for(tau,",
          "        self._requested = tau\n        cmd = self.quantise_all(rotor_speeds_sq_for(tau,"),
         ("    torque_applied_nm: Vec3 = ZERO3\n",
          "    torque_applied_nm: Vec3 = ZERO3\n    _requested: Vec3 = ZERO3\n")),
        "Fig. 4: the torque observer must see the saturated, applied torque, not the request",
        (f"{ONB}::test_saturated_rotors_are_not_mistaken_for_a_disturbance",),
    ),
    Mutation(
        "Coriolis sign in (15)", "companion/control/observers.py",
        (("- tau[0] + (w[1] * jw2 - w[2] * jw1)", "- tau[0] - (w[1] * jw2 - w[2] * jw1)"),
         ("- tau[1] + (w[2] * jw0 - w[0] * jw2)", "- tau[1] - (w[2] * jw0 - w[0] * jw2)"),
         ("- tau[2] + (w[0] * jw1 - w[1] * jw0)", "- tau[2] - (w[0] * jw1 - w[1] * jw0)")),
        "(15) measures J0 w' - tau + w x J0 w; the other sign reads 2 w x J w in any tumble",
        (f"{OBS}::test_torque_observer_sees_nothing_in_torque_free_tumbling",),
    ),
    Mutation(
        "omega_d' feed-forward dropped from (13)", "companion/control/attitude.py",
        (("    ff0, ff1, ff2 = ff0 + wd[0], ff1 + wd[1], ff2 + wd[2]\n", ""),),
        "(13)'s R~^T omega_d' term: without it a swinging rate reference lags by A nu / c",
        (f"{ATT}::test_rate_derivative_feedforward_of_13_tracks_a_swinging_reference",),
    ),
    Mutation(
        "(R~^T)' omega_d sign in (13)", "companion/control/attitude.py",
        (("    ff0 = a[1] * b[2] - a[2] * b[1]\n", "    ff0 = a[2] * b[1] - a[1] * b[2]\n"),
         ("    ff1 = a[2] * b[0] - a[0] * b[2]\n", "    ff1 = a[0] * b[2] - a[2] * b[0]\n"),
         ("    ff2 = a[0] * b[1] - a[1] * b[0]\n", "    ff2 = a[1] * b[0] - a[0] * b[1]\n")),
        "(R~^T)' omega_d = (R~^T omega_d) x omega~; the other order doubles the error it should cancel",
        (f"{ATT}::test_nominal_law_13_imposes_the_error_dynamics_8_on_the_nominal_model",),
    ),
    Mutation(
        "Coriolis sign in (13)", "companion/control/attitude.py",
        (("c * e[0]) + (w[1] * jw2 - w[2] * jw1)", "c * e[0]) - (w[1] * jw2 - w[2] * jw1)"),
         ("c * e[1]) + (w[2] * jw0 - w[0] * jw2)", "c * e[1]) - (w[2] * jw0 - w[0] * jw2)"),
         ("c * e[2]) + (w[0] * jw1 - w[1] * jw0)", "c * e[2]) - (w[0] * jw1 - w[1] * jw0)")),
        "tau_0 cancels the gyroscopic torque with + w x J0 w",
        (f"{ATT}::test_nominal_law_13_imposes_the_error_dynamics_8_on_the_nominal_model",),
    ),
    Mutation(
        "feedback vector without eta~ (unwinding)", "companion/control/attitude.py",
        (("    k = 2.0 * q_err[0]\n", "    k = 2.0\n"),),
        "e = 2 eta~ eps~ is the same for q and -q; 2 eps~ alone unwinds",
        (f"{ATT}::test_q_and_minus_q_give_the_same_torque",),
    ),
    Mutation(
        "ISM starts off the surface (z(0) = 0)", "companion/control/attitude.py",
        (("        z = (-s0[0], -s0[1], -s0[2])  # z(0) = -s0(0): sliding from the first instant",
          "        z = (0.0, 0.0, 0.0)"),),
        "(11): z(0) = -s0(0) so that sliding starts at t = 0",
        (f"{ATT}::test_ism_starts_on_the_sliding_surface_and_resets_when_saturated",),
    ),
    Mutation(
        "no anti-windup reset", "companion/control/attitude.py",
        (("    if not anti_windup:\n", "    if True:\n"),),
        "[29]: outside the layer z is reset to -s0 and not integrated",
        (f"{ATT}::test_ism_starts_on_the_sliding_surface_and_resets_when_saturated",),
    ),
    Mutation(
        "sliding gain without J0", "companion/control/attitude.py",
        (("mul(mul(gains.sliding_gain_rad_s, inertia_kg_m2), eps)",
          "mul(gains.sliding_gain_rad_s, eps)"),),
        "K = k_s J0: without J0 the sliding term is ~300 times too strong",
        (f"{ATT}::test_pd_leaves_the_steady_error_the_do_removes",
         f"{ATT}::test_recovers_from_upside_down_with_either_quaternion_sign"),
    ),
    Mutation(
        "force observer adds the force", "companion/control/observers.py",
        (("return sub(scale(mass_kg, specific_force_ned_m_s2), force_ned_n)",
          "return add(scale(mass_kg, specific_force_ned_m_s2), force_ned_n)"),
         ("    lowpass_alpha,\n", "    add,\n    lowpass_alpha,\n")),
        "(30): h = m0 (r'' - g e3) - f",
        (f"{POS}::test_force_observer_converges_to_the_disturbance_and_removes_the_error",),
    ),
    Mutation(
        "force source ignored (always measured)", "companion/control/outer_loop.py",
        (("if commanded and has_command:", "if False:"),),
        "the paper's (30) subtracts the commanded force",
        (f"{SRC}::test_commanded_force_absorbs_the_inner_loop_error_and_pd_do_removes_it",),
    ),
    Mutation(
        "matching filter without its delay", "companion/control/observers.py",
        (("steps = int(round(delay_s / dt_s))", "steps = 0"),),
        "the force must see the acceleration's delay as well as its filters",
        (f"{OBS}::test_matching_filter_is_a_delay_followed_by_equal_first_order_lags",
         f"{OBS}::test_matched_force_observer_sees_no_disturbance_where_the_unmatched_one_sees_the_delay"),
    ),
    Mutation(
        "thrust quaternion axis sign (32)", "companion/control/reference.py",
        (("return (w / n, fy / n, -fx / n, 0.0 * fx)", "return (w / n, -fy / n, fx / n, 0.0 * fx)"),),
        "(32) corrected: the axis is (-e3) x f",
        (f"{REF}::test_thrust_quaternion_turns_hover_thrust_onto_the_force",),
    ),
    Mutation(
        "rate reference differentiates backwards (34)", "companion/control/reference.py",
        (("delta = quat.log(quat.relative(prev, q_d))", "delta = quat.log(quat.relative(q_d, prev))"),),
        "(34): omega_d = log(R_d,k-1^T R_d,k) / t_s",
        (f"{REF}::test_rate_reference_recovers_a_constant_rotation",),
    ),
    Mutation(
        "rate command not limited", "companion/control/reference.py",
        (("o, limit = st.omega_d, c.rate_limit_rad_s", "o, limit = st.omega_d, 1e9"),),
        "the gyro-safe 250 deg/s limit",
        (f"{REF}::test_rate_reference_never_exceeds_the_limit",),
    ),
    Mutation(
        "tilt cone not applied", "companion/control/reference.py",
        (("    h_max = up * math.tan(tilt_max_rad)\n", "    h_max = up * 1e9\n"),),
        "limit_force keeps the thrust within tilt_max of vertical",
        (f"{REF}::test_force_limit_respects_tilt_and_keeps_direction",),
    ),
    Mutation(
        "AIBC integral coefficient c1 lam instead of c2 lam", "companion/control/position.py",
        (("k_i=tuple(c2[i] * lam[i] for i in range(3))",
          "k_i=tuple(c1[i] * lam[i] for i in range(3))"),),
        "the gain-matched AIBC's integral gain is c2 lam",
        (f"{POS}::test_aibc_closed_loop_has_the_pid_poles",),
    ),
    Mutation(
        "PID integral gain omega_c / 2", "companion/control/params.py",
        (("return (0.25 * w[0], 0.25 * w[1], 0.25 * w[2])", "return (0.5 * w[0], 0.5 * w[1], 0.5 * w[2])"),),
        "section V: K_i = omega_c / 4",
        ("tests/control/test_params.py::test_defaults_are_the_papers",
         f"{POS}::test_aibc_closed_loop_has_the_pid_poles"),
    ),
    Mutation(
        "position ISM integrates the velocity gain", "companion/control/position.py",
        (("mul(c.k_p, pos_err_m), eps, c.dt_s, c.anti_windup)",
          "mul(c.k_v, pos_err_m), eps, c.dt_s, c.anti_windup)"),),
        "(31): s_p integrates K_p r~",
        (f"{POS}::test_ism_do_closed_loop_is_the_pid_inside_the_layer",),
    ),
    Mutation(
        "INDI without its rotor model", "companion/control/observers.py",
        (("a_act = 1.0 - math.exp(-dt_s / tc) if tc > 0.0 else 1.0", "a_act = 1.0"),),
        "INDI must compare w' with the torque the rotors produce, not the one requested",
        (f"{INDI}::test_indi_measures_the_torque_through_its_second_order_filter",),
    ),
    Mutation(
        "INDI filters only the gyro", "companion/control/observers.py",
        (("    s3 = lowpass_step(s3, s2, alpha)\n", "    s3 = s2\n"),),
        "INDI's two signals must pass the same filter, or the difference holds its own lag",
        (f"{INDI}::test_indi_measures_the_torque_through_its_second_order_filter",),
    ),
    Mutation(
        "allocation roll row sign", "companion/control/allocation.py",
        (("tx, ty = arm * kf * (w2 - w4),", "tx, ty = arm * kf * (w4 - w2),"),),
        "(4) in FRD: a positive tau_x rolls right",
        (f"{ALLOC}::test_positive_roll_torque_rolls_right",),
    ),
)


def _copy_tree(dest: Path) -> None:
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".hypothesis", "*.ulg", "*.tlog")
    for name in COPIED:
        shutil.copytree(REPO / name, dest / name, ignore=ignore, symlinks=True)
    shutil.copy2(REPO / "pyproject.toml", dest / "pyproject.toml")


def apply(mutation: Mutation, root: Path) -> None:
    """Apply ``mutation`` to the copy under ``root`` (each old text exactly once)."""
    path = root / mutation.path
    text = path.read_text()
    for old, new in mutation.edits:
        n = text.count(old)
        if n != 1:
            raise ValueError(f"mutation {mutation.name!r}: {old!r} occurs {n} times in {mutation.path}")
        text = text.replace(old, new)
    path.write_text(text)


def run_one(mutation: Mutation, timeout_s: float = 300.0) -> Outcome:
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="mutation-") as tmp:
        root = Path(tmp)
        _copy_tree(root)
        apply(mutation, root)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        env["MPLBACKEND"] = "Agg"
        # the mutated source itself runs, interpreted: a compiled kernel would first have to be
        # compiled for each copy (a cold cache), tens of seconds per mutation
        env["NUMBA_DISABLE_JIT"] = "1"
        cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "--no-header",
               "-o", "addopts=", *mutation.tests]
        try:
            proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=timeout_s)
            out = proc.stdout[-2000:] + proc.stderr[-2000:]
            # exit 1: tests failed (caught). 0: passed (survived). Anything else (no tests
            # collected, usage error) means the entry is broken, which is an error, not a catch.
            if proc.returncode not in (0, 1):
                raise RuntimeError(f"mutation {mutation.name!r}: pytest exit {proc.returncode}\n{out}")
            caught = proc.returncode == 1
        except subprocess.TimeoutExpired:
            out, caught = f"timed out after {timeout_s:.0f} s", True
    return Outcome(mutation, caught, time.monotonic() - t0, out)


def run_all(mutations: tuple[Mutation, ...] = MUTATIONS, jobs: int = 2) -> list[Outcome]:
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(run_one, mutations))


def report(outcomes: list[Outcome]) -> str:
    caught = sum(o.caught for o in outcomes)
    lines = [
        "# Mutation check of the control core",
        "",
        "A named list of deliberate bugs (`tests/helpers/mutations.py`), each applied to a copy of the",
        "source and run against the fast tests named for it. CI runs the list (`tests/test_mutations.py`)",
        "and fails if any mutation survives. Regenerate this page with `make mutations`.",
        "",
        f"**Score: {caught} / {len(outcomes)} caught ({100.0 * caught / max(len(outcomes), 1):.0f} %).**",
        "",
        "| mutation | file | why it matters | caught by | result |",
        "|---|---|---|---|---|",
    ]
    for o in outcomes:
        m = o.mutation
        tests = "<br>".join(f"`{t.split('::')[-1]}`" for t in m.tests)
        lines.append(f"| {m.name} | `{m.path}` | {m.why} | {tests} | {'caught' if o.caught else '**survived**'} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--report", type=Path, help="write the markdown score here")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", help="run only mutations whose name contains this text")
    args = ap.parse_args(argv)
    chosen = tuple(m for m in MUTATIONS if args.only is None or args.only in m.name)
    outcomes = run_all(chosen, args.jobs)
    for o in outcomes:
        print(f"{'caught  ' if o.caught else 'SURVIVED'} {o.seconds:5.1f} s  {o.mutation.name}")
    if args.report:
        args.report.write_text(report(outcomes))
    return 0 if all(o.caught for o in outcomes) else 1


if __name__ == "__main__":
    raise SystemExit(main())
