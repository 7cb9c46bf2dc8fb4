"""K ReTLo networks trained together are their one-at-a-time twins, to float rounding."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from estimators.retlo import CM_PER_M
from estimators.retlo.api import evaluate
from estimators.retlo.chain import predict_chain
from estimators.retlo.ensemble import Job, StackedNet, StackedPredictor, stackable, train_many
from estimators.retlo.models import ModelConfig, RetloNet, TorchPredictor
from estimators.retlo.synthetic import synthetic_chains
from estimators.retlo.train import TrainConfig, mean_spacing, train
from macrostate_mj.core.errors import UserError

SMALL = dict(k=16, m=24, d=24)
MODELS = {"lstm": ModelConfig(**SMALL), "lstm ch3": ModelConfig(**SMALL, bidirectional=False,
                                                                  cos_sin=True),
          "fc": ModelConfig(kind="fc", **SMALL)}


def _jobs(model: ModelConfig, k: int, epochs: int = 3) -> list[Job]:
    val = synthetic_chains(6, 3, 99, n_steps=18)
    return [Job([synthetic_chains(16, 3, 10 + i, n_steps=18)], val,
                TrainConfig(epochs=epochs, seed=i, model=model)) for i in range(k)]


@pytest.mark.parametrize("name", sorted(MODELS))
def test_a_stack_predicts_as_each_of_its_networks(name):
    jobs = _jobs(MODELS[name], 3)
    nets = []
    for job in jobs:
        torch.manual_seed(job.cfg.seed)
        nets.append(RetloNet(job.cfg.model, CM_PER_M * mean_spacing(job.train)))
    test = synthetic_chains(5, 5, 7, n_steps=18)
    together = predict_chain(StackedPredictor(StackedNet(nets)), np.concatenate([test] * 3))
    for i, net in enumerate(nets):
        alone = predict_chain(TorchPredictor(net), test)
        assert np.allclose(together[5 * i:5 * (i + 1)], alone, atol=1e-5, equal_nan=True)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_models_trained_together_match_their_twins_trained_alone(name):
    """Same initial weights, data order, flips, feedback and early stopping: the validation
    curves agree to float32 rounding and the test errors within 1 % (measured: ~1e-6)."""
    jobs = _jobs(MODELS[name], 2)
    test = synthetic_chains(6, 5, 123, n_steps=18)
    together = train_many(jobs)
    for job, (net, info) in zip(jobs, together, strict=True):
        twin, twin_info = train(job.train, job.val, job.cfg, progress=False)
        curve = [c["val_cm"] for c in info["curve"]]
        assert np.allclose(curve, [c["val_cm"] for c in twin_info["curve"]], rtol=1e-4)
        assert info["best_epoch"] == twin_info["best_epoch"]
        err = evaluate(TorchPredictor(net), test)["mean_error_cm"]
        twin_err = evaluate(TorchPredictor(twin), test)["mean_error_cm"]
        assert abs(err - twin_err) <= 0.01 * twin_err


@pytest.mark.parametrize("name", ["lstm ch3", "fc"])
def test_samples_featurised_once_for_all_models_are_each_models_own(name):
    """Every model's teacher-forced samples, from one pass over the K jobs' chains side by
    side: the rows `make_samples` gives each job alone, bit for bit, over two files."""
    from estimators.retlo.ensemble import _bases
    from estimators.retlo.train import make_samples

    model = MODELS[name]
    val = synthetic_chains(4, 3, 99, n_steps=18)
    jobs = [Job([synthetic_chains(5, 3, 10 + i, n_steps=18),
                 synthetic_chains(3, 3, 20 + i, n_steps=14)], val,
                TrainConfig(seed=i, model=model)) for i in range(3)]
    for job, together in zip(jobs, _bases(jobs), strict=True):
        alone = make_samples(job.train, model)
        assert together.keys() == alone.keys()
        for key in alone:
            assert together[key].tobytes() == alone[key].tobytes(), key


def test_only_models_of_one_shape_train_together():
    a, b = _jobs(MODELS["fc"], 2)
    assert stackable([a, b]) is None
    other = Job(a.train, a.val, TrainConfig(epochs=3, seed=5, lr=1e-3, model=a.cfg.model))
    assert "settings" in stackable([a, other])
    shorter = Job([a.train[0][:10]], a.val, b.cfg)
    assert "shape" in stackable([a, shorter])
    with pytest.raises(UserError, match="cannot train these 2 models together"):
        train_many([a, other])


def test_the_ensemble_bench_reports_a_speedup_per_k_in_the_common_schema():
    from macrostate_mj.app.bench import FIELDS
    from macrostate_mj.app.bench.ensemble import bench_ensemble

    figs = bench_ensemble(ks=(1, 2))
    speedups = [f for f in figs if f["name"] == "speedup"]
    assert [(f["config"]["model"], f["config"]["k"]) for f in speedups] == [
        ("lstm", 1), ("lstm", 2), ("fc", 1), ("fc", 2)]
    arithmetic = [f for f in figs if f["name"] == "arithmetic"]
    assert [f["config"]["model"] for f in arithmetic] == ["lstm", "fc"]
    assert len(figs) == len(speedups) + len(arithmetic)
    for f in arithmetic:            # a rate against one thread's matrix product: value / limit
        assert set(FIELDS) <= set(f) and f["value"] > 0 and f["limit"] > 0
        assert f["ratio"] == pytest.approx(f["value"] / f["limit"], abs=1e-3)
    for f in speedups:
        assert set(FIELDS) <= set(f)
        alone, together = f["config"]["alone_s"], f["config"]["together_s"]   # to 1 ms
        assert (alone - 6e-4) / (together + 6e-4) <= f["value"] <= (
            (alone + 6e-4) / (together - 6e-4))


def test_a_training_step_counts_the_lstm_products_torch_does_not_see():
    """FLOPs by hand for batch 64: chapter 3's net has f_obs 4->80, fuse (80 + 160)->160,
    heads 160->2 and 160->6 (cos/sin), forward 2 x 64 x 40,000; backward twice that less the
    input gradient of f_obs (2 x 64 x 4 x 80), which nothing needs; the LSTM (9 inputs, 160
    wide, 10 steps) 3 x its forward 2 x 64 x 10 x 640 x 169. FC: 4->80->160, heads 2 and 3."""
    from macrostate_mj.app.bench.ensemble import step_flops

    linear = 3 * 2 * 64 * 40_000 - 2 * 64 * 4 * 80
    assert step_flops("lstm", 64) == linear + 3 * 2 * 64 * 10 * 640 * 169
    assert step_flops("fc", 64) == 3 * 2 * 64 * 13_920 - 2 * 64 * 4 * 80
