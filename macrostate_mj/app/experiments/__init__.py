"""Experiments that reproduce the dissertation's figures: data, estimators and figures together."""
