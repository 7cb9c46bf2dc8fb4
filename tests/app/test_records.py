"""Every experiment's results record (`core.records.Record`): what it writes is what it reads,
and every committed results folder reads through the type its experiment declares."""

import json
from dataclasses import dataclass, field

import pytest
from conftest import REPO

from macrostate_mj.app.experiments import registry
from macrostate_mj.core.records import OPTIONAL, UNITS, Record, RecordError

RESULTS = REPO / "results"


def _committed() -> list[tuple[str, str]]:
    """(folder, experiment) of every committed run an experiment made, nested runs included."""
    found = []
    for manifest in sorted(RESULTS.rglob("manifest.json")):
        command = json.loads(manifest.read_text()).get("command", "")
        if command.startswith("experiment ") and (manifest.parent / "results.json").is_file():
            name = command.split()[1]
            if name != "all":
                found.append((str(manifest.parent.relative_to(RESULTS)), name))
    return found


def test_every_experiment_declares_its_record_and_unit():
    for name, module in registry().items():
        if name == "all":               # its products are the others' folders and an index
            continue
        record = module.Results
        assert issubclass(record, Record) and record.UNIT in UNITS, name
        assert record.FILE in module.PRODUCTS, name


@pytest.mark.skipif(not RESULTS.is_dir(), reason="no committed results")
@pytest.mark.parametrize(("folder", "name"), _committed())
def test_every_committed_run_reads_through_its_record(folder, name):
    """The record is the file's shape: read and written again, the same object."""
    record = registry()[name].Results.read(RESULTS / folder)
    assert record.as_json() == json.loads((RESULTS / folder / "results.json").read_text())


@dataclass(frozen=True)
class _Toy(Record):
    UNIT = "seed"

    values: dict
    extra: dict | None = field(default=None, metadata=OPTIONAL)


def test_a_record_writes_its_keys_and_refuses_others(tmp_path):
    _Toy({"0": 1.0}).write(tmp_path)
    assert json.loads((tmp_path / "results.json").read_text()) == {"values": {"0": 1.0}}
    assert _Toy.read(tmp_path) == _Toy({"0": 1.0})
    (tmp_path / "results.json").write_text(json.dumps({"valeus": {}}))
    with pytest.raises(RecordError, match=r"unknown keys \['valeus'\], missing \['values'\]"):
        _Toy.read(tmp_path)
    with pytest.raises(TypeError, match="UNIT"):
        type("Bad", (Record,), {"UNIT": "row"})
