"""The experiment framework: cell keys, the cell cache (resume, damaged files), statistics, the local,
process-pool and Ray runners (same numbers), failures, tables and results.json."""

from __future__ import annotations

import json
import math
import random
import shutil
import subprocess
import sys

import numpy as np
import pytest
import torch
from scipy import stats

from falcon_rl.experiment import cells as cells_module
from falcon_rl.experiment.cache import CACHE_FORMAT, CellCache
from falcon_rl.experiment.cells import (
    CELL_FUNCTIONS,
    Cell,
    code_version,
    git_commit,
    register_cell_function,
    run_cell,
)
from falcon_rl.experiment.results import (
    RESULTS_FORMAT,
    Column,
    Row,
    experiment_document,
    latex_table,
    markdown_table,
    rows_from_groups,
    write_results,
)
from falcon_rl.experiment.runners import CellsFailedError, run_cells
from falcon_rl.experiment.statistics import Aggregate, aggregate, group_cells

VERSION = {"falcon_rl": "0.1.0", "commit": None}
#: Calls of the toy cell function in this process (the resume tests count them).
CALLS: list[Cell] = []


def toy_cell(cell: Cell) -> dict:
    """Random numbers from the three seeded global generators; raises when the cell asks to."""
    CALLS.append(cell)
    if cell.param_dict.get("fail"):
        raise RuntimeError("toy cell asked to fail\nsecond line")
    return {"summary": {"py": random.random(), "np": float(np.random.standard_normal()),
                        "torch": float(torch.rand(())), "nan": math.nan, "seed": float(cell.seed)},
            "extra": np.arange(3)}


def real_cell(cell: Cell):
    """A tiny real protocol run: 2 LQR altitude episodes of 2 s."""
    from falcon_rl.evaluation.controllers import make_controller
    from falcon_rl.evaluation.protocols import altitude_protocol

    return altitude_protocol(cell.airframe, cell.controller, lambda env: make_controller("lqr", env),
                             episodes=2, seed=cell.seed, episode_seconds=2)


@pytest.fixture(autouse=True)
def registry():
    """The toy studies registered by reference to this module, removed afterwards."""
    saved = dict(CELL_FUNCTIONS)
    register_cell_function("toy", f"{__name__}:toy_cell")
    register_cell_function("toy-real", f"{__name__}:real_cell")
    CALLS.clear()
    yield
    CELL_FUNCTIONS.clear()
    CELL_FUNCTIONS.update(saved)


def toy_cells(n_seeds: int = 2, draws: int = 2, **params) -> list[Cell]:
    return [Cell.make("toy", "altitude", "volantex_ranger", "MPPI", seed, draw, params)
            for seed in range(n_seeds) for draw in range(draws)]


def same_summary(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all((math.isnan(a[k]) and math.isnan(b[k])) or a[k] == b[k] for k in a)


# ---- cells and keys


def test_key_is_stable_and_ignores_parameter_order():
    cell = Cell.make("study", "altitude", "navion", "LQR", 3, 1, {"wind": 5.0, "arm": "full"})
    assert cell.key(VERSION) == "692d062a4ee55abd6d92f6e06340ee4b"  # the same in every process and run
    same = Cell("study", "altitude", "navion", "LQR", 3, 1, (("wind", 5.0), ("arm", "full")))
    assert same == cell and hash(same) == hash(cell) and same.key() == cell.key()
    assert cell.params == (("arm", "full"), ("wind", 5.0))
    assert Cell.from_dict(json.loads(json.dumps(cell.to_dict()))) == cell


def test_key_changes_with_every_field_and_the_code_version():
    base = Cell.make("study", "altitude", "navion", "LQR", 0, 0, {"wind": 5.0})
    variants = [Cell.make("other", "altitude", "navion", "LQR", 0, 0, {"wind": 5.0}),
                Cell.make("study", "attitude", "navion", "LQR", 0, 0, {"wind": 5.0}),
                Cell.make("study", "altitude", "volantex_ranger", "LQR", 0, 0, {"wind": 5.0}),
                Cell.make("study", "altitude", "navion", "PPO", 0, 0, {"wind": 5.0}),
                Cell.make("study", "altitude", "navion", "LQR", 1, 0, {"wind": 5.0}),
                Cell.make("study", "altitude", "navion", "LQR", 0, 1, {"wind": 5.0}),
                Cell.make("study", "altitude", "navion", "LQR", 0, 0, {"wind": 6.0}),
                Cell.make("study", "altitude", "navion", "LQR", 0, 0, {"wind": 5.0, "gust": True}),
                Cell.make("study", "altitude", "navion", "LQR", 0, 0)]
    keys = {base.key(VERSION), *(cell.key(VERSION) for cell in variants)}
    assert len(keys) == len(variants) + 1
    assert base.key({"falcon_rl": "0.2.0", "commit": None}) != base.key(VERSION)
    assert base.key({"falcon_rl": "0.1.0", "commit": "a" * 40}) != base.key(VERSION)
    assert set(code_version()) == {"falcon_rl", "commit"}


@pytest.mark.parametrize("bad", [{"study": ""}, {"seed": -1}, {"seed": 1.5}, {"draw": True},
                                 {"params": {"x": {"nested": 1}}}])
def test_bad_cells_are_one_line_value_errors(bad):
    fields = {"study": "s", "task": "t", "airframe": "a", "controller": "c", "seed": 0, **bad}
    with pytest.raises(ValueError) as error:
        Cell.make(**fields)
    assert "\n" not in str(error.value)


def test_git_commit_is_read_from_the_git_files(tmp_path):
    assert git_commit(tmp_path / "file.py") is None  # not in a checkout
    repo = tmp_path / "repo"
    (repo / ".git" / "refs" / "heads").mkdir(parents=True)
    (repo / "pkg").mkdir()
    (repo / ".git" / "HEAD").write_text("ref: refs/heads/main\n")
    (repo / ".git" / "refs" / "heads" / "main").write_text("1" * 40 + "\n")
    assert git_commit(repo / "pkg" / "module.py") == "1" * 40
    (repo / ".git" / "refs" / "heads" / "main").unlink()
    (repo / ".git" / "packed-refs").write_text(f"# pack-refs\n{'2' * 40} refs/heads/main\n")
    assert git_commit(repo / "pkg" / "module.py") == "2" * 40
    (repo / ".git" / "HEAD").write_text("3" * 40 + "\n")  # detached
    assert git_commit(repo / "pkg" / "module.py") == "3" * 40
    if shutil.which("git"):
        top = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                             cwd=cells_module.__file__.rsplit("/", 1)[0])
        if top.returncode == 0:
            assert git_commit() == top.stdout.strip()


def test_run_cell_seeds_the_global_generators():
    cell = toy_cells(1, 1)[0]
    first, second = run_cell(cell), run_cell(cell)
    assert same_summary(first["summary"], second["summary"]) and first["seconds"] >= 0
    assert math.isnan(first["summary"]["nan"]) and first["extra"] == [0, 1, 2]
    other = run_cell(Cell.make("toy", "altitude", "volantex_ranger", "MPPI", 0, 1))
    assert other["summary"]["py"] != first["summary"]["py"]  # another draw, another stream
    with pytest.raises(ValueError, match="no cell function for study 'nope'"):
        run_cell(Cell("nope", "altitude", "navion", "LQR", 0))
    with pytest.raises(ValueError, match="module:attribute"):
        register_cell_function("bad", "no_colon")


# ---- cache


def test_cache_round_trip_and_document(tmp_path):
    cache = CellCache(tmp_path / "cells")
    cell = toy_cells(1, 1)[0]
    assert cache.get(cell) is None and cache.finished([cell]) == set()
    result = run_cell(cell)
    path = cache.put(cell, result)
    assert path.name == f"{cell.key()}.json" and not list(path.parent.glob("*.tmp"))
    assert same_summary(cache.get(cell)["summary"], result["summary"])
    document = json.loads(path.read_text())
    assert document["format"] == CACHE_FORMAT and document["key"] == cell.key()
    assert document["cell"] == json.loads(json.dumps(cell.to_dict()))
    assert document["version"] == code_version()
    assert document["result"]["summary"]["nan"] is None  # standard JSON
    assert {"started", "finished"} <= set(document) and cache.finished([cell]) == {cell}


def test_a_killed_sweep_resumes_and_a_changed_cell_reruns_alone(tmp_path):
    cache = CellCache(tmp_path)
    cells = toy_cells(2, 2)
    first = run_cells(cells[:2], cache, progress=False)  # the sweep "killed" after two cells
    assert len(CALLS) == 2
    results = run_cells(cells, cache, progress=False)
    assert len(CALLS) == 4 and set(CALLS[2:]) == set(cells[2:])  # only the unfinished ones ran
    assert all(same_summary(results[k]["summary"], v["summary"]) for k, v in first.items())
    run_cells(cells, cache, progress=False)
    assert len(CALLS) == 4
    changed = [*cells[:3], Cell.make("toy", "altitude", "volantex_ranger", "MPPI", 1, 1, {"wind": 2.0})]
    run_cells(changed, cache, progress=False)
    assert CALLS[4:] == [changed[3]]


def test_a_damaged_cache_file_is_recomputed_with_a_warning(tmp_path):
    cache = CellCache(tmp_path)
    cells = toy_cells(1, 2)
    run_cells(cells, cache, progress=False)
    cache.path(cells[0]).write_text('{"format": "falcon-rl-cell/1", "key": ')  # a torn write
    with pytest.warns(UserWarning, match="damaged cache file"):
        results = run_cells(cells, cache, progress=False)
    assert CALLS[2:] == [cells[0]] and cells[0].key() in results
    assert cache.get(cells[0]) is not None  # replaced by a whole file
    other = cache.path(cells[1])
    other.write_text(cache.path(cells[0]).read_text())  # a file holding another cell
    with pytest.warns(UserWarning, match="another cell"):
        assert cache.get(cells[1]) is None


# ---- statistics


def test_aggregate_against_hand_computed_values():
    agg = aggregate([1.0, 2.0, 3.0, 4.0, 10.0, math.nan])
    assert agg.n == 5 and agg.n_excluded == 1 and not agg.empty
    assert agg.mean == pytest.approx(4.0) and agg.std == pytest.approx(math.sqrt(12.5))
    assert agg.iqm == pytest.approx(3.0)  # int(0.25 * 5) = 1 value cut from each end: mean(2, 3, 4)
    values = np.array([1.0, 2.0, 3.0, 4.0, 10.0])
    means = values[np.random.default_rng(0).integers(0, 5, size=(10_000, 5))].mean(axis=1)
    assert (agg.ci_low, agg.ci_high) == pytest.approx(tuple(np.percentile(means, [2.5, 97.5])))
    assert 1.0 <= agg.ci_low < agg.mean < agg.ci_high <= 10.0
    reference = stats.bootstrap((values,), np.mean, n_resamples=10_000, method="percentile",
                                random_state=np.random.default_rng(1)).confidence_interval
    assert agg.ci_low == pytest.approx(reference.low, abs=0.3)
    assert agg.ci_high == pytest.approx(reference.high, abs=0.5)
    assert aggregate([1.0, 2.0, 3.0, 4.0, 10.0], seed=0) == aggregate(values, seed=0)  # seeded


def test_aggregate_edge_cases_and_scipy_iqm():
    one = aggregate([2.5])
    assert (one.mean, one.std, one.n, one.ci_low, one.ci_high, one.iqm) == (2.5, 0.0, 1, 2.5, 2.5, 2.5)
    empty = aggregate([math.nan, None, math.inf])
    assert empty.empty and empty.n == 0 and empty.n_excluded == 3 and math.isnan(empty.mean)
    assert Aggregate.from_dict(json.loads(json.dumps(empty.to_dict()))) == empty
    rng = np.random.default_rng(7)
    for n in range(1, 13):
        values = rng.normal(size=n)
        agg = aggregate(values, resamples=200)
        assert agg.iqm == pytest.approx(stats.trim_mean(values, 0.25))
        assert agg.mean == pytest.approx(values.mean())
        assert agg.std == pytest.approx(values.std(ddof=1) if n > 1 else 0.0)
    assert aggregate(np.arange(8.0)).iqm == pytest.approx(np.mean([2, 3, 4, 5]))
    with pytest.raises(ValueError, match="resamples"):
        aggregate([1.0], resamples=0)


def test_group_cells_keeps_per_seed_rows():
    cells = [*toy_cells(3, 1), Cell("toy", "altitude", "navion", "LQR", 0)]
    results = {cell.key(): {"summary": {"rmse_m": float(cell.seed), "dead": math.nan}} for cell in cells[:3]}
    groups = group_cells(cells, results)
    assert len(groups) == 2
    mppi, lqr = groups
    assert [row["seed"] for row in mppi.rows] == [0, 1, 2] and mppi.aggregates["rmse_m"].mean == 1.0
    assert mppi.aggregates["dead"].empty and lqr.rows == [] and lqr.missing == [cells[3].key()]


# ---- runners


def test_process_pool_gives_the_in_process_numbers(tmp_path):
    cells = toy_cells(2, 1)
    local = run_cells(cells, CellCache(tmp_path / "a"), progress=False)
    pooled = run_cells(cells, CellCache(tmp_path / "b"), workers=2, progress=False)
    assert local.keys() == pooled.keys()
    assert all(same_summary(local[k]["summary"], pooled[k]["summary"]) for k in local)


def test_a_failing_cell_is_named_and_the_others_are_cached(tmp_path):
    cache = CellCache(tmp_path)
    cells = [*toy_cells(2, 1), Cell.make("toy", "altitude", "navion", "LQR", 5, 0, {"fail": True})]
    with pytest.raises(CellsFailedError) as error:
        run_cells(cells, cache, progress=False)
    message = str(error.value)
    assert "\n" not in message and message.startswith("1 of 3 cells failed")
    assert "toy/altitude/navion/LQR seed=5 draw=0 fail=True" in message
    assert "RuntimeError: toy cell asked to fail" in message
    assert cache.finished(cells) == set(cells[:2]) and len(error.value.results) == 2
    document = experiment_document({"runner": "local"}, cells, error.value.results, error.value.failures)
    failed = [row for row in document["cells"] if row["status"] == "failed"]
    assert len(failed) == 1 and failed[0]["error"].startswith("RuntimeError")


def test_bad_runner_arguments_and_missing_ray(tmp_path, monkeypatch):
    cache = CellCache(tmp_path)
    with pytest.raises(ValueError, match="runner must be one of"):
        run_cells(toy_cells(1, 1), cache, runner="slurm")
    with pytest.raises(ValueError, match="workers"):
        run_cells(toy_cells(1, 1), cache, workers=0)
    with pytest.raises(ValueError, match="no cell function"):
        run_cells([Cell("unknown", "altitude", "navion", "LQR", 0)], cache)
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    with pytest.raises(ImportError, match=r"pip install 'falcon-rl\[distributed\]'"):
        run_cells(toy_cells(1, 1), cache, runner="ray", progress=False)


def test_local_and_ray_runners_give_identical_results(tmp_path):
    pytest.importorskip("ray")
    cells = [*toy_cells(2, 2), Cell("toy-real", "altitude", "volantex_ranger", "LQR", 0)]
    local = run_cells(cells, CellCache(tmp_path / "local"), progress=False)
    ray_cache = CellCache(tmp_path / "ray")
    distributed = run_cells(cells, ray_cache, runner="ray", workers=2, progress=False)
    assert local.keys() == distributed.keys() == {cell.key() for cell in cells}
    for key in local:
        assert same_summary(local[key]["summary"], distributed[key]["summary"]), key
    real = local[cells[-1].key()]
    assert real["summary"]["survival"] == 1.0 and real["settings"]["episodes"] == 2
    assert real["episodes"]["survival"] == [1.0, 1.0]
    assert ray_cache.finished(cells) == set(cells)


# ---- tables and results.json


def test_tables_render_with_an_empty_cell(tmp_path):
    rows = [Row(("volantex_ranger", "PPO"), {"rmse_m": aggregate([1.0, 2.0]), "survival": 1.0}),
            Row(("volantex_ranger", "MPPI"), {"rmse_m": aggregate([math.nan]), "survival": 0.0}),
            Row(("navion", "LQR"), {"survival": 0.5})]
    columns = [Column("rmse_m", "RMSE (m)"), Column("survival", "Survival", 1)]
    markdown = markdown_table(rows, columns).splitlines()
    assert markdown[0] == "| Airframe | Alg. | RMSE (m) | Survival |"
    assert markdown[2] == "| volantex_ranger | PPO | 1.50 ± 0.71 | 1.0 |"
    assert markdown[3] == "| volantex_ranger | MPPI | -- | 0.0 |" and markdown[4].endswith("| -- | 0.5 |")
    assert "[" in markdown_table(rows, columns, ci=True).splitlines()[2]
    latex = latex_table(rows, columns, caption="Altitude hold (mean ± std over seeds)", label="tab:alt")
    lines = latex.splitlines()
    assert r"\toprule" in lines and r"\bottomrule" in lines and lines.count(r"\midrule") == 2
    assert r"volantex\_ranger & PPO & $1.50 \pm 0.71$ & $1.0$ \\" in lines
    assert r" & MPPI & -- & $0.0$ \\" in lines  # the airframe written once per block
    assert r"\label{tab:alt}" in lines and r"\begin{tabular}{llcc}" in lines
    with pytest.raises(ValueError, match="label columns"):
        markdown_table([Row(("a",), {})], columns)


def test_results_json_schema(tmp_path):
    cells = toy_cells(2, 1)
    results = run_cells(cells, CellCache(tmp_path / "cells"), progress=False)
    groups = group_cells(cells, results)
    rows = rows_from_groups(groups, ("airframe", "controller"))
    assert rows[0].labels == ("volantex_ranger", "MPPI") and "--" in markdown_table(rows, ["nan"])
    path = write_results(tmp_path / "results.json", experiment_document({"episodes": 2}, cells, results))
    document = json.loads(path.read_text())
    assert document["format"] == RESULTS_FORMAT and document["settings"] == {"episodes": 2}
    assert [row["seed"] for row in document["cells"]] == [0, 1]
    assert document["cells"][0]["summary"]["nan"] is None and document["cells"][0]["status"] == "finished"
    metrics = document["aggregates"][0]["metrics"]
    assert metrics["seed"]["mean"] == 0.5 and metrics["seed"]["n"] == 2 and metrics["nan"]["empty"]
    assert document["version"] == code_version()
    with pytest.raises(ValueError, match="format"):
        write_results(tmp_path / "bad.json", {"format": "other"})
