"""Plots of a flight record (``companion plot FLIGHT_DIR``), from its CSV and segment list."""

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
    t = d["t"] - d["t"][0] if len(d["t"]) else d["t"]
    t0 = d["t"][0] if len(d["t"]) else 0.0

    fig, axs = plt.subplots(6, 1, figsize=(10, 14), sharex=True)
    for i, (axis, color) in enumerate(zip("xyz", ("tab:blue", "tab:orange", "tab:green"))):
        axs[0].plot(t, d[axis], color=color, lw=1.0, label=f"{axis} (N/E/D)"[0] + " " + "NED"[i])
        axs[0].plot(t, d[f"{axis}_ref"], color=color, lw=0.8, ls="--")
    axs[0].set_ylabel("position [m]\n(dashed: reference)")
    if "error_m" in d:  # against the reference at the position's own time (recorder.py)
        err = d["error_m"]
    else:  # records written before that column
        err = np.sqrt((d["x"] - d["x_ref"]) ** 2 + (d["y"] - d["y_ref"]) ** 2 + (d["z"] - d["z_ref"]) ** 2)
    axs[1].plot(t, err, color="k", lw=0.8)
    axs[1].set_ylabel("position error [m]")
    axs[2].plot(t, _tilt_deg(d), color="tab:red", lw=0.8)
    axs[2].set_ylabel("tilt [deg]")
    rate = np.degrees(np.sqrt(d["p_d"] ** 2 + d["q_d"] ** 2 + d["r_d"] ** 2))
    axs[3].plot(t, rate, color="tab:purple", lw=0.6)
    axs[3].set_ylabel("|omega_d| [deg/s]")
    for name, color in (("hfx", "tab:blue"), ("hfy", "tab:orange"), ("hfz", "tab:green")):
        axs[4].plot(t, d[name], color=color, lw=0.8, label=name[2].upper() if name != "hfz" else "D")
    axs[4].set_ylabel("force estimate\nN / E / D [N]")
    axs[4].legend(fontsize=7, loc="upper left", labels=["north", "east", "down"])
    axs[5].plot(t, d["thrust"], color="tab:gray", lw=0.6, label="normalised thrust sent")
    ax2 = axs[5].twinx()
    ax2.plot(t, d["thrust_max_n"], color="tab:blue", lw=1.0, label="scale in use")
    ax2.plot(t, d["thrust_max_est_n"], color="tab:cyan", lw=1.0, ls="--", label="online estimate")
    ax2.set_ylabel("thrust scale [N]")
    ax2.legend(fontsize=7, loc="lower right")
    axs[5].set_ylabel("thrust [0..1]")
    axs[5].set_xlabel("vehicle time since start [s]")
    for ax in axs:
        ax.grid(alpha=0.3)
        for s in segs:
            if s.get("t_start") is not None and math.isfinite(s["t_start"] - t0):
                ax.axvline(s["t_start"] - t0, color="0.6", lw=0.6)
    for s in segs:
        if s.get("t_start") is not None:
            axs[0].annotate(s["name"], (s["t_start"] - t0, 1.0), xycoords=("data", "axes fraction"),
                            fontsize=6, rotation=90, va="top", ha="right")
    axs[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"{meta.get('mission', folder.name)}: {meta.get('controller', '')}, {meta.get('result', '')}")
    fig.tight_layout()
    out = folder / "flight.png"
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return [out]
