"""Plots of a flight record (``companion plot FLIGHT_DIR``), from its CSV and segment list.

One sheet: on the left, against vehicle time, north and east, altitude (drawn up: -down), the
tracking error, tilt, the commanded body rate, the force estimate and thrust; on the right, the
path seen from above (east to the right, north up) against the reference. Step names are staggered
so that they do not overwrite each other; every trace, dashed references included, is in a
legend; a flight cut short ends in a red cross with the reason.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

__all__ = ["load_timeseries", "draw_flight"]


def load_timeseries(folder: Path) -> dict[str, np.ndarray]:
    with open(folder / "timeseries.csv") as f:
        header = f.readline().strip().split(",")
        if not f.readline():
            return {name: np.zeros(0) for name in header}
    data = np.loadtxt(folder / "timeseries.csv", delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, i] for i, name in enumerate(header)}


def _tilt_deg(d: dict[str, np.ndarray]) -> np.ndarray:
    s = np.sqrt(d["qx"] ** 2 + d["qy"] ** 2)
    c = np.sqrt(d["qw"] ** 2 + d["qz"] ** 2)
    return np.degrees(2 * np.arctan2(s, c))


def draw_flight(folder: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    d = load_timeseries(folder)
    if len(d.get("t", ())) < 2:
        return []  # nothing was flown: nothing to draw
    meta = json.loads((folder / "segments.json").read_text()) if (folder / "segments.json").exists() else {}
    segs = meta.get("segments", [])
    t0 = d["t"][0]
    t = d["t"] - t0

    fig = plt.figure(figsize=(15, 14))
    grid = fig.add_gridspec(6, 2, width_ratios=(2.2, 1.0))
    axs = [fig.add_subplot(grid[0, 0])]
    axs += [fig.add_subplot(grid[i, 0], sharex=axs[0]) for i in range(1, 6)]
    top = fig.add_subplot(grid[0:3, 1])

    for axis, color, label in (("x", "tab:blue", "north"), ("y", "tab:orange", "east")):
        axs[0].plot(t, d[axis], color=color, lw=1.0, label=label)
        axs[0].plot(t, d[f"{axis}_ref"], color=color, lw=0.8, ls="--", label=f"{label} reference")
    alt = axs[0].twinx()
    alt.plot(t, -d["z"], color="tab:green", lw=1.0, label="altitude (up)")
    alt.plot(t, -d["z_ref"], color="tab:green", lw=0.8, ls="--", label="altitude reference")
    alt.set_ylabel("altitude, up [m]")
    axs[0].set_ylabel("north, east [m]")
    handles = axs[0].get_legend_handles_labels()
    more = alt.get_legend_handles_labels()
    axs[0].legend(handles[0] + more[0], handles[1] + more[1], fontsize=7, loc="lower left", ncol=3)

    err = d["error_m"] if "error_m" in d else np.sqrt(
        (d["x"] - d["x_ref"]) ** 2 + (d["y"] - d["y_ref"]) ** 2 + (d["z"] - d["z_ref"]) ** 2)
    axs[1].plot(t, err, color="k", lw=0.8, label="|position - reference| at the position's time")
    axs[1].set_ylabel("tracking error [m]")
    axs[2].plot(t, _tilt_deg(d), color="tab:red", lw=0.8, label="tilt")
    axs[2].set_ylabel("tilt [deg]")
    rate = np.degrees(np.sqrt(d["p_d"] ** 2 + d["q_d"] ** 2 + d["r_d"] ** 2))
    axs[3].plot(t, rate, color="tab:purple", lw=0.6, label="|omega_d| sent")
    axs[3].set_ylabel("body rate [deg/s]")
    for name, color, label in (("hfx", "tab:blue", "north"), ("hfy", "tab:orange", "east"),
                               ("hfz", "tab:green", "down")):
        axs[4].plot(t, d[name], color=color, lw=0.8, label=label)
    axs[4].set_ylabel("force estimate [N]")
    axs[5].plot(t, d["thrust"], color="tab:gray", lw=0.6, label="normalised thrust sent")
    axs[5].set_ylabel("thrust [0..1]")
    scale = axs[5].twinx()
    scale.plot(t, d["thrust_max_n"], color="tab:blue", lw=1.0, label="thrust scale in use [N]")
    scale.plot(t, d["thrust_max_est_n"], color="tab:cyan", lw=1.0, ls="--", label="its online estimate [N]")
    scale.set_ylabel("thrust scale [N]")
    h1, l1 = axs[5].get_legend_handles_labels()
    h2, l2 = scale.get_legend_handles_labels()
    axs[5].legend(h1 + h2, l1 + l2, fontsize=7, loc="lower right")
    for ax in axs[1:5]:
        ax.legend(fontsize=7, loc="upper right")
    axs[5].set_xlabel("vehicle time since the record began [s]")

    for ax in axs:
        ax.grid(alpha=0.3)
        for s in segs:
            if s.get("t_start") is not None and math.isfinite(s["t_start"] - t0):
                ax.axvline(s["t_start"] - t0, color="0.6", lw=0.6)
    for k, s in enumerate(segs):  # three staggered rows: neighbouring names never overwrite
        if s.get("t_start") is not None:
            axs[0].annotate(s["name"], (s["t_start"] - t0, 1.0 - 0.1 * (k % 3)), xycoords=("data", "axes fraction"),
                            fontsize=7, va="top", ha="left", color="0.3",
                            bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.7})

    top.plot(d["y"], d["x"], color="k", lw=0.9, label="flown")
    top.plot(d["y_ref"], d["x_ref"], color="tab:orange", lw=0.9, ls="--", label="reference")
    top.set_xlabel("east [m]")
    top.set_ylabel("north [m]")
    top.set_aspect("equal", adjustable="datalim")
    top.grid(alpha=0.3)
    top.set_title("seen from above", fontsize=9)

    result = meta.get("result", "")
    if result and result != "completed":
        for ax, x, y in ((axs[1], t[-1], err[-1]), (top, d["y"][-1], d["x"][-1])):
            ax.plot([x], [y], marker="X", color="red", ms=12, ls="none", label=f"cut short: {result}")
        top.annotate(f"{result}: {meta.get('message', '')}"[:90], (0.02, 0.02), xycoords="axes fraction",
                     fontsize=7, color="red")
    top.legend(fontsize=7, loc="upper right")
    fig.suptitle(f"{meta.get('mission', folder.name)}: {meta.get('controller', '')}, {result}")
    fig.tight_layout()
    out = folder / "flight.png"
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return [out]
