"""ReTLo with uncertainty: a Gaussian head calibrated on a case of known noise, point models
unchanged, checkpoints that say what they are, ensembles, Monte Carlo along the chain with a
known answer, ellipses, and bad input at the command line."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import torch
from clitools import cli_inprocess as _cli

from estimators.retlo.api import evaluate, predict
from estimators.retlo.chain import predict_chain
from estimators.retlo.files import world_to_pixels
from estimators.retlo.frames import FrameEstimate, decode
from estimators.retlo.gaussian import (
    GAUSSIAN_REGIONS,
    Regions,
    calibration,
    chi2_2dof,
    ellipse,
    mahalanobis2,
    moment_match,
)
from estimators.retlo.heads import GAUSSIAN, POINT
from estimators.retlo.heuristic import Heuristic2X
from estimators.retlo.mixture import GaussianEnsemble
from estimators.retlo.models import ModelConfig, TorchPredictor
from estimators.retlo.online import OnlineChain
from estimators.retlo.propagate import NoUncertaintyError, predict_chain_gaussian
from estimators.retlo.report import evaluate_chain
from estimators.retlo.synthetic import synthetic_chains
from estimators.retlo.train import (
    TrainConfig,
    load_checkpoint,
    recalibrate,
    save_checkpoint,
    train,
)
from macrostate_mj.core.errors import UserError
from macrostate_mj.formats.thymioloc import write_csv

TINY = dict(k=16, m=16, d=16)
SIGMA = 0.03      # m: the known noise of the Head around the 2X extrapolation


def _noisy(n_inst: int, seed: int, sigma: float = SIGMA) -> np.ndarray:
    """3-robot chains whose Head sits at 2F - T plus isotropic Gaussian noise of `sigma`: the
    best estimate is N(2F - T, sigma² I) exactly."""
    world = synthetic_chains(n_inst, 3, seed=seed)
    rng = np.random.default_rng(seed + 100)
    world[:, :, 0, :2] = (2 * world[:, :, 1, :2] - world[:, :, 2, :2]
                          + rng.normal(0.0, sigma, world[:, :, 0, :2].shape))
    return world


def _fit(head=GAUSSIAN, kind: str = "fc", epochs: int = 25, seed: int = 0, n: int = 40):
    cfg = TrainConfig(epochs=epochs, patience=epochs, seed=seed, lr=1e-2,
                      model=ModelConfig(kind=kind, **TINY))
    net, info = train([_noisy(n, 1)], _noisy(15, 2), cfg, progress=False, head=head)
    return net, info, cfg


@pytest.fixture(scope="module")
def calibrated():
    return _fit()


def test_gaussian_head_is_calibrated_on_known_noise(calibrated):
    net, _, _ = calibrated
    test = _noisy(40, 3)
    module = TorchPredictor(net)
    report = evaluate(module, test, calibrate=True)
    pooled = report["calibration"]["pooled"]
    assert pooled["n"] == 40 * 15
    assert abs(pooled["coverage_50"] - 0.5) < 0.08, pooled
    assert abs(pooled["coverage_90"] - 0.9) < 0.05, pooled
    assert report["calibration"]["H"] == {k: pooled[k] for k in report["calibration"]["H"]}
    _, cov = predict(module, test, gaussian=True)
    cov = cov[np.isfinite(cov).all((-1, -2))]
    sigma = np.sqrt(np.trace(cov, axis1=-2, axis2=-1).mean() / 2)
    assert sigma == pytest.approx(SIGMA, rel=0.2)
    # the mean is as good as the law allows: E|e| = σ √(π/2) for 2-D isotropic noise
    assert report["mean_error_cm"] < 1.15 * 100 * SIGMA * np.sqrt(np.pi / 2)


def test_the_faithful_head_trains_its_mean_as_a_point_model_does():
    """Its mean gets exactly the point model's gradient; its covariance the NLL's."""
    from estimators.retlo.heads import FAITHFUL

    raw = torch.tensor([[0.3, -0.2, 0.1, 0.4, -0.3]], requires_grad=True)
    target = torch.tensor([[1.0, 0.5]])
    FAITHFUL.position_loss(raw, target).sum().backward()
    point = raw[:, :2].detach().requires_grad_(True)
    POINT.position_loss(point, target).sum().backward()
    assert torch.allclose(raw.grad[:, :2], point.grad)
    assert raw.grad[:, 2:].abs().sum() > 0
    net, _, _ = _fit(FAITHFUL)
    pooled = evaluate(TorchPredictor(net), _noisy(40, 3), calibrate=True)["calibration"]["pooled"]
    assert abs(pooled["coverage_90"] - 0.9) < 0.06, pooled


def test_point_models_are_unchanged(tmp_path, calibrated):
    net, info, cfg = _fit(POINT, epochs=1)
    assert net.head is POINT and net.g_p.out_features == 2
    path = save_checkpoint(tmp_path / "p.pt", net, 3.0, cfg, info)
    raw = torch.load(path, weights_only=True)
    assert "uncertainty" not in raw      # the bytes of a point checkpoint as before heads
    loaded, _ = load_checkpoint(path)
    module = TorchPredictor(loaded)
    assert not module.uncertain
    world = synthetic_chains(4, 5, seed=3)
    assert evaluate(module, world) == evaluate_chain(module, world)
    est = module.estimate(module.features(_a_window(module, world)))
    assert est.head_cov is None
    with pytest.raises(NoUncertaintyError, match="--uncertainty gaussian"):
        evaluate(module, world, calibrate=True)
    assert issubclass(NoUncertaintyError, ValueError)


def _a_window(module, world):
    from estimators.retlo.chain import tracks_from_world, window

    return window(tracks_from_world(world[:, :, ::-1], 10), 0, 10, module.history, True)


def test_gaussian_checkpoint_records_and_checks_its_head(tmp_path, calibrated):
    net, info, cfg = calibrated
    path = save_checkpoint(tmp_path / "g.pt", net, 3.0, cfg, info)
    loaded, ckpt = load_checkpoint(path)
    assert ckpt["uncertainty"] == "gaussian" and loaded.head == GAUSSIAN
    assert loaded.cov_scale == net.cov_scale == ckpt["cov_scale"] == info["cov_scale"]
    assert loaded.regions == net.regions and net.regions.calibrated
    world = synthetic_chains(3, 3, seed=4)
    a = predict_chain_gaussian(TorchPredictor(net), world, 8, np.random.default_rng(0))
    b = predict_chain_gaussian(TorchPredictor(loaded), world, 8, np.random.default_rng(0))
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))
    for key, value, message in (("uncertainty", "laplace", "unknown uncertainty 'laplace'"),
                                ("uncertainty", None, "does not match"),
                                ("cov_scale", -1.0, "not a positive number"),
                                ("region_d2", [[1.0, 0.5] * 49 + [2.0]], "region radii")):
        bad = dict(ckpt)
        if value is None:
            del bad[key]          # Gaussian weights read as a point model
        else:
            bad[key] = value
        torch.save(bad, tmp_path / "bad.pt")
        with pytest.raises(UserError, match=message):
            load_checkpoint(tmp_path / "bad.pt")


def test_recalibration_fits_the_covariance_to_validation_errors(calibrated):
    net = copy.deepcopy(calibrated[0])
    (same, regions), (wider, _) = (recalibrate(net, _noisy(30, 9, sigma=s), 0)
                                   for s in (SIGMA, 2 * SIGMA))
    assert same == pytest.approx(1.0, abs=0.3)     # trained on this noise: little to fix
    assert wider / same == pytest.approx(4.0, rel=0.25)
    for p in (0.5, 0.9):                           # Gaussian errors: the χ² radii, nearly
        assert regions.radius2(p) == pytest.approx(chi2_2dof(p), rel=0.3)
    assert len(regions.tables) == 1            # 3-robot chains: the Head's position only


def test_fitted_regions_cover_heavy_tailed_errors():
    """Most errors small, a fifth large (a chain astray): the likelihood's scale puts far more
    than half inside the Gaussian's 50 % region; the radii fitted on one sample place both
    regions on another."""
    rng = np.random.default_rng(0)
    shape = np.array([[2.0, 0.8], [0.8, 1.0]])

    def draw(n):
        w = np.where(rng.random(n) < 0.8, 0.4, 5.0)
        x = np.sqrt(w)[:, None] * rng.multivariate_normal([0.0, 0.0], shape, size=n)
        return x, np.zeros_like(x), np.broadcast_to(shape * w.mean(), (n, 2, 2))

    fit_x, fit_mean, fit_cov = draw(5000)
    regions = Regions.fitted(mahalanobis2(fit_x, fit_mean, fit_cov))
    assert Regions.from_record([list(t) for t in regions.tables]) == regions
    cal = calibration(*draw(20000), regions)
    assert cal["gaussian_coverage_50"] > 0.6
    assert cal["coverage_50"] == pytest.approx(0.5, abs=0.02)
    assert cal["coverage_90"] == pytest.approx(0.9, abs=0.02)
    outline = ellipse(np.zeros(2), regions.outline_cov(shape), 0.9)
    assert np.allclose(mahalanobis2(outline, np.zeros(2), shape), regions.radius2(0.9))
    assert "gaussian_coverage_50" not in calibration(fit_x, fit_mean, fit_cov)
    assert GAUSSIAN_REGIONS.radius2(0.9) == chi2_2dof(0.9)
    with pytest.raises(ValueError, match="finite Mahalanobis"):
        Regions.fitted(np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="in \\(0, 1\\)"):
        regions.radius2(1.0)
    with pytest.raises(ValueError, match="tables of 99"):
        Regions.from_record([1.0, 2.0])


def test_regions_per_chain_position():
    """Two positions whose errors differ fourfold in scale: one pooled table misses both,
    a table per position holds each; positions past the last table use the last."""
    rng = np.random.default_rng(1)
    near, far = rng.chisquare(2, 4000), 4 * rng.chisquare(2, 4000)
    regions = Regions.fitted(near, far)
    assert regions.radius2(0.5, 1) == pytest.approx(4 * regions.radius2(0.5, 0), rel=0.1)
    assert regions.radius2(0.5, 7) == regions.radius2(0.5, 1)
    assert np.array_equal(regions.radius2(0.9, np.array([0, 1, 5])),
                          [regions.radius2(0.9, j) for j in (0, 1, 1)])
    # d2 = |x|² for unit covariances: test points drawn like the fitted ones
    x = np.stack([np.sqrt(np.stack([near, far], -1)), np.zeros((4000, 2))], -1)
    cov = np.broadcast_to(np.eye(2), (4000, 2, 2, 2))
    pooled = calibration(x, np.zeros_like(x), cov, regions, np.arange(2))
    assert pooled["coverage_50"] == pytest.approx(0.5, abs=0.01)
    one = calibration(x, np.zeros_like(x), cov, Regions.fitted(np.concatenate([near, far])))
    per = [calibration(x[:, j], np.zeros((4000, 2)), cov[:, j], regions, j)["coverage_50"]
           for j in (0, 1)]
    assert per == pytest.approx([0.5, 0.5], abs=0.01)
    assert one["coverage_50"] == pytest.approx(0.5, abs=0.01)     # pooled right, each wrong:
    assert calibration(x[:, 0], np.zeros((4000, 2)), cov[:, 0],
                       Regions.fitted(np.concatenate([near, far])))["coverage_50"] > 0.7


def test_covariances_turn_with_the_frame():
    est = FrameEstimate(np.zeros((1, 2)), head_cov=np.array([[[4.0, 0.0], [0.0, 1.0]]]))
    world = decode(est, np.zeros((1, 2)), np.array([np.pi / 2]))
    assert np.allclose(world.head_cov, [[[1.0, 0.0], [0.0, 4.0]]])


def test_mixture_moments_and_coverage_of_exact_gaussians():
    means = np.array([[0.0, 0.0], [2.0, 0.0]])
    covs = np.stack([np.eye(2), 3 * np.eye(2)])
    mu, cov = moment_match(means, covs)
    assert np.allclose(mu, [1.0, 0.0])
    assert np.allclose(cov, [[2.0 + 1.0, 0.0], [0.0, 2.0]])    # E Σ + spread of the means
    rng = np.random.default_rng(0)
    true_cov = np.array([[2.0, 0.8], [0.8, 1.0]])
    x = rng.multivariate_normal([1.0, -1.0], true_cov, size=20000)
    cal = calibration(x, np.broadcast_to([1.0, -1.0], x.shape),
                      np.broadcast_to(true_cov, (len(x), 2, 2)))
    assert cal["coverage_50"] == pytest.approx(0.5, abs=0.01)
    assert cal["coverage_90"] == pytest.approx(0.9, abs=0.01)
    outline = ellipse(np.zeros(2), true_cov, 0.9)
    d2 = mahalanobis2(outline, np.zeros(2), true_cov)
    assert np.allclose(d2, chi2_2dof(0.9))


class NoisyHeuristic(Heuristic2X):
    """The 2X heuristic saying its Head is N(2F - T, s² I): along a chain the Monte Carlo must
    give the variance that law implies."""

    uncertain = True

    def __init__(self, s: float) -> None:
        self.s = s

    def estimate(self, x):
        est = super().estimate(x)
        cov = np.broadcast_to(self.s ** 2 * np.eye(2), (len(est.head_xy), 2, 2)).copy()
        return FrameEstimate(est.head_xy, est.head_theta, est.fol_theta, head_cov=cov)


def test_monte_carlo_carries_uncertainty_along_the_chain():
    """x2 = 2x1 - x0 + e2, x3 = 2x̃2 - x1 + e3, x4 = 2x̃3 - x̃2 + e4 with x̃ the sampled
    inputs: variances s², 5 s², 14 s² for F2, F3, H of a 5-robot chain."""
    s, world = 0.01, synthetic_chains(2, 5, seed=5)
    module = NoisyHeuristic(s)
    est, cov = predict_chain_gaussian(module, world, 1500, np.random.default_rng(0))
    assert np.isnan(cov[:, :, 3:]).all()        # the neighbour and the Tail: not estimated
    var = np.nanmean(np.trace(cov[:, :, :3], axis1=-2, axis2=-1), axis=(0, 1)) / 2 / s ** 2
    assert var == pytest.approx([14.0, 5.0, 1.0], rel=0.12)     # H, F3, F2 in file order
    mean_chain = predict_chain(module, world)
    assert np.allclose(est[..., :2], mean_chain[..., :2], atol=0.3 * s, equal_nan=True)
    few = predict_chain_gaussian(module, world, 20, np.random.default_rng(0))[1]
    again = predict_chain_gaussian(module, world, 20, np.random.default_rng(0))[1]
    other = predict_chain_gaussian(module, world, 20, np.random.default_rng(1))[1]
    assert np.array_equal(again, few, equal_nan=True)     # the seed decides every draw
    assert not np.array_equal(other, few, equal_nan=True)


def test_ensemble_mixes_members_and_refuses_point_ones(calibrated):
    member = TorchPredictor(calibrated[0])
    world = _noisy(6, 7)
    alone = predict_chain_gaussian(member, world, 1, np.random.default_rng(0))
    twice = predict_chain_gaussian(GaussianEnsemble([member, member]), world, 1,
                                   np.random.default_rng(0))
    assert np.allclose(alone[1], twice[1], equal_nan=True)    # identical members: no spread
    other = TorchPredictor(_fit(epochs=3, seed=1)[0])
    pair = predict_chain_gaussian(GaussianEnsemble([member, other]), world, 1,
                                  np.random.default_rng(0))
    single = [predict_chain_gaussian(m, world, 1, np.random.default_rng(0))
              for m in (member, other)]
    mu, cov = moment_match(np.stack([e[..., :2] for e, _ in single]),
                           np.stack([c for _, c in single]))
    assert np.allclose(pair[0][..., :2], mu, equal_nan=True)
    assert np.allclose(pair[1], cov, atol=1e-9, equal_nan=True)
    with pytest.raises(UserError, match="uncertainty"):
        GaussianEnsemble([member, Heuristic2X()])
    with pytest.raises(UserError, match="at least two"):
        GaussianEnsemble([member])


def test_online_chain_keeps_the_covariance(calibrated):
    module = TorchPredictor(calibrated[0])
    world = _noisy(1, 8)[0, :, ::-1]           # Tail first
    live = OnlineChain(module, 3, len(world))
    live.start(world[0])
    for s in range(1, len(world)):
        live.observe(world[s, :2, :2])
    step, _ = live.head
    assert np.isfinite(live.head_cov).all() and live.head_cov.shape == (2, 2) and step > 10
    assert OnlineChain(Heuristic2X(), 3, 5).head_cov is None


def _files(tmp_path):
    def csv(name, world):
        return str(write_csv(tmp_path / name, world_to_pixels(world, 3.0)))

    return csv("train.csv", _noisy(30, 1)), csv("val.csv", _noisy(8, 2)), \
        csv("five.csv", synthetic_chains(4, 5, seed=3))


def test_train_and_evaluate_with_uncertainty_from_the_command_line(tmp_path, capsys):
    import cv2

    train_csv, val_csv, five = _files(tmp_path)
    models = []
    for seed in (0, 1):
        models.append(str(tmp_path / f"g{seed}.pt"))
        code, _, err = _cli(capsys, "train", "retlo", "--model", "fc", "--train", train_csv,
                            "--val", val_csv, "--out", models[-1], "--seed", str(seed),
                            "--epochs", "2", "--uncertainty", "gaussian", "--px-per-cm", "3")
        assert code == 0, err
    manifest = json.loads((tmp_path / "g0.pt.manifest.json").read_text())
    assert "gaussian" in json.dumps(manifest)
    report_path, video = tmp_path / "r.json", tmp_path / "r.mp4"
    code, out, err = _cli(capsys, "evaluate", "retlo", "--model", models[0], "--data", five,
                          "--out", str(report_path), "--px-per-cm", "3", "--particles", "8",
                          "--video", str(video), "--rerun", str(tmp_path / "r.rrd"))
    assert code == 0, err
    assert "calibration:" in out
    report = json.loads(report_path.read_text())
    assert set(report["calibration"]) == {"F2", "F3", "H", "pooled", "nll_unit"}
    assert {"coverage_50", "coverage_90", "nll"} <= set(report["calibration"]["pooled"])
    assert report["particles"] == 8
    manifest = json.loads((tmp_path / "r.json.manifest.json").read_text())
    assert manifest["status"] == "finished" and manifest["command"] == "evaluate retlo"
    assert manifest["config"]["particles"] == 8 and manifest["seed"] == 0
    assert manifest["mean_error_cm"] == report["mean_error_cm"]
    capture = cv2.VideoCapture(str(video))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == 3 * 26
    capture.release()
    assert (tmp_path / "r.rrd").stat().st_size > 0
    code, out, err = _cli(capsys, "evaluate", "retlo", "--model", models[0], "--model",
                          models[1], "--data", five, "--out", str(tmp_path / "e.json"),
                          "--px-per-cm", "3", "--particles", "8")
    assert code == 0, err
    ensemble = json.loads((tmp_path / "e.json").read_text())
    assert ensemble["model"] == "ensemble of 2 fc" and "calibration" in ensemble
    code, _, err = _cli(capsys, "evaluate", "retlo", "--model", models[0], "--data", five,
                        "--out", str(tmp_path / "n.json"), "--no-calibration")
    assert code == 0 and "calibration" not in json.loads((tmp_path / "n.json").read_text())
    # refitted on the 5-robot chains themselves, its regions hold their nominal shares there
    code, out, err = _cli(capsys, "calibrate", "retlo", "--model", models[0], "--val", five,
                          "--out", str(tmp_path / "c.pt"))
    assert code == 0 and "region radii" in out, err
    code, _, err = _cli(capsys, "evaluate", "retlo", "--model", str(tmp_path / "c.pt"),
                        "--data", five, "--out", str(tmp_path / "c.json"))
    assert code == 0, err
    pooled = json.loads((tmp_path / "c.json").read_text())["calibration"]["pooled"]
    assert pooled["coverage_50"] == pytest.approx(0.5, abs=0.06)     # ~170 estimates
    assert pooled["coverage_90"] == pytest.approx(0.9, abs=0.06)
    before = report["calibration"]["pooled"]
    assert (abs(pooled["coverage_50"] - 0.5) + abs(pooled["coverage_90"] - 0.9)
            < abs(before["coverage_50"] - 0.5) + abs(before["coverage_90"] - 0.9))
    calibrated, ckpt = load_checkpoint(tmp_path / "c.pt")
    original, _ = load_checkpoint(models[0])
    assert ckpt["train_info"]["calibrated_on"]["file"] == five
    assert all(torch.equal(a, b) for a, b in zip(calibrated.state_dict().values(),
                                                 original.state_dict().values(), strict=True))
    assert calibrated.regions != original.regions


def _point(tmp_path, capsys) -> str:
    train_csv, val_csv, _ = _files(tmp_path)
    path = str(tmp_path / "p.pt")
    code, _, err = _cli(capsys, "train", "retlo", "--model", "fc", "--train", train_csv,
                        "--val", val_csv, "--out", path, "--epochs", "1")
    assert code == 0, err
    return path


BAD = {
    "calibrate a point model": (lambda p, pt: ["calibrate", "retlo", "--model", pt, "--val",
                                               str(p / "five.csv"), "--out", str(p / "c.pt")],
                                "calibrate needs a model with uncertainty"),
    "calibration of a point model": (lambda p, pt: ["evaluate", "retlo", "--model", pt,
                                                    "--data", str(p / "five.csv"), "--out",
                                                    str(p / "r.json"), "--calibration",
                                                    "--video", str(p / "r.mp4")],
                                     "calibration needs a model with uncertainty"),
    "calibration of the heuristic": (lambda p, pt: ["evaluate", "retlo", "--model",
                                                    "heuristic2x", "--data",
                                                    str(p / "five.csv"), "--out",
                                                    str(p / "r.json"), "--calibration"],
                                     "--uncertainty gaussian"),
    "ensemble with a point member": (lambda p, pt: ["evaluate", "retlo", "--model", pt,
                                                    "--model", pt, "--data",
                                                    str(p / "five.csv"), "--out",
                                                    str(p / "r.json")],
                                     "every ensemble member must have uncertainty"),
    "unknown uncertainty": (lambda p, pt: ["train", "retlo", "--model", "fc", "--train",
                                           str(p / "train.csv"), "--val", str(p / "val.csv"),
                                           "--out", str(p / "m.pt"), "--uncertainty",
                                           "laplace"], "'laplace' is not one of none, gaussian"),
    "init of another head": (lambda p, pt: ["train", "retlo", "--model", "fc", "--train",
                                            str(p / "train.csv"), "--val", str(p / "val.csv"),
                                            "--out", str(p / "m.pt"), "--init", pt,
                                            "--uncertainty", "gaussian"],
                             "pass --uncertainty none"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_uncertainty_requests_exit_2_with_one_line(tmp_path, capsys, case):
    point = _point(tmp_path, capsys)
    before = sorted(p.name for p in tmp_path.iterdir())
    make_args, expected = BAD[case]
    code, _, err = _cli(capsys, *make_args(tmp_path, point))
    assert code == 2 and err.count("\n") == 1 and expected in err, err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before      # nothing written


def test_the_localize_env_loads_a_gaussian_checkpoint(tmp_path, calibrated):
    import gymnasium

    import macrostate_mj  # noqa: F401  (registers the ids)

    net, info, cfg = calibrated
    path = save_checkpoint(tmp_path / "g.pt", net, 3.0, cfg, info)
    env = gymnasium.make("macrostate_mj/LocalizeTail-v0", checkpoint=str(path), time_limit=10.0)
    env.reset(seed=0)
    rng, space = np.random.default_rng(0), env.action_space
    rewards = [env.step(rng.uniform(space.low, space.high).astype(np.float32))[1]
               for _ in range(20)]
    assert all(np.isfinite(rewards))
