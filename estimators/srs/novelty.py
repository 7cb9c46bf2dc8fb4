"""SRS novelty models (seed §3.3.1, Fig 3.2): an LSTM autoencoder (φ, ψ) on h′_t and a next-step
predictor ζ on φ(h′_t), trained jointly and self-supervised on the Rand-Only phase's data.

The text gives no sizes, epochs or rates; ours (`NoveltyConfig`) are small, because the RO phase
gives only m instances (100 by default: 1,700 windows), and chosen as documented in the docs.
Selection: early stopping on the reconstruction-plus-prediction loss of a held-out tenth of the
RO instances; nothing of the SR phase or of any test set is seen.
"""

from __future__ import annotations

import copy
import io
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import atomic_path
from macrostate_mj.formats.srs_windows import FEATURES, WINDOW, training_windows

FORMAT = "macrostate-mj/srs-novelty"
VERSION = 1
# Features are scaled before the nets see them: positions by a nominal spacing, angles as is.
POSITION_SCALE_CM = 30.0
SCALE = np.array([POSITION_SCALE_CM, POSITION_SCALE_CM, 1, 1] * 2, np.float32)


@dataclass(frozen=True)
class NoveltyConfig:
    hidden: int = 64         # LSTM width of φ and ψ, and ζ's hidden layer
    code: int = 16           # φ's code
    epochs: int = 300
    patience: int = 30       # epochs without a better held-out loss before stopping
    batch: int = 128
    lr: float = 2e-3
    zeta_weight: float = 1.0  # weight of ζ's next-step loss beside the reconstruction
    val_fraction: float = 0.1  # of the RO instances, held out for early stopping
    seed: int = 0
    threads: int = 1


class NoveltyNet(nn.Module):
    """φ: LSTM over the window -> code; ψ: the code repeated over the window -> LSTM -> the
    window; ζ: code -> the next step's change from the window's last step.

    Why ζ predicts a change: the step after is the last one moved a few cm, and from the code
    alone ζ learnt it worse than "nothing moves" (28.8 against 9.0 cm² on unseen webots windows);
    adding the last step back is a departure from Fig 3.2 (docs: explanation/srs)."""

    def __init__(self, cfg: NoveltyConfig):
        super().__init__()
        self.encoder = nn.LSTM(FEATURES, cfg.hidden, batch_first=True)
        self.to_code = nn.Linear(cfg.hidden, cfg.code)
        self.decoder = nn.LSTM(cfg.code, cfg.hidden, batch_first=True)
        self.to_step = nn.Linear(cfg.hidden, FEATURES)
        self.zeta = nn.Sequential(nn.Linear(cfg.code, cfg.hidden), nn.ReLU(),
                                  nn.Linear(cfg.hidden, FEATURES))

    def encode(self, x: torch.Tensor) -> torch.Tensor:
        _, (h, _) = self.encoder(x)
        return torch.tanh(self.to_code(h[-1]))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        code = self.encode(x)
        rec, _ = self.decoder(code[:, None, :].expand(-1, x.shape[1], -1))
        return self.to_step(rec), x[:, -1] + self.zeta(code)


class NoveltyModel:
    """A trained (φ, ψ, ζ) with numpy in and out, in the features of `srs_windows` (the SR
    phase's Tail sees it as a `NoveltyScorer`)."""

    def __init__(self, net: NoveltyNet, cfg: NoveltyConfig, robots: int, scenario: str,
                 info: dict | None = None):
        self.net, self.cfg = net.eval(), cfg
        self.robots, self.scenario = robots, scenario
        self.info = info or {}        # how it was trained (best epoch, losses, data key)
        # one thread: a forward pass of a 30 x 9 batch costs ~0.1 ms, and torch's thread pool
        # beside busy cores made it 15 ms (measured with another process on the second core)
        torch.set_num_threads(cfg.threads)
        self._scale = torch.from_numpy(SCALE)

    def _run(self, windows: np.ndarray) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        x = torch.from_numpy(np.asarray(windows, np.float32)) / self._scale
        with torch.no_grad():
            rec, nxt = self.net(x)
        return x, rec, nxt

    def novelty(self, windows: np.ndarray) -> np.ndarray:
        """e = ‖h′ − ψ(φ(h′))‖² per window (B, WINDOW, 8) -> (B,), in scaled features."""
        x, rec, _ = self._run(windows)
        return ((rec - x) ** 2).sum(dim=(1, 2)).double().numpy()

    def predict_next(self, windows: np.ndarray) -> np.ndarray:
        """ζ(φ(h′)): the step after each window (B, 8), in the window's frame."""
        _, _, nxt = self._run(windows)
        return (nxt * self._scale).double().numpy()


def _loss(net: NoveltyNet, x: torch.Tensor, y: torch.Tensor, zeta_weight: float
          ) -> torch.Tensor:
    rec, nxt = net(x)
    return ((rec - x) ** 2).sum(dim=(1, 2)).mean() + zeta_weight * ((nxt - y) ** 2).sum(1).mean()


def train_novelty(tracks: np.ndarray, cfg: NoveltyConfig, scenario: str,
                  progress: bool = False) -> tuple[NoveltyModel, dict]:
    """Train on RO team tracks (instances, steps, n, 3), world m and rad; keep the epoch with
    the lowest loss on the held-out instances."""
    tracks = np.asarray(tracks, np.float64)
    if tracks.ndim != 4 or tracks.shape[1] <= WINDOW or tracks.shape[2] < 3:
        raise UserError(f"novelty models need tracks of 3+ robots and more than {WINDOW} steps, "
                        f"got shape {tracks.shape}")
    rng = np.random.default_rng(cfg.seed)
    order = rng.permutation(len(tracks))
    n_val = max(1, int(round(cfg.val_fraction * len(tracks))))
    if len(tracks) - n_val < 1:
        raise UserError(f"novelty models need at least 2 RO instances, got {len(tracks)}")
    scale = torch.from_numpy(SCALE)

    def tensors(idx: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        x, y = training_windows(tracks[np.sort(idx)])
        return (torch.from_numpy(x.astype(np.float32)) / scale,
                torch.from_numpy(y.astype(np.float32)) / scale)

    (x_tr, y_tr), (x_va, y_va) = tensors(order[n_val:]), tensors(order[:n_val])
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    net = NoveltyNet(cfg)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    best = (float("inf"), -1, copy.deepcopy(net.state_dict()))
    curve = []
    start = time.perf_counter()
    from macrostate_mj.core.progress import LoggedProgress

    with LoggedProgress(disable=not progress, transient=True) as bar:
        task = bar.add_task("train novelty models", total=cfg.epochs)
        for epoch in range(cfg.epochs):
            net.train()
            perm = torch.from_numpy(rng.permutation(len(x_tr)))
            total = 0.0
            for i in range(0, len(perm), cfg.batch):
                idx = perm[i:i + cfg.batch]
                loss = _loss(net, x_tr[idx], y_tr[idx], cfg.zeta_weight)
                opt.zero_grad()
                loss.backward()
                opt.step()
                total += float(loss.detach()) * len(idx)
            net.eval()
            with torch.no_grad():
                val = float(_loss(net, x_va, y_va, cfg.zeta_weight))
            curve.append({"epoch": epoch, "train_loss": total / len(x_tr), "val_loss": val})
            if val < best[0]:
                best = (val, epoch, copy.deepcopy(net.state_dict()))
            bar.update(task, advance=1, description=f"train novelty epoch {epoch + 1} "
                       f"held-out loss {val:.3f} (best {best[0]:.3f} @ {best[1] + 1})")
            if epoch - best[1] >= cfg.patience:
                break
    net.load_state_dict(best[2])
    model = NoveltyModel(net, cfg, tracks.shape[2], scenario)
    info = {"best_val_loss": best[0], "best_epoch": best[1] + 1, "epochs_run": len(curve),
            "train_windows": len(x_tr), "val_windows": len(x_va),
            "train_seconds": time.perf_counter() - start, "curve": curve}
    return model, info


def save_novelty(path: str | os.PathLike, model: NoveltyModel, info: dict) -> Path:
    """Weights, config, team size, scenario, format and version, written atomically."""
    path = Path(path)
    buf = io.BytesIO()
    torch.save({"format": FORMAT, "version": VERSION, "robots": model.robots,
                "scenario": model.scenario, "config": asdict(model.cfg),
                "info": {k: v for k, v in info.items() if k != "train_seconds"},
                "state_dict": model.net.state_dict()}, buf)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())
    return path


def load_novelty(path: str | os.PathLike, robots: int | None = None,
                 scenario: str | None = None) -> NoveltyModel:
    """A model written by `save_novelty`; one-line errors for anything else, another format
    version, or a model of another team size or scenario than asked for."""
    path = Path(path)
    fix = "pass the novelty.pt that `collect --policy srs` wrote, or let it train one"
    if not path.is_file():
        raise UserError(f"{path}: no such novelty model; {fix}")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises many types for a file that is not its own
        raise UserError(f"{path}: not a readable torch file ({type(err).__name__}); {fix}"
                        ) from None
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        raise UserError(f"{path}: not an SRS novelty model; {fix}")
    if ckpt.get("version") != VERSION:
        raise UserError(f"{path}: novelty model format version {ckpt.get('version')}, this code "
                        f"reads {VERSION}; {fix}")
    if robots is not None and ckpt["robots"] != robots:
        raise UserError(f"{path}: novelty model of a {ckpt['robots']}-robot team, this "
                        f"collection has {robots}; {fix}")
    if scenario is not None and ckpt["scenario"] != scenario:
        raise UserError(f"{path}: novelty model of scenario {ckpt['scenario']!r}, this "
                        f"collection is {scenario!r}; {fix}")
    cfg = NoveltyConfig(**ckpt["config"])
    net = NoveltyNet(cfg)
    net.load_state_dict(ckpt["state_dict"])
    return NoveltyModel(net, cfg, ckpt["robots"], ckpt["scenario"], ckpt.get("info"))


@dataclass(frozen=True)
class NoveltyFile:
    """Models stored by `save_novelty`, as the SR phase's Tail loads them in each episode
    (a `formats.srs_windows.NoveltySource`): the path and hash name them in the plan."""

    path: str
    sha256: str = ""

    def load(self) -> NoveltyModel:
        return load_novelty(self.path)


@dataclass(frozen=True)
class NoveltyTraining:
    """These models as `collectors.srs_collection.collect_srs` makes them (its
    `NoveltyTrainer`), wired in by `app`: collectors cannot import estimators."""

    cfg: NoveltyConfig | None = None    # None: the defaults, seeded with the collection's seed

    def config(self, seed: int) -> NoveltyConfig:
        return self.cfg or NoveltyConfig(seed=seed)

    def train(self, tracks: np.ndarray, config: NoveltyConfig, scenario: str, path: Path,
              data_key: str, progress: bool) -> None:
        model, info = train_novelty(tracks, config, scenario, progress=progress)
        save_novelty(path, model, {**info, "data_key": data_key})

    def source(self, path: Path, sha256: str) -> NoveltyFile:
        return NoveltyFile(str(path), sha256)
