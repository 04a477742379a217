"""The companion against the autopilots' own position control, on the real firmware: the 4 m square
(missions/square_gps.toml) flown by PX4 v1.16 SIH and ArduCopter SITL themselves
(``--controller autopilot``: the same reference as position targets) and by the companion's ISM+DO,
in calm air and, where the simulator has wind (ArduPilot's SIM_WIND_*; PX4 v1.16's SIH has none),
in a constant 3 m/s wind. Each figure is a median over ``--runs`` flights in one boot.

    python benchmarks/bench_autopilots.py [--runs 3] [--out docs]

Prints a table (markdown) and draws docs/figures/autopilots_square.png; the firmware is found as
the tests find it (tests/helpers/firmware.py: PX4_SITL_BUILD, ARDUCOPTER_SITL, ~/autopilots).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from benchmarks.figures import save_figure  # noqa: E402
from companion.plots import load_timeseries  # noqa: E402
from tests.helpers.firmware import ArduCopterSitl, Px4Sih, find_arducopter, find_px4  # noqa: E402

PX4_SPEED, ARDUPILOT_SPEED = 4.0, 2.0


def fly(url: str, controller: str, out: Path) -> tuple[dict, Path]:
    r = subprocess.run([sys.executable, "-m", "companion", "fly", str(ROOT / "missions/square_gps.toml"), "--connect",
                        url, "--controller", controller, "--out", str(out), "--no-plots", "--quiet",
                        "--connect-timeout", "60"], capture_output=True, text=True, timeout=600, cwd=ROOT)
    folder = Path(r.stdout.strip().rsplit(" -> ", 1)[-1]) if " -> " in r.stdout else None
    if r.returncode != 0 or folder is None:
        raise RuntimeError(f"{controller} at {url}: {r.stdout[-2000:]}{r.stderr[-2000:]}")
    data = json.loads((folder / "segments.json").read_text())
    return next(s for s in data["segments"] if s["name"] == "square"), folder


def session(name: str, start, url_of, runs: int, work: Path) -> dict:
    """One boot: the autopilot's own control and the companion, alternating, ``runs`` times each."""
    figures: dict[str, list[dict]] = {"autopilot": [], "ism_do": []}
    folders: dict[str, Path] = {}
    t0 = time.monotonic()
    with start() as vehicle:
        for _ in range(runs):
            for controller in ("autopilot", "ism_do"):
                seg, folder = fly(url_of(vehicle), controller, work / name)
                figures[controller].append(seg)
                folders.setdefault(controller, folder)
    return {"figures": figures, "folders": folders, "wall_s": time.monotonic() - t0}


def median(segs: list[dict], key: str) -> float:
    return statistics.median(s[key] for s in segs)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "docs"))
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-autopilots-"))
    rows, sessions = [], {}
    px4, why_px4 = find_px4()
    copter, why_copter = find_arducopter()
    plan = []
    if px4 is not None:
        plan.append(("PX4 v1.16 SIH, calm", lambda: Px4Sih(px4, speed=PX4_SPEED), lambda v: v.url))
    else:
        print(f"skipped PX4: {why_px4}")
    if copter is not None:
        plan.append(("ArduCopter SITL, calm", lambda: ArduCopterSitl(copter, speedup=ARDUPILOT_SPEED), lambda v: v.url))
        # SIM_WIND_T 1: no height profile (with the default the wind is nil near the ground)
        wind = {"SIM_WIND_SPD": 3.0, "SIM_WIND_DIR": 0.0, "SIM_WIND_TURB": 0.0, "SIM_WIND_T": 1.0}
        plan.append(("ArduCopter SITL, 3 m/s wind", lambda: ArduCopterSitl(copter, speedup=ARDUPILOT_SPEED,
                                                                           params=wind), lambda v: v.url))
    else:
        print(f"skipped ArduCopter: {why_copter}")
    for name, start, url_of in plan:
        s = session(name.split(",")[0].split()[0] + "_" + str(len(sessions)), start, url_of, args.runs, work)
        sessions[name] = s
        f = s["figures"]
        rows.append((name, median(f["autopilot"], "rms_error_m"), median(f["ism_do"], "rms_error_m"),
                     median(f["autopilot"], "peak_error_m"), median(f["ism_do"], "peak_error_m"), s["wall_s"]))
    print(f"\nsquare_gps, median of {args.runs} flights each, one boot per row\n")
    print("| firmware, air | autopilot RMS [m] | ISM+DO RMS [m] | autopilot peak [m] | ISM+DO peak [m] "
          "| ISM+DO / autopilot (RMS) | wall [s] |")
    print("|---|---|---|---|---|---|---|")
    for name, a_rms, c_rms, a_pk, c_pk, wall in rows:
        print(f"| {name} | {a_rms:.3f} | {c_rms:.3f} | {a_pk:.3f} | {c_pk:.3f} | {c_rms / a_rms:.2f} | {wall:.0f} |")
    if sessions:
        draw(sessions, Path(args.out) / "figures" / "autopilots_square.png")
    return 0


def draw(sessions: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, len(sessions), figsize=(5.2 * len(sessions), 5.0), squeeze=False)
    for ax, (name, s) in zip(axs[0], sessions.items()):
        for controller, style in (("autopilot", dict(color="tab:orange", label="autopilot's own position control")),
                                  ("ism_do", dict(color="tab:blue", label="companion, ISM+DO"))):
            d = load_timeseries(s["folders"][controller])
            flying = d["offboard"] == 1
            ax.plot(d["y"][flying], d["x"][flying], lw=0.9, **style)
        d = load_timeseries(s["folders"]["ism_do"])
        ax.plot(d["y_ref"], d["x_ref"], color="k", lw=0.7, ls="--", label="reference")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("east [m]")
        ax.set_ylabel("north [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="center")
    fig.suptitle("The 4 m square at 2 m/s on the real firmware (first flight of each)")
    save_figure(fig, path)


if __name__ == "__main__":
    raise SystemExit(main())
