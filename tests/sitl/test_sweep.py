"""Sweeps: case tables, resumption, failures kept, and the cluster path giving the same numbers."""

import csv
import math

import pytest

from companion.config import ConfigError
from sitl.lab.sweep import fly_batch, load_sweep, plan, run_sweep

SMALL = """name = "small"
scenario = "E3_wind"
duration_s = 3.0
window_s = [1.0, 3.0]
position = ["pd_do", "ism_do"]
attitude = ["ism_do"]
seeds = { first = 1, count = 4 }
metrics = ["rms_horizontal_error_m", "peak_error_m"]
batch_size = 2

[grid]
wind_speed_m_s = [0.0, 3.0]
"""


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def rows(table):
    with open(table, newline="") as f:
        return list(csv.DictReader(f))


def test_every_case_becomes_one_row_and_a_rerun_skips_them(tmp_path):
    spec = load_sweep(write(tmp_path, SMALL))
    assert plan(spec)[1] == 2 * 2 * 4  # controllers x wind speeds x seeds
    table = run_sweep(spec, tmp_path / "out", jobs=2, progress=False, plots=True)
    first = rows(table)
    assert len(first) == 16 and {r["status"] for r in first} == {"ok"}
    assert len({r["case"] for r in first}) == 16
    assert (table.parent / "boxplots.png").exists() and (table.parent / "vs_wind_speed_m_s.png").exists()
    # stronger wind, larger error (mean over seeds and controllers): the table means something
    calm = [float(r["rms_horizontal_error_m"]) for r in first if r["wind_speed_m_s"] == "0.0"]
    windy = [float(r["rms_horizontal_error_m"]) for r in first if r["wind_speed_m_s"] == "3.0"]
    assert sum(windy) > sum(calm)
    tasks, _ = plan(spec, {r["case"] for r in first})
    assert tasks == []
    run_sweep(spec, tmp_path / "out", jobs=2, progress=False, plots=False)
    assert rows(table) == first  # nothing re-run, nothing duplicated


def test_a_failing_case_is_recorded_with_its_error_and_can_be_retried(tmp_path):
    # a zero rotor time constant loads (it is a number) but cannot be flown (division by zero)
    text = SMALL.replace("[grid]\nwind_speed_m_s = [0.0, 3.0]", "[grid]\n\"airframe.rotor_time_constant_s\" = [0.0]")
    spec = load_sweep(write(tmp_path, text))
    table = run_sweep(spec, tmp_path / "out", jobs=1, progress=False, plots=False)
    got = rows(table)
    assert len(got) == 8 and {r["status"] for r in got} == {"failed"}
    assert all("ZeroDivisionError" in r["error"] for r in got)
    assert all(math.isnan(float(r["peak_error_m"])) for r in got)
    run_sweep(spec, tmp_path / "out", jobs=1, retry_failed=True, progress=False, plots=False)
    assert len(rows(table)) == 8  # retried, replaced, not appended twice


def test_sweep_file_errors_name_the_line(tmp_path):
    with pytest.raises(ConfigError) as e:
        load_sweep(write(tmp_path, SMALL.replace('metrics = ["rms_horizontal_error_m"', 'metrics = ["rms"')))
    assert e.value.line == 8 and "'rms'" in str(e.value)
    with pytest.raises(ConfigError) as e:
        load_sweep(write(tmp_path, SMALL.replace("wind_speed_m_s = [0.0, 3.0]", '"attitude.omega_c" = [1.0]')))
    assert e.value.key == "grid.attitude.omega_c" and "not a scenario parameter" in str(e.value)
    with pytest.raises(ConfigError) as e:  # unquoted, TOML makes it a table
        load_sweep(write(tmp_path, SMALL.replace("wind_speed_m_s = [0.0, 3.0]", "attitude.omega_c = [1.0]")))
    assert "must be quoted" in str(e.value)
    with pytest.raises(ConfigError) as e:
        load_sweep(write(tmp_path, SMALL.replace("window_s = [1.0, 3.0]", "window_s = [5.0, 9.0]")))
    assert "after the flight" in str(e.value)
    with pytest.raises(ConfigError) as e:  # checked at load time, not after flying
        load_sweep(write(tmp_path, SMALL.replace("wind_speed_m_s = [0.0, 3.0]", "force_n = [2.0]")))
    assert "no force profile" in str(e.value)


def test_a_dask_cluster_of_two_workers_gives_the_local_numbers(tmp_path):
    """The same seeds on a local two-worker Dask cluster (separate processes, as on a real
    cluster) and on the local process pool: identical metrics, bit for bit."""
    from distributed import LocalCluster

    spec = load_sweep(write(tmp_path, SMALL))
    local = {r["case"]: r for r in rows(run_sweep(spec, tmp_path / "local", jobs=2, progress=False, plots=False))}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        table = run_sweep(spec, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False, plots=False)
    remote = {r["case"]: r for r in rows(table)}
    assert remote.keys() == local.keys()
    for k in local:
        for m in ("rms_horizontal_error_m", "peak_error_m"):
            assert remote[k][m] == local[k][m], (k, m)


GAINS = """name = "gains"
scenario = "E3_wind"
duration_s = 1.5
window_s = [0.5, 1.5]
position = ["pid", "aibc", "pd_do", "ism_do"]
attitude = ["pd", "pd_do", "ism_do"]
seeds = { first = 5, count = 3 }
metrics = ["rms_horizontal_error_m", "rms_vertical_error_m", "rms_rate_cmd_deg_s"]
batch_size = 12

[grid]
"attitude.omega_c_rad_s" = [10.0, 14.0]
"position.omega_c_rad_s" = [1.5, 2.2]
"""


def test_cases_that_differ_in_gains_fly_as_one_batch_with_the_numbers_of_separate_runs(tmp_path):
    """With batch_size 12 the four gain sets x three seeds of each controller pair are one batch
    whose gains are per-vehicle arrays; with batch_size 3 every gain set flies alone (each seed on
    floats, since 3 < FLOAT_BELOW). Every control law must give the same flight either way (float64 rounding only)."""
    spec = load_sweep(write(tmp_path, GAINS))
    tasks, total = plan(spec)
    assert total == 4 * 3 * 4 * 3 and len(tasks) == 12 and all(len(t.members) == 4 for t in tasks)
    together = {r["case"]: r for t in tasks for r in fly_batch(t)}  # the stacked path, no fall-back
    alone_spec = load_sweep(write(tmp_path, GAINS.replace("batch_size = 12", "batch_size = 3"), "b.toml"))
    assert all(len(t.members) == 1 for t in plan(alone_spec)[0])
    alone = {r["case"]: r for r in rows(run_sweep(alone_spec, tmp_path / "b", jobs=2, progress=False, plots=False))}
    assert together.keys() == alone.keys() and len(alone) == total
    for k, r in alone.items():
        assert r["status"] == together[k]["status"] == "ok", r
        for m in spec.metrics:
            assert together[k][m] == pytest.approx(float(r[m]), rel=1e-9, abs=1e-12), (r["position"],
                                                                                               r["attitude"], m)
    # the gains matter: the two position bandwidths give different errors
    a = [float(r["rms_horizontal_error_m"]) for r in alone.values() if r["position.omega_c_rad_s"] == "1.5"]
    b = [float(r["rms_horizontal_error_m"]) for r in alone.values() if r["position.omega_c_rad_s"] == "2.2"]
    assert a != b


def test_every_bundled_sweep_draws_its_figures_for_every_controller_it_names(tmp_path) -> None:
    """The figures of both bundled sweeps from a table written here (one row per controller pair
    and parameter set, the sweep's own columns): e3_wind and wind_and_mass flew every case and
    then died drawing them (KeyError: 'indi') while the labels were a table of their own."""
    import csv
    import random

    from companion.control.attitude import ATTITUDE_CONTROLLERS
    from companion.control.names import CONTROLLER_LABELS
    from companion.control.position import POSITION_CONTROLLERS
    from sitl.lab.sweep import SWEEP_DIR, _columns, draw_sweep, load_sweep

    assert set(ATTITUDE_CONTROLLERS) | set(POSITION_CONTROLLERS) <= set(CONTROLLER_LABELS)
    rng = random.Random(1)
    for path in sorted(SWEEP_DIR.glob("*.toml")):
        spec = load_sweep(path)
        table = tmp_path / spec.name / "cases.csv"
        table.parent.mkdir()
        columns = _columns(spec)
        with open(table, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            for p in spec.position:
                for a in spec.attitude:
                    for k, params in enumerate(spec.parameter_sets() or [{}]):
                        row = {c: rng.random() for c in columns}
                        row.update(case=f"{p}-{a}-{k}", position=p, attitude=a, status="ok", error="", **params)
                        w.writerow(row)
        drawn = draw_sweep(spec, table)
        assert drawn and all(f.stat().st_size > 10_000 for f in drawn), (path.name, drawn)
