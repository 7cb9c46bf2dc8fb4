"""One fitted pipeline that scores every one-class method it was trained for (higher = unstable).

| method | score |
|---|---|
| ofw   | optical-flow weight: mean flow magnitude (px) over pixels and sub-frames; no training |
| dcae  | reconstruction MSE of the DCAE |
| ocsvm | −decision of a ν-OC-SVM (RBF) on DCAE codes; ν fixed (never chosen on test data) |
| dsvdd | ‖φ(x) − c‖² |
| iogen | Classifier logit on φ(x), trained on real stable (label 1) vs IO-GEN codes (label 0) |
| gen   | the same with a feature-matching GAN that never sees DSVDD |
| ngen  | the same with noise c + α·N(0, 1) clamped at 0, α per coordinate = RMS of φ(G(z)) − c |
"""

from __future__ import annotations

import io
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from estimators.oneclass import train as T
from estimators.oneclass.methods import METHODS
from estimators.oneclass.nets import DCAE, Classifier, Encoder, Generator
from macrostate_mj.core.cache import TaskCache, task_key
from macrostate_mj.core.errors import UserError
from macrostate_mj.core.io import atomic_path


@dataclass
class OCModel:
    cfg: T.OCConfig
    methods: tuple[str, ...]
    channels: int
    ae: DCAE | None = None
    dsvdd: Encoder | None = None
    c: torch.Tensor | None = None
    generators: dict[str, Generator] = field(default_factory=dict)
    classifiers: dict[str, Classifier] = field(default_factory=dict)
    ocsvm: dict[str, torch.Tensor] = field(default_factory=dict)
    history: dict[str, list[float]] = field(default_factory=dict)
    resumed: list[str] = field(default_factory=list)   # stages reused from disk (not saved)

    def score(self, method: str, x: np.ndarray) -> np.ndarray:
        """Novelty score per sample; larger means more likely unstable."""
        if method not in self.methods:
            raise UserError(f"this model was trained for {', '.join(self.methods)}, not {method}; "
                            f"train it with --method {method}")
        if x.shape[1] != self.channels:
            raise UserError(f"model expects m = {self.channels // 2} but got inputs with m = "
                            f"{x.shape[1] // 2}; use --m {self.channels // 2}")
        with torch.no_grad():
            return METHODS[method].score(self, x)

    def _svm_decision(self, codes: torch.Tensor) -> np.ndarray:
        s = self.ocsvm
        z = codes.double()
        k = torch.exp(-s["gamma"] * torch.cdist(z, s["sv"]) ** 2)
        return (k @ s["dual"] + s["intercept"]).numpy()

    def to(self, device: str) -> OCModel:
        """This model with its weights and c on `device` (figures and Grad-CAM read CPU
        tensors; a model trained with `--device cuda` comes back for them)."""
        for mod in self._modules().values():
            mod.to(device)
        if self.c is not None:
            self.c = self.c.to(device)
        self.cfg = replace(self.cfg, device=device)
        return self

    # --- persistence: tensors in weights.pt (loadable with weights_only), the rest in JSON ---
    def save(self, out: Path) -> None:
        from macrostate_mj.core.io import atomic_path, write_json_atomic

        tensors: dict[str, torch.Tensor] = {}
        for name, mod in self._modules().items():
            tensors.update({f"{name}.{k}": v.cpu() for k, v in mod.state_dict().items()})
        if self.c is not None:
            tensors["c"] = self.c.cpu()
        tensors.update({f"ocsvm.{k}": v for k, v in self.ocsvm.items()})
        with atomic_path(out / "weights.pt") as tmp:
            torch.save(tensors, tmp)
        write_json_atomic(out / "model.json", {"methods": list(self.methods),
                                               "channels": self.channels,
                                               "config": asdict(self.cfg),
                                               "history": self.history})

    def _modules(self) -> dict[str, torch.nn.Module]:
        mods: dict[str, torch.nn.Module] = {}
        if self.ae is not None:
            mods["ae"] = self.ae
        if self.dsvdd is not None:
            mods["dsvdd"] = self.dsvdd
        mods.update({f"gen_{k}": v for k, v in self.generators.items()})
        mods.update({f"cls_{k}": v for k, v in self.classifiers.items()})
        return mods

    @classmethod
    def load(cls, path: Path) -> OCModel:
        path = Path(path)
        try:
            meta = json.loads((path / "model.json").read_text())
            tensors = torch.load(path / "weights.pt", weights_only=True)
        except (OSError, ValueError, RuntimeError) as err:
            raise UserError(f"{path} is not a trained model folder ({err.__class__.__name__}); "
                            "train one with `macrostate-mj oc train`") from None
        ch = int(meta["channels"])
        cfg = T.OCConfig(**{**meta["config"], "device": "cpu"})
        model = cls(cfg, tuple(meta["methods"]), ch,
                    history=meta.get("history", {}))
        stages = {s for m in model.methods for s in METHODS[m].needs}
        if "dcae" in stages:
            model.ae = DCAE(ch).to(memory_format=torch.channels_last)
        if "dsvdd" in stages:
            model.dsvdd = Encoder(ch).to(memory_format=torch.channels_last)
            model.c = tensors["c"]
        for g in ("iogen", "gen"):
            if g in stages:
                model.generators[g] = Generator(ch)
        for m in ("iogen", "gen", "ngen"):
            if f"cls_{m}" in stages:
                model.classifiers[m] = Classifier()
        for name, mod in model._modules().items():
            mod.load_state_dict({k[len(name) + 1:]: v for k, v in tensors.items()
                                 if k.startswith(name + ".")})
            mod.eval()
        model.ocsvm = {k[6:]: v for k, v in tensors.items() if k.startswith("ocsvm.")}
        return model


SNAPSHOT_EVERY_S = 600.0   # a killed stage loses at most this much work
STAGE_VERSION = 1          # bump when a stage's training code changes what it computes
_MODULES = {cls.__name__: cls for cls in (DCAE, Encoder, Generator, Classifier)}


class StageCache:
    """Each finished training stage is a cached task (`core.cache`) under
    `stages/oc-<name>/<key>/`: its tensors (`tensors.pt`, loaded with weights_only) and the
    structure around them (`stage.json`), with the generator and torch states after it, so that
    a killed run resumes from its last finished stage and ends with the same weights as an
    uninterrupted one. The key hashes the inputs, the whole config and the stage's version: a
    stage made with another config or other inputs is not reused. Inside a stage, its state is
    kept every `every_s` seconds (`StageSnapshots`, `oc-<name>/<key>.partial.pt`): a stage
    longer than a session (the published recipe's DCAE on a CPU) goes on where it stopped."""

    def __init__(self, folder: Path | None, x: np.ndarray, cfg: T.OCConfig, gen: torch.Generator,
                 every_s: float = SNAPSHOT_EVERY_S, device: str = "cpu"):
        self.cache = None if folder is None else TaskCache(folder)
        self.x, self.config, self.channels = x, asdict(cfg), x.shape[1]
        self.gen, self.every_s = gen, every_s
        self.device = device   # where the run trains: a stage's modules come back there
        self.reused: list[str] = []

    def run(self, name: str, train: Callable[[T.Snapshots], Any]) -> Any:
        if self.cache is None:
            return train(T.NO_SNAPSHOTS)
        stage = f"oc-{name}"
        key = task_key(stage, STAGE_VERSION, self.config, [self.x])
        folder = self.cache.get(stage, key)
        if folder is not None:
            tensors = self.load_tensors(folder / "tensors.pt")
            self.reused.append(name)
            out = _unpack(json.loads((folder / "stage.json").read_text()), tensors,
                          self.channels, self.device)
            self.restore_rng(tensors)       # after building the modules, which draw weights
            return out
        snaps = StageSnapshots(self.cache.folder(stage, key).with_suffix(".partial.pt"), self,
                               self.every_s)
        out = train(snaps)
        tensors: dict[str, torch.Tensor] = {}
        meta = _pack(out, "out", tensors)
        tensors.update(self.rng_states())
        buf = io.BytesIO()
        torch.save({k: v.detach().cpu() for k, v in tensors.items()}, buf)
        self.cache.put(stage, key, {"tensors.pt": buf.getvalue(),
                                    "stage.json": json.dumps(meta).encode()})
        snaps.path.unlink(missing_ok=True)
        return out

    def rng_states(self) -> dict[str, torch.Tensor]:
        return {"rng.gen": self.gen.get_state(), "rng.torch": torch.get_rng_state()}

    def restore_rng(self, saved: dict[str, Any]) -> None:
        self.gen.set_state(saved["rng.gen"].cpu())      # random states live on the CPU
        torch.set_rng_state(saved["rng.torch"].cpu())

    def load_tensors(self, path: Path) -> dict[str, Any]:
        """Tensors and plain data only: a tampered file cannot run code."""
        return torch.load(path, map_location=self.device, weights_only=True)


def _pack(obj: Any, prefix: str, tensors: dict[str, torch.Tensor]) -> Any:
    """A stage's output as JSON, its tensors moved into `tensors` under dotted names."""
    if isinstance(obj, torch.nn.Module):
        tensors.update({f"{prefix}.{k}": v for k, v in obj.state_dict().items()})
        return {"module": type(obj).__name__, "at": prefix}
    if isinstance(obj, torch.Tensor):
        tensors[prefix] = obj
        return {"tensor": prefix}
    if isinstance(obj, tuple):
        return {"tuple": [_pack(v, f"{prefix}.{i}", tensors) for i, v in enumerate(obj)]}
    if isinstance(obj, dict):
        return {"dict": {k: _pack(v, f"{prefix}.{k}", tensors) for k, v in obj.items()}}
    return {"value": obj}           # numbers and lists of numbers (histories)


def _unpack(meta: dict, tensors: dict[str, torch.Tensor], channels: int, device: str) -> Any:
    if "module" in meta:
        cls = _MODULES[meta["module"]]
        mod = cls() if cls is Classifier else cls(channels)
        mod = mod.to(device, memory_format=torch.channels_last)   # as trained (4-D weights)
        at = meta["at"] + "."
        mod.load_state_dict({k[len(at):]: v for k, v in tensors.items() if k.startswith(at)})
        return mod.eval()
    if "tensor" in meta:
        return tensors[meta["tensor"]]
    if "tuple" in meta:
        return tuple(_unpack(m, tensors, channels, device) for m in meta["tuple"])
    if "dict" in meta:
        return {k: _unpack(m, tensors, channels, device) for k, m in meta["dict"].items()}
    return meta["value"]


class StageSnapshots:
    """One stage's loop state (weights, optimizers, best epoch so far, random states) in
    `<key>.partial.pt` beside the stage's cache folder, written atomically when `every_s`
    seconds have passed since the last; removed once the stage is done. Restoring it continues
    the stage bit for bit."""

    def __init__(self, path: Path, cache: StageCache, every_s: float):
        self.path, self.cache, self.every_s = path, cache, every_s
        self.last = time.monotonic()

    def restore(self, parts: T.Parts) -> tuple[int, dict[str, Any]]:
        if not self.path.is_file():
            return 0, {}
        saved = self.cache.load_tensors(self.path)
        self.cache.restore_rng(saved)
        for name, part in parts.items():
            part.load_state_dict(saved["parts"][name])
        return saved["done"], saved["loop"]

    def save(self, done: int, parts: T.Parts, loop: dict[str, Any]) -> None:
        if time.monotonic() - self.last < self.every_s:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.path) as tmp:
            torch.save({"done": done, "loop": loop,
                        "parts": {name: part.state_dict() for name, part in parts.items()},
                        **self.cache.rng_states()}, tmp)
        self.last = time.monotonic()


@dataclass
class Probe:
    """Research only: the scores of fixed inputs `x` after every epoch of DSVDD and of each
    classifier (`curves[method]`, one array per epoch), to measure what choosing a checkpoint
    on them would gain, as the published code did on test data. It watches and never chooses:
    a fit with a probe ends with the same weights as one without (tested); stages reused from
    `stages_dir` are not watched."""

    x: np.ndarray
    curves: dict[str, list[np.ndarray]] = field(default_factory=dict)

    def watch(self, method: str, inputs: torch.Tensor) -> T.Watch:
        def log(score: T.Scorer) -> None:
            self.curves.setdefault(method, []).append(score(inputs).cpu().numpy())
        return log


def fit(x: np.ndarray, methods: Sequence[str], cfg: T.OCConfig, tick: T.Tick | None = None,
        stages_dir: Path | None = None, probe: Probe | None = None,
        snapshot_every_s: float = SNAPSHOT_EVERY_S) -> OCModel:
    """Train every stage `methods` need on stable training inputs x (N × 2m × 64 × 64); with
    `stages_dir`, keep each finished stage there and reuse those already done, and the
    unfinished one's state every `snapshot_every_s` seconds (`StageCache`)."""
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise UserError(f"unknown method {unknown[0]!r}; choose from {', '.join(METHODS)}")
    tick = tick or (lambda stage, frac: None)
    torch.set_num_threads(cfg.threads)
    if cfg.device == "cuda":   # cuDNN's fastest convolutions differ from run to run
        torch.backends.cudnn.deterministic, torch.backends.cudnn.benchmark = True, False
    torch.manual_seed(cfg.seed)  # weight initialisation
    gen = torch.Generator().manual_seed(cfg.seed)
    cache = StageCache(stages_dir, x, cfg, gen, snapshot_every_s, cfg.device)
    perm = np.random.default_rng(cfg.seed).permutation(len(x))
    n_val = max(1, round(len(x) * cfg.val_fraction))
    xall = torch.from_numpy(np.ascontiguousarray(x)).to(cfg.device)
    xtr, xval = xall[perm[n_val:]], xall[perm[:n_val]]
    model = OCModel(cfg, tuple(methods), x.shape[1])
    stages = {s for m in methods for s in METHODS[m].needs}
    if "dcae" in stages:
        model.ae, model.history["dcae_val"] = cache.run(
            "dcae", lambda snaps: T.train_dcae(xtr, xval, cfg, gen, tick, snaps))
    if "ocsvm" in stages:
        model.ocsvm = cache.run("ocsvm", lambda _: fit_ocsvm(
            T.encode(model.ae.encoder, xall).cpu(), cfg.ocsvm_nu))
    px = None if probe is None else torch.from_numpy(np.ascontiguousarray(probe.x)).to(cfg.device)

    def watch(method: str, inputs: Callable[[], torch.Tensor]) -> T.Watch | None:
        return None if probe is None else probe.watch(method, inputs())

    if "dsvdd" in stages:
        model.dsvdd, model.c, model.history["dsvdd_val"] = cache.run(
            "dsvdd", lambda snaps: T.train_dsvdd(model.ae, xtr, xval, cfg, gen, tick,
                                                 watch("dsvdd", lambda: px), snaps))
    for kind in ("iogen", "gen"):
        if kind in stages:
            model.generators[kind], log = cache.run(kind, lambda snaps, kind=kind: (
                T.train_generator(model.ae, model.dsvdd, model.c, xtr, cfg, gen, tick, kind,
                                  snaps)))
            model.history.update({f"{kind}_{k}": v[::10] for k, v in log.items()})
    if any(s.startswith("cls_") for s in stages):
        real, real_val = T.encode(model.dsvdd, xtr), T.encode(model.dsvdd, xval)
        for kind in ("iogen", "gen", "ngen"):
            if f"cls_{kind}" not in stages:
                continue

            def classifier(snaps: T.Snapshots, kind: str = kind) -> tuple:
                fake, fake_val = _synthetic(model, kind, 2 * len(xtr), len(xval), gen)
                return T.train_classifier(
                    real, real_val, fake, fake_val, model.c, cfg, gen, tick,
                    f"CLS-{kind.upper()}", watch(kind, lambda: T.encode(model.dsvdd, px)), snaps)

            model.classifiers[kind], model.history[f"cls_{kind}_val"] = cache.run(
                f"cls_{kind}", classifier)
    model.resumed = cache.reused
    return model


def _synthetic(model: OCModel, kind: str, n: int, n_val: int, gen: torch.Generator,
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """Codes of the 'most stable' class: generated (IO-GEN, GEN) or Gaussian noise (N-GEN).

    The seed draws every N-GEN element from N(0, α), α one global variation of IO-GEN's codes. Our
    codes are ReLU outputs with c far from 0, so noise around 0 lies outside the stable sphere and
    the label switch inverts (AUC .18-.20 on the simulated colony); around c with one global spread
    it still spreads over all 2048 coordinates where real codes move in few and is trivially
    separable (it also inverted on the real smoke set, .43-.47: a direction only, that set weighs
    the day bins unlike the colony). So the noise here keeps IO-GEN's spread about c per
    coordinate and the codes' sign: the ablation the seed means, noise in place of realistic
    inner outliers, with their scale but none of their structure.
    """
    if kind != "ngen":
        codes = T.generated_codes(model.generators[kind], model.dsvdd, n + n_val, gen)
    else:
        ref = T.generated_codes(model.generators["iogen"], model.dsvdd, 512, gen)
        spread = ((ref - model.c) ** 2).mean(0).sqrt()  # per coordinate
        codes = (model.c + spread * T.randn((n + n_val, ref.shape[1]), gen, ref)).clamp_min(0)
    return codes[:n], codes[n:]


def fit_ocsvm(codes: torch.Tensor, nu: float) -> dict[str, torch.Tensor]:
    """ν-OC-SVM (RBF, gamma='scale') on the codes, kept as plain arrays (no pickle to load)."""
    from sklearn.svm import OneClassSVM

    x = codes.double().numpy()
    gamma = 1.0 / (x.shape[1] * x.var())        # scikit-learn's gamma="scale", kept explicit
    svm = OneClassSVM(nu=nu, gamma=gamma).fit(x)
    return {"sv": torch.from_numpy(svm.support_vectors_),
            "dual": torch.from_numpy(svm.dual_coef_.ravel()),
            "intercept": torch.tensor(float(svm.intercept_[0]), dtype=torch.float64),
            "gamma": torch.tensor(float(gamma), dtype=torch.float64)}
