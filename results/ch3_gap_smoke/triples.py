import json
from pathlib import Path

from estimators.retlo.api import evaluate, fit
from estimators.retlo.files import read_world
from estimators.retlo.models import ModelConfig, TorchPredictor
from estimators.retlo.train import TrainConfig


def main():
    out = Path("/tmp/ch3/out_webots")
    train, val, test = (read_world(out / n / "instances.csv") for n in ("train", "val", "test"))
    net, info = fit([train], val, TrainConfig(epochs=60, seed=0, model=ModelConfig(
        history=10, bidirectional=False, cos_sin=True)))
    pred = TorchPredictor(net)
    chain = evaluate(pred, test)
    res = {"chain_all": chain["mean_error_cm"], "chain_per_robot": chain["per_robot_cm"]}
    # file order H, F1, F2, F3, T: each module alone with true inputs = a 3-robot chain
    for name, idx in (("module0 (F2 from F3,T)", [2, 3, 4]), ("module1 (F1 from F2,F3)", [1, 2, 3]),
                      ("module2 (H from F1,F2)", [0, 1, 2])):
        res[name] = evaluate(pred, test[:, :, idx])["per_robot_cm"]["H"]
    print(json.dumps(res, indent=1))
    Path("/tmp/ch3/triples.json").write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
