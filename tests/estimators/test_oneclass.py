"""One-class models: every method trains a few steps and scores; AUC and bins; label switch;
save/load; determinism; Grad-CAM and the pointing game; CLI train/evaluate and bad input."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from builders import make_layout
from clitools import cli as _cli

from estimators.oneclass import METHODS, OCConfig, OCModel, fit
from estimators.oneclass.metrics import auc_report, roc_auc
from estimators.oneclass.train import train_classifier
from macrostate_mj.core.errors import UserError
from viz.gradcam import (
    box_counts,
    box_share,
    centre_prior,
    gradcam,
    hit_share,
    pointing_game,
    top_pixels,
    top_share,
)

REPO = Path(__file__).resolve().parents[2]
TINY = OCConfig(m=1, seed=3, batch=16, dcae_epochs=1, dsvdd_epochs=1, gan_steps=2, gan_batch=4,
                cls_epochs=1)


def _flows(n: int, motion: float, seed: int) -> np.ndarray:
    """N × 2 × 64 × 64 inputs: noise around `motion` px, scaled like the loader (±20 px = ±1)."""
    rng = np.random.default_rng(seed)
    return ((motion + rng.normal(0, 0.3, (n, 2, 64, 64))) / 20).astype(np.float32)


@pytest.fixture(scope="module")
def fitted():
    x = _flows(40, 0.0, 0)
    return fit(x, METHODS, TINY), x


def test_every_method_trains_and_scores(fitted, tmp_path):
    model, x = fitted
    stable, unstable = _flows(12, 0.0, 1), _flows(12, 3.0, 2)
    for meth in METHODS:
        s, u = model.score(meth, stable), model.score(meth, unstable)
        assert s.shape == (12,) and u.shape == (12,) and np.isfinite(np.r_[s, u]).all(), meth
    assert roc_auc(model.score("ofw", stable), model.score("ofw", unstable)) == 1.0
    model.save(tmp_path)
    again = OCModel.load(tmp_path)
    for meth in METHODS:
        np.testing.assert_allclose(again.score(meth, unstable), model.score(meth, unstable),
                                   rtol=1e-5, atol=1e-6)
    with pytest.raises(UserError, match="m = 1"):
        model.score("dsvdd", _flows(2, 0.0, 0).repeat(2, axis=1))


def test_ngen_noise_has_iogen_spread_per_coordinate_around_c(fitted):
    from estimators.oneclass.model import _synthetic
    from estimators.oneclass.train import generated_codes

    model, _ = fitted
    noise, _ = _synthetic(model, "ngen", 4000, 1, torch.Generator().manual_seed(0))
    ref = generated_codes(model.generators["iogen"], model.dsvdd, 4000,
                          torch.Generator().manual_seed(1))
    spread = ((ref - model.c) ** 2).mean(0).sqrt()
    assert float(noise.min()) >= 0.0  # codes are ReLU outputs
    free = model.c > 4 * spread  # coordinates the clamp at 0 never reaches
    assert int(free.sum()) > 50
    got = ((noise - model.c) ** 2).mean(0).sqrt()
    np.testing.assert_allclose(got[free], spread[free], rtol=0.15, atol=1e-3)
    assert float((noise.mean(0) - model.c)[free].abs().max()) < 5 * float(spread.max()) / 4000 ** .5
    # busy coordinates get busy noise, quiet ones stay quiet: not one global spread
    assert np.corrcoef(got.numpy(), spread.numpy())[0, 1] > 0.9


def test_same_seed_same_model(fitted):
    model, x = fitted
    again = fit(x, ("dsvdd",), TINY)
    probe = _flows(5, 1.0, 9)
    assert np.array_equal(again.score("dsvdd", probe), model.score("dsvdd", probe))


def test_bf16_training_repeats_keeps_float32_weights_and_differs_from_fp32(fitted):
    model, x = fitted
    bf16 = replace(TINY, precision="bf16")
    one, two = fit(x, ("dsvdd", "iogen"), bf16), fit(x, ("dsvdd", "iogen"), bf16)
    probe = _flows(5, 1.0, 9)
    for meth in ("dsvdd", "iogen"):
        assert np.array_equal(one.score(meth, probe), two.score(meth, probe)), meth
    assert not np.array_equal(one.score("dsvdd", probe), model.score("dsvdd", probe))
    assert all(p.dtype == torch.float32 for p in one.dsvdd.parameters())
    assert one.score("iogen", probe).dtype == np.float32      # scored in float32 all the same
    with pytest.raises(UserError, match="unknown precision 'fp16'; choose fp32 or bf16"):
        replace(TINY, precision="fp16")
    with pytest.raises(UserError, match="precision has an option of its own"):
        TINY.overridden(["precision=bf16"])           # it has its option: --precision


def test_ocsvm_matches_sklearn(fitted):
    from sklearn.svm import OneClassSVM

    from estimators.oneclass.model import fit_ocsvm

    codes = torch.from_numpy(np.random.default_rng(0).random((60, 16)).astype(np.float32))
    ours = fit_ocsvm(codes, 0.1)
    ref = OneClassSVM(nu=0.1, gamma="scale").fit(codes.double().numpy())
    model, _ = fitted
    model_svm = OCModel(model.cfg, ("ocsvm",), 2, ocsvm=ours)
    np.testing.assert_allclose(model_svm._svm_decision(codes[:7]),
                               ref.decision_function(codes[:7].double().numpy()), rtol=1e-6)


def test_auc_and_bins():
    assert roc_auc([0, 1, 2], [3, 4]) == 1.0 and roc_auc([3, 4], [0, 1, 2]) == 0.0
    assert roc_auc([1, 1], [1, 1]) == 0.5  # ties count half
    assert roc_auc([0, 2], [1, 3]) == 0.75 and np.isnan(roc_auc([], [1.0]))
    rep = auc_report(np.zeros(4), np.array([1.0, -1.0, 2.0]), ["D+1", "D+2", "D+1"],
                     ["D+1", "D+2", "D+3-6"])
    assert rep["auc_bins"] == {"D+1": 1.0, "D+2": 0.0, "D+3-6": None}
    assert rep["auc_all"] == pytest.approx(2 / 3) and rep["n_unstable_bins"]["D+1"] == 2


def test_label_switch_makes_farther_codes_more_unstable():
    """Real stable codes (label 1) vs inner outliers near c (label 0): a code farther from c than
    the real ones must score higher, i.e. the classifier's 'unstable' grows with distance. The
    second case is the simulated colony's trap: synthetic codes leave c in the direction in which
    unstable codes lie farther out; a classifier on signed deviations scores those as synthetic."""
    g = torch.Generator().manual_seed(0)
    c = torch.full((2048,), 0.5)
    lean = torch.zeros(2048)
    lean[::2] = 0.02
    cfg = OCConfig(cls_epochs=6, cls_lr=1e-3)
    for fake_lean, far_lean, far_sd in ((0.0, 0.0, 0.15), (1.0, 3.0, 0.05)):
        real = c + 0.05 * torch.randn(200, 2048, generator=g)
        fake = c + fake_lean * lean + 0.01 * torch.randn(400, 2048, generator=g)
        torch.manual_seed(0)
        clf, hist = train_classifier(real[:160], real[160:], fake[:300], fake[300:], c, cfg, g,
                                     lambda s, f: None, "cls")
        far = c + far_lean * lean + far_sd * torch.randn(40, 2048, generator=g)
        with torch.no_grad():
            assert clf(fake[300:]).max() < clf(real[160:]).min(), fake_lean
            assert clf(real[160:]).mean() < clf(far).min(), fake_lean
        assert min(hist) < 0.3


def test_gradcam_and_pointing_game(fitted):
    model, _ = fitted
    x = _flows(3, 2.0, 5)
    maps = gradcam(model.dsvdd, model.classifiers["iogen"], x)
    assert maps.shape == (3, 8, 8) and (maps >= 0).all()
    shown = top_share(np.random.default_rng(0).random((4, 64, 64)))
    assert ((shown > 0).mean(axis=(1, 2)) <= 0.06).all()
    heat = np.zeros((3, 64, 64))
    heat[0, 10, 20] = heat[1, 50, 50] = 1.0  # sample 2: a flat map points nowhere
    boxes = [[(15, 5, 10, 10)], [(0, 0, 10, 10)], [(0, 0, 64, 64)]]
    assert pointing_game(heat, boxes) == pytest.approx(1 / 3)
    assert pointing_game(heat, [[], [(40, 40, 5, 5)], []], tolerance=6) == 1.0
    # chance: box (15, 5, 10, 10) holds 100 of 4096 pixel centres, the full frame all of them
    assert box_share([[(15, 5, 10, 10)], [], [(0, 0, 64, 64)]], (64, 64)) == pytest.approx(
        (100 / 4096 + 1) / 2)


def test_top_five_percent_box_hits_and_their_baselines():
    """The §4.7.4 pointing game: a box is hit when one of a map's top 5 % pixels lies in it."""
    heat = np.zeros((3, 64, 64))
    heat[0, 30:45, 30:45] = 1.0             # 225 px >= the 205 kept: all inside (30..45)
    heat[1, 0:15, 0:15] = 1.0               # in the corner, away from its box
    boxes = [[(28, 28, 20, 20), (0, 50, 5, 5)], [(40, 40, 10, 10)], []]
    hits, on = box_counts(heat, boxes)      # sample 2 has no box
    assert hits.tolist() == [[1, 2], [0, 1], [0, 0]]
    assert top_pixels(heat[0]).sum() == 205 and not top_pixels(np.zeros((64, 64))).any()
    share = hit_share(hits, np.random.default_rng(0), resamples=200)
    assert share["share"] == pytest.approx(1 / 3) and share["samples"] == 2
    assert share["lo"] <= share["share"] <= share["hi"]
    centre = centre_prior(2, (64, 64))      # the top 5 % of a centre prior: a central disc
    assert box_counts(centre, [[(30, 30, 4, 4)], [(0, 0, 8, 8)]])[0].tolist() == [[1, 1], [0, 1]]
    assert hit_share(np.zeros((2, 2), int), np.random.default_rng(0))["share"] is None
    # pixels on boxes: the square lies inside sample 0's first box
    assert on.tolist() == [[205, 205], [0, 205], [0, 0]]
    assert box_counts(np.zeros((1, 64, 64)), [[(0, 0, 9, 9)]])[1].tolist() == [[0, 205]]


def test_cli_train_evaluate_and_bad_input(tmp_path):
    data = make_layout(tmp_path / "ds", stable=20, unstable=(1333, 2000, 3000, 9500))
    model = tmp_path / "model"
    run = _cli("oc", "train", "--method", "dsvdd", "--data", str(data), "--split", "2", "--m",
               "2", "--out", str(model), "--seed", "1", "--epoch-scale", "0.05", "--threads", "1")
    assert run.returncode == 0, run.stderr
    assert {"weights.pt", "model.json", "manifest.json"} <= {p.name for p in model.iterdir()}
    report = tmp_path / "report.json"
    run = _cli("oc", "evaluate", "--model", str(model), "--data", str(data), "--split", "2",
               "--out", str(report))
    assert run.returncode == 0, run.stderr
    assert "4 stable and 4 unstable samples is a smoke test" in run.stderr   # said, not hidden
    rep = json.loads(report.read_text())
    assert set(rep["auc_bins"]) == {"D+1", "D+2", "D+3-6", "D+7-10", "D+11-14", "D+15-18"}
    # n_stable = 20: ids 1333, 2000, 3000, 9500 sit at positions 1313, 1980, 2980, 9480
    assert rep["n_unstable_bins"]["D+3-6"] == 2 and rep["auc_bins"]["D+1"] is None
    assert rep["auc_all"] > 0.9  # 4 px of motion against 0: any sane model separates them
    manifest = json.loads((tmp_path / "report.json.manifest.json").read_text())
    assert manifest["command"] == "oc evaluate" and manifest["status"] == "finished"
    assert manifest["config"]["split"] == 2 and "evaluate" in manifest["timings_s"]

    for args, words in ((("oc", "train", "--method", "svm", "--data", str(data), "--out",
                          str(tmp_path / "m2")), "'--method': 'svm' is not one of"),
                        (("oc", "evaluate", "--model", str(tmp_path), "--data", str(data),
                          "--out", str(tmp_path / "r.json")), "not a trained model"),
                        (("oc", "evaluate", "--model", str(model), "--data", str(data),
                          "--out", str(report)), "already exists")):
        run = _cli(*args)
        assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
        assert run.stderr.strip().count("\n") == 0 and words in run.stderr, run.stderr
    assert not (tmp_path / "m2").exists() or not any((tmp_path / "m2").iterdir())


@pytest.mark.skipif(torch.cuda.is_available(), reason="a GPU is here: --device cuda is valid")
def test_device_cuda_without_a_gpu_is_refused_before_anything_is_written(tmp_path):
    data = make_layout(tmp_path / "ds", stable=20, unstable=(1333, 2000))
    out = tmp_path / "out"
    for command in (("oc", "train", "--method", "dsvdd"), ("experiment", "oc")):
        run = _cli(*command, "--data", str(data), "--out", str(out), "--device", "cuda")
        assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
        assert "sees no GPU" in run.stderr and "--device cpu" in run.stderr, run.stderr
        assert not out.exists()


def test_rank_auc_is_scikit_learns_auc_ties_included():
    from estimators.oneclass.metrics import rank_auc, roc_auc

    rng = np.random.default_rng(0)
    neg, pos = rng.integers(0, 20, 300).astype(float), rng.integers(3, 25, 500).astype(float)
    assert rank_auc(neg, pos) == pytest.approx(roc_auc(neg, pos), abs=1e-12)


def test_bootstrap_interval_covers_the_true_auc():
    """Scores N(0, 1) against N(1, 1): AUC = Phi(1 / sqrt 2) = 0.7602. A 95 % interval should
    hold it in about 95 % of datasets; over 40 datasets, at least 34."""
    from scipy.stats import norm

    from estimators.oneclass.metrics import auc_interval

    truth = norm.cdf(1 / np.sqrt(2))
    hits = 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        lo, hi = auc_interval(rng.normal(0, 1, 266), rng.normal(1, 1, 400), n_resamples=500,
                              seed=seed)
        hits += lo <= truth <= hi
        assert 0.03 < hi - lo < 0.15
    assert hits >= 34
    assert auc_interval(np.zeros(1), np.ones(5)) is None


def test_paired_test_on_known_inputs():
    from estimators.oneclass.metrics import paired_auc_test

    rng = np.random.default_rng(1)
    base_neg, base_pos = rng.normal(0, 1, 200), rng.normal(0.8, 1, 300)
    same = paired_auc_test(base_neg, base_pos, base_neg, base_pos, n_resamples=300)
    assert same["diff"] == 0 and same["p"] == 1.0
    better = paired_auc_test(base_neg, base_pos + 0.5, base_neg, base_pos, n_resamples=300)
    assert better["diff"] > 0.05 and better["p"] < 0.01
    false_alarms = 0
    for seed in range(30):      # two equally good, differently noisy methods: p ~ uniform
        r = np.random.default_rng(100 + seed)
        neg, pos = r.normal(0, 1, 150), r.normal(0.8, 1, 200)
        a = paired_auc_test(neg + r.normal(0, .5, 150), pos + r.normal(0, .5, 200),
                            neg + r.normal(0, .5, 150), pos + r.normal(0, .5, 200),
                            n_resamples=300, seed=seed)
        false_alarms += a["p"] < 0.05
    assert false_alarms <= 5
    with pytest.raises(ValueError):
        paired_auc_test(base_neg, base_pos, base_neg[:10], base_pos)


def test_evaluate_on_a_held_apart_unstable_set_with_intervals_and_a_baseline(tmp_path):
    """`--unstable DIR` scores a dev set by its ids (20 stable here: D+1 is ids 20..685), with
    bootstrap intervals and a paired test against a baseline method of the same model."""
    import shutil

    data = make_layout(tmp_path / "ds", stable=20, unstable=(1333, 2000, 3000, 9500))
    dev = tmp_path / "dev" / "Unstable"
    make_layout(tmp_path / "devsrc", stable=20, unstable=(100, 200, 1000, 4010, 9000), seed=3)
    shutil.copytree(tmp_path / "devsrc" / "Unstable", dev)
    model = tmp_path / "model"
    run = _cli("oc", "train", "--method", "all", "--data", str(data), "--split", "2", "--m", "2",
               "--out", str(model), "--seed", "1", "--epoch-scale", "0.02", "--threads", "1")
    assert run.returncode == 0, run.stderr
    report = tmp_path / "dev.json"
    run = _cli("oc", "evaluate", "--model", str(model), "--data", str(data), "--split", "2",
               "--method", "iogen", "--baseline", "dsvdd", "--unstable", str(dev),
               "--out", str(report))
    assert run.returncode == 0, run.stderr
    rep = json.loads(report.read_text())
    assert rep["n_unstable"] == 5 and rep["n_unstable_bins"]["D+1"] == 2
    lo, hi = rep["auc_ci95"]["all"]
    assert lo <= rep["auc_all"] <= hi
    assert rep["vs_baseline"]["baseline"] == "dsvdd" and 0 <= rep["vs_baseline"]["all"]["p"] <= 1
    assert "vs dsvdd" in run.stdout


def test_significance_marks_need_every_split_to_agree():
    from macrostate_mj.app.experiments.oc import significance_marks

    def t(diff, p):
        return {"diff": diff, "p": p}

    splits = [{"all": t(0.05, 0.01), "bins": {"D+1": t(0.1, 0.001), "D+2": t(-0.1, 0.01),
                                              "D+3-6": None}},
              {"all": t(0.04, 0.03), "bins": {"D+1": t(0.1, 0.2), "D+2": t(-0.2, 0.001),
                                              "D+3-6": t(0.3, 0.0)}}]
    assert significance_marks(splits, ("D+1", "D+2", "D+3-6")) == {
        "all": "+", "D+1": "", "D+2": "-", "D+3-6": ""}


def test_a_killed_training_resumes_from_its_last_stage_with_the_same_weights(tmp_path):
    """Stages cached on disk: a rerun that finds dcae and dsvdd done (the later stages lost, as
    when a run is killed) ends with the same scores as one uninterrupted run."""
    rng = np.random.default_rng(0)
    x = rng.normal(0, 0.1, (40, 4, 64, 64)).astype(np.float32)
    probe = rng.normal(0, 0.3, (6, 4, 64, 64)).astype(np.float32)
    cfg = OCConfig.recipe("short", seed=2).scaled(0.02)
    plain = fit(x, ("dsvdd", "iogen"), cfg)
    stages = tmp_path / "stages"
    first = fit(x, ("dsvdd", "iogen"), cfg, stages_dir=stages)
    assert _stages(stages) == {"dcae": ["key"], "dsvdd": ["key"], "iogen": ["key"],
                               "cls_iogen": ["key"]}
    for late in ("iogen", "cls_iogen"):
        shutil.rmtree(stages / f"oc-{late}")
    resumed = fit(x, ("dsvdd", "iogen"), cfg, stages_dir=stages)
    assert resumed.resumed == ["dcae", "dsvdd"]
    for meth in ("dsvdd", "iogen"):
        assert np.array_equal(plain.score(meth, probe), first.score(meth, probe))
        assert np.array_equal(plain.score(meth, probe), resumed.score(meth, probe))
    other = fit(x, ("dsvdd",), OCConfig.recipe("short", seed=3).scaled(0.02), stages_dir=stages)
    assert other.resumed == []                      # another config: nothing reused
    assert OCConfig.recipe("published").gan_steps == 20_000


class _Killed(Exception):
    pass


def _stages(folder) -> dict[str, list[str]]:
    """What a stage cache holds: per stage, a finished key folder ("key") or a snapshot."""
    return {d.name.removeprefix("oc-"): sorted("partial" if p.name.endswith(".partial.pt")
                                               else "key" for p in d.iterdir())
            for d in folder.iterdir() if d.is_dir()}


def test_a_stage_killed_midway_goes_on_from_its_snapshot_with_the_same_weights(tmp_path):
    """A long stage keeps its loop state (`<stage>.partial.pt`): killed inside the DCAE, then
    inside the IO-GEN GAN, each rerun's progress starts where the last stopped, and the run
    ends with the weights of one uninterrupted run, no snapshot left behind."""
    rng = np.random.default_rng(0)
    x = rng.normal(0, 0.1, (40, 4, 64, 64)).astype(np.float32)
    probe = rng.normal(0, 0.3, (6, 4, 64, 64)).astype(np.float32)
    cfg = OCConfig(seed=2, batch=16, dcae_epochs=3, dsvdd_epochs=2, gan_steps=12, gan_batch=4,
                   cls_epochs=2)
    plain = fit(x, ("dsvdd", "iogen"), cfg)
    stages = tmp_path / "stages"

    def run(kill: tuple[str, float] | None) -> tuple[dict[str, list[float]], OCModel | None]:
        ticks: dict[str, list[float]] = {}

        def tick(stage: str, frac: float) -> None:
            ticks.setdefault(stage, []).append(frac)
            if kill is not None and stage == kill[0] and frac >= kill[1]:
                raise _Killed
        try:
            return ticks, fit(x, ("dsvdd", "iogen"), cfg, tick, stages, snapshot_every_s=0)
        except _Killed:
            return ticks, None

    ticks, _ = run(("DCAE", 2 / 3))
    assert ticks["DCAE"] == [1 / 3, 2 / 3] and _stages(stages) == {"dcae": ["partial"]}
    ticks, _ = run(("IOGEN", 10 / 12))
    assert ticks["DCAE"] == [1.0] and ticks["IOGEN"] == [10 / 12]
    assert _stages(stages) == {"dcae": ["key"], "dsvdd": ["key"], "iogen": ["partial"]}
    ticks, resumed = run(None)
    assert ticks["IOGEN"] == [1.0] and resumed.resumed == ["dcae", "dsvdd"]
    assert not list(stages.glob("*/*.partial.pt"))
    for meth in ("dsvdd", "iogen"):
        assert np.array_equal(plain.score(meth, probe), resumed.score(meth, probe))


def test_experiment_oc_over_splits_and_seeds_resumes_from_its_reports(tmp_path):
    """Tables are mean ± std over every (split, seed) run; each run's report is all a rerun
    needs (what a fresh machine has from a copy kept in git), and gives the same results; the
    research probe adds what a checkpoint chosen on test would score and changes nothing else."""
    import shutil

    data = make_layout(tmp_path / "ds", stable=20, unstable=(1333, 2000, 3000, 9500))
    # true duel boxes, as a simulated colony writes them: Grad-CAM is scored against them
    (data / "boxes.csv").write_text("sample_id,k,x,y,w,h\n1333,0,0,0,32,32\n2000,1,8,8,9,9\n")
    out = tmp_path / "tables"
    base = ("experiment", "oc", "--data", str(data), "--out", str(out), "--splits", "2", "--ms",
            "2", "--seed", "5", "--epoch-scale", "0.003", "--threads", "1")
    args = (*base, "--seeds", "2")
    run = _cli(*args)
    assert run.returncode == 0, run.stderr
    results = json.loads((out / "results.json").read_text())
    keys = {"m2_split2_s5", "m2_split2_s6"}
    assert set(results["runs"]) == keys
    aucs = [results["runs"][k]["iogen"]["auc_all"] for k in sorted(keys)]
    assert results["table4_2_auc_m2"]["iogen"]["mean"] == pytest.approx(np.mean(aucs))
    assert results["table4_2_auc_m2"]["iogen"]["std"] == pytest.approx(np.std(aucs))
    top5 = results["gradcam"]["top5"]
    assert set(top5) == {"gradcam", "gradcam_display", "flow_magnitude", "centre_prior",
                         "random"}
    hit = top5["centre_prior"]["boxes_hit"]["all"]
    assert hit["total"] == 2 and hit["samples"] == 2
    assert hit["share"] == 0.5                     # the 9 x 9 box misses the central disc
    on = top5["centre_prior"]["pixels_on_boxes"]["all"]    # 205 px a sample; the 32 x 32 box
    assert on["total"] == 410 and 0 < on["share"] < 0.5    # holds the disc's upper-left part
    assert (out / "gradcam" / "overlay_stable_unstable.png").stat().st_size > 0
    tables = (out / "tables.md").read_text()
    assert "split and seed" in tables
    assert "| IO-GEN | " in tables and "| 0.786 ± 0.009 |" in tables     # the text's beside ours
    before = (out / "results.json").read_bytes()
    for stage in (out / "cache").iterdir():       # keep only the runs' reports
        if stage.name != "oc-run":
            shutil.rmtree(stage)
    run = _cli(*args, "--overwrite")
    assert run.returncode == 0, run.stderr
    assert (out / "results.json").read_bytes() == before
    assert json.loads((out / "manifest.json").read_text())["status"] == "finished"
    # a report is keyed by its seed: another first seed trains only its own run
    run = _cli(*base, "--seed", "6", "--seeds", "1", "--overwrite")
    assert run.returncode == 0, run.stderr
    rerun = json.loads((out / "results.json").read_text())
    assert rerun["figures_run"] == "m2_split2_s6"
    assert rerun["runs"]["m2_split2_s6"] == results["runs"]["m2_split2_s6"]
    # the research probe: same honest figures, plus what choosing epochs on test would score
    run = _cli(*base, "--seeds", "1", "--probe-test", "--overwrite")
    assert run.returncode == 0, run.stderr
    probed = json.loads((out / "results.json").read_text())
    assert probed["runs"]["m2_split2_s5"]["iogen"] == results["runs"]["m2_split2_s5"]["iogen"]
    picks = probed["selection_on_test"]["iogen"]
    assert picks["best_auc"]["mean"] >= picks["kept_auc"]["mean"]
    assert "chosen on test data" in (out / "tables.md").read_text()
    # another recipe keys other reports: nothing of the earlier runs is reused
    reports = set((out / "cache" / "oc-run").iterdir())
    run = _cli(*base, "--set", "dsvdd_epochs=2", "--overwrite")
    assert run.returncode == 0, run.stderr
    assert len(set((out / "cache" / "oc-run").iterdir()) - reports) == 1     # trained anew


def test_a_probe_watches_every_epoch_and_never_chooses(fitted):
    """Scoring test data every epoch (the research probe of `--probe-test`) leaves the weights
    as they are, and its curve at the epoch that stable-only selection kept is the model's AUC;
    the best epoch on test can only be as good or better."""
    from estimators.oneclass.model import Probe
    from macrostate_mj.app.experiments.oc import selection_on_test

    model, x = fitted
    cfg = replace(TINY, dsvdd_epochs=3, cls_epochs=3)
    xs, xu = _flows(12, 0.0, 5), _flows(12, 3.0, 6)
    plain = fit(x, ("dsvdd", "iogen"), cfg)
    probe = Probe(np.concatenate([xs, xu]))
    watched = fit(x, ("dsvdd", "iogen"), cfg, probe=probe)
    for meth in ("dsvdd", "iogen"):
        assert np.array_equal(plain.score(meth, xu), watched.score(meth, xu))
        assert len(probe.curves[meth]) == 3
    picks = selection_on_test(probe, watched.history, len(xs))
    for meth in ("dsvdd", "iogen"):
        kept = roc_auc(watched.score(meth, xs), watched.score(meth, xu))
        assert picks[meth]["kept_auc"] == pytest.approx(kept)
        assert picks[meth]["best_auc"] >= picks[meth]["kept_auc"]


@pytest.mark.parametrize(("cores", "workers", "threads"),
                         [(2, 1, 2), (2, 2, 1), (3, 2, 1), (16, 4, 2), (1, 8, 1)])
def test_experiment_oc_shares_the_cores_among_its_workers(monkeypatch, cores, workers, threads):
    from macrostate_mj.core import parallel

    monkeypatch.setattr(parallel.os, "cpu_count", lambda: cores)
    assert parallel.torch_threads(workers) == threads


def test_a_worker_that_does_not_see_the_drivers_folders_is_refused_in_one_line(tmp_path):
    """On a Ray node without the shared file system the oc runs need, a run fails in one line
    rather than training on what it finds there and caching stages the driver never sees."""
    from macrostate_mj.app.experiments.oc import DRIVER_MARK, Config, RunTask

    stages = tmp_path / "cache"
    stages.mkdir()
    task = RunTask(Config(data=tmp_path), 2, 1, 0, 2, stages, mark="abc")
    with pytest.raises(UserError, match="a file system every node shares"):
        task.seen()
    (stages / DRIVER_MARK).mkdir()
    (stages / DRIVER_MARK / "another run's").touch()
    with pytest.raises(UserError, match="does not see"):
        task.seen()
    (stages / DRIVER_MARK / "abc").touch()
    task.seen()                                        # the driver's own folder: on it goes
