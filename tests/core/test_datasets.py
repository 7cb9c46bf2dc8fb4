"""`data fetch`: pinned files and archives from a mirror, verified; a second call is a no-op; a
corrupted or truncated download is refused with nothing left behind. Offline: a local HTTP
server on 127.0.0.1 serves small files and a zip the test makes."""

import hashlib
import http.server
import io
import threading
import time
import zipfile
from functools import partial

import pytest
from clitools import cli_inprocess

from macrostate_mj.core import datasets
from macrostate_mj.core.datasets import Archive, Files, Subset, fetch, tree_digest
from macrostate_mj.core.errors import UserError

FILES = {"Datasets/a.csv": b"x,y\n1,2\n" * 50, "Datasets/sub/b.csv": b"0,1,2\n" * 80}
COMMIT = "1" * 40
# an archive as GitHub makes one: a top folder <repo>-<commit>/ holding the repository
TREE = {"Stable/s_0.jpg": b"\xff\xd8stable0", "Stable/s_1.jpg": b"\xff\xd8stable1",
        "Unstable/u_0.jpg": b"\xff\xd8u0", "Unstable/u_1.jpg": b"\xff\xd8u1",
        "split1/train.csv": b"0\n1\n", "README.md": b"not pinned"}


@pytest.fixture
def served(tmp_path):
    """A mirror of FILES over HTTP; yields (base URL, its folder, the paths asked for)."""
    root = tmp_path / "mirror"
    for name, data in FILES.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_bytes(data)
    (root / "archive").mkdir()
    (root / "archive" / f"{COMMIT}.zip").write_bytes(zipped(TREE))
    asked = []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            asked.append(self.path)

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             partial(Handler, directory=str(root)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/", root, asked
    server.shutdown()


def zipped(tree: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in tree.items():
            zf.writestr(f"flows-{COMMIT}/{name}", data)
    return buf.getvalue()


def toy() -> Files:
    return Files("toy", "someone/toy", "0" * 40, "Toy",
                 files={n: hashlib.sha256(d).hexdigest() for n, d in FILES.items()})


def digests(tmp_path) -> dict[str, str]:
    """The tree digest of each top folder of TREE, from the files written out."""
    for name, data in TREE.items():
        (tmp_path / "tree" / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "tree" / name).write_bytes(data)
    return {top: tree_digest(tmp_path / "tree" / top) for top in ("Stable", "Unstable",
                                                                   "split1")}


def flows(tmp_path) -> Archive:
    return Archive("flows", "someone/flows", COMMIT, "Flows", trees=digests(tmp_path))


def dev(tmp_path) -> Subset:
    pick = {"Unstable/u_1.jpg": TREE["Unstable/u_1.jpg"]}
    (tmp_path / "pick" / "Unstable").mkdir(parents=True)
    (tmp_path / "pick" / "Unstable" / "u_1.jpg").write_bytes(pick["Unstable/u_1.jpg"])
    return Subset("flows-dev", "someone/flows", COMMIT, "Flows-dev", source=flows(tmp_path),
                  keep=lambda p: p in pick, rule="u_1 only",
                  trees={"Unstable": tree_digest(tmp_path / "pick" / "Unstable")})


def test_a_fetch_verifies_every_file_and_a_second_is_a_no_op(served, tmp_path):
    url, _, asked = served
    out = tmp_path / "data"
    paths = fetch(toy(), out, url)
    assert paths == 2
    assert [(out / "Toy" / n).read_bytes() for n in FILES] == list(FILES.values())
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
    monkeypatch.setattr(datasets, "DATASETS", {d.name: d for d in (toy(), flows(tmp_path),
                                                                    dev(tmp_path))})
    out = tmp_path / "data"
    code, text, err = cli_inprocess(capsys, "data", "fetch", "all", "--dir", str(out),
                                    "--mirror", url)
    assert code == 0, err
    assert all(f"{n} files verified" in text for n in (2, 5, 1)), text
    assert f"MACROSTATE_REFERENCE_DATA={out}" in text
    for args, words in ((["nothing"], "name one of"),
                        (["toy", "--mirror", "127.0.0.1:9"], "give a URL"),
                        (["toy", "--mirror", "http://127.0.0.1:9/"], "could not be fetched")):
        code, _, err = cli_inprocess(capsys, "data", "fetch", *args, "--dir",
                                     str(tmp_path / "other"))
        assert code == 2 and words in err and err.count("\n") == 1, err
    import pooch

    assert pooch.get_logger().level >= 30         # pooch's own INFO lines stay quiet
    assert not (tmp_path / "other" / "Toy" / "Datasets" / "a.csv").exists()


def test_the_published_datasets_are_pinned_to_a_commit_and_sha256():
    for d in datasets.DATASETS.values():
        pins = d.files if isinstance(d, Files) else d.trees
        assert len(d.commit) == 40 and pins and all(len(h) == 64 for h in pins.values())
        assert all(path.split("/")[0] in pins if isinstance(d, Archive) else path in pins
                   for path in d.held_out)
    assert datasets.RETLO.base_url.endswith(f"/{datasets.RETLO.commit}/")
    assert datasets.HSANTS_DEV.source is datasets.HSANTS


def test_an_archive_is_extracted_verified_by_tree_digest_and_fetched_once(served, tmp_path):
    url, _, asked = served
    out = tmp_path / "data"
    assert fetch(flows(tmp_path), out, url) == 5            # the README is not pinned: left out
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()) == [
        "Flows/.verified.json", "Flows/Stable/s_0.jpg", "Flows/Stable/s_1.jpg",
        "Flows/Unstable/u_0.jpg", "Flows/Unstable/u_1.jpg", "Flows/split1/train.csv"]
    assert asked == [f"/archive/{COMMIT}.zip"]
    start = time.perf_counter()
    assert fetch(flows(tmp_path), out, url) == 5 and len(asked) == 1
    assert time.perf_counter() - start < 1.0
    assert fetch(dev(tmp_path), out, url) == 1 and len(asked) == 1   # picked, not downloaded
    assert (out / "Flows-dev" / "Unstable" / "u_1.jpg").read_bytes() == TREE["Unstable/u_1.jpg"]
    assert datasets.fetched(out, "Flows-dev", COMMIT)


@pytest.mark.parametrize("spoil", [lambda z: z[:len(z) // 2],
                                   lambda z: zipped({**TREE, "Stable/s_1.jpg": b"\xff\xd8x"}),
                                   lambda z: zipped({**TREE, "Stable/extra.jpg": b"x"})],
                         ids=["truncated", "corrupted", "extra file"])
def test_an_archive_that_is_not_the_published_one_is_refused_with_nothing_left(
        served, tmp_path, spoil):
    url, root, _ = served
    archive = root / "archive" / f"{COMMIT}.zip"
    archive.write_bytes(spoil(archive.read_bytes()))
    out = tmp_path / "data"
    with pytest.raises(UserError, match="is not the published file"):
        fetch(flows(tmp_path), out, url)
    assert not [p for p in out.rglob("*") if p.is_file()]


def test_a_copy_placed_by_hand_is_adopted_if_published_and_never_overwritten(served,
                                                                              tmp_path):
    url, _, asked = served
    out = tmp_path / "data"
    for name, data in TREE.items():
        if name != "README.md":
            (out / "Flows" / name).parent.mkdir(parents=True, exist_ok=True)
            (out / "Flows" / name).write_bytes(data)
    assert fetch(flows(tmp_path), out, url) == 5 and not asked
    (out / "Flows" / ".verified.json").unlink()
    (out / "Flows" / "Stable" / "s_0.jpg").write_bytes(b"mine")
    with pytest.raises(UserError, match="move it away or fetch into another --dir"):
        fetch(flows(tmp_path), out, url)
    assert (out / "Flows" / "Stable" / "s_0.jpg").read_bytes() == b"mine" and not asked


def test_a_mirror_that_is_no_url_is_refused_from_python_too(tmp_path):
    with pytest.raises(UserError, match="give a URL"):
        fetch(toy(), tmp_path, "127.0.0.1:9")
    assert not (tmp_path / "Toy").exists()
