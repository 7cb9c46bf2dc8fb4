"""Networks of SPEC §8 / seed §4.6.4, channels first (N × 2m × 64 × 64 inputs in [−1, 1]).

The encoder keeps its biases as published, although Ruff et al. (2018) drop them against
"hypersphere collapse": measured on split 1 (m = 2, smoke unstable set) the bias-free DSVDD reached
AUC .63 against .80 with biases, and stable-only early stopping keeps the collapse away. Its
8 × 8 × 32 bottleneck (ReLU) flattens to the 2048-d code v.
"""

from __future__ import annotations

import torch
from torch import nn

CODE_SHAPE = (32, 8, 8)
CODE_DIM = 32 * 8 * 8
LATENT = 100
ENCODER_BIAS = True


class Encoder(nn.Module):
    """conv 32-64-128 (3 × 3, ReLU, max-pool) + a 32-kernel bottleneck: x -> F (N × 32 × 8 × 8)."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        for cin, cout in ((channels, 32), (32, 64), (64, 128)):
            layers += [nn.Conv2d(cin, cout, 3, padding=1, bias=ENCODER_BIAS), nn.ReLU(),
                       nn.MaxPool2d(2)]
        layers += [nn.Conv2d(128, 32, 3, padding=1, bias=ENCODER_BIAS), nn.ReLU()]
        self.net = nn.Sequential(*layers)

    def feature_map(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x).flatten(1)


class Decoder(nn.Module):
    """Mirror of the encoder (conv 128-64-32, ReLU, 2× up-sampling) + a tanh 2m-channel output.

    Each conv runs before its up-sampling, at the encoder's resolution for that width: the same
    layers as up-sample-then-conv at a quarter of the cost (330 -> 90 MFLOP per sample), which is
    what lets a split's pipeline fit a 2-core CPU.
    """

    def __init__(self, channels: int) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        for cin, cout in ((32, 128), (128, 64), (64, 32)):
            layers += [nn.Conv2d(cin, cout, 3, padding=1), nn.ReLU(), nn.Upsample(scale_factor=2)]
        layers += [nn.Conv2d(32, channels, 3, padding=1), nn.Tanh()]
        self.net = nn.Sequential(*layers)

    def forward(self, v: torch.Tensor) -> torch.Tensor:
        return self.net(v.view(-1, *CODE_SHAPE))


class DCAE(nn.Module):
    def __init__(self, channels: int) -> None:
        super().__init__()
        self.encoder, self.decoder = Encoder(channels), Decoder(channels)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.decoder(self.encoder(x))


class Generator(nn.Module):
    """z ∈ R^100 -> FC + ReLU -> a copy of the (pre-trained) decoder."""

    def __init__(self, channels: int, decoder: Decoder | None = None) -> None:
        super().__init__()
        self.fc = nn.Sequential(nn.Linear(LATENT, CODE_DIM), nn.ReLU())
        self.decoder = Decoder(channels)
        if decoder is not None:
            self.decoder.load_state_dict(decoder.state_dict())

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return self.decoder(self.fc(z))


class Discriminator(nn.Module):
    """A freshly initialised encoder + one logit (the sigmoid lives in the loss)."""

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.encoder = Encoder(channels)
        self.head = nn.Linear(CODE_DIM, 1)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        return self.encoder(x)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.encoder(x)).squeeze(1)


class Classifier(nn.Module):
    """Five 1-D conv blocks (8-16-24-48-48, LeakyReLU 0.3, avg-pool) on the 2048-d code -> logit.

    The code enters as ((v − c) / σ)², σ the RMS deviation of stable training codes from c, so
    that how far each coordinate sits from c is a feature the first layer reads linearly.
    Why squared: the label switch only works if the classifier's "unstable" grows with distance
    from c (seed Fig 4.10b). Fed the signed code (v − c) / σ, it keyed on the direction in which
    IO-GEN codes leave c instead, and that direction is shared by unstable codes (cosine .40
    between their mean deviations on the simulated colony): unstable samples scored as "more
    synthetic than stable", AUC .19-.20 over three classifier seeds against .81-.82 squared (split
    1, DSVDD .82). Without the 1/σ scaling held-out BCE stayed at ln 2: DSVDD squeezes codes to
    within ~0.1 of c, too small a signal for the classifier to pick up from its initialisation.
    """

    def __init__(self) -> None:
        super().__init__()
        self.register_buffer("shift", torch.zeros(CODE_DIM))
        self.register_buffer("scale", torch.ones(()))
        layers: list[nn.Module] = []
        cin = 1
        for cout in (8, 16, 24, 48, 48):
            layers += [nn.Conv1d(cin, cout, 3, padding=1), nn.LeakyReLU(0.3), nn.AvgPool1d(2)]
            cin = cout
        self.net = nn.Sequential(*layers, nn.Flatten(), nn.Linear(48 * CODE_DIM // 32, 1))

    def forward(self, v: torch.Tensor) -> torch.Tensor:
        return self.net((((v - self.shift) / self.scale) ** 2).unsqueeze(1)).squeeze(1)
