"""The offline tools' plumbing: `cbgo data fetch` (a real git sparse checkout of a local repo),
`cbgo data list`, and `cbgo bench --write` (a results document only from a run that succeeded).
"""

import shutil
import subprocess
import sys

import pytest

from cbgo.cli.bench import split_write
from cbgo_tools import results
from cbgo_tools.data import DATASETS, command

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="needs git")


def cbgo(*argv, env=None):
    return subprocess.run([sys.executable, "-m", "cbgo.cli.main", *argv], capture_output=True,
                          text=True, timeout=120, env=env)


@pytest.fixture
def upstream(tmp_path):
    """A git repository holding shrec17's folder and something else beside it."""
    repo = tmp_path / "upstream"
    folder = repo / DATASETS["shrec17"].folder
    folder.mkdir(parents=True)
    (folder / "train_gestures.txt").write_text("1 1 1 1 1 100\n")
    (repo / "unrelated.txt").write_text("not wanted\n")
    for step in (["init", "-q"], ["add", "."],
                 ["-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "data"]):
        subprocess.run(["git", "-C", str(repo), *step], check=True)
    return repo


def test_fetch_copies_only_the_sets_folder_into_the_cache(upstream, tmp_path, monkeypatch):
    monkeypatch.setenv("CBGO_CACHE_DIR", str(tmp_path / "cache"))
    assert command.fetch(DATASETS["shrec17"], source=str(upstream)) == 0
    fetched = tmp_path / "cache" / "shrec17"
    assert (fetched / "train_gestures.txt").read_text() == "1 1 1 1 1 100\n"
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["shrec17"]
    assert command.fetch(DATASETS["shrec17"], source=str(upstream)) == 0  # there: kept


def test_fetch_from_a_repository_without_the_folder_says_so(tmp_path, monkeypatch, upstream):
    monkeypatch.setenv("CBGO_CACHE_DIR", str(tmp_path / "cache"))
    with pytest.raises(SystemExit) as exit_:
        command.fetch(DATASETS["mmhgr"], source=str(upstream))
    assert exit_.value.code == 1
    assert not (tmp_path / "cache" / "mmhgr").exists()


def test_list_names_every_set_and_where_it_is_cached(tmp_path):
    done = cbgo("data", "list", env={"CBGO_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    for name in DATASETS:
        assert f"{name}:" in done.stdout and str(tmp_path / name) in done.stdout
    assert "reserved" in done.stdout


def test_write_is_taken_wherever_it_stands():
    assert split_write(["--seconds", "3", "--write", "r.md"]) == ("r.md", ["--seconds", "3"])
    assert split_write(["--write=r.md", "-n", "2"]) == ("r.md", ["-n", "2"])
    assert split_write(["-n", "2"]) == (None, ["-n", "2"])


def test_a_results_document_holds_the_command_and_what_it_printed(tmp_path):
    path = tmp_path / "results" / "wire.md"
    with results.written(path, ["cbgo", "bench", "wire", "--count", "3"]):
        print("encode 1.2 us")
    text = path.read_text()
    assert "`cbgo bench wire --count 3`" in text and "encode 1.2 us" in text


def test_a_failed_run_leaves_the_results_document_as_it_was(tmp_path):
    path = tmp_path / "wire.md"
    path.write_text("kept\n")
    with pytest.raises(SystemExit), results.written(path, ["cbgo", "bench", "wire"]):
        print("half")
        sys.exit(1)
    with pytest.raises(RuntimeError), results.written(path, ["cbgo", "bench", "wire"]):
        raise RuntimeError("broken")
    assert path.read_text() == "kept\n"
