"""The experiment registry: every experiment in one shape, listed by `experiment list`."""

import json
from dataclasses import is_dataclass, replace
from pathlib import Path

import pytest
from clitools import cli

from macrostate_mj.app.experiments import at_precision, registry
from macrostate_mj.app.experiments.all import Config
from macrostate_mj.core.cache import TaskCache
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import jsonable
from macrostate_mj.core.paths import reference_data

RESULTS = Path(__file__).resolve().parents[2] / "results"


def test_every_experiment_has_the_one_shape():
    found = registry()
    assert {"caging", "oc", "retlo", "retlo-sim", "sim2real", "srs"} <= set(found)
    for name, module in found.items():
        assert {"full", "quick"} <= set(module.PROFILES), name
        assert all(is_dataclass(c) and type(c) is module.Config
                   for c in module.PROFILES.values()), name
        assert callable(module.run) and "manifest.json" not in module.PRODUCTS, name


def test_experiment_list_names_each_with_its_profiles():
    res = cli("experiment", "list")
    assert res.returncode == 0, res.stderr
    for name, module in registry().items():
        line = next(x for x in res.stdout.splitlines() if x.startswith(name + " "))
        assert all(p in line for p in module.PROFILES)


def test_a_quick_caging_estimator_is_not_reused_by_a_full_run(tmp_path, monkeypatch):
    """The estimator was once cached by its stride alone: a `--quick` one (20 epochs) served a
    later full run. Its key now holds every training setting."""
    from macrostate_mj.app.experiments import caging

    trained = []

    def compute(self):
        trained.append(self.training["epochs"])
        return {"mlp.npz": b""}

    monkeypatch.setattr(caging.EstimatorTask, "compute", compute)
    cache = TaskCache(tmp_path)
    quick = caging.PROFILES["quick"]
    for cfg in (quick, replace(quick, seeds=5), replace(quick, epochs=200)):
        task = caging.EstimatorTask(cfg)
        cache.cached(task.stage, task.key(), task.compute)
    assert trained == [20, 200]       # more seeds reuse it; more epochs retrain


def test_a_retlo_model_is_keyed_by_every_setting_of_its_head():
    """A Gaussian model was once keyed by its head's name alone: one trained with another β
    would have been served from the cache. Point models keep the keys they always had."""
    import numpy as np

    from estimators.retlo.heads import GAUSSIAN, POINT, GaussianHead
    from estimators.retlo.train import TrainConfig
    from macrostate_mj.app.experiments.retlo import TrainTask

    world = np.zeros((2, 26, 3, 3))
    keys = {head: TrainTask([world], world, TrainConfig(), 3.0, head).key()
            for head in (POINT, GAUSSIAN, GaussianHead(beta=1.0), GaussianHead(max_log_std=5.0))}
    assert len(set(keys.values())) == 4
    assert keys[POINT] == TrainTask([world], world, TrainConfig(), 3.0).key()


def test_experiment_all_runs_keeps_and_skips_into_one_index(tmp_path, monkeypatch):
    """The quick profile of a cheap experiment runs; one whose real data is absent is skipped
    and said so; a second run keeps what finished; the index lists what each produced."""
    import json

    monkeypatch.setenv("MACROSTATE_REFERENCE_DATA", str(tmp_path / "no-data"))
    out = tmp_path / "all"
    args = ["experiment", "all", "--profile", "quick", "--only", "retlo-sim", "--only", "oc",
            "--out", str(out)]
    res = cli(*args)
    assert res.returncode == 0, res.stderr
    index = json.loads((out / "index.json").read_text())["experiments"]
    assert index["retlo-sim"]["status"] == "finished"
    assert "results.json" in index["retlo-sim"]["products"]
    assert index["oc"]["status"] == "skipped" and "no-data" in index["oc"]["reason"]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "finished" and manifest["command"] == "experiment all"
    again = cli(*args, "--overwrite")
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "index.json").read_text())["experiments"]["retlo-sim"][
        "status"] == "kept"
    bad = cli("experiment", "all", "--only", "nope", "--out", str(tmp_path / "x"))
    assert bad.returncode == 2 and "nope" in bad.stderr and not (tmp_path / "x").exists()


def test_experiment_all_sets_the_precision_of_every_training_that_has_one():
    """`experiment all --precision bf16` reaches oc's nested recipe and the ReTLo trainings;
    an experiment without a precision keeps its config; a bad name is refused up front."""
    full = {name: module.PROFILES["full"] for name, module in registry().items()}
    bf16 = {name: at_precision(cfg, "bf16") for name, cfg in full.items()}
    assert bf16["oc"].config.precision == "bf16" and full["oc"].config.precision == "fp32"
    assert {bf16[n].precision for n in ("retlo", "srs", "sim2real")} == {"bf16"}
    assert bf16["caging"] is full["caging"] and bf16["retlo"].model == full["retlo"].model
    with pytest.raises(UserError, match="unknown precision"):
        Config(precision="fp8")


# The committed folder each experiment's full profile reproduces (`experiment all --profile
# full`), and the settings it leaves out: retlo's lab 5-robot test is a collection of its own.
# srs_full (3 model seeds a dataset, earlier code) has its own profile. s2r_sealed's manifest
# holds its ledger's path on the machine that ran it, its scenario resolved (the lab by name
# here; the ledger's recipe hash holds its content) and its profile by path (results/
# sysid_timing2/fitted.json; here by name, `wider-rear-timed`: the same content, tested).
REPRODUCES = {("caging", "full"): ("caging", ()),
              ("caging-multi", "full"): ("caging_two_tails", ()),
              ("retlo-sim", "full"): ("retlo_sim_seeds/seed0", ()),
              ("learned-tail", "full"): ("learned_tail", ()),
              ("retlo", "full"): ("retlo_fig27_rerun", ("test",)),
              ("srs", "full"): ("srs_text", ()), ("srs", "full-seeds"): ("srs_full", ()),
              ("sim2real", "full"): ("s2r_mixed", ()), ("oc", "full"): ("oc_dev_table41", ()),
              ("uncertainty", "full"): ("retlo_uncertainty", ()),
              ("s2r-sealed", "full"): ("s2r_sealed_timing", ("ledger", "scenario",
                                                             "randomize"))}


def _plain(value):
    """A config value as comparable across machines: a path to the reference data from there."""
    for root in (f"{reference_data()}/", "reference-data/"):     # ours, then a manifest's
        if isinstance(value, str) and root in value:
            return value.split(root, 1)[1]
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


@pytest.mark.parametrize("name,profile", sorted(REPRODUCES))
def test_the_full_profile_is_the_config_of_the_committed_results_it_reproduces(name, profile):
    """What `experiment all --profile full` runs is what made the figures the docs show (every
    setting the committed manifest records; settings added since keep its behaviour)."""
    folder, apart = REPRODUCES[name, profile]
    committed = json.loads((RESULTS / folder / "manifest.json").read_text())["config"]
    committed = committed.get("profile", committed)      # srs_full's older manifest
    committed = {k: v for k, v in committed.items() if k not in apart}
    ours = jsonable(registry()[name].PROFILES[profile])
    assert committed, f"{folder}'s manifest records no settings"
    assert _differences(ours, committed, name) == []


def _differences(ours, committed, where: str) -> list[str]:
    """Where a setting the committed config records (nested configs too) differs from ours."""
    if isinstance(committed, str | int | float) and isinstance(ours, list | tuple):
        ours = ours[0] if len(ours) == 1 else ours    # a setting made repeatable since
    if not isinstance(committed, dict):
        return [] if _plain(ours) == _plain(committed) else [
            f"{where}: ours {ours!r}, committed {committed!r}"]
    if not isinstance(ours, dict):
        return [f"{where}: ours {ours!r}, committed a config"]
    return [d for key, value in committed.items()
            for d in (_differences(ours[key], value, f"{where}.{key}") if key in ours
                      else [f"{where}.{key}: not in ours"])]


def _parsed(monkeypatch, capsys, *args: str):
    """The config `experiment ARGS` would run, parsed by the generated command (not run)."""
    from clitools import cli_inprocess

    import macrostate_mj.app.experiments as experiments

    seen = []
    monkeypatch.setattr(experiments, "execute", lambda name, config, *a, **kw: seen.append(
        config) or [])
    code, _, err = cli_inprocess(capsys, "experiment", *args)
    assert code == 0, err
    return seen[0]


def test_every_experiment_command_is_generated_from_its_module(capsys):
    """`experiment NAME --help` for every registered experiment: its docstring's summary, each
    flagged field's flag with the profiles' values as its default, every profile named."""
    from dataclasses import fields

    from clitools import cli_inprocess

    from macrostate_mj.app.params import FLAG

    for name, module in registry().items():
        code, out, err = cli_inprocess(capsys, "experiment", name, "--help")
        assert code == 0, err
        text = " ".join(out.replace("│", " ").split())
        assert all(p in text for p in module.PROFILES), name
        assert "--out" in text and "--overwrite" in text, name
        for f in fields(module.Config):
            if FLAG in f.metadata:
                option = f.metadata[FLAG].option
                flag = next((d for d in option.param_decls if d.startswith("--")),
                            "--" + f.name.replace("_", "-"))
                assert flag.split("/")[0] in text, (name, f.name)


def test_a_flag_not_given_keeps_the_profiles_value(monkeypatch, capsys, tmp_path):
    from macrostate_mj.app.experiments import caging

    out = str(tmp_path / "o")
    quick = _parsed(monkeypatch, capsys, "caging", "--quick", "--out", out)
    assert quick == caging.PROFILES["quick"]
    given = _parsed(monkeypatch, capsys, "caging", "--profile", "quick", "--seeds", "3",
                    "--seed", "4", "--out", out)
    assert given == replace(caging.PROFILES["quick"], seeds=3, seed=4)
    full = _parsed(monkeypatch, capsys, "caging", "--time-limit", "30", "--out", out)
    assert full == replace(caging.PROFILES["full"], time_limit=30.0)


def test_flags_that_are_not_one_field_go_through_configure(monkeypatch, capsys, tmp_path):
    """retlo's --holdout without --folds means no cross-validation (one `replace`, so the
    config never holds both); the model's inputs and head come from their flags."""
    train = reference_data() / "ReTLo" / "Datasets" / "3Robots" / "Train.csv"
    if not train.is_file():
        pytest.skip("needs the real ThymioLoc files")
    config = _parsed(monkeypatch, capsys, "retlo", "--holdout", "0.25", "--history", "5",
                     "--cos-sin", "--uncertainty", "gaussian", "--out", str(tmp_path / "o"))
    assert (config.folds, config.holdout, config.model.history, config.model.cos_sin,
            config.head.name) == (0, 0.25, 5, True, "gaussian")


def test_each_training_variant_of_ch3_gap_changes_only_its_own_setting():
    from estimators.retlo.models import ModelConfig
    from estimators.retlo.train import TrainConfig
    from macrostate_mj.app.experiments.ch3_gap import VARIANTS

    ours = TrainConfig(model=ModelConfig(history=10, bidirectional=False, cos_sin=True))
    changed = {}
    for name, variant in VARIANTS.items():
        mine = variant(ours)
        changed[name] = {f for f in ("feedback", "chained", "mirror") if getattr(mine, f)
                         != getattr(ours, f)} | {f for f in ("mark_estimates", "rotate")
                                                  if getattr(mine.model, f)
                                                  != getattr(ours.model, f)}
    assert changed == {"ours": set(), "no_feedback": {"feedback"}, "no_chained": {"chained"},
                       "no_mirror": {"mirror"}, "no_mark": {"mark_estimates"},
                       "compass_frame": {"rotate"},
                       "text_like": {"feedback", "chained", "mirror", "mark_estimates",
                                     "rotate"}}


def test_experiment_uncertainty_quick_scores_both_heads_and_the_ensemble(tmp_path):
    real = reference_data() / "ReTLo" / "Datasets" / "3Robots"
    if not (real / "Train.csv").is_file():
        pytest.skip("needs the real ThymioLoc files")
    res = cli("experiment", "uncertainty", "--quick", "--out", str(tmp_path / "u"))
    assert res.returncode == 0, res.stderr
    results = json.loads((tmp_path / "u" / "results.json").read_text())
    for part in ("held", "val"):
        r = results[part]
        assert len(r["point_cm"]) == len(r["gaussian_cm"]) == 2
        assert 0 <= r["ensemble_calibration"]["coverage_90"] <= 1
    assert results["n_instances"]["held"] == 70
