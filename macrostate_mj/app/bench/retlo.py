"""`bench --only retlo`: one LSTM training on the real 3-robot data, against its compute floor.

The limit is the bare forward + backward + optimizer step of the same network on the same batch
shape, times the number of batches the training ran: what the training would cost with no data
preparation, feedback rollouts or validation. Without the reference data (a fresh clone), the
same sizes are drawn from `estimators.retlo.synthetic` and the figure names say so.
"""

from __future__ import annotations

import time

from macrostate_mj.app.bench import SUITES, figure


def _data() -> tuple[str, list, object]:
    from estimators.retlo.files import read_world
    from macrostate_mj.core.paths import real_thymioloc

    root = real_thymioloc("Train.csv").parent
    if (root / "Train.csv").is_file() and (root / "Val.csv").is_file():
        return "real 3-robot Train", [read_world(root / "Train.csv")], read_world(root / "Val.csv")
    from estimators.retlo.synthetic import synthetic_chains

    return "synthetic, real Train's size", [synthetic_chains(280, 3, 0)], synthetic_chains(45, 3, 1)


def _bare_batch_seconds(cfg, n_hist_features: int, repeats: int = 30) -> float:
    """Mean time of one forward + backward + Adam step on a random batch of the training shape."""
    import torch

    from estimators.retlo.models import RetloNet
    from estimators.retlo.train import _loss

    net = RetloNet(cfg.model, 31.0)   # a typical spacing in cm, the networks' unit
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    gen = torch.Generator().manual_seed(0)
    batch = {"obs": torch.randn(cfg.batch, 4, generator=gen),
             "hist": torch.randn(cfg.batch, cfg.model.history, n_hist_features, generator=gen),
             "pos": torch.randn(cfg.batch, 2, generator=gen),
             "ang": torch.randn(cfg.batch, 3, generator=gen)}
    for i in range(repeats + 5):
        if i == 5:
            start = time.perf_counter()
        loss = _loss(net, batch, cfg)
        opt.zero_grad()
        loss.backward()
        opt.step()
    return (time.perf_counter() - start) / repeats


@SUITES.register("retlo", rank=80)
def bench_retlo() -> list[dict]:
    """Figures: LSTM training wall time (limit: bare network steps), per-batch cost, accuracy."""
    import torch

    from estimators.retlo.api import fit
    from estimators.retlo.models import ModelConfig
    from estimators.retlo.train import TrainConfig, make_samples

    label, trains, val = _data()
    cfg = TrainConfig(seed=0, model=ModelConfig(kind="lstm"))
    start = time.perf_counter()
    _, info = fit(trains, val, cfg)
    seconds = time.perf_counter() - start
    n_feat = make_samples([trains[0][:1]], cfg.model)["hist"].shape[-1]
    torch.set_num_threads(cfg.threads)
    per_batch = _bare_batch_seconds(cfg, n_feat)
    floor = per_batch * info["batches"]
    tag = f"{label}; limit: bare fwd+bwd+step x batches run"
    return [
        figure("retlo_lstm_train_s", seconds, "s", floor, config=tag, lower_is_better=True),
        figure("retlo_lstm_epochs_run", info["epochs_run"], "epochs", config=label),
        figure("retlo_lstm_batch_ms", per_batch * 1e3, "ms", config=label),
        figure("retlo_lstm_best_val_head_cm", info["best_val_cm"], "cm", config=label),
    ]
