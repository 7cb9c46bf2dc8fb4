"""`data fetch`: pinned files from a mirror, verified; a second call is a no-op; a corrupted or
truncated download is refused with nothing left behind. Offline: a local HTTP server on
127.0.0.1 serves small files the test makes."""

import hashlib
import http.server
import threading
import time
from functools import partial

import pytest
from clitools import cli_inprocess

from macrostate_mj.core import datasets
from macrostate_mj.core.datasets import Dataset, fetch
from macrostate_mj.core.errors import UserError

FILES = {"Datasets/a.csv": b"x,y\n1,2\n" * 50, "Datasets/sub/b.csv": b"0,1,2\n" * 80}


@pytest.fixture
def served(tmp_path):
    """A mirror of FILES over HTTP; yields (base URL, its folder, the paths asked for)."""
    root = tmp_path / "mirror"
    for name, data in FILES.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(data)
    asked = []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            asked.append(self.path)

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             partial(Handler, directory=str(root)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/", root, asked
    server.shutdown()


def toy() -> Dataset:
    return Dataset("toy", "someone/toy", "0" * 40, "Toy",
                   {n: hashlib.sha256(d).hexdigest() for n, d in FILES.items()})


def test_a_fetch_verifies_every_file_and_a_second_is_a_no_op(served, tmp_path):
    url, _, asked = served
    out = tmp_path / "data"
    paths = fetch(toy(), out, url)
    assert [p.read_bytes() for p in paths] == list(FILES.values())
    assert paths[1] == out / "Toy" / "Datasets" / "sub" / "b.csv"
    assert datasets.fetched(out, "Toy")
    before, start = len(asked), time.perf_counter()
    fetch(toy(), out, url)
    assert len(asked) == before and time.perf_counter() - start < 1.0


@pytest.mark.parametrize("spoil", [lambda d: d[:-7], lambda d: d.replace(b"2", b"3")],
                         ids=["truncated", "corrupted"])
def test_a_download_that_is_not_the_published_file_is_refused_and_removed(served, tmp_path,
                                                                          spoil):
    url, root, _ = served
    bad = root / "Datasets" / "sub" / "b.csv"
    bad.write_bytes(spoil(bad.read_bytes()))
    out = tmp_path / "data"
    with pytest.raises(UserError, match="b.csv is not the published file"):
        fetch(toy(), out, url)
    left = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert left == ["Toy/Datasets/a.csv"]          # the verified one stays, nothing else
    assert not datasets.fetched(out, "Toy")


def test_the_command_fetches_by_name_and_refuses_bad_input_in_one_line(served, tmp_path,
                                                                       capsys, monkeypatch):
    url, _, _ = served
    monkeypatch.setitem(datasets.DATASETS, "toy", toy())
    out = tmp_path / "data"
    code, text, err = cli_inprocess(capsys, "data", "fetch", "toy", "--dir", str(out),
                                    "--mirror", url)
    assert code == 0, err
    assert "2 files verified" in text and f"MACROSTATE_REFERENCE_DATA={out}" in text
    for args, words in ((["nothing"], "name one of"),
                        (["toy", "--mirror", "127.0.0.1:9"], "give a URL"),
                        (["toy", "--mirror", "http://127.0.0.1:9/"], "could not be fetched")):
        code, _, err = cli_inprocess(capsys, "data", "fetch", *args, "--dir",
                                     str(tmp_path / "other"))
        assert code == 2 and words in err and err.count("\n") == 1, err
    import pooch

    assert pooch.get_logger().level >= 30         # pooch's own INFO lines stay quiet
    assert not (tmp_path / "other" / "Toy" / "Datasets" / "a.csv").exists()


def test_the_published_files_are_pinned_to_a_commit():
    for d in datasets.DATASETS.values():
        assert len(d.commit) == 40 and all(len(h) == 64 for h in d.files.values())
        assert d.held_out <= set(d.files) and d.base_url.endswith(f"/{d.commit}/")


def test_a_mirror_that_is_no_url_is_refused_from_python_too(tmp_path):
    with pytest.raises(UserError, match="give a URL"):
        fetch(toy(), tmp_path, "127.0.0.1:9")
    assert not (tmp_path / "Toy").exists()
