"""Experiments that reproduce the dissertation's figures: data, estimators and figures together."""

import numpy as np


def mean_std(values: list[float]) -> dict:
    """A figure over seeds or datasets as the results files give it: mean, std and count."""
    return {"mean": float(np.mean(values)), "std": float(np.std(values)), "n": len(values)}
