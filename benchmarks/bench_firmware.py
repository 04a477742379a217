"""The paper's experiments on the real firmware: PX4 v1.16 and ArduCopter fly the project's plant
(``sitl --firmware``, lockstep) with the paper's disturbances, under the companion's ISM+DO, PD+DO
and PID and under the autopilot's own position control (``--controller autopilot``: the same
reference as position targets), same plant, seeds and disturbance.

    python benchmarks/bench_firmware.py [--firmware px4 ardupilot] [--seeds 1 2 3] [--out docs]

Experiments (missions/): ``hover45`` — the 6 N weight attached for 20 s (the 45 deg hover), then
released (E5, Fig. 10); ``step`` — a 2 N step for 7 s (E1, Fig. 6); ``wind`` — hover in 3 m/s
wind with 0.6 m/s turbulence (E3, Fig. 8b); ``square`` — the 4 m square at 2 m/s in a constant
3 m/s wind. One boot per flight. Prints a markdown table (medians over the seeds of each
segment's RMS and peak position error) and draws docs/figures/firmware_experiments.png.
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

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from companion.control.names import CONTROLLER_LABELS  # noqa: E402
from benchmarks.figures import save_figure  # noqa: E402
from companion.plots import load_timeseries  # noqa: E402
from companion.vehicle_process import FirmwareVehicle  # noqa: E402
from sitl.firmware.builds import arducopter_binary, px4_build  # noqa: E402

EXPERIMENTS = {
    "hover45": ("missions/hover45.toml", ("45 deg hover", "after release")),
    "step": ("missions/step_force.toml", ("force on", "released")),
    "wind": ("missions/wind_hover.toml", ("hover in wind",)),
    "square": ("missions/square_wind.toml", ("square",)),
}
CONTROLLERS = ("ism_do", "pd_do", "pid", "autopilot")
LABELS = {**CONTROLLER_LABELS, "autopilot": "autopilot's own",
          "ism_do_shaped": "ISM+DO, ArduCopter's input shaping kept"}
TILT_PARAM = {"px4": "MPC_TILTMAX_AIR", "ardupilot": "ATC_ANGLE_MAX"}
FAILURES: list[str] = []
FLIGHT_WALL_S = 400.0
"""a flight takes 5-60 s of wall time; one that has not ended in this long is killed and listed"""


def fly(firmware: str, mission: str, controller: str, seed: int, speedup: float, out: Path,
        firmware_params: dict[str, float], companion_args: tuple[str, ...] = (), again: bool = True) -> Path | None:
    args = [f"--seed={seed}", *(f"--firmware-param={k}={v:g}" for k, v in firmware_params.items())]
    vehicle = FirmwareVehicle(firmware, *args, speedup=speedup, instance=7)
    try:
        r = subprocess.run([sys.executable, "-m", "companion", "fly", str(ROOT / mission), "--connect", vehicle.url,
                            "--controller", controller, "--out", str(out), "--no-plots", "--quiet",
                            "--connect-timeout", "120", *companion_args], capture_output=True, text=True,
                           timeout=FLIGHT_WALL_S, cwd=ROOT)
    except subprocess.TimeoutExpired:
        FAILURES.append(f"{firmware} {Path(mission).stem} {controller} seed {seed}: the companion did not end "
                        f"within {FLIGHT_WALL_S:.0f} s of wall time (killed; its record is incomplete)")
        return None
    finally:
        vehicle.stop(timeout_s=30)
    said = (r.stdout + r.stderr).strip()  # a flight that ends badly names its folder on stderr
    folder = Path(said.rsplit(" -> ", 1)[-1].split()[0]) if " -> " in said else None
    if r.returncode != 0 and folder is not None and (folder / "segments.json").exists():
        data = json.loads((folder / "segments.json").read_text())
        failed = [s["name"] for s in data["segments"] if not s["ok"]]
        print(f"  ({firmware} {mission} {controller} seed {seed}: the flight ended '{data['result']}' in "
              f"{', '.join(failed) or '?'}: {data['message']})", flush=True)
        FAILURES.append(f"{firmware} {Path(mission).stem} {controller} seed {seed}: {data['message']}")
        return folder  # its segments before the failure still count; the table lists the failure
    if r.returncode != 0 or folder is None:
        if "Address already in use" in r.stdout + r.stderr and again:
            time.sleep(2.0)  # the previous flight's sockets are still closing: once more
            return fly(firmware, mission, controller, seed, speedup, out, firmware_params, companion_args, False)
        raise RuntimeError(f"{firmware} {mission} {controller} seed {seed}: {r.stdout[-2000:]}{r.stderr[-2000:]}")
    return folder


JUMP_M = 1.0
"""a position change between two 100 Hz samples no vehicle can fly (100 m/s): the estimator reset"""
JUMP_SPEED_M_S = 20.0
"""...and, between samples further apart (the record thins out before the flight), faster than this"""


def estimator_jump(folder: Path) -> tuple[float, float] | None:
    """(time [s], size [m]) of the first jump of the estimated position, or None."""
    d = load_timeseries(folder)
    step = np.sqrt(np.diff(d["x"]) ** 2 + np.diff(d["y"]) ** 2 + np.diff(d["z"]) ** 2)
    limit = np.maximum(JUMP_M, JUMP_SPEED_M_S * np.diff(d["t"]))
    bad = np.flatnonzero(np.nan_to_num(step, nan=0.0) > limit)
    return None if bad.size == 0 else (float(d["t"][bad[0] + 1]), float(step[bad[0]]))


def segments(folder: Path, names: tuple[str, ...], flight: str) -> dict[str, dict]:
    """The named segments of a flight; those after an estimator jump are dropped (and listed)."""
    data = json.loads((folder / "segments.json").read_text())
    found = {s["name"]: s for s in data["segments"] if s["name"] in names and s["rms_error_m"] is not None}
    jump = estimator_jump(folder)
    if jump is not None:
        t, size = jump
        FAILURES.append(f"{flight}: the estimated position jumped {size:.1f} m at t = {t:.1f} s; "
                        "segments from then on dropped")
        found = {n: s for n, s in found.items() if s["t_end"] < t}
    missing = set(names) - set(found)
    if missing and jump is None:
        FAILURES.append(f"{flight}: no {', '.join(sorted(missing))} segment: {data['message']}")
    return found


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--firmware", nargs="+", default=["px4", "ardupilot"], choices=["px4", "ardupilot"])
    ap.add_argument("--experiments", nargs="+", default=list(EXPERIMENTS), choices=list(EXPERIMENTS))
    ap.add_argument("--controllers", nargs="+", default=list(CONTROLLERS), choices=list(CONTROLLERS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    ap.add_argument("--speedup", type=float, default=20.0, help="upper bound; lockstep sets the pace")
    ap.add_argument("--tilt", type=float, default=0.0,
                    help="also fly the autopilot's own control with its tilt limit raised to this [deg] "
                         "(PX4 MPC_TILTMAX_AIR, ArduCopter ATC_ANGLE_MAX; default: only their defaults)")
    ap.add_argument("--shaping", action="store_true",
                    help="on ArduCopter, also fly ISM+DO with its attitude input shaping kept (--ardupilot-shaping)")
    ap.add_argument("--out", default=str(ROOT / "docs"))
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-firmware-"))
    found = {"px4": px4_build()[0], "ardupilot": arducopter_binary()[0]}
    results: dict[tuple[str, str, str], list[dict[str, dict]]] = {}
    folders: dict[tuple[str, str, str], Path] = {}
    t0 = time.monotonic()
    for firmware in args.firmware:
        if found[firmware] is None:
            print(f"skipped {firmware}: {(px4_build if firmware == 'px4' else arducopter_binary)()[1]}")
            continue
        variants: list[tuple[str, dict[str, float], tuple[str, ...]]] = [(c, {}, ()) for c in args.controllers]
        if args.tilt and "autopilot" in args.controllers:
            variants.append((f"autopilot_tilt{args.tilt:g}", {TILT_PARAM[firmware]: args.tilt}, ()))
        if args.shaping and firmware == "ardupilot" and "ism_do" in args.controllers:
            variants.append(("ism_do_shaped", {}, ("--ardupilot-shaping",)))
        for experiment in args.experiments:
            mission, names = EXPERIMENTS[experiment]
            for controller, params, extra in variants:
                for seed in args.seeds:
                    folder = fly(firmware, mission, controller.split("_tilt")[0].removesuffix("_shaped"), seed,
                                 args.speedup, work / firmware / experiment, params, extra)
                    key = (firmware, experiment, controller)
                    if folder is None:
                        continue
                    seg = segments(folder, names, f"{firmware} {experiment} {controller} seed {seed}")
                    results.setdefault(key, []).append(seg)
                    if seed == args.seeds[0]:
                        folders[key] = folder
                    print(f"{firmware} {experiment} {controller} seed {seed}: " + "; ".join(
                        f"{n} RMS {s['rms_error_m']:.3f} peak {s['peak_error_m']:.3f} m, tilt {s['peak_tilt_deg']:.0f}"
                        for n, s in seg.items()), flush=True)
    print(f"\n{len(args.seeds)} seed(s) per cell, medians; one boot per flight; {time.monotonic() - t0:.0f} s wall\n")
    print("| firmware | experiment | segment | controller | RMS [m] | peak [m] | peak tilt [deg] | "
          "RMS / autopilot's | peak / autopilot's |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (firmware, experiment, controller), runs in results.items():
        base = results.get((firmware, experiment, "autopilot"))
        for name in EXPERIMENTS[experiment][1]:
            flown = [r[name] for r in runs if name in r]
            if not flown:
                continue
            rms = statistics.median(r["rms_error_m"] for r in flown)
            peak = statistics.median(r["peak_error_m"] for r in flown)
            tilt = statistics.median(r["peak_tilt_deg"] for r in flown)
            base_flown = [r[name] for r in base or [] if name in r]
            if base_flown and controller != "autopilot":
                b_rms = statistics.median(r["rms_error_m"] for r in base_flown)
                b_peak = statistics.median(r["peak_error_m"] for r in base_flown)
                ratio = f"{rms / b_rms:.2f} | {peak / b_peak:.2f}"
            else:
                ratio = "- | -"
            if len(flown) < len(args.seeds):
                name += f" ({len(flown)} of {len(args.seeds)} seeds)"
            label = LABELS.get(controller, controller.replace("autopilot_tilt", "autopilot's own, tilt ") + " deg")
            print(f"| {firmware} | {experiment} | {name} | {label} | {rms:.3f} | {peak:.3f} | {tilt:.0f} | {ratio} |")
    if FAILURES:
        print("\nflights that did not complete (their earlier segments are in the table):")
        for f in FAILURES:
            print(f"- {f}")
    if folders:
        draw(folders, args, Path(args.out) / "figures" / "firmware_experiments.png")
    return 0


COLOURS = {"ism_do": "tab:blue", "pd_do": "tab:green", "pid": "tab:red", "autopilot": "tab:orange",
           "ism_do_shaped": "tab:cyan"}


def draw(folders: dict[tuple[str, str, str], Path], args: argparse.Namespace, path: Path) -> None:
    """Position error against time from the first measured segment's start, first seed, one panel
    per firmware and experiment; a flight that ended early is drawn dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [(f, e) for f in args.firmware for e in args.experiments if any(k[:2] == (f, e) for k in folders)]
    fig, axs = plt.subplots(len(rows), 1, figsize=(9, 2.6 * len(rows)), squeeze=False)
    for ax, (firmware, experiment) in zip(axs[:, 0], rows):
        names = EXPERIMENTS[experiment][1]
        for (f, e, controller), folder in folders.items():
            if (f, e) != (firmware, experiment):
                continue
            data = json.loads((folder / "segments.json").read_text())
            measured = [s for s in data["segments"] if s["name"] in names]
            if not measured:
                continue
            t0, t1 = measured[0]["t_start"], measured[-1]["t_end"]
            jump = estimator_jump(folder)
            if jump is not None:
                t1 = min(t1, jump[0])
            d = load_timeseries(folder)
            keep = (d["t"] >= t0 - 2.0) & (d["t"] <= t1)
            ended = data["result"] != "completed" or jump is not None
            label = LABELS.get(controller, controller.replace("autopilot_tilt", "autopilot's own, tilt ") + " deg")
            ax.plot(d["t"][keep] - t0, d["error_m"][keep], lw=0.8, ls="--" if ended else "-",
                    color=COLOURS.get(controller, "tab:purple" if "tilt" in controller else "tab:gray"),
                    label=label + (" (ended early)" if ended else ""))
        ax.set_title(f"{firmware}: {experiment}, {' then '.join(names)} (seed {args.seeds[0]})", fontsize=9)
        ax.set_ylabel("position error [m]")
        ax.set_yscale("log")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=3)
    axs[-1, 0].set_xlabel("time from the disturbance [s]")
    save_figure(fig, path)


if __name__ == "__main__":
    raise SystemExit(main())
