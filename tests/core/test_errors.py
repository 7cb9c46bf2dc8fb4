"""Library errors are `ValueError`s; the checkout's default reference-data folder."""

import pytest

from macrostate_mj.core import paths
from macrostate_mj.core.errors import UserError


def test_a_user_error_is_a_value_error_with_a_one_line_message():
    from macrostate_mj.chain.scenarios import get_scenario

    assert issubclass(UserError, ValueError)
    with pytest.raises(ValueError) as err:
        get_scenario("nope")
    assert isinstance(err.value, UserError)
    message = str(err.value)
    assert "nope" in message and "\n" not in message


def test_reference_data_follows_the_variable_then_a_verified_fetch_then_the_checkout(
        monkeypatch, tmp_path):
    """Per dataset: `$MACROSTATE_REFERENCE_DATA`; else the fetch cache where `data fetch`
    verified that dataset (a half-done fetch's empty folders do not count); else the
    checkout's `../shared/reference-data` where it holds the dataset; else the fetch cache,
    where a missing file names `data fetch`."""
    monkeypatch.delenv("MACROSTATE_REFERENCE_DATA", raising=False)
    cache = tmp_path / "cache"
    monkeypatch.setenv("MACROSTATE_DATA_CACHE", str(cache))
    assert paths.CHECKOUT is not None and (paths.CHECKOUT / "macrostate_mj").is_dir()
    shared = paths.CHECKOUT.parent / "shared" / "reference-data"
    expected = shared if (shared / "ReTLo").is_dir() else cache
    assert paths.reference_data("ReTLo") == expected
    (cache / "ReTLo" / "Datasets" / "3Robots").mkdir(parents=True)     # a fetch cut short
    assert paths.reference_data("ReTLo") == expected
    (cache / "ReTLo" / ".verified.json").write_text("{}")
    assert paths.reference_data("ReTLo") == cache
    assert paths.real_dataset("OpticalFlows_HsAnts").parent == (
        shared if (shared / "OpticalFlows_HsAnts").is_dir() else cache)   # not fetched: apart
    monkeypatch.setenv("MACROSTATE_REFERENCE_DATA", str(tmp_path))
    assert paths.real_thymioloc("Train.csv") == tmp_path / "ReTLo" / "Datasets" / "3Robots" / (
        "Train.csv")
