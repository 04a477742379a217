"""Figures in the spirit of the paper's Figs. 6-10, written to PNG files (headless).

Each scenario names its figure (``Scenario.figure``); :func:`draw` dispatches. Every figure
takes the flight logs of one experiment (all controller combinations, one seed unless it is a
box plot over seeds).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .metrics import euler_deg, rate_cmd_deg_s, tilt_deg  # noqa: E402
from companion.control.names import controller_label, controller_style  # noqa: E402

from .simulation import FlightLog  # noqa: E402

__all__ = ["FIGURES", "draw", "label", "boxplot_figure"]



def label(log: FlightLog) -> str:
    return f"{controller_label(log.position)} / att. {controller_label(log.attitude)}"


def _style(log: FlightLog) -> dict[str, object]:
    return {**controller_style(log.position, log.attitude), "lw": 1.2}


def _shade_forces(ax: plt.Axes, log: FlightLog) -> None:
    for p in log.scenario.forces + log.scenario.torques:
        if p.kind != "constant":
            ax.axvspan(p.start_s, min(p.stop_s, float(log.t[-1])), color="0.92", zorder=0)


def _save(fig: plt.Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def step_force(logs: Sequence[FlightLog], path: Path) -> Path:
    """Fig. 6: position error along the force and the force estimate."""
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for log in logs:
        ax.plot(log.t, log["x"] - log["x_ref"], label=label(log), **_style(log))
        ax2.plot(log.t, log["hfx_hat"], **_style(log))
    ax2.plot(logs[0].t, logs[0]["hfx"], color="k", lw=0.8, label="true lumped force")
    for a in (ax, ax2):
        _shade_forces(a, logs[0])
        a.grid(alpha=0.3)
    ax.set_ylabel("x error [m]")
    ax2.set_ylabel("x disturbance estimate [N]")
    ax2.set_xlabel("time [s]")
    ax.legend(fontsize=8)
    ax2.legend(fontsize=8)
    ax.set_title(logs[0].scenario.description)
    return _save(fig, path)


def chirp_torque(logs: Sequence[FlightLog], path: Path) -> Path:
    """Fig. 7: roll, torque and its estimate, sliding variable, y force estimate."""
    fig, axs = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    for log in logs:
        roll, _, _ = euler_deg(log)
        axs[0].plot(log.t, roll, label=label(log), **_style(log))
        axs[1].plot(log.t, log["htx_hat"], **_style(log))
        axs[2].plot(log.t, log["sx_att"], **_style(log))
        axs[3].plot(log.t, log["hfy_hat"], **_style(log))
    axs[1].plot(logs[0].t, logs[0]["htx"], color="k", lw=0.6, label="true roll torque")
    axs[3].plot(logs[0].t, logs[0]["hfy"], color="k", lw=0.6, label="true y force")
    for level in (60, -60):
        axs[0].axhline(level, color="k", lw=0.5)
    for a, yl in zip(axs, ["roll [deg]", "roll torque estimate [N m]", "sliding variable s_x [rad/s]",
                           "y force estimate [N]"]):
        _shade_forces(a, logs[0])
        a.set_ylabel(yl)
        a.grid(alpha=0.3)
    for a in (axs[0], axs[1], axs[3]):
        a.legend(fontsize=7, loc="lower right")
    axs[-1].set_xlabel("time [s]")
    axs[0].set_title(logs[0].scenario.description, fontsize=9)
    return _save(fig, path)


def waypoints(logs: Sequence[FlightLog], path: Path) -> Path:
    """Fig. 9: position and velocity tracking, tilt, commanded rate against its limit, yaw."""
    fig, axs = plt.subplots(5, 1, figsize=(8, 11), sharex=True)
    ref = logs[0]
    for k, axis in enumerate("xyz"):
        axs[0].plot(ref.t, ref[f"{axis}_ref"], color="k", lw=0.7, linestyle=["-", "--", ":"][k],
                    label=f"{axis} reference")
    for log in logs:
        axs[0].plot(log.t, log["x"], **_style(log), label=label(log))
        axs[0].plot(log.t, log["y"], **_style(log))
        axs[0].plot(log.t, log["z"], **_style(log))
        speed = np.sqrt(log["vx"] ** 2 + log["vy"] ** 2 + log["vz"] ** 2)
        axs[1].plot(log.t, speed, **_style(log))
        axs[2].plot(log.t, tilt_deg(log), **_style(log))
        axs[3].plot(log.t, rate_cmd_deg_s(log), **_style(log))
        axs[4].plot(log.t, np.degrees(np.unwrap(np.radians(euler_deg(log)[2]))), **_style(log))
    speed_ref = np.sqrt(ref["vx_ref"] ** 2 + ref["vy_ref"] ** 2 + ref["vz_ref"] ** 2)
    axs[1].plot(ref.t, speed_ref, color="k", lw=0.7, label="reference speed")
    limit = np.degrees(ref.scenario.reference.rate_limit_rad_s)
    axs[3].axhline(limit, color="k", lw=0.7, label="rate limit")
    axs[4].plot(ref.t, np.degrees(np.unwrap(ref["yaw_ref"])), color="k", lw=0.7, label="yaw reference")
    for a, yl in zip(axs, ["position [m]", "speed [m/s]", "tilt [deg]", "|omega_d| [deg/s]", "yaw [deg]"]):
        a.set_ylabel(yl)
        a.grid(alpha=0.3)
    axs[0].legend(fontsize=6, ncol=2)
    axs[1].legend(fontsize=7)
    axs[3].legend(fontsize=7)
    axs[4].legend(fontsize=7)
    axs[-1].set_xlabel("time [s]")
    axs[0].set_title(ref.scenario.description, fontsize=9)
    return _save(fig, path)


def suspended_weight(logs: Sequence[FlightLog], path: Path) -> Path:
    """Fig. 10: x position, pitch and force estimate around attachment (left) and release (right)."""
    segs = logs[0].scenario.segments
    windows = [(s.start_s - 1.0, min(s.start_s + 8.0, s.stop_s)) for s in segs[:2]]
    fig, axs = plt.subplots(3, 2, figsize=(10, 8), sharex="col")
    for col, (lo, hi) in enumerate(windows):
        for log in logs:
            m = (log.t >= lo) & (log.t <= hi)
            _, pitch, _ = euler_deg(log)
            axs[0, col].plot(log.t[m], log["x"][m] - log["x_ref"][m], label=label(log), **_style(log))
            axs[1, col].plot(log.t[m], pitch[m], **_style(log))
            axs[2, col].plot(log.t[m], log["hfx_hat"][m], **_style(log))
        m = (logs[0].t >= lo) & (logs[0].t <= hi)
        axs[2, col].plot(logs[0].t[m], logs[0]["hfx"][m], color="k", lw=0.7, label="true lumped force")
        axs[2, col].set_xlabel("time [s]")
        axs[0, col].set_title(["force applied", "force released"][col])
    for row, yl in enumerate(["x error [m]", "pitch [deg]", "x disturbance estimate [N]"]):
        axs[row, 0].set_ylabel(yl)
        for col in range(2):
            axs[row, col].grid(alpha=0.3)
    axs[0, 0].legend(fontsize=7)
    axs[2, 0].legend(fontsize=7)
    fig.suptitle(logs[0].scenario.description, fontsize=9)
    return _save(fig, path)


def generic(logs: Sequence[FlightLog], path: Path) -> Path:
    fig, axs = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for log in logs:
        err = np.sqrt((log["x"] - log["x_ref"]) ** 2 + (log["y"] - log["y_ref"]) ** 2 + (log["z"] - log["z_ref"]) ** 2)
        axs[0].plot(log.t, err, label=label(log), **_style(log))
        axs[1].plot(log.t, tilt_deg(log), **_style(log))
        axs[2].plot(log.t, np.sqrt(log["hfx_hat"] ** 2 + log["hfy_hat"] ** 2), **_style(log))
    for a, yl in zip(axs, ["position error [m]", "tilt [deg]", "horizontal force estimate [N]"]):
        a.set_ylabel(yl)
        a.grid(alpha=0.3)
    axs[0].legend(fontsize=7)
    axs[-1].set_xlabel("time [s]")
    return _save(fig, path)


def boxplot_figure(groups: dict[str, dict[str, list[float]]], title: str, path: Path) -> Path:
    """Fig. 8: box plots of a metric per controller combination.

    ``groups`` maps a panel title to ``{combination label: values over seeds}``.
    """
    fig, axs = plt.subplots(1, len(groups), figsize=(6 * len(groups), 4.5), squeeze=False)
    for ax, (panel, data) in zip(axs[0], groups.items()):
        names = list(data)
        ax.boxplot([data[n] for n in names], showfliers=True)
        ax.set_xticks(range(1, len(names) + 1), names, rotation=40, ha="right", fontsize=8)
        ax.set_title(panel, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)


FIGURES: dict[str, Callable[[Sequence[FlightLog], Path], Path]] = {
    "step_force": step_force,
    "chirp_torque": chirp_torque,
    "waypoints": waypoints,
    "suspended_weight": suspended_weight,
    "generic": generic,
}


def draw(logs: Sequence[FlightLog], path: Path) -> Path:
    return FIGURES.get(logs[0].scenario.figure, generic)(logs, path)


