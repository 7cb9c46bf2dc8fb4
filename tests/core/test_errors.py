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


def test_reference_data_defaults_beside_the_checkout_and_follows_the_variable(monkeypatch,
                                                                              tmp_path):
    monkeypatch.delenv("MACROSTATE_REFERENCE_DATA", raising=False)
    assert paths.CHECKOUT is not None and (paths.CHECKOUT / "macrostate_mj").is_dir()
    assert paths.reference_data() == paths.CHECKOUT.parent / "shared" / "reference-data"
    monkeypatch.setenv("MACROSTATE_REFERENCE_DATA", str(tmp_path))
    assert paths.real_thymioloc("Train.csv") == tmp_path / "ReTLo" / "Datasets" / "3Robots" / (
        "Train.csv")
