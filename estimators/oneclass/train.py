"""Training stages of the one-class pipeline: DCAE -> DSVDD -> IO-GEN or GEN -> Classifier.

Model selection uses stable data only: each stage keeps the weights that did best on a held-out
slice of the stable *training* split (never test or unstable samples), and the GAN runs a fixed
number of steps. Every random draw comes from the `torch.Generator` passed in.
"""

from __future__ import annotations

import contextlib
import copy
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any, Protocol

import torch
import torch.nn.functional as F
from torch import nn

from estimators.oneclass.nets import DCAE, LATENT, Classifier, Discriminator, Encoder, Generator
from estimators.precision import precision_named
from macrostate_mj.core.errors import UserError

Tick = Callable[[str, float], None]  # (stage, completed fraction) -> None, for a progress bar
Scorer = Callable[[torch.Tensor], torch.Tensor]   # inputs -> novelty scores, this epoch's weights
Watch = Callable[[Scorer], None]   # called after every epoch (research probes, `model.Probe`)
Parts = dict[str, Any]   # what a stage's loop carries: modules and optimizers (state_dict owners)
GAN_TICK = 10            # the GAN stage reports progress every this many steps


class Snapshots(Protocol):
    """Where a long stage keeps its state between epochs or steps, so that a killed run goes on
    inside the stage (`model.StageSnapshots`; `NO_SNAPSHOTS` keeps nothing)."""

    def restore(self, parts: Parts) -> tuple[int, dict[str, Any]]:
        """Load the last snapshot into `parts`; (epochs or steps done, the loop's own state)."""
        ...

    def save(self, done: int, parts: Parts, loop: dict[str, Any]) -> None:
        """Offer the state after `done` epochs or steps; kept when one is due."""
        ...


class _NoSnapshots:
    def restore(self, parts: Parts) -> tuple[int, dict[str, Any]]:
        return 0, {}

    def save(self, done: int, parts: Parts, loop: dict[str, Any]) -> None:
        pass


NO_SNAPSHOTS: Snapshots = _NoSnapshots()


@dataclass(frozen=True)
class OCConfig:
    """Hyper-parameters. Defaults follow the published recipe, shortened for a 2-core CPU
    except DSVDD's epochs: fewer stop while its held-out stable loss still falls (docs)."""

    m: int = 2
    seed: int = 0
    val_fraction: float = 0.1  # held-out slice of the stable train split, for model selection
    batch: int = 32
    dcae_epochs: int = 30
    dcae_lr: float = 1e-3
    dcae_noise: float = 0.02  # denoising: input noise std (published: 0.02)
    dsvdd_epochs: int = 160  # the published count
    dsvdd_lr: float = 5e-5
    weight_decay: float = 1e-6  # the λ/2 ΣW² term of the DSVDD objective
    gan_steps: int = 1500
    gan_batch: int = 16
    gan_lr_d: float = 2e-5
    gan_lr_g: float = 8e-5  # 4 × the discriminator's, as published
    lam: float = 10.0  # weight of the DSVDD term in the IO-GEN loss
    # "mean": ‖mean φ(G(z)) − c‖² as the seed writes it; "sample": mean ‖φ(G(z)) − c‖², every
    # synthetic code pulled inside the sphere (Fig 4.2d). Measured on splits 1-3 (smoke unstable
    # set, seed 0, GPU): IO-GEN AUC .76/.76/.70 with "sample" against .63/.62/.54 with "mean"
    # (a repeat of "sample" gave .66/.74/.73: the GAN stage is the noisy one).
    io_term: str = "sample"
    cls_epochs: int = 30
    cls_lr: float = 1.25e-4
    ocsvm_nu: float = 0.1
    threads: int = 1
    device: str = "cpu"  # "cuda" where a GPU exists; random draws stay on the CPU generator
    # the training forward passes' arithmetic (`estimators.precision`): "bf16" is faster on a
    # CPU with AVX512-BF16 (`bench --only iogen`); every committed figure is "fp32"
    precision: str = "fp32"

    @classmethod
    def recipe(cls, name: str, **kw: Any) -> OCConfig:
        """A named recipe: "short" (these defaults, for a 2-core CPU) or "published" (the
        epoch and step counts of the published code: DCAE 750, DSVDD 160, 20,000 GAN steps,
        classifier 40)."""
        if name not in RECIPES:
            raise UserError(f"unknown recipe {name!r}; choose one of {', '.join(RECIPES)}")
        return cls(**{**RECIPES[name], **kw})

    def scaled(self, factor: float) -> OCConfig:
        """The same recipe with every epoch/step count scaled (for --quick runs and tests)."""
        def k(n: int) -> int:
            return max(1, round(n * factor))
        return OCConfig(**{**self.__dict__, "dcae_epochs": k(self.dcae_epochs),
                           "dsvdd_epochs": k(self.dsvdd_epochs), "gan_steps": k(self.gan_steps),
                           "cls_epochs": k(self.cls_epochs)})

    def overridden(self, settings: Sequence[str]) -> OCConfig:
        """`name=value` settings (the CLI's --set) on top of the recipe, for research runs;
        the manifest records the result. Unknown names and values of the wrong type are user
        errors; m, seed, threads, device and precision have options of their own."""
        types = {f.name: f.type for f in fields(self) if f.name not in _OWN_OPTIONS}
        kw: dict[str, Any] = {}
        for item in settings:
            name, sep, text = item.partition("=")
            if name in _OWN_OPTIONS:
                raise UserError(f"--set {item!r}: {name} has an option of its own; use it")
            if not sep or name not in types:
                raise UserError(f"--set {item!r}: expected NAME=VALUE with NAME one of "
                                f"{', '.join(types)}")
            try:
                kw[name] = {"int": int, "float": float}.get(str(types[name]), str)(text)
            except ValueError:
                raise UserError(f"--set {item!r}: {name} takes a number of type "
                                f"{types[name]}") from None
        return replace(self, **kw)

    def __post_init__(self) -> None:
        if self.io_term not in ("mean", "sample"):
            raise UserError(f"io_term {self.io_term!r}: choose mean or sample")
        precision_named(self.precision)

    def autocast(self) -> contextlib.AbstractContextManager:
        """Where a training forward pass runs (`estimators.precision`)."""
        return precision_named(self.precision).context(self.device)


_OWN_OPTIONS = ("m", "seed", "threads", "device", "precision")

RECIPES: dict[str, dict[str, int]] = {
    "short": {},
    "published": {"dcae_epochs": 750, "dsvdd_epochs": 160, "gan_steps": 20_000, "cls_epochs": 40},
}


def cl(x: torch.Tensor) -> torch.Tensor:
    """channels_last: ~1.4× faster convolutions on this CPU."""
    return x.contiguous(memory_format=torch.channels_last)


def randn(shape: tuple[int, ...] | torch.Size, gen: torch.Generator, like: torch.Tensor,
          ) -> torch.Tensor:
    """N(0, 1) draws from the (CPU) generator, on the device of `like`: same stream anywhere."""
    return torch.randn(tuple(shape), generator=gen).to(like.device)


def batches(n: int, size: int, gen: torch.Generator) -> Iterator[torch.Tensor]:
    perm = torch.randperm(n, generator=gen)
    for i in range(0, n, size):
        yield perm[i:i + size]


@torch.no_grad()
def encode(enc: Encoder, x: torch.Tensor, batch: int = 256) -> torch.Tensor:
    enc.eval()
    return torch.cat([enc(cl(x[i:i + batch])) for i in range(0, len(x), batch)])


@torch.no_grad()
def reconstruction_error(ae: DCAE, x: torch.Tensor, batch: int = 256) -> torch.Tensor:
    ae.eval()
    return torch.cat([((ae(cl(xb)) - xb) ** 2).flatten(1).mean(1)
                      for xb in x.split(batch)])


def _select_best(model: nn.Module, opt: torch.optim.Optimizer, epochs: int,
                 run_epoch: Callable[[], None], val_loss: Callable[[], float], stage: str,
                 tick: Tick, snaps: Snapshots, watch: Callable[[], None] | None = None,
                 ) -> list[float]:
    """Train `epochs` epochs; restore the weights with the lowest held-out stable loss.
    `watch` runs after every epoch's validation and takes no part in the choice."""
    parts = {"model": model, "opt": opt}
    done, loop = snaps.restore(parts)
    best, history = loop.get("best", float("inf")), loop.get("history", [])
    state = loop["state"] if "state" in loop else copy.deepcopy(model.state_dict())
    for e in range(done, epochs):
        model.train()
        run_epoch()
        loss = val_loss()
        history.append(loss)
        if loss < best:
            best, state = loss, copy.deepcopy(model.state_dict())
        if watch is not None:
            watch()
        snaps.save(e + 1, parts, {"best": best, "state": state, "history": history})
        tick(stage, (e + 1) / epochs)
    model.load_state_dict(state)
    return history


def train_dcae(x: torch.Tensor, xval: torch.Tensor, cfg: OCConfig, gen: torch.Generator,
               tick: Tick, snaps: Snapshots = NO_SNAPSHOTS) -> tuple[DCAE, list[float]]:
    """Denoising autoencoder, MSE; selected on held-out stable reconstruction error."""
    ae = DCAE(x.shape[1]).to(x.device, memory_format=torch.channels_last)
    opt = torch.optim.Adam(ae.parameters(), lr=cfg.dcae_lr)

    def epoch() -> None:
        for idx in batches(len(x), cfg.batch, gen):
            xb = x[idx]
            noisy = xb + cfg.dcae_noise * randn(xb.shape, gen, xb)
            with cfg.autocast():
                out = ae(cl(noisy))
            loss = F.mse_loss(out.float(), xb)
            opt.zero_grad()
            loss.backward()
            opt.step()

    hist = _select_best(ae, opt, cfg.dcae_epochs, epoch,
                        lambda: float(reconstruction_error(ae, xval).mean()), "DCAE", tick, snaps)
    return ae.eval(), hist


def center(codes: torch.Tensor) -> torch.Tensor:
    """c = mean code of the stable training inputs. Ruff et al. push near-zero coordinates to
    ±0.1; with ReLU codes that moved c off the data (measured: DSVDD AUC .49 against .63)."""
    return codes.mean(0)


def train_dsvdd(ae: DCAE, x: torch.Tensor, xval: torch.Tensor, cfg: OCConfig,
                gen: torch.Generator, tick: Tick, watch: Watch | None = None,
                snaps: Snapshots = NO_SNAPSHOTS) -> tuple[Encoder, torch.Tensor, list[float]]:
    """Fine-tune a copy of the DCAE encoder toward c; selected on held-out mean distance to c."""
    enc = copy.deepcopy(ae.encoder)
    c = center(encode(enc, x))
    opt = torch.optim.Adam(enc.parameters(), lr=cfg.dsvdd_lr, weight_decay=cfg.weight_decay)

    def epoch() -> None:
        for idx in batches(len(x), cfg.batch, gen):
            with cfg.autocast():
                codes = enc(cl(x[idx]))
            loss = ((codes.float() - c) ** 2).sum(1).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()

    def val() -> float:
        return float(((encode(enc, xval) - c) ** 2).sum(1).mean())

    def score(xb: torch.Tensor) -> torch.Tensor:
        return ((encode(enc, xb) - c) ** 2).sum(1)

    hist = _select_best(enc, opt, cfg.dsvdd_epochs, epoch, val, "DSVDD", tick, snaps,
                        None if watch is None else lambda: watch(score))
    for p in enc.parameters():
        p.requires_grad_(False)
    return enc.eval(), c, hist


def train_generator(ae: DCAE, dsvdd: Encoder, c: torch.Tensor, x: torch.Tensor, cfg: OCConfig,
                    gen: torch.Generator, tick: Tick, kind: str = "iogen",
                    snaps: Snapshots = NO_SNAPSHOTS) -> tuple[Generator, dict[str, list[float]]]:
    """IO-GEN: adversarial + λ‖mean φ(G(z)) − c‖² (frozen DSVDD φ); GEN: feature matching on D.

    Both start from a copy of the pre-trained decoder; the discriminator is a fresh encoder.
    Labels are smoothed as published (real ∈ [0.9, 1], fake ∈ [0, 0.1]).
    """
    g = Generator(x.shape[1], ae.decoder).to(x.device, memory_format=torch.channels_last)
    d = Discriminator(x.shape[1]).to(x.device, memory_format=torch.channels_last)
    opt_d = torch.optim.Adam(d.parameters(), lr=cfg.gan_lr_d, betas=(0.5, 0.999))
    opt_g = torch.optim.Adam(g.parameters(), lr=cfg.gan_lr_g, betas=(0.5, 0.999))
    parts = {"g": g, "d": d, "opt_d": opt_d, "opt_g": opt_g}
    done, loop = snaps.restore(parts)
    b, log = cfg.gan_batch, loop.get("log", {"d_loss": [], "g_adv": [], "g_feat": []})
    ones = torch.ones(b, device=x.device)
    for step in range(done, cfg.gan_steps):
        g.train()
        d.train()
        real = x[torch.randint(len(x), (b,), generator=gen)]
        z = randn((b, LATENT), gen, x)
        with cfg.autocast():
            fake = g(z).detach()
            logit_real, logit_fake = d(cl(real)), d(cl(fake))
        y_real = 1.0 - 0.1 * torch.rand(b, generator=gen).to(x.device)
        y_fake = 0.1 * torch.rand(b, generator=gen).to(x.device)
        d_loss = (F.binary_cross_entropy_with_logits(logit_real.float(), y_real)
                  + F.binary_cross_entropy_with_logits(logit_fake.float(), y_fake))
        opt_d.zero_grad()
        d_loss.backward()
        opt_d.step()

        z = randn((b, LATENT), gen, x)
        if kind == "iogen":
            with cfg.autocast():
                xg = g(z)
                logit, codes = d(xg), dsvdd(xg)
            adv = F.binary_cross_entropy_with_logits(logit.float(), ones)
            codes = codes.float()
            feat = (((codes.mean(0) - c) ** 2).sum() if cfg.io_term == "mean"
                    else ((codes - c) ** 2).sum(1).mean())
            g_loss = adv + cfg.lam * feat
        else:  # GEN: Salimans et al.'s feature matching in the discriminator, no DSVDD
            real = x[torch.randint(len(x), (b,), generator=gen)]
            with cfg.autocast():
                xg = g(z)
                with torch.no_grad():
                    target = d.features(cl(real)).float().mean(0)
                fake_features = d.features(xg)
            feat = ((fake_features.float().mean(0) - target) ** 2).sum()
            adv, g_loss = torch.zeros(()), feat
        opt_g.zero_grad()
        g_loss.backward()
        opt_g.step()
        for key, val in (("d_loss", d_loss), ("g_adv", adv), ("g_feat", feat)):
            log[key].append(float(val.detach()))
        snaps.save(step + 1, parts, {"log": log})
        if (step + 1) % GAN_TICK == 0 or step + 1 == cfg.gan_steps:
            tick(kind.upper(), (step + 1) / cfg.gan_steps)
    return g.eval(), log


@torch.no_grad()
def generated_codes(g: Generator, dsvdd: Encoder, n: int, gen: torch.Generator,
                    batch: int = 256) -> torch.Tensor:
    """φ(G(z)) for n draws of z."""
    g.eval()
    like = next(g.parameters())
    out = [dsvdd(g(randn((min(batch, n - i), LATENT), gen, like))) for i in range(0, n, batch)]
    return torch.cat(out)


def train_classifier(real: torch.Tensor, real_val: torch.Tensor, fake: torch.Tensor,
                     fake_val: torch.Tensor, center: torch.Tensor, cfg: OCConfig,
                     gen: torch.Generator, tick: Tick, stage: str, watch: Watch | None = None,
                     snaps: Snapshots = NO_SNAPSHOTS) -> tuple[Classifier, list[float]]:
    """Classifier on DSVDD codes with the label switch: real stable = 1 ("unstable"), synthetic = 0.

    Each epoch pairs every real code with a fresh draw from the synthetic pool; the epoch kept is
    the one with the lowest BCE on held-out stable codes vs held-out synthetic codes.
    """
    clf = Classifier().to(real.device)
    clf.shift.copy_(center)
    clf.scale.copy_(((real - center) ** 2).mean().sqrt())
    opt = torch.optim.Adam(clf.parameters(), lr=cfg.cls_lr)

    def epoch() -> None:
        pick = fake[torch.randint(len(fake), (len(real),), generator=gen)]
        data = torch.cat([real, pick])
        labels = torch.cat([torch.ones(len(real)), torch.zeros(len(pick))]).to(real.device)
        for idx in batches(len(data), cfg.batch, gen):
            with cfg.autocast():
                logits = clf(data[idx])
            loss = F.binary_cross_entropy_with_logits(logits.float(), labels[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()

    @torch.no_grad()
    def val() -> float:
        clf.eval()
        data = torch.cat([real_val, fake_val])
        labels = torch.cat([torch.ones(len(real_val)), torch.zeros(len(fake_val))]).to(data.device)
        return float(F.binary_cross_entropy_with_logits(clf(data), labels))

    @torch.no_grad()
    def score(codes: torch.Tensor) -> torch.Tensor:
        clf.eval()
        return torch.cat([clf(v) for v in codes.split(512)])

    hist = _select_best(clf, opt, cfg.cls_epochs, epoch, val, stage, tick, snaps,
                        None if watch is None else lambda: watch(score))
    return clf.eval(), hist
