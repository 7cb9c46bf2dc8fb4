"""Chapter 3's SR phase (§3.3.1): novelty windows, the (φ, ψ, ζ) models, the Tail's candidate
motion, the pick policies, and `collect --policy srs` end to end."""

import json
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
import torch
from clitools import assert_clean_error, cli

from estimators.srs.novelty import (
    NoveltyConfig,
    NoveltyFile,
    NoveltyModel,
    NoveltyNet,
    load_novelty,
    save_novelty,
    train_novelty,
)
from macrostate_mj.chain.motion import drive_tail
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.sim import ChainSim, Every, PoseLog
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.instances import cut_instances, instance_starts
from macrostate_mj.formats.srs_windows import (
    WINDOW,
    features_to_poses,
    module_of,
    step_features,
    training_windows,
    window_features,
)
from macrostate_mj.formats.thymioloc import read_csv
from macrostate_mj.tails.collection import PolicyConfig
from macrostate_mj.tails.srs import PICKS, SRSConfig, pick_index


def _tracks(seed: int, seconds: float = 400.0, sigma: float = 0.75) -> np.ndarray:
    """Rand-Only team tracks of a 3-robot webots team: (instances, 26, 3, 3)."""
    world = build_world(get_scenario("webots"), 3)
    sim = ChainSim(world)
    sim.reset(np.random.default_rng(seed))
    log = PoseLog(world.names)
    policy = PolicyConfig("random", sigma).build(np.random.default_rng([seed, 2]))
    sim.episode(seconds, [Every(0.5, policy), Every(0.5, log.append)])
    _, poses, _ = log.arrays()
    return cut_instances(poses, instance_starts(len(poses), 2.0, first=10))


@pytest.fixture(scope="module")
def trained() -> tuple[NoveltyModel, dict, np.ndarray]:
    tracks = _tracks(1, 800)
    model, info = train_novelty(tracks, NoveltyConfig(epochs=120), "webots")
    return model, info, tracks


def test_window_features_are_in_the_tail_frame_and_invert():
    rng = np.random.default_rng(0)
    team = rng.normal(0, 0.5, (4, WINDOW, 3, 3))
    tail, fol, head = module_of(team)
    feat = window_features(tail, fol, head)
    assert feat.shape == (4, WINDOW, 8)
    assert np.allclose(feat[:, -1, 1], 0)            # F on the frame's x axis at the last step
    dist = np.linalg.norm(fol[:, -1, :2] - tail[:, -1, :2], axis=1) * 100
    assert np.allclose(feat[:, -1, 0], dist)
    assert np.allclose(np.hypot(feat[..., 2], feat[..., 3]), 1)
    origin = tail[:, -1, :2]
    alpha = np.arctan2(*(fol[:, -1, :2] - origin).T[::-1])
    f_back, h_back = features_to_poses(step_features(fol[:, 3], head[:, 3], origin, alpha),
                                       origin, alpha)
    assert np.allclose(f_back[:, :2], fol[:, 3, :2]) and np.allclose(h_back[:, :2], head[:, 3, :2])
    d = np.angle(np.exp(1j * (h_back[:, 2] - head[:, 3, 2])))
    assert np.allclose(d, 0)


def test_tail_drives_toward_its_perturbed_destination():
    """The candidate motion: zero offset keeps the Tail rule; an offset to the left ends left."""
    tail, fol = np.array([0.0, 0.0, 0.0]), np.array([0.5, 0.0])
    offsets = np.array([[0.0, 0.0], [0.0, 0.08], [0.0, -0.08]])
    ends = drive_tail(tail, fol, offsets, 0.3, 3.0, 1.5, 0.2, True, 0.5, 1)
    assert ends[0, 0] > 0.05 and abs(ends[0, 1]) < 1e-9         # straight toward F
    assert ends[1, 1] > 0.005 and ends[2, 1] < -0.005           # left, right
    assert np.allclose(ends[1] * [1, -1, -1], ends[2])              # mirror images


def test_training_learns_and_novelty_flags_unseen_motion(trained):
    model, info, tracks = trained
    curve = info["curve"]
    assert info["best_val_loss"] < 0.25 * curve[0]["val_loss"]
    x, y = training_windows(_tracks(2, 200))                   # an unseen episode, same policy
    e_seen = model.novelty(x)
    # the same windows with F and H swapped: a team order the RO data never showed
    swapped = np.concatenate([x[..., 4:], x[..., :4]], axis=-1)
    assert np.median(model.novelty(swapped)) > 3 * np.median(e_seen)
    nxt = model.predict_next(x)                                 # ζ beats "no motion"
    still = x[:, -1]
    assert np.mean((nxt - y)[:, [0, 1, 4, 5]] ** 2) < np.mean((still - y)[:, [0, 1, 4, 5]] ** 2)


def test_pick_index_takes_the_quantile_order_statistic():
    e = np.random.default_rng(0).permutation(np.arange(30.0))
    assert e[pick_index(e, PICKS["max"])] == 29
    assert e[pick_index(e, PICKS["med"])] == 14          # the lower of the two middle ones
    assert e[pick_index(e, PICKS["q3"])] == 21 and e[pick_index(e, PICKS["q2"])] == 7


@pytest.mark.parametrize("pick", ["max", "med"])
def test_the_srs_tail_drives_to_its_pick_on_a_fixed_model(tmp_path, pick):
    """On a fixed model (seeded weights), every scored step's pick is the candidate of largest
    (median) e, the offset set is that candidate's, and the same seed repeats the choices."""
    torch.manual_seed(0)
    model = NoveltyModel(NoveltyNet(NoveltyConfig()), NoveltyConfig(), 3, "webots")
    path = save_novelty(tmp_path / "m.pt", model, {})

    def run(seed: int):
        world = build_world(get_scenario("webots"), 3)
        sim = ChainSim(world)
        sim.reset(np.random.default_rng(seed))
        policy = SRSConfig(NoveltyFile(str(path)), pick, k=9).build(
            np.random.default_rng([seed, 2]))
        offsets = []
        sim.run(30.0, [Every(0.5, lambda s: (policy(s), offsets.append(s.tail_offset.copy())))])
        return policy.records(), np.array(offsets)

    rec, offsets = run(4)
    assert rec.num_rows >= 10
    picks, es = rec["pick"].to_numpy(), np.array(rec["e"].to_pylist())
    cands = np.array(rec["offsets"].to_pylist()).reshape(rec.num_rows, 9, 2)
    order = np.sort(es, axis=1)
    chosen = es[np.arange(len(es)), picks]
    assert np.array_equal(chosen, order[:, -1] if pick == "max" else order[:, 4])
    times = np.round(rec["t"].to_numpy() / 0.5).astype(int)
    assert np.array_equal(offsets[times], cands[np.arange(len(picks)), picks])
    rec2, _ = run(4)
    assert rec2.equals(rec)


def test_a_tracking_srs_tail_scores_the_tracked_poses(tmp_path):
    """With `track`, the Tail's windows come from the overhead tracker: the first scored step's
    novelty differs from the ground truth's, by as little as the tracker's mm-level error."""
    from collectors.episodes import EpisodeSpec, run_episode

    torch.manual_seed(0)
    model = NoveltyModel(NoveltyNet(NoveltyConfig()), NoveltyConfig(), 3, "webots")
    path = str(save_novelty(tmp_path / "m.pt", model, {}))
    first = []
    for track in (False, True):
        policy = SRSConfig(NoveltyFile(path), "max", k=9, track=track)
        spec = EpisodeSpec(get_scenario("webots"), 3, 12.0, 0.0, 7, 0, policy)
        _, table, stats = run_episode(spec)
        first.append(np.array(stats["decisions"]["e"].to_pylist()[0]))
    assert not np.array_equal(first[0], first[1])
    assert np.allclose(first[0], first[1], rtol=0.05)


def test_novelty_models_refuse_another_team_or_format(tmp_path, trained):
    model, info, _ = trained
    path = save_novelty(tmp_path / "n.pt", model, info)
    assert load_novelty(path, 3, "webots").robots == 3
    with pytest.raises(UserError, match="3-robot team"):
        load_novelty(path, 5)
    with pytest.raises(UserError, match="scenario 'webots'"):
        load_novelty(path, 3, "lab")
    torch.save({"format": "macrostate-mj/srs-novelty", "version": 99}, tmp_path / "v.pt")
    with pytest.raises(UserError, match="version 99"):
        load_novelty(tmp_path / "v.pt")
    with pytest.raises(UserError, match="at least 2 candidates"):
        SRSConfig(NoveltyFile("x"), "max", k=1)


SRS = ["collect", "--scenario", "webots", "--robots", "3", "--policy", "srs", "--srs", "med",
       "--ro-instances", "4", "--instances", "8", "--k", "5", "--episode-minutes", "1",
       "--seed", "3"]


def test_collect_srs_end_to_end_and_resumes(tmp_path):
    out = tmp_path / "srs"
    res = cli(*SRS, "--split", "50/25/25", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert read_csv(out / "instances.csv").n_instances == 8
    assert read_csv(out / "Train.csv").n_instances == 4
    assert load_novelty(out / "novelty.pt", 3, "webots").robots == 3
    dec = pq.read_table(out / "decisions.parquet")
    es = np.array(dec["e"].to_pylist())
    assert dec.num_rows > 20 and es.shape[1] == 5
    assert np.array_equal(es[np.arange(len(es)), dec["pick"].to_numpy()], np.sort(es)[:, 2])
    first = {p.name: p.read_bytes() for p in out.glob("*.csv")}
    model = (out / "novelty.pt").stat().st_mtime_ns
    assert len(list((out / "cache" / "srs-novelty").iterdir())) == 1   # the models' task
    # killed during the SR phase: the run's manifest says so, the final files, the SR phase's
    # and one SR episode are gone; a rerun (no --overwrite) resumes
    manifest = json.loads((out / "manifest.json").read_text())
    (out / "manifest.json").write_text(json.dumps({**manifest, "status": "interrupted"}))
    for path in [*out.glob("*.csv"), *out.glob("*.parquet"), *(out / "sr").glob("*.*")]:
        path.unlink()
    shutil.rmtree(sorted((out / "sr" / "cache" / "collect-episode").iterdir())[-1])
    res = cli(*SRS, "--split", "50/25/25", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert first == {p.name: p.read_bytes() for p in out.glob("*.csv")}
    assert (out / "novelty.pt").stat().st_mtime_ns == model          # not trained again
    assert json.loads((out / "manifest.json").read_text())["status"] == "finished"
    res = cli(*SRS, "--split", "50/25/25", "--out", str(out))       # finished: not unasked
    assert_clean_error(res, "--overwrite")
    res = cli(*SRS, "--split", "50/25/25", "--out", str(out), "--overwrite")
    assert res.returncode == 0, res.stderr
    assert first == {p.name: p.read_bytes() for p in out.glob("*.csv")}


@pytest.mark.parametrize(("args", "names"), [
    (["--ro-instances", "8", "--instances", "8"], "--ro-instances"),
    (["--k", "1"], "--k"),
    (["--srs", "q4"], "--srs"),
    (["--sigma", "-1"], "--sigma"),
])
def test_collect_srs_bad_input(tmp_path, args, names):
    base = [a for a in SRS]
    for flag, value in zip(args[::2], args[1::2], strict=True):
        i = base.index(flag) if flag in base else None
        if i is None:
            base += [flag, value]
        else:
            base[i + 1] = value
    res = cli(*base, "--out", str(tmp_path / "bad"))
    assert_clean_error(res, names)
    assert not (tmp_path / "bad").exists()


def test_collect_srs_does_not_replace_a_novelty_model_unasked(tmp_path, trained):
    """A folder holding novelty models (an earlier run's, with its manifest gone) is refused
    before any work, as any output of the run would be."""
    model, info, _ = trained
    out = tmp_path / "other"
    out.mkdir()
    save_novelty(out / "novelty.pt", model, info)
    res = cli(*SRS, "--out", str(out))
    assert_clean_error(res, "novelty.pt", "--overwrite")
    assert not (out / "ro").exists()


def test_experiment_srs_quick_runs_resumes_and_keeps_its_invariants(tmp_path):
    """The chapter's task graph on the quick profile: every figure, and what must hold on any
    machine: Rand-Only with σ = 0 is Passive, and an SRS dataset begins with its RO phase, the
    same instances as the Rand-Only dataset of the same seed. Models are keyed by their data, so
    those identical training sets train once; a rerun takes every model from the cache, and a
    run killed while training trains only the models it had not finished."""
    out = tmp_path / "chapter3"
    res = cli("experiment", "srs", "--quick", "--out", str(out))
    assert res.returncode == 0, res.stderr
    for name in ("fig3_4.png", "fig3_5a.png", "fig3_5b.png", "fig3_6.png", "fig3_7.png"):
        assert (out / name).stat().st_size > 1000
    results = json.loads((out / "results.json").read_text())
    cfg = results["configs"]
    for metric in ("all_predictions_cm", "head_cm"):      # the text's metric, and the Head's
        assert cfg["ro_0"]["1.0000"][metric] == cfg["passive"]["1.0000"][metric]
    assert results["baseline"] == "ro_0.75"
    ro = read_csv(out / "data" / "ro_0.75_d0" / "instances.csv").poses
    srs = read_csv(out / "data" / "srs_max_d0" / "instances.csv").poses
    m = results["profile"]["ro_instances"]
    assert np.array_equal(ro[:m], srs[:m]) and not np.array_equal(ro[m:2 * m], srs[m:2 * m])
    assert set(results["distances"]) == {"srs_max", "ro_0.75"}
    # 9 models; ro_0 at 100 % is passive's, SRS-Max and -Med at 50 % (6 = m instances) are
    # ro_0.75's: 6 trained
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["models"], manifest["models_distinct"], manifest["models_trained"]) == (
        9, 6, 6)
    assert len(list((out / "cache" / "srs-model").iterdir())) == 6
    assert cfg["srs_max"]["0.5000"] == cfg["ro_0.75"]["0.5000"]
    # models/: one report a model, named to pair across configurations, as its task wrote it
    reports = sorted((out / "models").iterdir())
    assert len(reports) == 9 and "passive_b100_d0_m0.json" in {r.name for r in reports}
    assert {r.read_bytes() for r in reports} == {
        p.read_bytes() for p in (out / "cache" / "srs-model").glob("*/report.json")}
    before = (out / "results.json").read_bytes()
    res = cli("experiment", "srs", "--profile", "quick", "--out", str(out), "--overwrite")
    assert res.returncode == 0, res.stderr
    assert (out / "results.json").read_bytes() == before      # every task from its cache
    assert json.loads((out / "manifest.json").read_text())["models_trained"] == 0
    # killed while training: the manifest says so and one model's task is missing; the same
    # command resumes (no --overwrite) and trains that model alone
    manifest = json.loads((out / "manifest.json").read_text())
    (out / "manifest.json").write_text(json.dumps({**manifest, "status": "interrupted"}))
    shutil.rmtree(sorted((out / "cache" / "srs-model").iterdir())[0])
    res = cli("experiment", "srs", "--profile", "quick", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert (out / "results.json").read_bytes() == before
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["models_trained"] == 1 and manifest["status"] == "finished"


def test_srs_models_trained_as_a_group_report_as_when_trained_alone(tmp_path):
    """`--group K`: the chapter's models of one shape train together (estimators.retlo.ensemble),
    each report within float rounding of its model trained alone."""
    from estimators.retlo.files import world_to_pixels
    from estimators.retlo.synthetic import synthetic_chains
    from macrostate_mj.app.experiments.srs import ModelTask
    from macrostate_mj.formats.thymioloc import write_csv

    val = write_csv(tmp_path / "val.csv", world_to_pixels(synthetic_chains(6, 3, 9), 3.0))
    test = write_csv(tmp_path / "test.csv", world_to_pixels(synthetic_chains(4, 5, 8), 3.0))
    tasks = [ModelTask(synthetic_chains(10, 3, j), val, test, epochs=2, seed=s)
             for j in (0, 1) for s in (0, 1)]
    assert len({t.group() for t in tasks}) == 1
    together = ModelTask.compute_group(tasks)
    for task, files in zip(tasks, together, strict=True):
        grouped = json.loads(files["report.json"])
        alone = json.loads(task.compute()["report.json"])
        assert grouped["mean_error_cm"] == pytest.approx(alone["mean_error_cm"], rel=1e-3)
