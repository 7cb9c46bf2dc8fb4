"""The arithmetic a training runs its forward passes in: one home for what `precision` means.

A config names its precision ("fp32", the default every committed result was made with, or
"bf16") so that the name enters its cache key; the training code asks `precision_named` for the
object and runs each training forward pass inside its `context`. Under "bf16" those passes run
in `torch.autocast` with bfloat16: convolutions and matrix products take bfloat16 inputs, while
the weights, the optimizer's state, every loss and every score (validation, test, the stages'
outputs) stay float32 -- mixed-precision training, not a bfloat16 model.

Why offer it: the one-class pipeline's convolutions are bound by arithmetic on a CPU, so
batching models does not speed them (`bench --only ensemble`), but a CPU with AVX512-BF16 runs
them about twice as fast in bfloat16 (measured: a DSVDD epoch 3.8 -> 1.7 s on one core here).
A CPU without it emulates bfloat16 and is slower; a GPU gains too. What it does to the figures
is measured where the docs say so; nothing uses it unless asked.
"""

from __future__ import annotations

import contextlib
import functools
from dataclasses import dataclass

from macrostate_mj.core.errors import UserError


@dataclass(frozen=True)
class Precision:
    name: str
    dtype: str | None      # a torch dtype's name (torch loads with the first context); None: fp32

    def context(self, device: str = "cpu") -> contextlib.AbstractContextManager:
        """Where a training forward pass runs; losses take `.float()` of what comes out."""
        if self.dtype is None:
            return contextlib.nullcontext()
        import torch

        return torch.autocast(device_type=torch.device(device).type,
                              dtype=getattr(torch, self.dtype))

    def check_runs(self, net, device: str = "cpu") -> None:
        """Refuse, in one line before any work, a network this machine cannot run in this
        precision. oneDNN has a bfloat16 LSTM only on CPUs with AVX512 (measured: this
        project's 2-core build machine and its CI fail with "could not create a primitive
        descriptor"); matrix products and convolutions emulate bfloat16 anywhere."""
        import torch

        if self.dtype is None or not any(isinstance(m, torch.nn.LSTM) for m in net.modules()):
            return
        if not lstm_runs(self.dtype, torch.device(device).type):
            raise UserError(f"this {device.upper()} cannot run an LSTM in {self.name} (its "
                            f"oneDNN has no {self.dtype} LSTM, which needs AVX512); "
                            "train it with --precision fp32", "precision")


@functools.cache
def lstm_runs(dtype: str, device_type: str) -> bool:
    """Whether a one-step LSTM runs under autocast to `dtype` on this machine (probed once)."""
    import torch

    lstm = torch.nn.LSTM(2, 2, batch_first=True).to(device_type)
    try:
        with torch.autocast(device_type=device_type, dtype=getattr(torch, dtype)):
            lstm(torch.zeros(1, 1, 2, device=device_type))
    except RuntimeError:
        return False
    return True


FP32 = Precision("fp32", None)
BF16 = Precision("bf16", "bfloat16")
PRECISIONS = {p.name: p for p in (FP32, BF16)}


def precision_named(name: str) -> Precision:
    if name not in PRECISIONS:
        raise UserError(f"unknown precision {name!r}; choose {' or '.join(PRECISIONS)} "
                        "(fp32 unless your CPU has AVX512-BF16 or you train on a GPU)",
                        "precision")
    return PRECISIONS[name]
