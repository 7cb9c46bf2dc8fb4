"""`experiment sim2real`: cross-validated folds that never leak, the data-saving arithmetic, bad
input, and a quick end-to-end run (a small lab collection stands in for the real files, so the
test needs no reference data)."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from clitools import assert_clean_error, cli

from macrostate_mj.app.experiments import execute, sim2real
from macrostate_mj.app.experiments.sim2real import PROFILES, equivalent_fraction
from macrostate_mj.app.experiments.sim2real.models import choose_settings
from macrostate_mj.app.experiments.sim2real.report import summary_lines
from macrostate_mj.chain import scenarios
from macrostate_mj.core.cache import task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.stats import cv_blocks
from macrostate_mj.formats.thymioloc import DEFAULT_PX_PER_CM, read_csv


@pytest.mark.parametrize("fold", range(5))
def test_folds_are_contiguous_and_disjoint(fold):
    pool, val, test = cv_blocks(325, 5, fold, 0.15)
    assert np.array_equal(test, np.arange(test[0], test[-1] + 1))
    assert not set(test) & set(pool) and not set(test) & set(val) and not set(pool) & set(val)
    assert len(pool) + len(val) + len(test) == 325 and len(test) == 65
    assert val.min() > pool.max() or fold == 4 and val.min() > pool.max()
    with pytest.raises(UserError):
        cv_blocks(3, 5, 0, 0.15)


def test_equivalent_fraction_interpolates_in_log_share():
    fractions, errors = (0.1, 0.25, 0.5, 1.0), [8.0, 6.0, 5.0, 4.0]
    assert equivalent_fraction(6.0, fractions, errors) == pytest.approx(0.25)
    assert equivalent_fraction(4.5, fractions, errors) == pytest.approx(np.sqrt(0.5))
    assert equivalent_fraction(3.0, fractions, errors) is None       # better than all real data
    assert equivalent_fraction(9.0, fractions, errors) is None       # worse than the least
    assert equivalent_fraction(5.5, fractions, [8.0, 5.0, 6.0, 4.0]) == pytest.approx(
        np.exp(np.log(0.1) + 5 / 6 * (np.log(0.25) - np.log(0.1))))  # a noisy bump is ignored


def test_experiment_sim2real_quick(stand_in, tmp_path, monkeypatch):
    out = tmp_path / "s2r"
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--out", str(out))
    assert res.returncode == 0, res.stderr
    results = json.loads((out / "results.json").read_text())
    assert set(results["arms"]) == {"sim", "real", "finetune", "mixed"}
    for arm in ("real", "finetune", "mixed"):
        assert set(results["arms"][arm]) == {"0.5", "1"}
        assert all(c["head_cm"]["n"] == 2 and c["head_cm"]["mean"] > 0
                   for c in results["arms"][arm].values())
    assert results["sim_over_real"] > 0
    assert (out / "sim2real.png").stat().st_size > 1000
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["models"] == manifest["models_trained"] == 2 + 3 * 2 * 2
    models = sorted((out / "cache" / "sim2real-model").iterdir())
    assert len(models) == 14 and sum((m / "model.pt").is_file() for m in models) == 2
    # a rerun takes every model from the cache and writes the same results
    before = (out / "results.json").read_bytes()
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--out", str(out),
              "--overwrite")
    assert res.returncode == 0, res.stderr
    assert (out / "results.json").read_bytes() == before
    assert json.loads((out / "manifest.json").read_text())["models_trained"] == 0
    # killed while training: the manifest says so, one real-data model is missing; the same
    # command resumes (no --overwrite) and trains that model alone
    manifest = json.loads((out / "manifest.json").read_text())
    (out / "manifest.json").write_text(json.dumps({**manifest, "status": "interrupted"}))
    shutil.rmtree(next(m for m in models if not (m / "model.pt").exists()))
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert (out / "results.json").read_bytes() == before
    assert json.loads((out / "manifest.json").read_text())["models_trained"] == 1
    # new inputs make new data, never reuse the old: a refit lab (or a randomized one) is
    # collected again, and its CSVs' bytes key the sim models
    collected = []

    class Stop(Exception):
        pass

    def collect(req, progress=None):
        collected.append(req)
        raise Stop

    monkeypatch.setattr(sim2real.data, "collect", collect)
    config = replace(PROFILES["quick"], real=stand_in)
    with pytest.raises(Stop):
        execute("sim2real", replace(config, randomize=("wide",)), out, overwrite=True)
    refit = scenarios.SCENARIOS["lab"].with_overrides(marker_jitter=0.004)
    monkeypatch.setitem(scenarios.SCENARIOS, "lab", refit)
    with pytest.raises(Stop):
        execute("sim2real", config, out, overwrite=True)
    other = tmp_path / "other_lab.toml"        # another lab's file: collected in that lab
    other.write_text('extends = "lab"\nname = "other_lab"\n[chain]\nspacing = 0.25\n')
    with pytest.raises(Stop):
        execute("sim2real", replace(config, scenario=other), out, overwrite=True)
    assert [r.randomize for r in collected] == ["wide", None, None]
    assert collected[-1].scenario == scenarios.get_scenario(other)       # resolved once
    assert (out / "results.json").read_bytes() == before


def test_arms_train_only_what_they_need(stand_in, tmp_path):
    """`--arm sim` trains the sim models alone (no ratio without the real arm); `--arm real`
    collects no lab data; an unknown arm is one line, exit 2."""
    for arms, trained in ((["sim"], 2), (["real"], 4), (["real", "sim"], 2)):
        out = tmp_path / "_".join(arms)
        args = [a for arm in arms for a in ("--arm", arm)]
        res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), *args,
                  "--out", str(out))
        assert res.returncode == 0, res.stderr
        results = json.loads((out / "results.json").read_text())
        assert set(results["arms"]) == set(arms)
        assert ("sim_over_real" in results) == (len(arms) == 2)
        assert (out / "data" / "sim").exists() == ("sim" in arms)
        manifest = json.loads((out / "manifest.json").read_text())
        assert manifest["models_trained"] == (trained if len(arms) == 1 else 6)
    res = cli("experiment", "sim2real", "--quick", "--real", str(stand_in), "--arm", "tail",
              "--out", str(tmp_path / "bad"))
    assert_clean_error(res, "--arm")
    assert not (tmp_path / "bad").exists()


def test_sim2real_refuses_a_folder_without_real_files(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    res = cli("experiment", "sim2real", "--quick", "--real", str(empty), "--out",
              str(tmp_path / "out"))
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "Train.csv" in res.stderr
    assert not (tmp_path / "out").exists()


def test_sim_minutes_with_a_given_sim_folder_is_refused(tmp_path):
    res = cli("experiment", "sim2real", "--quick", "--real", str(tmp_path), "--sim",
              str(tmp_path), "--sim-minutes", "5", "--out", str(tmp_path / "out"))
    assert_clean_error(res, "--sim-minutes")
    assert not (tmp_path / "out").exists()
    res = cli("experiment", "sim2real", "--quick", "--real", str(tmp_path), "--sim",
              str(tmp_path), "--scenario", "webots", "--out", str(tmp_path / "out"))
    assert_clean_error(res, "--scenario")
    assert not (tmp_path / "out").exists()
    for flag, bad in (("--fraction", "1.5"), ("--fraction", "0"), ("--mix-weight", "1"),
                      ("--mix-weight", "nan"), ("--finetune-epochs", "0"),
                      ("--finetune-epochs", "2.5")):
        res = cli("experiment", "sim2real", "--quick", "--real", str(tmp_path), flag, bad,
                  "--out", str(tmp_path / "out"))
        assert_clean_error(res, flag)
        assert not (tmp_path / "out").exists()


def test_the_mixed_arm_keeps_the_weight_best_on_the_real_validation_block():
    """Of several `--mix-weight`s, each seed and share keeps the model with the lowest
    validation error, whatever its test error; one weight keeps the reports as they were."""
    def mixed(seed, f, w, val, test):
        return {"arm": "mixed", "seed": seed, "fraction": f, "mix_weight": w,
                "best_val_cm": val, "head_cm": test}
    real = {"arm": "real", "seed": 0, "fraction": 0.5, "best_val_cm": 1.0, "head_cm": 1.0}
    reports = [real, mixed(0, 0.5, 0.25, 5.0, 3.0), mixed(0, 0.5, 0.5, 4.0, 9.0),
               mixed(1, 0.5, 0.25, 4.0, 4.0), mixed(1, 0.5, 0.5, 4.0, 1.0)]
    config = replace(PROFILES["quick"], fractions=(0.5,), mix_weight=(0.25, 0.5))
    kept, tables = choose_settings(reports, config)
    mixes = tables["mixes"]
    assert kept == [real, reports[2], reports[3]]          # seed 1: the first of equals
    assert mixes["mixed"]["0.5"]["chosen_by_seed"] == {"0": 0.5, "1": 0.25}
    assert mixes["mixed"]["0.5"]["weights"]["0.25"]["head_cm_by_seed"] == {"0": 3.0, "1": 4.0}
    one = [real, reports[1], reports[3]]
    assert choose_settings(one, replace(config, mix_weight=(0.25,))) == (one, {})
    # the fine-tuned mixing arm chooses its own weight, apart from the mixed arm's
    both = [*reports, {**reports[1], "arm": "finetune-mixed", "best_val_cm": 1.0},
            {**reports[2], "arm": "finetune-mixed"}]
    kept, tables = choose_settings(both, replace(config, arms=sim2real.ARMS))
    assert kept[-1] == both[5] and set(tables["mixes"]) == {"mixed", "finetune-mixed"}
    assert tables["mixes"]["finetune-mixed"]["0.5"]["chosen_by_seed"] == {"0": 0.25}


def test_fine_tuned_arms_keep_the_epochs_best_on_the_real_validation_block():
    """Of several `--finetune-epochs`, each seed and share keeps the fine-tuned model of lowest
    validation error; with the lab share tuned too, every combination trains and each
    setting's table holds, per seed, its candidate's best over the other setting."""
    def tuned(arm, seed, epochs, val, test, w=None):
        return {"arm": arm, "seed": seed, "fraction": 1.0, "finetune_epochs": epochs,
                "best_val_cm": val, "head_cm": test, **({} if w is None else {"mix_weight": w})}
    reports = [tuned("finetune", 0, 30, 5.0, 4.0), tuned("finetune", 0, 60, 4.5, 6.0),
               tuned("finetune-mixed", 0, 30, 3.0, 7.0, 0.25),
               tuned("finetune-mixed", 0, 60, 4.0, 2.0, 0.25),
               tuned("finetune-mixed", 0, 30, 3.5, 5.0, 0.5),
               tuned("finetune-mixed", 0, 60, 2.5, 3.0, 0.5)]
    config = replace(PROFILES["quick"], fractions=(1.0,), finetune_epochs=(30, 60),
                     mix_weight=(0.25, 0.5), arms=("finetune", "finetune-mixed"))
    kept, tables = choose_settings(reports, config)
    assert kept == [reports[1], reports[5]]
    epochs = tables["finetunes"]["finetune-mixed"]["1"]
    assert epochs["chosen_by_seed"] == {"0": 60}
    assert epochs["epochs"]["30"]["head_cm_by_seed"] == {"0": 7.0}   # 0.25 beat 0.5 at 30
    assert tables["mixes"]["finetune-mixed"]["1"]["weights"]["0.25"]["head_cm_by_seed"] == \
        {"0": 7.0}                                                   # 30 beat 60 at 0.25
    assert tables["finetunes"]["finetune"]["1"]["chosen_by_seed"] == {"0": 60}
    assert [c for c in sim2real.candidates(config, "finetune-mixed")] == [
        {"mix_weight": w, "finetune_epochs": e} for w in (0.25, 0.5) for e in (30, 60)]
    assert sim2real.candidates(config, "real") == [{}]
    line = "finetune at 100 % real, epochs chosen per seed: 60 1x"
    assert line in summary_lines({"arms": {}, **tables})


def test_the_fine_tuned_mixing_arm_starts_from_the_sim_model_and_mixes_the_lab_in(tmp_path):
    chains, lab, init = np.zeros((4, 16, 3, 3)), tmp_path / "lab", tmp_path / "sim.pt"
    lab.mkdir()
    (lab / "Train.csv").write_text("lab rows")             # keys read their inputs' bytes
    init.write_bytes(b"a checkpoint")
    config = PROFILES["quick"]
    task = sim2real.arm_task("finetune-mixed", config, 0, chains, chains, chains, init, lab,
                              0.75)
    assert (task.init, task.mix, task.mix_weight) == (init, lab / "Train.csv", 0.75)
    assert (task.epochs, task.lr) == (config.finetune_epochs[0], config.finetune_lr)
    plain = sim2real.arm_task("finetune", config, 0, chains, chains, chains, init, lab, None)
    assert plain.mix is None and plain.key() != task.key()
    assert "finetune-mixed" not in config.arms          # trained only when named


def test_the_frozen_arm_fine_tunes_the_sim_model_with_its_encoders_fixed(tmp_path):
    """`--arm finetune-frozen`: the seed's sim checkpoint, its encoders kept fixed (as
    `train retlo --freeze-encoder`), no lab data mixed in; the other arms' keys unchanged."""
    from estimators.retlo.train import ENCODER

    chains, lab, init = np.zeros((4, 16, 3, 3)), tmp_path / "lab", tmp_path / "sim.pt"
    lab.mkdir()
    (lab / "Train.csv").write_text("lab rows")
    init.write_bytes(b"a checkpoint")
    config = replace(PROFILES["quick"], finetune_epochs=(3, 5))
    frozen = sim2real.arm_task("finetune-frozen", config, 0, chains, chains, chains, init, lab,
                                finetune_epochs=5)
    assert (frozen.init, frozen.mix, frozen.epochs) == (init, None, 5)
    assert frozen.train_config().frozen == ENCODER
    plain = sim2real.arm_task("finetune", config, 0, chains, chains, chains, init, lab,
                               finetune_epochs=5)
    assert plain.train_config().frozen == () and plain.key() != frozen.key()
    assert sim2real.candidates(config, "finetune-frozen") == [
        {"finetune_epochs": 3}, {"finetune_epochs": 5}]
    assert "finetune-frozen" not in config.arms            # trained only when named


def test_python_callers_get_the_cli_s_refusal_of_bad_fine_tuning_epochs(stand_in, tmp_path):
    """From Python, `validate` refuses what the flag refuses, before anything is collected."""
    for bad in ((0,), (2.5,), (), (True,)):
        with pytest.raises(UserError, match="--finetune-epochs"):
            sim2real.validate(replace(PROFILES["quick"], real=stand_in, finetune_epochs=bad))
    with pytest.raises(UserError, match=r"int64: pass int\(\.\.\.\)"):     # JSON cannot hold it
        sim2real.validate(replace(PROFILES["quick"], real=stand_in,
                                  finetune_epochs=(np.int64(30),)))
    sim2real.validate(replace(PROFILES["quick"], real=stand_in, finetune_epochs=(1, 2)))


def test_no_chained_reaches_every_arm_and_keeps_the_default_keys():
    """`--no-chained` trains every arm's model without chained Followers (they are scored on
    3-robot folds, where only the first module runs); the default keys stay those of the
    models already cached."""
    chains = np.zeros((4, 16, 3, 3))
    for chained in (True, False):
        config = replace(PROFILES["quick"], chained=chained)
        tasks = [sim2real.arm_task(arm, config, 0, chains, chains, chains, None, None)
                 for arm in ("real", "finetune")]
        assert all(t.train_config().chained is chained for t in tasks)
    plain = sim2real.ModelTask("real", 0, 2, chains, chains, chains)
    assert plain.key() == sim2real.ModelTask("real", 0, 2, chains, chains, chains,
                                             chained=True).key()
    assert plain.key() != sim2real.ModelTask("real", 0, 2, chains, chains, chains,
                                             chained=False).key()


def test_nested_fits_see_only_their_fold_s_training_blocks(stand_in, tmp_path, monkeypatch):
    """`--fit fold` fits each fold's lab on that fold's training and validation blocks alone
    (never its test block); `--fit train` on the real Train.csv (what the folds' test blocks
    are cut from: leaky). The first fit feeds the sim arm; each fit's sim-only models are
    reported apart, on the same folds. The fit and the collection are stand-ins here (a fit
    end to end is `test_sysid`'s): each fitted factor is made of its data's size, and each
    collection is the stand-in lab with as many Train rows dropped, so every fit trains its
    own models (fit k makes factor 1 + k / 10 and drops k rows)."""
    import macrostate_mj.app.usecases.sysid

    seen = {}

    def fit(cfg, train, val, out, progress=None):
        seen[len(seen)] = (train, val)
        score = {"before": 1.0, "after": 0.5}
        return {"fitted": {"k_f": 1 + len(seen) / 10}, "train": score, "val": score}

    def lab(config, out, progress, randomize):
        drop = round((json.loads(Path(randomize).read_text())["k_f"][0] / 0.8 - 1) * 10)
        out.mkdir(parents=True, exist_ok=True)
        rows = (stand_in / "Train.csv").read_text().splitlines(keepends=True)
        (out / "Train.csv").write_text("".join(rows[:-drop]))
        shutil.copy(stand_in / "Val.csv", out / "Val.csv")
        return out

    monkeypatch.setattr(macrostate_mj.app.usecases.sysid, "fit", fit)
    monkeypatch.setattr(sim2real.data, "_collect", lab)
    config = replace(PROFILES["quick"], real=stand_in, arms=("sim", "real"),
                     fits=("fold", "train"), randomize=("wide",))
    out = tmp_path / "nested"
    execute("sim2real", config, out)
    pooled = sim2real.read_real(stand_in)
    n_train = len(read_csv(stand_in / "Train.csv").poses)
    for fold in range(2):
        pool, val, test = cv_blocks(len(pooled), config.folds, fold, config.val_share)
        train_seen, val_seen = seen[fold]
        assert np.array_equal(train_seen, pooled[pool]) and np.array_equal(val_seen,
                                                                             pooled[val])
        assert len(train_seen) + len(val_seen) == len(pooled) - len(test)
    assert np.array_equal(seen[2][0], pooled[:n_train])
    assert np.array_equal(seen[2][1], pooled[n_train:])
    results = json.loads((out / "results.json").read_text())
    assert set(results["fits"]) == {"fold0", "fold1", "train"}
    assert results["fits"]["fold1"]["fitted"] == {"k_f": 1.2}
    by_fit = results["sim_by_fit"]
    assert by_fit["fold"]["head_cm"] == results["arms"]["sim"]["0"]["head_cm"]
    assert by_fit["fold"]["head_cm_by_seed"] != by_fit["train"]["head_cm_by_seed"]
    assert by_fit["train"]["sim_over_real"] == pytest.approx(
        by_fit["train"]["head_cm"]["mean"] / results["arms"]["real"]["1"]["head_cm"]["mean"])
    data = results["fits"]["fold0"]["data"]
    profile = json.loads((out / "data" / f"{data}.profile.json").read_text())
    assert profile["k_f"] == pytest.approx([0.8 * 1.1, 1.2 * 1.1])    # wide's, around 1.1
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["models_trained"] == 2 * 2 + 2 * 2       # sim per fit and seed; real
    bad = replace(config, fits=("fold", "fold"))
    with pytest.raises(UserError, match="at most once"):
        sim2real.validate(bad)


def test_randomization_candidates_are_chosen_on_each_fold_s_validation_block(stand_in,
                                                                              tmp_path,
                                                                              monkeypatch):
    """Several `--randomize` candidates: each seed's sim model is the candidate's whose Head
    error on that fold's real validation block (never its test block) is lowest; the sim arm
    reports it and the fine-tuned arm starts from it. The collections are stand-ins (`wide`'s
    drops Train rows, so its models differ)."""
    from estimators.retlo.files import pixels_to_world

    def lab(config, out, progress, randomize):
        out.mkdir(parents=True, exist_ok=True)
        rows = (stand_in / "Train.csv").read_text().splitlines(keepends=True)
        (out / "Train.csv").write_text("".join(rows[:-7] if randomize else rows))
        shutil.copy(stand_in / "Val.csv", out / "Val.csv")
        return out

    made = []
    original = sim2real.ModelTask.__init__

    def record(self, *args, **kwargs):
        original(self, *args, **kwargs)
        made.append(self)

    monkeypatch.setattr(sim2real.data, "_collect", lab)
    monkeypatch.setattr(sim2real.ModelTask, "__init__", record)
    config = replace(PROFILES["quick"], real=stand_in, arms=("sim", "finetune"),
                     fractions=(1.0,), randomize=("none", "wide"), finetune_epochs=(1, 2))
    out = tmp_path / "chosen"
    execute("sim2real", config, out)
    results = json.loads((out / "results.json").read_text())
    ranges = results["ranges"]["none"]
    pooled = pixels_to_world(sim2real.read_real(stand_in), DEFAULT_PX_PER_CM)
    sims = [t for t in made if t.arm == "sim"]
    assert len(sims) == 4
    for s in ("0", "1"):
        cands = ranges["candidates"]
        pick = min(("none", "wide"), key=lambda r: cands[r]["select_head_cm_by_seed"][s])
        assert ranges["chosen_by_seed"][s] == pick
        assert results["arms"]["sim"]["0"]["head_cm_by_seed"][s] == \
            cands[pick]["head_cm_by_seed"][s]
        _, val, test = cv_blocks(len(pooled), config.folds, int(s), config.val_share)
        for task in (t for t in sims if t.seed == int(s)):
            assert np.array_equal(task.select, pooled[val])
            assert np.array_equal(task.test, pooled[test])
        chosen = next(t for t in sims if t.seed == int(s) and
                      (t.train.parent.name == "sim-" + task_key("sim2real-lab", 1,
                                                                        "wide")[:12])
                      == (pick == "wide"))
        tuned = [t for t in made if t.arm == "finetune" and t.seed == int(s)]
        assert {t.init.parent.name for t in tuned} == {chosen.key()}
        assert sorted(t.epochs for t in tuned) == [1, 2]      # each candidate fine-tunes
        val_cm = {t.epochs: json.loads((out / "cache" / "sim2real-model" / t.key() /
                                        "report.json").read_text())["best_val_cm"]
                  for t in tuned}
        epochs = results["finetunes"]["finetune"]["1"]
        assert epochs["chosen_by_seed"][s] == min(val_cm, key=lambda e: (val_cm[e], e))
        kept = epochs["epochs"][str(epochs["chosen_by_seed"][s])]["head_cm_by_seed"][s]
        assert results["arms"]["finetune"]["1"]["head_cm_by_seed"][s] == kept
    assert "--randomize chosen per fold (none)" in "\n".join(summary_lines(results))
    with pytest.raises(UserError, match="each candidate once"):
        sim2real.validate(replace(config, randomize=("wide", "wide")))


def test_ablations_switch_parameters_off_in_each_seed_s_own_profile(stand_in, tmp_path,
                                                                    monkeypatch):
    """`--ablate`: per seed, a lab collected from the profile its sim model used with the
    named parameters removed trains one more sim-only model, paired with the lab's own (mean
    and 95 % interval of the difference). Collections are stand-ins (a profile with `k_f`
    drops Train rows, so switching it off changes the data); bad names are one line."""
    profiles = []

    def lab(config, out, progress, randomize):
        profile = json.loads(Path(randomize).read_text()) if randomize else {}
        profiles.append(profile)
        out.mkdir(parents=True, exist_ok=True)
        rows = (stand_in / "Train.csv").read_text().splitlines(keepends=True)
        (out / "Train.csv").write_text("".join(rows[:-7] if "k_f" in profile else rows))
        shutil.copy(stand_in / "Val.csv", out / "Val.csv")
        return out

    ranges = tmp_path / "ranges.json"
    ranges.write_text(json.dumps({"k_f": [0.9, 1.1], "k_t": 1.2}))
    monkeypatch.setattr(sim2real.data, "_collect", lab)
    config = replace(PROFILES["quick"], real=stand_in, arms=("sim",), randomize=(str(ranges),),
                     ablate=(("k_f",), ("k_t", "k_omega")))
    out = tmp_path / "ablate"
    execute("sim2real", config, out)
    assert profiles[1:] == [{"k_t": 1.2}, {"k_t": 1.2}, {"k_f": [0.9, 1.1]},
                            {"k_f": [0.9, 1.1]}]
    results = json.loads((out / "results.json").read_text())
    lab_by_seed = results["arms"]["sim"]["0"]["head_cm_by_seed"]
    without_kf = results["ablations"]["k_f"]
    diffs = [without_kf["head_cm_by_seed"][s] - lab_by_seed[s] for s in ("0", "1")]
    assert without_kf["minus_lab"]["mean"] == pytest.approx(np.mean(diffs))
    assert without_kf["minus_lab"]["low"] < without_kf["minus_lab"]["mean"]
    assert results["ablations"]["k_t,k_omega"]["head_cm_by_seed"] == lab_by_seed  # same data
    assert "without k_f: Head" in "\n".join(summary_lines(results))
    with pytest.raises(UserError, match="--ablate k_x"):
        sim2real.validate(replace(config, ablate=(("k_x",),)))
    with pytest.raises(UserError, match="make the first --fit"):
        sim2real.validate(replace(config, randomize=()))


def test_ablations_that_cannot_be_measured_are_refused_or_said(stand_in, tmp_path, monkeypatch):
    """A group the lab's profile does not hold trains nothing and says so; a repeated group,
    or an ablation with no sim models to train, is refused in one line."""
    lab = _copying(stand_in)
    ranges = tmp_path / "ranges.json"
    ranges.write_text(json.dumps({"k_f": [0.9, 1.1]}))
    monkeypatch.setattr(sim2real.data, "_collect", lab)
    config = replace(PROFILES["quick"], real=stand_in, arms=("sim",), randomize=(str(ranges),),
                     ablate=(("frame_hz",),))
    execute("sim2real", config, tmp_path / "absent")
    results = json.loads((tmp_path / "absent" / "results.json").read_text())
    assert results["ablations"]["frame_hz"]["minus_lab"]["n"] == 0
    assert "not in the lab's profile" in "\n".join(summary_lines(results))
    for bad, words in (({"ablate": (("k_f", "k_t"), ("k_t", "k_f"))}, "each group once"),
                       ({"arms": ("real",)}, "add --arm sim")):
        with pytest.raises(UserError, match=words):
            sim2real.validate(replace(config, **bad))


def test_sim_models_are_picked_on_the_lab_or_on_the_real_validation_block(tmp_path):
    """`--sim-select real` stops a sim model's training on the fold's real validation block
    (the test block still takes no part); the default, the lab's Val.csv, keeps its keys."""
    lab, val, test = tmp_path / "lab", np.zeros((4, 16, 3, 3)), np.ones((4, 16, 3, 3))
    lab.mkdir()
    for name in ("Train.csv", "Val.csv"):
        (lab / name).write_text(name)                    # keys read their inputs' bytes
    plain = sim2real.sim_task(PROFILES["quick"], 0, lab, val, test, choose=False)
    assert (plain.train, plain.val, plain.select) == (lab / "Train.csv", lab / "Val.csv", None)
    assert plain.key() == sim2real.ModelTask("sim", 0, PROFILES["quick"].epochs,
                                             lab / "Train.csv", lab / "Val.csv", test).key()
    real = sim2real.sim_task(replace(PROFILES["quick"], sim_select="real"), 0, lab, val, test,
                              choose=True)
    assert real.val is val and real.select is val and real.test is test
    assert real.key() != plain.key()
    res = cli("experiment", "sim2real", "--quick", "--sim-select", "test",
              "--out", str(tmp_path / "bad"))
    assert_clean_error(res, "--sim-select")
    assert not (tmp_path / "bad").exists()
    with pytest.raises(UserError, match="--sim-select"):     # from Python, the same check
        sim2real.validate(replace(PROFILES["quick"], sim_select="test"))


def test_train_only_cross_validates_without_reading_the_sealed_file(stand_in, tmp_path,
                                                                     monkeypatch):
    """`--train-only`: the folds are cut from Train.csv alone and a `--fit train` is checked
    on Train's last 15 %; a folder without Val.csv is enough, so the sealed file is never
    read (its absence proves it)."""
    import macrostate_mj.app.usecases.sysid

    seen = []

    def fit(cfg, train, val, out, progress=None):
        seen.append((train, val))
        score = {"before": 1.0, "after": 0.5}
        return {"fitted": {"k_f": 1.0}, "train": score, "val": score}

    lab = _copying(stand_in)
    folder = tmp_path / "train_only"
    folder.mkdir()
    shutil.copy(stand_in / "Train.csv", folder / "Train.csv")
    monkeypatch.setattr(macrostate_mj.app.usecases.sysid, "fit", fit)
    monkeypatch.setattr(sim2real.data, "_collect", lab)
    config = replace(PROFILES["quick"], real=folder, arms=("sim", "real"), fits=("train",),
                     randomize=("wide",), train_only=True)
    train = read_csv(folder / "Train.csv").poses
    assert np.array_equal(sim2real.validate(config), train)
    execute("sim2real", config, tmp_path / "out")
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    assert results["real_instances"] == len(train)
    n_check = round(0.15 * len(train))
    assert np.array_equal(seen[0][0], train[:-n_check]) and np.array_equal(seen[0][1],
                                                                         train[-n_check:])
    with pytest.raises(UserError, match="Val.csv"):
        sim2real.validate(replace(config, train_only=False))


def _copying(stand_in: Path):
    """A stand-in for the lab collection (`sim2real.data._collect`): the stand-in files copied."""
    def lab(config, out, progress, randomize):
        out.mkdir(parents=True, exist_ok=True)
        for name in ("Train.csv", "Val.csv"):
            shutil.copy(stand_in / name, out / name)
        return out
    return lab
