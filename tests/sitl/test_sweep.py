"""Sweeps: case tables, resumption, failures kept, and the cluster path giving the same numbers."""

import csv
import dataclasses
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


def shortened(spec):
    """The bundled sweep with every controller pair it names, one seed, one random sample and at
    most two grid values per parameter: the fewest cases that still draw every figure."""
    return dataclasses.replace(spec, seeds=spec.seeds[:1], random_samples=min(spec.random_samples, 1),
                               grid={k: v[:2] for k, v in spec.grid.items()})


def test_every_bundled_sweep_and_experiment_flies_and_draws_its_figures(tmp_path) -> None:
    """Both bundled sweeps (every controller pair, one seed) and every paper experiment (one
    seed) flown and drawn: e3_wind and wind_and_mass flew every case and then died drawing them
    (KeyError: 'indi') while the sweep's labels were a table of their own."""
    from sitl.lab.experiments import PAPER_EXPERIMENTS, run_experiment
    from sitl.lab.sweep import SWEEP_DIR
    from sitl.plant.scenario import load_scenario

    bundled = sorted(SWEEP_DIR.glob("*.toml"))
    assert {p.stem for p in bundled} >= {"e3_wind", "wind_and_mass"}
    for path in bundled:
        spec = shortened(load_sweep(path))
        table = run_sweep(spec, tmp_path / "sweeps", jobs=1, progress=False, plots=True)
        got = rows(table)
        pairs = {(r["position"], r["attitude"]) for r in got if r["status"] == "ok"}
        assert pairs == {(p, a) for p in spec.position for a in spec.attitude}, path.name
        figures = [table.parent / "boxplots.png", *(table.parent / f"vs_{n}.png" for n in spec.parameter_names)]
        assert all(f.stat().st_size > 10_000 for f in figures), path.name
    for name in PAPER_EXPERIMENTS:
        result = run_experiment(load_scenario(name), tmp_path / "experiments" / name, seeds=[1], jobs=1)
        assert result.figure is not None and result.figure.stat().st_size > 10_000, name


ENGINE = """name = "engine"
scenario = "E3_wind"
duration_s = 2.0
window_s = [0.5, 2.0]
position = ["ism_do"]
attitude = ["ism_do"]
seeds = [1, 2]
metrics = ["rms_horizontal_error_m", "peak_error_m"]
"""


def test_one_table_keeps_each_engines_cases_apart_and_a_rerun_skips_both(tmp_path, capsys):
    """The engine is a column and part of a case's key: a compiled run and an objects run into one
    --out are four rows (their numbers differ: another random stream), not two rows where the
    second engine silently found its cases "done"."""
    spec = load_sweep(write(tmp_path, ENGINE))
    table = run_sweep(spec, tmp_path / "out", jobs=1, progress=False, plots=False, engine="compiled")
    run_sweep(spec, tmp_path / "out", jobs=1, progress=False, plots=True, engine="objects")
    got = rows(table)
    assert sorted(r["engine"] for r in got) == ["compiled", "compiled", "objects", "objects"]
    by = {(r["engine"], r["seed"]): float(r["rms_horizontal_error_m"]) for r in got}
    assert by[("compiled", "1")] != by[("objects", "1")]
    run_sweep(spec, tmp_path / "out", jobs=1, progress=True, plots=False, engine="objects")
    assert len(rows(table)) == 4 and "2 already done, 0 to run" in capsys.readouterr().err
    from sitl.lab.sweep import summary

    assert "2 cases on the objects engine" in summary(spec, table, "objects")


def test_the_engine_asked_for_reaches_dask_workers_whose_environment_says_otherwise(tmp_path, monkeypatch, capsys):
    """A worker process started before the sweep (its SITL_ENGINE unset: compiled) flies the
    objects engine when --engine objects asks: its numbers are the local objects run's, bit for bit
    (setting SITL_ENGINE in the client never reached it: the compiled numbers came back)."""
    from distributed import LocalCluster

    from sitl.lab.sweep import main

    monkeypatch.delenv("SITL_ENGINE", raising=False)
    path = write(tmp_path, ENGINE)
    local = rows(run_sweep(load_sweep(path), tmp_path / "local", jobs=1, progress=False, plots=False,
                           engine="objects"))
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        rc = main([str(path), "--engine", "objects", "--scheduler", cluster.scheduler_address,
                   "--out", str(tmp_path / "dask"), "--no-plots"])
    assert rc == 0
    remote = rows(tmp_path / "dask" / "engine" / "cases.csv")
    assert [r["engine"] for r in remote] == ["objects", "objects"]
    assert {r["case"]: r["rms_horizontal_error_m"] for r in remote} == {
        r["case"]: r["rms_horizontal_error_m"] for r in local}
    assert "1 Dask workers at" in capsys.readouterr().err


def closed_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_scheduler_is_one_line_within_the_connect_timeout(tmp_path, capsys):
    from sitl.lab.sweep import main

    address = f"tcp://127.0.0.1:{closed_port()}"
    rc = main([str(write(tmp_path, ENGINE)), "--scheduler", address, "--connect-timeout", "1",
               "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and err[-1].startswith(f"sitl-sweep: error: no Dask scheduler answered at {address} within 1 s")
    assert not any("Traceback" in line for line in err)
    assert not (tmp_path / "out" / "engine" / "cases.csv").exists()  # nothing written, nothing lost


def test_a_scheduler_without_workers_says_it_is_waiting_then_gives_up_at_the_worker_timeout(tmp_path, capsys):
    from distributed import LocalCluster

    from sitl.lab.sweep import main

    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        rc = main([str(write(tmp_path, ENGINE)), "--scheduler", cluster.scheduler_address, "--worker-timeout", "2",
                   "--out", str(tmp_path / "out")])
        address = cluster.scheduler_address
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and err[-1] == (f"sitl-sweep: error: the Dask scheduler at {address} has no workers after 2 s "
                                   f"(start some: dask worker {address})")
    assert any(line.startswith(f"sitl-sweep: waiting for a worker at {address}") for line in err)
